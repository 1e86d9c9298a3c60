"""`bubblecal sensitivity`: Sobol indices of a surrogate over a prior box, written as JSON + plot."""

import json

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from bubblecal.priors import load_priors
from bubblecal.surrogates import load
from bubblecal.workflows.cli_sensitivity import register
from bubblecal.workflows.sensitivity import surrogate_sensitivity

app = typer.Typer()
register(app)
app.command("noop")(lambda: None)  # a second command keeps typer in multi-command mode


def test_sensitivity_cli_writes_report(tiny_compression_surrogate, tmp_path):
    out = tmp_path / "sens"
    result = CliRunner().invoke(app, ["sensitivity", "--surrogate", str(tiny_compression_surrogate), "--curve",
                                      "definity-2.1", "--priors", "definity_reduced", "--n", "256", "--points", "12",
                                      "--out", str(out)])
    assert result.exit_code == 0, result.output
    report = json.loads((out / "definity_compression_2.1um_sobol.json").read_text())
    assert report["names"] == ["ka", "kb"] and report["fixed"] == {"b1": 0.0, "b2": 0.0, "a3": 0.0, "a4": 0.0}
    assert report["N"] == 256 and report["n_evaluations"] == 256 * 4
    avg = {row["parameter"]: row for row in report["averaged"]}
    # two inputs carry all the variance: first-order indices add up to ~1, each within [0, 1]
    assert 0.8 < avg["ka"]["S1"] + avg["kb"]["S1"] < 1.2
    assert all(-0.05 < avg[k]["S1"] <= avg[k]["ST"] + 0.05 for k in ("ka", "kb"))
    # the reduced shell evaluates b1 = b2 = a4 = 0, on the edge of the training data: reported, not silent
    assert report["outside_training_fraction"] > 0
    assert (out / "definity_compression_2.1um_sobol.png").stat().st_size > 10_000


def test_indices_are_consistent(tiny_compression_surrogate):
    s = load(tiny_compression_surrogate)
    with pytest.warns(UserWarning, match="outside the training box"):
        run = surrogate_sensitivity(s, load_priors("definity_full"), (0.2, 1.6), N=256, num_points=10)
    r = run.result
    assert r.names == ("ka", "kb", "b1", "b2", "a3", "a4")
    # S1 <= ST up to the bootstrap error, and both sum sensibly
    assert np.all(r.S1_mean <= r.ST_mean + 3 * (r.S1_conf_mean + r.ST_conf_mean))
    assert 0.5 < r.S1_mean.sum() < 1.3


def test_bad_inputs(tiny_compression_surrogate, tmp_path):
    runner = CliRunner()
    result = runner.invoke(app, ["sensitivity", "--surrogate", str(tmp_path / "none.npz"), "--curve", "definity-2.1"])
    assert result.exit_code == 1 and "surrogate file not found" in result.output
    result = runner.invoke(app, ["sensitivity", "--surrogate", str(tiny_compression_surrogate), "--curve",
                                 "sonovue-3.2"])
    assert result.exit_code == 1 and "cannot explain the indentation curve" in result.output
    s = load(tiny_compression_surrogate)
    with pytest.raises(ValueError, match="power of two"):
        surrogate_sensitivity(s, load_priors("definity_full"), (0.2, 1.6), N=1000)
    with pytest.raises(ValueError, match="must lie inside the surrogate's loading range"):
        surrogate_sensitivity(s, load_priors("definity_full"), (0.2, 5.0), N=256)
