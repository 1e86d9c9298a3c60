"""`bubblecal calibrate` hardening: the likelihood preflight, a damaged phase file, the run lock, --curve of
another agent and --out on a read-only file system."""

from __future__ import annotations

import dataclasses
import errno
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from bubblecal.workflows.calibrate import (
    LOCK_NAME,
    CalibrationConfig,
    CalibrationError,
    make_plan,
    read_phase,
    run_calibration,
    run_lock,
)
from bubblecal.workflows.calibrate.preflight import preflight
from bubblecal.workflows.cli import app

runner = CliRunner()
ONE = ("definity_compression_2.1um",)


def _config(bundle, out, **kw):
    return CalibrationConfig(**{"agents": ("definity",), "workflow": "reduced", "bundle": bundle, "population": 120,
                                "out": out, "phase2_samples": 120, "predictive_samples": 100, "num_mcmc_steps": 2,
                                "curves": ONE, "figures": False, "summaries": False, **kw})


# -------------------------------------------------------------------------------------------------
# likelihood preflight: a dataset whose likelihood is not finite is named before any phase runs
# -------------------------------------------------------------------------------------------------
def test_preflight_names_the_curve_and_the_acoustic_table(tmp_path, synthetic_bundle):
    plan = make_plan(_config(synthetic_bundle, tmp_path / "o", workflow="reduced-acoustic"))
    (ap,) = plan.agents
    good = ap.curves[0]
    ap.curves[0] = dataclasses.replace(good, y=np.full_like(good.y, 1e300))
    with pytest.raises(CalibrationError, match=r"definity dataset definity_compression_2\.1um \(.*_dpd\.csv\): "
                                               r"the log likelihood is not finite at 4 of 4 prior draws"):
        preflight(plan)
    ap.curves[0] = good
    ds = ap.acoustic[0]
    ap.acoustic[0] = dataclasses.replace(ds, frequency_MHz=np.full_like(ds.frequency_MHz, 1e300))
    with pytest.raises(CalibrationError, match=r"definity_acoustic \(the shipped acoustic table\)"):
        preflight(plan)
    assert not list((tmp_path / "o").rglob("phase*"))


# -------------------------------------------------------------------------------------------------
# --curve of another agent, --out on a read-only file system
# -------------------------------------------------------------------------------------------------
def test_curve_of_another_agent_is_named(tmp_path, synthetic_bundle):
    cfg = _config(synthetic_bundle, tmp_path / "o", curves=(*ONE, "sonovue_indentation_3.2um"))
    with pytest.raises(CalibrationError, match=r"--curve sonovue_indentation_3\.2um \(a sonovue curve\): not a "
                                               r"curve of --agent definity"):
        make_plan(cfg)


def test_out_on_a_read_only_file_system(tmp_path, synthetic_bundle, monkeypatch):
    def erofs(self, *a, **k):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(self))

    monkeypatch.setattr(os, "access", lambda *a, **k: True)  # a read-only mount that access() does not flag
    monkeypatch.setattr(Path, "mkdir", erofs)
    out = tmp_path / "ro" / "cal"
    r = runner.invoke(app, ["calibrate", "--agent", "definity", "--bundle", str(synthetic_bundle), "--out", str(out)])
    assert r.exit_code == 1 and f"--out {out}" in r.output and "Read-only file system" in r.output, r.output
    assert "Traceback" not in r.output


# -------------------------------------------------------------------------------------------------
# one run per output folder
# -------------------------------------------------------------------------------------------------
def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_lock_refuses_a_live_run_and_takes_over_a_stale_one(tmp_path, synthetic_bundle):
    import json
    import socket

    out = tmp_path / "o"
    out.mkdir()
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (out / LOCK_NAME).write_text(json.dumps({"pid": live.pid, "host": socket.gethostname(), "started": "x"}))
        with pytest.raises(CalibrationError, match=rf"another calibrate run \(PID {live.pid}, started x\)"):
            with run_lock(out):
                pass
        r = runner.invoke(app, ["calibrate", "--agent", "definity", "--workflow", "reduced", "--curve", ONE[0],
                                "--bundle", str(synthetic_bundle), "--population", "120", "--out", str(out)])
        assert r.exit_code == 1 and f"PID {live.pid}" in r.output and "Traceback" not in r.output, r.output
        assert not list(out.rglob("phase*"))
    finally:
        live.kill()
        live.wait()
    dead = _dead_pid()
    (out / LOCK_NAME).write_text(json.dumps({"pid": dead, "host": socket.gethostname()}))
    said = []
    with run_lock(out, say=said.append) as lock:
        assert json.loads(lock.read_text())["pid"] == os.getpid()
    assert said and f"PID {dead} (no longer running)" in said[0] and not (out / LOCK_NAME).exists()


