"""Reading and validating a loading-curve CSV file (the user's curves and the shipped ones alike).

Every problem found is reported at once in one :class:`~bubblecal.data.DataError`, each naming the file,
the data row, the file line and the column. The file format is described in :func:`load_curve`
(docs/data-formats.md).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from bubblecal.data.curves import KINDS, LoadingCurve, SourceCurve, _check_kind_units, expected_columns
from bubblecal.data.errors import DataError
from bubblecal.data.plausibility import plausibility_problems
from bubblecal.data.units import DEFAULT_UNITS, UnitSystem

__all__ = ["RETAINED_COLUMN", "MIN_POINTS", "load_curve", "read_csv_rows", "separator_hint"]

#: Optional column of a physical-unit curve file: 1 if the row enters the likelihood, 0 if not.
RETAINED_COLUMN = "retained_in_inference"
#: Fewest (retained) points a curve may have.
MIN_POINTS = 3


def _parse_float(text: str) -> float | None:
    """``float(text)``, or None if ``text`` is not a number."""
    try:
        return float(text)
    except ValueError:
        return None


def read_csv_rows(path: Path) -> list[list[str]]:
    """The rows of a CSV file, UTF-8 with or without a byte-order mark (a BOM is dropped, never part of a name).

    Parameters
    ----------
    path : pathlib.Path
        The file.

    Returns
    -------
    list of list of str
        Every row's cells, comma-separated.

    Raises
    ------
    DataError
        The file is missing, a folder, unreadable or not UTF-8 text.
    """
    try:
        with open(path, newline="", encoding="utf-8-sig") as handle:
            return list(csv.reader(handle))
    except FileNotFoundError as exc:
        raise DataError(path, ["file not found"]) from exc
    except IsADirectoryError as exc:
        raise DataError(path, ["is a folder, not a CSV file"]) from exc
    except UnicodeDecodeError as exc:
        raise DataError(path, [f"not UTF-8 text (byte {exc.start}); save the file as UTF-8 CSV"]) from exc
    except (OSError, csv.Error) as exc:
        raise DataError(path, [f"cannot read file: {exc}"]) from exc


def separator_hint(header: list[str]) -> str:
    """A hint when a header row was written with another separator than the comma (else an empty string).

    Parameters
    ----------
    header : list of str
        The header cells as read with the comma separator.

    Returns
    -------
    str
        E.g. ``" (the header holds ';': the file seems semicolon-separated; use commas)"``.
    """
    if len(header) == 1:
        for sep, name in ((";", "semicolon"), ("\t", "tab"), ("|", "pipe")):
            if sep in header[0]:
                return (f" (the header holds {sep!r}: the file seems {name}-separated; columns must be separated "
                        "by commas)")
    return ""


def _read_table(path: Path, required: tuple[str, ...], optional: tuple[str, ...], label: str):
    """Read a headed CSV; return (columns dict name -> list[(file line, text)], problems)."""
    problems: list[str] = []
    rows = read_csv_rows(path)
    rows = [(i + 1, r) for i, r in enumerate(rows) if any(cell.strip() for cell in r)]
    if not rows:
        raise DataError(path, ["file is empty (expected a header row with columns " + ", ".join(required) + ")"])
    header_line, header = rows[0]
    header = [h.strip() for h in header]
    hint = separator_hint(header)
    if hint:
        raise DataError(path, [f"header (line {header_line}): {header[0]!r} is one column{hint}; {label} expects "
                               "columns " + ", ".join(required)])
    allowed = required + optional
    for name in header:
        if name not in allowed:
            problems.append(f"header (line {header_line}): unknown column {name!r}; {label} expects columns "
                            + ", ".join(required) + (f" (optional: {', '.join(optional)})" if optional else ""))
    for name in required:
        if name not in header:
            problems.append(
                f"header (line {header_line}): missing column {name!r} (found: {', '.join(header) or 'none'})"
            )
    if len(set(header)) != len(header):
        problems.append(f"header (line {header_line}): duplicate column names")
    if problems:
        raise DataError(path, problems)
    columns: dict[str, list[tuple[int, str]]] = {name: [] for name in header}
    for data_row, (line, cells) in enumerate(rows[1:], start=1):
        if len(cells) != len(header):
            problems.append(f"row {data_row} (line {line}): {len(cells)} cells, expected {len(header)}")
            continue
        for name, cell in zip(header, cells, strict=True):
            columns[name].append((line, cell.strip()))
    return columns, problems


def _numeric_column(name: str, cells: list[tuple[int, str]], problems: list[str], nonneg: bool = True) -> np.ndarray:
    """The cells of column ``name`` as floats (NaN where invalid); each invalid cell adds a problem."""
    values = np.full(len(cells), np.nan)
    for k, (line, text) in enumerate(cells):
        value = _parse_float(text)
        where = f"row {k + 1} (line {line}), column {name!r}"
        if value is None:
            problems.append(f"{where}: {text!r} is not a number")
        elif not math.isfinite(value):
            problems.append(f"{where}: {text} is not finite (NaN/inf are not allowed)")
        elif nonneg and value < 0:
            problems.append(f"{where}: negative value {value:g} (must be >= 0)")
        else:
            values[k] = value
    return values


def _check_increasing(name: str, values: np.ndarray, lines: list[int], problems: list[str]) -> None:
    """Add a problem for every finite value not larger than the finite value before it."""
    for k in range(1, values.size):
        if np.isfinite(values[k]) and np.isfinite(values[k - 1]) and values[k] <= values[k - 1]:
            problems.append(
                f"row {k + 1} (line {lines[k]}), column {name!r}: {values[k]:g} is not larger than the previous "
                f"value {values[k - 1]:g} (x must be strictly increasing)"
            )


def _check_plausible(kind: str, units: str, unit_system: UnitSystem, columns, lines: list[int],
                     problems: list[str]) -> None:
    """Add a problem for every value outside its quantity's plausible range (physical units, as in the message)."""
    to_physical = {"force": unit_system.dpd_to_nN, "displacement": unit_system.dpd_to_nm}
    dpd_unit = {"force": "DPD force", "displacement": "DPD length"}
    for (name, values), quantity in zip(columns, KINDS[kind], strict=True):
        labels = [f"row {k + 1} (line {line}), column {name!r}" for k, line in enumerate(lines)]
        if units == "dpd":
            problems += plausibility_problems(quantity, to_physical[quantity](values), labels, shown=values,
                                              shown_unit=dpd_unit[quantity])
        else:
            problems += plausibility_problems(quantity, values, labels)


