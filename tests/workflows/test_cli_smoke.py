"""CLI smoke matrix: each command with bad options and unusable paths -> the exit status of the convention
(1 bad input or failed run, 2 usage error), a message naming the path or option, and never a traceback."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from bubblecal.workflows.cli import app

runner = CliRunner()
ROOT = Path(__file__).resolve().parents[2]
TINY = ROOT / "tests" / "campaigns" / "tiny_campaign.toml"
NPZ = sorted((ROOT / "surrogates" / "bundle").glob("*.npz"))[0]


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("smoke")
    out = {"dir": d / "folder", "missing": d / "missing.csv", "file": d / "a_file"}
    out["dir"].mkdir()
    out["file"].write_text("x")
    for name, text in {"big.csv": "displacement_dpd,force_dpd\n0.1,1\n0.2,1e300\n0.3,5\n",
                       "zero.csv": "displacement_dpd,force_dpd\n0.1,0\n0.2,0\n0.3,0\n",
                       "semi.csv": "displacement_dpd;force_dpd\n0.1;1\n0.2;2\n0.3;5\n",
                       "trunc.json": '{"format": "bubblecal-acoustic-surr'}.items():
        (d / name).write_text(text)
        out[name.replace(".csv", "").replace(".", "_")] = d / name
    (d / "latin1.toml").write_bytes(b"[workflow]\nagent = '\xe9'\n")
    out["latin1"] = d / "latin1.toml"
    (d / "trunc.npz").write_bytes(NPZ.read_bytes()[:600])
    out["trunc_npz"] = d / "trunc.npz"
    return out


# (arguments with {placeholders}, exit status, text the output must contain)
MATRIX = [
    (["--help"], 0, "Exit status of every command"),
    (["data", "check", "{dir}", "--kind", "compression"], 1, "is a folder"),
    (["data", "check", "{missing}", "--kind", "compression"], 1, "file not found"),
    (["data", "check", "{big}", "--kind", "compression"], 1, "plausible range [0, 10000] nN"),
    (["data", "check", "{zero}", "--kind", "compression"], 1, "carries no signal"),
    (["data", "check", "{semi}", "--kind", "compression"], 1, "semicolon-separated"),
    (["data", "check", "{big}", "--kind", "bogus"], 2, "'bogus' is not one of 'compression', 'indentation'"),
    (["data", "check", "{big}", "--kind", "compression", "--units", "si"], 2, "'si' is not one of 'dpd', 'physical'"),
    (["data", "check", "{big}"], 2, "--kind"),
    (["data", "show", "nothing"], 1, "unknown curve 'nothing'"),
    (["priors", "check", "{dir}"], 1, "is a folder"),
    (["priors", "check", "{latin1}"], 1, "not UTF-8"),
    (["priors", "check", "{missing}"], 1, "no such priors file or shipped workflow"),
    (["surrogates", "info", "{trunc_json}"], 1, "not valid JSON"),
    (["surrogates", "info", "{trunc_npz}"], 1, "trunc.npz"),
    (["surrogates", "info", "{missing}"], 1, "missing.csv"),
    (["sensitivity", "--surrogate", "{trunc_npz}", "--curve", "definity-2.1", "--out", "{dir}"], 1, "trunc.npz"),
    (["sensitivity", "--surrogate", "{missing}", "--curve", "definity-2.1"], 1, "surrogate file not found"),
    (["sim", "campaign", str(TINY), "--store", "{dir}/s1", "--scheduler", "bogus"], 1,
     "--scheduler: 'bogus' is not a scheduler address"),
    (["sim", "campaign", str(TINY), "--store", "{dir}/s2", "--scheduler", "tcp://127.0.0.1:9",
      "--connect-timeout", "0.5"], 1, "cannot reach the Dask scheduler at tcp://127.0.0.1:9"),
    (["sim", "campaign", "{latin1}"], 1, "not UTF-8"),
    (["sim", "campaign", "no_such_campaign"], 1, "no_such_campaign"),
    (["sim", "campaign-status", "{missing}"], 1, "no such campaign store"),
    (["calibrate", "--seed", "-1"], 1, "--seed"),
    (["calibrate", "--chunk-size", "0"], 1, "--chunk-size"),
    (["calibrate", "--population", "1e23"], 2, "--population"),
    (["calibrate", "--agent", "definity", "--curve", "sonovue_indentation_3.2um"], 1,
     "sonovue_indentation_3.2um (a sonovue curve): not a curve of --agent definity"),
    (["calibrate", "--out", "{file}"], 1, "exists and is not a folder"),
    (["calibrate", "--out", "{file}/sub"], 1, "is a file, so the folder cannot be made"),
    (["calibrate", "--data-dir", "{missing}"], 1, "not a directory"),
    (["calibrate", "--no-such-option"], 2, "No such option"),
    # closed sets of values: a usage error naming the allowed values, before any work
    (["calibrate", "--agent", "optison"], 2, "'optison' is not one of 'definity', 'sonovue', 'all'"),
    (["calibrate", "--workflow", "medium"], 2, "'medium' is not one of 'reduced-acoustic', 'reduced', 'full'"),
    (["calibrate", "--sampler", "hmc"], 2, "'hmc' is not one of 'tmcmc', 'nuts'"),
    (["calibrate", "--device", "tpu"], 2, "'tpu' is not one of 'cpu', 'gpu'"),
    (["calibrate", "--phase3", "joint"], 2, "'joint' is not one of 'published', 'exact'"),
    (["evidence", "--device", "tpu"], 2, "'tpu' is not one of 'cpu', 'gpu'"),
    (["confirm", "{dir}", "--tier", "fast"], 2, "'fast' is not one of 'explicit', 'implicit', 'quasistatic'"),
    (["compare", "--data", "{big}", "--kind", "stretch", "--surrogate", str(NPZ)], 2,
     "'stretch' is not one of 'compression', 'indentation'"),
    (["sim", "ringdown", "--agent", "optison", "--diameter", "2", "--out", "{dir}"], 2,
     "'optison' is not one of 'definity', 'sonovue'"),
    (["sim", "ringdown", "--agent", "definity", "--tier", "quasistatic", "--diameter", "2", "--out", "{dir}"], 2,
     "'quasistatic' is not one of 'explicit', 'implicit'"),
    (["surrogates", "train", "{big}", "--setup", "stretch", "--out", "{dir}"], 2,
     "'stretch' is not one of 'compression', 'indentation'"),
    (["surrogates", "synthetic", "{dir}/s.csv", "--setup", "stretch"], 2,
     "'stretch' is not one of 'compression', 'indentation'"),
    (["surrogates", "acoustic", "{dir}", "--agent", "optison", "--out", "{dir}/a.json"], 2,
     "'optison' is not one of 'definity', 'sonovue'"),
]


@pytest.mark.parametrize(("args", "code", "needle"), MATRIX, ids=[" ".join(a[:3]) for a, _, _ in MATRIX])
def test_cli_matrix(files, args, code, needle):
    argv = [a.format(**files) if "{" in a else a for a in args]
    result = runner.invoke(app, argv, env={"COLUMNS": "250"})
    output = " ".join(result.output.split())  # rich wraps long messages
    assert result.exit_code == code, output
    assert needle in output, output
    assert "Traceback" not in output
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(result.exception)


# (command, option, the values its --help must list)
CHOICES = [
    (["calibrate"], "--agent", "<definity|sonovue|all>"),
    (["calibrate"], "--workflow", "<reduced-acoustic|reduced|full>"),
    (["calibrate"], "--sampler", "<tmcmc|nuts>"),
    (["calibrate"], "--device", "<cpu|gpu>"),
    (["calibrate"], "--phase3", "<published|exact>"),
    (["calibrate"], "--surrogates", "<over-diameter|per-diameter>"),
    (["calibrate"], "--networks", "<fast|accurate>"),
    (["evidence"], "--surrogates", "<over-diameter|per-diameter>"),
    (["evidence"], "--agent", "<definity|sonovue|all>"),
    (["confirm"], "--tier", "<explicit|implicit|quasistatic>"),
    (["compare"], "--kind", "<compression|indentation>"),
    (["compare"], "--units", "<dpd|physical>"),
    (["data", "check"], "--kind", "<compression|indentation>"),
    (["sim", "ringdown"], "--tier", "<explicit|implicit>"),
    (["surrogates", "train"], "--setup", "<compression|indentation>"),
    (["surrogates", "acoustic"], "--form", "<scale-free|gas|gas-coupled|gas-bending|gas-coupled-bending|"
                                           "liquid-inertia>"),
]


@pytest.mark.parametrize(("command", "option", "values"), CHOICES, ids=[f"{' '.join(c)} {o}" for c, o, _ in CHOICES])
def test_help_lists_the_allowed_values(command, option, values):
    result = runner.invoke(app, [*command, "--help"], env={"COLUMNS": "250"})
    assert result.exit_code == 0, result.output
    line = next(ln for ln in result.output.splitlines() if ln.strip("│ *").startswith(f"{option} "))
    assert values in line, line
