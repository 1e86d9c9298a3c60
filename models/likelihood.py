"""Pure-JAX observation model: the mechanical prediction and the relative-noise log density with its floor.

Everything here is a plain function of arrays (jit/vmap/grad-ready, no NumPyro effects), so the same
formula serves the NumPyro models (:mod:`bubblecal.models.mechanical`, :mod:`bubblecal.models.acoustic`,
:mod:`bubblecal.models.hierarchical`, through :mod:`bubblecal.models.distributions`), the predictive
checks and hand-written checks. The population side (truncated normal, staged-hierarchy sums) is
:mod:`bubblecal.models.population`.

Noise model and its floor
-------------------------
Observations carry *relative* Gaussian noise, y ~ N(ŷ, (σ ŷ)²) (``docs/inference.md`` sections 2-3).
A prediction clamped to ŷ = 0 would make the standard deviation vanish, so the standard deviation
actually used is

    sd = sqrt((σ ŷ)² + s_floor²),        s_floor = SD_FLOOR_REL · y_scale,

with ``SD_FLOOR_REL = 1e-4`` and ``y_scale`` the largest |y| of the curve (or dataset). The floor is
smooth (NUTS-friendly); near a good fit it changes the standard deviations of the shipped curves by
well under a percent, and at ŷ = 0 it keeps the density finite (about −(y / s_floor)² / 2: decisively
rejected, never NaN/inf). The choice of the value is a decision note (``docs/decisions.md``).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import jax
import jax.numpy as jnp

__all__ = ["SD_FLOOR_REL", "sd_floor_for", "noise_sd", "normal_logpdf", "relative_normal_loglik", "predict_mechanical"]

#: Floor of the noise standard deviation, relative to the data scale (largest |y| of a curve).
SD_FLOOR_REL = 1e-4
_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


# ----------------------------------------------------------------------------------------------
# Relative Gaussian noise
# ----------------------------------------------------------------------------------------------
def sd_floor_for(y_scale, rel: float = SD_FLOOR_REL):
    """The standard-deviation floor s_floor = rel · |y_scale|.

    Parameters
    ----------
    y_scale : array_like
        Data scale, the largest |y| of the curve or dataset (units of y: DPD force or length, MHz).
    rel : float
        Relative floor (default :data:`SD_FLOOR_REL`).

    Returns
    -------
    Array
        s_floor, in the units of y.
    """
    return rel * jnp.abs(jnp.asarray(y_scale))


@jax.jit
def noise_sd(yhat, sigma, sd_floor):
    """Standard deviation of the relative noise model, sqrt((σ ŷ)² + s_floor²).

    Parameters
    ----------
    yhat : array_like
        Predictions ŷ (units of the data).
    sigma : array_like
        Relative noise amplitude σ [-].
    sd_floor : array_like
        Floor s_floor (units of ŷ, :func:`sd_floor_for`).

    Returns
    -------
    Array
        The standard deviation, units of ŷ, broadcast shape.
    """
    yhat = jnp.asarray(yhat)
    return jnp.sqrt(jnp.square(sigma * yhat) + jnp.square(sd_floor))


@jax.jit
def normal_logpdf(y, mean, sd):
    """Elementwise log N(y | mean, sd²) (y, mean and sd in one unit; broadcast)."""
    z = (y - mean) / sd
    return -0.5 * jnp.square(z) - jnp.log(sd) - _LOG_SQRT_2PI


def relative_normal_loglik(y, yhat, sigma, sd_floor):
    """Log likelihood of a curve or acoustic dataset under relative noise: Σ_j log N(y_j | ŷ_j, sd_j²).

    Parameters
    ----------
    y : array_like
        Observations (units of the data).
    yhat : array_like
        Predictions ŷ, same shape.
    sigma : array_like
        Relative noise amplitude σ [-].
    sd_floor : array_like
        Floor s_floor (units of y); sd_j = :func:`noise_sd` (ŷ_j, σ, s_floor).

    Returns
    -------
    Array
        Scalar log likelihood.
    """
    return jnp.sum(normal_logpdf(jnp.asarray(y), yhat, noise_sd(yhat, sigma, sd_floor)))


# ----------------------------------------------------------------------------------------------
# Mechanical prediction
# ----------------------------------------------------------------------------------------------
def predict_mechanical(surrogate: Callable, setup: str, params, d0, x):
    """Predicted curve ŷ at the loading coordinates ``x`` (``docs/inference.md`` section 2).

    - compression (x = displacement, y = force): x̃ = max(0, x − d0), ŷ = max(0, S(Θ; x̃));
    - indentation (x = force, y = displacement): ŷ = max(0, S(Θ; x) + d0).

    Parameters
    ----------
    surrogate : callable
        ``(params[..., 6], x[...]) -> y[...]`` in DPD units.
    setup : {'compression', 'indentation'}
        Loading protocol.
    params : array_like
        (..., 6) shell parameters in :data:`~bubblecal.data.names.SHELL_PARAMETERS` order (DPD units);
        the leading shape broadcasts with ``x`` following the surrogate's convention.
    d0 : array_like
        (...) contact / indentation offset [DPD length].
    x : array_like
        Loading coordinates: displacement [DPD length] (compression) or force [DPD force] (indentation).

    Returns
    -------
    Array
        ŷ: force [DPD force] (compression) or indentation depth [DPD length] (indentation), >= 0.

    Raises
    ------
    ValueError
        For an unknown ``setup``.
    """
    x = jnp.asarray(x)
    d0 = jnp.asarray(d0)
    if setup == "compression":
        x_shift = jnp.maximum(x - d0, 0.0)
        return jnp.maximum(surrogate(params, x_shift), 0.0)
    if setup == "indentation":
        return jnp.maximum(surrogate(params, x) + d0, 0.0)
    raise ValueError(f"setup must be 'compression' or 'indentation', got {setup!r}")
