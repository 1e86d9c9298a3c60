"""Loading curves (AFM force spectroscopy): the shipped reference curves and a validating CSV reader.

A :class:`LoadingCurve` always stores ``x`` and ``y`` in DPD units in the order of the experiment:

* compression (Definity): x = imposed displacement [DPD length], y = plate force [DPD force];
* indentation (SonoVue):  x = applied force [DPD force],         y = indentation depth [DPD length].

Physical-unit views (nm, nN) are derived through :mod:`bubblecal.data.units`.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from bubblecal.data.units import DEFAULT_UNITS, UnitSystem

__all__ = [
    "KINDS",
    "UNITS",
    "DataError",
    "LoadingCurve",
    "SourceCurve",
    "REFERENCE_CURVES",
    "load_curve",
    "load_reference",
    "reference_curves",
    "reference_names",
    "expected_columns",
    "resolve_reference_name",
]

#: Loading protocols and the physical quantity on each axis (x, y).
KINDS: dict[str, tuple[str, str]] = {
    "compression": ("displacement", "force"),
    "indentation": ("force", "displacement"),
}
#: Unit systems a curve file may be written in.
UNITS = ("dpd", "physical")
_COLUMN_SUFFIX = {
    ("displacement", "dpd"): "displacement_dpd",
    ("force", "dpd"): "force_dpd",
    ("displacement", "physical"): "displacement_nm",
    ("force", "physical"): "force_nN",
}
_UNIT_LABEL = {
    ("displacement", "dpd"): "DPD length",
    ("force", "dpd"): "DPD force",
    ("displacement", "physical"): "nm",
    ("force", "physical"): "nN",
}
RETAINED_COLUMN = "retained_in_inference"
MIN_POINTS = 3

#: The six shipped curves: name -> (agent, kind, nominal diameter [um], measured diameter [um], citation).
#: The nominal diameter names the curve; the measured one (3.19, 3.40, 5.76 um for SonoVue) sets the
#: DPD geometry, as in the published training sets (radius_dpd 6.38, 6.8, 11.52).
REFERENCE_CURVES: dict[str, tuple[str, str, float, float, str]] = {
    "definity_compression_2.1um": ("definity", "compression", 2.1, 2.1, "Buchner Santos et al., Langmuir 28:5753 (2012)"),
    "definity_compression_2.9um": ("definity", "compression", 2.9, 2.9, "Buchner Santos et al., Langmuir 28:5753 (2012)"),
    "definity_compression_3.0um": ("definity", "compression", 3.0, 3.0, "Buchner Santos et al., Langmuir 28:5753 (2012)"),
    "sonovue_indentation_3.2um": ("sonovue", "indentation", 3.2, 3.19, "J. K. Morris, PhD thesis, Edinburgh (2014)"),
    "sonovue_indentation_3.4um": ("sonovue", "indentation", 3.4, 3.40, "J. K. Morris, PhD thesis, Edinburgh (2014)"),
    "sonovue_indentation_5.8um": ("sonovue", "indentation", 5.8, 5.76, "J. K. Morris, PhD thesis, Edinburgh (2014)"),
}


class DataError(ValueError):
    """A data file failed validation; ``problems`` lists every problem found (file, row, column)."""

    def __init__(self, path: str | Path, problems: list[str]):
        self.path = str(path)
        self.problems = list(problems)
        lines = "\n".join(f"  - {p}" for p in self.problems)
        noun = "problem" if len(self.problems) == 1 else "problems"
        super().__init__(f"{self.path}: {len(self.problems)} {noun}:\n{lines}")


def expected_columns(kind: str, units: str) -> tuple[str, str]:
    """Column names (x, y) a ``kind`` curve file must have in ``units`` ('dpd' or 'physical')."""
    _check_kind_units(kind, units, where="expected_columns")
    xq, yq = KINDS[kind]
    return _COLUMN_SUFFIX[(xq, units)], _COLUMN_SUFFIX[(yq, units)]


def _check_kind_units(kind: str, units: str, where: str) -> None:
    if kind not in KINDS:
        raise DataError(where, [f"unknown kind {kind!r}; allowed: {', '.join(KINDS)}"])
    if units not in UNITS:
        raise DataError(where, [f"unknown units {units!r}; allowed: {', '.join(UNITS)}"])


@dataclass(frozen=True)
class SourceCurve:
    """A whole digitised source curve in physical units, with the points kept for inference.

    ``x`` and ``y`` in nm / nN following the experiment's axis order; ``retained`` a boolean mask.
    """

    kind: str
    x: np.ndarray
    y: np.ndarray
    retained: np.ndarray
    path: str | None = None


@dataclass(frozen=True)
class LoadingCurve:
    """One force-spectroscopy curve; ``x``, ``y`` in DPD units (see module docstring for the axes).

    ``agent`` ('definity'|'sonovue' or None for user data), ``diameter_um`` bubble diameter [um]
    (None if unknown), ``source`` a citation or file, ``source_curve`` the full physical source
    curve with its retained flags when known.
    """

    name: str
    kind: str
    x: np.ndarray
    y: np.ndarray
    agent: str | None = None
    diameter_um: float | None = None
    source: str = ""
    path: str | None = None
    source_curve: SourceCurve | None = None
    units: UnitSystem = field(default=DEFAULT_UNITS, repr=False)
    bubble_diameter_um: float | None = None

    @property
    def n_points(self) -> int:
        """Number of (retained) points."""
        return int(self.x.size)

    @property
    def x_quantity(self) -> str:
        """'displacement' or 'force'."""
        return KINDS[self.kind][0]

    @property
    def y_quantity(self) -> str:
        """'force' or 'displacement'."""
        return KINDS[self.kind][1]

    @property
    def radius_dpd(self) -> float | None:
        """Bubble radius [DPD length] (measured diameter / 0.5 um), None if the diameter is unknown."""
        diameter = self.bubble_diameter_um if self.bubble_diameter_um is not None else self.diameter_um
        return None if diameter is None else float(self.units.radius_dpd(diameter))

    def axis_label(self, axis: str, units: str = "dpd") -> str:
        """Label such as 'displacement [nm]' for axis 'x' or 'y' in 'dpd' or 'physical' units."""
        quantity = self.x_quantity if axis == "x" else self.y_quantity
        return f"{quantity} [{_UNIT_LABEL[(quantity, units)]}]"

    def _to_physical(self, values: np.ndarray, quantity: str) -> np.ndarray:
        if quantity == "force":
            return self.units.dpd_to_nN(values)
        return self.units.dpd_to_nm(values)

    @property
    def x_physical(self) -> np.ndarray:
        """x in physical units (nm for displacement, nN for force)."""
        return self._to_physical(self.x, self.x_quantity)

    @property
    def y_physical(self) -> np.ndarray:
        """y in physical units (nm for displacement, nN for force)."""
        return self._to_physical(self.y, self.y_quantity)

    @property
    def displacement_dpd(self) -> np.ndarray:
        """The displacement axis [DPD length], whichever of x/y it is."""
        return self.x if self.x_quantity == "displacement" else self.y

    @property
    def force_dpd(self) -> np.ndarray:
        """The force axis [DPD force], whichever of x/y it is."""
        return self.x if self.x_quantity == "force" else self.y

    @property
    def displacement_nm(self) -> np.ndarray:
        """Displacement [nm]."""
        return self.units.dpd_to_nm(self.displacement_dpd)

    @property
    def force_nN(self) -> np.ndarray:
        """Force [nN]."""
        return self.units.dpd_to_nN(self.force_dpd)


# ----------------------------------------------------------------------------------------------
# CSV reading and validation
# ----------------------------------------------------------------------------------------------
def _parse_float(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None


def _read_table(path: Path, required: tuple[str, ...], optional: tuple[str, ...], label: str):
    """Read a headed CSV; return (columns dict name -> list[(file line, text)], problems)."""
    problems: list[str] = []
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            rows = list(csv.reader(handle))
    except FileNotFoundError as exc:
        raise DataError(path, ["file not found"]) from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise DataError(path, [f"cannot read file: {exc}"]) from exc
    rows = [(i + 1, r) for i, r in enumerate(rows) if any(cell.strip() for cell in r)]
    if not rows:
        raise DataError(path, ["file is empty (expected a header row with columns " + ", ".join(required) + ")"])
    header_line, header = rows[0]
    header = [h.strip() for h in header]
    allowed = required + optional
    for name in header:
        if name not in allowed:
            problems.append(f"header (line {header_line}): unknown column {name!r}; {label} expects columns "
                            + ", ".join(required) + (f" (optional: {', '.join(optional)})" if optional else ""))
    for name in required:
        if name not in header:
            problems.append(f"header (line {header_line}): missing column {name!r} (found: {', '.join(header) or 'none'})")
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
    for k in range(1, values.size):
        if np.isfinite(values[k]) and np.isfinite(values[k - 1]) and values[k] <= values[k - 1]:
            problems.append(
                f"row {k + 1} (line {lines[k]}), column {name!r}: {values[k]:g} is not larger than the previous "
                f"value {values[k - 1]:g} (x must be strictly increasing)"
            )


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
    """Read and validate a user's loading-curve CSV.

    The file has a header row. Columns for ``kind``/``units`` (see :func:`expected_columns`):
    compression: ``displacement_dpd, force_dpd`` or ``displacement_nm, force_nN``; indentation:
    ``force_dpd, displacement_dpd`` or ``force_nN, displacement_nm``. Physical files may carry a
    ``retained_in_inference`` column (1/0): then only retained rows form the curve and the whole
    curve is kept as ``source_curve``. Returns a :class:`LoadingCurve` in DPD units.

    Raises :class:`DataError` listing every problem with file, row and column: missing or unknown
    columns, non-numeric cells, NaN/inf, negative values, x not strictly increasing, fewer than 3
    points, unknown kind or units.
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


