"""The training set of a mechanical surrogate: one curve per row, in the surrogate's orientation.

A :class:`TrainingSet` holds the curves of one loading protocol (normally at one diameter) in DPD units
(axes in :mod:`bubblecal.surrogates.axes`):

* compression: ``x`` = imposed total displacement [DPD length], ``y`` = force [DPD force];
* indentation: ``x`` = applied force [DPD force], ``y`` = indentation depth [DPD length].

A curve may be a failure-truncated prefix: finite up to some load point and NaN after it (kept by
:func:`bubblecal.surrogates.training.filter_curves` with ``keep_failed_prefix=True``). Everything here is
pointwise and accepts such NaN tails: :meth:`TrainingSet.points` returns the finite points only and
:meth:`TrainingSet.check_trainable` accepts a trailing NaN block in ``y`` and nothing else.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field, replace

import numpy as np

from bubblecal.data import LOADING_PROTOCOLS, SHELL_PARAMETERS
from bubblecal.surrogates.axes import X_INFO, Y_INFO
from bubblecal.surrogates.features import UM_PER_RADIUS_DPD, network_inputs, response_scale

__all__ = ["DatasetError", "TrainingSet", "concat_training_sets", "leading_finite", "diameter_um_from_radius"]


class DatasetError(ValueError):
    """Training data failed validation; the message names the file (or source) and the field."""


def leading_finite(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Length of the leading finite block of each row, and whether only NaN follows it.

    Parameters
    ----------
    y : numpy.ndarray
        Responses, shape (n, m) (a 1-D array is one row; a scalar is one row of one point).

    Returns
    -------
    k : numpy.ndarray of int, shape (n,)
        Number of leading finite values of each row.
    nan_tail : numpy.ndarray of bool, shape (n,)
        True where every value after the first ``k`` is NaN: a row ``[finite] * k + [nan] * (m - k)``
        (also for ``k = m``); an interior NaN (a finite value after the first NaN) or any +-inf gives False.
    """
    y = np.asarray(y, dtype=float)
    y = y.reshape(-1, y.shape[-1]) if y.ndim else y.reshape(1, 1)
    m = y.shape[1]
    fin = np.isfinite(y)
    k = np.where(fin.all(axis=1), m, np.argmin(fin, axis=1))
    after = np.arange(m)[None, :] >= k[:, None]
    nan_tail = np.all(~after | np.isnan(y), axis=1)
    return k.astype(int), nan_tail


def diameter_um_from_radius(radius_dpd: float) -> float:
    """Bubble diameter of a DPD radius, with the default unit system (radius 4.2 -> 2.1 um).

    Parameters
    ----------
    radius_dpd : float
        Bubble radius [DPD length].

    Returns
    -------
    float
        Bubble diameter [um].
    """
    return float(radius_dpd) * UM_PER_RADIUS_DPD


def _rows(values, n: int) -> np.ndarray:
    """``values`` as n rows of floats; an empty selection of a 2-D array keeps its number of points."""
    a = np.asarray(values, dtype=float)
    return a if a.ndim == 2 and a.shape[0] == n else a.reshape(n, -1)


