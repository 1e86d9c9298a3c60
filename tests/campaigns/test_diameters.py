"""Designs over a diameter range: levels, balanced hypercube strata, scaled grids, errors naming the field."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bubblecal.campaigns import (
    CampaignConfig,
    CampaignConfigError,
    CampaignFileError,
    design_points,
    diameter_levels,
    fraction_grid,
    load_campaign_config,
    load_campaign_file,
    make_tasks,
)
from bubblecal.data import SHELL_PARAMETERS

BOX = {k: (1.0, 2.0) for k in SHELL_PARAMETERS}
FRACTIONS = (0.0, 0.1, 0.2)


def config(**kw) -> CampaignConfig:
    base = dict(name="d", protocol="compression", diameter_um=None, ranges=BOX, n_samples=100, seed=3,
                diameter_range_um=(1.5, 8.0), diameter_step_um=0.5, loading_fractions=FRACTIONS,
                replicas_per_task=4)
    return CampaignConfig(**{**base, **kw})


def test_levels_are_inclusive_and_rounded():
    assert diameter_levels(1.5, 8.0, 0.5) == tuple(1.5 + 0.5 * i for i in range(14))
    levels = diameter_levels(1.5, 8.0, 0.1)
    assert len(levels) == 66 and levels[0] == 1.5 and levels[-1] == 8.0 and levels[13] == 2.8


@pytest.mark.parametrize("n", [100, 1000, 1003])
def test_each_level_holds_n_over_levels_points(n):
    c = config(n_samples=n)
    design = design_points(c)
    levels, counts = np.unique(design["diameter_um"], return_counts=True)
    assert tuple(levels) == c.diameters
    assert counts.min() == n // 14 and counts.max() == -(-n // 14)
    # the shell parameters are still a Latin hypercube: one point per stratum of every free parameter
    for k in SHELL_PARAMETERS:
        strata = np.floor((design[k] - 1.0) * n).astype(int)
        assert sorted(strata) == list(range(n))
    # the design is a pure function of the config
    again = design_points(config(n_samples=n))
    assert all(np.array_equal(design[k], again[k]) for k in design)


def test_tasks_group_one_level_and_its_grid():
    c = config()
    tasks = make_tasks(c, range(c.n_design))
    assert len(tasks) == c.n_tasks
    design = design_points(c)
    for t in tasks:
        assert all(design["diameter_um"][i] == t.diameter_um for i in t.indices)
        # total displacement = fraction x diameter (4 DPD lengths per um)
        assert t.grid == pytest.approx(tuple(f * 4.0 * t.diameter_um for f in FRACTIONS))
    assert fraction_grid((0.0, 0.2), 2.1) == pytest.approx((0.0, 1.68))  # the published grid's deepest point


def test_old_designs_keep_their_hash():
    c = CampaignConfig(name="x", protocol="compression", diameter_um=2.1, ranges=BOX, n_samples=10)
    assert not {"diameter_range_um", "diameter_step_um", "loading_fractions"} & set(c.design_dict())
    d = config()
    assert d.design_dict()["diameter_range_um"] == [1.5, 8.0] and d.design_dict()["diameter_um"] is None
    assert config(diameter_step_um=0.25).design_hash() != d.design_hash()


@pytest.mark.parametrize("kw, field, words", [
    (dict(diameter_range_um=(1.0, 8.0)), "ranges.diameter_um", "within [1.5, 8]"),
    (dict(diameter_range_um=(3.0, 3.0)), "ranges.diameter_um", "lo < hi"),
    (dict(diameter_step_um=0.3), "diameter_step_um", "whole steps"),
    (dict(diameter_step_um=None), "diameter_step_um", "needs both"),
    (dict(diameter_um=3.0), "diameter_um", "not both"),
    (dict(design="grid"), "ranges.diameter_um", "Latin hypercube"),
    (dict(loading_fractions=None), "loading_fractions", "does not scale"),
    (dict(loading_fractions=None, loading_grid=(0.0, 1.0)), "loading_fractions", "does not scale"),
    (dict(loading_fractions=(0.0, 0.6)), "loading_fractions", "[0, 0.5]"),
    (dict(loading_fractions=(0.2, 0.1)), "loading_fractions", "increasing"),
    (dict(loading_grid=(0.0, 1.0)), "loading_grid", "not both"),
    (dict(protocol="indentation", loading_fractions=None), "loading_grid", "published grids exist"),
    (dict(protocol="indentation"), "loading_fractions", "compression only"),
])
def test_bad_diameter_designs_name_the_field(kw, field, words):
    with pytest.raises(CampaignConfigError) as err:
        config(**kw)
    assert err.value.field == field and words in str(err.value)


def test_campaign_file_errors_name_the_key(tmp_path):
    text = """
