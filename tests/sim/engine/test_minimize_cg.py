"""The force-only nonlinear CG: the NumPy reference (bubblecal.sim.engine.minimize_cg) on analytic quadratics, and
the device-resident batched CG (bubblecal.sim.engine.minimize_device_cg) against it.

CPU Warp, float64.
"""

import numpy as np
import pytest

from bubblecal.sim.engine import cg_minimize


def _quadratic(seed=3, n=40, kappa=1e3):
    """Anisotropic harmonic well: stiffness per component log-uniform in [1, kappa], minimum ``target``."""
    rng = np.random.default_rng(seed)
    k = np.exp(rng.uniform(0.0, np.log(kappa), (n, 3)))
    return k, rng.normal(size=(n, 3))


def test_reference_reaches_the_minimum_of_an_ill_conditioned_quadratic():
    k, target = _quadratic()
    res = cg_minimize(lambda x: -k * (x - target), np.zeros((40, 3)), ftol=1e-6, max_steps=100_000)
    assert res.converged and res.fmax <= 1e-6
    # |F| <= ftol componentwise bounds the distance by ftol / k_min
    np.testing.assert_allclose(res.x, target, rtol=0, atol=1e-6 / k.min())
    # an exact-line-search CG needs ~sqrt(kappa) ln(2 / tol) ~ 500 steps here, steepest descent ~kappa ln(1 / tol)
    # ~ 17,000; this one (measured 250 lines, 460 evaluations) stays within 2 evaluations per line
    assert res.n_lines <= 400 and res.steps + 1 <= 2 * res.n_lines + 20


def test_reference_status_at_the_start_at_max_steps_and_when_nonfinite():
    res = cg_minimize(lambda x: np.zeros_like(x), np.ones((5, 3)))
    assert res.status == "converged" and res.steps == 0 and res.fmax == 0.0
    res = cg_minimize(lambda x: -x, np.ones((5, 3)), ftol=1e-12, max_steps=3)
    assert res.status == "max_steps" and res.steps == 3
    res = cg_minimize(lambda x: np.where(x[:, :1] < 0.5, np.nan, -x), np.ones((5, 3)), ftol=1e-12)
    assert res.status == "nonfinite"
    with pytest.raises(ValueError, match="max_steps"):
        cg_minimize(lambda x: -x, np.ones((5, 3)), max_steps=-1)
    with pytest.raises(ValueError, match="positive"):
        cg_minimize(lambda x: -x, np.ones((5, 3)), accept=0.0)


def test_reference_exact_on_a_one_dimensional_quadratic_line():
    # F = -k (x - c) is linear along the first direction: once a trial overshoots, the secant lands on the root
    res = cg_minimize(lambda x: -4.0 * (x - 2.0), np.zeros((1, 3)), ftol=1e-9, first_alpha=1.0, first_move=10.0)
    assert res.converged and res.n_lines == 0 and res.steps == 2
    np.testing.assert_allclose(res.x, 2.0, atol=1e-12)
    # with the default small first step the extrapolation (at most doubling) needs more trials, same root
    res = cg_minimize(lambda x: -4.0 * (x - 2.0), np.zeros((1, 3)), ftol=1e-9)
    assert res.converged and res.steps > 2
    np.testing.assert_allclose(res.x, 2.0, atol=1e-9)


# ---- the device CG ----
wp = pytest.importorskip("warp")
wp.config.quiet = True

from bubblecal.sim.engine import DeviceCG, numpy_force_fn  # noqa: E402


def _batch(n_rep=3, seed=3):
    ks, ts = zip(*[_quadratic(seed + i) for i in range(n_rep)], strict=True)
    return np.concatenate(ks), np.concatenate(ts), np.arange(n_rep + 1) * 40


