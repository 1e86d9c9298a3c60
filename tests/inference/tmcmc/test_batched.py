"""Batched TMCMC (run_batched): K datasets of one structure in one compiled program give, dataset by dataset,
the populations of K sequential fused runs with the same keys, to float32 round-off (the ``same_tempering``
check of ``tests/inference/conftest.py``, tolerance 1e-4 on particles, β, log Z: XLA may fuse the vmapped
arithmetic differently; a flipped accept/reject decision ends the comparison at its stage)."""

from __future__ import annotations

import jax
import numpy as np
import numpyro
import numpyro.distributions as dist
import pytest

from bubblecal.inference import TMCMC, BatchStructureError, run_batched
from bubblecal.inference.tmcmc import _programs as tm
from bubblecal.inference.tmcmc import batch_groups

LENGTH = 12  # every curve padded to this many points
ATOL = 1e-4  # particles (O(1) values), β and log Z: float32 round-off


def line_model(x, y, mask, noise):
    a = numpyro.sample("a", dist.Normal(0.0, 3.0))
    b = numpyro.sample("b", dist.Uniform(-5.0, 5.0))
    with numpyro.handlers.mask(mask=mask):
        numpyro.sample("y", dist.Normal(a + b * x, noise), obs=y)


def other_model(x, y, mask, noise):
    a = numpyro.sample("a", dist.Normal(0.0, 3.0))
    with numpyro.handlers.mask(mask=mask):
        numpyro.sample("y", dist.Normal(a * x, 0.3), obs=y)


def padded(seed, n, length=LENGTH):
    """A line with noise, n points padded to ``length`` (the padding masked out)."""
    rng = np.random.default_rng(seed)
    x = np.linspace(-1.0, 1.0, n)
    y = 0.5 + 1.5 * x + 0.3 * rng.normal(size=n)
    return (np.r_[x, np.full(length - n, x[-1])], np.r_[y, np.zeros(length - n)], np.arange(length) < n,
            np.asarray(0.3))  # the noise: one value for every dataset, passed to the batch once


ARGS = [padded(1, 8), padded(2, 12), padded(3, 10)]
KEYS = list(jax.random.split(jax.random.PRNGKey(3), 3))
OPTIONS = {"num_particles": 300, "num_replicas": 2, "num_mcmc_steps": 3}


@pytest.fixture(scope="module")
def batched():
    """The three datasets in one batch (the compiled programs are shared by the tests of this module)."""
    tm.clear_program_cache()
    seen = []
    out = run_batched(line_model, ARGS, None, KEYS, callback=lambda i, s: seen.append(i), **OPTIONS)
    assert seen == [0, 1, 2]
    return out


def assert_same_run(batched: TMCMC, single: TMCMC, same_tempering) -> bool:
    """Same status, tempering (to round-off) and samples; returns whether no accept/reject decision flipped."""
    assert batched.status == single.status == "converged"
    strict = same_tempering(batched, single, atol=ATOL)
    if strict:
        np.testing.assert_allclose(batched.get_samples()["b"], single.get_samples()["b"], atol=ATOL)
        np.testing.assert_allclose(batched.log_evidences, single.log_evidences, atol=ATOL)
    return strict


def test_batched_runs_equal_sequential_fused_runs(batched, same_tempering):
    strict = [assert_same_run(res, TMCMC(line_model, compiled=True, **OPTIONS).run(key, *args), same_tempering)
              for key, args, res in zip(KEYS, ARGS, batched, strict=True)]
    assert any(strict)  # at least one dataset compared particle by particle to the end
    with pytest.raises(AssertionError):  # the check tells two datasets apart from their first stage
        same_tempering(batched[0], batched[1], atol=ATOL)
    # the datasets differ: their own data gave their own posteriors
    assert len({round(float(r.log_evidence), 3) for r in batched}) == 3
    assert np.isfinite(batched[0].log_evidence_se)
    assert batched[1].prior_log_likelihood(KEYS[1], *ARGS[1]).shape == (300,)
    (key,) = [k for k in tm._program_cache if k[0] == "batched"]
    assert key[-1] == (0, 0, 0, None)  # x, y, mask stacked; the noise passed once


def test_batched_results_export_like_single_runs(batched):
    idata = batched[2].to_inference_data()
    assert idata.posterior["b"].shape == (2, 300)  # replicas as chains
    np.testing.assert_allclose(idata.posterior["b"].values[0], batched[2].get_samples()["b"])
    assert idata.posterior.attrs["status"] == "converged"


@pytest.mark.slow
def test_chunked_batches_and_chunked_likelihood_keep_the_sequential_result(same_tempering):
    # three datasets x two replicas in chunks of four runs (the second padded with copies), the likelihood
    # in chunks of 128 particles: each dataset as its sequential fused run with the same chunk_size
    options = {**OPTIONS, "chunk_size": 128}
    chunked = run_batched(line_model, ARGS, None, KEYS, batch_size=4, **options)
    for key, args, res in zip(KEYS, ARGS, chunked, strict=True):
        assert_same_run(res, TMCMC(line_model, compiled=True, **options).run(key, *args), same_tempering)


def test_mismatched_structures_are_refused_with_the_dataset_named():
    with pytest.raises(BatchStructureError, match=r"dataset 1 .* array argument shapes"):
        run_batched(line_model, [ARGS[0], padded(2, 9, length=9)], None, KEYS[:2], num_particles=100)
    with pytest.raises(BatchStructureError, match=r"dataset 1 .*other_model.* model function"):
        run_batched([line_model, other_model], ARGS[:2], None, KEYS[:2], num_particles=100)
    with pytest.raises(ValueError, match="2 keys for 3 datasets"):
        run_batched(line_model, ARGS, None, KEYS[:2], num_particles=100)
    with pytest.raises(ValueError, match="batch_size"):
        run_batched(line_model, ARGS, None, KEYS, batch_size=0)


def test_batch_groups_by_function_and_shapes():
    args = [ARGS[0], padded(5, 9, length=9), ARGS[1], ARGS[2]]
    models = [line_model, line_model, other_model, line_model]
    assert batch_groups(models, args) == [[0, 3], [1], [2]]
