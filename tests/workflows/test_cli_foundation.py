"""The command line of the foundation: --help/--version, info, data show/check, priors show/check."""

import re

from typer.testing import CliRunner

from bubblecal import __version__
from bubblecal.workflows.cli import app

runner = CliRunner()


def _run(*args):
    result = runner.invoke(app, list(args), env={"COLUMNS": "200"})
    return result.exit_code, result.output


def test_help_and_version():
    code, out = _run("--help")
    assert code == 0 and "data" in out and "priors" in out
    code, out = _run("--version")
    assert code == 0 and out.strip() == f"bubblecal {__version__}"


def test_the_command_process_ends_with_the_commands_status_and_all_of_its_output():
    """``python -m bubblecal.workflows.cli`` (the console script's ``run``): status 0 / 2 / 1 as ``main`` raises
    them, and what the command printed reaches the pipe although the process skips the interpreter's teardown."""
    import subprocess
    import sys

    def command(*args):
        proc = subprocess.run([sys.executable, "-m", "bubblecal.workflows.cli", *args], capture_output=True,
                              text=True, env={**__import__("os").environ, "COLUMNS": "200"}, timeout=300)
        return proc.returncode, proc.stdout + proc.stderr

    code, out = command("--version")
    assert code == 0 and out.strip() == f"bubblecal {__version__}"
    code, out = command("no-such-command")
    assert code == 2 and "No such command" in out
    code, out = command("calibrate", "--population", "1")
    assert code == 1 and "--population" in out and "got 1" in out


def test_info():
    code, out = _run("info")
    assert code == 0
    assert "1 nN = 446.698" in out and "definity_reduced_acoustic" in out and "acoustic observations: 17" in out


def test_data_show():
    code, out = _run("data", "show")
    assert code == 0
    assert "displacement [nm]" in out and "force [nN]" in out and "24/27" in out and "20/46" in out
    assert "f_res [MHz]" in out
    code, out = _run("data", "show", "definity-2.1")
    assert code == 0 and "force [DPD force]" in out and "288.41" in out
    code, out = _run("data", "show", "nothing")
    assert code == 1 and "unknown curve 'nothing'" in out


def test_data_check(tmp_path):
    good = tmp_path / "good.csv"
    good.write_text("force_nN,displacement_nm\n1,10\n2,20\n3,31\n")
    code, out = _run("data", "check", str(good), "--kind", "indentation", "--units", "physical")
    assert code == 0 and "valid indentation curve" in out
    bad = tmp_path / "bad.csv"
    bad.write_text("force_nN,displacement_nm\n1,10\n2,x\n3,31\n")
    code, out = _run("data", "check", str(bad), "--kind", "indentation", "--units", "physical")
    assert code == 1
    assert "bad.csv" in out and re.search(r"row 2 \(line 3\), column 'displacement_nm'", out)
    code, out = _run("data", "check", str(good), "--kind", "indentation", "--units", "furlongs")
    assert code == 2 and "'furlongs' is not one of 'dpd', 'physical'" in out


def test_priors_show_and_check(tmp_path):
    code, out = _run("priors", "show", "definity_reduced_acoustic")
    assert code == 0
    for text in ("prior range [DPD]", "population mean m range [DPD]", "E 6.27 – 60.9 MPa", "sigma_ac",
                 "fixed = 0"):
        assert text in out
    code, out = _run("priors", "show")
    assert code == 0 and "sonovue_full" in out
    bad = tmp_path / "bad.toml"
    bad.write_text('[workflow]\nagent = "definity"\nsetup = "compression"\nshell = "full"\nacoustic = false\n'
                   "[parameters.ka]\nprior = [10.0, 1.0]\n")
    code, out = _run("priors", "check", str(bad))
    assert code == 1 and "bad.toml" in out and "parameters.ka.prior: lo (10) must be smaller than hi (1)" in out
    assert "parameters.kb: missing" in out
