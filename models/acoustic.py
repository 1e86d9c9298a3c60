"""Acoustic resonance model: one dataset of (diameter, resonance frequency) pairs sharing one k_a.

Units
-----
The acoustic surrogate returns the **physical resonance frequency in MHz** at a bubble diameter in
µm: ``f_res(ka, diameter_um) -> MHz`` with ``ka`` in DPD 2-D modulus units (the surrogate layer
converts the DPD ringdown frequencies with
:meth:`bubblecal.data.units.UnitSystem.frequency_to_physical`). The observations
(:class:`bubblecal.data.AcousticDataset`) are in MHz too, so no conversion happens in the model.

Model (``docs/inference.md`` section 3)::

    ka       ~ Uniform(prior_ka)               site 'ka'
    sigma_ac ~ Uniform(prior_sigma_ac)         site 'sigma_ac'
    f̂_j = f_res(ka, D_j)                        [MHz]
    f_j ~ N(f̂_j, (σ_ac f̂_j)² + s_floor²)       observed site (default 'f'); s_floor = 1e-4 · max f

``f_res`` is any JAX callable ``(ka[...], diameter_um: float) -> f[...]`` (elementwise in ``ka``; the
diameter is passed as a concrete Python float, one call per observed diameter, so a per-diameter
lookup of fitted polynomials may use Python logic) or an object with such an ``f_res`` method. A
surrogate of the form sqrt(a0 + a1 ka + a2 ka²) is valid only inside its simulated k_a range: keep the
prior inside it (a NaN from the surrogate cannot be repaired here).

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

from bubblecal.data import DEFAULT_UNITS, UnitSystem
from bubblecal.models.distributions import relative_normal, uniform_prior
from bubblecal.models.likelihood import SD_FLOOR_REL, noise_sd, sd_floor_for
from bubblecal.models.mechanical import population_factor
from bubblecal.priors import PriorSpec

__all__ = ["acoustic_model", "acoustic_prediction", "as_fres", "predict_frequency", "FrequencyTable"]


@jax.tree_util.register_pytree_node_class
class FrequencyTable:
    """f_res(k_a) = sqrt(max(a0 + a1 k_a + a2 k_a², 0)) [MHz] at fixed diameters, as a pytree of arrays.

    Called like a surrogate, ``table(ka, diameter_um)``, with diameters that may be traced arrays; each
    diameter must be one of the table's (the nearest row is used). :meth:`at` builds it from an
    acoustic surrogate with ``coefficients(diameter_um)`` (e.g.
    :class:`bubblecal.surrogates.acoustic.AcousticSurrogate`, which checks the diameters exist).

    Parameters
    ----------
    diameter_um : array_like
        (n,) diameters [µm].
    coefficients : array_like
        (n, 3) quadratic per diameter: a0 [MHz²], a1 [MHz² per DPD 2-D modulus], a2 [MHz² per (DPD 2-D
        modulus)²].
    """

    def __init__(self, diameter_um, coefficients):
        self.diameter_um = diameter_um
        self.coefficients = coefficients

    @classmethod
    def at(cls, f_res, diameter_um) -> FrequencyTable:
        """The quadratics of an acoustic surrogate at given diameters.

        Parameters
        ----------
        f_res : object
            Acoustic surrogate with ``coefficients(diameter_um) -> (n, 3)``.
        diameter_um : array_like
            Diameters [µm].

        Returns
        -------
        FrequencyTable
        """
        d = np.atleast_1d(np.asarray(diameter_um, dtype=float))
        return cls(d, np.asarray(f_res.coefficients(d), dtype=float).reshape(len(d), 3))

    def __call__(self, ka, diameter_um):
        """Resonance frequency [MHz] at ``ka`` [DPD 2-D modulus] and the table's ``diameter_um`` [µm]."""
        table_d = jnp.asarray(self.diameter_um)
        d = jnp.asarray(diameter_um, dtype=table_d.dtype)
        row = jnp.argmin(jnp.abs(d[..., None] - table_d), axis=-1)
        c = jnp.asarray(self.coefficients)[row]
        ka = jnp.asarray(ka)
        # AcousticSurrogate.f_res: the same quadratic in the same order, clamped before the root
        return jnp.sqrt(jnp.maximum(c[..., 0] + c[..., 1] * ka + c[..., 2] * ka * ka, 0.0))

    def tree_flatten(self):
        """Pytree children (diameters, coefficients), no auxiliary data."""
        return (self.diameter_um, self.coefficients), None

    @classmethod
    def tree_unflatten(cls, aux, children):
        """Rebuild from :meth:`tree_flatten`'s output."""
        return cls(*children)


