"""Predictive metrics against analytic answers: Gaussian and mixture quantiles, coverage, MAP, bad inputs."""

import numpy as np
import pytest
from scipy import stats

from bubblecal.inference import (
    coverage,
    map_estimate,
    map_index,
    mixture_cdf,
    mixture_quantile,
    predictive_band,
    predictive_crps,
)


def test_single_component_gives_gaussian_quantiles():
    mu = np.array([[0.0, 5.0, -3.0, 1e3]])
    sd = np.array([[1.0, 0.1, 2.0, 50.0]])
    band = predictive_band(mu, sd, level=0.9)
    np.testing.assert_allclose(band.median, mu[0], atol=1e-7 * 1e3)
    np.testing.assert_allclose(band.lower, stats.norm.ppf(0.05, mu[0], sd[0]), rtol=1e-8, atol=1e-7)
    np.testing.assert_allclose(band.upper, stats.norm.ppf(0.95, mu[0], sd[0]), rtol=1e-8, atol=1e-7)
    # many identical components: same answer
    band2 = predictive_band(np.repeat(mu, 50, axis=0), np.repeat(sd, 50, axis=0))
    np.testing.assert_allclose(band2.upper, band.upper, rtol=1e-8)


def test_mixture_quantiles_invert_the_cdf():
    rng = np.random.default_rng(0)
    mu = rng.normal(size=(300, 6)) * [1, 10, 0.1, 5, 1, 100]
    sd = rng.uniform(0.05, 2.0, size=(300, 6)) * [1, 10, 0.1, 5, 1, 100]
    q = mixture_quantile(mu, sd, [0.05, 0.5, 0.95])
    assert q.shape == (3, 6)
    np.testing.assert_allclose(mixture_cdf(q, mu, sd), np.repeat([[0.05], [0.5], [0.95]], 6, axis=1), atol=1e-8)
    # symmetric two-component mixture: median at the centre, quantiles mirrored
    mu2 = np.array([[-2.0], [2.0]])
    sd2 = np.array([[0.5], [0.5]])
    band = predictive_band(mu2, sd2)
    assert band.median[0] == pytest.approx(0.0, abs=1e-8)
    assert band.lower[0] == pytest.approx(-band.upper[0], rel=1e-8)
    # weights: all weight on one component
    qw = mixture_quantile(mu2, sd2, 0.5, weights=[1.0, 0.0])
    assert qw[0] == pytest.approx(-2.0, abs=1e-8)


def test_coverage_and_band_membership():
    band = predictive_band(np.zeros((1, 4)), np.ones((1, 4)))
    y = np.array([0.0, 1.0, 2.0, -1.6])
    assert coverage(y, band.lower, band.upper) == pytest.approx(0.75)
    assert band.coverage(y) == pytest.approx(0.75)
    # nominal coverage on draws from the predictive itself
    rng = np.random.default_rng(1)
    y = rng.normal(size=20000)
    b = predictive_band(np.zeros((1, y.size)), np.ones((1, y.size)))
    assert abs(coverage(y, b.lower, b.upper) - 0.9) < 4 * np.sqrt(0.09 / y.size)


def test_map():
    lp = np.array([-3.0, np.nan, -1.0, -np.inf, -2.0])
    assert map_index(lp) == 2
    est = map_estimate({"ka": np.arange(5.0), "kb": np.arange(5.0) * 10}, lp)
    assert est == {"ka": 2.0, "kb": 20.0}
    np.testing.assert_array_equal(map_estimate(np.arange(10.0).reshape(5, 2), lp), [4.0, 5.0])
    with pytest.raises(ValueError):
        map_index([np.nan, -np.inf])


def test_bad_inputs():
    with pytest.raises(ValueError):
        predictive_band(np.zeros((3, 2)), -np.ones((3, 2)))
    with pytest.raises(ValueError):
        mixture_quantile(np.zeros((3, 2)), np.ones((3, 2)), 1.0)
    with pytest.raises(ValueError):
        predictive_crps(np.zeros((3, 2)), np.ones((3, 2)), np.zeros(3))


def test_point_mass_component():
    """A zero-sd component is a point mass: the CDF jumps from 0.25 to 0.75 at 0, so the median is 0."""
    q = mixture_quantile(np.array([[0.0], [0.0]]), np.array([[0.0], [1.0]]), [0.5, 0.95])
    assert q[0, 0] == pytest.approx(0.0, abs=1e-9)
    assert q[1, 0] == pytest.approx(stats.norm.ppf(0.9), rel=1e-8)  # 0.5 + 0.5 Phi(z) = 0.95
