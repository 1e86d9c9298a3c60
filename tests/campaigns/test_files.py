"""Campaign TOML files: the shipped ones are valid, relative stores, priors boxes, errors name file and field."""

from __future__ import annotations

from pathlib import Path

import pytest

from bubblecal.campaigns import (
    CampaignFileError,
    available_campaigns,
    load_campaign_config,
    load_campaign_file,
)

#: a tiny valid campaign file (shared with tests/workflows/test_campaign_cli.py)
GOOD = (Path(__file__).parent / "tiny_campaign.toml").read_text()


def write(tmp_path, text=GOOD, name="c.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_shipped_campaigns_are_valid():
    names = available_campaigns()
    # the designs over the diameter are checked in test_diameters.py
    mech = [n for n in names if "ringdown" not in n and "1.5-8um" not in n]
    mirheo = [n for n in mech if n.endswith("_mirheo")]
    assert len(mech) == 9 and {"definity_ringdown", "sonovue_ringdown"} <= set(names)
    # the Mirheo-convention twins of the three indentation sets: same box, seed and grid, another design
    assert sorted(mirheo) == [f"sonovue_indentation_{d}um_mirheo" for d in ("3.2", "3.4", "5.8")]
    for n in mirheo:
        twin, c = load_campaign_config(n[: -len("_mirheo")]), load_campaign_config(n)
        assert (c.tier_settings["indentation_convention"] == "mirheo"
                and "indentation_convention" not in twin.tier_settings)
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
    ("max_steps = 4000", 'minimizer = "lbfgs"', "[tier].minimizer", "('fire', 'cg')"),
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


def test_the_minimizer_is_part_of_the_design(tmp_path):
    # the CG's curves differ from FIRE's within the force tolerance: a store of one refuses a config of the other
    fire = load_campaign_config(write(tmp_path, GOOD))
    cg = load_campaign_config(write(tmp_path, GOOD.replace("max_steps = 4000", 'max_steps = 4000\nminimizer = "cg"')))
    assert cg.tier_settings["minimizer"] == "cg" and cg.design_hash() != fire.design_hash()
    # how often the host reads the status is scheduling only: the same design
    often = load_campaign_config(write(tmp_path, GOOD.replace("max_steps = 4000", "max_steps = 4000\nsync_every = 10")))
    assert often.tier_settings["sync_every"] == 10 and often.design_hash() == fire.design_hash()


def test_missing_sections_and_bad_toml(tmp_path):
    with pytest.raises(CampaignFileError, match=r"\[ranges\]: missing section"):
        load_campaign_config(write(tmp_path, GOOD.split("[ranges]")[0]))
    with pytest.raises(CampaignFileError, match=r"\[campaign\]: missing section"):
        load_campaign_config(write(tmp_path, "[ranges]\nka = 1.0\n"))
    with pytest.raises(CampaignFileError, match="not valid TOML"):
        load_campaign_config(write(tmp_path, "[campaign\n"))
    with pytest.raises(CampaignFileError, match="shipped: .*definity_compression_2.1um"):
        load_campaign_config("no_such_campaign")
