"""`bubblecal calibrate` plan validation: bad inputs fail with one clear error before any sampling."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from bubblecal.workflows.calibrate import CalibrationConfig, CalibrationError, make_plan
from bubblecal.workflows.cli import app

runner = CliRunner()


def _phase_files(root: Path) -> list[Path]:
    return sorted(root.rglob("phase*.nc")) + sorted(root.rglob("phase*.npz"))


def _cli(*args):
    return runner.invoke(app, ["calibrate", *map(str, args)])


# -------------------------------------------------------------------------------------------------
# bad inputs: one clear error before any sampling (no phase files)
# -------------------------------------------------------------------------------------------------
def test_broken_priors_file(tmp_path, synthetic_bundle):
    bad = tmp_path / "broken.toml"
    bad.write_text("[workflow]\nagent = 'definity'\nsetup = 'compression'\nshell = 'reduced'\nacoustic = false\n"
                   "[parameters.ka]\nprior = [3.0e4, 1.0e3]\n")
    out = tmp_path / "out"
    r = _cli("--agent", "definity", "--workflow", "reduced", "--priors", bad, "--bundle", synthetic_bundle,
             "--population", 200, "--out", out)
    assert r.exit_code == 1, r.output
    assert "broken.toml" in r.output and "ka" in r.output
    assert not _phase_files(out)


def test_bad_data_rows(tmp_path, synthetic_bundle):
    data = tmp_path / "data"
    data.mkdir()
    (data / "definity_compression_2.9um_dpd.csv").write_text(
        "displacement_dpd,force_dpd\n0.3,600\n0.5,abc\n0.4,-5\n0.9,3000\n")
    with pytest.raises(CalibrationError, match=r"definity_compression_2\.9um_dpd\.csv.*\n.*row"):
        make_plan(CalibrationConfig(agents=("definity",), workflow="reduced", bundle=synthetic_bundle, population=200,
                                    data_dir=data, out=tmp_path / "out"))
    r = _cli("--agent", "definity", "--workflow", "reduced", "--data-dir", data, "--bundle", synthetic_bundle,
             "--population", 200, "--out", tmp_path / "out")
    assert r.exit_code == 1 and "abc" in r.output
    assert not _phase_files(tmp_path / "out")


def test_bundle_missing_a_diameter(tmp_path, synthetic_bundle):
    partial = tmp_path / "partial"
    shutil.copytree(synthetic_bundle, partial)
    manifest = json.loads((partial / "manifest.json").read_text())
    manifest["surrogates"] = [e for e in manifest["surrogates"] if not (e["setup"] == "indentation"
                                                                         and abs(e["diameter_um"] - 3.4) < 0.01)]
    (partial / "manifest.json").write_text(json.dumps(manifest))
    r = _cli("--agent", "sonovue", "--bundle", partial, "--population", 500, "--out", tmp_path / "out")
    assert r.exit_code == 1
    assert "no indentation surrogate at 3.4 um" in r.output and "sonovue_indentation_3.4um" in r.output
    assert not _phase_files(tmp_path / "out")


def test_population_too_small_and_other_fields(tmp_path, synthetic_bundle):
    r = _cli("--agent", "definity", "--bundle", synthetic_bundle, "--population", 50, "--out", tmp_path / "out")
    assert r.exit_code == 1 and "--population 50 is too small" in r.output and "phase" in r.output
    assert not _phase_files(tmp_path / "out")
    for kwargs, match in (({"workflow": "medium"}, "--workflow"), ({"sampler": "hmc"}, "--sampler"),
                          ({"phase3": "joint"}, "--phase3"),
                          ({"agents": ("optison",)}, "--agent"), ({"bundle": tmp_path}, "manifest.json")):
        base = {"agents": ("definity",), "bundle": synthetic_bundle, "population": 200, "out": tmp_path / "o"}
        with pytest.raises(CalibrationError, match=match):
            make_plan(CalibrationConfig(**{**base, **kwargs}))


def test_no_shipped_bundle_message(tmp_path, monkeypatch):
    import bubblecal.surrogates.bundle as bundle_mod

    monkeypatch.setattr(bundle_mod, "__file__", str(tmp_path / "nowhere" / "bundle.py"))
    with pytest.raises(CalibrationError, match="no shipped surrogate bundle found at .*synthetic-bundle"):
        make_plan(CalibrationConfig(agents=("definity",), out=tmp_path / "o"))
