"""Sobol indices via SALib: Ishigami (analytic indices), pointwise along x, averaging over an x-range."""

import math

import numpy as np
import pytest

from bubblecal.inference import SobolResult, saltelli_design, sobol_along

A, B = 7.0, 0.1
_V = A**2 / 8 + B * math.pi**4 / 5 + B**2 * math.pi**8 / 18 + 0.5
_V1 = 0.5 * (1 + B * math.pi**4 / 5) ** 2
_V2 = A**2 / 8
_V13 = B**2 * math.pi**8 * (1 / 18 - 1 / 50)
S1_TRUE = np.array([_V1 / _V, _V2 / _V, 0.0])
ST_TRUE = np.array([(_V1 + _V13) / _V, _V2 / _V, _V13 / _V])
BOX = {"x1": (-math.pi, math.pi), "x2": (-math.pi, math.pi), "x3": (-math.pi, math.pi)}


def ishigami(p, x):
    x1, x2, x3 = p[..., 0], p[..., 1], p[..., 2]
    return (np.sin(x1) + A * np.sin(x2) ** 2 + B * x3**4 * np.sin(x1)) * np.ones_like(x)


def test_analytic_values():
    np.testing.assert_allclose(S1_TRUE, [0.3139, 0.4424, 0.0], atol=1e-4)
    np.testing.assert_allclose(ST_TRUE, [0.5576, 0.4424, 0.2437], atol=1e-4)


def test_ishigami_indices():
    res = sobol_along(ishigami, BOX, np.array([0.0, 1.0]), N=1024, num_resamples=50, seed=1)
    assert isinstance(res, SobolResult)
    assert res.S1.shape == (2, 3) and res.n_evaluations == 1024 * 5
    np.testing.assert_allclose(res.S1_mean, S1_TRUE, atol=0.08)
    np.testing.assert_allclose(res.ST_mean, ST_TRUE, atol=0.08)
    # the bootstrap intervals are honest: analytic values within ~2 half-widths
    assert np.all(np.abs(res.S1_mean - S1_TRUE) < 2.5 * res.S1_conf_mean + 0.01)
    assert np.all(np.abs(res.ST_mean - ST_TRUE) < 2.5 * res.ST_conf_mean + 0.01)
    assert [r["parameter"] for r in res.table()] == ["x1", "x2", "x3"]
    assert "x3" in res.summary()


def test_pointwise_along_x_and_range_average():
    """y = x p0 + p1 with p0, p1 ~ U(0, 1): S1_0(x) = x^2 / (x^2 + 1); x = 0 has S1_0 = 0."""
    def fn(p, x):
        return x * p[..., 0] + p[..., 1]

    x = np.array([0.0, 0.5, 1.0, 2.0, 3.0])
    res = sobol_along(fn, (("p0", "p1"), [0.0, 0.0], [1.0, 1.0]), x, N=512, x_range=(0.4, 2.5), num_resamples=30)
    want = x**2 / (x**2 + 1)
    np.testing.assert_allclose(res.S1[:, 0], want, atol=0.05)
    np.testing.assert_allclose(res.ST[:, 1], 1 - want, atol=0.05)
    np.testing.assert_array_equal(res.in_range, [False, True, True, True, False])
    np.testing.assert_allclose(res.S1_mean[0], want[1:4].mean(), atol=0.04)


def test_zero_variance_points_are_excluded():
    def fn(p, x):
        return x * p[..., 0]  # no variance at x = 0

    res = sobol_along(fn, {"a": (1.0, 2.0), "b": (0.0, 1.0)}, np.array([0.0, 1.0]), N=256, num_resamples=20)
    assert np.isnan(res.S1[0]).all() and not res.in_range[0]
    assert res.S1_mean[0] == pytest.approx(1.0, abs=0.05)


def test_design_and_bad_input():
    X = saltelli_design(BOX, 64)
    assert X.shape == (64 * 5, 3) and np.all(np.abs(X) <= math.pi)
    with pytest.raises(ValueError, match="power of two"):
        saltelli_design(BOX, 1000)
    with pytest.raises(ValueError, match="lo < hi"):
        saltelli_design({"a": (1.0, 1.0)}, 64)


def test_fixed_inputs_with_order():
    """Vary x1, x2 of Ishigami with x3 held at 0: V = V1' + V2 with V1' = 1/2, S1 = (1/2, A^2/8) / V."""
    res = sobol_along(ishigami, {"x2": BOX["x2"], "x1": BOX["x1"]}, np.array([1.0]), N=1024, num_resamples=20,
                      order=("x1", "x2", "x3"), fixed={"x3": 0.0})
    v = 0.5 + A**2 / 8
    np.testing.assert_allclose(res.S1_mean, [A**2 / 8 / v, 0.5 / v], atol=0.06)
    assert res.names == ("x2", "x1")
    with pytest.raises(ValueError, match="no value"):
        sobol_along(ishigami, {"x1": BOX["x1"]}, np.array([1.0]), N=64, order=("x1", "x2", "x3"))
