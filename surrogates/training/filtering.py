"""Filtering training curves: drop unusable curves, or keep the usable prefix of a failed one.

:func:`filter_curves` removes, with counts reported per reason (:class:`FilterReport`): rows with non-finite
numbers; store records whose status is not ``'ok'``; rupture by *trailing zeros* (the last raw response -
force for compression, axial diameter for indentation - at most ``zero_frac`` of the curve's largest
magnitude); rupture by a *drop*: the response must grow along the loading path, and a curve is dropped when
it falls below its running maximum by more than ``max_rel_drop`` of the curve's largest magnitude.

Failure-truncated prefixes (``keep_failed_prefix=True``): a store record with status ``'ruptured'`` or
``'failed'`` (:data:`PREFIX_STATUSES`) holds a finite response up to the load point where the shell broke
and NaN after it. Such a curve keeps its finite prefix *minus its last finite point* (the point just before
failure is unreliable) when at least ``min_prefix_points`` points (x = 0 included) remain; the dropped tail
is NaN in ``y`` (``x`` keeps its grid). Downstream code is pointwise and accepts such NaN tails
(:class:`~bubblecal.surrogates.training.TrainingSet`, the holdout scores of
:func:`~bubblecal.surrogates.training.run_sweep`, which use the finite points of each curve).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from bubblecal.surrogates.training.dataset import TrainingSet, leading_finite

__all__ = ["PREFIX_STATUSES", "FilterReport", "filter_curves"]

#: Store statuses whose finite prefix ``filter_curves(keep_failed_prefix=True)`` can keep.
PREFIX_STATUSES: tuple[str, ...] = ("ruptured", "failed")


@dataclass
class FilterReport:
    """Counts of curves removed per reason by :func:`filter_curves` (a curve counts under the first reason it meets).

    Parameters
    ----------
    source : str
        The training set's source.
    n_in, n_kept : int
        Curves read and kept.
    counts : dict of str to int
        Curves removed per reason (``status``, ``non_finite``, [``prefix_invalid``, ``prefix_too_short``],
        ``rupture_trailing_zero``, ``rupture_drop``).
    dropped : dict of str to list of str
        Curve ids removed per reason.
    settings : dict
        The criteria used (``filter_curves`` keyword arguments).
    status_counts : dict of str to int
        Curves dropped for reason ``status``, split by their store status (e.g. ruptured, invalid, failed).
    prefix : dict of str to dict
        With ``keep_failed_prefix``, per store status (ruptured, failed): the prefix curves ``kept`` and the
        ``points`` they contribute (x = 0 included), and those rejected: ``invalid`` (no NaN tail, interior
        NaN, infinity), ``too_short`` (< ``min_prefix_points`` after dropping the last finite point) and
        ``quality`` (removed by the rupture checks on the kept prefix).
    n_points_kept : int
        Usable points of the kept curves.
    """

    source: str
    n_in: int
    n_kept: int
    counts: dict[str, int]
    dropped: dict[str, list[str]]
    settings: dict
    status_counts: dict[str, int] = field(default_factory=dict)
    prefix: dict[str, dict[str, int]] = field(default_factory=dict)
    n_points_kept: int = 0

    @property
    def n_prefix_curves(self) -> int:
        """Kept curves that are failure-truncated prefixes."""
        return int(sum(v["kept"] for v in self.prefix.values()))

    @property
    def n_prefix_points(self) -> int:
        """Points contributed by the kept prefix curves."""
        return int(sum(v["points"] for v in self.prefix.values()))

    def as_dict(self) -> dict:
        """Plain-JSON form (recorded as ``filter`` in a surrogate's metadata)."""
        return {"source": self.source, "n_in": self.n_in, "n_kept": self.n_kept, "n_points_kept": self.n_points_kept,
                "counts": dict(self.counts), "status_counts": dict(self.status_counts),
                "n_prefix_curves": self.n_prefix_curves, "n_prefix_points": self.n_prefix_points,
                "prefix": {k: dict(v) for k, v in self.prefix.items()}, "settings": dict(self.settings)}

    def __str__(self) -> str:
        """A table of counts per reason, for the command line."""
        lines = [f"{self.source}: {self.n_in} curves read, {self.n_kept} kept ({self.n_points_kept} points)"]
        for reason, count in self.counts.items():
            lines.append(f"  {reason:<24s} {count:6d}")
            if reason == "status":
                for status, n in self.status_counts.items():
                    lines.append(f"    {status:<22s} {n:6d}")
        if self.settings.get("keep_failed_prefix"):
            lines.append(f"  failure-truncated prefixes kept: {self.n_prefix_curves} curves, {self.n_prefix_points} "
                         f"points (finite prefix minus its last point, >= {self.settings['min_prefix_points']} points)")
            for status, c in self.prefix.items():
                lines.append(f"    {status:<10s} kept {c['kept']:5d} curves {c['points']:6d} points; rejected: "
                             f"too short {c['too_short']}, invalid {c['invalid']}, rupture checks {c['quality']}")
        return "\n".join(lines)


def _raw_response(ts: TrainingSet) -> np.ndarray:
    """The stored response before orientation: force (compression) or axial diameter (indentation)."""
    if ts.setup == "compression":
        return ts.y
    d0 = 2.0 * ts.radius_dpd[:, None]
    return d0 - ts.y


def filter_curves(ts: TrainingSet, zero_frac: float = 0.01, max_rel_drop: float = 0.10,
                  statuses: Sequence[str] = ("ok",), keep_failed_prefix: bool = False, min_prefix_points: int = 5,
                  prefix_statuses: Sequence[str] = PREFIX_STATUSES) -> tuple[TrainingSet, FilterReport]:
    """Drop unusable curves (or keep failure-truncated prefixes), counting each removal under its reason.

    Reasons, checked in order: ``status`` (store status not in ``statuses``, and not a prefix
    candidate; the report's ``status_counts`` splits it by status: ruptured, invalid = non-finite
    curve, failed, unstable, ...), ``non_finite`` (any non-finite parameter, radius, x or - except
    for prefix candidates - y), [``prefix_invalid``, ``prefix_too_short``: prefix candidates, see
    below], ``rupture_trailing_zero`` (last kept raw response <= ``zero_frac`` x the curve's
    largest |raw response|), ``rupture_drop`` (the response falls below its running maximum by
    more than ``max_rel_drop`` x the curve's largest |response|).

    ``keep_failed_prefix`` (default False: whole curves only): records whose status is in
    ``prefix_statuses`` (``'ruptured'``, ``'failed'``; never ``'unstable'`` or ``'invalid'``) are
    prefix candidates. A candidate's response must be finite on a leading prefix and NaN to the end
    (at least one trailing NaN; otherwise ``prefix_invalid``: an interior NaN, an infinity or a fully
    finite curve whose failure point is unknown). It keeps the finite prefix minus its last finite
    point (the point just before failure is unreliable) if at least ``min_prefix_points`` points
    (x = 0 included) remain (otherwise ``prefix_too_short``); the dropped tail becomes NaN in ``y``
    (the arrays keep their (n_curves, n_points) shape, x keeps its grid). The rupture checks then
    apply to the kept prefix. x and y are in DPD units (compression: displacement [DPD length] ->
    force [DPD force]; indentation: force [DPD force] -> displacement [DPD length]). The report's
    ``prefix`` lists, per status, the prefix curves kept and the points they contribute.

    Parameters
    ----------
    ts : TrainingSet
        Curves as read (DPD units).
    zero_frac : float
        Trailing-zero rupture threshold, relative to the curve's largest |raw response|.
    max_rel_drop : float
        Largest allowed fall below the running maximum, relative to the curve's largest |response|.
    statuses : sequence of str
        Store statuses kept whole.
    keep_failed_prefix : bool
        Keep the finite prefixes of records whose status is in ``prefix_statuses``.
    min_prefix_points : int
        Fewest points (x = 0 included) of a kept prefix; at least 2.
    prefix_statuses : sequence of str
        Statuses whose prefixes may be kept (default :data:`PREFIX_STATUSES`).

    Returns
    -------
    kept : TrainingSet
        The kept curves (kept prefixes with NaN tails in ``y``).
    report : FilterReport
        Counts per reason, the dropped curve ids and the settings.

    Raises
    ------
    ValueError
        When ``min_prefix_points < 2``.
    """
    if min_prefix_points < 2:
        raise ValueError(f"min_prefix_points must be >= 2, got {min_prefix_points}")
    n, m = ts.n_curves, ts.n_points
    reason = np.full(n, "", dtype=object)
    ok_status = np.isin(ts.status, list(statuses))
    candidate = (np.isin(ts.status, list(prefix_statuses)) & ~ok_status) if keep_failed_prefix else np.zeros(n, bool)
    bad_status = ~ok_status & ~candidate
    reason[bad_status] = "status"
    finite_meta = (np.all(np.isfinite(ts.params), axis=1) & np.isfinite(ts.radius_dpd)
                   & np.all(np.isfinite(ts.x), axis=1))
    finite = finite_meta & np.all(np.isfinite(ts.y), axis=1)
    reason[(reason == "") & ~candidate & ~finite] = "non_finite"
    reason[(reason == "") & candidate & ~finite_meta] = "non_finite"
    k, nan_tail = leading_finite(ts.y) if m else (np.zeros(n, int), np.ones(n, bool))
    n_prefix = k - 1  # finite prefix minus its last finite point
    reason[(reason == "") & candidate & ~(nan_tail & (k < m))] = "prefix_invalid"
    reason[(reason == "") & candidate & (n_prefix < min_prefix_points)] = "prefix_too_short"
    truncate = (reason == "") & candidate
    y = ts.y.copy()
    if truncate.any():
        y[truncate] = np.where(np.arange(m)[None, :] < n_prefix[truncate, None], y[truncate], np.nan)
    work = replace(ts, y=y)
    valid = work.point_mask()
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN rows (already dropped) in nanmax
        raw = np.abs(_raw_response(work))
        scale = np.nanmax(raw, axis=1)
        last = np.where(valid.any(axis=1), m - 1 - np.argmax(valid[:, ::-1], axis=1), 0)
        trailing = raw[np.arange(n), last] <= zero_frac * scale
        reason[(reason == "") & trailing] = "rupture_trailing_zero"
        # order along the loading path (x increasing)
        order = np.argsort(np.where(np.isfinite(work.x), work.x, np.inf), axis=1)
        y_sorted = np.take_along_axis(work.y, order, axis=1)
        running = np.maximum.accumulate(np.nan_to_num(y_sorted, nan=-np.inf), axis=1)
        drop = np.nanmax(running - y_sorted, axis=1)
        yscale = np.nanmax(np.abs(work.y), axis=1)
        dropped = drop > max_rel_drop * yscale
    reason[(reason == "") & dropped] = "rupture_drop"
    keep = reason == ""
    reasons = ["status", "non_finite"]
    if keep_failed_prefix:
        reasons += ["prefix_invalid", "prefix_too_short"]
    reasons += ["rupture_trailing_zero", "rupture_drop"]
    counts = {r: int(np.sum(reason == r)) for r in reasons}
    dropped_ids = {r: ts.curve_id[reason == r].tolist() for r in reasons}
    status_values, status_n = np.unique(ts.status[bad_status], return_counts=True)
    prefix: dict[str, dict[str, int]] = {}
    if keep_failed_prefix:
        for st in prefix_statuses:
            c = candidate & (ts.status == st)
            if not c.any():
                continue
            kept = c & keep
            prefix[str(st)] = {
                "kept": int(kept.sum()), "points": int(n_prefix[kept].sum()),
                "invalid": int(np.sum(c & (reason == "prefix_invalid"))),
                "too_short": int(np.sum(c & (reason == "prefix_too_short"))),
                "quality": int(np.sum(c & np.isin(reason, ["rupture_trailing_zero", "rupture_drop"]))),
            }
    report = FilterReport(source=ts.source, n_in=n, n_kept=int(keep.sum()), counts=counts, dropped=dropped_ids,
                          settings={"zero_frac": zero_frac, "max_rel_drop": max_rel_drop,
                                    "statuses": list(statuses), "keep_failed_prefix": bool(keep_failed_prefix),
                                    "min_prefix_points": int(min_prefix_points),
                                    "prefix_statuses": list(prefix_statuses)},
                          status_counts={str(k): int(v) for k, v in zip(status_values, status_n, strict=True)},
                          prefix=prefix, n_points_kept=int(valid[keep].sum()))
    return work.subset(keep), report
