"""The `bubblecal sim campaign` / `campaign-status` commands over campaign files (shipped and user-written)."""

from __future__ import annotations

import json
import re
from pathlib import Path

from typer.testing import CliRunner

from bubblecal.workflows.cli import app

runner = CliRunner()

#: a tiny valid campaign file (shared with tests/campaigns/test_files.py)
GOOD = (Path(__file__).resolve().parents[1] / "campaigns" / "tiny_campaign.toml").read_text()


def write(tmp_path, text=GOOD, name="c.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def plain(text: str) -> str:
    return re.sub(r"\s+", " ", text)


def test_cli_dry_run_run_resume_and_status(tmp_path):
    path = write(tmp_path)
    res = runner.invoke(app, ["sim", "campaign", str(path), "--dry-run"])
    assert res.exit_code == 0, res.output
    out = plain(res.output)
    assert "design points │ 2" in out and "done / pending │ 0 / 2" in out and "DPD 2-D modulus" in out
    assert "nothing simulated" in out and not (tmp_path / "stores" / "tiny").exists()

    res = runner.invoke(app, ["sim", "campaign", str(path), "--limit", "1", "--no-progress"])
    assert res.exit_code == 0, res.output
    summary = json.loads(res.output.strip().splitlines()[-1])
    assert summary["n_written"] == 1 and summary["counts"]["ok"] == 1 and summary["n_remaining"] == 1

    res = runner.invoke(app, ["sim", "campaign-status", str(tmp_path / "stores" / "tiny")])
    assert res.exit_code == 0, res.output
    status = json.loads(res.output.strip().splitlines()[-1])
    assert status["counts"]["ok"] == 1 and status["n_pending"] == 1 and status["name"] == "tiny"
    # --config: 'pending' follows that config's retry statuses (here one that also retries 'unstable')
    retry = write(tmp_path, GOOD.replace("n_samples = 2", 'n_samples = 2\nretry_statuses = ["failed", "unstable"]'),
                  name="retry.toml")
    res = runner.invoke(app, ["sim", "campaign-status", str(tmp_path / "stores" / "tiny"), "--config", str(retry)])
    assert res.exit_code == 0, res.output
    assert "failed/unstable" in plain(res.output) and json.loads(res.output.strip().splitlines()[-1])["n_pending"] == 1
    res = runner.invoke(app, ["sim", "campaign-status", str(tmp_path / "stores" / "tiny"), "--config", "nosuch"])
    out = plain(res.output)
    assert res.exit_code == 1 and "definity_compression_2.1um, " in out and "shipped: " in out

    res = runner.invoke(app, ["sim", "campaign", str(path), "--no-progress"])
    assert res.exit_code == 0, res.output
    summary = json.loads(res.output.strip().splitlines()[-1])
    assert summary["n_done_before"] == 1 and summary["n_written"] == 1 and summary["store_counts"]["ok"] == 2
    res = runner.invoke(app, ["sim", "campaign", str(path), "--dry-run"])
    assert "done / pending │ 2 / 0" in plain(res.output)
    # a bare .jsonl copy of the records (e.g. a decompressed shipped set) resumes the same design
    bare = tmp_path / "copy.jsonl"
    bare.write_bytes((tmp_path / "stores" / "tiny" / "records.jsonl").read_bytes())
    res = runner.invoke(app, ["sim", "campaign", str(path), "--dry-run", "--store", str(bare)])
    assert "done / pending │ 2 / 0" in plain(res.output) and "(exists)" in plain(res.output)


def test_cli_notes_an_indentation_campaign_without_a_convention():
    for name, noted in (("sonovue_indentation_3.2um", True), ("sonovue_indentation_3.2um_mirheo", False),
                        ("definity_compression_2.1um", False)):
        res = runner.invoke(app, ["sim", "campaign", name, "--dry-run"])
        assert res.exit_code == 0, res.output
        out = plain(res.output)
        assert ("[tier].indentation_convention is not set" in out) == noted, (name, out[:300])
        if noted:
            assert "tiers' default 'bubblecal-v1'" in out and 'indentation_convention = "mirheo" under [tier]' in out


def test_cli_errors_exit_1(tmp_path):
    res = runner.invoke(app, ["sim", "campaign", str(write(tmp_path, GOOD.replace("n_samples = 2", "n_samples = 0")))])
    assert res.exit_code == 1 and "[campaign].n_samples" in res.output
    res = runner.invoke(app, ["sim", "campaign", str(write(tmp_path)), "--device", "gpu", "--dry-run"])
    assert res.exit_code == 1 and "--device" in res.output
    res = runner.invoke(app, ["sim", "campaign-status", str(tmp_path / "nothing")])
    assert res.exit_code == 1 and "no such campaign store" in res.output
    res = runner.invoke(app, ["sim", "campaign", "--help"])
    assert res.exit_code == 0 and "SLURMCluster" in plain(res.output)


def test_cli_tier_setting_overrides_the_file_and_is_validated(tmp_path):
    """--tier-setting KEY=VALUE (a TOML value) sets a [tier] key on top of the file's: a new design (the store of the
    file's design refuses it), validated like the file's keys with the offending one named."""
    path = write(tmp_path)
    res = runner.invoke(app, ["sim", "campaign", str(path), "--limit", "1", "--no-progress"])
    assert res.exit_code == 0, res.output
    store = tmp_path / "stores" / "tiny"
    res = runner.invoke(app, ["sim", "campaign", str(path), "--no-progress", "--tier-setting", "ftol=0.01"])
    assert res.exit_code == 1 and "another design" in plain(res.output)
    res = runner.invoke(app, ["sim", "campaign", str(path), "--no-progress", "--tier-setting", "ftol=0.01",
                              "--store", str(tmp_path / "tight")])
    assert res.exit_code == 0, res.output
    assert json.loads(res.output.strip().splitlines()[-1])["counts"]["ok"] == 2
    settings = json.loads((tmp_path / "tight" / "store.json").read_text())["meta"]["campaign"]["tier_settings"]
    assert settings["ftol"] == 0.01
    assert store.exists()
    bad = runner.invoke(app, ["sim", "campaign", str(path), "--dry-run", "--tier-setting", "schedule=sideways"])
    out = plain(bad.output)
    assert bad.exit_code == 1 and "[tier].schedule" in out and "--tier-setting schedule" in out and "c.toml" in out
    res = runner.invoke(app, ["sim", "campaign", str(path), "--dry-run", "--tier-setting", "ftol"])
    assert res.exit_code == 1 and "expected KEY=VALUE" in plain(res.output)


def test_help_and_dry_run_keep_bracketed_words():
    out = plain(runner.invoke(app, ["sim", "campaign", "--help"]).output)
    for word in ("[dask]", "[campaign].device", "[campaign].store", "[um]", "[tier],"):
        assert word in out, word
    res = runner.invoke(app, ["sim", "campaign", "definity_compression_2.1um", "--dry-run"])
    assert res.exit_code == 0 and "[um]" in plain(res.output)
