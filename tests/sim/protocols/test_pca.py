"""PCA breathing-mode estimate on synthetic vertex trajectories with a known answer."""

from __future__ import annotations

import numpy as np
import pytest

from bubblecal.sim.engine.mesh import icosphere
from bubblecal.sim.protocols import breathing_mode_pca, remove_rigid_motion, spectral_peak


def _trajectory(f0=1.7, lam=0.3, n=400, dt=0.01, seed=0, rotate=True):
    m = icosphere(3.0, 1)
    v = m.vertices
    rhat = v / np.linalg.norm(v, axis=1, keepdims=True)
    t = np.arange(n) * dt
    wd = np.sqrt((2 * np.pi * f0) ** 2 - lam**2)
    a = 0.15 * np.exp(-lam * t) * np.cos(wd * t)
    b = 0.03 * np.sin(2 * np.pi * 3.1 * t)  # a non-breathing (P2-like) shape mode at 3.1
    pat2 = np.zeros_like(v)
    pat2[:, 2] = v[:, 2] ** 2 / 9 - 1 / 3
    rng = np.random.default_rng(seed)
    x = v[None] + a[:, None, None] * rhat[None] + b[:, None, None] * pat2[None] + rng.normal(0, 0.005, (n, *v.shape))
    if rotate:  # slow rigid rotation about z + drift: removed by the alignment
        ang = 0.05 * t
        c, s = np.cos(ang), np.sin(ang)
        rot = np.zeros((n, 3, 3))
        rot[:, 0, 0], rot[:, 0, 1], rot[:, 1, 0], rot[:, 1, 1], rot[:, 2, 2] = c, -s, s, c, 1
        x = np.einsum("tij,tvj->tvi", rot, x)
    x = x + np.array([0.1, 0.2, 0.3]) * t[:, None, None]
    return x, t, f0, lam


def test_breathing_mode_found_and_frequency():
    x, t, f0, lam = _trajectory()
    r = breathing_mode_pca(x, t)
    assert r.radial_overlap > 0.99
    assert r.resolution == pytest.approx(1 / (t.size * (t[1] - t[0])))
    assert abs(r.f_0 - f0) < 0.1 * r.resolution
    assert r.coordinate.shape == t.shape and r.pattern.shape == (42, 3)
    assert r.as_dict()["component"] == r.component


def test_rigid_motion_removed():
    x, t, _, _ = _trajectory(lam=0.0, rotate=True)
    y = remove_rigid_motion(x)
    x0, _, _, _ = _trajectory(lam=0.0, rotate=False)
    y0 = remove_rigid_motion(x0)
    assert np.allclose(y.mean(axis=1), 0.0, atol=1e-9)
    spread = np.std(y - y.mean(axis=0))
    assert spread == pytest.approx(np.std(y0 - y0.mean(axis=0)), rel=1e-6)
    raw = remove_rigid_motion(x, align=False)
    assert np.std(raw - raw.mean(axis=0)) > 1.5 * spread  # the rotation dominates without the alignment


def test_spectral_peak_and_errors():
    t = np.arange(400) * 0.02
    p = spectral_peak(t, np.sin(2 * np.pi * 2.3 * t))
    assert abs(p["f_peak"] - 2.3) < 0.02 * p["resolution"] + 1e-3
    with pytest.raises(ValueError, match="uniform"):
        spectral_peak(np.r_[t[:-1], t[-1] + 0.5], np.sin(t))
    with pytest.raises(ValueError, match=r"\[T, Nv, 3\]"):
        breathing_mode_pca(np.zeros((10, 5)), np.arange(10.0))
    with pytest.raises(ValueError, match="8 frames"):
        breathing_mode_pca(np.random.default_rng(0).normal(size=(5, 12, 3)), np.arange(5.0))
