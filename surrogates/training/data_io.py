"""Reading and writing training data: the published row layout and the campaign store.

Published layout (docs/data-formats.md): :data:`N_META` + 2 m numbers per row, comma separated with a
header or whitespace separated ``.dat`` without one: ``Yt_Pa, ka, kb, b1, b2, a3, a4, radius_dpd``
(:data:`PUBLISHED_META_COLUMNS`), m loading coordinates, m responses (m = :data:`PUBLISHED_POINTS` = 15 in the
published tables). For indentation files the first block is the *axial diameter* at each force and the
second the force; the reader converts to depth = initial diameter - axial diameter, with initial diameter
= 2 median(radius_dpd column), so that every :class:`~bubblecal.surrogates.training.TrainingSet` is in the
surrogate's orientation (:mod:`bubblecal.surrogates.axes`).

Campaign stores (:mod:`bubblecal.data.store`) are read with every record and its status;
:func:`bubblecal.surrogates.training.filter_curves` decides what is kept.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from bubblecal.data import DEFAULT_UNITS, LOADING_PROTOCOLS, SHELL_PARAMETERS
from bubblecal.surrogates.training.dataset import DatasetError, TrainingSet

__all__ = ["N_META", "PUBLISHED_POINTS", "PUBLISHED_META_COLUMNS", "read_published", "write_published",
           "read_store_dataset", "read_dataset"]

#: Leading columns of a published row, in order (the written header; the reader accepts any header names).
PUBLISHED_META_COLUMNS: tuple[str, ...] = ("Yt_Pa", "ka_dpd", "kb_dpd", "b1", "b2", "a3", "a4", "radius_dpd")
#: Number of leading (non-curve) columns of a published row.
N_META = len(PUBLISHED_META_COLUMNS)
#: Load points per curve in the published tables (38 columns).
PUBLISHED_POINTS = 15


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
    """The loading protocol named by the header or the file name."""
    names = " ".join(header or []).lower() + " " + path.name.lower()
    if "axial" in names or "indent" in names or "samples_all" in names:
        return "indentation"
    if "disp" in names or "compress" in names or "f_delta" in names:
        return "compression"
    raise DatasetError(f"{path}: cannot tell compression from indentation from the header/file name; "
                       "pass setup='compression' or 'indentation'")


def read_published(path: str | Path, setup: str | None = None, n_points: int | str = PUBLISHED_POINTS) -> TrainingSet:
    """Read a table in the published row layout (CSV with header or whitespace ``.dat``).

    Parameters
    ----------
    path : str or Path
        The table.
    setup : {'compression', 'indentation'}, optional
        Loading protocol; default: inferred from the header or the file name.
    n_points : int or 'auto'
        Load points m per row (15 in the published layout: 38 columns); ``'auto'`` accepts any
        ``8 + 2 m`` columns (e.g. the 12-column CI smoke fixture).

    Returns
    -------
    TrainingSet
        One curve per row, in DPD units; ``extra`` holds ``yt_pa`` (Young's modulus column [Pa]) and, for
        indentation, ``initial_diameter_dpd`` [DPD length]. Non-finite numbers are kept here and counted by
        :func:`~bubblecal.surrogates.training.filter_curves`.

    Raises
    ------
    FileNotFoundError
        When ``path`` is not a file.
    DatasetError
        For no data rows, a row or header with an unexpected number of columns (naming the file, the line and
        the count), a token that is not a number, or a setup that cannot be told.
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

    Indentation curves are written back as axial diameters: value = initial diameter - y with initial
    diameter = 2 median(radius_dpd) (the reader's convention), so a round trip is exact up to float round-off.

    Parameters
    ----------
    ts : TrainingSet
        The curves (DPD units).
    path : str or Path
        Output file (parent folders are created).
    units : bubblecal.data.units.UnitSystem
        Converts ka [DPD 2-D modulus] to the ``Yt_Pa`` column [Pa].

    Returns
    -------
    Path
        ``path``.
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
    header = list(PUBLISHED_META_COLUMNS) + cols
    yt = units.ka_to_yt(ts.params[:, 0])
    table = np.column_stack([yt, ts.params, ts.radius_dpd, first, second])
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w") as fh:
        fh.write(",".join(header) + "\n")
        for row in table:
            fh.write(",".join(repr(float(v)) for v in row) + "\n")
    return path



def read_store_dataset(path: str | Path, setup: str | None = None) -> TrainingSet:
    """Read every record of a campaign store (:mod:`bubblecal.data.store`) as a TrainingSet.

    All statuses are returned (``status`` column); ``filter_curves`` keeps ``'ok'`` only, plus the
    failure-truncated prefixes of ``'ruptured'``/``'failed'`` records with ``keep_failed_prefix=True``
    (their responses are NaN after the failure point).

    Parameters
    ----------
    path : str or Path
        Store directory, ``.jsonl`` or ``.jsonl.gz`` file.
    setup : {'compression', 'indentation'}, optional
        Selects the records of one loading protocol when the store holds several.

    Returns
    -------
    TrainingSet
        One curve per record (DPD units); a record whose arrays do not have the common length gets NaN
        curves. ``extra`` holds ``seed`` and ``tier`` per record.

    Raises
    ------
    DatasetError
        For no (matching) records, records of several setups without ``setup``, or ``'ok'`` records of
        different lengths.
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
    """Read a campaign store (directory, ``.jsonl`` or compressed ``.jsonl.gz``) or a published-layout table.

    Parameters
    ----------
    path : str or Path
        A store (:func:`read_store_dataset`) or a table (:func:`read_published`).
    setup : {'compression', 'indentation'}, optional
        Loading protocol (selects records in a store; overrides inference for a table).
    n_points : int or 'auto'
        Load points per row of a table (see :func:`read_published`).

    Returns
    -------
    TrainingSet
        Every curve, unfiltered (DPD units).

    Raises
    ------
    FileNotFoundError, DatasetError
        As the reader used.
    """
    path = Path(path)
    if path.is_dir() or path.suffix == ".jsonl" or path.name.endswith(".jsonl.gz"):
        return read_store_dataset(path, setup=setup)
    return read_published(path, setup=setup, n_points=n_points)

