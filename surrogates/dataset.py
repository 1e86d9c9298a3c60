"""Training data I/O for the mechanical surrogates: the published row layout and our campaign store.

A :class:`TrainingSet` holds one curve per row in the *surrogate's* orientation (DPD units):

* compression: ``x`` = imposed total displacement [DPD length], ``y`` = force [DPD force];
* indentation: ``x`` = applied force [DPD force], ``y`` = indentation depth [DPD length].

Published layout (``../shared/reference/README.md`` section (c)): 38 numbers per row (comma
separated with a header, or whitespace separated ``.dat`` without one): ``Yt_Pa, ka, kb, b1, b2,
a3, a4, radius_dpd``, 15 loading coordinates, 15 responses. For indentation files the first block
is the *axial diameter* at each force and the second the force; the reader converts to
displacement = initial diameter - value, with initial diameter = 2 median(radius_dpd column).

Filtering (:func:`filter_curves`) removes, with counts reported per reason: rows with non-finite
numbers; store records whose status is not ``'ok'``; rupture by *trailing zeros* (the last raw
response - force for compression, axial diameter for indentation - at most ``zero_frac`` of the
curve's largest magnitude); rupture by a *drop*: the response must grow along the loading path, and
a curve is dropped when it falls below its running maximum by more than ``max_rel_drop`` of the
curve's largest magnitude.

Failure-truncated prefixes (``filter_curves(..., keep_failed_prefix=True)``): a store record with
status ``'ruptured'`` or ``'failed'`` holds a finite response up to the load point where the shell
broke and NaN after it (e.g. at 3.4 um, k_b < ~940 breaks at pole forces of 1,300-5,600 DPD force
on the 0-6,000 grid). Such a curve keeps its finite prefix *minus its last finite point* (the point
just before failure is unreliable) when at least ``min_prefix_points`` points (x = 0 included)
remain; the dropped tail is NaN in ``y`` (``x`` keeps its grid). Everything downstream is pointwise
and accepts such NaN tails: :meth:`TrainingSet.points` returns finite points only,
:meth:`TrainingSet.check_trainable` accepts a trailing NaN block in ``y`` and nothing else, and the
holdout scores of :mod:`bubblecal.surrogates.sweep` use the finite points of each curve.
"""

from __future__ import annotations

import hashlib
import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from bubblecal.data import DEFAULT_UNITS, LOADING_PROTOCOLS, SHELL_PARAMETERS

__all__ = [
    "DatasetError", "TrainingSet", "FilterReport", "read_published",
    "write_published", "read_store_dataset", "read_dataset", "filter_curves", "diameter_um_from_radius",
    "X_INFO", "Y_INFO", "PREFIX_STATUSES", "leading_finite",
]

N_META = 8  # Yt_Pa, ka, kb, b1, b2, a3, a4, radius_dpd
PUBLISHED_POINTS = 15

#: store statuses whose finite prefix filter_curves(keep_failed_prefix=True) can keep
PREFIX_STATUSES: tuple[str, ...] = ("ruptured", "failed")

#: (name, units) of the loading coordinate and the response, per setup.
X_INFO = {"compression": ("displacement", "DPD length"), "indentation": ("force", "DPD force")}
Y_INFO = {"compression": ("force", "DPD force"), "indentation": ("displacement", "DPD length")}


class DatasetError(ValueError):
    """Training data failed validation; the message names the file (or source) and the field."""


