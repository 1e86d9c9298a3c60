"""Reading and validating tidy bubble files: curves, resonances and the two together.

Every problem of a file is collected and raised in one :class:`~bubblecal.data.TidyDataError` naming the row
(1-based data row and file line), the column, the value and the allowed range (docs/data-formats.md, "Tidy
bubble files"). Nothing is clipped or dropped silently. The unit checks live in :mod:`bubblecal.data.tidy_units`.
"""

from __future__ import annotations

import difflib
import math
from pathlib import Path

import numpy as np

from bubblecal.data.curves import KINDS
from bubblecal.data.errors import DataError
from bubblecal.data.names import LOADING_PROTOCOLS
from bubblecal.data.plausibility import plausibility_problems
from bubblecal.data.readers import MIN_POINTS, read_csv_rows, separator_hint
from bubblecal.data.tidy import (
    CURVE_COLUMNS,
    CURVE_OPTIONAL,
    RESONANCE_COLUMNS,
    RESONANCE_OPTIONAL,
    BubbleCurve,
    BubbleCurveSet,
    ResonanceSet,
    TidyDataError,
)
from bubblecal.data.tidy_units import bubble_problems
from bubblecal.data.units import DEFAULT_UNITS, UnitSystem

__all__ = ["read_bubble_curves", "read_resonance", "check_consistency", "tidy_kind"]

#: The quantity of each numeric column of a tidy file.
_QUANTITY = {"diameter_um": "diameter", "displacement_nm": "displacement", "force_nN": "force",
             "frequency_MHz": "resonance_frequency"}


def _where(row: int, line: int, column: str) -> str:
    """``"row 3 (line 4), column 'force_nN'"``."""
    return f"row {row} (line {line}), column {column!r}"


