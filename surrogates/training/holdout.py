"""The grouped parameter-set holdout of an architecture sweep and its scores (numpy only).

Whole curves are held out (:func:`grouped_holdout`), and for a network over the diameter whole diameter
bands too (:func:`diameter_bands`); a model is scored per held-out curve by the relative L2
error over the curve's finite points (:func:`curve_errors`), and the sweep compares the median over curves
(:func:`error_summary`). A held-out curve with fewer than :data:`MIN_SCORED_POINTS` finite points (a short
failure-truncated prefix) is skipped and counted.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from bubblecal.surrogates.features import network_inputs, response_scale
from bubblecal.surrogates.training.dataset import DatasetError, TrainingSet

if TYPE_CHECKING:
    from bubblecal.surrogates.training.train import TrainedMLP

__all__ = ["MIN_SCORED_POINTS", "grouped_holdout", "diameter_bands", "curve_errors", "error_summary", "selection_score",
           "fast_choice", "FAST_MEDIAN_FACTOR", "FAST_P90_FACTOR"]

#: A held-out curve needs this many finite points to be scored.
MIN_SCORED_POINTS = 2


def grouped_holdout(n_curves: int, frac: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Seeded split of curve indices into (train, holdout); at least one curve on each side.

    Parameters
    ----------
    n_curves : int
        Number of curves (at least 2).
    frac : float
        Fraction held out, in (0, 1).
    seed : int
        Seed of the permutation.

    Returns
    -------
    train, holdout : numpy.ndarray of int
        Sorted curve indices.

    Raises
    ------
    ValueError
        For ``frac`` outside (0, 1) or fewer than 2 curves.
    """
    if not 0.0 < frac < 1.0:
        raise ValueError(f"holdout_frac must be in (0, 1), got {frac}")
    if n_curves < 2:
        raise ValueError(f"need at least 2 curves for a grouped holdout, got {n_curves}")
    rng = np.random.default_rng(seed)
    perm = rng.permutation(n_curves)
    n_hold = min(n_curves - 1, max(1, int(round(frac * n_curves))))
    return np.sort(perm[n_hold:]), np.sort(perm[:n_hold])


def diameter_bands(diameters_um, bands) -> np.ndarray:
    """Mask of the curves whose diameter lies in one of the held-out bands (leave-diameters-out).

    Parameters
    ----------
    diameters_um : array_like, shape (n,)
        Diameter of each curve [um].
    bands : sequence of (float, float)
        Closed diameter intervals [um], each lo <= hi.

    Returns
    -------
    numpy.ndarray of bool, shape (n,)
        True for the curves inside a band.

    Raises
    ------
    ValueError
        For a band with lo > hi or a non-finite end.
    """
    d = np.asarray(diameters_um, dtype=float)
    mask = np.zeros(d.shape, dtype=bool)
    for band in bands:
        lo, hi = (float(v) for v in band)
        if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
            raise ValueError(f"diameter band must be finite with lo <= hi [um], got {band!r}")
        mask |= (d >= lo - 1e-9) & (d <= hi + 1e-9)
    return mask


