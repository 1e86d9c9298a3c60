"""Single-curve mechanical model (AFM force spectroscopy), full or reduced shell, driven by a PriorSpec.

Units: DPD throughout (:mod:`bubblecal.data.units`). Compression curves: x = imposed displacement
[DPD length], y = plate force [DPD force]; indentation curves: x = applied force [DPD force],
y = indentation depth [DPD length]. ``ka`` [DPD 2-D modulus], ``kb`` [DPD energy], ``b1, b2, a3, a4``
[-], ``d0`` [DPD length], ``sigma``/``sigma_mech`` [-].

Model (``shared/docs/inference.md`` §2)::

    Θ_k ~ Uniform(prior_k)              for every free shell parameter k of the spec (sites ka, kb, ..., d0)
    σ   ~ Uniform(prior_σ)              site 'sigma' ('sigma_mech' in acoustic workflows)
    compression: ŷ_j = max(0, S(Θ; max(0, x_j − d0)))
    indentation: ŷ_j = max(0, S(Θ; x_j) + d0)
    y_j ~ N(ŷ_j, (σ ŷ_j)² + s_floor²)   observed site (default name 'y'); s_floor = 1e-4 · max|y|

Parameters listed under ``[fixed]`` of the spec are not sampled; a reduced spec fixes
b1 = b2 = a3 = a4 = 0 and evaluates the *same* surrogate at those zeros (:func:`reduced_spec` builds one
from a full spec). Deterministic sites: ``E_MPa`` (Young's modulus, ν = 1/2) when ``ka`` is free and
``kappa_kBT`` (continuum bending modulus) when ``kb`` is free.

Phase 3 of the staged hierarchy (``inference.md`` §4): pass ``population=(m_samples, tau_samples)``
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
match the curve's. :class:`TracedSurrogate` wraps a loaded MLP surrogate so that its weights are
arguments of a compiled sampler rather than constants (curves with networks of one shape then share
one compiled likelihood); ``mask`` lets curves padded to one length share it too (:func:`pad_curve`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping

import jax
import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist

from bubblecal.data import DEFAULT_UNITS, MODEL_PARAMETERS, NONLINEAR_PARAMETERS, SHELL_PARAMETERS, UnitSystem
from bubblecal.models.likelihood import (
    SD_FLOOR_REL,
    noise_sd,
    population_predictive_log_density,
    predict_mechanical,
    sd_floor_for,
)
from bubblecal.priors import PriorSpec
from bubblecal.surrogates import mlp_forward, surrogate_inputs

__all__ = [
    "nuts_init_values",
    "population_factor",
    "mechanical_model",
    "mechanical_prediction",
    "reduced_spec",
    "resolve_setup",
    "shell_params",
    "derived_sites",
    "TracedSurrogate",
    "pad_curve",
]


@jax.tree_util.register_pytree_node_class
class TracedSurrogate:
    """A loaded MLP surrogate (:class:`bubblecal.surrogates.Surrogate`) as a pytree of its arrays.

    Same call ``(params[..., 6], x[...]) -> y[...]`` and the same arithmetic as the surrogate, but the
    weights and normalisations are pytree leaves: given to a model as an argument they are traced data
    of a compiled TMCMC program (not constants compiled into it), so curves whose networks have the same
    layer sizes and setup share one compiled likelihood. ``setup`` as the surrogate's (checked by
    :func:`resolve_setup`); ``param_names`` the surrogate's parameter inputs (``x`` is the last input).
    """

    def __init__(self, weights, biases, in_mean, in_std, out_mean, out_std, setup: str, param_names: tuple):
        self.weights, self.biases = tuple(weights), tuple(biases)
        self.in_mean, self.in_std, self.out_mean, self.out_std = in_mean, in_std, out_mean, out_std
        self.setup = setup
        self.param_names = tuple(param_names)

    @classmethod
    def wrap(cls, surrogate):
        """The surrogate as a :class:`TracedSurrogate`; anything that is not an MLP surrogate unchanged."""
        fields = ("weights", "biases", "in_mean", "in_std", "out_mean", "out_std", "setup", "param_names")
        if isinstance(surrogate, cls) or not all(hasattr(surrogate, f) for f in fields):
            return surrogate
        return cls(*(getattr(surrogate, f) for f in fields))

    def __call__(self, params, x):
        u = surrogate_inputs(params, x, self.param_names)  # as Surrogate.__call__
        y = mlp_forward(self.weights, self.biases, self.in_mean, self.in_std, self.out_mean, self.out_std, u)
        return y[..., 0]

    def tree_flatten(self):
        return (self.weights, self.biases, self.in_mean, self.in_std, self.out_mean, self.out_std), (
            self.setup, self.param_names)

    @classmethod
    def tree_unflatten(cls, aux, children):
        return cls(*children, *aux)


def pad_curve(x, y, length: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x, y, mask) of a curve padded to ``length`` points for :func:`mechanical_model`'s ``mask``.

    Padding repeats the last x (a point the surrogate evaluates normally) with y = 0, and the mask
    (True on the real points) removes those points from the likelihood and from max |y|.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    n = len(x)
    if length < n:
        raise ValueError(f"cannot pad a curve of {n} points to {length}")
    pad = length - n
    return (np.concatenate([x, np.full(pad, x[-1])]), np.concatenate([y, np.zeros(pad)]),
            np.arange(length) < n)


def resolve_setup(spec: PriorSpec, surrogate=None, setup: str | None = None, kind: str | None = None) -> str:
    """The loading protocol, checked for consistency between spec, surrogate, curve kind and argument."""
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
    """The reduced shell of ``spec``: b1 = b2 = a3 = a4 fixed at 0, other ranges unchanged."""
    parameters = {k: v for k, v in spec.parameters.items() if k not in NONLINEAR_PARAMETERS}
    fixed = dict(spec.fixed)
    fixed.update({k: 0.0 for k in NONLINEAR_PARAMETERS})
    return dataclasses.replace(spec, name=f"{spec.name}_reduced" if spec.shell == "full" else spec.name,
                               shell="reduced", parameters=parameters, fixed=fixed)


def shell_params(values: Mapping, spec: PriorSpec):
    """(params[..., 6], d0[...]) from sampled ``values`` and the spec's fixed parameters.

    ``values`` maps free parameter names to arrays of a common batch shape (scalars for one Θ).
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
    """Record ``E_MPa`` (from ka) and ``kappa_kBT`` (from kb) as deterministic sites when present."""
    if "ka" in values:
        numpyro.deterministic("E_MPa" + suffix, values["ka"] * (float(units.ka_to_young(1.0)) * 1e-6))
    if "kb" in values:
        numpyro.deterministic("kappa_kBT" + suffix, values["kb"] * float(units.kb_to_bending_kBT(1.0)))