# ----------------------------------------------------------------------------------------------
# Shipped reference curves
# ----------------------------------------------------------------------------------------------
def _reference_path(filename: str) -> Path:
    return Path(str(resources.files("bubblecal.data") / "reference" / filename))


def reference_names() -> list[str]:
    """Names of the six shipped curves, e.g. 'definity_compression_2.1um'."""
    return list(REFERENCE_CURVES)


def resolve_reference_name(name: str) -> str:
    """Map 'definity-2.1', 'definity_2.1um', 'sonovue 5.8' or a full name to the canonical name."""
    key = name.strip().lower().replace("-", "_").replace(" ", "_")
    if key in REFERENCE_CURVES:
        return key
    for canonical, (agent, kind, diameter, _measured, _) in REFERENCE_CURVES.items():
        for alias in (f"{agent}_{diameter}", f"{agent}_{diameter}um", f"{agent}_{kind}_{diameter}"):
            if key == alias:
                return canonical
    raise DataError("reference data", [f"unknown curve {name!r}; available: {', '.join(REFERENCE_CURVES)}"])


def _load_named_reference(name: str, unit_system: UnitSystem) -> LoadingCurve:
    agent, kind, diameter, measured, citation = REFERENCE_CURVES[name]
    curve = load_curve(_reference_path(f"{name}_dpd.csv"), kind, "dpd", name=name, agent=agent,
                       diameter_um=diameter, source=citation, unit_system=unit_system)
    src = load_curve(_reference_path(f"{name}_source_physical.csv"), kind, "physical", unit_system=unit_system)
    return LoadingCurve(name=name, kind=kind, x=curve.x, y=curve.y, agent=agent, diameter_um=diameter,
                        source=citation, path=curve.path, source_curve=src.source_curve, units=unit_system,
                        bubble_diameter_um=measured)


