"""Pareto k̂ of importance weights: the shape of the generalized Pareto tail that PSIS fits (Vehtari et al. 2024).

:func:`pareto_k` is ArviZ's ``psislw`` diagnostic, operation for operation (the tail size, the cut-off, the
empirical-Bayes fit of Zhang & Stephens 2009 with its weak prior on k), in NumPy alone: the calibration job
reads k̂ of its phase-2 weights without importing ArviZ, whose import compiles Numba kernels where Numba is
installed. ``tests/inference/test_psis.py`` checks it against ``arviz.psislw``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["pareto_k"]

#: Prior of the generalized Pareto fit (ArviZ's ``_gpdfit``): the scale of b's grid and the pseudo-draws at k = 0.5.
_PRIOR_BS, _PRIOR_K = 3, 10


def pareto_k(log_weights, reff: float = 1.0) -> np.ndarray:
    """Pareto k̂ of PSIS-smoothed importance weights, one per column (the k̂ of ArviZ's ``psislw``).

    Parameters
    ----------
    log_weights : array_like
        (S,) or (S, n) unnormalised log importance weights over S draws (−inf allowed).
    reff : float
        Relative efficiency of the draws (1 for independent draws); sets the tail size with S.

    Returns
    -------
    numpy.ndarray
        Scalar array or (n,) k̂: below 0.7 the importance estimate is reliable; above, not; inf where the tail
        holds 4 draws or fewer.
    """
    lw = np.asarray(log_weights, dtype=np.float64)
    columns = lw.reshape(lw.shape[0], -1)
    s = columns.shape[0]
    cutoff_ind = -int(np.ceil(min(s / 5.0, 3 * (s / reff) ** 0.5))) - 1
    cutoff_min = np.log(np.finfo(float).tiny)
    k = np.array([_tail_shape(columns[:, j], cutoff_ind, cutoff_min) for j in range(columns.shape[1])])
    return k.reshape(lw.shape[1:])


def _tail_shape(log_weights: np.ndarray, cutoff_ind: int, cutoff_min: float) -> float:
    """k̂ of one column (ArviZ's ``_psislw`` without the smoothing of the weights)."""
    x = log_weights - np.max(log_weights)
    order = np.argsort(x)
    cutoff = max(x[order[cutoff_ind]], cutoff_min)
    tail = x[x > cutoff]
    if len(tail) <= 4:  # too few tail draws to fit
        return np.inf
    tail = np.exp(tail[np.argsort(tail)]) - np.exp(cutoff)
    return _gpd_shape(tail)


def _gpd_shape(ary: np.ndarray) -> float:
    """Shape k of the generalized Pareto distribution fitted to the sorted exceedances ``ary`` (Zhang & Stephens
    2009, with ArviZ's weak prior on k)."""
    n = len(ary)
    m_est = 30 + int(n**0.5)
    b_ary = 1 - np.sqrt(m_est / (np.arange(1, m_est + 1, dtype=float) - 0.5))
    b_ary /= _PRIOR_BS * ary[int(n / 4 + 0.5) - 1]
    b_ary += 1 / ary[-1]
    k_ary = np.log1p(-b_ary[:, None] * ary).mean(axis=1)
    len_scale = n * (np.log(-(b_ary / k_ary)) - k_ary - 1)
    weights = 1 / np.exp(len_scale - len_scale[:, None]).sum(axis=1)
    keep = weights >= 10 * np.finfo(float).eps  # negligible weights removed
    if not np.all(keep):
        weights, b_ary = weights[keep], b_ary[keep]
    weights /= weights.sum()
    b_post = np.sum(b_ary * weights)
    k_post = np.log1p(-b_post * ary).mean()
    return float((n * k_post + _PRIOR_K * 0.5) / (n + _PRIOR_K))
