"""CRPS against analytic answers: brute-force ensemble sums, Gaussian closed form, mixture by quadrature."""

import numpy as np
import pytest

from bubblecal.inference import crps_ensemble, gaussian_crps, mixture_cdf, predictive_crps


def test_crps_ensemble_matches_brute_force():
    rng = np.random.default_rng(2)
    z = rng.normal(size=(40, 3))
    y = np.array([0.3, -1.0, 2.0])
    pair = np.abs(z[:, None, :] - z[None, :, :]).sum(axis=(0, 1))
    for fair, denom in ((False, 2 * 40 * 40), (True, 2 * 40 * 39)):
        want = np.abs(z - y).mean(axis=0) - pair / denom
        np.testing.assert_allclose(crps_ensemble(z, y, fair=fair), want, rtol=1e-12)


def test_crps_of_a_gaussian_matches_closed_form_within_mc_error():
    mu, sd = 1.0, 2.0
    y = np.array([1.0, 2.5, -3.0, 7.0])
    S = 4000
    res = predictive_crps(np.full((S, y.size), mu), np.full((S, y.size), sd), y, replicates=5, seed=3, fair=True)
    exact = gaussian_crps(mu, sd, y)
    assert res.replicates.shape == (5,)
    # MC standard error of the point-averaged score from the replicate spread (plus a floor)
    se = max(res.mc_error, 1e-3)
    assert abs(res.mean - exact.mean()) < 5 * se
    np.testing.assert_allclose(res.per_point, exact, rtol=0.1)
    # the default (empirical-CDF) estimator is biased upward by E|X - X'| / (2M) = sd / (sqrt(pi) M)
    res_nrg = predictive_crps(np.full((S, y.size), mu), np.full((S, y.size), sd), y, replicates=5, seed=3)
    assert res_nrg.mean - res.mean == pytest.approx(sd / np.sqrt(np.pi) / S, rel=0.2)


def test_crps_of_a_mixture_matches_quadrature():
    rng = np.random.default_rng(4)
    mu = rng.normal(0.0, 2.0, size=(400, 2))
    sd = rng.uniform(0.5, 1.5, size=(400, 2))
    y = np.array([0.5, 3.0])
    z = np.linspace(-15, 15, 6001)
    F = mixture_cdf(np.repeat(z[:, None], 2, axis=1), mu, sd)
    exact = [np.trapezoid((F[:, p] - (z >= y[p])) ** 2, z) for p in range(2)]
    res = predictive_crps(np.tile(mu, (10, 1)), np.tile(sd, (10, 1)), y, replicates=5, seed=5, fair=True)
    np.testing.assert_allclose(res.per_point, exact, rtol=0.05)
