"""Closed-form shell force laws over the six shell parameters: known-answer training data for the surrogates.

These laws are *not* a physical model of the DPD bubble; they are smooth, monotone, Reissner-
flavoured maps of the same inputs and output scales, so that the surrogate pipeline can be
checked against a known answer: with multiplicative Gaussian noise of relative level ``noise``
on every point, the best possible grouped-holdout score is the *noise floor* (the score of the
exact law against the noisy curves, :func:`noise_floor`).

Compression, total plate displacement d -> force F (strain e = d / (2R)):

    k_R = 8 sqrt(ka kb / sqrt 3) / R                           (Reissner point-load stiffness)
    F(d) = k_R d [1 + b1 e / 2 + b2 e^2] + pi ka R e^2 [1 + a3 e + a4 e^2] + F_c
    F_c = 0.01 k_R R                                            (a small contact preload)

Indentation, force F -> pole displacement (q = F / (ka R), a dimensionless load):

    delta(F) = (F / k_R) [1 + b1 q / 4 + b2 q^2] / [1 + (2 + a3 / 2 + a4 / 4) q]

Default parameter boxes mimic the published designs' magnitudes (DPD units; b1..a4 dimensionless).
"""

from __future__ import annotations

import math

import numpy as np

from bubblecal.data import SHELL_PARAMETERS
from bubblecal.surrogates.training.dataset import TrainingSet

__all__ = ["DEFAULT_RANGES", "DEFAULT_X", "compression_force", "indentation_displacement", "truth", "make_synthetic",
           "noise_floor", "relative_l2"]

#: Default parameter box [lo, hi] per loading protocol (DPD units; b1..a4 dimensionless).
DEFAULT_RANGES: dict[str, dict[str, tuple[float, float]]] = {
    "compression": {"ka": (5.0e3, 5.0e4), "kb": (100.0, 1000.0), "b1": (0.0, 3.0), "b2": (0.0, 10.0),
                    "a3": (-2.5, 3.0), "a4": (0.0, 4.0)},
    "indentation": {"ka": (5.0e3, 5.0e4), "kb": (5.0e3, 4.0e4), "b1": (0.0, 10.0), "b2": (-2.5, 3.0),
                    "a3": (0.0, 4.0), "a4": (0.0, 4.0)},
}

#: Default load points per loading protocol: displacement [DPD length] or force [DPD force].
DEFAULT_X = {
    "compression": np.linspace(0.0, 1.68, 15),  # DPD length, as in F_Delta.dat
    "indentation": np.linspace(0.0, 6000.0, 15),  # DPD force, as in the 3.2 um samples_all.dat
}


def _reissner(ka, kb, radius):
    """Reissner point-load stiffness k_R [DPD force / DPD length]."""
    return 8.0 * np.sqrt(np.abs(ka * kb) / math.sqrt(3.0)) / radius


def _columns(params, coord, radius_dpd: float):
    """Split params (..., 6) into ka..a4 plus the Reissner stiffness, broadcast against the loading coordinate."""
    p = np.asarray(params, dtype=float)
    coord = np.asarray(coord, dtype=float)
    cols = [p[..., j] for j in range(6)]
    cols.append(_reissner(cols[0], cols[1], radius_dpd))
    if coord.ndim > 0 and p.ndim > 1:
        cols = [v[..., None] for v in cols]
    return cols, coord


def compression_force(params, d, radius_dpd: float):
    """Closed-form compression force F(d) (module docstring).

    Parameters
    ----------
    params : array_like, shape (6,) or (n, 6)
        Shell parameters (ka, kb, b1, b2, a3, a4) [DPD units].
    d : array_like, shape (m,) or scalar
        Total plate displacement [DPD length].
    radius_dpd : float
        Bubble radius [DPD length].

    Returns
    -------
    numpy.ndarray
        Force [DPD force]: (m,) for ``params`` (6,); (n, m) for ``params`` (n, 6) with ``d`` (m,).
    """
    (ka, kb, b1, b2, a3, a4, kr), d = _columns(params, d, radius_dpd)
    e = d / (2.0 * radius_dpd)
    return (kr * d * (1.0 + 0.5 * b1 * e + b2 * e**2) + math.pi * ka * radius_dpd * e**2 * (1.0 + a3 * e + a4 * e**2)
            + 0.01 * kr * radius_dpd)


def indentation_displacement(params, force, radius_dpd: float):
    """Closed-form indentation depth delta(F) (module docstring).

    Parameters
    ----------
    params : array_like, shape (6,) or (n, 6)
        Shell parameters (ka, kb, b1, b2, a3, a4) [DPD units].
    force : array_like, shape (m,) or scalar
        Applied pole force [DPD force].
    radius_dpd : float
        Bubble radius [DPD length].

    Returns
    -------
    numpy.ndarray
        Depth [DPD length], shaped as for :func:`compression_force`.
    """
    (ka, kb, b1, b2, a3, a4, kr), f = _columns(params, force, radius_dpd)
    q = f / (ka * radius_dpd)
    return (f / kr) * (1.0 + 0.25 * b1 * q + b2 * q**2) / (1.0 + (2.0 + 0.5 * a3 + 0.25 * a4) * q)