def as_fres(f_res) -> Callable:
    """The callable ``(ka, diameter_um) -> MHz`` behind an acoustic surrogate.

    Parameters
    ----------
    f_res : callable or object
        A callable, or an object with an ``f_res`` method.

    Returns
    -------
    callable

    Raises
    ------
    TypeError
        If ``f_res`` is neither.
    """
    if callable(f_res):
        return f_res
    method = getattr(f_res, "f_res", None)
    if callable(method):
        return method
    raise TypeError(f"expected an acoustic surrogate callable (ka, diameter_um) -> MHz, got {type(f_res).__name__}")


def predict_frequency(f_res, ka, diameter_um):
    """Predicted resonance frequencies f̂_j = max(0, f_res(ka, D_j)) for each diameter.

    Parameters
    ----------
    f_res : callable or object
        Acoustic surrogate (see :func:`as_fres`; a :class:`FrequencyTable` takes traced diameters).
    ka : array_like
        Stretching modulus [DPD 2-D modulus].
    diameter_um : array_like
        (n,) diameters [µm].

    Returns
    -------
    Array
        Frequencies [MHz], shape ``ka.shape + (n,)``.
    """
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

    Sites: ``ka``, ``sigma_ac``, the deterministic ``E_MPa`` and the observed ``obs_name``.

    Parameters
    ----------
    diameter_um : array_like
        (n,) bubble diameters [µm]; may be traced with a :class:`FrequencyTable` as ``f_res``.
    frequency_MHz : array_like or None
        (n,) resonance frequencies [MHz]; None samples them.
    f_res : callable or object
        Acoustic surrogate ``(ka, diameter_um) -> MHz`` (see :func:`as_fres`).
    spec : PriorSpec
        Priors of ``ka`` and ``sigma_ac``.
    obs_name : str
        Name of the observed site.
    f_scale : float or None
        Data scale of the noise floor [MHz] (default max |f|).
    sd_floor_rel : float
        Relative noise floor.
    units : UnitSystem
        Conversion of ``E_MPa``.
    population : tuple of (dict, dict) or None
        Phase-3 population prior of ``ka`` (see :func:`~bubblecal.models.mechanical.population_factor`).

    Raises
    ------
    ValueError
        If the spec declares no ``sigma_ac`` or ``ka`` is not free.
    """
    if "sigma_ac" not in spec.noise:
        raise ValueError(f"priors {spec.name!r} declare no 'sigma_ac' (use an acoustic workflow's priors)")
    if "ka" not in spec.parameters:
        raise ValueError(f"priors {spec.name!r}: ka must be a free parameter for the acoustic model")
    if not isinstance(as_fres(f_res), FrequencyTable):
        diameter_um = np.asarray(diameter_um, dtype=float)  # the surrogate looks diameters up on the host
    ka = numpyro.sample("ka", uniform_prior(spec.parameters["ka"].prior))
    numpyro.deterministic("E_MPa", ka * (float(units.ka_to_young(1.0)) * 1e-6))
    if population is not None:
        population_factor({"ka": ka}, spec, population)
    sigma_ac = numpyro.sample("sigma_ac", uniform_prior(spec.noise["sigma_ac"].prior))
    fhat = predict_frequency(f_res, ka, diameter_um)
    obs = None if frequency_MHz is None else jnp.asarray(frequency_MHz, dtype=float)
    if f_scale is None:
        # max |f| (the float32 of the float64 maximum, as np.max gave)
        f_scale = jnp.max(jnp.abs(obs)) if obs is not None else jnp.max(fhat)
    numpyro.sample(obs_name, relative_normal(fhat, sigma_ac, sd_floor_for(f_scale, sd_floor_rel)), obs=obs)


def acoustic_prediction(ka_samples, sigma_samples, f_res, diameter_um, *, f_scale: float,
                        sd_floor_rel: float = SD_FLOOR_REL):
    """Per-sample predicted frequency and noise standard deviation, for the Gaussian-mixture predictive.

    Parameters
    ----------
    ka_samples, sigma_samples : array_like
        (S,) draws of ``ka`` [DPD 2-D modulus] and ``sigma_ac`` [-].
    f_res : callable or object
        Acoustic surrogate.
    diameter_um : array_like
        (n,) diameters [µm].
    f_scale : float
        Data scale of the noise floor [MHz], as in the fit.
    sd_floor_rel : float
        Relative noise floor.

    Returns
    -------
    fhat, sd : Array
        (S, n) each [MHz].
    """
    fhat = predict_frequency(f_res, jnp.asarray(ka_samples), diameter_um)
    sigma = jnp.asarray(sigma_samples)[:, None]
    return fhat, noise_sd(fhat, sigma, sd_floor_for(f_scale, sd_floor_rel))
