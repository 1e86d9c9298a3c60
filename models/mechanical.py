"""Single-curve mechanical model (AFM force spectroscopy), full or reduced shell, driven by a PriorSpec.

Units: DPD throughout (:mod:`bubblecal.data.units`). Compression curves: x = imposed displacement
[DPD length], y = plate force [DPD force]; indentation curves: x = applied force [DPD force],
y = indentation depth [DPD length]. ``ka`` [DPD 2-D modulus], ``kb`` [DPD energy], ``b1, b2, a3, a4``
[-], ``d0`` [DPD length], ``sigma``/``sigma_mech`` [-].

Model (``docs/inference.md`` section 2)::

    Θ_k ~ Uniform(prior_k)              for every free shell parameter k of the spec (sites ka, kb, ..., d0)
    σ   ~ Uniform(prior_σ)              site 'sigma' ('sigma_mech' in acoustic workflows)
    compression: ŷ_j = max(0, S(Θ; max(0, x_j − d0)))
    indentation: ŷ_j = max(0, S(Θ; x_j) + d0)
    y_j ~ N(ŷ_j, (σ ŷ_j)² + s_floor²)   observed site (default name 'y'); s_floor = 1e-4 · max|y|

Parameters listed under ``[fixed]`` of the spec are not sampled; a reduced spec fixes
b1 = b2 = a3 = a4 = 0 and evaluates the *same* surrogate at those zeros (:func:`reduced_spec` builds one
from a full spec). Deterministic sites: ``E_MPa`` (Young's modulus, ν = 1/2) when ``ka`` is free and
``kappa_kBT`` (continuum bending modulus) when ``kb`` is free.

Phase 3 of the staged hierarchy (``docs/inference.md`` section 4): pass ``population=(m_samples, tau_samples)``
(dicts name -> (S,) arrays of phase-2 hyperparameter samples) and the model adds the factor site
``population_prior`` = log mean_s p(θ_pooled | ψ_s) − log p0(θ_pooled), i.e. the learned population
prior replaces the uniform prior of the pooled parameters (p0 is divided out, not multiplied twice).
Being a factor, a TMCMC tempers it together with the likelihood; the tempered path differs but the
final posterior (β = 1) and the evidence ∫ p(D | θ) p(θ | data_pop) dθ are the same as with the
population prior as the starting distribution.

Gradient-based samplers: where x_j < d0 (compression) the prediction is clamped to 0 and the log
density is flat in d0 (a plateau about −(y_j / s_floor)² / 2 below the good region); a NUTS chain
started there cannot find its way out. Start NUTS with d0 below the first displacement, e.g.
``NUTS(model, init_strategy=init_to_value(values=nuts_init_values(spec)))``. TMCMC is unaffected.

``surrogate`` is any callable ``(params[..., 6], x[...]) -> y[...]`` (ka, kb, b1, b2, a3, a4 in the last
axis; leading shape broadcasts with ``x``) written in JAX; if it has a ``setup`` attribute it must
match the curve's. :class:`~bubblecal.models.traced.TracedSurrogate` wraps a loaded MLP surrogate so
that its weights are arguments of a compiled sampler rather than constants (curves with networks of one
shape then share one compiled likelihood); ``mask`` lets curves padded to one length share it too
(:func:`~bubblecal.models.traced.pad_curve`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping

import jax
import jax.numpy as jnp
import numpy as np
import numpyro

from bubblecal.data import DEFAULT_UNITS, MODEL_PARAMETERS, NONLINEAR_PARAMETERS, SHELL_PARAMETERS, UnitSystem
from bubblecal.models.distributions import relative_normal, uniform_prior
from bubblecal.models.likelihood import SD_FLOOR_REL, noise_sd, predict_mechanical, sd_floor_for
from bubblecal.models.population import population_predictive_log_density
from bubblecal.priors import PriorSpec

__all__ = [
    "POPULATION_SITE",
    "nuts_init_values",
    "population_factor",
    "mechanical_model",
    "mechanical_prediction",
    "reduced_spec",
    "resolve_setup",
    "shell_params",
    "derived_sites",
]


def resolve_setup(spec: PriorSpec, surrogate=None, setup: str | None = None, kind: str | None = None) -> str:
    """The loading protocol, checked for consistency between spec, surrogate, curve kind and argument.

    Parameters
    ----------
    spec : PriorSpec
        The priors (their ``setup``).
    surrogate : object or None
        The surrogate; its ``setup`` attribute, if any, is checked.
    setup : str or None
        Explicit protocol (default the spec's).
    kind : str or None
        The curve's kind, if known.

    Returns
    -------
    str
        'compression' or 'indentation'.

    Raises
    ------
    ValueError
        If the sources disagree or the protocol is unknown.
    """
    chosen = setup or spec.setup
    for what, value in (("surrogate.setup", getattr(surrogate, "setup", None)), ("curve kind", kind),
                        ("spec.setup", spec.setup)):
        if value is not None and value != chosen:
            raise ValueError(f"setup mismatch: {what} is {value!r} but the model runs {chosen!r} "
                             f"(priors {spec.name!r})")
    if chosen not in ("compression", "indentation"):
        raise ValueError(f"setup must be 'compression' or 'indentation', got {chosen!r}")
    return chosen


def reduced_spec(spec: PriorSpec) -> PriorSpec:
    """The reduced shell of a spec: b1 = b2 = a3 = a4 fixed at 0, other ranges unchanged.

    Parameters
    ----------
    spec : PriorSpec
        A full or reduced spec.

    Returns
    -------
    PriorSpec
        Shell 'reduced'; a full spec's name gets the suffix ``_reduced``.
    """
    parameters = {k: v for k, v in spec.parameters.items() if k not in NONLINEAR_PARAMETERS}
    fixed = dict(spec.fixed)
    fixed.update({k: 0.0 for k in NONLINEAR_PARAMETERS})
    return dataclasses.replace(spec, name=f"{spec.name}_reduced" if spec.shell == "full" else spec.name,
                               shell="reduced", parameters=parameters, fixed=fixed)


def shell_params(values: Mapping, spec: PriorSpec):
    """Surrogate inputs and offset from sampled values and the spec's fixed parameters.

    Parameters
    ----------
    values : mapping of str to array_like
        Free parameter name -> array of a common batch shape (scalars for one Θ), DPD units.
    spec : PriorSpec
        Gives the fixed parameters.

    Returns
    -------
    params : Array
        (..., 6) in :data:`~bubblecal.data.names.SHELL_PARAMETERS` order.
    d0 : Array
        (...) offset [DPD length].
    """
    free = [values[k] for k in MODEL_PARAMETERS if k in values]
    like = jnp.asarray(free[0]) if free else jnp.zeros(())
    cols = []
    for k in SHELL_PARAMETERS:
        v = values[k] if k in values else spec.fixed[k]
        cols.append(jnp.broadcast_to(jnp.asarray(v, dtype=like.dtype), like.shape))
    d0 = values["d0"] if "d0" in values else spec.fixed["d0"]
    return jnp.stack(cols, axis=-1), jnp.broadcast_to(jnp.asarray(d0, dtype=like.dtype), like.shape)


def derived_sites(values: Mapping, units: UnitSystem = DEFAULT_UNITS, suffix: str = "") -> None:
    """Record ``E_MPa`` (from ka) and ``kappa_kBT`` (from kb) as deterministic sites when present.

    Parameters
    ----------
    values : mapping of str to array_like
        Sampled parameters (DPD units).
    units : UnitSystem
        Conversions: Young's modulus [MPa] (ν = 1/2) and continuum bending modulus [k_BT].
    suffix : str
        Appended to the site names.
    """
    if "ka" in values:
        numpyro.deterministic("E_MPa" + suffix, values["ka"] * (float(units.ka_to_young(1.0)) * 1e-6))
    if "kb" in values:
        numpyro.deterministic("kappa_kBT" + suffix, values["kb"] * float(units.kb_to_bending_kBT(1.0)))


def nuts_init_values(spec: PriorSpec, n_curves: int | None = None) -> dict:
    """Initial values that keep NUTS off the clamped plateau (see the module docstring).

    d0 near the bottom of its prior for compression (lo + 2% of the width), 0 (clipped into the prior)
    for indentation. Pass to ``numpyro.infer.init_to_value(values=...)``; other sites keep NumPyro's
    default initialisation.

    Parameters
    ----------
    spec : PriorSpec
        The priors.
    n_curves : int or None
        For :func:`~bubblecal.models.hierarchical_model`: per-bubble arrays of this length, plus
        ``m_d0`` and, for the non-centred form, ``d0_u``.

    Returns
    -------
    dict
        Site name -> initial value [DPD length for d0]; empty if d0 is fixed.
    """
    if "d0" not in spec.parameters:
        return {}
    p = spec.parameters["d0"]
    lo, hi = p.prior.lo, p.prior.hi
    d0 = lo + 0.02 * (hi - lo) if spec.setup == "compression" else min(max(0.0, lo), hi)
    if n_curves is None:
        return {"d0": d0}
    out = {"d0": np.full(n_curves, d0)}
    if p.pooled:
        out["m_d0"] = float(np.clip(d0, p.hyper_m.lo + 1e-3 * p.hyper_m.width, p.hyper_m.hi))
        out["d0_u"] = np.full(n_curves, 0.1)
    return out


#: The factor site through which a phase-3 model adds its population prior (the one a TMCMC from phase 1 tempers).
POPULATION_SITE = "population_prior"


def population_factor(values: Mapping, spec: PriorSpec, population, site: str = POPULATION_SITE) -> None:
    """Add the phase-3 factor log mean_s p(θ | ψ_s) − log p0(θ) over the pooled parameters in ``values``.

    Parameters
    ----------
    values : mapping of str to array_like
        Sampled parameters (DPD units).
    spec : PriorSpec
        Gives the pooled parameters and their prior ranges (p0 is uniform on them).
    population : tuple of (dict, dict)
        (m_samples, tau_samples): parameter name -> (S,) phase-2 draws of ψ.
    site : str
        Name of the factor site.

    Raises
    ------
    ValueError
        If the population shares no pooled parameter with the model.
    """
    m_samples, tau_samples = population
    names = [k for k in spec.pooled_names if k in values and k in m_samples]
    if not names:
        raise ValueError("population samples share no pooled parameter with the model")
    bounds = {k: spec.parameters[k].prior.as_tuple() for k in names}
    theta = {k: values[k] for k in names}
    log_pop = population_predictive_log_density(theta, {k: m_samples[k] for k in names},
                                                {k: tau_samples[k] for k in names}, bounds)
    log_p0 = -sum(float(np.log(bounds[k][1] - bounds[k][0])) for k in names)
    numpyro.factor(site, log_pop - log_p0)


def mechanical_model(x, y, surrogate: Callable, spec: PriorSpec, *, setup: str | None = None, obs_name: str = "y",
                     y_scale: float | None = None, sd_floor_rel: float = SD_FLOOR_REL,
                     units: UnitSystem = DEFAULT_UNITS, population=None, mask=None):
    """NumPyro model of one loading curve under uniform priors (module docstring for the equations).

    Sites: the free shell parameters of ``spec`` by name, the mechanical noise
    (``spec.mechanical_noise_name``), the observed ``obs_name`` and the deterministic ``E_MPa`` /
    ``kappa_kBT``.

    Parameters
    ----------
    x : array_like
        (n,) loading coordinates: displacement [DPD length] (compression) or force [DPD force]
        (indentation); may be traced (a jit argument).
    y : array_like or None
        (n,) observations: force [DPD force] or depth [DPD length]; None samples them (prior /
        posterior predictive).
    surrogate : callable
        ``(params[..., 6], x[...]) -> y[...]`` in DPD units (e.g. a
        :class:`~bubblecal.models.traced.TracedSurrogate`).
    spec : PriorSpec
        Priors of the free parameters and the noise.
    setup : str or None
        Loading protocol (default the spec's; checked by :func:`resolve_setup`).
    obs_name : str
        Name of the observed site.
    y_scale : float or None
        Data scale of the noise floor s_floor = ``sd_floor_rel`` · y_scale (units of y; default
        max |y| over the real points); pass it with ``y=None`` to reproduce the fit's density.
    sd_floor_rel : float
        Relative noise floor.
    units : UnitSystem
        Conversions of the deterministic sites.
    population : tuple of (dict, dict) or None
        Phase-3 population prior (module docstring): adds the factor site ``population_prior``.
    mask : array_like or None
        (n,) booleans, False on padding points (:func:`~bubblecal.models.traced.pad_curve`), which add
        nothing to the likelihood.

    Raises
    ------
    ValueError
        For an inconsistent setup or a spec without the mechanical noise amplitude.
    """
    setup = resolve_setup(spec, surrogate, setup)
    x = jnp.asarray(x, dtype=float)
    values = {k: numpyro.sample(k, uniform_prior(p.prior)) for k, p in spec.parameters.items()}
    noise_name = spec.mechanical_noise_name
    if noise_name not in spec.noise:
        raise ValueError(f"priors {spec.name!r} declare no noise amplitude {noise_name!r}")
    sigma = numpyro.sample(noise_name, uniform_prior(spec.noise[noise_name].prior))
    derived_sites(values, units)
    if population is not None:
        population_factor(values, spec, population)
    params, d0 = shell_params(values, spec)
    yhat = predict_mechanical(surrogate, setup, params, d0, x)
    y = None if y is None else jnp.asarray(y, dtype=float)
    if y_scale is None:
        # max |y| over the real points (the float32 of the float64 maximum, as np.max gave)
        y_scale = jnp.max(jnp.abs(y if mask is None else jnp.where(mask, y, 0.0))) if y is not None \
            else jnp.max(jnp.abs(yhat))
    likelihood = relative_normal(yhat, sigma, sd_floor_for(y_scale, sd_floor_rel))
    numpyro.sample(obs_name, likelihood if mask is None else likelihood.mask(jnp.asarray(mask, dtype=bool)), obs=y)


def mechanical_prediction(samples: Mapping, surrogate: Callable, spec: PriorSpec, x, *, y_scale: float,
                          setup: str | None = None, sd_floor_rel: float = SD_FLOOR_REL, noise_name: str | None = None):
    """Per-sample predicted curve and noise standard deviation, for the Gaussian-mixture predictive.

    Parameters
    ----------
    samples : mapping of str to array_like
        Free parameter names and the noise name -> (S,) draws (of :func:`mechanical_model`, or one
        bubble's slice of the hierarchical model), DPD units.
    surrogate : callable
        ``(params[..., 6], x[...]) -> y[...]`` in DPD units.
    spec : PriorSpec
        The priors the samples come from.
    x : array_like
        Loading coordinates (DPD units).
    y_scale : float
        Data scale of the noise floor (units of y, as in the fit).
    setup : str or None
        Loading protocol (default the spec's).
    sd_floor_rel : float
        Relative noise floor.
    noise_name : str or None
        Noise site (default ``spec.mechanical_noise_name``).

    Returns
    -------
    yhat, sd : Array
        (S, len(x)) each, in the DPD units of y; the pair :mod:`bubblecal.inference.predictive` needs.
    """
    setup = resolve_setup(spec, surrogate, setup)
    noise_name = noise_name or spec.mechanical_noise_name
    values = {k: jnp.asarray(samples[k])[:, None] for k in spec.parameters}
    params, d0 = shell_params(values, spec)  # (S, 1, 6), (S, 1)
    # a float array in JAX's default precision, concrete or traced (the prediction may run under jit)
    x = jnp.asarray(x, dtype=jax.dtypes.canonicalize_dtype(np.float64))
    yhat = predict_mechanical(surrogate, setup, params, d0, x[None, :])
    sigma = jnp.asarray(samples[noise_name])[:, None]
    return yhat, noise_sd(yhat, sigma, sd_floor_for(y_scale, sd_floor_rel))
