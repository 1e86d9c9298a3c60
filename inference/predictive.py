"""Posterior-predictive metrics over arrays: mixture quantiles, bands, coverage, MAP.

The metrics of ``docs/inference.md`` section 7; the CRPS is :mod:`bubblecal.inference.crps`.

Knows no physics: every function takes plain arrays. The pointwise predictive at P points from S
posterior samples is the Gaussian mixture

    p(z_p) = Σ_k w_k N(z_p | μ_kp, s_kp²)          (w_k = 1/S unless weights are given)

with ``means`` μ (S, P) and ``sds`` s (S, P) (for the relative-noise models s = σ^(k) ŷ^(k) with its
floor, see :func:`bubblecal.models.mechanical_prediction`). Quantiles are found by inverting the
mixture CDF in float64 (NumPy/SciPy), vectorised over points and levels: a safeguarded Newton
iteration inside a bisection bracket [min_k Q_k(q), max_k Q_k(q)] (component quantiles), which
provably contains the mixture quantile.

MAP: the posterior sample with the largest (finite) log posterior density.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr, ndtri

__all__ = ["PredictiveBand", "mixture_cdf", "mixture_quantile", "predictive_band", "coverage", "map_index",
           "map_estimate"]


@dataclass(frozen=True)
class PredictiveBand:
    """Pointwise predictive median and central band.

    Parameters
    ----------
    median, lower, upper : numpy.ndarray
        (P,) arrays in the units of y.
    level : float
        Probability mass of the central band.
    """

    median: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    level: float

    def contains(self, y) -> np.ndarray:
        """Boolean mask lower <= y <= upper of observations ``y`` (P,)."""
        y = np.asarray(y, dtype=float)
        return (y >= self.lower) & (y <= self.upper)

    def coverage(self, y) -> float:
        """Fraction of the observations ``y`` (P,) inside the band."""
        return coverage(y, self.lower, self.upper)


def _prepare(means, sds, weights):
    """Validated (S, P) means and sds and normalised (S,) weights."""
    mu, sd = np.broadcast_arrays(np.asarray(means, dtype=float), np.asarray(sds, dtype=float))
    if mu.ndim == 1:  # S samples at a single point
        mu, sd = mu[:, None], sd[:, None]
    if mu.ndim != 2:
        raise ValueError(f"means must have shape (S, P) (samples x points), got {mu.shape}")
    if np.any(~np.isfinite(mu)) or np.any(~np.isfinite(sd)) or np.any(sd < 0):
        raise ValueError("means must be finite and sds finite and >= 0")
    S = mu.shape[0]
    if weights is None:
        w = np.full(S, 1.0 / S)
    else:
        w = np.asarray(weights, dtype=float)
        if w.shape != (S,) or np.any(w < 0) or not np.isfinite(w).all() or w.sum() <= 0:
            raise ValueError(f"weights must be {S} finite non-negative numbers with a positive sum")
        w = w / w.sum()
    return mu, sd, w


def _component_cdf(z, mu, sd):
    """CDF of each Gaussian component (a step where sd = 0)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        c = ndtr((z - mu) / np.where(sd > 0, sd, 1.0))
    return np.where(sd > 0, c, (z >= mu).astype(float))


def mixture_cdf(z, means, sds, weights=None) -> np.ndarray:
    """Mixture CDF F_p(z_p) of the pointwise Gaussian mixture.

    Parameters
    ----------
    z : array_like
        (..., P) evaluation points (units of y).
    means, sds : array_like
        (S, P) component means and standard deviations (units of y).
    weights : array_like or None
        (S,) component weights (default equal).

    Returns
    -------
    numpy.ndarray
        CDF values, shape of ``z``.

    Raises
    ------
    ValueError
        For badly shaped or non-finite inputs or invalid weights.
    """
    mu, sd, w = _prepare(means, sds, weights)
    return _mixture_cdf(np.asarray(z, dtype=float), mu, sd, w)


def _mixture_cdf(z, mu, sd, w):
    """Mixture CDF of validated inputs."""
    return np.einsum("s,...sp->...p", w, _component_cdf(z[..., None, :], mu, sd))


def _mixture_cdf_pdf(z, mu, sd, w):
    """Mixture CDF (the values of :func:`_mixture_cdf`) and density of validated inputs, sharing the
    standardised distances; a component with sd = 0 is a step of zero density."""
    with np.errstate(divide="ignore", invalid="ignore"):
        positive = sd > 0
        degenerate = not positive.all()
        safe = np.where(positive, sd, 1.0) if degenerate else sd
        u = (z[..., None, :] - mu) / safe
        c = ndtr(u)
        dens = np.exp(-0.5 * u * u) / (safe * np.sqrt(2.0 * np.pi))
    if degenerate:
        c = np.where(positive, c, (z[..., None, :] >= mu).astype(float))
        dens = np.where(positive, dens, 0.0)
    return np.einsum("s,...sp->...p", w, c), np.einsum("s,...sp->...p", w, dens)


