"""Ringdown protocol (physics.md section 5, check 7): shapes, perturbation, f ~ M^-1/2, check 7, PCA.

Default tests use the implicit tier at a tiny size (1.5 um, icosphere level 1: 42 vertices; ~10 s);
the explicit tier runs a consistency check of the perturbation (no particle changes side) here and
its physics in the slow test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bubblecal.sim.protocols import (
    RingdownBatch,
    auto_schedule,
    breathing_mode_pca,
    breathing_mode_prediction,
    ringdown_batch,
)
from bubblecal.surrogates import fit_ringdown

KA = np.array([5584.0, 20000.0])
KB = np.array([389.23, 389.23])
TINY = dict(tier="implicit", subdivisions=1, equilibration_steps=300, n_periods=6, samples_per_period=20)


@pytest.fixture(scope="module")
def implicit_runs():
    """Two mass factors, same parameters and seeds (vertices recorded for the PCA at 160)."""
    import warp as wp

    wp.config.quiet = True
    heavy = ringdown_batch(1.5, {"ka": KA, "kb": KB}, [11, 12], mass_factor=160.0, record_vertices=True, **TINY)
    light = ringdown_batch(1.5, {"ka": KA, "kb": KB}, [11, 12], mass_factor=40.0, **TINY)
    return heavy, light


def _omega0(batch: RingdownBatch) -> np.ndarray:
    return np.array([2 * math.pi * fit_ringdown(batch.t, batch.radius[r]).f_0 for r in range(batch.n_replicas)])


def test_batch_shapes_and_info(implicit_runs):
    heavy, _ = implicit_runs
    R, T = 2, heavy.t.size
    assert heavy.radius.shape == (R, T) and heavy.status == ["ok", "ok"] and heavy.ok.all()
    assert heavy.t[0] == 0.0 and np.all(np.diff(heavy.t) > 0)
    info = heavy.info
    assert info["n_vertices"] == 42 and info["mass_factor"] == 160.0
    assert info["shell_mass"] == pytest.approx(42 * info["vertex_mass"])
    # the vertex mass carries the mass factor: rho h A / N_v x 160
    from bubblecal.sim.engine.mesh import mesh_for_diameter

    assert info["vertex_mass"] == pytest.approx(mesh_for_diameter(1.5, 1).vertex_mass(mass_factor=160.0))
    # t = 0 is right after the homothety 1 + 0.015 of the equilibrium shell
    r_eq = np.array(info["radius_equilibrium"])
    assert np.allclose(heavy.radius[:, 0] / r_eq, 1.015, atol=0.004)
    assert heavy.vertices.shape == (R, heavy.vertex_t.size, 42, 3) and heavy.vertex_t.size == T


def test_mass_scaling(implicit_runs):
    """(a) f ~ M^-1/2: mass factors 160 and 40 give f_0 ratios of 2 within 3 %.

    In the implicit tier the shell is the only inertia, so the scaling is exact up to the fit's
    statistical error (thermal noise ~ sqrt(k_BT / 16 pi k_a) ~ 2e-3 against a 0.045 amplitude) and
    the friction, which f_0 = sqrt(w_d^2 + lam^2) / 2 pi removes (lam ~ gamma / 2 m grows 4x: checked)."""
    heavy, light = implicit_runs
    ratio = _omega0(light) / _omega0(heavy)
    assert np.all(np.abs(ratio - 2.0) < 0.06), ratio
    lam_h = np.array([fit_ringdown(heavy.t, heavy.radius[r]).lam for r in range(2)])
    lam_l = np.array([fit_ringdown(light.t, light.radius[r]).lam for r in range(2)])
    assert np.all(np.abs(lam_l / lam_h - 4.0) < 1.2)


def test_check7_ratio(implicit_runs):
    """(b) physics.md check 7: omega0^2 = (16 pi ka + 12 pi R p_g) / M.

    Measured / predicted is A_mesh / (4 pi r_v^2) = 0.928 on this 42-vertex icosphere (the uniform
    dilation of equal-mass vertices on an inscribed polyhedron; 0.9988 at subdivision 4), and 1 within
    4 % once that is included (thermal softening, the fit's error and the 1.5 % amplitude's
    anharmonicity are each <~ 1 %)."""
    heavy, light = implicit_runs
    for b in (heavy, light):
        w2 = _omega0(b) ** 2
        pred = b.info["prediction"]
        ratio_mesh = w2 / np.array(pred["omega0_sq_mesh"])
        ratio = w2 / np.array(pred["omega0_sq"])
        assert np.all(np.abs(ratio_mesh - 1.0) < 0.04), ratio_mesh
        assert np.all(np.abs(ratio - pred["area_ratio"][0]) < 0.04), ratio
        assert np.allclose(b.info["p_gas"], 3.0, rtol=0.02)


def test_pca_matches_ringdown(implicit_runs):
    """(c) the breathing mode found by PCA of the vertex trajectories has the ringdown's f_0 within
    the spectral resolution 1 / T_span."""
    heavy, _ = implicit_runs
    for r in range(2):
        fit = fit_ringdown(heavy.t, heavy.radius[r])
        pca = breathing_mode_pca(heavy.vertices[r], heavy.vertex_t)
        assert pca.radial_overlap > 0.9
        assert abs(pca.f_0 - fit.f_0) <= pca.resolution, (pca.f_0, fit.f_0, pca.resolution)


def test_prediction_formula():
    p = breathing_mode_prediction(5584.0, 9.36, 3.0, 11660.0)
    assert p["omega0_sq"] == pytest.approx((16 * math.pi * 5584.0 + 12 * math.pi * 9.36 * 3.0) / 11660.0)
    pe = breathing_mode_prediction(5584.0, 9.36, 3.0, 11660.0, explicit=True, box=(23.7, 23.7, 28.7))
    assert pe["added_mass"] > 0 and pe["omega0_sq_water"] < pe["omega0_sq"] * 1.2
    with pytest.raises(ValueError, match="box"):
        breathing_mode_prediction(5584.0, 9.36, 3.0, 11660.0, explicit=True)
    s = auto_schedule(10.0, 20.0, 1e-3, n_periods=5, samples_per_period=20)
    assert s["record_steps"] % s["record_every"] == 0
    assert s["record_steps"] * 1e-3 >= 5 * 2 * math.pi / 10.0


@pytest.mark.parametrize("kwargs, match", [
    (dict(tier="quasistatic"), "tier"),
    (dict(mass_factor=0.0), "mass_factor"),
    (dict(perturbation=0.5), "perturbation"),
    (dict(record_every=0), "record_every"),
])
def test_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ringdown_batch(1.5, {"ka": KA, "kb": KB}, [1, 2], **kwargs)


def test_bad_params():
    with pytest.raises(ValueError, match="seed"):
        ringdown_batch(1.5, {"ka": KA, "kb": KB}, [1])
    with pytest.raises(ValueError, match="'ka' and 'kb'"):
        ringdown_batch(1.5, {"ka": KA}, [1, 2])
    with pytest.raises(ValueError, match="unknown"):
        ringdown_batch(1.5, {"ka": KA, "kb": KB, "kx": KA}, [1, 2])
    with pytest.raises(ValueError, match="ka must be > 0"):
        ringdown_batch(1.5, {"ka": -KA, "kb": KB}, [1, 2])
    with pytest.raises(ValueError, match="diameter"):
        ringdown_batch(50.0, {"ka": KA, "kb": KB}, [1, 2])


def test_explicit_perturbation_keeps_sides():
    """Explicit tier: the homothety + water taper moves no water inside and no gas outside."""
    import warp as wp

    wp.config.quiet = True
    b = ringdown_batch(1.0, {"ka": KA[:1], "kb": KB[:1]}, [5], tier="explicit", subdivisions=1, dt=2e-4,
                       equilibration_steps=40, record_steps=40, record_every=20)
    h = b.info["health_after_perturbation"]
    assert h["water_inside"] == [0] and h["gas_outside"] == [0] and b.status == ["ok"]
    assert b.radius.shape == (1, 3)
    assert b.radius[0, 0] / b.info["radius_equilibrium"][0] == pytest.approx(1.015, abs=0.01)


@pytest.mark.slow
def test_explicit_ringdown_physics():
    """Explicit tier (water + gas), 1.5 um, level 2, CPU (~5 min per mass factor): a clean damped ringdown whose
    omega0 lies between the water-loaded estimate and ~1.1x check 7 (measured 0.94x check 7 at mass factor 160;
    at 40 the water contact layer stiffens it to 1.28x: f ~ M^-1/2 does NOT hold with explicit water, see
    benchmarks/RESULTS.md)."""
    import warp as wp

    wp.config.quiet = True
    b = ringdown_batch(1.5, {"ka": KA[:1], "kb": KB[:1]}, [7], tier="explicit", subdivisions=2, dt=3e-4,
                       mass_factor=160.0, equilibration_steps=1000, n_periods=6, samples_per_period=30)
    fit = fit_ringdown(b.t, b.radius[0])
    pred = b.info["prediction"]
    w0 = 2 * math.pi * fit.f_0
    assert b.status == ["ok"] and fit.r2 > 0.9
    assert 0.9 * pred["omega0_water"][0] < w0 < 1.1 * pred["omega0"][0]


@pytest.mark.gpu
def test_implicit_check7_production_mesh():
    """Implicit tier on a CUDA device at a production mesh (4.68 um, level 4): check-7 ratio 1 within 3 %."""
    import warp as wp

    wp.init()
    if not wp.is_cuda_available():
        pytest.skip("no CUDA device")
    b = ringdown_batch(4.68, {"ka": np.array([3500.0, 34000.0]), "kb": KB}, [1, 2], tier="implicit", device="cuda")
    ratios = _omega0(b) ** 2 / np.array(b.info["prediction"]["omega0_sq"])
    assert np.all(np.abs(ratios - 1.0) < 0.03), ratios
