"""Joint hierarchical model of one agent: population ψ, every bubble's Θ_i and σ_i, acoustic datasets.

Model (``docs/inference.md`` section 4), for the pooled parameters k of the PriorSpec (those with
``hyper_m``/``hyper_tau``) and bubbles i = 1..n (one loading curve each)::

    m_k   ~ Uniform(hyper_m_k)                                   sites 'm_<k>'
    τ_k   ~ Uniform(hyper_tau_k)                                 sites 'tau_<k>'
    Θ_i,k | ψ ~ Normal(m_k, τ_k²) truncated to prior_k            site '<k>', shape (n,) in plate 'curves'
    Θ_i,k ~ Uniform(prior_k)                (free, not pooled)   site '<k>', shape (n,)
    σ_i   ~ Uniform(prior_σ)                (never pooled)       site 'sigma' | 'sigma_mech', shape (n,)
    y_i   ~ mechanical likelihood of curve i (models.mechanical)  observed site 'y_<curve name>'

and, in acoustic workflows, for acoustic datasets j = 1..n_ac (Definity: one dataset of 14 bubbles;
SonoVue: one per bubble), each with its own latent k_a (the only shell parameter the resonance
frequency depends on) and its own noise amplitude::

    ka_ac_j | ψ ~ TruncNormal(m_ka, τ_ka², prior_ka)            site 'ka_ac', shape (n_ac,) in plate 'acoustic'
    σ_ac_j ~ Uniform(prior_σac)                                  site 'sigma_ac', shape (n_ac,)
    f_j ~ acoustic likelihood of dataset j (models.acoustic)      observed site 'f_<dataset name>'

The population density is normalised by the truncation mass
(:func:`bubblecal.models.population.log_truncnorm`, via
:class:`~bubblecal.models.distributions.TruncatedNormalPopulation`), so the latent sites are *prior*
sites (a TMCMC tempers only the observed sites). ``noncentred=True`` samples u_i,k ~ Uniform(0, 1)
(sites '<k>_u') and sets the deterministic Θ_i,k = F⁻¹(u_i,k | ψ), the inverse CDF of the truncated
normal: the same joint distribution, without the funnel between τ_k and Θ_i,k that hampers NUTS when
the data are weak.
Deterministic sites: ``E_MPa``/``kappa_kBT`` (per bubble) and ``E_MPa_ac`` (per acoustic dataset).

Units: DPD for shell parameters and curves, MHz and µm for acoustic data (see the two single-dataset
modules).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist

from bubblecal.data import DEFAULT_UNITS, UnitSystem
from bubblecal.models.acoustic import predict_frequency
from bubblecal.models.distributions import (
    TruncatedNormalPopulation,
    hyperprior_sites,
    relative_normal,
    uniform_prior,
)
from bubblecal.models.likelihood import SD_FLOOR_REL, predict_mechanical, sd_floor_for
from bubblecal.models.mechanical import derived_sites, resolve_setup, shell_params
from bubblecal.models.population import truncnorm_icdf
from bubblecal.priors import PriorSpec

__all__ = ["hierarchical_model", "curve_site_name", "acoustic_site_name"]


def curve_site_name(curve, index: int) -> str:
    """Observed-site name of a curve.

    Parameters
    ----------
    curve : object
        A loading curve (its optional ``name`` is used).
    index : int
        Its position among the curves.

    Returns
    -------
    str
        'y_<curve.name>', or 'y_<index>' for an unnamed curve.
    """
    name = getattr(curve, "name", None)
    return f"y_{name}" if name else f"y_{index}"


def acoustic_site_name(dataset, index: int) -> str:
    """Observed-site name of an acoustic dataset.

    Parameters
    ----------
    dataset : object
        An acoustic dataset (its optional ``name`` is used).
    index : int
        Its position among the acoustic datasets.

    Returns
    -------
    str
        'f_<dataset.name>', or 'f_<index>' for an unnamed dataset.
    """
    name = getattr(dataset, "name", None)
    return f"f_{name}" if name else f"f_{index}"


def _population_draw(site: str, k: str, spec: PriorSpec, m: dict, tau: dict, noncentred: bool):
    """Sample parameter ``k`` at ``site``: uniform if not pooled, else from the population (either form)."""
    p = spec.parameters[k]
    if not p.pooled:
        return numpyro.sample(site, uniform_prior(p.prior))
    lo, hi = float(p.prior.lo), float(p.prior.hi)
    if noncentred:
        u = numpyro.sample(f"{site}_u", dist.Uniform(0.0, 1.0))
        return numpyro.deterministic(site, truncnorm_icdf(u, m[k], tau[k], lo, hi))
    return numpyro.sample(site, TruncatedNormalPopulation(m[k], tau[k], lo, hi))


def hierarchical_model(curves: Sequence, surrogates: Sequence[Callable], spec: PriorSpec, *,
                       acoustic: Sequence = (), f_res=None, noncentred: bool = False, observed: bool = True,
                       sd_floor_rel: float = SD_FLOOR_REL, units: UnitSystem = DEFAULT_UNITS):
    """NumPyro joint model of one agent (module docstring for the sites and equations).

    Parameters
    ----------
    curves : sequence
        Loading curves: objects with ``x``, ``y`` in DPD units and a ``name`` (e.g.
        :class:`bubblecal.data.LoadingCurve`); an optional ``kind`` is checked against the spec's setup.
    surrogates : sequence of callable
        ``surrogates[i]``: the surrogate ``(params[..., 6], x[...]) -> y[...]`` of curve i's diameter.
    spec : PriorSpec
        Priors, hyperpriors and the pooled parameters.
    acoustic : sequence
        Acoustic datasets: objects with ``diameter_um`` [µm], ``frequency_MHz`` [MHz] and a ``name``
        (e.g. :class:`bubblecal.data.AcousticDataset`); used only when the spec is an acoustic workflow.
    f_res : callable or object or None
        The acoustic surrogate ``(ka, diameter_um) -> MHz``.
    noncentred : bool
        Non-centred parameterisation of the pooled parameters (module docstring).
    observed : bool
        False samples every observation (prior / posterior predictive) with the same noise floors.
    sd_floor_rel : float
        Relative noise floor.
    units : UnitSystem
        Conversions of the deterministic sites.

    Raises
    ------
    ValueError
        For mismatched curves and surrogates, no data, acoustic data without ``f_res``, colliding site
        names, an inconsistent setup, or acoustic data with ``ka`` not free.
    """
    curves = list(curves)
    surrogates = list(surrogates)
    acoustic = list(acoustic) if spec.acoustic else []
    if len(curves) != len(surrogates):
        raise ValueError(f"{len(curves)} curves but {len(surrogates)} surrogates (one per curve)")
    if not curves and not acoustic:
        raise ValueError("hierarchical_model needs at least one curve or acoustic dataset")
    if acoustic and f_res is None:
        raise ValueError("acoustic datasets given but no acoustic surrogate f_res")
    setups = [resolve_setup(spec, s, kind=getattr(c, "kind", None)) for c, s in zip(curves, surrogates, strict=True)]
    names = [curve_site_name(c, i) for i, c in enumerate(curves)] + [acoustic_site_name(d, j)
                                                                      for j, d in enumerate(acoustic)]
    if len(set(names)) != len(names):
        raise ValueError(f"observation site names collide: {names}")
    noise_name = spec.mechanical_noise_name

    m, tau = hyperprior_sites(spec)  # population level

    # mechanical curves
    if curves:
        with numpyro.plate("curves", len(curves)):
            theta = {k: _population_draw(k, k, spec, m, tau, noncentred) for k in spec.free_names}
            sigma = numpyro.sample(noise_name, uniform_prior(spec.noise[noise_name].prior))
        derived_sites(theta, units)
        for i, (curve, surrogate, setup) in enumerate(zip(curves, surrogates, setups, strict=True)):
            params, d0 = shell_params({k: v[i] for k, v in theta.items()}, spec)
            x = jnp.asarray(np.asarray(curve.x, dtype=float))
            y = np.asarray(curve.y, dtype=float)
            yhat = predict_mechanical(surrogate, setup, params, d0, x)
            likelihood = relative_normal(yhat, sigma[i], sd_floor_for(float(np.max(np.abs(y))), sd_floor_rel))
            numpyro.sample(names[i], likelihood, obs=jnp.asarray(y) if observed else None)

    # acoustic datasets: own k_a and sigma_ac each
    if acoustic:
        if "ka" not in spec.parameters:
            raise ValueError(f"priors {spec.name!r}: ka must be free for the acoustic datasets")
        with numpyro.plate("acoustic", len(acoustic)):
            ka_ac = _population_draw("ka_ac", "ka", spec, m, tau, noncentred)
            sigma_ac = numpyro.sample("sigma_ac", uniform_prior(spec.noise["sigma_ac"].prior))
        numpyro.deterministic("E_MPa_ac", ka_ac * (float(units.ka_to_young(1.0)) * 1e-6))
        for j, ds in enumerate(acoustic):
            f_obs = np.asarray(ds.frequency_MHz, dtype=float)
            fhat = predict_frequency(f_res, ka_ac[j], ds.diameter_um)
            likelihood = relative_normal(fhat, sigma_ac[j], sd_floor_for(float(np.max(np.abs(f_obs))), sd_floor_rel))
            numpyro.sample(names[len(curves) + j], likelihood, obs=jnp.asarray(f_obs) if observed else None)
