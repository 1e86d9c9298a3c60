"""The quasi-static tier's settings and runs through get_tier (bubblecal.sim.tiers.quasistatic.tier)."""

from __future__ import annotations

import numpy as np
import pytest

from bubblecal.sim.tiers import CurveRequest

KA, KB = 16751.0, 500.0  # the Reissner check's parameter set (physics.md 6.5)
PARAMS = {"ka": [5584.0, 8000.0], "kb": [389.23, 600.0], "b1": [0.0, 1.0], "b2": [0.0, 2.0], "a3": [-2.0, 0.5],
          "a4": [8.0, 1.0]}


def test_quasistatic_tier_stop_unstable_setting():
    from bubblecal.sim.tiers import get_tier

    assert get_tier("quasistatic").stop_unstable is False  # the shipped sets ran without it
    with pytest.raises(ValueError, match="stop_unstable must be true or false"):
        get_tier("quasistatic", stop_unstable="yes")


def test_quasistatic_tier_first_load_ramp_setting():
    pytest.importorskip("warp")
    from bubblecal.sim.tiers import get_tier

    assert get_tier("quasistatic").first_load_ramp == 0  # the shipped sets ran without it
    for bad in (-1, 21, 2.0, True):
        with pytest.raises(ValueError, match="first_load_ramp must be an integer"):
            get_tier("quasistatic", first_load_ramp=bad)
    shell = dict(ka=KA, kb=KB, b1=0.0, b2=0.0, a3=0.0, a4=0.0)
    req = CurveRequest("compression", 2.1, (0.0, 0.12), {k: np.array([v]) for k, v in shell.items()}, (1,),
                       subdivisions=2)
    with pytest.raises(ValueError, match="indentation only"):
        get_tier("quasistatic", first_load_ramp=2).run(req)


def test_quasistatic_tier_self_avoidance_inert_and_dtype_checked():
    pytest.importorskip("warp")
    from bubblecal.sim.tiers import get_tier

    req = CurveRequest("compression", 1.5, (0.0, 0.12, 0.24, 0.36), PARAMS, (1, 2), subdivisions=2)
    off = get_tier("quasistatic").run(req)
    on = get_tier("quasistatic", self_avoid=True).run(req)
    assert off.info["self_avoid"] is False and on.info["self_avoid"] is True
    assert off.status == on.status == ["ok", "ok"]
    # the repulsion never engages in athermal plate loading: the same curves to round-off
    np.testing.assert_allclose(off.observable, on.observable, rtol=1e-10, atol=1e-9)
    with pytest.raises(ValueError, match="dtype must be 'float64' or 'float32'"):
        get_tier("quasistatic", dtype="float16")
    with pytest.raises(ValueError, match="schedule must be"):
        get_tier("quasistatic", schedule="eager")


def test_quasistatic_tier_slot_refill_same_curves():
    pytest.importorskip("warp")
    from bubblecal.sim.tiers import get_tier

    req = CurveRequest("compression", 1.5, (0.0, 0.12, 0.24), PARAMS, (1, 2), subdivisions=2)
    whole = get_tier("quasistatic").run(req)
    one_slot = get_tier("quasistatic", max_replicas=1).run(req)
    assert one_slot.info["settings"]["max_replicas"] == 1
    assert one_slot.status == whole.status
    np.testing.assert_array_equal(one_slot.observable, whole.observable)
    for bad in (0, 2.0, True):
        with pytest.raises(ValueError, match="max_replicas must be an integer"):
            get_tier("quasistatic", max_replicas=bad)
    with pytest.raises(ValueError, match="needs schedule"):
        get_tier("quasistatic", max_replicas=4, schedule="lockstep")


@pytest.mark.parametrize("minimizer", ["fire", "cg"])
def test_quasistatic_tier_sync_every_schedules_only(minimizer):
    pytest.importorskip("warp")
    from bubblecal.campaigns import EXECUTION_ONLY_TIER_SETTINGS
    from bubblecal.sim.tiers import get_tier

    req = CurveRequest("compression", 1.5, (0.0, 0.12, 0.24), PARAMS, (1, 2), subdivisions=2)
    base = get_tier("quasistatic", minimizer=minimizer).run(req)
    often = get_tier("quasistatic", minimizer=minimizer, sync_every=1, max_replicas=1).run(req)
    assert often.status == base.status == ["ok", "ok"]
    # the host reads the status after every iteration instead of every 4: the same iterates, the same curves
    np.testing.assert_array_equal(often.observable, base.observable)
    assert often.info["fire_steps"] == base.info["fire_steps"]
    assert "sync_every" in EXECUTION_ONLY_TIER_SETTINGS  # so it leaves a campaign's design hash alone
    for bad in (0, 2.5, True):
        with pytest.raises(ValueError, match="sync_every must be an integer"):
            get_tier("quasistatic", sync_every=bad)


def test_quasistatic_tier_overpressure_inflates_the_shell_by_laplace():
    """A gas pressure Δp above the ambient inflates the unloaded sphere until the Lim area tension and the
    gas's expansion balance it: k_a α (2 + 2ε) A0 = [p0 / (1 + ε)³ − (p0 − Δp)] 3 V0 (1 + ε)², α = 2ε + ε²
    (uniform scaling of the mesh, its own A0 and V0); the unloaded depth is d = −2 R ε."""
    pytest.importorskip("warp")
    from scipy.optimize import brentq

    from bubblecal.sim.engine import mesh_for_diameter
    from bubblecal.sim.tiers import get_tier

    ka, dp, p0 = 2000.0, 5.0, 3.0
    shell = dict(ka=ka, kb=KB, b1=0.0, b2=0.0, a3=0.0, a4=0.0)
    req = CurveRequest("indentation", 2.1, (0.0, 5.0), {k: np.array([v]) for k, v in shell.items()}, (1,),
                       subdivisions=2)
    with pytest.raises(ValueError, match="overpressure must be a finite number"):
        get_tier("quasistatic", overpressure=float("nan"))
    balanced = get_tier("quasistatic", ftol=1e-4).run(req)
    inflated = get_tier("quasistatic", overpressure=dp, ftol=1e-4).run(req)
    mesh = mesh_for_diameter(2.1, 2)
    a0, v0 = mesh.area(), mesh.volume()

    def balance(eps):
        alpha = 2 * eps + eps * eps
        return ka * alpha * (2 + 2 * eps) * a0 - (p0 / (1 + eps) ** 3 - (p0 - dp)) * 3 * v0 * (1 + eps) ** 2

    eps = brentq(balance, 0.0, 0.1)
    assert balanced.observable[0, 0] == pytest.approx(0.0, abs=1e-6)
    assert inflated.observable[0, 0] == pytest.approx(-2 * mesh.radius_dpd * eps, rel=0.02)
    # the inflated, pre-tensioned shell is stiffer against the pole load
    assert inflated.observable[0, 1] - inflated.observable[0, 0] < balanced.observable[0, 1]
