"""Campaign TOML files (shipped and user-written) and the `bubblecal sim campaign` / `campaign-status` commands."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from bubblecal.workflows.campaign import (
    CampaignFileError,
    available_campaigns,
    load_campaign_config,
    load_campaign_file,
)
from bubblecal.workflows.cli import app

runner = CliRunner()

GOOD = """
[campaign]
name = "tiny"
protocol = "compression"
diameter_um = 2.1
tier = "quasistatic"
n_samples = 2
seed = 5
replicas_per_task = 2
device = "cpu"
subdivisions = 1
loading_grid = [0.0, 0.12, 0.24]
store = "stores/tiny"

[ranges]
priors = "definity_full"
kb = 500.0

[tier]
max_steps = 4000

[dask]
scheduler_address = "inline"
"""


def write(tmp_path, text=GOOD, name="c.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def plain(text: str) -> str:
    return re.sub(r"\s+", " ", text)


def test_shipped_campaigns_are_valid():
    names = available_campaigns()
    mech = [n for n in names if "ringdown" not in n]
    mirheo = [n for n in mech if n.endswith("_mirheo")]
    assert len(mech) == 9 and {"definity_ringdown", "sonovue_ringdown"} <= set(names)
    # the Mirheo-convention twins of the three indentation sets: same box, seed and grid, another design
    assert sorted(mirheo) == [f"sonovue_indentation_{d}um_mirheo" for d in ("3.2", "3.4", "5.8")]
    for n in mirheo:
        twin, c = load_campaign_config(n[: -len("_mirheo")]), load_campaign_config(n)
        assert c.tier_settings["indentation_convention"] == "mirheo" and "indentation_convention" not in twin.tier_settings
        assert (c.seed, c.n_samples, c.ranges, c.grid_for(c.diameter_um)) == (
            twin.seed, twin.n_samples, twin.ranges, twin.grid_for(twin.diameter_um))
        assert c.design_hash() != twin.design_hash() and c.replicas_per_task == c.n_samples  # one refill pool
    for n in mech:
        if n in mirheo:
            continue
        c = load_campaign_config(n)
        # compression spans the union of the three workflow boxes (1.5x the full box's ka x kb area): 7,500 points
        assert c.n_samples == (7500 if c.protocol == "compression" else 6000) and c.design == "lhs"
        # the fastest tier that passed the 3 % gate against explicit at this diameter (benchmarks/RESULTS.md)
        assert c.tier == "quasistatic" and c.tier_settings["max_replicas"] == 500
        design = c.design_dict()["tier_settings"]
        assert "max_replicas" not in design and design["dtype"] == "float64"  # scheduling is not design
        if c.protocol == "compression":  # the thermal plate contact passed the gate at 2.1 / 3.0 um
            assert design == {"dtype": "float64", "thermal_contact": True}
        elif c.diameter_um == 5.8:  # validated at subdivision 4 against the explicit tier at 5
            assert design == {"dtype": "float64", "subdivisions": 4}
        else:
            assert design == {"dtype": "float64"}
        agent = "definity" if c.protocol == "compression" else "sonovue"
        assert n.startswith(agent) and f"{c.diameter_um}um" in n
        assert c.ranges["ka"] == ((3500.0, 34000.0) if agent == "definity" else (558.0, 558000.0))
        if agent == "definity":  # reduced-acoustic reaches kb 1,100, the full box's b1 b2 a3 a4 are kept
            assert c.ranges["kb"] == (100.0, 1100.0) and c.ranges["a3"] == (-2.5, 3.0)
        assert len(c.free_names) == 6
    d = load_campaign_config("definity_ringdown")
    assert d.diameters[0] == 4.68 and d.diameters[-1] == 11.2 and len(d.diameters) == 14 and d.n_design == 14 * 28
    assert d.ranges["kb"] == (389.23, 389.23) and d.free_names == ("ka",) and d.fixed["b1"] == 0.0
    assert d.subdivisions == 4 and d.tier == "implicit"  # s4 vs s5 at 5.18 um: 0.18 % median in f_res
    s = load_campaign_config("sonovue_ringdown")
    assert s.diameters == (2.6, 3.2, 4.0) and s.ranges["kb"] == (7850.29, 7850.29) and s.n_samples == 28
    assert load_campaign_file("definity_ringdown").config.store_path.name == "definity_ringdown.store"


def test_relative_store_and_priors_box(tmp_path):
    f = load_campaign_file(write(tmp_path))
    c = f.config
    assert c.store_path == tmp_path / "stores" / "tiny" and f.scheduler_address == "inline"
    assert c.ranges["ka"] == (5580.0, 27900.0) and c.ranges["kb"] == (500.0, 500.0)  # override fixes kb
    assert c.tier_settings == {"max_steps": 4000}


def test_priors_list_gives_the_union_box(tmp_path):
    # the reduced-acoustic box is wider in ka and kb than the full one; b1..a4 come from the full box only
    text = GOOD.replace('priors = "definity_full"\nkb = 500.0',
                        'priors = ["definity_full", "definity_reduced_acoustic"]')
    f = load_campaign_file(write(tmp_path, text))
    r = f.config.ranges
    assert r["ka"] == (3500.0, 34000.0) and r["kb"] == (100.0, 1100.0)
    assert r["b1"] == (0.0, 3.0) and r["a3"] == (-2.5, 3.0)
    assert f.priors == "definity_full, definity_reduced_acoustic"


@pytest.mark.parametrize("old, new, key, allowed", [
    ('protocol = "compression"', 'protocol = "shear"', "[campaign].protocol", "compression, indentation, ringdown"),
    ("n_samples = 2", "n_samples = 0", "[campaign].n_samples", ">= 1"),
    ("n_samples = 2", "n_samples = 2.5", "[campaign].n_samples", ">= 1"),
    ("diameter_um = 2.1", "diameter_um = 99.0", "[campaign].diameter_um", "[0.5, 20]"),
    ("diameter_um = 2.1", "diameter_um = [2.1, 2.9]", "[campaign].diameter_um", "only with design = 'grid'"),
    ('device = "cpu"', 'device = "tpu"', "[campaign].device", "'cpu', 'cuda' or 'cuda:N'"),
    ('tier = "quasistatic"', 'tier = "fast"', "[campaign].tier", "explicit, implicit, quasistatic"),
    ("seed = 5", "seed = -1", "[campaign].seed", "[0, 2^63)"),
    ("seed = 5", "seeds = 5", "[campaign].seeds", "allowed: name, protocol"),
    ("kb = 500.0", "kb = [900.0, 100.0]", "[ranges].kb", "lo <= hi"),
    ("kb = 500.0", 'kb = "soft"', "[ranges].kb", "[lo, hi]"),
    ("kb = 500.0", "mu = 3.0", "[ranges].mu", "allowed: priors, ka, kb"),
    ('priors = "definity_full"', 'priors = "nosuch_full"', "[ranges].priors", "shipped workflows: definity_full"),
    ('priors = "definity_full"', "", "[ranges].ka", "missing"),
    ('priors = "definity_full"', "priors = []", "[ranges].priors", "list of them (union box)"),
    ('priors = "definity_full"', 'priors = ["definity_full", "nosuch"]', "[ranges].priors", "'nosuch'"),
    ("max_steps = 4000", "max_step = 4000", "[tier].max_step", "allowed for tier 'quasistatic'"),
    ("max_steps = 4000", 'indentation_convention = "published"', "[tier].indentation_convention",
     "['bubblecal-v1', 'mirheo']"),
    ('scheduler_address = "inline"', "n_workers = 0", "[dask].n_workers", ">= 1"),
    ('scheduler_address = "inline"', "threads = 2", "[dask].threads", "allowed: scheduler_address, n_workers"),
    ("[dask]", "[cluster]", "[cluster]", "allowed: campaign, ranges, tier, dask"),
    ("loading_grid = [0.0, 0.12, 0.24]", "loading_grid = [0.0, 0.2, 0.1]", "[campaign].loading_grid",
     "strictly increasing"),
])
def test_config_file_errors_name_file_field_and_allowed(tmp_path, old, new, key, allowed):
    assert old in GOOD
    path = write(tmp_path, GOOD.replace(old, new))
    with pytest.raises(CampaignFileError) as info:
        load_campaign_config(path)
    msg = str(info.value)
    assert str(path) in msg and f"{key}:" in msg and allowed in msg, msg


def test_missing_sections_and_bad_toml(tmp_path):
    with pytest.raises(CampaignFileError, match=r"\[ranges\]: missing section"):
        load_campaign_config(write(tmp_path, GOOD.split("[ranges]")[0]))
    with pytest.raises(CampaignFileError, match=r"\[campaign\]: missing section"):
        load_campaign_config(write(tmp_path, "[ranges]\nka = 1.0\n"))
    with pytest.raises(CampaignFileError, match="not valid TOML"):
        load_campaign_config(write(tmp_path, "[campaign\n"))
    with pytest.raises(CampaignFileError, match="shipped: definity_compression_2.1um"):
        load_campaign_config("no_such_campaign")


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
    assert res.exit_code == 1 and "shipped: definity_compression_2.1um" in plain(res.output)

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
