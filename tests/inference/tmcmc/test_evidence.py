"""Analytic log evidence of TMCMC (inference.md §6).

Three problems with closed-form log Z:
(a) 1-D Gaussian likelihood under a uniform box prior (erf);
(b) isotropic Gaussian likelihood, d = 10, s = 0.1, box ±10 (erf per dimension);
(c) correlated Gaussian likelihood (d = 10, ρ = 0.95) with a Gaussian prior:
    log Z = log N(μ_L | μ_p, Σ_L + Σ_p).
Fast versions (default suite) at small N; the slow versions at N = 10⁴ over 10 seeds assert a mean
bias ≤ 0.15 nats and print the seed-to-seed spread.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist
import pytest
from scipy.special import erf
from scipy.stats import multivariate_normal, norm

from bubblecal.inference import TMCMC


def box_1d():
    lo, hi, y, s = -3.0, 5.0, 1.2, 0.3

    def model_box_1d():
        x = numpyro.sample("x", dist.Uniform(lo, hi))
        numpyro.sample("y", dist.Normal(x, s), obs=y)

    exact = math.log((norm.cdf((hi - y) / s) - norm.cdf((lo - y) / s)) / (hi - lo))
    return model_box_1d, exact


def iso_10d():
    d, s, half = 10, 0.1, 10.0

    def model_iso_10d():
        x = numpyro.sample("x", dist.Uniform(-half, half).expand([d]).to_event(1))
        numpyro.factor("lik", dist.Normal(0.0, s).log_prob(x).sum())

    exact = d * (math.log(erf(half / (s * math.sqrt(2.0)))) - math.log(2 * half))
    return model_iso_10d, exact


def corr_10d():
    d, rho = 10, 0.95
    mu_p = np.zeros(d)
    cov_p = 4.0 * np.eye(d)
    cov_l = 0.25 * ((1 - rho) * np.eye(d) + rho * np.ones((d, d)))
    mu_l = np.linspace(-1.0, 1.0, d)
    tril_l = jnp.asarray(np.linalg.cholesky(cov_l))
    tril_p = jnp.asarray(np.linalg.cholesky(cov_p))

    def model_corr_10d():
        x = numpyro.sample("x", dist.MultivariateNormal(jnp.asarray(mu_p), scale_tril=tril_p))
        numpyro.sample("y", dist.MultivariateNormal(x, scale_tril=tril_l), obs=jnp.asarray(mu_l))

    exact = float(multivariate_normal(mu_p, cov_p + cov_l).logpdf(mu_l))
    return model_corr_10d, exact


PROBLEMS = {"box_1d": box_1d, "iso_10d": iso_10d, "corr_10d": corr_10d}


def corr_posterior():
    d, rho = 10, 0.95
    cov_p = 4.0 * np.eye(d)
    cov_l = 0.25 * ((1 - rho) * np.eye(d) + rho * np.ones((d, d)))
    mu_l = np.linspace(-1.0, 1.0, d)
    post_cov = np.linalg.inv(np.linalg.inv(cov_p) + np.linalg.inv(cov_l))
    return post_cov @ np.linalg.solve(cov_l, mu_l), post_cov


@pytest.mark.parametrize("name", list(PROBLEMS))
def test_log_evidence_fast(name):
    """N = 2,000, 3 replicas: within 0.35 nats of the closed form (and within 5 SE + 0.1)."""
    model, exact = PROBLEMS[name]()
    tm = TMCMC(model, num_particles=2000, num_replicas=3, compiled=True).run(jax.random.PRNGKey(11))
    assert tm.status == "converged"
    err = tm.log_evidence - exact
    assert abs(err) <= 0.35, (name, tm.log_evidences, exact)
    assert abs(err) <= 5 * tm.log_evidence_se + 0.1, (name, tm.log_evidences, exact)
    assert np.all(np.isfinite(tm.log_evidences))
    if name == "corr_10d":
        # the final particles have the analytic posterior mean, sds and correlation
        post_mean, post_cov = corr_posterior()
        x = tm.get_samples()["x"]
        sd = np.sqrt(np.diag(post_cov))
        assert np.all(np.abs(x.mean(0) - post_mean) / sd < 0.15)
        assert np.all(np.abs(x.std(0) / sd - 1) < 0.15)
        assert abs(np.corrcoef(x.T)[0, 1] - post_cov[0, 1] / (sd[0] * sd[1])) < 0.05


@pytest.mark.slow
@pytest.mark.parametrize("name", list(PROBLEMS))
def test_log_evidence_slow(name):
    """N = 10⁴ over 10 seeds: mean bias ≤ 0.15 nats; spread printed (run with -s to see it)."""
    model, exact = PROBLEMS[name]()
    tm = TMCMC(model, num_particles=10_000, num_replicas=10, compiled=True).run(jax.random.PRNGKey(2026))
    z = tm.log_evidences
    bias = z.mean() - exact
    print(
        f"\n{name}: exact {exact:.4f}  mean {z.mean():.4f}  bias {bias:+.4f}  sd {z.std(ddof=1):.4f}  "
        f"se {tm.log_evidence_se:.4f}  min {z.min():.4f}  max {z.max():.4f}  stages {len(tm.stage_info) - 1}"
    )
    assert tm.status == "converged"
    assert abs(bias) <= 0.15
