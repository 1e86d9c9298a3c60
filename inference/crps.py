"""Continuous ranked probability score (CRPS) of the Gaussian-mixture posterior predictive.

The score of ``docs/inference.md`` section 7, over plain arrays (knows no physics); the mixture is the
one of :mod:`bubblecal.inference.predictive`: at P points from S posterior samples,
p(z_p) = (1/S) Σ_k N(z_p | μ_kp, s_kp²) with ``means`` μ (S, P) and ``sds`` s (S, P).

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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr

from bubblecal.inference.predictive import _prepare

__all__ = ["CRPSResult", "gaussian_crps", "crps_ensemble", "predictive_crps"]


@dataclass(frozen=True)
class CRPSResult:
    """CRPS of a predictive, averaged over points and replicates, with its Monte Carlo error.

    Parameters
    ----------
    mean : float
        CRPS averaged over points and replicates (units of y).
    replicates : numpy.ndarray
        Point-averaged CRPS of each replicate.
    per_point : numpy.ndarray
        (P,) CRPS per point, averaged over replicates.
    fair : bool
        Whether the fair (unbiased) ensemble estimator was used.
    """

    mean: float
    replicates: np.ndarray
    per_point: np.ndarray
    fair: bool

    @property
    def mc_error(self) -> float:
        """Standard error of ``mean`` over the replicates (0 for a single replicate)."""
        r = self.replicates
        return float(np.std(r, ddof=1) / np.sqrt(r.size)) if r.size > 1 else 0.0


def gaussian_crps(mu, sd, y) -> np.ndarray:
    """Closed-form CRPS of N(mu, sd²) at y: sd [z (2Φ(z) − 1) + 2φ(z) − 1/√π], z = (y − mu)/sd.

    Parameters
    ----------
    mu, sd, y : array_like
        Mean, standard deviation and observation (one unit; broadcast).

    Returns
    -------
    numpy.ndarray
        CRPS in the units of y.
    """
    mu, sd, y = (np.asarray(a, dtype=float) for a in (mu, sd, y))
    z = (y - mu) / sd
    pdf = np.exp(-0.5 * z * z) / np.sqrt(2.0 * np.pi)
    return sd * (z * (2.0 * ndtr(z) - 1.0) + 2.0 * pdf - 1.0 / np.sqrt(np.pi))


def crps_ensemble(draws, y, *, fair: bool = False) -> np.ndarray:
    """Ensemble CRPS per point.

    (1/M) Σ|z_k − y| − c Σ_k Σ_l |z_k − z_l| with c = 1/(2M²) (``fair=False``, empirical-CDF CRPS) or
    1/(2M(M−1)) (``fair=True``); the double sum uses the sorted form 2 Σ_k (2k − M − 1) z_(k).

    Parameters
    ----------
    draws : array_like
        (M, P) ensemble members (units of y).
    y : array_like
        (P,) observations.
    fair : bool
        Use the fair (unbiased) estimator.

    Returns
    -------
    numpy.ndarray
        (P,) CRPS in the units of y.

    Raises
    ------
    ValueError
        For the fair estimator with fewer than 2 members.
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
                    fair: bool = False, normals=None) -> CRPSResult:
    """CRPS of the Gaussian-mixture predictive at the observations, by Monte Carlo (module docstring).

    Each replicate draws one z_kp ~ N(μ_kp, s_kp²) per posterior sample and point; the per-point
    ensemble CRPS is averaged over points; ``mean`` averages the ``replicates`` independent values.

    Parameters
    ----------
    means, sds : array_like
        (S, P) per-sample predictions and noise standard deviations (units of y).
    y : array_like
        (P,) observations.
    replicates : int
        Independent replicates (>= 1).
    seed : int or numpy.random.Generator
        Seed or generator of the draws.
    fair : bool
        Use the fair ensemble estimator.
    normals : array_like, optional
        (R, S, P) standard normal draws to use instead of drawing from ``seed``; R replaces
        ``replicates``. Drawing them in advance lets callers fix the random stream of several scores
        and compute the scores in any order (e.g. on threads).

    Returns
    -------
    CRPSResult

    Raises
    ------
    ValueError
        For a badly shaped ``y`` or ``normals``, ``replicates`` < 1 or invalid inputs.
    """
    mu, sd, _ = _prepare(means, sds, None)
    y = np.asarray(y, dtype=float)
    if y.shape != (mu.shape[1],):
        raise ValueError(f"y must have shape ({mu.shape[1]},), got {y.shape}")
    if normals is not None:
        normals = np.asarray(normals, dtype=float)
        if normals.ndim != 3 or normals.shape[1:] != mu.shape:
            raise ValueError(f"normals must have shape (replicates, {mu.shape[0]}, {mu.shape[1]}), "
                             f"got {normals.shape}")
        replicates = normals.shape[0]
    if replicates < 1:
        raise ValueError("replicates must be >= 1")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    per_rep = np.empty(replicates)
    per_point = np.zeros(mu.shape[1])
    for r in range(replicates):
        draws = mu + sd * (normals[r] if normals is not None else rng.standard_normal(mu.shape))
        c = crps_ensemble(draws, y, fair=fair)
        per_rep[r] = c.mean()
        per_point += c / replicates
    return CRPSResult(mean=float(per_rep.mean()), replicates=per_rep, per_point=per_point, fair=fair)
