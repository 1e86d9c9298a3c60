"""DPD pair forces: formula, symmetric random numbers, Newton's third law."""

from __future__ import annotations

import numpy as np
import pytest

wp = pytest.importorskip("warp")
wp.config.quiet = True

from bubblecal.sim.engine import WATER, ParticleSystem, ReplicaSpec, fluid_pair_table  # noqa: E402  # noqa: E402


def _two_particles(r_vec, dv, a=25.0, gamma=4.5, s=0.5, kbt=1.0, seed=3):
    box = (6.0, 6.0, 6.0)
    x = np.array([[3.0, 3.0, 3.0], [3.0, 3.0, 3.0]]) - np.array([np.zeros(3), r_vec])
    v = np.array([dv, np.zeros(3)])
    spec = ReplicaSpec(box=box, pairs=fluid_pair_table(a, gamma, s), kbt=kbt, seed=seed, water_density=0.0,
                       extra_positions=x, extra_types=np.array([WATER, WATER]), extra_velocities=v)
    ps = ParticleSystem([spec], dt=1e-3)
    ps.v.assign(v.astype(np.float32))  # set-up removed the mean momentum; restore the chosen velocities
    ps.rebuild()
    ps.compute_forces()
    order = np.argsort(ps.pid.numpy())
    return ps.f.numpy().astype(np.float64)[order], ps


def test_conservative_and_dissipative_formula():
    # kBT = 0 -> sigma = 0: F = e [a (1 - r) - gamma w^2 (e . v)], w = (1 - r)^s
    r_vec = np.array([0.3, -0.2, 0.4])
    dv = np.array([0.5, 1.0, -0.7])
    f, _ = _two_particles(r_vec, dv, a=25.0, gamma=4.5, s=0.25, kbt=0.0)
    r = np.linalg.norm(r_vec)
    e = r_vec / r
    w = (1 - r) ** 0.25
    expected = e * (25.0 * (1 - r) - 4.5 * w * w * e.dot(dv))
    np.testing.assert_allclose(f[0], expected, rtol=1e-5)
    np.testing.assert_array_equal(f[1], -f[0])


def test_no_force_beyond_cutoff():
    f, _ = _two_particles(np.array([0.7, 0.5, 0.6]), np.zeros(3), kbt=1.0)
    assert np.all(f == 0.0)


def test_random_force_is_symmetric_and_unit_variance():
    # gamma > 0, kBT > 0, zero relative velocity and a = 0: only the random term; F_i = -F_j exactly
    vals = []
    for seed in range(200):
        f, ps = _two_particles(np.array([0.2, 0.1, 0.0]), np.zeros(3), a=0.0, gamma=2.0, s=0.5, seed=seed)
        np.testing.assert_array_equal(f[0], -f[1])
        r = np.hypot(0.2, 0.1)
        theta = np.linalg.norm(f[0]) * np.sqrt(ps.dt) / (np.sqrt(2 * 2.0) * (1 - r) ** 0.5)
        vals.append(theta)
    vals = np.array(vals)
    # |theta| of a uniform variable on [-sqrt3, sqrt3]: mean sqrt(3)/2, max <= sqrt(3)
    assert vals.max() <= np.sqrt(3) + 1e-4
    assert abs(vals.mean() - np.sqrt(3) / 2) < 0.15


def test_total_force_vanishes_in_a_fluid():
    spec = ReplicaSpec(box=(5.0, 5.0, 5.0), pairs=fluid_pair_table(25.0, 4.5, 0.5), seed=1)
    ps = ParticleSystem([spec], dt=0.01)
    ps.rebuild()
    ps.compute_forces()
    f = ps.f.numpy().astype(np.float64)
    scale = np.abs(f).sum()
    assert np.linalg.norm(f.sum(axis=0)) < 1e-5 * scale


def test_fsi_friction_factor_scales_only_the_vertex_solvent_friction():
    from bubblecal.sim.engine import GAS, VERTEX, bubble_spec, published_pair_table

    base = published_pair_table(5.0, "compression")
    slow = published_pair_table(5.0, "compression", fsi_friction_factor=0.1)
    scaled = np.zeros_like(base.gamma, dtype=bool)
    for a, b in ((VERTEX, WATER), (VERTEX, GAS)):
        scaled[a, b] = scaled[b, a] = True
    np.testing.assert_allclose(slow.gamma[scaled], 0.1 * base.gamma[scaled], rtol=1e-12)
    np.testing.assert_array_equal(slow.gamma[~scaled], base.gamma[~scaled])
    np.testing.assert_array_equal(slow.a, base.a)
    assert bubble_spec(1.5, 1, fsi_friction_factor=0.1).pairs.gamma[VERTEX, WATER] == pytest.approx(
        0.1 * bubble_spec(1.5, 1).pairs.gamma[VERTEX, WATER])
    with pytest.raises(ValueError, match="fsi_friction_factor"):
        published_pair_table(5.0, fsi_friction_factor=0.0)


def test_no_gas_means_no_vertex_gas_friction():
    from bubblecal.sim.engine import GAS, VERTEX, published_pair_table

    t = published_pair_table(5.0, "compression", rho_gas_number=0.0)
    assert t.gamma[VERTEX, GAS] == 0.0 and t.gamma[GAS, VERTEX] == 0.0
    assert t.gamma[VERTEX, WATER] == published_pair_table(5.0, "compression").gamma[VERTEX, WATER]


def test_water_repulsion_is_a_setting():
    from bubblecal.sim.engine import bubble_spec, published_pair_table

    assert published_pair_table(5.0).a[WATER, WATER] == 100.0
    assert bubble_spec(1.5, 1, a_water=25.0).pairs.a[WATER, WATER] == 25.0
    for bad in (-1.0, float("nan")):
        with pytest.raises(ValueError, match="a_water must be a finite repulsion >= 0"):
            published_pair_table(5.0, a_water=bad)
