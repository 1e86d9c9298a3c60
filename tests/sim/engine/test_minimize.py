"""FIRE minimiser (bubblecal.sim.engine.minimize): per-replica convergence, masks, statuses."""

from __future__ import annotations

import numpy as np
import pytest

from bubblecal.sim.engine import fire_minimize


def springs(k, target):
    """Independent anisotropic harmonic wells: E = sum k (x - target)^2 / 2 per row."""
    k = np.asarray(k, dtype=float)

    def ef(x):
        d = x - target
        return None, -k * d

    return ef


def test_converges_per_replica_and_freezes_converged():
    rng = np.random.default_rng(0)
    n = 12
    target = rng.standard_normal((n, 3))
    groups = np.repeat([0, 1, 2], 4)
    k = np.ones((n, 3))
    k[groups == 1] = 50.0          # stiff replica
    k[groups == 2] *= np.array([1.0, 20.0, 300.0])  # ill-conditioned replica
    x0 = target + rng.standard_normal((n, 3))
    res = fire_minimize(springs(k, target), x0, groups, ftol=1e-6, max_steps=20_000, dt=0.01, max_move=None)
    assert res.status == ["converged"] * 3
    assert res.all_converged
    np.testing.assert_allclose(res.x, target, atol=1e-5)
    assert np.all(res.fmax <= 1e-6)
    assert res.steps[2] > res.steps[0]  # replicas stop independently
    assert not np.shares_memory(res.x, x0)


def test_frozen_rows_and_components():
    target = np.zeros((3, 3))
    x0 = np.ones((3, 3))
    groups = np.array([0, 0, -1])
    free = np.ones((3, 3), bool)
    free[1, 2] = False
    res = fire_minimize(springs(np.ones((3, 3)), target), x0, groups, free=free, ftol=1e-8, max_steps=5000)
    assert res.status == ["converged"]
    np.testing.assert_allclose(res.x[0], 0.0, atol=1e-7)
    np.testing.assert_allclose(res.x[1], [0.0, 0.0, 1.0], atol=1e-7)
    np.testing.assert_array_equal(res.x[2], x0[2])


def test_max_steps_and_nonfinite_status():
    x0 = np.ones((2, 3))
    res = fire_minimize(springs(np.ones((2, 3)), np.zeros((2, 3))), x0, ftol=1e-12, max_steps=3)
    assert res.status == ["max_steps"] and not res.all_converged

    def bad(x):
        f = -x.copy()
        f[1] = np.nan
        return np.array([0.0, 0.0]), f

    res = fire_minimize(bad, np.ones((2, 3)), np.array([0, 1]), ftol=1e-6, max_steps=5000)
    assert res.status[1] == "nonfinite"
    assert res.status[0] == "converged"


def test_max_move_caps_displacement():
    def ef(x):
        return None, np.full_like(x, 1e6)

    res = fire_minimize(ef, np.zeros((1, 3)), ftol=1e-3, max_steps=1, dt=1.0, max_move=0.05)
    assert np.linalg.norm(res.x[0]) <= 0.05 + 1e-12


def test_energy_reported_and_validation():
    target = np.zeros((2, 3))

    def ef(x):
        return np.array([0.5 * np.sum(x**2)]), -x

    res = fire_minimize(ef, np.ones((2, 3)), ftol=1e-8, max_steps=5000)
    assert res.energy[0] < 1e-14
    with pytest.raises(ValueError, match="groups"):
        fire_minimize(ef, np.ones((2, 3)), np.array([0]))
    with pytest.raises(ValueError, match="free"):
        fire_minimize(ef, np.ones((2, 3)), free=np.ones((2, 2), bool))
    assert target.sum() == 0