@dataclass
class TrainingSet:
    """Curves of one loading protocol and (normally) one diameter, in the surrogate's orientation.

    Parameters
    ----------
    setup : str
        Loading protocol, one of :data:`bubblecal.data.names.LOADING_PROTOCOLS`.
    params : array_like, shape (n, 6)
        Shell parameters (ka, kb, b1, b2, a3, a4) per curve [DPD units; b1..a4 dimensionless].
    radius_dpd : array_like, shape (n,)
        Bubble radius per curve [DPD length].
    x : array_like, shape (n, m)
        Loading coordinate: displacement [DPD length] (compression) or force [DPD force] (indentation).
    y : array_like, shape (n, m)
        Response: force [DPD force] (compression) or depth [DPD length] (indentation); NaN after the
        failure point of a failure-truncated prefix.
    curve_id : array_like of str, shape (n,)
        Identifier of each curve (e.g. ``file:line`` or the campaign record id).
    source : str
        Where the data came from (file name, store, synthetic recipe).
    status : array_like of str, shape (n,), optional
        Campaign-store status per curve (:data:`bubblecal.data.names.RECORD_STATUSES`); None means all ``'ok'``.
    extra : dict
        Further per-curve arrays of length n (kept aligned by :meth:`subset`).

    Raises
    ------
    DatasetError
        For an unknown ``setup`` or ``x``/``y`` of different shapes.
    """

    setup: str
    params: np.ndarray
    radius_dpd: np.ndarray
    x: np.ndarray
    y: np.ndarray
    curve_id: np.ndarray
    source: str = ""
    status: np.ndarray | None = None
    extra: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.setup not in LOADING_PROTOCOLS:
            raise DatasetError(f"{self.source}: setup must be one of {LOADING_PROTOCOLS}, got {self.setup!r}")
        self.params = np.asarray(self.params, dtype=float).reshape(-1, len(SHELL_PARAMETERS))
        n = self.params.shape[0]
        self.radius_dpd = np.asarray(self.radius_dpd, dtype=float).reshape(n)
        self.x, self.y = _rows(self.x, n), _rows(self.y, n)
        if self.x.shape != self.y.shape:
            raise DatasetError(f"{self.source}: x and y shapes differ: {self.x.shape} vs {self.y.shape}")
        self.curve_id = np.asarray(self.curve_id).astype(str).reshape(n)
        if self.status is None:
            self.status = np.full(n, "ok")
        self.status = np.asarray(self.status).astype(str).reshape(n)

    @property
    def n_curves(self) -> int:
        """Number of curves n."""
        return int(self.params.shape[0])

    @property
    def n_points(self) -> int:
        """Number of load points m per curve (finite or not)."""
        return int(self.x.shape[1])

    @property
    def diameter_um(self) -> float:
        """Bubble diameter [um] from the median finite radius (NaN when there is none)."""
        r = self.radius_dpd[np.isfinite(self.radius_dpd)]
        return diameter_um_from_radius(np.median(r)) if r.size else float("nan")

    @property
    def x_name(self) -> str:
        """Name of the loading coordinate (:data:`bubblecal.surrogates.axes.X_INFO`)."""
        return X_INFO[self.setup][0]

    @property
    def y_name(self) -> str:
        """Name of the response (:data:`bubblecal.surrogates.axes.Y_INFO`)."""
        return Y_INFO[self.setup][0]

    def subset(self, mask_or_index) -> TrainingSet:
        """The curves selected by a boolean mask or an index array (every per-curve array, ``extra`` included).

        Parameters
        ----------
        mask_or_index : array_like
            Boolean mask (n,) or curve indices.

        Returns
        -------
        TrainingSet
            The selected curves (same source).
        """
        idx = np.asarray(mask_or_index)
        return replace(self, params=self.params[idx], radius_dpd=self.radius_dpd[idx], x=self.x[idx],
                       y=self.y[idx], curve_id=self.curve_id[idx], status=self.status[idx],
                       extra={k: v[idx] for k, v in self.extra.items()})

    def data_hash(self) -> str:
        """sha256 (hex) of setup, parameters, radius, x and y (float64, C order): identifies the data."""
        h = hashlib.sha256()
        h.update(self.setup.encode())
        for arr in (self.params, self.radius_dpd, self.x, self.y):
            h.update(np.ascontiguousarray(arr, dtype="<f8").tobytes())
        return h.hexdigest()

    def point_mask(self) -> np.ndarray:
        """(n, m) True where the point is usable: finite x and finite y (NaN tails of truncated curves are not)."""
        return np.isfinite(self.x) & np.isfinite(self.y)

    @property
    def n_valid_points(self) -> int:
        """Number of usable (finite) points over all curves."""
        return int(self.point_mask().sum())

    def points(self):
        """Pointwise arrays of the finite points only, curve by curve (row-major order).

        Returns
        -------
        u : numpy.ndarray, shape (p, 7)
            Network inputs (ka, kb, b1, b2, a3, a4, x) [DPD units]; p = :attr:`n_valid_points`.
        y : numpy.ndarray, shape (p,)
            Targets [DPD force (compression) or DPD length (indentation)].
        curve : numpy.ndarray of int, shape (p,)
            Index of the curve of each point.
        """
        n, m = self.x.shape
        mask = self.point_mask().reshape(-1)
        u = np.concatenate([np.repeat(self.params, m, axis=0), self.x.reshape(-1, 1)], axis=1)
        return u[mask], self.y.reshape(-1)[mask], np.repeat(np.arange(n), m)[mask]

    @property
    def diameters_um(self) -> np.ndarray:
        """Bubble diameter of each curve [um] (from its radius, default unit system)."""
        return self.radius_dpd * UM_PER_RADIUS_DPD

    def network_points(self, inputs: str = "raw", log_inputs: tuple[str, ...] = ()):
        """Pointwise network inputs and targets of the finite points (:mod:`bubblecal.surrogates.features`).

        Parameters
        ----------
        inputs : {'raw', 'diameter'}
            Input kind: ``raw`` gives :meth:`points` (target = response); ``diameter`` appends each curve's
            diameter [um] to the inputs and divides the response by its size scale.
        log_inputs : tuple of str
            Shell parameters entered as natural logarithms (:data:`~bubblecal.surrogates.LOG_INPUT_CHOICES`).

        Returns
        -------
        u : numpy.ndarray, shape (p, 7 or 8)
            Network inputs [DPD units; diameter in um].
        target : numpy.ndarray, shape (p,)
            Network targets (response over ``scale``).
        curve : numpy.ndarray of int, shape (p,)
            Index of the curve of each point.
        scale : numpy.ndarray, shape (p,)
            Response scale of each point (1 for ``raw``).

        Raises
        ------
        ValueError
            For an unknown input kind.
        """
        n, m = self.x.shape
        mask = self.point_mask().reshape(-1)
        d = np.repeat(self.diameters_um, m)
        p = np.repeat(self.params, m, axis=0)
        u = network_inputs(inputs, p, self.x.reshape(-1), d if inputs == "diameter" else None, log_inputs=log_inputs)
        scale = np.broadcast_to(response_scale(inputs, self.setup, p, d), (n * m,))
        return u[mask], self.y.reshape(-1)[mask] / scale[mask], np.repeat(np.arange(n), m)[mask], scale[mask]

    def truncation_summary(self) -> dict:
        """Counts of curves with a NaN tail (failure-truncated prefixes) and of points, overall and per status.

        Returns
        -------
        dict
            ``{"n_curves", "n_points" (finite points), "n_prefix_curves", "n_prefix_points",
            "prefix_by_status": {status: {"curves", "points"}}}``; a *prefix curve* is a curve with at
            least one non-finite response (after ``filter_curves`` only the kept prefixes have one).
        """
        valid = self.point_mask()
        per_curve = valid.sum(axis=1)
        trunc = per_curve < self.n_points
        by_status: dict[str, dict[str, int]] = {}
        for st in np.unique(self.status[trunc]):
            sel = trunc & (self.status == st)
            by_status[str(st)] = {"curves": int(sel.sum()), "points": int(per_curve[sel].sum())}
        return {"n_curves": self.n_curves, "n_points": int(per_curve.sum()), "n_prefix_curves": int(trunc.sum()),
                "n_prefix_points": int(per_curve[trunc].sum()), "prefix_by_status": by_status}

    def param_ranges(self) -> dict[str, tuple[float, float]]:
        """(min, max) of each shell parameter over the curves, keyed by name [DPD units]."""
        return {k: (float(self.params[:, j].min()), float(self.params[:, j].max()))
                for j, k in enumerate(SHELL_PARAMETERS)}

    def x_range(self) -> tuple[float, float]:
        """(min, max) of the loading coordinate over the usable points (NaN when there are none)."""
        x = self.x[self.point_mask()]
        return (float(x.min()), float(x.max())) if x.size else (float("nan"), float("nan"))

    def check_trainable(self, min_curves: int = 1, several_sizes: bool = False) -> None:
        """Check that the data can be standardised and trained on.

        ``params`` must be finite; the response ``y`` of each curve must be finite on a leading prefix of at
        least one point and NaN after it (a failure-truncated prefix): an interior NaN or an infinity is an
        error; ``x`` must be finite wherever ``y`` is; no parameter, loading coordinate or response may have
        zero variance; all curves must share one radius (one surrogate per diameter) unless ``several_sizes``
        (a network over the diameter, which needs at least two).

        Parameters
        ----------
        min_curves : int
            Fewest curves accepted.
        several_sizes : bool
            The data train one network over the sizes (inputs ``diameter``).

        Raises
        ------
        DatasetError
            Naming the source and the field that fails.
        """
        src = self.source or "<training set>"
        if self.n_curves < min_curves:
            raise DatasetError(f"{src}: {self.n_curves} curve(s) after filtering; at least {min_curves} needed")
        if not np.all(np.isfinite(self.params)):
            raise DatasetError(f"{src}: field 'params' holds non-finite values (run filter_curves first)")
        k, nan_tail = leading_finite(self.y)
        bad = np.flatnonzero(~nan_tail)
        if bad.size:
            raise DatasetError(f"{src}: field 'y' ({self.y_name}) of curve {self.curve_id[bad[0]]!r} (and "
                               f"{bad.size - 1} more) holds an interior NaN or an infinity; only a trailing NaN "
                               "block (failure-truncated prefix) is allowed (run filter_curves first)")
        empty = np.flatnonzero(k == 0)
        if empty.size:
            raise DatasetError(f"{src}: field 'y' ({self.y_name}) of curve {self.curve_id[empty[0]]!r} (and "
                               f"{empty.size - 1} more) has no finite point (run filter_curves first)")
        x_bad = np.isfinite(self.y) & ~np.isfinite(self.x)
        if x_bad.any():
            i = int(np.flatnonzero(x_bad.any(axis=1))[0])
            raise DatasetError(f"{src}: field 'x' ({self.x_name}) of curve {self.curve_id[i]!r} holds non-finite "
                               "values where the response is finite (run filter_curves first)")
        for j, name in enumerate(SHELL_PARAMETERS):
            col = self.params[:, j]
            if np.ptp(col) == 0:
                raise DatasetError(f"{src}: parameter '{name}' has zero variance (every value {col[0]:g}); "
                                   "it cannot be standardised - drop it from the design or vary it")
        valid = self.point_mask()
        if np.ptp(self.x[valid]) == 0:
            raise DatasetError(f"{src}: loading coordinate '{self.x_name}' has zero variance")
        if np.ptp(self.y[valid]) == 0:
            raise DatasetError(f"{src}: response '{self.y_name}' has zero variance")
        radii = np.unique(np.round(self.radius_dpd, 9))
        if several_sizes and radii.size < 2:
            raise DatasetError(f"{src}: field 'radius_dpd' holds one radius ({radii[0]:g}); a network over the "
                               "diameter needs curves at several sizes (train it per diameter instead)")
        if not several_sizes and radii.size > 1:
            raise DatasetError(f"{src}: field 'radius_dpd' holds several radii {radii[:5].tolist()}; train one "
                               "surrogate per diameter, or one over the sizes (inputs 'diameter')")


