"""Pluggable moves: NumPyro HMC / NUTS kernels as the TMCMC mutation, with per-stage step size."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist
import pytest
from scipy.stats import multivariate_normal

from bubblecal.inference import TMCMC, KernelMove, hmc_move, nuts_move

COV_L = np.array([[0.04, 0.038], [0.038, 0.04]])  # a narrow ridge (ρ = 0.95)
MU_L = np.array([0.3, -0.2])


def model_ridge():
    x = numpyro.sample("x", dist.Normal(0.0, 1.0).expand([2]).to_event(1))
    numpyro.sample("y", dist.MultivariateNormal(x, jnp.asarray(COV_L)), obs=jnp.asarray(MU_L))


EXACT = float(multivariate_normal(np.zeros(2), np.eye(2) + COV_L).logpdf(MU_L))


def test_hmc_move_evidence_and_step_size_adaptation():
    tm = TMCMC(model_ridge, num_particles=1000, num_replicas=2, move=hmc_move(), compiled=True)
    tm.run(jax.random.PRNGKey(0))
    assert tm.status == "converged"
    assert abs(tm.log_evidence - EXACT) < 0.2
    table = tm.stage_info
    # the step size moves between stages and the acceptance ends near the 0.8 target
    assert table["scale"].iloc[1:].nunique() > 1
    assert 0.6 < table["acceptance"].iloc[-1] <= 1.0
    # evaluations are counted (leapfrog steps + one evaluation per particle per stage)
    assert table["num_evaluations"].iloc[1:].min() > 2 * 1000


def test_any_numpyro_kernel_barker():
    """A kernel with no mass-matrix argument (NumPyro's BarkerMH) plugs in through the same factory."""
    from numpyro.infer import BarkerMH

    def factory(potential_fn, step_size, cov):
        return BarkerMH(
            potential_fn=potential_fn, step_size=step_size, adapt_step_size=False, adapt_mass_matrix=False
        )

    move = KernelMove(factory, num_steps=5, target_accept=0.4)
    tm = TMCMC(model_ridge, num_particles=1000, move=move, compiled=True).run(jax.random.PRNGKey(3))
    assert tm.status == "converged"
    assert abs(tm.log_evidence - EXACT) < 0.3
    assert 0.2 < tm.stage_info["acceptance"].iloc[-1] < 0.6


@pytest.mark.slow
def test_nuts_move_evidence():
    tm = TMCMC(model_ridge, num_particles=2000, num_replicas=2, move=nuts_move(), compiled=True)
    tm.run(jax.random.PRNGKey(1))
    assert tm.status == "converged"
    assert abs(tm.log_evidence - EXACT) < 0.15


def test_kernel_move_bad_arguments():
    with pytest.raises(ValueError, match="num_steps must be >= 1"):
        KernelMove(lambda *a: None, num_steps=0)
    with pytest.raises(ValueError, match=r"target_accept must be in \(0, 1\)"):
        KernelMove(lambda *a: None, target_accept=1.5)
    with pytest.raises(ValueError, match="give num_mcmc_steps to the move itself"):
        TMCMC(model_ridge, move=hmc_move(), num_mcmc_steps=3)
