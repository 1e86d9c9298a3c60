"""Thermal plate contact of the quasi-static tier (bubblecal.sim.tiers.quasistatic.thermal_contact).

Analytic checks of the one-vertex model (exact integrals of a Gaussian against a hard wall), the
Barker-Henderson wall, the thin-shell sigma, and the Warp kernels against the NumPy reference.
CPU, float64, subdivision-2 icospheres.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from bubblecal.sim.engine import ShellParams
from bubblecal.sim.protocols import PlateContact, plate_force_energy
from bubblecal.sim.tiers.quasistatic import (
    G_MIN,
    ThermalContact,
    hard_wall_distance,
    inverse_mills_ratio,
    shell_fluctuation_sigma,
    thermal_plate_force,
    wall_force_psi,
)


def _truncated_gaussian(anchor: float, sigma: float, wall: float, kT: float = 1.0):
    """Exact mean position and mean wall force of x ~ N(anchor, sigma^2) conditioned on x > wall, where the
    Gaussian is a spring k = kT / sigma^2: mean force on the wall = kT * density at the wall (contact theorem)."""
    lo = wall
    norm, _ = quad(lambda x: math.exp(-0.5 * ((x - anchor) / sigma) ** 2), lo, anchor + 40 * sigma + abs(lo - anchor),
                   limit=400)
    first, _ = quad(lambda x: x * math.exp(-0.5 * ((x - anchor) / sigma) ** 2), lo,
                    anchor + 40 * sigma + abs(lo - anchor), limit=400)
    density_at_wall = math.exp(-0.5 * ((wall - anchor) / sigma) ** 2) / norm
    return first / norm, kT * density_at_wall


@pytest.mark.parametrize("anchor", [-0.05, -0.02, 0.0, 0.01, 0.03, 0.08])
def test_force_as_function_of_the_mean_position_is_exact_for_spring_and_wall(anchor):
    # one vertex on a spring (rms 0.02) next to a hard wall at 0.99: F(mean position) must equal the exact
    # contact-theorem force (tolerance 1e-6 relative: quadrature + Newton)
    sigma, wall = 0.02, 0.99
    mean, force = _truncated_gaussian(wall + anchor, sigma, wall)
    got = thermal_plate_force(np.array([mean]), sigma, wall)[0]
    assert got == pytest.approx(force, rel=1e-6)
    # and the spring balance: k (mean - anchor) = mean wall force
    assert (mean - (wall + anchor)) / sigma**2 == pytest.approx(force, rel=1e-6)


def test_psi_limits_and_inverse_mills_ratio():
    z = np.array([-30.0, -8.5, -7.5, -2.0, 0.0, 1.5, 6.0])
    from scipy.stats import norm

    exact = norm.pdf(z) / norm.cdf(z)
    np.testing.assert_allclose(inverse_mills_ratio(z), exact, rtol=1e-5)
    # pressed: Psi ~ 1/g (ideal-gas repulsion kT / gap); far: Psi ~ phi(g)
    assert wall_force_psi(np.array([0.1]))[0] * 0.1 == pytest.approx(1.0, rel=0.02)
    assert wall_force_psi(np.array([4.0]))[0] == pytest.approx(norm.pdf(4.0), rel=0.05)
    # monotone decreasing, continuous at the linear continuation below G_MIN
    g = np.linspace(-0.2, 6.0, 2000)
    psi = wall_force_psi(g)
    assert np.all(np.diff(psi) < 0)
    eps = 1e-7
    assert wall_force_psi(np.array([G_MIN - eps]))[0] == pytest.approx(wall_force_psi(np.array([G_MIN + eps]))[0],
                                                                        rel=1e-5)


def test_hard_wall_distance_of_the_default_wca_plate():
    c = PlateContact()
    h = np.linspace(1e-3, c.cutoff, 400_001)
    _, e = plate_force_energy(h, c)
    reference = h[0] + np.trapezoid(1.0 - np.exp(-np.minimum(e, 700.0)), h)  # integrand = 1 below h[0]
    assert hard_wall_distance(c) == pytest.approx(reference, abs=1e-6)
    assert 0.99 < hard_wall_distance(c) < 1.0  # eps = 1000 k_BT: nearly the LJ range
    # hotter -> softer wall -> the hard-wall distance moves in
    assert hard_wall_distance(c, kT=10.0) < hard_wall_distance(c)


def test_shell_sigma_from_thin_shell_theory():
    # sigma^2 = kT R / (8 sqrt(kappa Y)), kappa = (sqrt 3 / 2) kb, Y = ka for mu = ka/3
    s = shell_fluctuation_sigma([ShellParams(ka=5580.0, kb=100.0), ShellParams(ka=27900.0, kb=1000.0)], 6.0)
    expected = [math.sqrt(6.0 / (8.0 * math.sqrt(math.sqrt(3) / 2 * kb * ka)))
                for ka, kb in ((5580, 100), (27900, 1000))]
    np.testing.assert_allclose(s, expected, rtol=1e-12)
    assert s[0] == pytest.approx(0.0328, abs=2e-4)  # the implicit tier measured 0.035 (RESULTS.md)
    with pytest.raises(ValueError, match="kb > 0"):
        shell_fluctuation_sigma([ShellParams(ka=5580.0, kb=0.0)], 6.0)
    with pytest.raises(ValueError, match="radius_dpd"):
        shell_fluctuation_sigma([ShellParams(ka=5580.0, kb=1.0)], -1.0)
    with pytest.raises(ValueError, match="ThermalContact.kT"):
        ThermalContact(kT=0.0)
    with pytest.raises(ValueError, match="ThermalContact.sigma"):
        ThermalContact(sigma=-0.1)


# ------------------------------------------------------------------------------------------------
# the tier with Warp kernels
# ------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def qs():
    pytest.importorskip("warp")
    from bubblecal.sim.tiers import quasistatic

    return quasistatic


@pytest.fixture(scope="module")
def mesh():
    pytest.importorskip("trimesh")
    from bubblecal.sim.engine.mesh import icosphere

    return icosphere(6.0, 2)


SHELLS = [ShellParams(ka=5580.0, kb=100.0, self_avoid=False), ShellParams(ka=27900.0, kb=1000.0, self_avoid=False),
          ShellParams(ka=12000.0, kb=400.0, self_avoid=False)]
GRID = [0.0, 0.12, 0.24, 0.48]


def test_kernels_match_the_numpy_reference_and_add_a_contact_force(qs, mesh, qs_reference):
    dev = qs.quasistatic_compression(SHELLS, mesh, GRID, thermal=qs.ThermalContact())
    ref = qs_reference.reference_compression(SHELLS, mesh, GRID, thermal=qs.ThermalContact())
    athermal = qs.quasistatic_compression(SHELLS, mesh, GRID)
    assert dev.status == ["ok"] * 3 and ref.status == ["ok"] * 3
    # same minima within the FIRE tolerance (ftol 0.05 per vertex on ~10 contact vertices)
    np.testing.assert_allclose(dev.force, ref.force, rtol=2e-3, atol=0.5)
    # thermal contact: F(0) > 0 (the athermal tier has exactly 0 there) and the plate acts earlier
    assert np.all(athermal.force[:, 0] == 0.0)
    assert np.all(dev.force[:, 0] > 1.0)
    assert np.all(dev.force[:, 1:] > athermal.force[:, 1:])
    tc = dev.settings["thermal_contact"]
    assert tc["hard_wall"] == pytest.approx(hard_wall_distance(PlateContact()))
    assert tc["radius_dpd"] == pytest.approx(6.0, rel=1e-9)


def test_slot_refill_carries_each_shells_sigma(qs, mesh):
    # three shells with different sigma through two slots: the refilled slot must take the new shell's sigma
    lock = qs.quasistatic_compression(SHELLS, mesh, GRID, thermal=qs.ThermalContact(), schedule="lockstep")
    pool = qs.quasistatic_compression(SHELLS, mesh, GRID, thermal=qs.ThermalContact(), max_replicas=2)
    assert pool.status == lock.status
    np.testing.assert_array_equal(pool.fire_steps, lock.fire_steps)
    np.testing.assert_array_equal(pool.force, lock.force)
    np.testing.assert_array_equal(pool.x_final, lock.x_final)


def test_fixed_sigma_and_bad_argument(qs, mesh):
    small = qs.quasistatic_compression(SHELLS[:1], mesh, GRID[:2], thermal=qs.ThermalContact(sigma=0.005))
    large = qs.quasistatic_compression(SHELLS[:1], mesh, GRID[:2], thermal=qs.ThermalContact(sigma=0.05))
    assert large.force[0, 0] > small.force[0, 0]  # more fluctuation, more contact force at d = 0
    with pytest.raises(ValueError, match="ThermalContact"):
        qs.quasistatic_compression(SHELLS[:1], mesh, GRID[:2], thermal=1.0)


def test_tier_setting(qs):
    from bubblecal.sim.tiers import CurveRequest, QuasistaticTier

    with pytest.raises(ValueError, match="thermal_contact"):
        QuasistaticTier(thermal_contact="yes")
    with pytest.raises(ValueError, match="kT"):
        QuasistaticTier(kT=-1.0)
    req = CurveRequest(protocol="compression", diameter_um=3.0, grid=(0.0, 0.12),
                       params={"ka": [5580.0], "kb": [100.0], "b1": [0.0], "b2": [0.0], "a3": [0.0], "a4": [0.0]},
                       seeds=(1,), subdivisions=2)
    hot = QuasistaticTier(thermal_contact=True).run(req)
    cold = QuasistaticTier().run(req)
    assert hot.info["thermal_contact"] is True and cold.info["thermal_contact"] is False
    assert hot.observable[0, 0] > 0.0 == cold.observable[0, 0]