def concat_training_sets(sets: list[TrainingSet]) -> TrainingSet:
    """One training set of the curves of several (e.g. a design and a denser slice of its box), in order.

    Parameters
    ----------
    sets : list of TrainingSet
        At least one; all of one protocol and with the same number of load points per curve.

    Returns
    -------
    TrainingSet
        Every curve of every set; ``source`` joins the sources with ``" + "``; ``extra`` keeps the keys every set
        has.  A single set is returned as it is.

    Raises
    ------
    DatasetError
        If ``sets`` is empty, the protocols differ, the point counts differ, or a curve id occurs twice.
    """
    if not sets:
        raise DatasetError("concat_training_sets: no training set given")
    if len(sets) == 1:
        return sets[0]
    first = sets[0]
    for ts in sets[1:]:
        if ts.setup != first.setup:
            raise DatasetError(f"{ts.source}: holds {ts.setup} data, {first.source} holds {first.setup} data")
        if ts.n_points != first.n_points:
            raise DatasetError(f"{ts.source}: {ts.n_points} load points per curve, {first.source} has "
                               f"{first.n_points}; give sets of one loading grid length")
    ids = np.concatenate([ts.curve_id for ts in sets])
    uniq, counts = np.unique(ids, return_counts=True)
    if (counts > 1).any():
        raise DatasetError(f"{' + '.join(ts.source for ts in sets)}: curve id {str(uniq[counts > 1][0])!r} occurs "
                           f"{int(counts[counts > 1][0])} times (the same store given twice?)")
    keys = set(first.extra).intersection(*(ts.extra for ts in sets[1:]))
    return TrainingSet(setup=first.setup, params=np.concatenate([ts.params for ts in sets]),
                       radius_dpd=np.concatenate([ts.radius_dpd for ts in sets]),
                       x=np.concatenate([ts.x for ts in sets]), y=np.concatenate([ts.y for ts in sets]),
                       curve_id=ids, source=" + ".join(ts.source for ts in sets),
                       status=np.concatenate([ts.status for ts in sets]),
                       extra={k: np.concatenate([np.asarray(ts.extra[k]) for ts in sets]) for k in sorted(keys)})