def load_reference(agent: str, diameter_um: float, unit_system: UnitSystem = DEFAULT_UNITS) -> LoadingCurve:
    """The shipped curve of ``agent`` ('definity'|'sonovue') at ``diameter_um`` [um], in DPD units."""
    agent_key = agent.strip().lower()
    agents = sorted({a for a, *_ in REFERENCE_CURVES.values()})
    if agent_key not in agents:
        raise DataError("reference data", [f"unknown agent {agent!r}; allowed: {', '.join(agents)}"])
    for name, (a, _kind, diameter, _measured, _) in REFERENCE_CURVES.items():
        if a == agent_key and abs(diameter - float(diameter_um)) < 1e-6:
            return _load_named_reference(name, unit_system)
    available = ", ".join(f"{d:g}" for a, _k, d, *_ in REFERENCE_CURVES.values() if a == agent_key)
    raise DataError("reference data", [f"no {agent_key} curve at diameter {diameter_um} um; available: {available} um"])


def reference_curves(agent: str | None = None, unit_system: UnitSystem = DEFAULT_UNITS) -> list[LoadingCurve]:
    """All six shipped curves (or one agent's), ordered by agent then diameter."""
    names = [n for n, (a, *_) in REFERENCE_CURVES.items() if agent is None or a == agent.lower()]
    if not names:
        raise DataError("reference data", [f"unknown agent {agent!r}; allowed: definity, sonovue"])
    return [_load_named_reference(n, unit_system) for n in names]
