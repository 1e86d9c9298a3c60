"""Campaign configs and designs: validation errors name the field, LHS and grid designs, task chunking, the hash."""

from __future__ import annotations

import numpy as np
import pytest

from bubblecal.campaigns import (
    CampaignConfig,
    CampaignConfigError,
    design_points,
    grid_design,
    lhs_design,
    make_tasks,
    sample_ids,
    sample_seed,
)

BOX = {"ka": (5580.0, 27900.0), "kb": (100.0, 1000.0), "b1": (0.0, 3.0), "b2": (0.0, 10.0), "a3": (-2.5, 3.0),
       "a4": (0.0, 4.0)}


def cfg(tmp_path, **kw) -> CampaignConfig:
    base = dict(name="t", protocol="compression", diameter_um=2.1, ranges=BOX, n_samples=20, seed=7,
                replicas_per_task=3, store=str(tmp_path / "t.store"))
    base.update(kw)
    return CampaignConfig(**base)


# ------------------------------------------------------------------------------------------------
# configuration and design
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("change, field, text", [
    ({"protocol": "shear"}, "protocol", "compression, indentation, ringdown"),
    ({"n_samples": 0}, "n_samples", ">= 1"),
    ({"design": "sobol"}, "design", "lhs, grid"),
    ({"diameter_um": 40.0}, "diameter_um", "[0.5, 20]"),
    ({"diameter_um": (2.1, 2.9)}, "diameter_um", "only with design = 'grid'"),
    ({"ranges": {**BOX, "ka": (10.0, 5.0)}}, "ranges.ka", "lo <= hi"),
    ({"ranges": {**BOX, "ka": (0.0, 5.0)}}, "ranges.ka", "> 0"),
    ({"ranges": {k: v for k, v in BOX.items() if k != "a4"}}, "ranges.a4", "missing"),
    ({"ranges": {**BOX, "mu": (1.0, 2.0)}}, "ranges.mu", "allowed: ka, kb"),
    ({"tier": "fast"}, "tier", "explicit, implicit, quasistatic"),
    ({"device": "gpu"}, "device", "'cpu', 'cuda' or 'cuda:N'"),
    ({"replicas_per_task": 0}, "replicas_per_task", ">= 1"),
    ({"loading_grid": (0.0, 0.5, 0.4)}, "loading_grid", "strictly increasing"),
    ({"protocol": "indentation", "diameter_um": 4.0}, "loading_grid", "give loading_grid explicitly"),
    ({"design": "grid"}, "ranges.kb", "fix every other parameter"),
    ({"retry_statuses": ("ok",)}, "retry_statuses", "choose from"),
])
def test_config_errors_name_the_field(tmp_path, change, field, text):
    with pytest.raises(CampaignConfigError) as info:
        cfg(tmp_path, **change)
    assert info.value.field == field
    assert text in str(info.value)


def test_lhs_design_is_deterministic_stratified_and_in_range(tmp_path):
    box = {**BOX, "kb": (500.0, 500.0)}  # kb fixed
    c = cfg(tmp_path, ranges=box, n_samples=50)
    d1, d2 = lhs_design(c), lhs_design(cfg(tmp_path, ranges=box, n_samples=50))
    for k in BOX:
        np.testing.assert_array_equal(d1[k], d2[k])  # a restart regenerates the same design
    assert np.all(d1["kb"] == 500.0)
    for k in ("ka", "b1", "b2", "a3", "a4"):
        lo, hi = box[k]
        u = (d1[k] - lo) / (hi - lo)
        assert np.all((u >= 0) & (u <= 1))
        assert sorted(np.floor(u * 50).astype(int).tolist()) == list(range(50))  # one point per stratum
    assert not np.array_equal(lhs_design(cfg(tmp_path, ranges=box, n_samples=50, seed=8))["ka"], d1["ka"])
    ids = sample_ids(c)
    assert ids[0] == "t-000000" and ids[-1] == "t-000049"
    seeds = design_points(c)["seed"]
    assert len(set(seeds.tolist())) == 50 and seeds[3] == sample_seed(7, 3) and 0 <= seeds.min()


def test_grid_design_over_diameters_and_tasks(tmp_path):
    fixed = {**{k: (v[0], v[0]) for k, v in BOX.items()}, "ka": (1000.0, 28000.0), "kb": (389.23, 389.23)}
    c = cfg(tmp_path, protocol="ringdown", design="grid", diameter_um=(4.68, 5.18), ranges=fixed, n_samples=28,
            replicas_per_task=10)
    d = grid_design(c)
    assert c.n_design == 56 and c.n_tasks == 6
    np.testing.assert_allclose(d["ka"][:28], np.linspace(1000.0, 28000.0, 28))
    assert np.all(d["kb"] == 389.23) and d["diameter_um"][27] == 4.68 and d["diameter_um"][28] == 5.18
    tasks = make_tasks(c, range(56))
    assert [t.n_replicas for t in tasks] == [10, 10, 8, 10, 10, 8]
    assert all(len({d["diameter_um"][i] for i in t.indices}) == 1 for t in tasks)  # never mixed
    assert tasks[0].grid is None and tasks[3].diameter_um == 5.18
    explicit = cfg(tmp_path, protocol="ringdown", design="grid", diameter_um=4.68, ranges=fixed, n_samples=None,
                   ka_values=(2000.0, 3000.0, 5000.0))
    assert explicit.n_samples == 3 and grid_design(explicit)["ka"].tolist() == [2000.0, 3000.0, 5000.0]


def test_scheduling_settings_leave_the_design_hash(tmp_path):
    # slot refill / schedule give the same curves, so a store started without them resumes with them
    base = cfg(tmp_path, tier="quasistatic", tier_settings={"ftol": 0.05})
    same = cfg(tmp_path, tier="quasistatic", tier_settings={"ftol": 0.05, "max_replicas": 500, "schedule": "async"})
    other = cfg(tmp_path, tier="quasistatic", tier_settings={"ftol": 0.02})
    assert same.design_hash() == base.design_hash() != other.design_hash()
    assert same.design_dict()["tier_settings"] == {"ftol": 0.05}
    assert same.to_dict()["tier_settings"]["max_replicas"] == 500  # the store header keeps every setting
