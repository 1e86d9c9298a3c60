"""CLI on tidy files: ``data check`` detects the kind by header and lists every problem (exit 1), ``data show FILE``
summarises a tidy file, ``priors template`` writes a TOML that ``priors check`` accepts."""

from __future__ import annotations

import tomllib

from typer.testing import CliRunner

from bubblecal.data import PUBLISHED_AGENT_OF_PROTOCOL, published_tidy_paths
from bubblecal.priors import load_priors
from bubblecal.workflows.cli import app

runner = CliRunner()
CURVES, RESONANCE = published_tidy_paths()
HEADER = "bubble,agent,protocol,diameter_um,displacement_nm,force_nN,retained\n"


def _run(*args):
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    return result.exit_code, result.output


def test_check_published_curves_with_resonance():
    code, out = _run("data", "check", CURVES, "--resonance", RESONANCE)
    assert code == 0, out
    assert "valid tidy curve file (6 bubbles, 2 agents, 169 points, 128 retained)" in " ".join(out.split())
    assert "17 resonance rows" in " ".join(out.split())


def test_check_resonance_alone_and_acoustic_table():
    code, out = _run("data", "check", RESONANCE)
    assert code == 0 and "valid tidy resonance file" in out
    table = CURVES.parent / "acoustic_observations_published.csv"
    code, out = _run("data", "check", table)
    assert code == 0 and "valid acoustic table with 17 rows" in " ".join(out.split())


def test_check_lists_every_problem_with_exit_1(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text(HEADER + "b,lab,squeeze,3,10,0.1,1\nb,lab,squeeze,3,20,1e-9,2\n")
    orphan = tmp_path / "res.csv"
    orphan.write_text("agent,diameter_um,frequency_MHz\nghost,3,2\n")
    code, out = _run("data", "check", bad, "--resonance", orphan)
    flat = " ".join(out.split())
    assert code == 1
    for text in ("unknown protocol 'squeeze'", "'2' must be 0 or 1", "only 1 retained points"):
        assert text in flat, text
    good = tmp_path / "good.csv"
    good.write_text(HEADER + "".join(f"b,lab,compression,3,{x},{x / 100},1\n" for x in (10, 20, 30)))
    code, out = _run("data", "check", good, "--resonance", orphan)
    assert code == 1 and "'ghost' has no curves" in " ".join(out.split())


def test_check_single_curve_still_needs_kind(tmp_path):
    one = tmp_path / "one.csv"
    one.write_text("displacement_dpd,force_dpd\n0.1,100\n0.2,200\n0.3,300\n")
    code, out = _run("data", "check", one)
    assert code == 2 and "--kind" in out
    code, out = _run("data", "check", one, "--kind", "compression")
    assert code == 0 and "valid compression curve" in out


def test_show_tidy_file_and_shipped_data(tmp_path):
    code, out = _run("data", "show", CURVES)
    assert code == 0 and "definity" in out and "sonovue" in out and "total" in out
    code, out = _run("data", "show", RESONANCE)
    assert code == 0 and "resonance rows" in out
    code, out = _run("data", "show", "definity-2.1")
    assert code == 0 and "definity_compression_2.1um" in out
    other = tmp_path / "other.csv"
    other.write_text("a,b\n1,2\n")
    code, out = _run("data", "show", other)
    assert code == 1 and "not a tidy curve file" in " ".join(out.split())


def test_priors_template_is_accepted_by_priors_check(tmp_path):
    for protocol, published in PUBLISHED_AGENT_OF_PROTOCOL.items():
        out_file = tmp_path / f"{protocol}.toml"
        code, out = _run("priors", "template", "--agent", "my lab's \"A\"", "--protocol", protocol,
                         "--workflow", "reduced-acoustic", "--out", out_file)
        assert code == 0, out
        text = out_file.read_text()
        assert "my lab's" in text and "hyper_tau = [lo, hi]" in text
        spec = load_priors(out_file)
        assert spec.agent == published and spec.setup == protocol and spec.acoustic
        assert tomllib.loads(text)["workflow"]["description"].startswith("my lab's \"A\": " + protocol)
        code, out = _run("priors", "check", out_file)
        assert code == 0 and "is valid" in out
    code, out = _run("priors", "template", "--agent", "x", "--protocol", "compression", "--out", out_file)
    assert code == 1 and "--force" in out
    code, out = _run("priors", "template", "--agent", " ", "--protocol", "compression", "--out", tmp_path / "n.toml")
    assert code == 1 and "must be non-empty" in out and not (tmp_path / "n.toml").exists()
