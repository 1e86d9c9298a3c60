"""TMCMCKernel: TMCMC under numpyro.infer.MCMC (docs/inference.md section 5).

The conjugate model: m ~ N(mu0, tau0²), y_i | m ~ N(m, sigma²) (n = 5), plus a LogNormal(0, 0.5) site
``s`` that the data do not see (its posterior is its prior) and a deterministic ``m2 = 2 m``. Posterior
of m: precision 1/tau0² + n/sigma²; log Z = log N(y | mu0 1, sigma² I + tau0² 11ᵀ).
Tolerances are Monte Carlo ones for N = 2,000 correlated particles (ESS of a few hundred at least):
mean within 0.15 posterior sd, sd within 10 %, log Z within 0.15 nats (the suite's evidence tolerance).
"""

from __future__ import annotations

import math

import arviz as az
import jax
import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist
import pytest
from numpyro.infer import MCMC
from scipy.stats import multivariate_normal

from bubblecal.inference import TMCMC, TMCMCKernel

MU0, TAU0, SIGMA = 0.5, 2.0, 0.7
Y = np.array([1.1, 0.4, 1.9, 1.3, 0.8])
N = 2000


def conjugate(y):
    """The conjugate model of the module docstring."""
    m = numpyro.sample("m", dist.Normal(MU0, TAU0))
    numpyro.sample("s", dist.LogNormal(0.0, 0.5))
    numpyro.deterministic("m2", 2.0 * m)
    numpyro.sample("y", dist.Normal(m, SIGMA), obs=y)


def analytic():
    """(posterior mean, posterior sd, log Z) of m in the conjugate model."""
    prec = 1.0 / TAU0**2 + len(Y) / SIGMA**2
    mean = (MU0 / TAU0**2 + Y.sum() / SIGMA**2) / prec
    cov = SIGMA**2 * np.eye(len(Y)) + TAU0**2 * np.ones((len(Y), len(Y)))
    log_z = multivariate_normal(np.full(len(Y), MU0), cov).logpdf(Y)
    return mean, 1.0 / math.sqrt(prec), float(log_z)


@pytest.fixture(scope="module")
def mcmc():
    mc = MCMC(TMCMCKernel(conjugate, num_particles=N), num_warmup=100, num_samples=N, progress_bar=False)
    mc.run(jax.random.PRNGKey(3), jnp.asarray(Y))
    return mc


def test_posterior_and_evidence_match_the_analytic_answer(mcmc):
    mean, sd, log_z = analytic()
    m = np.asarray(mcmc.get_samples()["m"])
    assert m.shape == (N,)
    assert abs(m.mean() - mean) < 0.15 * sd
    assert abs(m.std() / sd - 1.0) < 0.10
    assert abs(float(mcmc.last_state.log_evidence) - log_z) < 0.15
    assert float(mcmc.last_state.beta) == 1.0


def test_samples_are_constrained_with_deterministic_sites(mcmc):
    """get_samples() returns constrained values like NUTS: s > 0 with log s ~ N(0, 0.5²); m2 = 2 m."""
    samples = mcmc.get_samples()
    s = np.asarray(samples["s"])
    assert (s > 0).all()
    assert abs(np.log(s).mean()) < 0.15 * 0.5
    assert abs(np.log(s).std() / 0.5 - 1.0) < 0.10
    np.testing.assert_allclose(samples["m2"], 2.0 * np.asarray(samples["m"]), rtol=1e-6)
    # the raw draw (sample field) is in the unconstrained space, as NUTS's z
    np.testing.assert_allclose(mcmc.last_state.z["s"], np.log(s[-1]), rtol=1e-5, atol=1e-6)


def test_population_is_that_of_the_front_end_with_the_same_key(mcmc):
    """All N particles of TMCMC(...).run(key), after 100 warmup iterations: warmup draws nothing."""
    tm = TMCMC(conjugate, num_particles=N).run(jax.random.PRNGKey(3), jnp.asarray(Y))
    for site in ("m", "s"):
        np.testing.assert_array_equal(np.sort(tm.get_samples()[site]), np.sort(np.asarray(mcmc.get_samples()[site])))
    assert float(mcmc.last_state.log_evidence) == pytest.approx(tm.log_evidence, abs=0.0)


