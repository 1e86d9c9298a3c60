"""TMCMC front end: failure behaviour, bad arguments, the model split, samples, exports."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist
import pytest
from scipy.stats import gamma, kstest, norm

from bubblecal.inference import TMCMC, RandomWalk
from bubblecal.inference.tmcmc._flat_model import FlatModel


def model_simple(y=0.4):
    x = numpyro.sample("x", dist.Uniform(0.0, 1.0))
    numpyro.deterministic("x2", 2.0 * x)
    numpyro.sample("y", dist.Normal(x, 0.1), obs=y)


# -- bad arguments: ValueError before anything is traced or compiled ---------------------------------


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"num_particles": 1}, "num_particles must be >= 2"),
        ({"num_particles": 2.5}, "num_particles must be an integer"),
        ({"target_cov": 0.0}, "target_cov must be a positive finite number"),
        ({"target_cov": -1.0}, "target_cov must be a positive finite number"),
        ({"target_cov": float("nan")}, "target_cov must be a positive finite number"),
        ({"cov_scale": 0.0}, "cov_scale must be a positive finite number"),
        ({"num_mcmc_steps": 0}, "num_mcmc_steps must be >= 1"),
        ({"preset": "fast"}, "preset must be one of"),
        ({"num_replicas": 0}, "num_replicas must be >= 1"),
        ({"max_stages": 0}, "max_stages must be >= 1"),
        ({"chunk_size": 0}, "chunk_size must be >= 1"),
        ({"space": "box"}, "space must be 'unconstrained' or 'constrained'"),
        ({"min_delta": 1.5}, r"min_delta must be a number in \[0, 1\)"),
        ({"preset": "korali", "num_mcmc_steps": 5}, "preset='korali' runs one MH step"),
        ({"preset": "korali", "move": RandomWalk()}, "preset='korali' uses Korali's random walk"),
        ({"move": "hmc"}, "move must be a RandomWalk or KernelMove-like object"),
    ],
)
def test_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        TMCMC(model_simple, **kwargs)


def test_model_not_callable():
    with pytest.raises(ValueError, match="model must be a callable NumPyro model"):
        TMCMC("model")


def test_results_before_run():
    with pytest.raises(RuntimeError, match="call TMCMC.run"):
        _ = TMCMC(model_simple, num_particles=10).log_evidence


def test_discrete_latent_rejected():
    def model_discrete():
        numpyro.sample("k", dist.Poisson(3.0))

    with pytest.raises(ValueError, match="latent site 'k' is discrete"):
        TMCMC(model_discrete, num_particles=10).run(jax.random.PRNGKey(0))


# -- the model split ------------------------------------------------------------------------------------


def test_likelihood_is_observed_plus_factor_without_jacobian():
    """log L = observed sites + user factor; log prior = prior density + log|J| (computed by us)."""

    def model_split(y):
        s = numpyro.sample("s", dist.Gamma(3.0, 2.0))
        m = numpyro.sample("m", dist.Normal(0.0, 1.0))
        numpyro.sample("y", dist.Normal(m, s), obs=y)
        numpyro.factor("extra", -0.5 * m**2)

    y = jnp.array([0.3, -0.2, 1.1])
    flat = FlatModel(model_split, (y,))
    u = jnp.array([0.7, -0.4])  # flat order: m, s (ravel_pytree sorts keys)
    m, log_s = u[0], u[1]
    s = jnp.exp(log_s)
    lp, ll = flat.log_terms(u)
    expect_ll = dist.Normal(m, s).log_prob(y).sum() - 0.5 * m**2
    expect_lp = dist.Gamma(3.0, 2.0).log_prob(s) + log_s + dist.Normal(0, 1).log_prob(m)
    np.testing.assert_allclose(ll, expect_ll, rtol=1e-6)
    np.testing.assert_allclose(lp, expect_lp, rtol=1e-6)


@pytest.mark.filterwarnings("ignore:Out-of-support values")
def test_constrained_space_prior_is_minus_inf_outside_support():
    flat = FlatModel(model_simple, space="constrained")
    assert np.isfinite(flat.log_prior(jnp.array([0.5])))
    assert flat.log_prior(jnp.array([1.2])) == -np.inf
    assert flat.log_prior(jnp.array([-0.1])) == -np.inf


def test_stage0_particles_are_exact_prior_draws():
    def model_prior(y=1.0):
        s = numpyro.sample("s", dist.Gamma(2.5, 1.5))
        numpyro.sample("y", dist.Normal(0.0, s), obs=y)

    flat = FlatModel(model_prior)
    draws = jax.vmap(flat.constrain)(flat.prior_draws(jax.random.PRNGKey(5), 4000))["s"]
    assert kstest(np.asarray(draws), gamma(2.5, scale=1 / 1.5).cdf).pvalue > 1e-3


# -- failure behaviour ----------------------------------------------------------------------------------


def test_nonfinite_likelihood_gets_zero_weight():
    """log L is NaN for x > 0.8: those particles get weight 0 and log Z stays finite and correct."""

    def model_nan(y=0.3):
        x = numpyro.sample("x", dist.Uniform(0.0, 1.0))
        ll = dist.Normal(x, 0.1).log_prob(y)
        numpyro.factor("lik", jnp.where(x > 0.8, jnp.nan, ll))

    tm = TMCMC(model_nan, num_particles=2000, num_replicas=2, compiled=True).run(jax.random.PRNGKey(0))
    exact = math.log(norm.cdf((0.8 - 0.3) / 0.1) - norm.cdf((0 - 0.3) / 0.1))
    assert np.all(np.isfinite(tm.log_evidences))
    assert abs(tm.log_evidence - exact) < 0.1
    assert tm.stage_info["num_nonfinite"].iloc[0] > 0
    assert np.all(tm.get_samples()["x"] <= 0.8)


def test_all_particles_minus_inf_names_the_model():
    def model_impossible():
        x = numpyro.sample("x", dist.Normal(0.0, 1.0))
        numpyro.factor("never", jnp.where(x > 100.0, 0.0, -jnp.inf))

    with pytest.raises(
        ValueError,
        match=r"all 50 initial particles \(prior draws or init_samples\) of model "
        r"'test_all_particles_minus_inf_names_the_model.<locals>.model_impossible'.*non-finite",
    ):
        TMCMC(model_impossible, num_particles=50).run(jax.random.PRNGKey(0))


@pytest.mark.parametrize("compiled", [False, True])
def test_max_stages_status_warning_and_partial_results(compiled):
    def model_sharp():
        x = numpyro.sample("x", dist.Normal(0.0, 10.0).expand([3]).to_event(1))
        numpyro.sample("y", dist.Normal(x, 0.01).to_event(1), obs=jnp.zeros(3))

    tm = TMCMC(model_sharp, num_particles=300, max_stages=2, compiled=compiled)
    with pytest.warns(RuntimeWarning, match="status 'max_stages'"):
        tm.run(jax.random.PRNGKey(1))
    assert tm.status == "max_stages"
    assert len(tm.stage_info) == 3  # prior row + 2 stages
    assert 0 < tm.stage_info["beta"].iloc[-1] < 1
    assert np.isfinite(tm.log_evidence)
    assert tm.get_samples()["x"].shape == (300, 3)


def test_stalled_status():
    def model_sharp():
        x = numpyro.sample("x", dist.Normal(0.0, 10.0))
        numpyro.sample("y", dist.Normal(x, 0.001), obs=0.0)

    tm = TMCMC(model_sharp, num_particles=300, min_delta=0.5)
    with pytest.warns(RuntimeWarning, match="status 'stalled'"):
        tm.run(jax.random.PRNGKey(2))
    assert tm.status == "stalled"
    assert tm.stage_info["beta"].iloc[-1] < 1
    assert tm.get_samples()["x"].shape == (300,)


# -- samples, replicas, chunks, compiled loop, exports --------------------------------------------------


def test_samples_stage_table_and_exports():
    tm = TMCMC(model_simple, num_particles=500, num_replicas=2).run(jax.random.PRNGKey(4), y=0.4)
    s = tm.get_samples()
    assert set(s) == {"x", "x2"}
    assert s["x"].shape == (500,)
    np.testing.assert_allclose(s["x2"], 2 * s["x"], rtol=1e-6)
    assert np.all((s["x"] > 0) & (s["x"] < 1))
    table = tm.stage_info
    for col in (
        "beta",
        "delta",
        "cov",
        "ess",
        "log_z_increment",
        "log_evidence",
        "acceptance",
        "unique_fraction",
        "scale",
        "max_log_likelihood",
        "num_nonfinite",
        "num_evaluations",
        "seconds",
    ):
        assert col in table.columns
    assert table["beta"].iloc[-1] == 1.0
    np.testing.assert_allclose(table["log_z_increment"].sum(), tm.log_evidences[0], atol=1e-4)
    assert table["num_evaluations"].sum() == tm.num_evaluations
    assert np.isfinite(tm.log_evidence_se) and tm.log_evidence_se > 0
    idata = tm.to_inference_data()
    assert idata.posterior["x"].shape == (2, 500)  # one chain per replica
    np.testing.assert_array_equal(idata.posterior["x"].values[1], tm.get_samples(1)["x"])
    assert "loglik" in idata.sample_stats and "lp" in idata.sample_stats
    assert idata.posterior.attrs["log_evidence"] == pytest.approx(tm.log_evidence)
    np.testing.assert_allclose(idata.sample_stats["stage_beta"].values[0, :len(table)], table["beta"])
    tm.print_summary()


def test_auto_chunk_size_is_the_cpu_chunk_on_a_cpu_and_none_for_small_populations():
    from bubblecal.inference.tmcmc.evaluator import CPU_CHUNK_SIZE, resolve_chunk_size

    with jax.default_device(jax.devices("cpu")[0]):
        assert resolve_chunk_size("auto", 4 * CPU_CHUNK_SIZE) == CPU_CHUNK_SIZE
        assert resolve_chunk_size("auto", 2 * CPU_CHUNK_SIZE) is None  # a small population: plain vmap
        # a chunk that divides the population (no remainder body), at least half the CPU chunk
        assert TMCMC(model_simple, num_particles=2000).config.chunk_size == 500
        assert resolve_chunk_size("auto", 50_000) == 500
        assert resolve_chunk_size("auto", 1201) == CPU_CHUNK_SIZE  # 1201 is prime: chunks with a remainder
    assert resolve_chunk_size(None, 10**6) is None and resolve_chunk_size(64, 10**6) == 64
    with pytest.raises(ValueError, match="'auto'"):
        resolve_chunk_size("fast", 100)
    with pytest.raises(ValueError, match="chunk_size"):
        TMCMC(model_simple, chunk_size="fast")


def test_auto_chunk_matches_one_vmap():
    """The default ('auto', chunks of 500 on a CPU) and one vmap over all 2,000 particles give the same run."""
    with jax.default_device(jax.devices("cpu")[0]):
        auto = TMCMC(model_simple, num_particles=2000).run(jax.random.PRNGKey(3))
        whole = TMCMC(model_simple, num_particles=2000, chunk_size=None).run(jax.random.PRNGKey(3))
    np.testing.assert_allclose(auto.log_evidence, whole.log_evidence, atol=1e-4)
    np.testing.assert_allclose(auto.get_samples()["x"], whole.get_samples()["x"], atol=1e-5)


def test_chunked_and_compiled_match_plain():
    base = TMCMC(model_simple, num_particles=400).run(jax.random.PRNGKey(7))
    chunked = TMCMC(model_simple, num_particles=400, chunk_size=64).run(jax.random.PRNGKey(7))
    compiled = TMCMC(model_simple, num_particles=400, compiled=True).run(jax.random.PRNGKey(7))
    for other in (chunked, compiled):
        np.testing.assert_allclose(other.log_evidence, base.log_evidence, atol=1e-4)
        np.testing.assert_allclose(other.get_samples()["x"], base.get_samples()["x"], atol=1e-5)