# -------------------------------------------------------------------------------------------------
# a damaged phase file: named, that phase and its dependants recomputed, the rest reused
# -------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("suffix", [".nc", ".npz"])
def test_phase_store_names_a_damaged_file_and_recomputes_its_dependants(tmp_path, suffix):
    """The store alone (no sampling): a damaged phase is not reused, nor is any phase computed from it."""
    from bubblecal.inference.phase_results import PhaseResult
    from bubblecal.workflows.calibrate import PhaseStore

    names = ["phase1_a", "phase1_b", "phase2", "phase3_a", "phase3_b"]

    def store(said=None):
        st = PhaseStore(tmp_path, netcdf=suffix == ".nc", say=said.append if said is not None else None)
        st.expected = {n: f"hash-{n}" for n in names}
        return st

    first = store()
    for k, n in enumerate(names):
        first.save(PhaseResult(n, {"ka": np.arange(5.0) + k}, -1.0, 0.1, "converged", 1.0))
    (tmp_path / f"phase1_b{suffix}").write_bytes(b"\x89HDF\r\n garbage")
    said = []
    st = store(said)
    loaded = {n: st.load(n) for n in names}
    assert [n for n, r in loaded.items() if r is not None] == ["phase1_a"]  # phase 2 and both phase 3 use phase1_b
    assert st.recomputed == ["phase1_b", "phase2", "phase3_a", "phase3_b"]
    assert str(tmp_path / f"phase1_b{suffix}") in said[0] and "damaged or unreadable phase file" in said[0]
    assert np.array_equal(loaded["phase1_a"].samples["ka"], np.arange(5.0))
    first.save(PhaseResult("phase1_b", {"ka": np.arange(5.0) + 1}, -1.0, 0.1, "converged", 1.0))
    path = tmp_path / f"phase3_a{suffix}"
    path.write_bytes(path.read_bytes()[:40])  # truncated
    st = store([])
    assert [n for n in names if st.load(n) is None] == ["phase3_a"]


@pytest.mark.slow
def test_damaged_phase_files_are_named_and_recomputed(tmp_path, synthetic_bundle):
    config = _config(synthetic_bundle, tmp_path / "cal")
    (first,) = run_calibration(make_plan(config))
    run_dir = tmp_path / "cal" / "definity" / "reduced"
    p1, p2, p3 = (run_dir / f"{n}.nc" for n in ("phase1_" + ONE[0], "phase2", "phase3_" + ONE[0]))
    before = {p: read_phase(p)[0].samples for p in (p1, p2, p3)}

    p3.write_bytes(p3.read_bytes()[: p3.stat().st_size // 2])  # truncated: only phase 3 reruns
    said = []
    (res,) = run_calibration(make_plan(config), progress=said.append)
    assert sorted(res.reused) == sorted([p1.stem, p2.stem])
    assert any(str(p3) in m and "damaged" in m for m in said), said
    p2.write_bytes(b"garbage, not HDF5")  # phase 2 and the phase 3 that depends on it rerun; phase 1 is kept
    said = []
    (res,) = run_calibration(make_plan(config), progress=said.append)
    assert res.reused == [p1.stem] and any(str(p2) in m for m in said)
    assert any(m.startswith(f"{p3.stem}: recomputed, it depends on phase2") for m in said), said
    for p, samples in before.items():  # the recomputed phases are the same draws (same seeds)
        again = read_phase(p)[0].samples
        assert all(np.array_equal(samples[k], again[k]) for k in samples)


# -------------------------------------------------------------------------------------------------
# SIGKILL during a phase, then resume: the same draws as an uninterrupted run, the stale lock taken over
# -------------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_sigkill_during_a_phase_then_resume_gives_identical_results(tmp_path, synthetic_bundle):
    import signal
    import time

    def command(out):
        return [sys.executable, "-m", "bubblecal.workflows.cli", "calibrate", "--agent", "definity", "--workflow",
                "reduced", "--curve", ONE[0], "--curve", "definity_compression_2.9um", "--bundle",
                str(synthetic_bundle), "--population", "120", "--phase2-samples", "120", "--mcmc-steps", "2",
                "--no-figures", "--out", str(out)]

    reference = tmp_path / "reference"
    subprocess.run(command(reference), check=True, capture_output=True, timeout=900)
    killed = tmp_path / "killed"
    run_dir = killed / "definity" / "reduced"
    proc = subprocess.Popen(command(killed), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    t_end = time.time() + 900
    while time.time() < t_end and proc.poll() is None and not list(run_dir.glob("phase1_*.nc")):
        time.sleep(0.05)
    assert proc.poll() is None, "the run finished before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)  # phase 1 of the second curve (or phase 2) is running
    proc.wait()
    assert (killed / LOCK_NAME).exists() and not list(run_dir.glob("phase3_*"))
    done = subprocess.run(command(killed), capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    out = " ".join(done.stdout.split())
    assert "took over the lock of PID" in out and "reused phases: phase1_definity_compression_2.1um" in out
    for ref in sorted((reference / "definity" / "reduced").glob("phase*.nc")):
        a, b = read_phase(ref)[0].samples, read_phase(run_dir / ref.name)[0].samples
        assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a), ref.name
    assert not (killed / LOCK_NAME).exists() and not list(run_dir.glob(".*tmp"))