def curve_errors(model: TrainedMLP, ts: TrainingSet, inputs: str = "raw",
                 log_inputs: tuple[str, ...] = ()) -> tuple[np.ndarray, np.ndarray]:
    """Per-curve relative L2 errors and predictions of ``model`` on the curves of ``ts``.

    Each curve is scored on its finite points (``ts.point_mask()``): ||y_hat - y||_2 / ||y||_2, in the response
    itself (a diameter network's output is multiplied back by its size scale).

    Parameters
    ----------
    model : TrainedMLP
        The trained network.
    ts : TrainingSet
        The curves to score (DPD units).
    inputs : {'raw', 'diameter'}
        The network's input kind (:mod:`bubblecal.surrogates.features`).
    log_inputs : tuple of str
        Shell parameters the network takes as natural logarithms.

    Returns
    -------
    err : numpy.ndarray, shape (n,)
        Relative L2 error per curve; NaN for a curve with fewer than :data:`MIN_SCORED_POINTS` finite points
        (skipped; see :func:`error_summary`).
    y_hat : numpy.ndarray, shape (n, m)
        Predictions at every point with a finite x (also a curve's NaN tail), NaN elsewhere.
    """
    n, m = ts.x.shape
    xfin = np.isfinite(ts.x)
    p = np.repeat(ts.params, m, axis=0)
    d = np.repeat(ts.diameters_um, m) if inputs == "diameter" else None
    u = network_inputs(inputs, p, np.where(xfin, ts.x, 0.0).reshape(-1), d, log_inputs=log_inputs)
    scale = np.broadcast_to(response_scale(inputs, ts.setup, p, d), (n * m,))
    y_hat = np.where(xfin, (model.predict(u) * scale).reshape(n, m), np.nan)
    valid = ts.point_mask()
    diff = np.where(valid, y_hat - ts.y, 0.0)
    ref = np.where(valid, ts.y, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        err = np.linalg.norm(diff, axis=1) / np.linalg.norm(ref, axis=1)
    err[valid.sum(axis=1) < MIN_SCORED_POINTS] = np.nan
    return err, y_hat


def error_summary(err: np.ndarray, prefix_mask: np.ndarray | None = None) -> dict:
    """Median / mean / p90 / max of the finite per-curve errors, with the numbers scored and skipped.

    Parameters
    ----------
    err : numpy.ndarray, shape (n,)
        Per-curve errors from :func:`curve_errors` (NaN = skipped).
    prefix_mask : numpy.ndarray of bool, shape (n,), optional
        Marks failure-truncated curves: their median and count are added (``holdout_median_prefix`` is None
        when none was scored).

    Returns
    -------
    dict
        ``holdout_median``, ``holdout_mean``, ``holdout_p90``, ``holdout_max``, ``holdout_n_scored``,
        ``holdout_n_skipped`` [, ``holdout_n_prefix``, ``holdout_median_prefix``].

    Raises
    ------
    DatasetError
        When no curve could be scored.
    """
    err = np.asarray(err, dtype=float)
    ok = np.isfinite(err)
    if not ok.any():
        raise DatasetError(f"no held-out curve has >= {MIN_SCORED_POINTS} finite points to score")
    e = err[ok]
    out = {"holdout_median": float(np.median(e)), "holdout_mean": float(np.mean(e)),
           "holdout_p90": float(np.quantile(e, 0.9)), "holdout_max": float(np.max(e)),
           "holdout_n_scored": int(ok.sum()), "holdout_n_skipped": int((~ok).sum())}
    if prefix_mask is not None:
        pm = np.asarray(prefix_mask, bool) & ok
        out["holdout_n_prefix"] = int(pm.sum())
        out["holdout_median_prefix"] = float(np.median(err[pm])) if pm.any() else None
    return out


def selection_score(row: dict) -> float:
    """The score a sweep row is selected by: the worst of its held-out, leave-diameters-out and off-grid medians.

    Parameters
    ----------
    row : dict
        A row of :attr:`SweepResult.rows` (or of a network's ``training.sweep`` metadata).

    Returns
    -------
    float
        Relative L2 (a fraction).
    """
    return max(row["holdout_median"], row.get("ldo_median", 0.0), row.get("offgrid_median", 0.0))


#: A fast network's worst median may be at most this many times the selection's (:func:`fast_choice`).
FAST_MEDIAN_FACTOR = 1.5
#: A fast network's held-out p90 may be at most this many times the selection's (:func:`fast_choice`).
FAST_P90_FACTOR = 2.0


def fast_choice(rows: list[dict], best: int) -> int | None:
    """The fast twin of a sweep's selection: its smallest architecture that stays close to the selection.

    Close means a :func:`selection_score` within :data:`FAST_MEDIAN_FACTOR` times the selection's and a held-out
    p90 within :data:`FAST_P90_FACTOR` times the selection's (a small network whose median is close but whose tail
    is not would fit some curves much worse; docs/decisions.md, "Fast networks over the diameter").

    Parameters
    ----------
    rows : list of dict
        :attr:`SweepResult.rows` (``n_params``, ``holdout_median``, ``holdout_p90`` and the other medians).
    best : int
        Index of the selected row.

    Returns
    -------
    int or None
        Index of the fast row (fewest parameters, ties to the lower score); None when no architecture smaller
        than the selection qualifies.
    """
    sel = rows[best]
    limit_median = FAST_MEDIAN_FACTOR * selection_score(sel)
    limit_p90 = FAST_P90_FACTOR * sel["holdout_p90"]
    ok = [i for i, r in enumerate(rows) if r["n_params"] < sel["n_params"] and selection_score(r) <= limit_median
          and r["holdout_p90"] <= limit_p90]
    return min(ok, key=lambda i: (rows[i]["n_params"], selection_score(rows[i]))) if ok else None
