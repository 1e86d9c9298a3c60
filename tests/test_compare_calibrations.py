"""benchmarks/compare_calibrations.py: the before/after referee of behaviour-preserving changes."""

from __future__ import annotations

import json

import numpy as np
import pytest


@pytest.fixture
def cc(load_script):
    return load_script("benchmarks/compare_calibrations.py")


def _folder(root, ka, summary_value="1.5", log_z=-3.25):
    phase = root / "agent" / "wf"
    phase.mkdir(parents=True)
    np.savez(phase / "phase1_x.npz", ka=np.asarray(ka, dtype=np.float64), kb=np.array([1.0, np.nan]))
    (phase / "summary.csv").write_text(f"parameter,mean,seconds\nka,{summary_value},9.0\n")
    (phase / "manifest.json").write_text(json.dumps(
        {"phases": {"phase1_x": {"config_hash": "abc", "status": "converged", "log_evidence": log_z,
                                 "log_evidence_se": None, "seconds": 1.0}}}))
    return root


def test_identical_folders_agree(cc, tmp_path, capsys):
    a = _folder(tmp_path / "a", [1.0, 2.0])
    b = _folder(tmp_path / "b", [1.0, 2.0])
    assert cc.main([str(a), str(b)]) == 0
    last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert last["equal"] is True and last["files"] == 3 and last["max_abs"] == 0.0


def test_a_changed_sample_is_reported_with_its_size(cc, tmp_path, capsys):
    a = _folder(tmp_path / "a", [1.0, 2.0])
    b = _folder(tmp_path / "b", [1.0, 2.0 + 1e-9])
    assert cc.main([str(a), str(b)]) == 1
    out = capsys.readouterr().out
    assert "DIFFERENT: ka" in out
    assert json.loads(out.strip().splitlines()[-1])["max_abs"] == pytest.approx(1e-9, rel=1e-3)
    # within a stated tolerance the same folders agree
    assert cc.main([str(a), str(b), "--rtol", "1e-6"]) == 0


def test_wall_times_are_ignored_but_evidence_and_summaries_are_not(cc, tmp_path, capsys):
    a = _folder(tmp_path / "a", [1.0], log_z=-3.25)
    b = _folder(tmp_path / "b", [1.0], log_z=-3.5)
    assert cc.main([str(a), str(b)]) == 1
    assert "phase1_x/log_evidence" in capsys.readouterr().out
    c = _folder(tmp_path / "c", [1.0], summary_value="1.6")
    assert cc.main([str(a), str(c)]) == 1


def test_missing_files_and_unusable_folders(cc, tmp_path, capsys):
    a = _folder(tmp_path / "a", [1.0])
    b = _folder(tmp_path / "b", [1.0])
    (b / "agent" / "wf" / "phase1_x.npz").unlink()
    assert cc.main([str(a), str(b)]) == 1
    assert "missing on one side" in capsys.readouterr().out
    assert cc.main([str(a), str(tmp_path / "nowhere")]) == 2
    (tmp_path / "empty").mkdir()
    assert cc.main([str(tmp_path / "empty"), str(tmp_path / "empty")]) == 2
