"""TMCMC started from draws of a base density, tempering only some factor sites (``tempered``, ``init_samples``).

θ ~ N(0, 1), y₁ ~ N(θ, 1) observed at 1, and a factor log N(0.5 | θ, 0.5): the base (prior × y₁ term) is
N(0.5, 0.5) with evidence N(1 | 0, √2); the full posterior and evidence are Gaussian in closed form.
"""

import jax
import numpy as np
import numpyro
import numpyro.distributions as dist
import pytest
from scipy.stats import norm

from bubblecal.inference.tmcmc import TMCMC

Y1, F, F_SD = 1.0, 0.5, 0.5


def model():
    theta = numpyro.sample("theta", dist.Normal(0.0, 1.0))
    numpyro.sample("y1", dist.Normal(theta, 1.0), obs=Y1)
    numpyro.factor("pop", dist.Normal(theta, F_SD).log_prob(F))


def exact():
    """(log evidence, posterior mean, posterior sd) of ``model`` and (log evidence, mean, variance) of its base."""
    base_mean, base_var = 0.5, 0.5
    log_z_base = norm.logpdf(Y1, 0.0, np.sqrt(2.0))
    log_z = log_z_base + norm.logpdf(F, base_mean, np.sqrt(base_var + F_SD**2))
    prec = 1 / base_var + 1 / F_SD**2
    return log_z, (base_mean / base_var + F / F_SD**2) / prec, np.sqrt(1 / prec), log_z_base, base_mean, base_var


def base_draws(n, seed=0):
    _, _, _, _, mean, var = exact()
    return {"theta": np.random.default_rng(seed).normal(mean, np.sqrt(var), n).astype(np.float32)}


def test_tempered_run_from_base_draws_has_the_exact_evidence_and_posterior():
    log_z, mean, sd, log_z_base, _, _ = exact()
    n = 20_000
    tm = TMCMC(model, num_particles=n, tempered=["pop"])
    tm.run(jax.random.PRNGKey(2), init_samples=base_draws(n), init_log_evidence=log_z_base)
    theta = np.asarray(tm.get_samples()["theta"])
    # N = 20,000 draws, ESS > 10,000: Monte Carlo sd of the mean ~0.005, of log Z ~0.01 (one or two stages)
    assert tm.log_evidence == pytest.approx(log_z, abs=0.03)
    assert theta.mean() == pytest.approx(mean, abs=0.02)
    assert theta.std() == pytest.approx(sd, rel=0.03)
    rows = tm.stage_info
    assert rows["beta"].iloc[0] == 0.0 and rows["log_evidence"].iloc[0] == pytest.approx(log_z_base, abs=1e-5)
    assert len(rows) - 1 <= 2  # the factor alone is a short way from the base: one or two stages
    # the results keep the model's own split: log likelihood = y1 term + factor, log prior = N(0, 1) density
    state = tm._results[0]["state"]
    th = np.asarray(state.position)[:, 0]
    expected_ll = norm.logpdf(Y1, th, 1.0) + norm.logpdf(F, th, F_SD)
    np.testing.assert_allclose(np.asarray(state.log_likelihood), expected_ll, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(np.asarray(state.log_prior), norm.logpdf(th), rtol=1e-5, atol=1e-5)


def test_untempered_run_from_prior_draws_equals_the_usual_run_in_distribution():
    """init_samples without ``tempered`` are exact prior draws: the run estimates the full evidence."""
    log_z, mean, _, _, _, _ = exact()
    n = 20_000
    prior = {"theta": np.random.default_rng(1).normal(0.0, 1.0, n).astype(np.float32)}
    tm = TMCMC(model, num_particles=n).run(jax.random.PRNGKey(3), init_samples=prior)
    assert tm.log_evidence == pytest.approx(log_z, abs=0.05)
    assert float(np.mean(tm.get_samples()["theta"])) == pytest.approx(mean, abs=0.02)


def test_bad_tempered_settings_are_named():
    with pytest.raises(ValueError, match="non-empty sequence"):
        TMCMC(model, tempered="pop")
    with pytest.raises(ValueError, match="non-empty sequence"):
        TMCMC(model, tempered=[])
    tm = TMCMC(model, num_particles=100, tempered=["pop"])
    with pytest.raises(ValueError, match="needs init_samples"):
        tm.run(jax.random.PRNGKey(0))
    with pytest.raises(ValueError, match="lacks the latent sites"):
        tm.run(jax.random.PRNGKey(0), init_samples={"other": np.zeros(100)})
    with pytest.raises(ValueError, match=r"must have shape \(100,\)"):
        tm.run(jax.random.PRNGKey(0), init_samples={"theta": np.zeros(99)})
    with pytest.raises(ValueError, match="init_log_evidence must be finite"):
        tm.run(jax.random.PRNGKey(0), init_samples=base_draws(100), init_log_evidence=float("nan"))
    with pytest.raises(ValueError, match="not among its observed and factor sites"):
        TMCMC(model, num_particles=100, tempered=["nope"]).run(jax.random.PRNGKey(0), init_samples=base_draws(100))


@pytest.mark.parametrize("compiled", [True, False])
def test_tempered_run_in_one_program_and_with_a_gradient_move(compiled):
    """The fused run (``compiled=True``) and the HMC move reach the same exact answer from the base draws."""
    from bubblecal.inference.tmcmc import hmc_move

    log_z, mean, sd, log_z_base, _, _ = exact()
    n = 5_000
    move = hmc_move() if not compiled else None
    tm = TMCMC(model, num_particles=n, tempered=("pop",), compiled=compiled, move=move)
    tm.run(jax.random.PRNGKey(4), init_samples=base_draws(n, seed=2), init_log_evidence=log_z_base)
    # N = 5,000: Monte Carlo sd of log Z ~0.02, of the mean ~0.01
    assert tm.status == "converged"
    assert tm.log_evidence == pytest.approx(log_z, abs=0.06)
    assert float(np.mean(tm.get_samples()["theta"])) == pytest.approx(mean, abs=0.03)
    assert float(np.std(tm.get_samples()["theta"])) == pytest.approx(sd, rel=0.06)
