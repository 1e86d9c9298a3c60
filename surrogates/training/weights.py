"""Per-point loss weights of a training run: how much each curve counts in the mean squared error.

With ``"none"`` every point counts the same, so a curve's share of the loss grows with the square of its response:
a few curves far larger than the rest (deep indentations of soft, large shells: a response over the size up to 1.4
where the others stay under 0.1) take the fit from the others.  ``"capped"`` divides a curve's squared errors by
its mean square response wherever that exceeds the median curve's, so no curve counts more than a typical one,
while the typical and smaller curves keep the plain MSE (docs/decisions.md, "The indentation stores and the
conjugate gradient").
"""

from __future__ import annotations

import numpy as np

__all__ = ["CURVE_WEIGHTS", "curve_weights"]

#: Accepted ``TrainConfig.curve_weights`` values.
CURVE_WEIGHTS = ("none", "capped")


def curve_weights(target: np.ndarray, curve: np.ndarray, kind: str = "none") -> np.ndarray | None:
    """Per-point weights of the training loss, normalised to a mean of 1 over the points.

    Parameters
    ----------
    target : numpy.ndarray, shape (p,)
        Network targets of the training points (the response over its size scale; any units).
    curve : numpy.ndarray of int, shape (p,)
        Curve index of each point.
    kind : str
        ``"none"`` (no weights: None) or ``"capped"``: curve c weighs min(1, m / s_c), s_c its mean square target
        and m the median of s_c over the curves with a positive one.

    Returns
    -------
    numpy.ndarray or None
        [p] weights with mean 1, or None for ``"none"``.

    Raises
    ------
    ValueError
        For an unknown ``kind``, mismatched shapes, or ``"capped"`` without a curve of non-zero response.
    """
    if kind not in CURVE_WEIGHTS:
        raise ValueError(f"curve_weights must be one of {CURVE_WEIGHTS}, got {kind!r}")
    if kind == "none":
        return None
    target = np.asarray(target, dtype=float).reshape(-1)
    curve = np.asarray(curve).reshape(-1)
    if target.shape != curve.shape:
        raise ValueError(f"target and curve must have one value per point, got {target.shape} and {curve.shape}")
    ids, inverse = np.unique(curve, return_inverse=True)
    ms = np.bincount(inverse, weights=target ** 2) / np.bincount(inverse)
    positive = ms > 0
    if not positive.any():
        raise ValueError("curve_weights 'capped' needs at least one curve with a non-zero response")
    m = float(np.median(ms[positive]))
    w_curve = np.ones_like(ms)
    w_curve[positive] = np.minimum(1.0, m / ms[positive])
    w = w_curve[inverse]
    return w / w.mean()
