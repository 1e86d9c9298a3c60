"""`bubblecal compare`: one curve sampled by TMCMC and NUTS, agreement report; bad inputs fail early."""

import json

import arviz as az
import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from bubblecal.data import load_reference
from bubblecal.workflows.cli_compare import register

app = typer.Typer()
register(app)
app.command("noop")(lambda: None)  # a second command keeps typer in multi-command mode


def test_compare_runs_both_samplers_and_writes_report(tiny_compression_surrogate, tmp_path):
    out = tmp_path / "cmp"
    result = CliRunner().invoke(app, ["compare", "--curve", "definity-2.1", "--surrogate",
                                      str(tiny_compression_surrogate), "--particles", "300", "--replicas", "2",
                                      "--nuts-samples", "100", "--nuts-chains", "2", "--seed", "1",
                                      "--out", str(out)])
    assert result.exit_code == 0, result.output  # the verdict is information, not an error
    text = result.output
    assert "log Z =" in text and "SE over 2 replicas" in text and "stages" in text
    assert "r_hat" in text and "divergences" in text and "verdict:" in text
    # the reduced shell evaluates b1 = b2 = a4 = 0, outside the synthetic training box: warned
    assert "exceeds the surrogate's training box" in text
    report = json.loads((out / "definity_compression_2.1um_compare.json").read_text())
    assert report["priors"] == "definity_reduced" and report["tmcmc"]["status"] == "converged"
    assert np.isfinite(report["tmcmc"]["log_evidence"]) and report["tmcmc"]["log_evidence_se"] > 0
    assert len(report["tmcmc"]["log_evidences"]) == 2 and report["tmcmc"]["stages"] >= 1
    assert [row["name"] for row in report["comparison"]["table"]] == ["ka", "kb", "d0", "sigma"]
    assert isinstance(report["comparison"]["passed"], bool)
    tm = az.from_netcdf(out / "definity_compression_2.1um_tmcmc.nc")
    nuts = az.from_netcdf(out / "definity_compression_2.1um_nuts.nc")
    assert tm.posterior["ka"].shape == (2, 300)  # one chain per TMCMC replica
    assert "log_likelihood" in tm.groups() and "lp" in tm.sample_stats
    assert nuts.posterior["ka"].shape == (2, 100)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--curve", "definity-9.9"], "unknown curve"),
        (["--curve", "sonovue-3.2"], "cannot explain the indentation curve"),
        (["--curve", "definity-2.1", "--priors", "sonovue_reduced"], "are for indentation"),
        ([], "exactly one of --curve"),
        (["--curve", "definity-2.1", "--particles", "1"], "--particles must be >= 2"),
    ],
)
def test_bad_inputs_fail_before_sampling(tiny_compression_surrogate, args, message):
    result = CliRunner().invoke(app, ["compare", "--surrogate", str(tiny_compression_surrogate), *args])
    assert result.exit_code == 1 and message in result.output, result.output


def test_bad_files_fail_before_sampling(tiny_compression_surrogate, tmp_path):
    runner = CliRunner()
    result = runner.invoke(app, ["compare", "--curve", "definity-2.1", "--surrogate", str(tmp_path / "none.npz")])
    assert result.exit_code == 1 and "surrogate file not found" in result.output
    junk = tmp_path / "junk.npz"
    junk.write_text("not a surrogate")
    result = runner.invoke(app, ["compare", "--curve", "definity-2.1", "--surrogate", str(junk)])
    assert result.exit_code == 1 and "not a surrogate file" in result.output
    broken = tmp_path / "broken.toml"
    broken.write_text("[workflow]\nagent = 'definity'\n")
    result = runner.invoke(app, ["compare", "--curve", "definity-2.1", "--surrogate", str(tiny_compression_surrogate),
                                 "--priors", str(broken)])
    # every problem listed, literally (rich must not eat '[fixed]' as a style tag)
    assert result.exit_code == 1 and "list it under [parameters.ka] or [fixed]" in result.output, result.output
    # a user CSV: loaded and validated, then rejected for the wrong kind of surrogate / priors
    curve = load_reference("definity", 2.1)
    csv = tmp_path / "mine.csv"
    csv.write_text("displacement_dpd,force_dpd\n" + "".join(f"{x:.17g},{y:.17g}\n" for x, y in zip(curve.x, curve.y,
                                                                                            strict=True)))
    result = runner.invoke(app, ["compare", "--data", str(csv), "--kind", "compression", "--surrogate",
                                 str(tiny_compression_surrogate), "--priors", "sonovue_reduced"])
    assert result.exit_code == 1 and "the curve mine is compression" in result.output, result.output
    result = runner.invoke(app, ["compare", "--data", str(csv), "--surrogate", str(tiny_compression_surrogate)])
    assert result.exit_code == 1 and "--data needs --kind" in result.output
    bad = tmp_path / "bad.csv"
    bad.write_text("displacement_dpd,force_dpd\n0.1,1\n0.05,2\n")
    result = runner.invoke(app, ["compare", "--data", str(bad), "--kind", "compression", "--surrogate",
                                 str(tiny_compression_surrogate)])
    assert result.exit_code == 1 and "bad.csv" in result.output
