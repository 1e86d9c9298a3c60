"""`bubblecal evidence`: Kass–Raftery verdicts, bad inputs, a tiny full-vs-reduced run (slow)."""

from __future__ import annotations

import math

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
