"""The synthetic population study run end to end (slow): 40 bubbles simulated with the quasi-static tier at known
parameters (benchmarks/studies/synthetic_population_40, docs/synthetic-study.md) go through ``calibrate --data`` and
the population and per-bubble k_a must be recovered: true m_ka and tau_ka inside their 90 % intervals, and the
per-bubble 90 % intervals covering the true k_a a number of times inside the binomial 95 % range of Binomial(40, 0.9)
([32, 39])."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bubblecal.workflows.calibrate import CalibrationConfig, make_plan, run_calibration

STUDY = Path(__file__).resolve().parents[2] / "benchmarks" / "studies" / "synthetic_population_40"


@pytest.mark.slow
def test_synthetic_population_is_recovered(tmp_path, load_script):
    load_script("benchmarks/synthetic_population.py")
    import synthetic_population_checks as checks

    truth = json.loads((STUDY / "truth.json").read_text())
    config = CalibrationConfig(data=STUDY / "curves.csv", workflow="reduced", phase3="exact", out=tmp_path,
                               figures=False, seed=0)
    (result,) = run_calibration(make_plan(config))
    verdict = checks.evaluate(truth, checks.read_summary(result.plan.out_dir))
    for name in ("m_ka", "tau_ka", "coverage_ka"):
        assert verdict["checks"][name]["pass"], (name, verdict["checks"][name])
