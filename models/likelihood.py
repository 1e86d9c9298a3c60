"""Pure-JAX log densities shared by the NumPyro models, the staged hierarchy and the predictive checks.

Everything here is a plain function of arrays (jit/vmap/grad-ready, no NumPyro effects), so the same
formula serves the NumPyro models in :mod:`bubblecal.models.mechanical`,
:mod:`bubblecal.models.acoustic` and :mod:`bubblecal.models.hierarchical`, the staged phases 2/3 of the
hierarchy (``shared/docs/inference.md`` §4) and hand-written checks.

Noise model and its floor
-------------------------
Observations carry *relative* Gaussian noise, y ~ N(ŷ, (σ ŷ)²) (``inference.md`` §2–3). A prediction
clamped to ŷ = 0 would make the standard deviation vanish, so the standard deviation actually used is

    sd = sqrt((σ ŷ)² + s_floor²),        s_floor = SD_FLOOR_REL · y_scale,

with ``SD_FLOOR_REL = 1e-4`` and ``y_scale`` the largest |y| of the curve (or dataset). The floor is
smooth (NUTS-friendly). Why 1e-4: the smallest retained observation of the shipped curves is ~8% of
its curve's maximum and σ ≥ 0.02 in the shipped priors, so σ ŷ ≥ 1.5e-3 · y_scale at every data point
near a good fit and the floor changes those standard deviations by < 0.3% (< 1e-6 relative where
ŷ is near the curve's maximum); at ŷ = 0 it keeps the density finite (about −(y / s_floor)² / 2, i.e.
≈ −3e5 for a point at 8% of the maximum: decisively rejected, never NaN/inf). A much smaller floor
would be as correct for NUTS but stretches the log-likelihood range of prior draws to ~1e11, which
starves a tempering sampler (TMCMC's first exponent would have to be ~1e-11).

Truncated-normal population prior
---------------------------------
Θ_k | ψ ~ Normal(m_k, τ_k²) truncated to the prior range [lo_k, hi_k] and normalised by the truncation
mass Φ(β) − Φ(α) (α = (lo − m)/τ, β = (hi − m)/τ), computed in log space with the tail-stable
formula (−∞ outside the range). τ is floored at ``TAU_FLOOR_REL · (hi − lo)`` so τ = 0 (a hyperprior
lower bound of 0) never produces NaN.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence

import jax
import jax.numpy as jnp
from jax.scipy.special import log_ndtr, logsumexp, ndtr, ndtri

__all__ = [
    "SD_FLOOR_REL",
    "TAU_FLOOR_REL",
    "sd_floor_for",
    "noise_sd",
    "normal_logpdf",
    "relative_normal_loglik",
    "predict_mechanical",
    "log_truncation_mass",
    "log_truncnorm",
    "truncnorm_icdf",
    "population_log_prob",
    "population_predictive_log_density",
    "staged_log_likelihood",
    "importance_log_weights",
    "importance_ess",
    "sample_population_predictive",
]

#: Floor of the noise standard deviation, relative to the data scale (largest |y| of a curve).
SD_FLOOR_REL = 1e-4
#: Floor of the population spread τ, relative to the width of the prior range.
TAU_FLOOR_REL = 1e-12
_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


# ----------------------------------------------------------------------------------------------
# Relative Gaussian noise
# ----------------------------------------------------------------------------------------------
def sd_floor_for(y_scale, rel: float = SD_FLOOR_REL):
    """The standard-deviation floor s_floor = rel · y_scale (units of y); y_scale = max |y| of the data."""
    return rel * jnp.abs(jnp.asarray(y_scale))


@jax.jit
def noise_sd(yhat, sigma, sd_floor):
    """Standard deviation of the relative noise model, sqrt((σ ŷ)² + s_floor²) (units of ŷ)."""
    yhat = jnp.asarray(yhat)
    return jnp.sqrt(jnp.square(sigma * yhat) + jnp.square(sd_floor))


@jax.jit
def normal_logpdf(y, mean, sd):
    """Elementwise log N(y | mean, sd²)."""
    z = (y - mean) / sd
    return -0.5 * jnp.square(z) - jnp.log(sd) - _LOG_SQRT_2PI


def relative_normal_loglik(y, yhat, sigma, sd_floor):
    """Σ_j log N(y_j | ŷ_j, (σ ŷ_j)² + s_floor²): the log likelihood of a curve or acoustic dataset."""
    return jnp.sum(normal_logpdf(jnp.asarray(y), yhat, noise_sd(yhat, sigma, sd_floor)))


# ----------------------------------------------------------------------------------------------
# Mechanical prediction
# ----------------------------------------------------------------------------------------------
def predict_mechanical(surrogate: Callable, setup: str, params, d0, x):
    """Predicted curve ŷ at the loading coordinates ``x`` (DPD units; ``inference.md`` §2).

    ``params`` (..., 6) in :data:`SHELL_PARAMETERS` order and ``d0`` (...) broadcast against ``x``
    following the surrogate's convention (leading shape of ``params`` broadcasts with ``x``).

    - compression (x = displacement, y = force): x̃ = max(0, x − d0), ŷ = max(0, S(Θ; x̃));
    - indentation (x = force, y = displacement): ŷ = max(0, S(Θ; x) + d0).
    """
    x = jnp.asarray(x)
    d0 = jnp.asarray(d0)
    if setup == "compression":
        x_shift = jnp.maximum(x - d0, 0.0)
        return jnp.maximum(surrogate(params, x_shift), 0.0)
    if setup == "indentation":
        return jnp.maximum(surrogate(params, x) + d0, 0.0)
    raise ValueError(f"setup must be 'compression' or 'indentation', got {setup!r}")


# ----------------------------------------------------------------------------------------------
# Truncated normal
# ----------------------------------------------------------------------------------------------
def _log1mexp(a):
    """log(1 − exp(a)) for a ≤ 0, accurate everywhere (Mächler 2012)."""
    a = jnp.minimum(a, 0.0)
    return jnp.where(a > -math.log(2.0), jnp.log(-jnp.expm1(a)), jnp.log1p(-jnp.exp(a)))


def _standardise(m, tau, lo, hi):
    tau = jnp.maximum(tau, TAU_FLOOR_REL * (hi - lo))
    return tau, (lo - m) / tau, (hi - m) / tau


@jax.jit
def log_truncation_mass(m, tau, lo, hi):
    """log(Φ(β) − Φ(α)), α = (lo − m)/τ, β = (hi − m)/τ: stable in either tail (elementwise)."""
    _, alpha, beta = _standardise(m, tau, lo, hi)
    flip = alpha >= 0.0  # both limits in the upper tail: use Φ(−α) − Φ(−β)
    a = jnp.where(flip, -beta, alpha)
    b = jnp.where(flip, -alpha, beta)
    log_b = log_ndtr(b)
    return log_b + _log1mexp(log_ndtr(a) - log_b)


@jax.jit
def log_truncnorm(theta, m, tau, lo, hi):
    """Elementwise log density of Normal(m, τ²) truncated to [lo, hi] at ``theta`` (−∞ outside).

    All arguments broadcast; vectorised over samples and over ψ = (m, τ).
    """
    theta = jnp.asarray(theta)
    tau_f, _, _ = _standardise(m, tau, lo, hi)
    z = (theta - m) / tau_f
    logp = -0.5 * jnp.square(z) - _LOG_SQRT_2PI - jnp.log(tau_f) - log_truncation_mass(m, tau, lo, hi)
    inside = (theta >= lo) & (theta <= hi)
    return jnp.where(inside, logp, -jnp.inf)


@jax.jit
def truncnorm_icdf(u, m, tau, lo, hi):
    """Quantile function of Normal(m, τ²) truncated to [lo, hi] at u ∈ [0, 1] (for non-centred sampling).

    Uses the lower-tail form when α < 0 and the mirrored upper-tail form when α ≥ 0, and clips to
    [lo, hi] against round-off.
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
    """log p(θ | ψ) = Σ_k log TruncNormal(θ_k | m_k, τ_k², [lo_k, hi_k]) over the pooled ``names``.

    ``theta``, ``m``, ``tau`` map parameter names to arrays that broadcast against each other, e.g.
    θ_k (N,) and m_k, τ_k (P, 1) give (P, N). ``names`` defaults to the keys of ``m`` present in
    ``theta`` (a dataset that never sampled a pooled parameter, such as an acoustic dataset that has
    only k_a, simply does not contribute the others).
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
    """log mean_s p(θ | ψ_s) over S hyperparameter samples (phase 3's prior; population predictive).

    θ_k of shape (...) and ψ samples m_k, τ_k of shape (S,) give a result of shape (...).
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


def _uniform_log_p0(theta_k, lo, hi):
    inside = (theta_k >= lo) & (theta_k <= hi)
    return jnp.where(inside, -math.log(hi - lo), -jnp.inf)


def importance_log_weights(m: Mapping[str, jax.Array], tau: Mapping[str, jax.Array],
                           samples: Mapping[str, jax.Array], bounds: Mapping[str, tuple[float, float]],
                           log_p0=None, names: Sequence[str] | None = None):
    """log w_k = log p(θ^k | ψ) − log p0(θ^k) for one dataset's phase-1 samples.

    ``samples`` maps names to (N,) arrays; ``m``/``tau`` map names to arrays of batch shape B (scalars
    for one ψ) giving B + (N,). ``log_p0`` (N,) is the phase-1 prior log density *of the pooled
    components*; by default the uniform prior on ``bounds`` (the non-pooled components of θ — noise,
    free unpooled parameters — cancel between p(θ | ψ) p0(rest) and p0(θ)).
    """
    names = [k for k in m if k in samples] if names is None else list(names)
    if not names:
        raise ValueError("importance_log_weights: the dataset has none of the pooled parameters")
    lp = 0.0
    lp0 = 0.0
    for k in names:
        lo, hi = bounds[k]
        mk = jnp.asarray(m[k])
        tk = jnp.asarray(tau[k])
        th = jnp.asarray(samples[k])
        lp = lp + log_truncnorm(th, mk[..., None], tk[..., None], lo, hi)
        lp0 = lp0 + _uniform_log_p0(th, lo, hi)
    if log_p0 is not None:
        lp0 = jnp.asarray(log_p0)
    return lp - lp0


def staged_log_likelihood(m: Mapping[str, jax.Array], tau: Mapping[str, jax.Array],
                          datasets: Sequence[Mapping[str, jax.Array]], bounds: Mapping[str, tuple[float, float]],
                          log_p0: Sequence[jax.Array | None] | None = None):
    """Phase-2 log L(ψ) = Σ_i [logsumexp_k (log p(θ_i^k | ψ) − log p0(θ_i^k)) − log N_i].

    ``datasets[i]`` maps parameter names to the (N_i,) phase-1 posterior samples of dataset i;
    ``m``/``tau`` map the pooled names to arrays of batch shape B (scalars for one ψ); returns shape B.
    ``log_p0[i]`` overrides the uniform phase-1 prior of dataset i (see :func:`importance_log_weights`).
    """
    total = 0.0
    for i, samples in enumerate(datasets):
        lw = importance_log_weights(m, tau, samples, bounds, None if log_p0 is None else log_p0[i])
        total = total + logsumexp(lw, axis=-1) - math.log(lw.shape[-1])
    return total


def importance_ess(log_weights, axis: int = -1):
    """Importance-sampling effective sample size (Σ w)² / Σ w² from log weights (0 if all w = 0)."""
    lw = jnp.asarray(log_weights)
    a = logsumexp(lw, axis=axis)
    b = logsumexp(2.0 * lw, axis=axis)
    ess = jnp.exp(2.0 * a - b)
    return jnp.where(jnp.isfinite(ess), ess, 0.0)


def sample_population_predictive(rng_key, m_samples: Mapping[str, jax.Array], tau_samples: Mapping[str, jax.Array],
                                 bounds: Mapping[str, tuple[float, float]], num: int):
    """Draw ``num`` new-bubble parameter sets θ_new ~ mean_s p(θ | ψ_s) (population predictive).

    Picks ψ_s uniformly among the S hyperparameter samples (the same s for every parameter of one draw),
    then each θ_k by the truncated-normal inverse CDF. Returns {name: (num,) array}.
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
