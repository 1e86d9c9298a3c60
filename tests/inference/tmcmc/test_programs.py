"""Compiled-program reuse in TMCMC: models of one structure share programs (their arrays are traced
arguments), and sharing changes nothing in the result."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist

from bubblecal.inference import TMCMC
from bubblecal.inference.tmcmc import _programs as tm


def line_model(x, y):
    a = numpyro.sample("a", dist.Normal(0.0, 3.0))
    b = numpyro.sample("b", dist.Uniform(-5.0, 5.0))
    numpyro.sample("y", dist.Normal(a + b * x, 0.3), obs=y)


def _data(seed, n=12):
    rng = np.random.default_rng(seed)
    x = np.linspace(-1.0, 1.0, n)
    return x, 0.5 + 1.5 * x + 0.3 * rng.normal(size=n)


def _model_entries():
    return [k for k in tm._program_cache if k[0] in ("model", "fused")]


def test_datasets_of_one_structure_share_programs_and_get_their_own_posterior():
    tm.clear_program_cache()
    x1, y1 = _data(1)
    x2, y2 = _data(2)
    r1 = TMCMC(line_model, num_particles=1500).run(jax.random.PRNGKey(0), x1, y1)
    assert len(_model_entries()) == 1
    r2 = TMCMC(line_model, num_particles=1500).run(jax.random.PRNGKey(0), x2, y2)
    assert len(_model_entries()) == 1  # the second dataset reused the first one's programs
    TMCMC(line_model, num_particles=1500).run(jax.random.PRNGKey(0), *_data(3, n=13))
    assert len(_model_entries()) == 2  # another length: another structure

    # each posterior is its own dataset's: conjugate-normal slope b (flat in its box, a ~ N(0, 9))
    for res, (x, y) in ((r1, (x1, y1)), (r2, (x2, y2))):
        X = np.c_[np.ones_like(x), x]
        prec = X.T @ X / 0.09 + np.diag([1 / 9.0, 0.0])
        mean = np.linalg.solve(prec, X.T @ y / 0.09)
        sd = np.sqrt(np.diag(np.linalg.inv(prec)))
        s = res.get_samples()
        assert abs(s["b"].mean() - mean[1]) < 0.1 * sd[1] + 3 * sd[1] / np.sqrt(300)
        assert abs(s["a"].std() / sd[0] - 1) < 0.15


def test_shared_programs_give_the_result_of_fresh_ones():
    x, y = _data(4)
    tm.clear_program_cache()
    TMCMC(line_model, num_particles=800).run(jax.random.PRNGKey(5), *_data(6))  # fills the cache
    shared = TMCMC(line_model, num_particles=800).run(jax.random.PRNGKey(7), x, y)
    tm.clear_program_cache()
    fresh = TMCMC(line_model, num_particles=800).run(jax.random.PRNGKey(7), x, y)
    np.testing.assert_allclose(shared.get_samples()["b"], fresh.get_samples()["b"], rtol=1e-6)
    assert float(shared.log_evidence) == float(fresh.log_evidence)


def test_cache_is_bounded():
    tm.clear_program_cache()
    for i in range(tm._PROGRAM_CACHE_SIZE + 3):
        tm._cached_programs(("test", i), lambda: object())
    assert len(tm._program_cache) == tm._PROGRAM_CACHE_SIZE
    assert ("test", 0) not in tm._program_cache and ("test", tm._PROGRAM_CACHE_SIZE + 2) in tm._program_cache
    tm.clear_program_cache()
    assert not tm._program_cache


def test_model_that_needs_concrete_arrays_still_runs():
    # np.asarray of an argument inside the model: the arrays stay constants, nothing is shared
    def host_model(x, y):
        scale = float(np.asarray(y).std())
        a = numpyro.sample("a", dist.Normal(0.0, 3.0))
        numpyro.sample("y", dist.Normal(a * jnp.ones_like(x), scale), obs=y)

    x, y = _data(8)
    res = TMCMC(host_model, num_particles=500).run(jax.random.PRNGKey(0), x, y)
    assert res.status == "converged"


def test_exports_of_one_structure_share_the_pointwise_program():
    """The pointwise log likelihood of the ArviZ export is compiled once per structure, not once per dataset."""
    from numpyro.infer import log_likelihood

    tm.clear_program_cache()
    runs = [TMCMC(line_model, num_particles=600).run(jax.random.PRNGKey(i), *_data(i)) for i in (1, 2)]
    exports = [r.to_inference_data() for r in runs]
    (programs,) = [v for k, v in tm._program_cache.items() if k[0] == "model"]
    assert programs.pointwise.executables() == 1
    for r, idata, i in zip(runs, exports, (1, 2), strict=True):  # and each export holds its own dataset's values
        want = log_likelihood(line_model, r.get_samples(), *_data(i))["y"]
        np.testing.assert_allclose(idata.log_likelihood["y"].values[0], np.asarray(want), rtol=1e-5, atol=1e-5)
