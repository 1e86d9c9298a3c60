"""`bubblecal confirm`: the phase-3 MAP of a run re-simulated with a tier (quasi-static, subdivision 1, CPU)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from bubblecal.inference import PhaseResult
from bubblecal.workflows.calibrate import write_phase
from bubblecal.workflows.cli import app
from bubblecal.workflows.confirm import find_runs, map_parameters


@pytest.fixture
def run_dir(tmp_path, synthetic_bundle):
    """A hand-made run folder: manifest + a phase-3 result of the Definity 2.1 um curve (MAP = draw 1)."""
    from bubblecal.priors import prior_path

    folder = tmp_path / "cal" / "definity" / "reduced"
    folder.mkdir(parents=True)
    samples = {"ka": np.array([9000.0, 15000.0, 20000.0]), "kb": np.array([300.0, 500.0, 700.0]),
               "d0": np.array([0.05, 0.1, 0.15]), "sigma": np.array([0.05, 0.05, 0.05])}
    res = PhaseResult("phase3_definity_compression_2.1um", samples, -10.0, 0.1, "converged", 1.0)
    write_phase(folder / "phase3_definity_compression_2.1um.npz", res, np.array([-12.0, -3.0, -8.0]), {})
    (folder / "manifest.json").write_text(json.dumps({"run": {"agent": "definity", "bundle": str(synthetic_bundle),
                                                              "priors": str(prior_path("definity_reduced"))},
                                                      "phases": {}}))
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
