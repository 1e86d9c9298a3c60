"""Joint hierarchical model: log density by hand, prior/likelihood split, non-centred equivalence, NUTS."""

import math
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from numpyro.infer import MCMC, NUTS, Predictive, init_to_value
from numpyro.infer.util import log_density
from scipy import stats

from bubblecal.data import acoustic_datasets
from bubblecal.models import (
    SD_FLOOR_REL,
    TruncatedNormalPopulation,
    hierarchical_model,
    log_truncnorm,
    nuts_init_values,
)
from bubblecal.priors import load_priors

DIAMETERS = (2.1, 2.9, 3.0)


def _synthetic_curves(make_surrogate, thetas, sigma=0.03, seed=0):
    rng = np.random.default_rng(seed)
    curves, surrogates = [], []
    for d, th in zip(DIAMETERS, thetas, strict=True):
        sur = make_surrogate("compression", d)
        x = np.linspace(0.2, 1.6, 15)
        p = np.array([th["ka"], th["kb"], 0, 0, 0, 0])
        yhat = np.asarray(sur(p, np.maximum(x - th["d0"], 0.0)), float)
        y = yhat * (1 + sigma * rng.standard_normal(x.size))
        curves.append(SimpleNamespace(name=f"synthetic_{d}um", kind="compression", x=x, y=y))
        surrogates.append(sur)
    return curves, surrogates


THETAS = [{"ka": 1.40e4, "kb": 500.0, "d0": 0.10}, {"ka": 1.55e4, "kb": 650.0, "d0": 0.15},
          {"ka": 1.48e4, "kb": 550.0, "d0": 0.05}]


def _normal_ll(y, yhat, sigma):
    sd = np.sqrt((sigma * yhat) ** 2 + (SD_FLOOR_REL * np.max(np.abs(y))) ** 2)
    return np.sum(-0.5 * ((y - yhat) / sd) ** 2 - np.log(sd) - 0.5 * math.log(2 * math.pi))


def test_joint_log_density_matches_hand_formula(make_surrogate, fres):
    spec = load_priors("definity_reduced_acoustic")
    curves, surs = _synthetic_curves(make_surrogate, THETAS)
    ac = acoustic_datasets("definity")
    values = {"m_ka": 1.5e4, "tau_ka": 1.5e3, "m_kb": 600.0, "tau_kb": 200.0, "m_d0": 0.1, "tau_d0": 0.1,
              "ka": np.array([t["ka"] for t in THETAS]), "kb": np.array([t["kb"] for t in THETAS]),
              "d0": np.array([t["d0"] for t in THETAS]), "sigma_mech": np.array([0.03, 0.04, 0.05]),
              "ka_ac": np.array([1.45e4]), "sigma_ac": np.array([0.1])}
    got, tr = log_density(hierarchical_model, (curves, surs, spec), {"acoustic": ac, "f_res": fres}, values)

    prior = 0.0
    for k in spec.pooled_names:
        p = spec.parameters[k]
        prior -= math.log(p.hyper_m.width) + math.log(p.hyper_tau.width)
        lo, hi = p.prior.as_tuple()
        m, tau = values[f"m_{k}"], values[f"tau_{k}"]
        dist = stats.truncnorm((lo - m) / tau, (hi - m) / tau, loc=m, scale=tau)
        prior += dist.logpdf(values[k]).sum()
        if k == "ka":
            prior += dist.logpdf(values["ka_ac"]).sum()
    prior -= 3 * math.log(spec.bounds("sigma_mech").width) + math.log(spec.bounds("sigma_ac").width)
    lik = 0.0
    for i, (c, s) in enumerate(zip(curves, surs, strict=True)):
        p = np.array([values["ka"][i], values["kb"][i], 0, 0, 0, 0])
        yhat = np.maximum(np.asarray(s(p, np.maximum(c.x - values["d0"][i], 0.0)), float), 0.0)
        lik += _normal_ll(c.y, yhat, values["sigma_mech"][i])
    fhat = np.array([float(fres(values["ka_ac"][0], d)) for d in ac[0].diameter_um])
    lik += _normal_ll(ac[0].frequency_MHz, fhat, values["sigma_ac"][0])
    assert float(got) == pytest.approx(prior + lik, rel=1e-5)

    # what a TMCMC reads: observed sites = likelihood, latent sample sites = prior
    observed = {n for n, s in tr.items() if s["type"] == "sample" and s["is_observed"]}
    assert observed == {f"y_{c.name}" for c in curves} | {"f_definity_acoustic"}
    lik_sites = sum(float(jnp.sum(tr[n]["fn"].log_prob(tr[n]["value"]))) for n in observed)
    assert lik_sites == pytest.approx(lik, rel=1e-5)
    assert tr["E_MPa"]["value"].shape == (3,) and tr["E_MPa_ac"]["value"].shape == (1,)


