"""Acoustic resonance model: one dataset of (diameter, resonance frequency) pairs sharing one k_a.

Units and the decision on frequencies
-------------------------------------
The acoustic surrogate is taken to return the **physical resonance frequency in MHz** at a bubble
diameter in µm: ``f_res(ka, diameter_um) -> MHz`` with ``ka`` in DPD 2-D modulus units (the DPD
ringdown frequencies are converted to MHz by the surrogate layer through
:meth:`bubblecal.data.units.UnitSystem.frequency_to_physical`, which knows the ringdown mass factor).
The observations (:class:`bubblecal.data.AcousticDataset`) are in MHz too, so no conversion happens in
the model; with relative noise the likelihood is scale-free anyway.

Model (``shared/docs/inference.md`` §3)::

    ka       ~ Uniform(prior_ka)               site 'ka'
    sigma_ac ~ Uniform(prior_sigma_ac)         site 'sigma_ac'
    f̂_j = f_res(ka, D_j)                        [MHz]
    f_j ~ N(f̂_j, (σ_ac f̂_j)² + s_floor²)       observed site (default 'f'); s_floor = 1e-4 · max f

``f_res`` is any JAX callable ``(ka[...], diameter_um: float) -> f[...]`` (elementwise in ``ka``; the
diameter is passed as a concrete Python float, one call per observed diameter, so a per-diameter
lookup of fitted polynomials may use Python logic) or an object with such an ``f_res`` method. A surrogate of the form
sqrt(a0 + a1 ka + a2 ka²) is valid only inside its simulated k_a range: keep the prior inside it
(a NaN from the surrogate cannot be repaired here).
"""

from __future__ import annotations

from collections.abc import Callable

import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist

from bubblecal.data.units import DEFAULT_UNITS, UnitSystem
from bubblecal.models.likelihood import SD_FLOOR_REL, noise_sd, sd_floor_for
from bubblecal.models.mechanical import population_factor
from bubblecal.priors.spec import PriorSpec

__all__ = ["acoustic_model", "acoustic_prediction", "as_fres", "predict_frequency"]


def as_fres(f_res) -> Callable:
    """The callable ``(ka, diameter_um) -> MHz`` behind ``f_res`` (a callable or an object with ``f_res``)."""
    if callable(f_res):
        return f_res
    method = getattr(f_res, "f_res", None)
    if callable(method):
        return method
    raise TypeError(f"expected an acoustic surrogate callable (ka, diameter_um) -> MHz, got {type(f_res).__name__}")


def predict_frequency(f_res, ka, diameter_um):
    """f̂_j = f_res(ka, D_j) [MHz] for each diameter, clamped at 0: shape ka.shape + (n,)."""
    fres = as_fres(f_res)
    diameters = np.atleast_1d(np.asarray(diameter_um, dtype=float))
    return jnp.maximum(jnp.stack([jnp.asarray(fres(ka, float(d))) for d in diameters], axis=-1), 0.0)


def acoustic_model(diameter_um, frequency_MHz, f_res, spec: PriorSpec, *, obs_name: str = "f",
                   f_scale: float | None = None, sd_floor_rel: float = SD_FLOOR_REL,
                   units: UnitSystem = DEFAULT_UNITS, population=None):
    """NumPyro model of one acoustic dataset (module docstring for the equations).

    ``diameter_um`` [µm] and ``frequency_MHz`` [MHz] are arrays of equal length (``frequency_MHz=None``
    samples the observations); ``spec`` provides the priors of ``ka`` and ``sigma_ac``. ``population``:
    phase-3 population prior of ``ka`` (see :func:`bubblecal.models.mechanical.population_factor`).
    """
    if "sigma_ac" not in spec.noise:
        raise ValueError(f"priors {spec.name!r} declare no 'sigma_ac' (use an acoustic workflow's priors)")
    if "ka" not in spec.parameters:
        raise ValueError(f"priors {spec.name!r}: ka must be a free parameter for the acoustic model")
    diameter_um = np.asarray(diameter_um, dtype=float)
    b = spec.parameters["ka"].prior
    ka = numpyro.sample("ka", dist.Uniform(float(b.lo), float(b.hi)))
    numpyro.deterministic("E_MPa", ka * (float(units.ka_to_young(1.0)) * 1e-6))
    if population is not None:
        population_factor({"ka": ka}, spec, population)
    b = spec.noise["sigma_ac"].prior
    sigma_ac = numpyro.sample("sigma_ac", dist.Uniform(float(b.lo), float(b.hi)))
    fhat = predict_frequency(f_res, ka, diameter_um)
    if f_scale is None:
        f_scale = float(np.max(np.abs(frequency_MHz))) if frequency_MHz is not None else jnp.max(fhat)
    sd = noise_sd(fhat, sigma_ac, sd_floor_for(f_scale, sd_floor_rel))
    obs = None if frequency_MHz is None else jnp.asarray(np.asarray(frequency_MHz, dtype=float))
    numpyro.sample(obs_name, dist.Normal(fhat, sd), obs=obs)


def acoustic_prediction(ka_samples, sigma_samples, f_res, diameter_um, *, f_scale: float,
                        sd_floor_rel: float = SD_FLOOR_REL):
    """Per-sample predicted frequency and noise sd [MHz] at ``diameter_um``: arrays (S, n) each."""
    fhat = predict_frequency(f_res, jnp.asarray(ka_samples), diameter_um)
    sigma = jnp.asarray(sigma_samples)[:, None]
    return fhat, noise_sd(fhat, sigma, sd_floor_for(f_scale, sd_floor_rel))
