"""The 'korali' preset against an independent plain-NumPy implementation of Korali's TMCMC.

The reference below is written from Korali's algorithm description only (no code shared with
bubblecal): CoV of the incremental weights solved with scipy's brentq, multinomial resampling with
numpy, weighted covariance × 0.04, one Metropolis step per resampled particle in the original
(constrained) space with the box prior, a last generation at β = 1.  On a 2-D problem the two must
give the same posterior distribution, log evidence and number of stages.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist
from scipy.optimize import brentq
from scipy.stats import ks_2samp

from bubblecal.inference import TMCMC

LO, HI = np.array([-4.0, -4.0]), np.array([4.0, 4.0])
MU = np.array([0.5, -1.0])
COV = np.array([[0.3, 0.24], [0.24, 0.4]])
PREC = np.linalg.inv(COV)
LOGNORM = -0.5 * np.log(np.linalg.det(2 * np.pi * COV))


def loglik_np(x):
    d = x - MU
    return -0.5 * np.einsum("ni,ij,nj->n", d, PREC, d) + LOGNORM


def model_box_2d():
    x = numpyro.sample("x", dist.Uniform(jnp.asarray(LO), jnp.asarray(HI)).to_event(1))
    d = x - jnp.asarray(MU)
    numpyro.factor("lik", -0.5 * d @ jnp.asarray(PREC) @ d + LOGNORM)


def korali_reference(rng, n, target_cov=0.8, cov_scale=0.04):
    """Plain-NumPy Korali TMCMC; returns (particles, log Z, number of generations after the prior)."""
    x = rng.uniform(LO, HI, size=(n, 2))
    ll = loglik_np(x)
    beta, log_z, stages = 0.0, 0.0, 0

    def cov_of(delta):
        w = np.exp(delta * (ll - ll.max()))
        return w.std(ddof=1) / w.mean()

    while beta < 1.0:
        if cov_of(1.0 - beta) <= target_cov:
            delta = 1.0 - beta
        else:
            delta = brentq(lambda dl: cov_of(dl) - target_cov, 0.0, 1.0 - beta, xtol=1e-14)
        new_beta = 1.0 if delta >= 1.0 - beta else beta + delta
        w = np.exp(delta * (ll - ll.max()))
        log_z += np.log(w.mean()) + delta * ll.max()
        wn = w / w.sum()
        mean = wn @ x
        cov = cov_scale * ((x - mean).T * wn) @ (x - mean)
        counts = rng.multinomial(n, wn)
        leaders = np.repeat(np.arange(n), counts)
        x, ll = x[leaders], ll[leaders]
        prop = x + rng.multivariate_normal(np.zeros(2), cov, size=n)
        inside = np.all((prop >= LO) & (prop <= HI), axis=1)
        ll_prop = np.where(inside, loglik_np(prop), -np.inf)
        accept = np.log(rng.uniform(size=n)) < new_beta * (ll_prop - ll)
        x = np.where(accept[:, None], prop, x)
        ll = np.where(accept, ll_prop, ll)
        beta = new_beta
        stages += 1
    return x, log_z, stages


def test_korali_preset_matches_numpy_reference():
    n, reps = 4000, 4
    rng = np.random.default_rng(123)
    ref = [korali_reference(rng, n) for _ in range(reps)]
    ref_x = np.concatenate([r[0] for r in ref])
    ref_z = np.array([r[1] for r in ref])
    ref_stages = {r[2] for r in ref}

    tm = TMCMC(model_box_2d, num_particles=n, preset="korali", num_replicas=reps, compiled=True)
    tm.run(jax.random.PRNGKey(0))
    assert tm.space == "constrained" and tm.resampling == "multinomial"
    assert tm.status == "converged"
    ours_x = np.concatenate([np.asarray(tm._results[r]["state"].position) for r in range(reps)])
    ours_z = tm.log_evidences

    # same tempering schedule length and Korali's fixed scale (s² = 0.04 → s = 0.2)
    assert len(tm.stage_info) - 1 in {s + k for s in ref_stages for k in (-1, 0, 1)}
    assert np.allclose(tm.stage_info["scale"].iloc[1:], 0.2)
    # acceptance of one step with s² = 0.04 is high, as in Korali
    assert tm.stage_info["acceptance"].iloc[1:].min() > 0.5

    # distributions agree: marginal KS and moments (particles are duplicated, so loose-ish KS)
    for j in range(2):
        assert ks_2samp(ours_x[:, j], ref_x[:, j]).statistic < 0.04
    np.testing.assert_allclose(ours_x.mean(0), ref_x.mean(0), atol=0.05)
    np.testing.assert_allclose(np.cov(ours_x.T), np.cov(ref_x.T), atol=0.04)
    # evidence: the box normalisation is log(1/64); the likelihood mass inside the box is ≈ 1
    exact = -np.log(64.0)
    se = np.hypot(ours_z.std(ddof=1), ref_z.std(ddof=1)) / np.sqrt(reps)
    assert abs(ours_z.mean() - ref_z.mean()) < 4 * se + 0.03
    assert abs(ref_z.mean() - exact) < 0.1 and abs(ours_z.mean() - exact) < 0.1