def _header_problems(header: list[str], line: int, required, optional) -> list[str]:
    """Unknown (with a near-miss hint), missing and duplicate columns of a header row."""
    problems = []
    allowed = tuple(required) + tuple(optional)
    lowered = {a.lower(): a for a in allowed}
    for name in header:
        if name in allowed:
            continue
        close = [lowered[name.lower()]] if name.lower() in lowered else difflib.get_close_matches(name, allowed, 1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        problems.append(f"header (line {line}): unknown column {name!r}{hint}; allowed columns: "
                        + ", ".join(required) + f" (optional: {', '.join(optional)})")
    for name in required:
        if name not in header:
            problems.append(f"header (line {line}): missing column {name!r} (found: {', '.join(header) or 'none'})")
    duplicates = sorted({h for h in header if header.count(h) > 1})
    if duplicates:
        problems.append(f"header (line {line}): duplicate columns {', '.join(map(repr, duplicates))}")
    return problems


def _read_rows(path: Path, required, optional, what: str):
    """The file's data rows as (data row, line, {column: text}); raise on a header problem."""
    try:
        cells = read_csv_rows(path)
    except DataError as exc:
        raise TidyDataError(path, exc.problems) from exc
    rows = [(i + 1, r) for i, r in enumerate(cells) if any(c.strip() for c in r)]
    if not rows:
        raise TidyDataError(path, [f"file is empty (a {what} needs a header row with columns {', '.join(required)})"])
    line, header = rows[0]
    header = [h.strip() for h in header]
    hint = separator_hint(header)
    if hint:
        raise TidyDataError(path, [f"header (line {line}): {header[0]!r} is one column{hint}"])
    problems = _header_problems(header, line, required, optional)
    if problems:
        raise TidyDataError(path, problems)
    out = []
    for row, (line, cells) in enumerate(rows[1:], start=1):
        if len(cells) != len(header):
            problems.append(f"row {row} (line {line}): {len(cells)} cells, expected {len(header)} "
                            f"({', '.join(header)})")
            continue
        out.append((row, line, {h: c.strip() for h, c in zip(header, cells, strict=True)}))
    if not out and not problems:
        problems.append(f"no data rows after the header (line {line})")
    return out, problems


def _number(row: int, line: int, column: str, text: str, problems: list[str]) -> float:
    """The cell as a finite, non-negative float, or NaN after adding a problem."""
    try:
        value = float(text)
    except ValueError:
        problems.append(f"{_where(row, line, column)}: {text!r} is not a number")
        return math.nan
    if not math.isfinite(value):
        problems.append(f"{_where(row, line, column)}: {text} is not finite (NaN/inf are not allowed)")
        return math.nan
    if value < 0:
        problems.append(f"{_where(row, line, column)}: negative value {value:g} (must be >= 0)")
        return math.nan
    return value


def _label(row: int, line: int, column: str, text: str, problems: list[str]) -> str:
    """A non-empty text cell (an id or agent label), or '' after adding a problem."""
    if not text:
        problems.append(f"{_where(row, line, column)}: empty (every row needs a {column})")
    return text


def _rows_text(rows: list[int]) -> str:
    """``"rows 1-3, 7"`` from 1-based data rows."""
    spans, start = [], rows[0]
    for a, b in zip(rows, rows[1:] + [None], strict=True):
        if b != a + 1:
            spans.append(f"{start}" if start == a else f"{start}-{a}")
            start = b
    return ("row " if len(rows) == 1 else "rows ") + ", ".join(spans)


def _disagreement(bubble: str, column: str, values: dict, problems: list[str]) -> None:
    """A problem when the rows of one bubble hold more than one value of ``column``."""
    if len(values) < 2:
        return
    parts = "; ".join(f"{v!r} in {_rows_text(rows)}" for v, rows in values.items())
    if column == "agent" and all(len(r) >= MIN_POINTS and r == list(range(r[0], r[-1] + 1)) for r in values.values()):
        problems.append(f"bubble {bubble!r}: the id is used in {len(values)} agents ({parts}); bubble ids must be "
                        "unique across agents")
    else:
        problems.append(f"bubble {bubble!r}: its rows disagree on {column} ({parts}); every row of a bubble must "
                        f"hold the same {column}")


def read_bubble_curves(path: str | Path, unit_system: UnitSystem = DEFAULT_UNITS) -> BubbleCurveSet:
    """Read and validate a tidy curve file (one row per measured point; docs/data-formats.md).

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file with columns ``bubble, agent, protocol, diameter_um, displacement_nm, force_nN`` and
        optionally ``retained`` (0/1; default every point enters the likelihood).
    unit_system : UnitSystem
        Converts nm and nN to DPD units.

    Returns
    -------
    BubbleCurveSet
        Every bubble in the order of its first row, x and y in DPD units in the protocol's axis order.

    Raises
    ------
    TidyDataError
        Listing every problem with row, line, column, value and allowed range: unreadable file, missing or
        unknown columns (with a hint for near misses), ragged rows, empty ids, non-numeric, non-finite or
        negative values, an unknown protocol, a bubble whose rows disagree on agent, protocol or diameter, a
        bubble id used in two agents, values outside :data:`~bubblecal.data.PLAUSIBLE_RANGES`, forces or
        lengths that look like another unit, a protocol axis that does not increase within a bubble, a
        ``retained`` other than 0/1, a bubble with fewer than :data:`~bubblecal.data.MIN_POINTS` retained points.
    """
    path = Path(path)
    rows, problems = _read_rows(path, CURVE_COLUMNS, CURVE_OPTIONAL, "tidy curve file")
    groups: dict[str, list] = {}
    for row, line, cell in rows:
        bubble = _label(row, line, "bubble", cell["bubble"], problems)
        agent = _label(row, line, "agent", cell["agent"], problems)
        protocol = cell["protocol"]
        if protocol not in LOADING_PROTOCOLS:
            hint = f" (did you mean {protocol.lower()!r}?)" if protocol.lower() in LOADING_PROTOCOLS else ""
            problems.append(f"{_where(row, line, 'protocol')}: unknown protocol {protocol!r}{hint}; allowed: "
                            + ", ".join(LOADING_PROTOCOLS))
        values = {c: _number(row, line, c, cell[c], problems) for c in ("diameter_um", "displacement_nm", "force_nN")}
        retained = cell.get("retained", "1")
        if retained not in ("0", "1"):
            problems.append(f"{_where(row, line, 'retained')}: {retained!r} must be 0 or 1")
        if bubble:
            groups.setdefault(bubble, []).append((row, line, agent, protocol, values, retained == "1"))
    bubbles = []
    for bubble, pts in groups.items():
        for column, k in (("agent", 2), ("protocol", 3)):
            seen: dict = {}
            for p in pts:
                seen.setdefault(p[k], []).append(p[0])
            _disagreement(bubble, column, seen, problems)
        diam: dict = {}
        for p in pts:
            if not math.isnan(p[4]["diameter_um"]):
                diam.setdefault(p[4]["diameter_um"], []).append(p[0])
        _disagreement(bubble, "diameter_um", {f"{d:g}": r for d, r in diam.items()}, problems)
        columns = {c: np.array([p[4][c] for p in pts]) for c in ("diameter_um", "displacement_nm", "force_nN")}
        labels = {c: [f"bubble {bubble!r}, {_where(p[0], p[1], c)}" for p in pts] for c in columns}
        sniffed = bubble_problems(bubble, columns, [p[0] for p in pts])
        problems += [msg for _, msg in sniffed]
        for c, values in columns.items():
            if c not in {q for q, _ in sniffed}:
                problems += plausibility_problems(_QUANTITY[c], values, labels[c])
        protocol, retained = pts[0][3], np.array([p[5] for p in pts])
        if protocol in KINDS:
            x_col = "displacement_nm" if KINDS[protocol][0] == "displacement" else "force_nN"
            x = columns[x_col]
            for k in range(1, x.size):
                if x[k] <= x[k - 1]:
                    problems.append(f"bubble {bubble!r}, {_where(pts[k][0], pts[k][1], x_col)}: {x[k]:g} is not "
                                    f"larger than the previous {x[k - 1]:g} ({protocol}: {x_col} must increase "
                                    "strictly within a bubble; the curve is not monotone)")
        if int(retained.sum()) < MIN_POINTS:
            problems.append(f"bubble {bubble!r} ({_rows_text([p[0] for p in pts])}): only {int(retained.sum())} "
                            f"retained points; a bubble needs at least {MIN_POINTS}")
        if problems:
            continue
        conv = {"force": unit_system.nN_to_dpd(columns["force_nN"]),
                "displacement": unit_system.nm_to_dpd(columns["displacement_nm"])}
        x_q, y_q = KINDS[protocol]
        bubbles.append(BubbleCurve(bubble=bubble, agent=pts[0][2], protocol=protocol,
                                   diameter_um=float(columns["diameter_um"][0]), x=conv[x_q], y=conv[y_q],
                                   retained=retained, lines=tuple(p[1] for p in pts), path=str(path),
                                   units=unit_system))
    if problems:
        raise TidyDataError(path, problems)
    return BubbleCurveSet(bubbles=tuple(bubbles), path=str(path))


def read_resonance(path: str | Path, unit_system: UnitSystem = DEFAULT_UNITS) -> ResonanceSet:
    """Read and validate a tidy resonance file (one row per bubble; docs/data-formats.md).

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file with columns ``agent, diameter_um, frequency_MHz`` and optionally ``source``.
    unit_system : UnitSystem
        Converts MHz to 1 / DPD time.

    Returns
    -------
    ResonanceSet
        The rows in file order, frequencies in MHz and in DPD units.

    Raises
    ------
    TidyDataError
        Listing every problem with row, line, column, value and allowed range: unreadable file, missing or
        unknown columns, ragged rows, empty agents, non-numeric, non-finite or negative values, diameters or
        frequencies outside :data:`~bubblecal.data.PLAUSIBLE_RANGES` (a diameter in nm or a frequency in Hz
        or kHz named as such).
    """
    path = Path(path)
    rows, problems = _read_rows(path, RESONANCE_COLUMNS, RESONANCE_OPTIONAL, "tidy resonance file")
    agents, diam, freq = [], [], []
    for row, line, cell in rows:
        agents.append(_label(row, line, "agent", cell["agent"], problems))
        d = _number(row, line, "diameter_um", cell["diameter_um"], problems)
        f = _number(row, line, "frequency_MHz", cell["frequency_MHz"], problems)
        where = _where(row, line, "diameter_um")
        if d > 100.0:
            problems.append(f"{where}: {d:g} looks like nm (a microbubble is 0.5-10 um): give the diameter in um")
        else:
            problems += plausibility_problems("diameter", [d], [where])
        where = _where(row, line, "frequency_MHz")
        if f > 1e4:
            unit = "Hz" if f > 1e5 else "kHz"
            problems.append(f"{where}: {f:g} looks like {unit} (bubble resonances lie at 0.1-30 MHz): give MHz")
        else:
            problems += plausibility_problems("resonance_frequency", [f], [where])
        diam.append(d)
        freq.append(f)
    if problems:
        raise TidyDataError(path, problems)
    freq_arr = np.array(freq, dtype=float)
    return ResonanceSet(agent=tuple(agents), diameter_um=np.array(diam, dtype=float), frequency_MHz=freq_arr,
                        frequency_dpd=unit_system.frequency_to_dpd(freq_arr * 1e6),
                        source=tuple(c.get("source", "") for _, _, c in rows), lines=tuple(ln for _, ln, _ in rows),
                        path=str(path))


def check_consistency(curves: BubbleCurveSet, resonance: ResonanceSet) -> None:
    """Check a curve file and a resonance file together: every resonance row's agent must have curves.

    Parameters
    ----------
    curves : BubbleCurveSet
        A validated tidy curve file.
    resonance : ResonanceSet
        A validated tidy resonance file.

    Raises
    ------
    TidyDataError
        Naming every resonance row whose agent has no bubble in the curve file, with the agents that do.
    """
    known = set(curves.agents)
    problems = [f"row {k + 1} (line {line}), column 'agent': {agent!r} has no curves in {curves.path}; agents "
                f"with curves: {', '.join(curves.agents)}"
                for k, (agent, line) in enumerate(zip(resonance.agent, resonance.lines, strict=True))
                if agent not in known]
    if problems:
        raise TidyDataError(resonance.path, problems)


def tidy_kind(path: str | Path) -> str | None:
    """What a CSV file holds, judged by its header row.

    Parameters
    ----------
    path : str or pathlib.Path
        A CSV file.

    Returns
    -------
    str or None
        'curves' (a ``bubble`` column), 'resonance' (a ``frequency_MHz`` column) or None (another file:
        a single curve, the published acoustic table, or no header).

    Raises
    ------
    DataError
        The file is missing, a folder, unreadable or not UTF-8 text.
    """
    rows = [r for r in read_csv_rows(Path(path)) if any(c.strip() for c in r)]
    header = {h.strip() for h in rows[0]} if rows else set()
    if "bubble" in header:
        return "curves"
    if "frequency_MHz" in header:
        return "resonance"
    return None
