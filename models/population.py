"""Pure-JAX population densities: the truncated-normal population prior and the population predictive.

Plain functions of arrays (jit/vmap/grad-ready, no NumPyro effects) used by the hierarchical model
(through :class:`~bubblecal.models.distributions.TruncatedNormalPopulation`), phase 3 of the staged
hierarchy (``docs/inference.md`` section 4; phase 2's sums are :mod:`bubblecal.models.importance`) and the
population-predictive checks.

Truncated-normal population prior
---------------------------------
Θ_k | ψ ~ Normal(m_k, τ_k²) truncated to the prior range [lo_k, hi_k] and normalised by the truncation
mass Φ(β) − Φ(α) (α = (lo − m)/τ, β = (hi − m)/τ), computed in log space with the tail-stable
formula (−∞ outside the range). τ is floored at ``TAU_FLOOR_REL · (hi − lo)`` so τ = 0 (a hyperprior
lower bound of 0) never produces NaN.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import jax
import jax.numpy as jnp
from jax.scipy.special import log_ndtr, logsumexp, ndtr, ndtri

__all__ = [
    "TAU_FLOOR_REL",
    "log_truncation_mass",
    "log_truncnorm",
    "truncnorm_icdf",
    "population_log_prob",
    "population_predictive_log_density",
    "sample_population_predictive",
]

#: Floor of the population spread τ, relative to the width of the prior range.
TAU_FLOOR_REL = 1e-12
_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


# ----------------------------------------------------------------------------------------------
# Truncated normal
# ----------------------------------------------------------------------------------------------
def _log1mexp(a):
    """log(1 − exp(a)) for a ≤ 0, accurate everywhere (Mächler 2012)."""
    a = jnp.minimum(a, 0.0)
    return jnp.where(a > -math.log(2.0), jnp.log(-jnp.expm1(a)), jnp.log1p(-jnp.exp(a)))


def _standardise(m, tau, lo, hi):
    """(τ floored, α, β) of a truncated normal."""
    tau = jnp.maximum(tau, TAU_FLOOR_REL * (hi - lo))
    return tau, (lo - m) / tau, (hi - m) / tau


@jax.jit
def log_truncation_mass(m, tau, lo, hi):
    """Log truncation mass log(Φ(β) − Φ(α)), α = (lo − m)/τ, β = (hi − m)/τ, stable in either tail.

    Parameters
    ----------
    m, tau : array_like
        Mean and spread of the normal (units of the parameter); τ is floored (module docstring).
    lo, hi : array_like
        Truncation range (units of the parameter).

    Returns
    -------
    Array
        Elementwise log mass, broadcast shape.
    """
    _, alpha, beta = _standardise(m, tau, lo, hi)
    flip = alpha >= 0.0  # both limits in the upper tail: use Φ(−α) − Φ(−β)
    a = jnp.where(flip, -beta, alpha)
    b = jnp.where(flip, -alpha, beta)
    log_b = log_ndtr(b)
    return log_b + _log1mexp(log_ndtr(a) - log_b)


@jax.jit
def log_truncnorm(theta, m, tau, lo, hi):
    """Elementwise log density of Normal(m, τ²) truncated to [lo, hi].

    Parameters
    ----------
    theta : array_like
        Values (units of the parameter).
    m, tau : array_like
        Population mean and spread ψ = (m, τ) (units of the parameter).
    lo, hi : array_like
        Prior range of the parameter.

    Returns
    -------
    Array
        Log density, −∞ outside [lo, hi]; all arguments broadcast (vectorised over samples and over ψ).
    """
    theta = jnp.asarray(theta)
    tau_f, _, _ = _standardise(m, tau, lo, hi)
    z = (theta - m) / tau_f
    logp = -0.5 * jnp.square(z) - _LOG_SQRT_2PI - jnp.log(tau_f) - log_truncation_mass(m, tau, lo, hi)
    inside = (theta >= lo) & (theta <= hi)
    return jnp.where(inside, logp, -jnp.inf)


@jax.jit
def truncnorm_icdf(u, m, tau, lo, hi):
    """Quantile function of Normal(m, τ²) truncated to [lo, hi] (the non-centred parameterisation).

    Uses the lower-tail form when α < 0 and the mirrored upper-tail form when α ≥ 0, and clips to
    [lo, hi] against round-off.

    Parameters
    ----------
    u : array_like
        Probabilities in [0, 1].
    m, tau : array_like
        Population mean and spread (units of the parameter).
    lo, hi : array_like
        Prior range of the parameter.

    Returns
    -------
    Array
        Quantiles in [lo, hi], broadcast shape.
    """
    tau_f, alpha, beta = _standardise(m, tau, lo, hi)
    flip = alpha >= 0.0
    a = jnp.where(flip, -beta, alpha)
    b = jnp.where(flip, -alpha, beta)
    pa, pb = ndtr(a), ndtr(b)
    # direct: Φ⁻¹(Φ(α) + u (Φ(β) − Φ(α)));  mirrored: −Φ⁻¹(Φ(−α) − u (Φ(−α) − Φ(−β)))
    p = jnp.where(flip, pb - u * (pb - pa), pa + u * (pb - pa))
    z = ndtri(jnp.clip(p, jnp.finfo(jnp.result_type(p)).tiny, 1.0))
    z = jnp.where(flip, -z, z)
    return jnp.clip(m + tau_f * z, lo, hi)


# ----------------------------------------------------------------------------------------------
# Population prior over named parameters (staged hierarchy, phases 2 and 3)
# ----------------------------------------------------------------------------------------------
def population_log_prob(theta: Mapping[str, jax.Array], m: Mapping[str, jax.Array], tau: Mapping[str, jax.Array],
                        bounds: Mapping[str, tuple[float, float]], names: Sequence[str] | None = None):
    """Population log density log p(θ | ψ) = Σ_k log TruncNormal(θ_k | m_k, τ_k², [lo_k, hi_k]).

    Parameters
    ----------
    theta, m, tau : mapping of str to array_like
        Parameter name -> values, population means, population spreads (DPD units); arrays broadcast
        against each other, e.g. θ_k (N,) and m_k, τ_k (P, 1) give (P, N).
    bounds : mapping of str to (float, float)
        Prior range of each pooled parameter.
    names : sequence of str or None
        Pooled parameters to sum over; default the keys of ``m`` present in ``theta`` (a dataset that
        never sampled a pooled parameter, such as an acoustic dataset with only k_a, does not
        contribute the others).

    Returns
    -------
    Array
        The log density, broadcast shape.

    Raises
    ------
    ValueError
        If no pooled parameter is common to ``theta`` and ψ.
    """
    names = [k for k in m if k in theta] if names is None else list(names)
    if not names:
        raise ValueError("population_log_prob: no pooled parameter in common between theta and psi")
    total = 0.0
    for k in names:
        lo, hi = bounds[k]
        total = total + log_truncnorm(theta[k], m[k], tau[k], lo, hi)
    return total


def population_predictive_log_density(theta: Mapping[str, jax.Array], m_samples: Mapping[str, jax.Array],
                                      tau_samples: Mapping[str, jax.Array],
                                      bounds: Mapping[str, tuple[float, float]], names: Sequence[str] | None = None):
    """Population-predictive log density log mean_s p(θ | ψ_s) over S hyperparameter samples.

    Phase 3's prior of the staged hierarchy, and the density of a new bubble's parameters.

    Parameters
    ----------
    theta : mapping of str to array_like
        Parameter name -> values θ_k of shape (...) (DPD units).
    m_samples, tau_samples : mapping of str to array_like
        Parameter name -> (S,) draws of the population mean and spread.
    bounds : mapping of str to (float, float)
        Prior range of each pooled parameter.
    names : sequence of str or None
        Pooled parameters; default the keys of ``m_samples`` present in ``theta``.

    Returns
    -------
    Array
        Shape (...) of θ.

    Raises
    ------
    ValueError
        If no pooled parameter is common to ``theta`` and the samples.
    """
    names = [k for k in m_samples if k in theta] if names is None else list(names)
    lp = 0.0
    for k in names:
        th = jnp.asarray(theta[k])
        shape = (-1,) + (1,) * th.ndim
        mk = jnp.asarray(m_samples[k]).reshape(shape)
        tk = jnp.asarray(tau_samples[k]).reshape(shape)
        lo, hi = bounds[k]
        lp = lp + log_truncnorm(th, mk, tk, lo, hi)  # (S, ...)
    if not names:
        raise ValueError("population_predictive_log_density: no pooled parameter in common")
    return logsumexp(lp, axis=0) - math.log(lp.shape[0])


def sample_population_predictive(rng_key, m_samples: Mapping[str, jax.Array], tau_samples: Mapping[str, jax.Array],
                                 bounds: Mapping[str, tuple[float, float]], num: int):
    """Draw new-bubble parameter sets θ_new ~ mean_s p(θ | ψ_s) (population predictive).

    Picks ψ_s uniformly among the S hyperparameter samples (the same s for every parameter of one draw),
    then each θ_k by the truncated-normal inverse CDF.

    Parameters
    ----------
    rng_key : jax.Array
        PRNG key.
    m_samples, tau_samples : mapping of str to array_like
        Parameter name -> (S,) draws of the population mean and spread (DPD units).
    bounds : mapping of str to (float, float)
        Prior range of each parameter.
    num : int
        Number of draws.

    Returns
    -------
    dict
        Parameter name -> (num,) array.
    """
    names = list(m_samples)
    S = jnp.asarray(m_samples[names[0]]).shape[0]
    key_s, key_u = jax.random.split(rng_key)
    idx = jax.random.randint(key_s, (num,), 0, S)
    u = jax.random.uniform(key_u, (num, len(names)))
    out = {}
    for j, k in enumerate(names):
        lo, hi = bounds[k]
        out[k] = truncnorm_icdf(u[:, j], jnp.asarray(m_samples[k])[idx], jnp.asarray(tau_samples[k])[idx], lo, hi)
    return out
