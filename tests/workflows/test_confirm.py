"""`bubblecal confirm`: the phase-3 MAP of a run re-simulated with a tier (quasi-static, subdivision 1, CPU)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from bubblecal.inference import PhaseResult
from bubblecal.workflows.calibrate import CalibrationConfig, CalibrationError, run_plan, write_phase
from bubblecal.workflows.cli import app
from bubblecal.workflows.confirm import find_runs, map_parameters


def _write_run(folder, config, agent: str, curve: str) -> None:
    """A hand-made run folder: the manifest of ``config`` + a phase-3 result of ``curve`` (MAP = draw 1)."""
    folder.mkdir(parents=True)
    samples = {"ka": np.array([9000.0, 15000.0, 20000.0]), "kb": np.array([300.0, 500.0, 700.0]),
               "d0": np.array([0.05, 0.1, 0.15]), "sigma": np.array([0.05, 0.05, 0.05])}
    res = PhaseResult(f"phase3_{curve}", samples, -10.0, 0.1, "converged", 1.0)
    write_phase(folder / f"phase3_{curve}.npz", res, np.array([-12.0, -3.0, -8.0]), {})
    (folder / "manifest.json").write_text(json.dumps({"run": {"config": config.as_dict(), "agent": agent},
                                                      "phases": {}}))


@pytest.fixture
def run_dir(tmp_path, synthetic_bundle):
    """A published-study run folder of the Definity 2.1 um curve on the synthetic bundle."""
    config = CalibrationConfig(agents=("definity",), workflow="reduced", bundle=synthetic_bundle,
                               out=tmp_path / "cal", curves=("definity_compression_2.1um",))
    folder = tmp_path / "cal" / "definity" / "reduced"
    _write_run(folder, config, "definity", "definity_compression_2.1um")
    return folder


def test_map_and_find(run_dir, tmp_path):
    assert find_runs(tmp_path / "cal") == [run_dir] and find_runs(run_dir) == [run_dir]
    assert find_runs(run_dir.parent) == [run_dir]  # OUT/<agent>
    theta = map_parameters(run_dir, "definity_compression_2.1um")
    assert theta["ka"] == 15000.0 and theta["d0"] == 0.1
    assert map_parameters(run_dir, "definity_compression_2.9um") is None


def test_confirm_quasistatic_cpu(run_dir):
    r = CliRunner().invoke(app, ["confirm", str(run_dir), "--tier", "quasistatic", "--device", "cpu",
                                 "--subdivisions", "1"])
    assert r.exit_code == 0, r.output
    summ = pd.read_csv(run_dir / "confirm" / "confirm_quasistatic_summary.csv")
    assert list(summ["curve"]) == ["definity_compression_2.1um"]
    s = summ.iloc[0]
    assert s["map_ka"] == 15000.0 and np.isfinite(s["rel_l2_sim_vs_surrogate"])
    pts = pd.read_csv(run_dir / "confirm" / "confirm_quasistatic.csv")
    assert (pts["grid_dpd"] > 0).all() and len(pts) > 10  # x - d0 > 0 points only
    assert (run_dir / "confirm" / "confirm_quasistatic.png").stat().st_size > 10_000
    r = CliRunner().invoke(app, ["confirm", str(run_dir.parent.parent / "nothing")])
    assert r.exit_code == 1 and "no calibration run folder" in r.output


def test_run_plan_rebuilds_the_runs_inputs(run_dir, tmp_path):
    """The plan of a finished run: its agent, curves and priors, also after the output root moved."""
    ap = run_plan(run_dir)
    assert ap.agent == "definity" and [c.name for c in ap.curves] == ["definity_compression_2.1um"]
    moved = tmp_path / "elsewhere" / "definity" / "reduced"
    moved.parent.parent.mkdir()
    run_dir.parent.parent.rename(moved.parent.parent)
    assert run_plan(moved).out_dir == moved
    with pytest.raises(CalibrationError, match="not a calibration manifest"):
        (moved / "manifest.json").write_text("{}")
        run_plan(moved)


def test_config_round_trips_through_the_manifest(tmp_path):
    config = CalibrationConfig(agents=("sonovue",), workflow="full", out=tmp_path, data=tmp_path / "c.csv",
                               priors={"sonovue": "p.toml"}, curves=("a", "b"), population=600, networks="accurate")
    # the manifest records the surrogates the run resolved to (measured bubbles: the networks over the diameter)
    assert CalibrationConfig.from_dict(json.loads(json.dumps(config.as_dict()))) == dataclasses.replace(
        config, surrogates="over-diameter")


def test_confirm_a_run_of_measured_bubbles(tmp_path):
    """`confirm` on a `calibrate --data` run: the user's bubble (its own name and diameter), the fast network."""
    from bubblecal.priors import prior_path

    src = tmp_path / "curves.csv"
    rows = [f"bead-7,definity,compression,2.5,{x:.3f},{0.02 * x:.4f}" for x in np.linspace(5.0, 120.0, 12)]
    src.write_text("bubble,agent,protocol,diameter_um,displacement_nm,force_nN\n" + "\n".join(rows) + "\n")
    config = CalibrationConfig(workflow="reduced", out=tmp_path / "cal", data=src,
                               priors={"definity": str(prior_path("definity_reduced"))})
    folder = tmp_path / "cal" / "definity" / "reduced"
    _write_run(folder, config, "definity", "bead-7")
    r = CliRunner().invoke(app, ["confirm", str(folder), "--tier", "quasistatic", "--device", "cpu",
                                 "--subdivisions", "1"])
    assert r.exit_code == 0, r.output
    summ = pd.read_csv(folder / "confirm" / "confirm_quasistatic_summary.csv")
    assert list(summ["curve"]) == ["bead-7"] and summ.iloc[0]["map_ka"] == 15000.0
    assert np.isfinite(summ.iloc[0]["rel_l2_sim_vs_surrogate"])
