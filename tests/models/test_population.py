"""Pure population densities: truncated-normal population prior, staged-hierarchy sums."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats
from scipy.special import logsumexp

from bubblecal.models import (
    importance_ess,
    importance_log_weights,
    log_truncnorm,
    population_log_prob,
    population_predictive_log_density,
    staged_log_likelihood,
    truncnorm_icdf,
)
from bubblecal.models.population import log_truncation_mass

CASES = [  # (m, tau, lo, hi)
    (0.3, 0.2, 0.0, 1.0),
    (1.0, 0.05, 0.0, 1.0),      # mean on the upper edge, narrow
    (1.3e4, 1.5e3, 3.5e3, 3.4e4),
    (0.0, 5.0, -0.5, 0.5),      # wide: nearly uniform
    (-0.5, 0.01, -0.5, 0.5),
]


@pytest.mark.parametrize("m,tau,lo,hi", CASES)
def test_truncnorm_normalised_and_matches_scipy(m, tau, lo, hi):
    grid = np.linspace(lo, hi, 200_001)
    dens = np.exp(np.asarray(log_truncnorm(jnp.asarray(grid), m, tau, lo, hi), dtype=float))
    assert np.trapezoid(dens, grid) == pytest.approx(1.0, abs=2e-3)
    ref = stats.truncnorm((lo - m) / tau, (hi - m) / tau, loc=m, scale=tau)
    pts = np.linspace(lo, hi, 7)
    got = np.asarray(log_truncnorm(jnp.asarray(pts), m, tau, lo, hi), dtype=float)
    np.testing.assert_allclose(got, ref.logpdf(pts), rtol=2e-4, atol=2e-4)


def test_truncnorm_outside_and_degenerate_tau():
    lp = log_truncnorm(jnp.array([-0.1, 1.1]), 0.5, 0.1, 0.0, 1.0)
    assert np.all(np.isneginf(np.asarray(lp)))
    lp0 = log_truncnorm(jnp.array([0.2, 0.5]), 0.5, 0.0, 0.0, 1.0)  # tau = 0 is floored, never NaN
    assert not np.any(np.isnan(np.asarray(lp0)))


def test_truncation_mass_far_tail_is_finite_and_accurate():
    # interval 10..40 standard deviations above the mean: the naive difference of CDFs underflows
    got = float(log_truncation_mass(0.0, 1.0, 10.0, 40.0))
    assert got == pytest.approx(float(stats.norm.logsf(10.0)), rel=1e-4)
    got = float(log_truncation_mass(0.0, 1.0, -40.0, -10.0))
    assert got == pytest.approx(float(stats.norm.logcdf(-10.0)), rel=1e-4)


@pytest.mark.parametrize("m,tau,lo,hi", CASES)
def test_icdf_inverts_cdf(m, tau, lo, hi):
    u = np.linspace(0.01, 0.99, 11)
    x = np.asarray(truncnorm_icdf(jnp.asarray(u), m, tau, lo, hi), dtype=float)
    ref = stats.truncnorm((lo - m) / tau, (hi - m) / tau, loc=m, scale=tau)
    np.testing.assert_allclose(ref.cdf(x), u, atol=2e-3)


def _brute_staged(m, tau, datasets, bounds):
    total = 0.0
    for samples in datasets:
        lw = 0.0
        for k in m:
            if k not in samples:
                continue
            lo, hi = bounds[k]
            a, b = (lo - m[k]) / tau[k], (hi - m[k]) / tau[k]
            lw = lw + stats.truncnorm(a, b, loc=m[k], scale=tau[k]).logpdf(samples[k]) + math.log(hi - lo)
        total += logsumexp(lw) - math.log(len(lw))
    return total


def test_staged_log_likelihood_matches_brute_force_and_vectorises():
    rng = np.random.default_rng(1)
    bounds = {"ka": (1.0, 10.0), "d0": (0.0, 0.5)}
    datasets = [{"ka": rng.uniform(3, 6, 400), "d0": rng.uniform(0.1, 0.2, 400), "sigma": rng.uniform(0, 1, 400)},
                {"ka": rng.uniform(4, 7, 300), "d0": rng.uniform(0.0, 0.3, 300)},
                {"ka": rng.uniform(2, 8, 200)}]  # an acoustic dataset: k_a only
    psis = [({"ka": 5.0, "d0": 0.15}, {"ka": 1.0, "d0": 0.1}), ({"ka": 4.0, "d0": 0.3}, {"ka": 2.5, "d0": 0.05})]
    jdata = [{k: jnp.asarray(v) for k, v in d.items()} for d in datasets]
    loglik = jax.jit(lambda m, tau: staged_log_likelihood(m, tau, jdata, bounds))  # as a sampler would call it
    # a batch of psi in one call
    mb = {k: jnp.array([p[0][k] for p in psis]) for k in bounds}
    tb = {k: jnp.array([p[1][k] for p in psis]) for k in bounds}
    batch = np.asarray(loglik(mb, tb))
    assert batch.shape == (2,)
    np.testing.assert_allclose(batch, [_brute_staged(m, t, datasets, bounds) for m, t in psis], rtol=1e-4)


def test_importance_ess():
    assert float(importance_ess(jnp.zeros(50))) == pytest.approx(50.0, rel=1e-5)
    assert float(importance_ess(jnp.array([0.0] + [-jnp.inf] * 9))) == pytest.approx(1.0)
    assert float(importance_ess(jnp.full(5, -jnp.inf))) == 0.0
    lw = importance_log_weights({"ka": 5.0}, {"ka": 1.0}, {"ka": jnp.linspace(2, 8, 100)}, {"ka": (0.0, 10.0)})
    assert lw.shape == (100,) and 1.0 < float(importance_ess(lw)) < 100.0


def test_population_predictive_and_joint_prior():
    bounds = {"ka": (0.0, 10.0), "kb": (0.0, 1.0)}
    theta = {"ka": jnp.array([2.0, 5.0]), "kb": jnp.array([0.5, 0.1])}
    m = {"ka": jnp.array([4.0, 6.0]), "kb": jnp.array([0.4, 0.6])}
    tau = {"ka": jnp.array([1.0, 2.0]), "kb": jnp.array([0.2, 0.3])}
    got = np.asarray(population_predictive_log_density(theta, m, tau, bounds))
    ref = []
    for j in range(2):
        terms = [float(population_log_prob({k: v[j] for k, v in theta.items()}, {k: v[s] for k, v in m.items()},
                                           {k: v[s] for k, v in tau.items()}, bounds)) for s in range(2)]
        ref.append(logsumexp(terms) - math.log(2))
    np.testing.assert_allclose(got, ref, rtol=1e-5)


def test_population_predictive_draws():
    from bubblecal.models import sample_population_predictive

    m = {"ka": jnp.array([5.0, 5.0]), "d0": jnp.array([0.1, 0.1])}
    tau = {"ka": jnp.array([2.0, 2.0]), "d0": jnp.array([0.2, 0.2])}
    bounds = {"ka": (1.0, 10.0), "d0": (0.0, 0.5)}
    draws = sample_population_predictive(jax.random.PRNGKey(0), m, tau, bounds, 4000)
    for k in ("ka", "d0"):
        lo, hi = bounds[k]
        ref = stats.truncnorm((lo - float(m[k][0])) / float(tau[k][0]), (hi - float(m[k][0])) / float(tau[k][0]),
                              loc=float(m[k][0]), scale=float(tau[k][0]))
        assert stats.kstest(np.asarray(draws[k]), ref.cdf).pvalue > 1e-3
