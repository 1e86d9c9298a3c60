"""TMCMC and NUTS agree on a 5-D posterior (one model written once, sampled both ways)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist
import pytest

from bubblecal.inference import TMCMC, compare_posteriors, run_nuts

X = jnp.linspace(-1.5, 1.5, 20)
Y = 0.4 + 1.1 * X - 0.6 * X**2 + 0.3 * jnp.sin(3 * X) + 0.25 * jax.random.normal(jax.random.PRNGKey(9), (20,))


def model_5d(x, y=None):
    a = numpyro.sample("a", dist.Normal(0.0, 2.0))
    b = numpyro.sample("b", dist.Normal(0.0, 2.0))
    c = numpyro.sample("c", dist.Normal(0.0, 1.0))
    d = numpyro.sample("d", dist.Uniform(-2.0, 2.0))
    s = numpyro.sample("s", dist.HalfNormal(1.0))
    mu = numpyro.deterministic("mu0", a + b * x + c * x**2 + d * jnp.sin(3 * x))
    numpyro.sample("y", dist.Normal(mu, s), obs=y)


@pytest.mark.slow  # statistical, ~20-30 s on 2 cores; the default suite covers the path more cheaply
def test_tmcmc_agrees_with_nuts_5d():
    nuts = run_nuts(
        model_5d, X, y=Y, rng_key=jax.random.PRNGKey(1), num_warmup=500, num_samples=1000, num_chains=2
    )
    assert nuts.max_r_hat < 1.02
    assert nuts.min_n_eff > 400
    tm = TMCMC(model_5d, num_particles=8000, compiled=True).run(jax.random.PRNGKey(2), X, y=Y)
    assert tm.status == "converged"
    assert tm.get_samples()["mu0"].shape == (8000, 20)
    result = compare_posteriors(tm, nuts, names=["a", "b", "c", "d", "s"])
    print(result)
    assert result.passed, str(result)
    assert {row["name"] for row in result.table} == {"a", "b", "c", "d", "s"}


def test_compare_posteriors_detects_a_shift():
    rng = np.random.default_rng(0)
    a = {"t": rng.normal(size=3000)}
    b = {"t": rng.normal(0.4, 1.0, size=3000)}
    same = {"t": rng.normal(size=3000)}
    assert not compare_posteriors(a, b).passed
    assert compare_posteriors(a, same).passed
    assert "verdict: PASS" in str(compare_posteriors(a, same))


def test_compare_posteriors_bad_input():
    with pytest.raises(ValueError, match="share no site names"):
        compare_posteriors({"a": np.zeros(5)}, {"b": np.zeros(5)})
    with pytest.raises(ValueError, match=r"sites \['z'\] are not in both"):
        compare_posteriors({"a": np.zeros(5)}, {"a": np.zeros(5)}, names=["z"])
    with pytest.raises(ValueError, match="expected a dict of samples"):
        compare_posteriors([1, 2], {"a": np.zeros(5)})


def test_run_nuts_bad_arguments():
    with pytest.raises(ValueError, match="num_chains must be an integer >= 1"):
        run_nuts(model_5d, X, num_chains=0)