def leading_finite(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row of ``y`` (n, m): (k = number of leading finite values, True where every value after them is NaN).

    A row of the form ``[finite] * k + [nan] * (m - k)`` has ``nan_tail`` True (also for k = m);
    an interior NaN (a finite value after the first NaN) or any +-inf gives False.
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
    """DPD radius -> bubble diameter [um] (radius 4.2 -> 2.1 um)."""
    return float(radius_dpd) * 2.0 * DEFAULT_UNITS.length_m * 1e6


@dataclass
class TrainingSet:
    """Curves of one setup and (normally) one diameter, in the surrogate's orientation."""

    setup: str
    params: np.ndarray  # (n, 6) ka, kb, b1, b2, a3, a4
    radius_dpd: np.ndarray  # (n,)
    x: np.ndarray  # (n, m)
    y: np.ndarray  # (n, m)
    curve_id: np.ndarray  # (n,) str
    source: str = ""
    status: np.ndarray | None = None  # (n,) str; None means all 'ok'
    extra: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.setup not in LOADING_PROTOCOLS:
            raise DatasetError(f"{self.source}: setup must be one of {LOADING_PROTOCOLS}, got {self.setup!r}")
        self.params = np.asarray(self.params, dtype=float).reshape(-1, len(SHELL_PARAMETERS))
        n = self.params.shape[0]
        self.radius_dpd = np.asarray(self.radius_dpd, dtype=float).reshape(n)
        self.x = np.asarray(self.x, dtype=float).reshape(n, -1)
        self.y = np.asarray(self.y, dtype=float).reshape(n, -1)
        if self.x.shape != self.y.shape:
            raise DatasetError(f"{self.source}: x and y shapes differ: {self.x.shape} vs {self.y.shape}")
        self.curve_id = np.asarray(self.curve_id).astype(str).reshape(n)
        if self.status is None:
            self.status = np.full(n, "ok")
        self.status = np.asarray(self.status).astype(str).reshape(n)

    # -- basic properties ------------------------------------------------------------------------
    @property
    def n_curves(self) -> int:
        return int(self.params.shape[0])

    @property
    def n_points(self) -> int:
        return int(self.x.shape[1])

    @property
    def diameter_um(self) -> float:
        """Bubble diameter [um] from the median radius (NaN when empty)."""
        r = self.radius_dpd[np.isfinite(self.radius_dpd)]
        return diameter_um_from_radius(np.median(r)) if r.size else float("nan")

    @property
    def x_name(self) -> str:
        return X_INFO[self.setup][0]

    @property
    def y_name(self) -> str:
        return Y_INFO[self.setup][0]

    def subset(self, mask_or_index) -> TrainingSet:
        idx = np.asarray(mask_or_index)
        return replace(self, params=self.params[idx], radius_dpd=self.radius_dpd[idx], x=self.x[idx],
                       y=self.y[idx], curve_id=self.curve_id[idx], status=self.status[idx],
                       extra={k: v[idx] for k, v in self.extra.items()})

    def data_hash(self) -> str:
        """sha256 of setup, parameters, radius, x and y (float64, C order): identifies the data."""
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
        """Pointwise arrays of the finite points only (row-major order, curve by curve):
        inputs (p, 7) = (params, x), targets (p,), curve index (p,); p = :attr:`n_valid_points`.

        Units as the set: x and y in DPD units (see the module docstring).
        """
        n, m = self.x.shape
        mask = self.point_mask().reshape(-1)
        u = np.concatenate([np.repeat(self.params, m, axis=0), self.x.reshape(-1, 1)], axis=1)
        return u[mask], self.y.reshape(-1)[mask], np.repeat(np.arange(n), m)[mask]

    def truncation_summary(self) -> dict:
        """Counts of curves with a NaN tail (failure-truncated prefixes) and of points, overall and per status.

        ``{"n_curves", "n_points" (finite points), "n_prefix_curves", "n_prefix_points",
        "prefix_by_status": {status: {"curves", "points"}}}``; a *prefix curve* is a curve with at
        least one non-finite response (after :func:`filter_curves` only the kept prefixes have one).
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
        return {k: (float(self.params[:, j].min()), float(self.params[:, j].max()))
                for j, k in enumerate(SHELL_PARAMETERS)}

    def x_range(self) -> tuple[float, float]:
        """(min, max) of the loading coordinate over the usable points (NaN when there are none)."""
        x = self.x[self.point_mask()]
        return (float(x.min()), float(x.max())) if x.size else (float("nan"), float("nan"))

    def check_trainable(self, min_curves: int = 1) -> None:
        """Raise :class:`DatasetError` naming the file and field for data that cannot be standardised/trained.

        ``params`` must be finite; the response ``y`` of each curve must be finite on a leading prefix
        of at least one point and NaN after it (a failure-truncated prefix, see :func:`filter_curves`):
        an interior NaN or an infinity is an error; ``x`` must be finite wherever ``y`` is.
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
        if radii.size > 1:
            raise DatasetError(f"{src}: field 'radius_dpd' holds several radii {radii[:5].tolist()}; train one "
                               "surrogate per diameter")


@dataclass
class FilterReport:
    """Counts of curves removed per reason (a curve is counted under the first reason it meets).

    With ``keep_failed_prefix``, ``prefix`` gives per store status (ruptured, failed) the prefix
    curves kept and the points they contribute (x = 0 included), and those rejected: ``invalid``
    (no NaN tail, interior NaN, infinity), ``too_short`` (< ``min_prefix_points`` after dropping
    the last finite point) and ``quality`` (removed by the rupture checks on the kept prefix).
    """

    source: str
    n_in: int
    n_kept: int
    counts: dict[str, int]
    dropped: dict[str, list[str]]
    settings: dict
    #: curves dropped for reason 'status', split by their store status (e.g. ruptured, invalid, failed)
    status_counts: dict[str, int] = field(default_factory=dict)
    #: per status: {"kept", "points", "invalid", "too_short", "quality"} of failure-truncated prefixes
    prefix: dict[str, dict[str, int]] = field(default_factory=dict)
    #: usable points of the kept curves
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
        return {"source": self.source, "n_in": self.n_in, "n_kept": self.n_kept, "n_points_kept": self.n_points_kept,
                "counts": dict(self.counts), "status_counts": dict(self.status_counts),
                "n_prefix_curves": self.n_prefix_curves, "n_prefix_points": self.n_prefix_points,
                "prefix": {k: dict(v) for k, v in self.prefix.items()}, "settings": dict(self.settings)}

    def __str__(self) -> str:
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


# ----------------------------------------------------------------------------------------------
# published layout
# ----------------------------------------------------------------------------------------------
def _parse_rows(path: Path) -> tuple[list[str] | None, list[tuple[int, list[str]]]]:
    """Return (header or None, [(line number, tokens)]) of a comma- or whitespace-separated file."""
    text = path.read_text()
    header = None
    rows = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        tokens = [t for t in re.split(r"[,\s]+", s) if t]
        if header is None and not rows and any(re.match(r"^[A-Za-z_]", t) and t.lower() not in
                                               ("nan", "inf", "-inf", "+inf", "infinity") for t in tokens):
            header = tokens
            continue
        rows.append((lineno, tokens))
    return header, rows


def _infer_setup(header: list[str] | None, path: Path) -> str:
    names = " ".join(header or []).lower() + " " + path.name.lower()
    if "axial" in names or "indent" in names or "samples_all" in names:
        return "indentation"
    if "disp" in names or "compress" in names or "f_delta" in names:
        return "compression"
    raise DatasetError(f"{path}: cannot tell compression from indentation from the header/file name; "
                       "pass setup='compression' or 'indentation'")


def read_published(path: str | Path, setup: str | None = None, n_points: int | str = PUBLISHED_POINTS) -> TrainingSet:
    """Read a table in the published row layout (CSV with header or whitespace ``.dat``).

    ``n_points`` is the number of loading points per row (15 in the published layout: 38 columns);
    ``'auto'`` accepts any ``8 + 2 m`` columns (e.g. the 12-column CI smoke fixture). Every row
    must have the same, expected number of columns; a mismatch raises :class:`DatasetError`
    naming the file, the line and the count. Non-finite numbers are kept here and counted by
    :func:`filter_curves`.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"training data file not found: {path}")
    header, rows = _parse_rows(path)
    if not rows:
        raise DatasetError(f"{path}: no data rows")
    if n_points == "auto":
        ncol = len(rows[0][1])
        if ncol < N_META + 2 or (ncol - N_META) % 2:
            raise DatasetError(f"{path}: line {rows[0][0]}: {ncol} columns; the published layout needs "
                               f"{N_META} + 2 m columns")
        m = (ncol - N_META) // 2
    else:
        m = int(n_points)
    expected = N_META + 2 * m
    if header is not None and len(header) != expected:
        raise DatasetError(f"{path}: header has {len(header)} columns, expected {expected} "
                           f"(Yt_Pa, ka..a4, radius_dpd, {m} loading coordinates, {m} responses)")
    data = np.empty((len(rows), expected))
    for i, (lineno, tokens) in enumerate(rows):
        if len(tokens) != expected:
            raise DatasetError(f"{path}: line {lineno}: {len(tokens)} columns, expected {expected} "
                               f"(Yt_Pa, ka..a4, radius_dpd, {m} loading coordinates, {m} responses)")
        try:
            data[i] = [float(t) for t in tokens]
        except ValueError as exc:
            raise DatasetError(f"{path}: line {lineno}: not a number ({exc})") from exc
    setup = setup or _infer_setup(header, path)
    if setup not in LOADING_PROTOCOLS:
        raise DatasetError(f"{path}: setup must be one of {LOADING_PROTOCOLS}, got {setup!r}")
    params = data[:, 1:7]
    radius = data[:, 7]
    first, second = data[:, N_META:N_META + m], data[:, N_META + m:]
    extra = {"yt_pa": data[:, 0]}
    if setup == "compression":
        x, y = first, second
    else:
        finite_r = radius[np.isfinite(radius)]
        d0 = 2.0 * float(np.median(finite_r)) if finite_r.size else float("nan")
        x, y = second, d0 - first
        extra["initial_diameter_dpd"] = np.full(len(rows), d0)
    curve_id = np.array([f"{path.stem}:{lineno}" for lineno, _ in rows])
    return TrainingSet(setup=setup, params=params, radius_dpd=radius, x=x, y=y, curve_id=curve_id,
                       source=str(path), extra=extra)


def write_published(ts: TrainingSet, path: str | Path, units=DEFAULT_UNITS) -> Path:
    """Write ``ts`` in the published row layout (CSV with header; values as Python repr).

    Indentation curves are written back as axial diameters: value = initial diameter - y with
    initial diameter = 2 median(radius_dpd) (the reader's convention), so a round trip is exact
    up to float round-off.
    """
    path = Path(path)
    m = ts.n_points
    if ts.setup == "compression":
        cols = [f"disp_dpd_{i:02d}" for i in range(1, m + 1)] + [f"force_dpd_{i:02d}" for i in range(1, m + 1)]
        first, second = ts.x, ts.y
    else:
        cols = ([f"axial_diameter_dpd_{i:02d}" for i in range(1, m + 1)]
                + [f"force_dpd_{i:02d}" for i in range(1, m + 1)])
        d0 = 2.0 * float(np.median(ts.radius_dpd))
        first, second = d0 - ts.y, ts.x
    header = ["Yt_Pa", "ka_dpd", "kb_dpd", "b1", "b2", "a3", "a4", "radius_dpd"] + cols
    yt = units.ka_to_yt(ts.params[:, 0])
    table = np.column_stack([yt, ts.params, ts.radius_dpd, first, second])
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w") as fh:
        fh.write(",".join(header) + "\n")
        for row in table:
            fh.write(",".join(repr(float(v)) for v in row) + "\n")
    return path


# ----------------------------------------------------------------------------------------------
# campaign store
# ----------------------------------------------------------------------------------------------
def read_store_dataset(path: str | Path, setup: str | None = None) -> TrainingSet:
    """Read every record of a campaign store (:mod:`bubblecal.data.store`) as a TrainingSet.

    All statuses are returned (``status`` column); :func:`filter_curves` keeps ``'ok'`` only, plus the
    failure-truncated prefixes of ``'ruptured'``/``'failed'`` records with ``keep_failed_prefix=True``
    (their responses are NaN after the failure point).
    Records of one setup only (``setup`` selects when the store holds several). Curves must all
    have the same number of points (the published protocol); otherwise DatasetError.
    """
    from bubblecal.data import CampaignStore

    store = CampaignStore(path)
    records = store.read()
    if setup is not None:
        records = [r for r in records if r["setup"] == setup]
    if not records:
        raise DatasetError(f"{path}: no records{' for setup ' + setup if setup else ''}")
    setups = {r["setup"] for r in records}
    if len(setups) > 1:
        raise DatasetError(f"{path}: records of several setups {sorted(setups)}; pass setup=")
    lengths = {len(r["x"]) for r in records if r["status"] == "ok"} or {len(r["x"]) for r in records}
    if len(lengths) > 1:
        raise DatasetError(f"{path}: field 'x' has different lengths across 'ok' records: {sorted(lengths)}")
    m = lengths.pop()

    def _arr(values):
        a = np.full(m, np.nan)
        v = np.asarray(values, dtype=float)
        if v.size == m:
            a[:] = v
        return a

    params = np.array([[r["params"][k] for k in SHELL_PARAMETERS] for r in records], dtype=float)
    return TrainingSet(
        setup=setups.pop(), params=params, radius_dpd=[r["radius_dpd"] for r in records],
        x=np.array([_arr(r["x"]) for r in records]), y=np.array([_arr(r["y"]) for r in records]),
        curve_id=[r["curve_id"] for r in records], status=[r["status"] for r in records], source=str(path),
        extra={"seed": np.array([r.get("seed", -1) for r in records]),
               "tier": np.array([str(r.get("tier", "")) for r in records])},
    )


def read_dataset(path: str | Path, setup: str | None = None, n_points: int | str = PUBLISHED_POINTS) -> TrainingSet:
    """Read a campaign store (directory, ``.jsonl`` or compressed ``.jsonl.gz``) or a published-layout table."""
    path = Path(path)
    if path.is_dir() or path.suffix == ".jsonl" or path.name.endswith(".jsonl.gz"):
        return read_store_dataset(path, setup=setup)
    return read_published(path, setup=setup, n_points=n_points)


# ----------------------------------------------------------------------------------------------
# filtering
# ----------------------------------------------------------------------------------------------
def _raw_response(ts: TrainingSet) -> np.ndarray:
    """The stored response before orientation: force (compression) or axial diameter (indentation)."""
    if ts.setup == "compression":
        return ts.y
    d0 = 2.0 * ts.radius_dpd[:, None]
    return d0 - ts.y


def filter_curves(ts: TrainingSet, zero_frac: float = 0.01, max_rel_drop: float = 0.10,
                  statuses: Sequence[str] = ("ok",), keep_failed_prefix: bool = False, min_prefix_points: int = 5,
                  prefix_statuses: Sequence[str] = PREFIX_STATUSES) -> tuple[TrainingSet, FilterReport]:
    """Drop unusable curves (or keep failure-truncated prefixes); returns (kept set, report with counts per reason).

    Reasons, checked in order: ``status`` (store status not in ``statuses``, and not a prefix
    candidate; the report's ``status_counts`` splits it by status: ruptured, invalid = non-finite
    curve, failed, unstable, ...), ``non_finite`` (any non-finite parameter, radius, x or - except
    for prefix candidates - y), [``prefix_invalid``, ``prefix_too_short``: prefix candidates, see
    below], ``rupture_trailing_zero`` (last kept raw response <= ``zero_frac`` x the curve's
    largest |raw response|), ``rupture_drop`` (the response falls below its running maximum by
    more than ``max_rel_drop`` x the curve's largest |response|).

    ``keep_failed_prefix`` (default False, the historical behaviour): records whose status is in
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
