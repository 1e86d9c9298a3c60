"""`bubblecal evidence`: Kass–Raftery verdicts, bad inputs, a tiny full-vs-reduced run (slow)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from bubblecal.workflows.cli import app
from bubblecal.workflows.evidence import EVIDENCE_COLUMNS, kass_raftery, run_evidence


@pytest.mark.parametrize("ln_b, se, expected", [
    (0.5, 0.1, ("full", "not worth more than a bare mention")), (2.0, 0.1, ("full", "positive")),
    (-4.0, 0.5, ("reduced", "strong")), (-6.0, 0.5, ("reduced", "very strong")),
    (1.0, 0.8, ("full", "inconclusive (Monte Carlo error)")), (math.nan, 0.1, ("", "undefined"))])
def test_kass_raftery(ln_b, se, expected):
    assert kass_raftery(ln_b, se) == expected


def test_bad_inputs(tmp_path, synthetic_bundle):
    runner = CliRunner()
    r = runner.invoke(app, ["evidence", "--agent", "optison", "--bundle", str(synthetic_bundle)],
                      env={"COLUMNS": "250"})
    assert r.exit_code == 2 and "'optison' is not one of 'definity', 'sonovue', 'all'" in r.output
    r = runner.invoke(app, ["evidence", "--replicas", "1", "--bundle", str(synthetic_bundle)])
    assert r.exit_code == 1 and "--replicas" in r.output
    r = runner.invoke(app, ["evidence", "--bundle", str(tmp_path)])
    assert r.exit_code == 1 and "manifest.json" in r.output


@pytest.mark.slow
def test_tiny_evidence_run(tmp_path, synthetic_bundle):
    from bubblecal.surrogates import load_bundle

    df = run_evidence(["definity"], load_bundle(synthetic_bundle), population=300, replicas=2, out=tmp_path,
                      curves=("definity_compression_2.9um",), num_mcmc_steps=3)
    assert list(df.columns) == list(EVIDENCE_COLUMNS) and len(df) == 1
    row = df.iloc[0]
    assert math.isfinite(row["ln_bayes_factor"]) and row["ln_bayes_factor_se"] >= 0
    assert row["ln_bayes_factor"] == pytest.approx(row["log_z_full"] - row["log_z_reduced"])
    assert pd.read_csv(tmp_path / "definity" / "evidence.csv").shape[0] == 1
    assert math.isfinite(row["elpd_loo_full"]) and math.isfinite(row["elpd_loo_reduced_se"])
    assert row["loo_favours"] in ("full", "reduced") and row["pareto_k_bad_full"] >= 0


def test_loo_columns_rank_the_better_fitting_model():
    """Two models of 30 normal points: the one at the data's mean has the larger elpd_loo, az.compare ranks it
    first, and elpd_loo equals the analytic sum of log mean_s p(y_j | θ_s) to PSIS accuracy."""
    from scipy import stats

    from bubblecal.inference import build_inference_data
    from bubblecal.workflows.evidence import loo_columns

    rng = np.random.default_rng(0)
    y = rng.normal(0.0, 1.0, 30)
    idatas = {}
    for name, centre in (("full", 0.0), ("reduced", 1.5)):
        mu = rng.normal(centre, 0.05, (2, 400))
        ll = stats.norm.logpdf(y[None, None, :], mu[..., None], 1.0)
        idatas[name] = build_inference_data({"mu": mu}, log_likelihood={"y": ll}, observed_data={"y": y})
    row = loo_columns(idatas)
    assert row["loo_favours"] == "full" and row["elpd_diff"] > 0 and row["elpd_diff_se"] > 0
    assert row["pareto_k_bad_full"] == 0 and isinstance(row["pareto_k_bad_reduced"], int)
    mu = idatas["full"].posterior["mu"].values.ravel()
    lpd = np.log(stats.norm.pdf(y[None, :], mu[:, None], 1.0).mean(axis=0)).sum()
    assert row["elpd_loo_full"] == pytest.approx(lpd, abs=0.5) and 0 < row["p_loo_full"] < 1
