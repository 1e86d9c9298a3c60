"""Device-resident batched FIRE (bubblecal.sim.engine.minimize_device) against the NumPy reference FIRE.

CPU Warp, float64 unless stated; the GPU checks at the end run only with -m gpu on a CUDA machine.
"""

import numpy as np
import pytest

wp = pytest.importorskip("warp")
wp.config.quiet = True

from bubblecal.sim.engine import (  # noqa: E402
    DeviceFire,
    cuda_threads_per_replica,
    fire_minimize,
    numpy_force_fn,
)


@wp.kernel
def _spring_kernel(x: wp.array(dtype=wp.vec3d), f: wp.array(dtype=wp.vec3d), k: wp.array(dtype=wp.vec3d),
                   target: wp.array(dtype=wp.vec3d)):
    i = wp.tid()
    f[i] = f[i] - wp.cw_mul(k[i], x[i] - target[i])


def _wells(seed=0):
    """Three replicas of four rows in anisotropic harmonic wells (one stiff, one ill-conditioned)."""
    rng = np.random.default_rng(seed)
    n = 12
    target = rng.standard_normal((n, 3))
    groups = np.repeat([0, 1, 2], 4)
    k = np.ones((n, 3))
    k[groups == 1] = 50.0
    k[groups == 2] *= np.array([1.0, 20.0, 300.0])
    x0 = target + rng.standard_normal((n, 3))
    return k, target, groups, x0


def _spring_forces(k, target, dev):
    """Warp force function of the harmonic wells (k, target [12, 3]) on ``dev``."""
    ka = wp.array(k, dtype=wp.vec3d, device=dev)
    ta = wp.array(target, dtype=wp.vec3d, device=dev)

    def forces(x, f):
        wp.launch(_spring_kernel, dim=12, inputs=[x, f, ka, ta], device=dev)

    return forces


def _numpy_reference(k, target, groups, x0, free, remove_mean, **kw):
    comps = np.array(remove_mean)

    def ef(x):
        f = (-k * (x - target)).reshape(3, 4, 3)
        f[:, :, comps] -= f[:, :, comps].mean(axis=1, keepdims=True)
        return None, f.reshape(-1, 3)

    return fire_minimize(ef, x0, groups, free=free, **kw)


