"""Tempering arithmetic of a TMCMC stage: next exponent, incremental weights, resampling, covariance.

Pure, jittable functions of the particle arrays (``docs/inference.md`` section 5, steps 1-4). A
particle whose log likelihood is not finite gets weight exactly 0, so it never makes log Z NaN.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
from jax import lax

Array = jax.Array

_BISECTION_ITERS = 60

__all__ = [
    "tempered",
    "weights_cov",
    "solve_delta",
    "normalised_log_weights",
    "resample",
    "weighted_moments",
    "safe_cholesky",
]


def tempered(log_prior: Array, log_likelihood: Array, beta: Array) -> Array:
    """Tempered log target log p(x) + β log L(x).

    Parameters
    ----------
    log_prior, log_likelihood : Array
        Log prior and log likelihood of the particles, same shape.
    beta : Array
        Tempering exponent in [0, 1].

    Returns
    -------
    Array
        log prior + β log L, −∞ wherever either term is not finite (so such proposals are rejected).
    """
    ok = jnp.isfinite(log_prior) & jnp.isfinite(log_likelihood)
    return jnp.where(ok, log_prior + beta * jnp.where(ok, log_likelihood, 0.0), -jnp.inf)


def weights_cov(delta: Array, log_likelihood: Array) -> Array:
    """Coefficient of variation of the incremental weights w_i = exp(Δ·L_i).

    Parameters
    ----------
    delta : Array
        Exponent increment Δ (scalar).
    log_likelihood : Array
        (N,) log likelihoods; particles with a non-finite value are left out.

    Returns
    -------
    Array
        Standard deviation (ddof 1) over mean of the weights of the finite particles.
    """
    finite = jnp.isfinite(log_likelihood)
    n = jnp.maximum(finite.sum(), 2)
    ll = jnp.where(finite, log_likelihood, 0.0)
    llmax = jnp.max(jnp.where(finite, log_likelihood, -jnp.inf))
    w = jnp.where(finite, jnp.exp(delta * (ll - llmax)), 0.0)
    mean = w.sum() / n
    var = jnp.where(finite, (w - mean) ** 2, 0.0).sum() / (n - 1)
    return jnp.sqrt(var) / mean


def solve_delta(log_likelihood: Array, beta: Array, target_cov: float) -> tuple[Array, Array]:
    """Exponent increment Δ in [0, 1 − β] whose weights reach the target CoV (bracketed bisection).

    CoV grows monotonically with Δ, so if the full step 1 − β stays under the target it is taken.
    The bisection runs in log Δ over [1e-30·(1 − β), 1 − β] so tiny increments keep relative precision.

    Parameters
    ----------
    log_likelihood : Array
        (N,) log likelihoods of the current particles.
    beta : Array
        Current exponent.
    target_cov : float
        Target coefficient of variation c* of the incremental weights.

    Returns
    -------
    delta : Array
        The increment (never above the target: the bracket's lower end is kept).
    cov : Array
        The CoV achieved with it.
    """
    dmax = 1.0 - beta

    def body(_, bounds):
        lo, hi = bounds
        mid = 0.5 * (lo + hi)
        too_big = weights_cov(jnp.exp(mid), log_likelihood) > target_cov
        return jnp.where(too_big, lo, mid), jnp.where(too_big, mid, hi)

    # lo stays on the side CoV ≤ target, so Δ never overshoots the target
    log_dmax = jnp.log(dmax)
    lo, _ = lax.fori_loop(0, _BISECTION_ITERS, body, (log_dmax - 69.0, log_dmax))  # 69 ≈ log 1e30
    delta = jnp.where(weights_cov(dmax, log_likelihood) <= target_cov, dmax, jnp.exp(lo))
    return delta, weights_cov(delta, log_likelihood)


def normalised_log_weights(delta: Array, log_likelihood: Array) -> tuple[Array, Array]:
    """Normalised log weights of a stage and its log evidence increment.

    Parameters
    ----------
    delta : Array
        Exponent increment Δ.
    log_likelihood : Array
        (N,) log likelihoods; a non-finite value gets weight exactly 0.

    Returns
    -------
    log_weights : Array
        (N,) log ŵ_i, normalised (logsumexp = 0).
    log_z_increment : Array
        logsumexp(Δ L) − log N.
    """
    n = log_likelihood.shape[0]
    logw = jnp.where(jnp.isfinite(log_likelihood), delta * log_likelihood, -jnp.inf)
    lse = jax.scipy.special.logsumexp(logw)
    return logw - lse, lse - math.log(n)


def resample(rng_key: Array, log_weights: Array, method: str) -> Array:
    """Draw N particle indices from normalised weights.

    Parameters
    ----------
    rng_key : Array
        JAX PRNG key.
    log_weights : Array
        (N,) normalised log weights.
    method : {'multinomial', 'systematic'}
        Multinomial (Korali) or systematic resampling.

    Returns
    -------
    Array
        (N,) int indices; a zero-weight particle is never selected.

    Raises
    ------
    ValueError
        For an unknown ``method`` (the front end validates it first).
    """
    n = log_weights.shape[0]
    w = jnp.exp(log_weights)
    cdf = jnp.cumsum(w)
    cdf = cdf / cdf[-1]
    if method == "multinomial":
        u = jax.random.uniform(rng_key, (n,), dtype=cdf.dtype)
    elif method == "systematic":
        u = (jax.random.uniform(rng_key, (), dtype=cdf.dtype) + jnp.arange(n, dtype=cdf.dtype)) / n
    else:  # pragma: no cover - validated by the front end
        raise ValueError(f"unknown resampling method {method!r}")
    idx = jnp.searchsorted(cdf, u, side="right")
    # never select a zero-weight particle because of round-off at the top of the cdf
    return jnp.minimum(idx, n - 1)


def weighted_moments(position: Array, log_weights: Array) -> tuple[Array, Array]:
    """Weighted mean and covariance of the particles (Korali's, no ddof correction).

    Parameters
    ----------
    position : Array
        (N, d) particles.
    log_weights : Array
        (N,) normalised log weights.

    Returns
    -------
    mean : Array
        (d,) Σ_i ŵ_i x_i.
    cov : Array
        (d, d) Σ_i ŵ_i (x_i − μ)(x_i − μ)ᵀ, symmetrised.
    """
    w = jnp.exp(log_weights)
    mean = w @ position
    centred = position - mean
    cov = (centred * w[:, None]).T @ centred
    return mean, 0.5 * (cov + cov.T)


def safe_cholesky(cov: Array) -> Array:
    """Cholesky factor of a covariance with a relative jitter, or of its diagonal if that fails.

    Parameters
    ----------
    cov : Array
        (d, d) covariance.

    Returns
    -------
    Array
        (d, d) lower-triangular factor.
    """
    d = cov.shape[0]
    diag = jnp.clip(jnp.diag(cov), 1e-30)
    eps = 1e-10 if cov.dtype == jnp.float64 else 1e-6
    chol = jnp.linalg.cholesky(cov + eps * jnp.diag(diag) + 1e-30 * jnp.eye(d, dtype=cov.dtype))
    return jnp.where(jnp.all(jnp.isfinite(chol)), chol, jnp.diag(jnp.sqrt(diag)))