def test_device_follows_the_reference():
    k, target, rs = _batch()
    refs = [cg_minimize(lambda x, i=i: -k[rs[i]:rs[i + 1]] * (x - target[rs[i]:rs[i + 1]]), np.zeros((40, 3)),
                        ftol=1e-6, max_steps=100_000) for i in range(3)]
    d = DeviceCG(rs, numpy_force_fn(lambda x: -k * (x - target)), sync_every=7)
    res = d.minimize(ftol=1e-6, max_steps=100_000)
    assert res.status == ["converged"] * 3
    # the same iterates up to round-off (the device moves x by step differences, the reference from the line's
    # base): measured 459 / 471 / 521 against 460 / 473 / 516 evaluations
    np.testing.assert_allclose(res.steps, [r.steps for r in refs], rtol=0.02)
    x = d.positions()
    for i, r in enumerate(refs):
        np.testing.assert_allclose(x[rs[i]:rs[i + 1]], r.x, rtol=0, atol=2e-6 / k.min())
    assert np.all(res.fmax <= 1e-6)


def test_device_mask_mean_removal_frozen_and_nonfinite():
    k, target, rs = _batch(4)
    k[rs[3]:] = np.nan  # the last replica's forces are non-finite
    free = np.ones((160, 3), dtype=bool)
    free[5, 1] = free[50, 2] = False
    x0 = np.zeros((160, 3))
    d = DeviceCG(rs, numpy_force_fn(lambda x: -k * (x - target)), free=free, remove_mean=(True, True, False))
    d.set_positions(x0)
    res = d.minimize(ftol=1e-5, max_steps=50_000, active=np.array([True, False, True, True]))
    assert res.status == ["converged", "frozen", "converged", "nonfinite"]
    assert np.isnan(res.fmax[1]) and res.fmax[3] == np.inf
    x = d.positions()
    np.testing.assert_array_equal(x[rs[1]:rs[2]], 0.0)  # the frozen replica never moved
    assert x[5, 1] == 0.0 and x[50, 2] == 0.0  # fixed components stay
    # with the mean x, y force removed the minimum solves F - mean(F) = 0 in x, y: check the projected force
    for i in (0, 2):
        sl = slice(rs[i], rs[i + 1])
        f = -k[sl] * (x[sl] - target[sl])
        f[:, :2] -= f[:, :2].mean(axis=0)
        f *= free[sl]
        assert np.max(np.linalg.norm(f, axis=1)) <= 1e-5


def test_device_replicas_move_between_minimisers_with_their_iterates():
    # half a run in a batch of three, then replica 2 alone in a minimiser of one: the same finish as uninterrupted
    k, target, rs = _batch()
    fn = numpy_force_fn(lambda x: -k * (x - target))
    whole = DeviceCG(rs, fn, sync_every=5)
    whole.begin(ftol=1e-6, max_steps=100_000)
    whole.restart(np.ones(3, dtype=bool))
    code = whole.advance()
    while np.any(code == 0):
        code = whole.advance()
    ref = whole.positions()[rs[2]:]
    ref_steps = whole.replica_report()[0][2]

    part = DeviceCG(rs, fn, sync_every=5)
    part.begin(ftol=1e-6, max_steps=100_000)
    part.restart(np.ones(3, dtype=bool))
    for _ in range(40):
        part.advance()
    k2, t2 = k[rs[2]:], target[rs[2]:]
    alone = DeviceCG([0, 40], numpy_force_fn(lambda x: -k2 * (x - t2)), sync_every=5)
    alone.import_rows(part.export_rows([2]))
    while alone.advance()[0] == 0:
        pass
    assert alone.replica_report()[0][0] == ref_steps
    np.testing.assert_allclose(alone.positions(), ref, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="do not match"):
        alone.import_rows(part.export_rows([0, 1]))


def test_device_validates_its_constants():
    with pytest.raises(ValueError, match="positive"):
        DeviceCG([0, 4], numpy_force_fn(lambda x: -x), grow=0.0)
    with pytest.raises(ValueError, match="row_start"):
        DeviceCG([0, 0], numpy_force_fn(lambda x: -x))