[campaign]
name = "d"
protocol = "indentation"
diameter_step_um = 0.5
n_samples = 20
loading_grid = [0.0, 100.0, 200.0]
[ranges]
priors = "sonovue_full"
diameter_um = [1.5, 9.0]
"""
    path = Path(tmp_path) / "d.toml"
    path.write_text(text)
    with pytest.raises(CampaignFileError) as err:
        load_campaign_file(path)
    assert "[ranges].diameter_um" in str(err.value) and str(path) in str(err.value) and "[1.5, 8]" in str(err.value)
    path.write_text(text.replace("9.0", "8.0"))
    c = load_campaign_config(path)
    assert c.diameters[0] == 1.5 and len(c.diameters) == 14 and c.grid_for(4.0) == (0.0, 100.0, 200.0)
    path.write_text(text.replace("diameter_step_um = 0.5\n", ""))
    with pytest.raises(CampaignFileError, match=r"diameter_step_um"):
        load_campaign_file(path)


def test_shipped_diameter_campaigns():
    comp = load_campaign_config("definity_compression_1.5-8um")
    ind = load_campaign_config("sonovue_indentation_1.5-8um_mirheo")
    for c, twin in ((comp, "definity_compression_2.1um"), (ind, "sonovue_indentation_5.8um_mirheo")):
        per_diameter = load_campaign_config(twin)
        assert c.ranges == per_diameter.ranges  # the shell box of the per-diameter sets
        assert c.diameters[0] == 1.5 and c.diameters[-1] == 8.0 and len(c.diameters) == 66
        assert c.n_samples == 33000 and c.subdivisions == 4
        assert c.tier == "quasistatic" and c.design_dict()["tier_settings"]["dtype"] == "float64"
    # compression reaches past the published grid's deepest fraction (1.68 DPD length at 2.1 um)
    assert comp.grid_for(2.1)[-1] >= 1.68 and comp.tier_settings["thermal_contact"] is True
    # indentation forces cover the published grids and the largest measured force (8,227 DPD force)
    assert ind.grid_for(1.5) == ind.grid_for(8.0) and ind.grid_for(3.2)[-1] >= 8227
    assert ind.tier_settings["indentation_convention"] == "mirheo"
    # one task over every level (the tier runs one refill pool per chain length), each curve stored as it finishes
    assert ind.pools_levels and ind.n_tasks == 1 and comp.pools_levels and comp.n_tasks == 1


@pytest.mark.parametrize("protocol", ["indentation", "compression"])
def test_levels_share_one_pool_and_keep_their_curves(tmp_path, protocol):
    pytest.importorskip("warp")
    from bubblecal.campaigns import run_campaign
    from bubblecal.data import CampaignStore
    from bubblecal.sim.tiers import CurveRequest, get_tier

    box = {**{k: (0.0, 0.0) for k in SHELL_PARAMETERS}, "ka": (3000.0, 20000.0), "kb": (100.0, 1000.0)}
    settings = {"max_steps": 3000, "max_replicas": 2}
    # compression: 0.015 D steps make one plate sub-step at 2 um and two at 2.5 and 3 um (two pools)
    loading = (dict(loading_grid=(0.0, 20.0, 40.0)) if protocol == "indentation" else
               dict(loading_fractions=(0.0, 0.015, 0.03)))
    if protocol == "compression":
        settings["thermal_contact"] = True
    c = CampaignConfig(name="pool", protocol=protocol, diameter_um=None, ranges=box, n_samples=6, seed=2,
                       diameter_range_um=(2.0, 3.0), diameter_step_um=0.5, subdivisions=2, tier_settings=settings,
                       replicas_per_task=6, store=str(tmp_path / "s"), **loading)
    assert c.pools_levels and c.n_tasks == 1
    tasks = make_tasks(c, range(6))
    assert len(tasks) == 1 and sorted(set(tasks[0].diameters_um)) == [2.0, 2.5, 3.0]
    run_campaign(c, scheduler_address="inline", progress=False)
    records = {r["sample_id"]: r for r in CampaignStore(c.store_path).read()}
    design = design_points(c)
    tier = get_tier("quasistatic", **settings)
    for d in c.diameters:  # each level alone gives the pooled records' curves, bit for bit
        idx = [i for i in range(6) if design["diameter_um"][i] == d]
        alone = tier.run(CurveRequest(protocol=protocol, diameter_um=d, grid=c.grid_for(d),
                                      params={k: design[k][idx] for k in SHELL_PARAMETERS},
                                      seeds=tuple(int(design["seed"][i]) for i in idx), subdivisions=2))
        for row, i in enumerate(idx):
            rec = records[f"pool-{i:06d}"]
            assert rec["provenance"]["diameter_um"] == d and rec["radius_dpd"] == pytest.approx(2 * d)
            assert rec["status"] == alone.status[row] and rec["provenance"]["streamed"] is True
            np.testing.assert_array_equal(np.asarray(rec["x"], dtype=float), np.asarray(c.grid_for(d)))
            np.testing.assert_array_equal(np.asarray(rec["y"], dtype=float), alone.observable[row])