def test_print_summary_and_arviz(mcmc, capsys):
    mcmc.print_summary()
    out = capsys.readouterr().out
    assert " m " in out and " s " in out and "m2" not in out  # deterministic sites left out, as for NUTS
    idata = az.from_numpyro(mcmc)
    assert idata.posterior["m"].shape == (1, N)
    assert set(idata.posterior.data_vars) == {"m", "s", "m2"}
    assert idata.log_likelihood["y"].shape == (1, N, len(Y))
    # ArviZ's lp is the log density of the draw: log prior (with log|J|) + log L
    lp = np.asarray(idata.sample_stats["lp"]).ravel()
    assert np.isfinite(lp).all() and lp.shape == (N,)


def small(y):
    m = numpyro.sample("m", dist.Normal(MU0, TAU0))
    numpyro.sample("y", dist.Normal(m, SIGMA), obs=y)


def test_draws_beyond_the_population_come_from_moves_at_beta_one():
    """num_samples = 2 N: the second block is the population after one frozen move at β = 1; continuing
    from ``last_state`` (post_warmup_state) moves again without a new tempering."""
    n = 400
    kernel = TMCMCKernel(small, num_particles=n)
    mc = MCMC(kernel, num_warmup=10, num_samples=2 * n, progress_bar=False)
    mc.run(jax.random.PRNGKey(0), jnp.asarray(Y))
    m = np.asarray(mc.get_samples()["m"])
    first, later = set(m[:n].tolist()), m[n:]
    assert len(first) == len(np.unique(m[:n]))
    assert np.mean([v in first for v in later]) < 0.5  # most particles moved
    mean, sd, _ = analytic()
    assert abs(later.mean() - mean) < 0.2 * sd and abs(later.std() / sd - 1.0) < 0.15
    tempering = kernel.tmcmc.num_evaluations
    steps = kernel.tmcmc.move.num_steps
    assert int(mc.last_state.num_evaluations) == tempering + n * steps
    assert 0.05 < float(mc.last_state.acceptance) < 0.9
    log_z = float(mc.last_state.log_evidence)
    mc.post_warmup_state = mc.last_state
    mc.run(jax.random.PRNGKey(6), jnp.asarray(Y))
    assert float(mc.last_state.log_evidence) == log_z
    assert int(mc.last_state.num_evaluations) == tempering + 3 * n * steps
    assert kernel.tmcmc.num_evaluations == tempering  # no second tempering


@pytest.mark.slow  # two 2-chain temperings per chain method (~20 s idle): the suite's time budget
def test_chains_are_independent_temperings_vectorized_or_sequential():
    n = 200
    out = {}
    for method in ("vectorized", "sequential"):
        mc = MCMC(TMCMCKernel(small, num_particles=n), num_warmup=0, num_samples=n, num_chains=2,
                  chain_method=method, progress_bar=False)
        mc.run(jax.random.PRNGKey(7), jnp.asarray(Y))
        out[method] = mc
    vec, seq = out["vectorized"], out["sequential"]
    assert vec.get_samples(group_by_chain=True)["m"].shape == (2, n)
    np.testing.assert_allclose(vec.last_state.log_evidence, seq.last_state.log_evidence, rtol=1e-5)
    np.testing.assert_allclose(vec.get_samples()["m"], seq.get_samples()["m"], rtol=1e-5, atol=1e-6)
    key1 = jax.random.split(jax.random.PRNGKey(7), 2)[1]
    tm = TMCMC(small, num_particles=n).run(key1, jnp.asarray(Y))
    assert float(seq.last_state.log_evidence[1]) == pytest.approx(tm.log_evidence, rel=1e-6)


def test_bad_arguments():
    with pytest.raises(ValueError, match="pass num_chains to MCMC instead of num_replicas"):
        TMCMCKernel(small, num_replicas=2)
    with pytest.raises(ValueError, match="num_particles must be >= 2"):
        TMCMCKernel(small, num_particles=1)
    kernel = TMCMCKernel(small, num_particles=10)
    with pytest.raises(ValueError, match="init_params must be None"):
        kernel.init(jax.random.PRNGKey(0), 0, init_params={"m": jnp.zeros(())}, model_args=(jnp.asarray(Y),))
    with pytest.raises(ValueError, match="call init"):
        kernel.postprocess_fn((), {})
