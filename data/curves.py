"""Loading curves (AFM force spectroscopy): the curve types and what each axis holds.

A :class:`LoadingCurve` always stores ``x`` and ``y`` in DPD units in the order of the experiment:

* compression (Definity): x = imposed displacement [DPD length], y = plate force [DPD force];
* indentation (SonoVue):  x = applied force [DPD force],         y = indentation depth [DPD length].

Physical-unit views (nm, nN) are derived through :mod:`bubblecal.data.units` (docs/physics.md section 1).
Curve files are read by :func:`bubblecal.data.load_curve`; the shipped curves come from
:func:`bubblecal.data.reference_curves`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bubblecal.data.errors import DataError
from bubblecal.data.units import DEFAULT_UNITS, UnitSystem

__all__ = ["KINDS", "UNITS", "LoadingCurve", "SourceCurve", "expected_columns"]

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


def expected_columns(kind: str, units: str) -> tuple[str, str]:
    """Column names (x, y) that a curve file of ``kind`` written in ``units`` must have.

    Parameters
    ----------
    kind : str
        Loading protocol, one of :data:`KINDS` ('compression' or 'indentation').
    units : str
        Units of the file, one of :data:`UNITS` ('dpd' or 'physical').

    Returns
    -------
    tuple of str
        The x and y column names, e.g. ``("displacement_nm", "force_nN")`` for a physical compression curve.

    Raises
    ------
    DataError
        If ``kind`` or ``units`` is unknown.
    """
    _check_kind_units(kind, units, where="expected_columns")
    xq, yq = KINDS[kind]
    return _COLUMN_SUFFIX[(xq, units)], _COLUMN_SUFFIX[(yq, units)]


def _check_kind_units(kind: str, units: str, where: str) -> None:
    """Raise :class:`DataError` (labelled ``where``) for an unknown kind or unit system."""
    if kind not in KINDS:
        raise DataError(where, [f"unknown kind {kind!r}; allowed: {', '.join(KINDS)}"])
    if units not in UNITS:
        raise DataError(where, [f"unknown units {units!r}; allowed: {', '.join(UNITS)}"])


@dataclass(frozen=True)
class SourceCurve:
    """A whole digitised source curve in physical units, with the points kept for inference.

    Parameters
    ----------
    kind : str
        Loading protocol ('compression' or 'indentation'); sets the axis order.
    x, y : numpy.ndarray
        The curve in the experiment's axis order, displacement [nm] and force [nN].
    retained : numpy.ndarray of bool
        True for the points that enter the likelihood; same length as ``x``.
    path : str or None
        The file the curve was read from.
    """

    kind: str
    x: np.ndarray
    y: np.ndarray
    retained: np.ndarray
    path: str | None = None


@dataclass(frozen=True)
class LoadingCurve:
    """One force-spectroscopy curve in DPD units (see the module docstring for the axes).

    Parameters
    ----------
    name : str
        Curve name, e.g. ``"definity_compression_2.1um"`` or a user file's stem.
    kind : str
        Loading protocol, 'compression' or 'indentation'.
    x, y : numpy.ndarray
        The retained points in the experiment's axis order: displacement [DPD length], force [DPD force].
    agent : str or None
        'definity', 'sonovue', or None for user data.
    diameter_um : float or None
        Nominal bubble diameter [um] (names the curve); None if unknown.
    source : str
        A citation or the file the curve came from.
    path : str or None
        The DPD file the curve was read from.
    source_curve : SourceCurve or None
        The whole physical source curve with its retained flags, when known.
    units : UnitSystem
        Unit system of the physical views (default :data:`~bubblecal.data.DEFAULT_UNITS`).
    bubble_diameter_um : float or None
        Measured bubble diameter [um] that sets the DPD geometry, when it differs from the nominal one.
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
        """Bubble radius [DPD length] (measured diameter [um] / 0.5 um), None if the diameter is unknown."""
        diameter = self.bubble_diameter_um if self.bubble_diameter_um is not None else self.diameter_um
        return None if diameter is None else float(self.units.radius_dpd(diameter))

    def axis_label(self, axis: str, units: str = "dpd") -> str:
        """Axis label naming the quantity and its unit.

        Parameters
        ----------
        axis : str
            'x' or 'y' (anything other than 'x' means 'y').
        units : str
            'dpd' or 'physical'.

        Returns
        -------
        str
            E.g. ``"displacement [nm]"`` or ``"force [DPD force]"``.
        """
        quantity = self.x_quantity if axis == "x" else self.y_quantity
        return f"{quantity} [{_UNIT_LABEL[(quantity, units)]}]"

    def _to_physical(self, values: np.ndarray, quantity: str) -> np.ndarray:
        """DPD force -> nN or DPD length -> nm, by ``quantity``."""
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