def mixture_quantile(means, sds, q, weights=None, *, tol: float = 1e-10, max_iter: int = 200) -> np.ndarray:
    """Quantile(s) of the pointwise Gaussian mixture.

    Safeguarded Newton on the mixture CDF inside a bisection bracket: the quantile lies between the
    smallest and the largest component quantile (the mixture CDF is a weighted mean of the component
    CDFs), each step shrinks the bracket, and a Newton step that leaves it is replaced by bisection.
    Stops when the bracket is below ``tol`` times its initial width or |F(z) − q| < 1e-13.

    Parameters
    ----------
    means, sds : array_like
        (S, P) component means and standard deviations (units of y).
    q : float or array_like
        Level(s) in (0, 1).
    weights : array_like or None
        (S,) component weights (default equal).
    tol : float
        Relative bracket width at which to stop.
    max_iter : int
        Iteration cap.

    Returns
    -------
    numpy.ndarray
        (P,) for a scalar ``q``, else (len(q), P), units of y.

    Raises
    ------
    ValueError
        For a level outside (0, 1) or invalid inputs.
    """
    mu, sd, w = _prepare(means, sds, weights)
    qs = np.atleast_1d(np.asarray(q, dtype=float))
    if np.any((qs <= 0) | (qs >= 1)):
        raise ValueError(f"quantile levels must lie in (0, 1), got {qs}")
    comp_q = mu[None, :, :] + sd[None, :, :] * ndtri(qs)[:, None, None]  # (Q, S, P)
    keep = w > 0
    lo = comp_q[:, keep].min(axis=1)
    hi = comp_q[:, keep].max(axis=1)
    scale = np.maximum(hi - lo, np.finfo(float).eps * np.maximum(1.0, np.abs(hi)))
    target = np.broadcast_to(qs[:, None], lo.shape)
    z = 0.5 * (lo + hi)
    for _ in range(max_iter):
        F, f = _mixture_cdf_pdf(z, mu, sd, w)
        below = F < target
        lo = np.where(below, z, lo)
        hi = np.where(below, hi, z)
        done = (hi - lo <= tol * scale) | (np.abs(F - target) < 1e-13)
        if np.all(done):
            break
        with np.errstate(divide="ignore", invalid="ignore"):
            newton = z - (F - target) / f
        ok = np.isfinite(newton) & (newton > lo) & (newton < hi)
        z = np.where(done, z, np.where(ok, newton, 0.5 * (lo + hi)))
    return z[0] if np.ndim(q) == 0 else z


def predictive_band(means, sds, level: float = 0.9, weights=None, **kwargs) -> PredictiveBand:
    """Median and central band of the pointwise mixture.

    Parameters
    ----------
    means, sds : array_like
        (S, P) component means and standard deviations (units of y).
    level : float
        Mass of the central band (default 0.9: the 5% and 95% quantiles).
    weights : array_like or None
        (S,) component weights (default equal).
    **kwargs
        Passed to :func:`mixture_quantile`.

    Returns
    -------
    PredictiveBand

    Raises
    ------
    ValueError
        For a level outside (0, 1) or invalid inputs.
    """
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must lie in (0, 1), got {level}")
    a = 0.5 * (1.0 - level)
    lower, median, upper = mixture_quantile(means, sds, [a, 0.5, 1.0 - a], weights, **kwargs)
    return PredictiveBand(median=median, lower=lower, upper=upper, level=float(level))


def coverage(y, lower, upper) -> float:
    """Fraction of observations inside a pointwise band.

    Parameters
    ----------
    y, lower, upper : array_like
        Observations and band limits, arrays of equal shape (units of y).

    Returns
    -------
    float
    """
    y = np.asarray(y, dtype=float)
    inside = (y >= np.asarray(lower)) & (y <= np.asarray(upper))
    return float(np.mean(inside))


def map_index(log_posterior) -> int:
    """Index of the sample with the largest finite log posterior.

    Parameters
    ----------
    log_posterior : array_like
        (S,) log posterior densities.

    Returns
    -------
    int

    Raises
    ------
    ValueError
        If no value is finite.
    """
    lp = np.asarray(log_posterior, dtype=float).reshape(-1)
    finite = np.isfinite(lp)
    if not finite.any():
        raise ValueError("no sample has a finite log posterior")
    return int(np.argmax(np.where(finite, lp, -np.inf)))


def map_estimate(samples: Mapping[str, Sequence] | np.ndarray, log_posterior):
    """The MAP sample (largest finite log posterior).

    Parameters
    ----------
    samples : mapping of str to array_like or array_like
        Dict of (S, ...) arrays, or an (S, D) array.
    log_posterior : array_like
        (S,) log posterior densities.

    Returns
    -------
    dict or numpy.ndarray
        {name: value} for dict input, else the row of the array.

    Raises
    ------
    ValueError
        If no log posterior is finite.
    """
    i = map_index(log_posterior)
    if isinstance(samples, Mapping):
        return {k: np.asarray(v)[i] for k, v in samples.items()}
    return np.asarray(samples)[i]
