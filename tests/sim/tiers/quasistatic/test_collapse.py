"""The collapse verdict of quasi-static indentation (``max_depth_fall``): the pure scan, the per-curve cut, the tier
setting and its design hash, a stable run it leaves alone, and (slow) the two design points of the indentation
design over the diameter whose CG minima collapse."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from bubblecal.sim.tiers import get_tier
from bubblecal.sim.tiers.quasistatic import STATUS_COLLAPSED, depth_collapse_point
from bubblecal.sim.tiers.quasistatic.collapse import cut_collapsed

ROOT = Path(__file__).resolve().parents[4]


@pytest.mark.parametrize(("depth", "tol", "expected"), [
    ([0.0, 1.0, 2.0, 3.0], 0.05, None),           # monotone
    ([0.0, 1.0, 2.0, 1.91, 3.0], 0.05, None),     # a 4.5 % fall: within
    ([0.0, 1.0, 2.0, 1.89, 3.0], 0.05, 3),        # a 5.5 % fall: cut there, even though the depth recovers
    ([0.0, 1.0, 2.0, 1.95, 1.85], 0.05, 4),       # measured from the deepest earlier point, not the previous one
    ([0.0, 1.0, 2.0, np.nan, 0.0], 0.05, None),   # a failed curve's NaN tail ends the scan
    ([0.0, -1e-9, -2e-9, 1.0], 0.05, None),       # no positive depth yet: nothing to fall from
    ([0.0, 6.6, 1.1, -3.5], 0.5, 2),
])
def test_depth_collapse_point(depth, tol, expected):
    assert depth_collapse_point(depth, tol) == expected


@pytest.mark.parametrize("bad", [None, 0.0, 1.0, -0.1, float("nan"), True, "0.05"])
def test_depth_collapse_point_rejects_bad_tolerance(bad):
    with pytest.raises(ValueError, match="max_depth_fall"):
        depth_collapse_point([0.0, 1.0], bad)


def test_cut_collapsed_keeps_the_prefix():
    depth = np.array([0.0, 1.0, 2.0, 0.5, 3.0])
    out, status, ps, j = cut_collapsed(depth, "ok", ["ok"] * 5, 0.05)
    assert (status, j) == (STATUS_COLLAPSED, 3)
    assert ps == ["ok", "ok", "ok", STATUS_COLLAPSED, STATUS_COLLAPSED]
    assert np.array_equal(out[:3], depth[:3]) and np.all(np.isnan(out[3:]))
    assert depth[3] == 0.5  # the input is not modified
    # an unconverged curve is cut too; a failure's verdict (it ended the curve first) and None leave it alone
    assert cut_collapsed(depth, "not_converged", ["ok"] * 5, 0.05)[1] == STATUS_COLLAPSED
    for status, tol in (("ruptured", 0.05), ("ok", None)):
        out, s, p, j = cut_collapsed(depth, status, ["ok"] * 5, tol)
        assert (s, j) == (status, None) and out is depth


@pytest.mark.parametrize("bad", [0.0, 1.0, 2.0, -0.5, True, "x"])
def test_tier_rejects_bad_max_depth_fall(bad):
    with pytest.raises(ValueError, match="quasistatic tier: max_depth_fall"):
        get_tier("quasistatic", max_depth_fall=bad)


def test_tier_refuses_max_depth_fall_for_compression():
    pytest.importorskip("warp")
    from bubblecal.sim.tiers import CurveRequest

    req = CurveRequest(protocol="compression", diameter_um=2.1, grid=(0.0, 0.1),
                       params={k: np.array([v]) for k, v in zip(("ka", "kb", "b1", "b2", "a3", "a4"),
                                                      (1000.0, 500.0, 0.0, 0.0, 0.0, 0.0), strict=True)},
                       seeds=(1,), subdivisions=1)
    with pytest.raises(ValueError, match="max_depth_fall applies to indentation only"):
        get_tier("quasistatic", max_depth_fall=0.05).run(req)


def test_the_setting_enters_the_design_hash():
    from bubblecal.campaigns import load_campaign_file

    cfg = load_campaign_file("sonovue_indentation_1.5-8um_mirheo").config
    assert cfg.tier_settings["max_depth_fall"] == 0.05  # the shipped design runs with the verdict
    without = dataclasses.replace(cfg, tier_settings={k: v for k, v in cfg.tier_settings.items()
                                                      if k != "max_depth_fall"})
    other = dataclasses.replace(cfg, tier_settings={**cfg.tier_settings, "max_depth_fall": 0.1})
    assert len({cfg.design_hash(), without.design_hash(), other.design_hash()}) == 3


def test_a_stable_curve_is_left_alone_and_records_the_setting():
    pytest.importorskip("warp")
    from bubblecal.sim.engine.kernels.shell import ShellParams
    from bubblecal.sim.engine.mesh import icosphere
    from bubblecal.sim.tiers.quasistatic import quasistatic_indentation

    mesh, forces = icosphere(6.0, 2), [0.0, 10.0, 20.0, 40.0]
    params = [ShellParams(ka=16751.0, kb=500.0, self_avoid=False), ShellParams(ka=4000.0, kb=500.0, self_avoid=False)]
    rows = {}
    on = quasistatic_indentation(params, mesh, forces, max_depth_fall=0.01,
                                 on_curve=lambda i, row: rows.update({i: row}))
    off = quasistatic_indentation(params, mesh, forces)
    assert on.status == off.status == ["ok", "ok"]
    assert np.array_equal(on.displacement, off.displacement)
    assert on.settings["max_depth_fall"] == 0.01 and "max_depth_fall" not in off.settings
    for i, row in rows.items():
        assert row["status"] == "ok" and np.array_equal(row["displacement"], on.displacement[i])
    with pytest.raises(ValueError, match="max_depth_fall"):
        quasistatic_indentation(params, mesh, forces, max_depth_fall=1.5)


@pytest.mark.slow
def test_collapsing_design_points_end_unstable_with_their_prefix():
    """Design points 252 (7.3 um, depth 6.6 -> 1.1 -> -3.5 DPD under the CG) and 324 (6.7 um, a 7 % fall over its
    last two points) of the indentation design over the diameter: with the CG and a 5 % tolerance both end
    'unstable', their prefixes rise and follow the FIRE records (whose rupture flag ended them earlier), and the
    campaign's per-curve rows equal the batch's."""
    pytest.importorskip("warp")
    from bubblecal.campaigns import load_campaign_file
    from bubblecal.campaigns.tasks import make_tasks, simulate_task
    from bubblecal.data.store import CampaignStore

    cfg = load_campaign_file("sonovue_indentation_1.5-8um_mirheo").config
    cfg = dataclasses.replace(cfg, device="cpu", replicas_per_task=2,
                              tier_settings={**cfg.tier_settings, "minimizer": "cg", "max_depth_fall": 0.05,
                                             "max_replicas": None})
    (task,) = make_tasks(cfg, [252, 324])
    rows = {}
    res = simulate_task(task, on_curve=lambda r, y, status, info: rows.update({r: (y, status)}))
    assert res.status == ["unstable", "unstable"]
    fire = {r["sample_id"][-6:]: np.asarray(r["y"], float) for r in CampaignStore(
        ROOT / "data" / "training" / "sonovue_indentation_1.5-8um_mirheo.jsonl.gz").read(warn=False)
        if r["sample_id"][-6:] in ("000252", "000324")}
    for r, sample_id in enumerate(task.sample_ids):  # the task orders its replicas by diameter level
        sid, y = sample_id[-6:], res.y[r]
        n = int(np.argmax(~np.isfinite(y)))  # the collapse point
        assert n >= 5 and np.all(np.isnan(y[n:]))
        assert np.all(np.diff(y[:n]) > 0)
        both = np.isfinite(fire[sid]) & np.isfinite(y)
        assert both.sum() >= 4
        np.testing.assert_allclose(y[both][1:], fire[sid][both][1:], rtol=0.02)
        assert rows[r][1] == "unstable"
        np.testing.assert_array_equal(rows[r][0], y)
