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

:class:`FrequencyTable` holds an acoustic surrogate's quadratics at given diameters as arrays: passed
as ``f_res`` (with the diameters and frequencies as arrays too) nothing of the dataset is a constant
of a compiled sampler, so datasets with the same number of bubbles share one compiled likelihood.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist

from bubblecal.data import DEFAULT_UNITS, UnitSystem
from bubblecal.models.likelihood import SD_FLOOR_REL, noise_sd, sd_floor_for
from bubblecal.models.mechanical import population_factor
from bubblecal.priors import PriorSpec

__all__ = ["acoustic_model", "acoustic_prediction", "as_fres", "predict_frequency", "FrequencyTable"]


@jax.tree_util.register_pytree_node_class
class FrequencyTable:
    """f_res(k_a) = sqrt(max(a0 + a1 k_a + a2 k_a², 0)) [MHz] at fixed diameters, as a pytree of arrays.

    ``diameter_um`` (n,) [µm] and ``coefficients`` (n, 3) (a0 [MHz²], a1, a2 per diameter). Called
    like a surrogate, ``table(ka, diameter_um)``, with diameters that may be traced arrays; each
    diameter must be one of the table's (the nearest row is used). :meth:`at` builds it from an
    acoustic surrogate with ``coefficients(diameter_um)`` (e.g.
    :class:`bubblecal.surrogates.acoustic.AcousticSurrogate`, which checks the diameters exist).
    """

    def __init__(self, diameter_um, coefficients):
        self.diameter_um = diameter_um
        self.coefficients = coefficients

    @classmethod
    def at(cls, f_res, diameter_um) -> FrequencyTable:
        """The quadratics of acoustic surrogate ``f_res`` at the diameters ``diameter_um`` [µm]."""
        d = np.atleast_1d(np.asarray(diameter_um, dtype=float))
        return cls(d, np.asarray(f_res.coefficients(d), dtype=float).reshape(len(d), 3))

    def __call__(self, ka, diameter_um):
        table_d = jnp.asarray(self.diameter_um)
        d = jnp.asarray(diameter_um, dtype=table_d.dtype)
        row = jnp.argmin(jnp.abs(d[..., None] - table_d), axis=-1)
        c = jnp.asarray(self.coefficients)[row]
        ka = jnp.asarray(ka)
        # AcousticSurrogate.f_res: the same quadratic in the same order, clamped before the root
        return jnp.sqrt(jnp.maximum(c[..., 0] + c[..., 1] * ka + c[..., 2] * ka * ka, 0.0))

    def tree_flatten(self):
        return (self.diameter_um, self.coefficients), None

    @classmethod
    def tree_unflatten(cls, aux, children):
        return cls(*children)


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
    if isinstance(fres, FrequencyTable):  # all diameters in one call: they may be traced
        d = jnp.atleast_1d(jnp.asarray(diameter_um, dtype=float))
        return jnp.maximum(fres(jnp.asarray(ka)[..., None], d), 0.0)
    diameters = np.atleast_1d(np.asarray(diameter_um, dtype=float))
    return jnp.maximum(jnp.stack([jnp.asarray(fres(ka, float(d))) for d in diameters], axis=-1), 0.0)


def acoustic_model(diameter_um, frequency_MHz, f_res, spec: PriorSpec, *, obs_name: str = "f",
                   f_scale: float | None = None, sd_floor_rel: float = SD_FLOOR_REL,
                   units: UnitSystem = DEFAULT_UNITS, population=None):
    """NumPyro model of one acoustic dataset (module docstring for the equations).

    ``diameter_um`` [µm] and ``frequency_MHz`` [MHz] are arrays of equal length (``frequency_MHz=None``
    samples the observations); ``spec`` provides the priors of ``ka`` and ``sigma_ac``. ``population``:
    phase-3 population prior of ``ka`` (see :func:`bubblecal.models.mechanical.population_factor`).
    With a :class:`FrequencyTable` as ``f_res`` the arrays may be traced (jit arguments).
    """
    if "sigma_ac" not in spec.noise:
        raise ValueError(f"priors {spec.name!r} declare no 'sigma_ac' (use an acoustic workflow's priors)")
    if "ka" not in spec.parameters:
        raise ValueError(f"priors {spec.name!r}: ka must be a free parameter for the acoustic model")
    if not isinstance(as_fres(f_res), FrequencyTable):
        diameter_um = np.asarray(diameter_um, dtype=float)  # the surrogate looks diameters up on the host
    b = spec.parameters["ka"].prior
    ka = numpyro.sample("ka", dist.Uniform(float(b.lo), float(b.hi)))
    numpyro.deterministic("E_MPa", ka * (float(units.ka_to_young(1.0)) * 1e-6))
    if population is not None:
        population_factor({"ka": ka}, spec, population)
    b = spec.noise["sigma_ac"].prior
    sigma_ac = numpyro.sample("sigma_ac", dist.Uniform(float(b.lo), float(b.hi)))
    fhat = predict_frequency(f_res, ka, diameter_um)
    obs = None if frequency_MHz is None else jnp.asarray(frequency_MHz, dtype=float)
    if f_scale is None:
        # max |f| (the float32 of the float64 maximum, as np.max gave)
        f_scale = jnp.max(jnp.abs(obs)) if obs is not None else jnp.max(fhat)
    sd = noise_sd(fhat, sigma_ac, sd_floor_for(f_scale, sd_floor_rel))
    numpyro.sample(obs_name, dist.Normal(fhat, sd), obs=obs)


def acoustic_prediction(ka_samples, sigma_samples, f_res, diameter_um, *, f_scale: float,
                        sd_floor_rel: float = SD_FLOOR_REL):
    """Per-sample predicted frequency and noise sd [MHz] at ``diameter_um``: arrays (S, n) each."""
    fhat = predict_frequency(f_res, jnp.asarray(ka_samples), diameter_um)
    sigma = jnp.asarray(sigma_samples)[:, None]
    return fhat, noise_sd(fhat, sigma, sd_floor_for(f_scale, sd_floor_rel))
