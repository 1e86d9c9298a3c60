"""The collapse verdict of quasi-static indentation: a depth that falls under a rising force ends the curve.

Under a force that only grows, a stable indented shell only gets deeper.  A minimum whose depth lies well below
an earlier point's belongs to another branch (the loaded cap turned into a different buckled mode, or the
shell snapped past a fold), which a force-controlled AFM never follows; such a curve is cut at that point
('collapsed', its prefix kept) rather than reported as one smooth d(F) (docs/physics.md, section 7).
"""

from __future__ import annotations

import math

import numpy as np

from bubblecal.sim.tiers.quasistatic.settings import STATUS_COLLAPSED, STATUS_NOT_CONVERGED, STATUS_OK

__all__ = ["depth_collapse_point"]


def check_max_depth_fall(max_depth_fall) -> float | None:
    """``max_depth_fall`` as a float in (0, 1), or None (no collapse verdict).

    Raises
    ------
    ValueError
        If it is not None and not a number in (0, 1).
    """
    if max_depth_fall is None:
        return None
    v = max_depth_fall
    if isinstance(v, bool) or not isinstance(v, (int, float, np.floating)) or not (math.isfinite(v) and 0 < v < 1):
        raise ValueError(f"max_depth_fall must be a fraction in (0, 1) or omitted, got {max_depth_fall!r}")
    return float(v)


def depth_collapse_point(depth, max_depth_fall: float) -> int | None:
    """First load point whose depth lies below the deepest earlier point by more than a fraction of it.

    Parameters
    ----------
    depth : array_like
        [P] indentation depth d(F) at increasing forces (DPD length); the scan stops at the first non-finite
        value (a failed curve's NaN tail).
    max_depth_fall : float
        Largest allowed fall below the running maximum depth, as a fraction of it, in (0, 1).

    Returns
    -------
    int or None
        The index j of the first point with d_j < (1 - max_depth_fall) max_{i<j} d_i (while that maximum is
        positive), or None when the curve never falls that far.

    Raises
    ------
    ValueError
        If ``max_depth_fall`` is not in (0, 1).
    """
    tol = check_max_depth_fall(max_depth_fall)
    if tol is None:
        raise ValueError("max_depth_fall must be a fraction in (0, 1), got None")
    deepest = -math.inf
    for j, d in enumerate(np.asarray(depth, dtype=float).ravel()):
        if not math.isfinite(d):
            return None
        if deepest > 0 and d < (1.0 - tol) * deepest:
            return j
        deepest = max(deepest, d)
    return None


def cut_collapsed(depth: np.ndarray, status: str, point_status: list[str],
                  max_depth_fall: float | None) -> tuple[np.ndarray, str, list[str], int | None]:
    """One curve with the collapse verdict applied: from the collapse point on, NaN depths and 'collapsed'.

    Only curves still 'ok' or 'not_converged' (a failure already ended the others, before any collapse the scan
    could see) are cut.

    Parameters
    ----------
    depth : numpy.ndarray
        [P] d(F) at the reported points (DPD length).
    status : str
        The curve's verdict so far.
    point_status : list of str
        [P] per-point verdicts.
    max_depth_fall : float or None
        :func:`depth_collapse_point`'s tolerance; None: no verdict (the inputs come back unchanged).

    Returns
    -------
    depth, status, point_status, j
        The (copied where cut) curve, its verdict and point verdicts, and the collapse point (None: not cut).
    """
    if max_depth_fall is None or status not in (STATUS_OK, STATUS_NOT_CONVERGED):
        return depth, status, point_status, None
    j = depth_collapse_point(depth, max_depth_fall)
    if j is None:
        return depth, status, point_status, None
    depth = np.array(depth, dtype=float)
    depth[j:] = np.nan
    return depth, STATUS_COLLAPSED, list(point_status[:j]) + [STATUS_COLLAPSED] * (len(point_status) - j), j
