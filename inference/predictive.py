"""Posterior-predictive metrics over arrays: mixture bands, coverage, CRPS, MAP (``inference.md`` §7).

Knows no physics: every function takes plain arrays. The pointwise predictive at P points from S
posterior samples is the Gaussian mixture

    p(z_p) = Σ_k w_k N(z_p | μ_kp, s_kp²)          (w_k = 1/S unless weights are given)

with ``means`` μ (S, P) and ``sds`` s (S, P) (for the relative-noise models s = σ^(k) ŷ^(k) with its
floor, see :func:`bubblecal.models.mechanical_prediction`). Quantiles are found by inverting the
mixture CDF in float64 (NumPy/SciPy), vectorised over points and levels: a safeguarded Newton
iteration inside a bisection bracket [min_k Q_k(q), max_k Q_k(q)] (component quantiles), which
provably contains the mixture quantile.

CRPS estimator
--------------
For each replicate r, one draw z_kp ~ N(μ_kp, s_kp²) per posterior sample k and point p forms an
ensemble of M = S members per point, and the CRPS of the observation y_p is estimated by the
ensemble ("energy", NRG) form

    CRPS_p = (1/M) Σ_k |z_kp − y_p| − 1/(2 M²) Σ_k Σ_l |z_kp − z_lp|,

the exact CRPS of the ensemble's empirical CDF (the estimator of ``properscoring.crps_ensemble``);
``fair=True`` uses 1/(2 M (M − 1)) instead, an unbiased estimator of the mixture's CRPS (the two differ
by O(spread / M)). The score is averaged over the points, then over ``replicates`` (default 5)
independent draws; the spread over replicates is reported as its Monte-Carlo error. Units: those of y.

MAP: the posterior sample with the largest (finite) log posterior density.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr, ndtri

__all__ = [
    "PredictiveBand",
    "CRPSResult",
    "mixture_cdf",
    "mixture_quantile",
    "predictive_band",
    "coverage",
    "gaussian_crps",
    "crps_ensemble",
    "predictive_crps",
    "map_index",
    "map_estimate",
]


@dataclass(frozen=True)
class PredictiveBand:
    """Pointwise predictive median and central band (arrays of shape (P,), units of y)."""

    median: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    level: float

    def contains(self, y) -> np.ndarray:
        """Boolean mask: lower <= y <= upper."""
        y = np.asarray(y, dtype=float)
        return (y >= self.lower) & (y <= self.upper)

    def coverage(self, y) -> float:
        """Fraction of the observations inside the band."""
        return coverage(y, self.lower, self.upper)


@dataclass(frozen=True)
class CRPSResult:
    """CRPS averaged over points and replicates (``mean``), per replicate, per point, and its MC error."""

    mean: float
    replicates: np.ndarray
    per_point: np.ndarray
    fair: bool

    @property
    def mc_error(self) -> float:
        """Standard error of ``mean`` over the replicates (0 for a single replicate)."""
        r = self.replicates
        return float(np.std(r, ddof=1) / np.sqrt(r.size)) if r.size > 1 else 0.0


def _prepare(means, sds, weights):
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
    with np.errstate(divide="ignore", invalid="ignore"):
        c = ndtr((z - mu) / np.where(sd > 0, sd, 1.0))
    return np.where(sd > 0, c, (z >= mu).astype(float))


def mixture_cdf(z, means, sds, weights=None) -> np.ndarray:
    """Mixture CDF F_p(z_p) at ``z`` (..., P) for means/sds (S, P): shape of ``z``."""
    mu, sd, w = _prepare(means, sds, weights)
    return _mixture_cdf(np.asarray(z, dtype=float), mu, sd, w)


def _mixture_cdf(z, mu, sd, w):
    return np.einsum("s,...sp->...p", w, _component_cdf(z[..., None, :], mu, sd))


def _mixture_pdf(z, mu, sd, w):
    with np.errstate(divide="ignore", invalid="ignore"):
        safe = np.where(sd > 0, sd, 1.0)
        u = (z[..., None, :] - mu) / safe
        dens = np.where(sd > 0, np.exp(-0.5 * u * u) / (safe * np.sqrt(2.0 * np.pi)), 0.0)
    return np.einsum("s,...sp->...p", w, dens)


def mixture_quantile(means, sds, q, weights=None, *, tol: float = 1e-10, max_iter: int = 200) -> np.ndarray:
    """Quantile(s) ``q`` of the pointwise Gaussian mixture: shape (P,) for scalar q, else (len(q), P).

    Safeguarded Newton on the mixture CDF inside a bisection bracket: the quantile lies between the
    smallest and the largest component quantile (the mixture CDF is a weighted mean of the component
    CDFs), each step shrinks the bracket, and a Newton step that leaves it is replaced by bisection.
    Stops when the bracket is below ``tol`` times its initial width or |F(z) − q| < 1e-13.
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
        F = _mixture_cdf(z, mu, sd, w)
        below = F < target
        lo = np.where(below, z, lo)
        hi = np.where(below, hi, z)
        done = (hi - lo <= tol * scale) | (np.abs(F - target) < 1e-13)
        if np.all(done):
            break
        f = _mixture_pdf(z, mu, sd, w)
        with np.errstate(divide="ignore", invalid="ignore"):
            newton = z - (F - target) / f
        ok = np.isfinite(newton) & (newton > lo) & (newton < hi)
        z = np.where(done, z, np.where(ok, newton, 0.5 * (lo + hi)))
    return z[0] if np.ndim(q) == 0 else z