def truth(setup: str, params, x, radius_dpd: float):
    """The exact law of ``setup`` at (params, x).

    Parameters
    ----------
    setup : {'compression', 'indentation'}
        Loading protocol.
    params : array_like, shape (6,) or (n, 6)
        Shell parameters [DPD units].
    x : array_like
        Loading coordinate: displacement [DPD length] or force [DPD force].
    radius_dpd : float
        Bubble radius [DPD length].

    Returns
    -------
    numpy.ndarray
        Force [DPD force] (compression) or depth [DPD length] (indentation).

    Raises
    ------
    ValueError
        For an unknown ``setup``.
    """
    if setup == "compression":
        return compression_force(params, x, radius_dpd)
    if setup == "indentation":
        return indentation_displacement(params, x, radius_dpd)
    raise ValueError(f"setup must be 'compression' or 'indentation', got {setup!r}")


def make_synthetic(n_curves: int, setup: str = "compression", radius_dpd: float = 4.2, noise: float = 0.01,
                   seed: int = 0, ranges: dict | None = None, x=None) -> TrainingSet:
    """Latin-hypercube parameter sets in ``ranges`` with curves from the closed form plus noise.

    Noise is multiplicative Gaussian: y = y_true (1 + noise * N(0, 1)), independent per point.

    Parameters
    ----------
    n_curves : int
        Number of parameter sets (one curve each).
    setup : {'compression', 'indentation'}
        Loading protocol.
    radius_dpd : float
        Bubble radius [DPD length].
    noise : float
        Relative noise level.
    seed : int
        Seed of the design and the noise.
    ranges : dict, optional
        Parameter box {name: (lo, hi)} (default :data:`DEFAULT_RANGES` of ``setup``).
    x : array_like, optional
        Load points (default :data:`DEFAULT_X` of ``setup``) [DPD length or DPD force].

    Returns
    -------
    TrainingSet
        The noisy curves; the clean ones are in ``extra['y_true']``.
    """
    rng = np.random.default_rng(seed)
    ranges = dict(ranges or DEFAULT_RANGES[setup])
    x = np.asarray(DEFAULT_X[setup] if x is None else x, dtype=float)
    # Latin hypercube: one stratum per curve and dimension, shuffled per dimension
    u = (rng.permuted(np.tile(np.arange(n_curves), (6, 1)), axis=1).T + rng.random((n_curves, 6))) / n_curves
    lo = np.array([ranges[k][0] for k in SHELL_PARAMETERS])
    hi = np.array([ranges[k][1] for k in SHELL_PARAMETERS])
    params = lo + u * (hi - lo)
    xx = np.tile(x, (n_curves, 1))
    y_true = truth(setup, params, x, radius_dpd)
    y = y_true * (1.0 + noise * rng.standard_normal(y_true.shape))
    return TrainingSet(setup=setup, params=params, radius_dpd=np.full(n_curves, float(radius_dpd)), x=xx, y=y,
                       curve_id=np.array([f"synthetic-{setup}-{seed}-{i:05d}" for i in range(n_curves)]),
                       source=f"synthetic:{setup}:n={n_curves}:noise={noise}:seed={seed}",
                       extra={"y_true": y_true})


def relative_l2(y_hat, y) -> np.ndarray:
    """Per-curve relative L2 error ||y_hat - y||_2 / ||y||_2 (last axis = points).

    Parameters
    ----------
    y_hat, y : array_like
        Predictions and references of the same shape (any units, the same for both).

    Returns
    -------
    numpy.ndarray
        One error per curve (the shape without the last axis).
    """
    y_hat = np.asarray(y_hat, dtype=float)
    y = np.asarray(y, dtype=float)
    return np.linalg.norm(y_hat - y, axis=-1) / np.linalg.norm(y, axis=-1)


def noise_floor(ts: TrainingSet, curve_index=None) -> float:
    """Median per-curve relative L2 of the exact law against the noisy curves: the best achievable score.

    Parameters
    ----------
    ts : TrainingSet
        A set from :func:`make_synthetic` (needs ``extra['y_true']``).
    curve_index : array_like, optional
        Curves to score (default: all).

    Returns
    -------
    float
        The noise floor of the grouped-holdout score.
    """
    idx = np.arange(ts.n_curves) if curve_index is None else np.asarray(curve_index)
    y_true = ts.extra["y_true"][idx]
    return float(np.median(relative_l2(y_true, ts.y[idx])))
