"""Single-curve mechanical model: log density by hand, reduced = full at zero, floor, NUTS recovery."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from numpyro.infer import MCMC, NUTS, Predictive, init_to_value
from numpyro.infer.util import log_density

from bubblecal.data import DEFAULT_UNITS
from bubblecal.models import (
    SD_FLOOR_REL,
    mechanical_model,
    mechanical_prediction,
    nuts_init_values,
    reduced_spec,
)
from bubblecal.priors import load_priors

TRUE = {"ka": 1.3e4, "kb": 600.0, "b1": 1.0, "b2": 2.0, "a3": 0.5, "a4": 1.0, "d0": 0.1, "sigma": 0.05}


def _hand_log_density(values, x, y, surrogate, spec, setup):
    """log prior + log likelihood written out from inference.md section 2."""
    lp = 0.0
    for p in spec.parameters.values():
        lp += -math.log(p.prior.hi - p.prior.lo)
    noise = spec.mechanical_noise_name
    lp += -math.log(spec.noise[noise].prior.hi - spec.noise[noise].prior.lo)
    theta = {**spec.fixed, **{k: values[k] for k in spec.parameters}}
    params = np.array([theta[k] for k in ("ka", "kb", "b1", "b2", "a3", "a4")])
    if setup == "compression":
        yhat = np.maximum(np.asarray(surrogate(params, np.maximum(x - theta["d0"], 0.0)), float), 0.0)
    else:
        yhat = np.maximum(np.asarray(surrogate(params, x), float) + theta["d0"], 0.0)
    sd = np.sqrt((values[noise] * yhat) ** 2 + (SD_FLOOR_REL * np.max(np.abs(y))) ** 2)
    return lp + np.sum(-0.5 * ((y - yhat) / sd) ** 2 - np.log(sd) - 0.5 * math.log(2 * math.pi))


@pytest.mark.parametrize("name,setup", [("definity_full", "compression"), ("sonovue_full", "indentation"),
                                        ("definity_reduced_acoustic", "compression")])
def test_log_density_matches_hand_formula(name, setup, make_surrogate):
    spec = load_priors(name)
    sur = make_surrogate(setup, 2.9)
    if setup == "compression":
        x = np.linspace(0.05, 1.6, 12)
    else:
        x = np.linspace(400.0, 6000.0, 12)
    values = {k: TRUE[k] for k in spec.parameters}
    values["d0"] = 0.05
    values[spec.mechanical_noise_name] = 0.05
    y = np.asarray(sur(np.array([TRUE[k] if k in values else 0.0 for k in ("ka", "kb", "b1", "b2", "a3", "a4")]), x))
    y = y * (1 + 0.03 * np.sin(np.arange(x.size)))
    got, trace = log_density(mechanical_model, (x, y, sur, spec), {}, values)
    want = _hand_log_density(values, x, y, sur, spec, setup)
    assert float(got) == pytest.approx(want, rel=1e-5)
    assert float(trace["E_MPa"]["value"]) == pytest.approx(float(DEFAULT_UNITS.ka_to_young(values["ka"])) / 1e6,
                                                          rel=1e-5)
    assert trace["y"]["is_observed"]


def test_reduced_equals_full_at_zero_nonlinear_terms(compression_surrogate):
    full = load_priors("definity_full")
    red = reduced_spec(full)
    assert red.free_names == ("ka", "kb", "d0") and red.fixed["b1"] == 0.0 and red.shell == "reduced"
    assert red.bounds("ka") == full.bounds("ka")
    x = np.linspace(0.1, 1.6, 10)
    y = np.asarray(compression_surrogate(np.array([1.2e4, 500.0, 0, 0, 0, 0]), x)) * 1.02
    common = {"ka": 1.25e4, "kb": 520.0, "d0": 0.03, "sigma": 0.04}
    lp_red, tr_red = log_density(mechanical_model, (x, y, compression_surrogate, red), {}, common)
    zeros = {k: 0.0 for k in ("b1", "b2", "a3", "a4")}
    lp_full, tr_full = log_density(mechanical_model, (x, y, compression_surrogate, full), {}, {**common, **zeros})
    # identical likelihood; priors differ only by the four uniform densities of b1..a4
    np.testing.assert_allclose(np.asarray(tr_red["y"]["fn"].log_prob(y)), np.asarray(tr_full["y"]["fn"].log_prob(y)),
                               rtol=1e-6)
    extra = sum(math.log(full.bounds(k).width) for k in zeros)
    assert float(lp_red) == pytest.approx(float(lp_full) + extra, rel=1e-6)
    # the shipped reduced file is the same model as reduced_spec(full)
    shipped = load_priors("definity_reduced")
    lp_shipped, _ = log_density(mechanical_model, (x, y, compression_surrogate, shipped), {}, common)
    assert float(lp_shipped) == pytest.approx(float(lp_red), rel=1e-6)


@pytest.mark.parametrize("setup", ["compression", "indentation"])
def test_floor_prevents_nan_at_clamped_prediction(setup, make_surrogate):
    spec = load_priors("definity_reduced" if setup == "compression" else "sonovue_reduced")
    # compression: d0 beyond every displacement -> x~ = 0 -> S <= 0 -> clamped; indentation: large negative offset
    sur = make_surrogate(setup, 3.0, offset=-1e-3 if setup == "compression" else 0.0)
    x = np.linspace(0.05, 0.4, 6) if setup == "compression" else np.linspace(10.0, 50.0, 6)
    y = np.linspace(1.0, 5.0, 6)
    values = {"ka": 1e4, "kb": 500.0 if setup == "compression" else 5e3, "d0": 0.45 if setup == "compression" else -0.5,
              "sigma": 0.1}

    def potential(v):
        return log_density(mechanical_model, (x, y, sur, spec), {}, v)[0]

    lp = potential(values)
    _, tr = log_density(mechanical_model, (x, y, sur, spec), {}, values)
    assert np.all(np.asarray(tr["y"]["fn"].loc) == 0.0)  # the prediction is clamped everywhere
    assert np.isfinite(float(lp))
    grads = jax.grad(potential)(values)
    assert all(np.isfinite(float(g)) for g in grads.values())


def test_setup_mismatch_is_an_error(indentation_surrogate):
    spec = load_priors("definity_reduced")
    with pytest.raises(ValueError, match="setup mismatch"):
        log_density(mechanical_model, (np.ones(3), np.ones(3), indentation_surrogate, spec), {},
                    {"ka": 1e4, "kb": 500.0, "d0": 0.1, "sigma": 0.05})


def test_prior_predictive_and_prediction_helper(compression_surrogate):
    spec = load_priors("definity_reduced")
    x = np.linspace(0.1, 1.6, 8)
    draws = Predictive(mechanical_model, num_samples=20)(jax.random.PRNGKey(0), x, None, compression_surrogate,
                                                            spec, y_scale=3000.0)
    assert draws["y"].shape == (20, 8) and np.isfinite(np.asarray(draws["y"])).all()
    lo, hi = spec.bounds("ka").as_tuple()
    assert np.all((np.asarray(draws["ka"]) >= lo) & (np.asarray(draws["ka"]) <= hi))
    yhat, sd = mechanical_prediction(draws, compression_surrogate, spec, x, y_scale=3000.0)
    assert yhat.shape == sd.shape == (20, 8)
    # matches the model's own mean and sd for one draw
    one = {k: draws[k][3] for k in ("ka", "kb", "d0", "sigma")}
    _, tr = log_density(mechanical_model, (x, np.ones(8), compression_surrogate, spec), {"y_scale": 3000.0}, one)
    np.testing.assert_allclose(np.asarray(yhat[3]), np.asarray(tr["y"]["fn"].loc), rtol=1e-5)
    np.testing.assert_allclose(np.asarray(sd[3]), np.asarray(tr["y"]["fn"].scale), rtol=1e-5)


def test_nuts_recovers_known_parameters(compression_surrogate):
    """Synthetic curve from the stand-in at known (ka, kb, d0) with 3% noise: NUTS posterior covers them."""
    spec = load_priors("definity_reduced")
    truth = {"ka": 1.5e4, "kb": 400.0, "d0": 0.12, "sigma": 0.03}
    x = np.linspace(0.2, 1.7, 25)
    params = np.array([truth["ka"], truth["kb"], 0, 0, 0, 0])
    yhat = np.asarray(compression_surrogate(params, np.maximum(x - truth["d0"], 0.0)), float)
    y = yhat * (1 + truth["sigma"] * np.random.default_rng(3).standard_normal(x.size))
    start = nuts_init_values(spec)
    assert 0.0 < start["d0"] < x[0]  # below the first displacement: off the clamped plateau
    mcmc = MCMC(NUTS(mechanical_model, init_strategy=init_to_value(values=start)), num_warmup=250, num_samples=300,
                progress_bar=False)
    mcmc.run(jax.random.PRNGKey(1), x, y, compression_surrogate, spec)
    s = mcmc.get_samples()
    for k in ("ka", "kb", "d0"):
        lo, hi = np.quantile(np.asarray(s[k]), [0.005, 0.995])
        assert lo <= truth[k] <= hi, (k, lo, hi, truth[k])
    assert 0.015 < float(jnp.median(s["sigma"])) < 0.06
    assert np.isfinite(np.asarray(s["E_MPa"])).all()


def test_phase3_population_prior_factor(compression_surrogate):
    """population=(m, tau) adds log mean_s p(theta | psi_s) - log p0(theta) over the pooled parameters."""
    from scipy import stats
    from scipy.special import logsumexp

    spec = load_priors("definity_reduced_acoustic")
    x = np.linspace(0.2, 1.6, 8)
    y = np.asarray(compression_surrogate(np.array([1.4e4, 500.0, 0, 0, 0, 0]), x))
    rng = np.random.default_rng(0)
    m = {"ka": rng.uniform(1.3e4, 1.8e4, 30), "kb": rng.uniform(300, 800, 30), "d0": rng.uniform(0, 0.5, 30)}
    tau = {"ka": rng.uniform(1e3, 2e3, 30), "kb": rng.uniform(100, 500, 30), "d0": rng.uniform(0.01, 0.3, 30)}
    values = {"ka": 1.45e4, "kb": 520.0, "d0": 0.1, "sigma_mech": 0.05}
    base, _ = log_density(mechanical_model, (x, y, compression_surrogate, spec), {}, values)
    with_pop, tr = log_density(mechanical_model, (x, y, compression_surrogate, spec), {"population": (m, tau)}, values)
    terms = np.zeros(30)
    log_p0 = 0.0
    for k in ("ka", "kb", "d0"):
        lo, hi = spec.bounds(k).as_tuple()
        terms += stats.truncnorm((lo - m[k]) / tau[k], (hi - m[k]) / tau[k], loc=m[k], scale=tau[k]).logpdf(values[k])
        log_p0 -= math.log(hi - lo)
    want = logsumexp(terms) - math.log(30) - log_p0
    assert float(with_pop - base) == pytest.approx(want, rel=1e-4, abs=1e-3)
    assert tr["population_prior"]["is_observed"]  # a factor: a TMCMC tempers it with the likelihood