def predictive_band(means, sds, level: float = 0.9, weights=None, **kwargs) -> PredictiveBand:
    """Median and central ``level`` band of the pointwise mixture (default 90%: 5% and 95% quantiles)."""
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must lie in (0, 1), got {level}")
    a = 0.5 * (1.0 - level)
    lower, median, upper = mixture_quantile(means, sds, [a, 0.5, 1.0 - a], weights, **kwargs)
    return PredictiveBand(median=median, lower=lower, upper=upper, level=float(level))


def coverage(y, lower, upper) -> float:
    """Fraction of observations ``y`` inside [lower, upper] (pointwise arrays of equal shape)."""
    y = np.asarray(y, dtype=float)
    inside = (y >= np.asarray(lower)) & (y <= np.asarray(upper))
    return float(np.mean(inside))


def gaussian_crps(mu, sd, y) -> np.ndarray:
    """Closed-form CRPS of N(mu, sd²) at y: sd [z (2Φ(z) − 1) + 2φ(z) − 1/√π], z = (y − mu)/sd."""
    mu, sd, y = (np.asarray(a, dtype=float) for a in (mu, sd, y))
    z = (y - mu) / sd
    pdf = np.exp(-0.5 * z * z) / np.sqrt(2.0 * np.pi)
    return sd * (z * (2.0 * ndtr(z) - 1.0) + 2.0 * pdf - 1.0 / np.sqrt(np.pi))


def crps_ensemble(draws, y, *, fair: bool = False) -> np.ndarray:
    """Ensemble CRPS per point: ``draws`` (M, P) members, ``y`` (P,) observations -> (P,).

    (1/M) Σ|z_k − y| − c Σ_k Σ_l |z_k − z_l| with c = 1/(2M²) (``fair=False``, empirical-CDF CRPS) or
    1/(2M(M−1)) (``fair=True``); the double sum uses the sorted form 2 Σ_k (2k − M − 1) z_(k).
    """
    z = np.asarray(draws, dtype=float)
    if z.ndim == 1:
        z = z[:, None]
    y = np.broadcast_to(np.asarray(y, dtype=float), z.shape[1:])
    M = z.shape[0]
    if fair and M < 2:
        raise ValueError("the fair CRPS needs at least 2 ensemble members")
    term1 = np.mean(np.abs(z - y[None, :]), axis=0)
    zs = np.sort(z, axis=0)
    k = np.arange(1, M + 1, dtype=float)[:, None]
    pair_sum = 2.0 * np.sum((2.0 * k - M - 1.0) * zs, axis=0)
    denom = 2.0 * M * (M - 1) if fair else 2.0 * M * M
    return term1 - pair_sum / denom


def predictive_crps(means, sds, y, *, replicates: int = 5, seed: int | np.random.Generator = 0,
                    fair: bool = False) -> CRPSResult:
    """CRPS of the Gaussian-mixture predictive at the observations ``y`` (P,), Monte Carlo (module doc).

    Each replicate draws one z_kp ~ N(μ_kp, s_kp²) per posterior sample and point; the per-point
    ensemble CRPS is averaged over points; ``mean`` averages the ``replicates`` independent values.
    """
    mu, sd, _ = _prepare(means, sds, None)
    y = np.asarray(y, dtype=float)
    if y.shape != (mu.shape[1],):
        raise ValueError(f"y must have shape ({mu.shape[1]},), got {y.shape}")
    if replicates < 1:
        raise ValueError("replicates must be >= 1")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    per_rep = np.empty(replicates)
    per_point = np.zeros(mu.shape[1])
    for r in range(replicates):
        draws = mu + sd * rng.standard_normal(mu.shape)
        c = crps_ensemble(draws, y, fair=fair)
        per_rep[r] = c.mean()
        per_point += c / replicates
    return CRPSResult(mean=float(per_rep.mean()), replicates=per_rep, per_point=per_point, fair=fair)


def map_index(log_posterior) -> int:
    """Index of the sample with the largest finite log posterior (ValueError if none is finite)."""
    lp = np.asarray(log_posterior, dtype=float).reshape(-1)
    finite = np.isfinite(lp)
    if not finite.any():
        raise ValueError("no sample has a finite log posterior")
    return int(np.argmax(np.where(finite, lp, -np.inf)))


def map_estimate(samples: Mapping[str, Sequence] | np.ndarray, log_posterior):
    """The MAP sample: a dict {name: value} for dict-of-arrays input, or the row of an (S, D) array."""
    i = map_index(log_posterior)
    if isinstance(samples, Mapping):
        return {k: np.asarray(v)[i] for k, v in samples.items()}
    return np.asarray(samples)[i]