def load_curve(
    path: str | Path,
    kind: str,
    units: str = "dpd",
    *,
    name: str | None = None,
    agent: str | None = None,
    diameter_um: float | None = None,
    source: str = "",
    unit_system: UnitSystem = DEFAULT_UNITS,
) -> LoadingCurve:
    """Read and validate a loading-curve CSV file.

    The file has a header row and one row per point. Its columns depend on ``kind`` and ``units``
    (:func:`~bubblecal.data.expected_columns`): compression ``displacement_dpd, force_dpd`` or
    ``displacement_nm, force_nN``; indentation ``force_dpd, displacement_dpd`` or ``force_nN, displacement_nm``.
    A physical-unit file may carry a ``retained_in_inference`` column (1/0): then only the retained rows form
    the curve, and the whole curve is kept as ``source_curve``.

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file.
    kind : str
        Loading protocol: 'compression' or 'indentation'.
    units : str
        Units of the file: 'dpd' (DPD length, DPD force) or 'physical' (nm, nN).
    name : str, optional
        Curve name (default: the file's stem).
    agent : str, optional
        Contrast agent, 'definity' or 'sonovue' (None for user data).
    diameter_um : float, optional
        Bubble diameter [um].
    source : str
        Citation (default: the file path).
    unit_system : UnitSystem
        Converts a physical file to DPD units and sets the curve's physical views.

    Returns
    -------
    LoadingCurve
        The curve in DPD units (x, y in the experiment's axis order); ``source_curve`` set for a physical file.

    Raises
    ------
    DataError
        Listing every problem with file, row and column: unknown kind or units, missing or unreadable file,
        missing, unknown or duplicate columns, ragged rows, non-numeric cells, NaN/inf, negative values,
        x not strictly increasing, a force or displacement outside its plausible range or a column without
        signal (:data:`~bubblecal.data.PLAUSIBLE_RANGES`), a retained flag other than 0/1, fewer than
        :data:`MIN_POINTS` points, a header written with another separator than the comma (a UTF-8 byte-order
        mark is accepted).
    """
    path = Path(path)
    _check_kind_units(kind, units, where=str(path))
    x_col, y_col = expected_columns(kind, units)
    optional = (RETAINED_COLUMN,) if units == "physical" else ()
    columns, problems = _read_table(path, (x_col, y_col), optional, f"a {kind} curve in {units} units")
    lines = [line for line, _ in columns[x_col]]
    x = _numeric_column(x_col, columns[x_col], problems)
    y = _numeric_column(y_col, columns[y_col], problems)
    retained = np.ones(x.size, dtype=bool)
    if RETAINED_COLUMN in columns:
        for k, (line, text) in enumerate(columns[RETAINED_COLUMN]):
            if text not in ("0", "1"):
                problems.append(f"row {k + 1} (line {line}), column {RETAINED_COLUMN!r}: {text!r} must be 0 or 1")
            retained[k] = text == "1"
    _check_increasing(x_col, x, lines, problems)
    _check_plausible(kind, units, unit_system, ((x_col, x), (y_col, y)), lines, problems)
    if int(retained.sum()) < MIN_POINTS:
        what = "retained points" if RETAINED_COLUMN in columns else "data rows"
        problems.append(f"only {int(retained.sum())} {what}; a curve needs at least {MIN_POINTS}")
    if problems:
        raise DataError(path, problems)

    source_curve = None
    if units == "physical":
        source_curve = SourceCurve(kind=kind, x=x, y=y, retained=retained, path=str(path))
        x_q, y_q = KINDS[kind]
        conv = {"force": unit_system.nN_to_dpd, "displacement": unit_system.nm_to_dpd}
        x_dpd, y_dpd = conv[x_q](x[retained]), conv[y_q](y[retained])
    else:
        x_dpd, y_dpd = x, y
    return LoadingCurve(
        name=name or path.stem, kind=kind, x=np.asarray(x_dpd, float), y=np.asarray(y_dpd, float),
        agent=agent, diameter_um=diameter_um, source=source or str(path), path=str(path),
        source_curve=source_curve, units=unit_system,
    )