@pytest.mark.parametrize("max_move", [None, 0.05])
@pytest.mark.parametrize("remove_mean", [(False, False, False), (True, True, False)])
def test_matches_numpy_fire_exactly(max_move, remove_mean):
    k, target, groups, x0 = _wells()
    k[groups == 1] = 5.0  # FIRE with a move cap stalls (max_steps, both versions) in the stiffer wells of _wells
    k[groups == 2] = np.array([1.0, 5.0, 30.0])
    x0 = target + 3.0 * (x0 - target)  # large first moves: the cap is active
    free = np.ones((12, 3), dtype=bool)
    free[3, 1] = False
    free[9, 2] = False
    ref = _numpy_reference(k, target, groups, x0, free, remove_mean, ftol=1e-6, max_steps=5000, dt=0.01,
                           max_move=max_move)
    d = DeviceFire([0, 4, 8, 12], numpy_force_fn(lambda x: -k * (x - target)), free=free, dt=0.01,
                   max_move=max_move, remove_mean=remove_mean, sync_every=7)
    d.set_positions(x0)
    res = d.minimize(ftol=1e-6, max_steps=5000)
    assert res.status == ref.status == ["converged"] * 3
    if max_move is None or not any(remove_mean):
        # same iterates to round-off
        np.testing.assert_array_equal(res.steps, ref.steps)
        np.testing.assert_allclose(d.positions(), ref.x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(res.fmax, ref.fmax, rtol=1e-6, atol=1e-12)
    else:
        # a near-tie of the capped move flips on round-off (mean removal sums in another order): same
        # minimum up to a uniform x, y translation (the zero mode the mean removal leaves free)
        np.testing.assert_allclose(res.steps, ref.steps, rtol=0.05)
        centred = [(x.reshape(3, 4, 3) - x.reshape(3, 4, 3).mean(axis=1, keepdims=True))
                   for x in (d.positions(), ref.x)]
        np.testing.assert_allclose(centred[0], centred[1], rtol=0, atol=1e-5)
    assert np.all(res.fmax <= 1e-6)
    assert res.n_evaluations >= res.steps.max() + 1 and res.n_syncs >= 1


def test_warp_force_kernel_sync_every_and_frozen_replicas():
    k, target, groups, x0 = _wells(1)
    k[groups == 2] = 3.0
    dev = "cpu"
    forces = _spring_forces(k, target, dev)

    runs = []
    for sync in (1, 5, 40):
        d = DeviceFire([0, 4, 8, 12], forces, device=dev, dt=0.01, max_move=None, sync_every=sync)
        d.set_positions(x0)
        runs.append((d.minimize(ftol=1e-8, max_steps=20_000, active=np.array([True, False, True])),
                     d.positions()))
    for res, x in runs:
        assert res.status == ["converged", "frozen", "converged"]
        np.testing.assert_array_equal(x[4:8], x0[4:8])  # frozen replica untouched
        np.testing.assert_allclose(x[:4], target[:4], atol=1e-7)
        np.testing.assert_array_equal(res.steps, runs[0][0].steps)
        np.testing.assert_array_equal(x, runs[0][1])
    assert np.isnan(runs[0][0].fmax[1])


def test_threads_per_replica_change_only_the_summation_order():
    """More threads per replica (what a small batch gets on a GPU) split each replica's row loop and its
    reductions: the same minimum and the same FIRE step counts as one thread per replica."""
    k, target, groups, x0 = _wells(2)
    k[groups == 1] = 5.0  # (the stiff wells stall under the move cap, see above)
    k[groups == 2] = 3.0
    dev = "cpu"
    forces = _spring_forces(k, target, dev)

    runs = []
    for nthr in (1, 3, 4):  # 3: rows per replica not a multiple; 4: one row per thread
        d = DeviceFire([0, 4, 8, 12], forces, device=dev, dt=0.01, max_move=0.05, sync_every=5,
                       remove_mean=(True, False, False), threads_per_replica=nthr)
        assert d.nthr == nthr
        d.set_positions(x0)
        runs.append((d.minimize(ftol=1e-8, max_steps=20_000), d.positions()))
    for res, x in runs[1:]:
        assert res.status == ["converged"] * 3
        np.testing.assert_array_equal(res.steps, runs[0][0].steps)
        np.testing.assert_allclose(x, runs[0][1], rtol=0, atol=1e-9)


def test_cuda_threads_per_replica_grows_for_small_batches():
    # big batches keep 64 threads per replica; small ones get more (<= 1,024, <= the rows), >= 16,384 in all
    assert cuda_threads_per_replica(500, 2562) == 64
    assert cuda_threads_per_replica(1000, 2562) == 64
    assert cuda_threads_per_replica(62, 2562) == 512
    assert cuda_threads_per_replica(1, 2562) == 1024
    assert cuda_threads_per_replica(1, 300) == 300
    for R in (1, 2, 7, 16, 33, 128, 255, 256):
        t = cuda_threads_per_replica(R, 10242)
        assert 64 <= t <= 1024 and (R * t >= 16384 or t == 1024)


def test_max_steps_nonfinite_and_max_move():
    d = DeviceFire([0, 1, 2], numpy_force_fn(lambda x: np.where(np.arange(2)[:, None] == 1, np.nan, -x)),
                   dt=0.01)
    d.set_positions(np.ones((2, 3)))
    res = d.minimize(ftol=1e-6, max_steps=5000)
    assert res.status == ["converged", "nonfinite"] and res.fmax[1] == np.inf
    d = DeviceFire([0, 2], numpy_force_fn(lambda x: -x), dt=0.01)
    d.set_positions(np.ones((2, 3)))
    res = d.minimize(ftol=1e-12, max_steps=3)
    assert res.status == ["max_steps"] and res.steps[0] == 3 and not res.all_converged
    d = DeviceFire([0, 1], numpy_force_fn(lambda x: np.full_like(x, 1e6)), dt=1.0, max_move=0.05)
    d.set_positions(np.zeros((1, 3)))
    d.minimize(ftol=1e-3, max_steps=1)
    assert np.linalg.norm(d.positions()[0]) <= 0.05 + 1e-12


def test_validation():
    fn = numpy_force_fn(lambda x: -x)
    with pytest.raises(ValueError, match="row_start"):
        DeviceFire([0, 0], fn)
    with pytest.raises(ValueError, match="dtype"):
        DeviceFire([0, 2], fn, dtype=np.float64)
    with pytest.raises(ValueError, match="free"):
        DeviceFire([0, 2], fn, free=np.ones((2, 2), bool))
    d = DeviceFire([0, 2], fn)
    with pytest.raises(ValueError, match="active"):
        d.minimize(active=np.ones(3, bool))
    assert not d.use_graph  # host callbacks are never captured


# ----- GPU (run on a CUDA machine: pytest -m gpu tests/sim/engine/test_minimize_device.py) ----------------
@pytest.mark.gpu
@pytest.mark.parametrize("minimizer", ["fire", "cg"])
def test_cuda_graph_matches_cpu(minimizer):
    wp.init()
    if not wp.get_cuda_device_count():
        pytest.skip("no CUDA device")
    from bubblecal.sim.engine import ShellParams, icosphere
    from bubblecal.sim.tiers.quasistatic import FireSettings, quasistatic_compression, quasistatic_indentation

    mesh = icosphere(6.0, 3)
    p = [ShellParams(ka=16751.0, kb=500.0), ShellParams(ka=4000.0, kb=300.0, b1=0.7, b2=0.75)]
    fire = FireSettings(minimizer=minimizer)
    for fn, grid, key in ((quasistatic_compression, [0.0, 0.12, 0.24], "force"),
                          (quasistatic_indentation, [0.0, 20.0, 40.0], "displacement")):
        cpu = fn(p, mesh, grid, device="cpu", fire=fire)
        gpu = fn(p, mesh, grid, device="cuda:0", fire=fire)
        assert gpu.status == cpu.status == ["ok", "ok"]
        ref = getattr(cpu, key)
        scale = np.max(np.abs(ref))
        # GPU atomics sum in another order: the minimiser may stop elsewhere within ftol
        assert np.max(np.abs(getattr(gpu, key) - ref)) < 2e-3 * scale
        if minimizer == "fire":  # float32 is FIRE's claim only (on CPU: <= 8e-4)
            f32 = fn(p, mesh, grid, device="cuda:0", dtype=wp.float32, fire=fire)
            assert f32.status == ["ok", "ok"]
            assert np.max(np.abs(getattr(f32, key) - ref)) < 1e-2 * scale


def test_export_import_rows_continues_the_same_iterates():
    # three independent springs; after a few steps replica 2 moves into a one-replica minimiser and must
    # finish exactly as it would have in the big one
    fn = numpy_force_fn(lambda x: -np.array([1.0, 2.0, 3.0])[:, None] * (x - 0.5))
    x0 = np.arange(9, dtype=float).reshape(3, 3) / 10
    ref = DeviceFire([0, 1, 2, 3], fn, dt=0.01)
    ref.set_positions(x0)
    ref.begin(ftol=1e-8, max_steps=10_000)
    ref.restart(np.ones(3, dtype=bool))
    for _ in range(3):
        ref.advance()
    state = ref.export_rows([2])
    small = DeviceFire([0, 1], numpy_force_fn(lambda x: -3.0 * (x - 0.5)), dt=0.01)
    small.import_rows(state)
    for _ in range(10_000):
        a, b = ref.advance(), small.advance()
        if not (np.any(a == 0) or np.any(b == 0)):  # 0 = ACTIVE
            break
    assert b[0] == a[2] != 0
    np.testing.assert_array_equal(small.positions()[0], ref.positions()[2])
    assert small.replica_report()[0][0] == ref.replica_report()[0][2]
    with pytest.raises(ValueError, match="do not match"):
        DeviceFire([0, 2], fn, dt=0.01).import_rows(state)