def nuts_init_values(spec: PriorSpec, n_curves: int | None = None) -> dict:
    """Initial values that keep NUTS off the clamped plateau (see the module docstring).

    d0 near the bottom of its prior for compression (lo + 2% of the width), 0 (clipped into the prior)
    for indentation; with ``n_curves`` the per-bubble arrays of :func:`bubblecal.models.hierarchical_model`
    plus ``m_d0`` and, for the non-centred form, ``d0_u``. Empty if d0 is fixed. Pass to
    ``numpyro.infer.init_to_value(values=...)``; other sites keep NumPyro's default initialisation.
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


def population_factor(values: Mapping, spec: PriorSpec, population, site: str = "population_prior") -> None:
    """Add log mean_s p(θ | ψ_s) − log p0(θ) over the pooled parameters present in ``values`` as a factor.

    ``population`` = (m_samples, tau_samples): dicts name -> (S,) arrays (phase-2 samples of ψ).
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


def _uniform(bounds):
    return dist.Uniform(float(bounds.lo), float(bounds.hi))


def mechanical_model(x, y, surrogate: Callable, spec: PriorSpec, *, setup: str | None = None, obs_name: str = "y",
                     y_scale: float | None = None, sd_floor_rel: float = SD_FLOOR_REL,
                     units: UnitSystem = DEFAULT_UNITS, population=None, mask=None):
    """NumPyro model of one loading curve under uniform priors (module docstring for the equations).

    ``x``, ``y``: the curve in DPD units (``y=None`` samples the observations: prior/posterior
    predictive). ``y_scale`` sets the noise floor s_floor = ``sd_floor_rel`` · y_scale (default max|y|;
    pass it explicitly together with ``y=None`` to reproduce the fit's density). Sites: the free
    shell parameters of ``spec`` by name, the mechanical noise (``spec.mechanical_noise_name``), the
    observed ``obs_name`` and the deterministic ``E_MPa`` / ``kappa_kBT``. ``population``: phase-3
    population prior (module docstring), adds the factor site ``population_prior``. ``mask``: (n,)
    booleans, False on padding points (:func:`pad_curve`), which then add nothing to the likelihood.
    ``x``, ``y`` and ``mask`` may be traced arrays (jit arguments).
    """
    setup = resolve_setup(spec, surrogate, setup)
    x = jnp.asarray(x, dtype=float)
    values = {k: numpyro.sample(k, _uniform(p.prior)) for k, p in spec.parameters.items()}
    noise_name = spec.mechanical_noise_name
    if noise_name not in spec.noise:
        raise ValueError(f"priors {spec.name!r} declare no noise amplitude {noise_name!r}")
    sigma = numpyro.sample(noise_name, _uniform(spec.noise[noise_name].prior))
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
    sd = noise_sd(yhat, sigma, sd_floor_for(y_scale, sd_floor_rel))
    likelihood = dist.Normal(yhat, sd)
    numpyro.sample(obs_name, likelihood if mask is None else likelihood.mask(jnp.asarray(mask, dtype=bool)), obs=y)


def mechanical_prediction(samples: Mapping, surrogate: Callable, spec: PriorSpec, x, *, y_scale: float,
                          setup: str | None = None, sd_floor_rel: float = SD_FLOOR_REL, noise_name: str | None = None):
    """Per-sample predicted curve and noise sd at ``x``: arrays (S, len(x)) each (DPD units of y).

    ``samples`` maps the free parameter names and the noise name to (S,) arrays (posterior draws of
    :func:`mechanical_model`, or one bubble's slice of the hierarchical model). The pair is what
    :mod:`bubblecal.inference.predictive` needs for the Gaussian-mixture predictive.
    """
    setup = resolve_setup(spec, surrogate, setup)
    noise_name = noise_name or spec.mechanical_noise_name
    values = {k: jnp.asarray(samples[k])[:, None] for k in spec.parameters}
    params, d0 = shell_params(values, spec)  # (S, 1, 6), (S, 1)
    yhat = predict_mechanical(surrogate, setup, params, d0, jnp.asarray(np.asarray(x, float))[None, :])
    sigma = jnp.asarray(samples[noise_name])[:, None]
    return yhat, noise_sd(yhat, sigma, sd_floor_for(y_scale, sd_floor_rel))