def test_population_distribution_matches_pure_density_and_scipy():
    d = TruncatedNormalPopulation(0.2, 0.3, 0.0, 0.5)
    x = jnp.linspace(0.01, 0.49, 9)
    np.testing.assert_allclose(np.asarray(d.log_prob(x)), np.asarray(log_truncnorm(x, 0.2, 0.3, 0.0, 0.5)))
    draws = np.asarray(d.sample(jax.random.PRNGKey(0), (4000,)))
    ref = stats.truncnorm((0.0 - 0.2) / 0.3, (0.5 - 0.2) / 0.3, loc=0.2, scale=0.3)
    assert stats.kstest(draws, ref.cdf).pvalue > 1e-3


def test_noncentred_is_the_same_prior(make_surrogate):
    spec = load_priors("sonovue_reduced")
    curves, surs = [], []
    for d in (3.2, 3.4):
        surs.append(make_surrogate("indentation", d))
        curves.append(SimpleNamespace(name=f"c{d}", kind="indentation", x=np.linspace(400, 6000, 5),
                                      y=np.linspace(0.1, 1.2, 5)))
    draws = {}
    for nc in (False, True):
        pred = Predictive(hierarchical_model, num_samples=3000, return_sites=["kb", "d0", "m_kb"])
        draws[nc] = pred(jax.random.PRNGKey(int(nc)), curves, surs, spec, noncentred=nc, observed=False)
    for k in ("kb", "d0"):
        a, b = np.asarray(draws[False][k])[:, 0], np.asarray(draws[True][k])[:, 0]
        assert stats.ks_2samp(a, b).pvalue > 1e-3, k
    # non-centred sites: u latent, theta deterministic
    _, tr = log_density(hierarchical_model, (curves, surs, spec), {"noncentred": True},
                        {"m_ka": 1e4, "tau_ka": 2e3, "m_kb": 5e3, "tau_kb": 1e3, "m_d0": 0.0, "tau_d0": 0.1,
                         "ka_u": np.array([0.3, 0.6]), "kb_u": np.array([0.5, 0.5]), "d0_u": np.array([0.5, 0.9]),
                         "sigma": np.array([0.1, 0.1])})
    assert tr["kb"]["type"] == "deterministic"
    assert float(tr["kb"]["value"][0]) == pytest.approx(5e3, rel=1e-4)  # median of an untruncated-looking prior


def test_bad_inputs():
    spec = load_priors("definity_reduced")
    c = SimpleNamespace(name="a", kind="compression", x=np.ones(3), y=np.ones(3))
    with pytest.raises(ValueError, match="surrogates"):
        log_density(hierarchical_model, ([c], [], spec), {}, {})
    with pytest.raises(ValueError, match="collide"):
        log_density(hierarchical_model, ([c, c], [lambda p, x: x, lambda p, x: x], spec), {}, {})


@pytest.mark.slow  # statistical, ~20-30 s on 2 cores; the default suite covers the path more cheaply
def test_nuts_runs_on_joint_model(make_surrogate):
    """Short NUTS smoke run on two synthetic bubbles: finite draws of every site (compile-dominated)."""
    spec = load_priors("definity_reduced")
    curves, surs = _synthetic_curves(make_surrogate, THETAS)
    init = init_to_value(values=nuts_init_values(spec, 2))
    mcmc = MCMC(NUTS(hierarchical_model, max_tree_depth=3, init_strategy=init),
                num_warmup=40, num_samples=20, progress_bar=False)
    mcmc.run(jax.random.PRNGKey(0), curves[:2], surs[:2], spec)
    s = mcmc.get_samples()
    assert s["ka"].shape == (20, 2) and s["m_ka"].shape == (20,)
    assert all(np.isfinite(np.asarray(v)).all() for v in s.values())


@pytest.mark.slow
def test_nuts_joint_model_recovers_population_mean(make_surrogate):
    """Longer NUTS run: the bubbles' d0 and the population mean of k_a are recovered.

    NUTS must start with d0 below the first displacement: where x_j < d0 the prediction is clamped and
    the log density is flat in d0 (a plateau gradient-based samplers cannot leave), hence init_to_value.
    """
    spec = load_priors("definity_reduced")
    curves, surs = _synthetic_curves(make_surrogate, THETAS)
    init = init_to_value(values=nuts_init_values(spec, n_curves=3))
    for nc in (False, True):
        mcmc = MCMC(NUTS(hierarchical_model, dense_mass=True, init_strategy=init), num_warmup=500, num_samples=500,
                    progress_bar=False)
        mcmc.run(jax.random.PRNGKey(0), curves, surs, spec, noncentred=nc)
        _check_recovery(mcmc.get_samples())


def _check_recovery(s):
    for i, th in enumerate(THETAS):
        lo, hi = np.quantile(np.asarray(s["d0"][:, i]), [0.005, 0.995])
        assert lo < th["d0"] < hi
    lo, hi = np.quantile(np.asarray(s["m_ka"]), [0.005, 0.995])
    assert lo < np.mean([t["ka"] for t in THETAS]) < hi
