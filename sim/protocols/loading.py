"""Published mechanical loading grids (docs/physics.md section 5; docs/data-formats.md), typed.

All values are DPD units (length 0.25 um, shell force u_e/u_l with fscale applied, see
:mod:`bubblecal.data.units`).

* Compression (Definity): 15 imposed *total* plate displacements 0, 0.12, ..., 1.68 DPD length
  (shared symmetrically by the two plates).
* Indentation (SonoVue): 15 forces 0 ... F_max in 14 equal steps; F_max = 6000 DPD force for the
  3.2 and 3.4 um bubbles and 8000 for 5.8 um.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = [
    "CompressionProtocol",
    "IndentationProtocol",
    "validate_grid",
    "published_compression_protocol",
    "published_indentation_protocol",
    "PUBLISHED_DISPLACEMENT_STEP_DPD",
    "PUBLISHED_N_POINTS",
    "PUBLISHED_INDENTATION_FMAX_DPD",
]

#: Points of every published grid.
PUBLISHED_N_POINTS = 15
#: Step of the published compression grid (DPD length).
PUBLISHED_DISPLACEMENT_STEP_DPD = 0.12
#: Published indentation F_max per diameter: diameter [um] -> F_max [DPD force].
PUBLISHED_INDENTATION_FMAX_DPD = {3.2: 6000.0, 3.4: 6000.0, 5.8: 8000.0}


def validate_grid(values: Sequence[float] | np.ndarray, name: str, *, nonnegative: bool = True,
                  strictly_increasing: bool = True) -> np.ndarray:
    """Check a loading grid and return it as float64.

    Parameters
    ----------
    values : sequence of float
        The grid (DPD length or DPD force).
    name : str
        Field name that starts every error message.
    nonnegative : bool
        Require values >= 0.
    strictly_increasing : bool
        Require strictly increasing values.

    Returns
    -------
    numpy.ndarray
        The grid [P] (float64).

    Raises
    ------
    ValueError
        If the grid is not a non-empty, finite 1-D sequence meeting the requirements (message starts with
        ``name``).
    """
    a = np.asarray(values, dtype=np.float64)
    if a.ndim != 1 or a.size == 0:
        raise ValueError(f"{name} must be a non-empty 1-D sequence, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite, got {a.tolist()}")
    if nonnegative and np.any(a < 0):
        raise ValueError(f"{name} must be non-negative, got {a.tolist()}")
    if strictly_increasing and np.any(np.diff(a) <= 0):
        raise ValueError(f"{name} must be strictly increasing, got {a.tolist()}")
    return a


@dataclass(frozen=True)
class CompressionProtocol:
    """Parallel-plate compression grid; the observable is the plate reaction force F(d) (DPD force).

    Parameters
    ----------
    displacements_dpd : tuple of float
        Imposed total plate displacements (DPD length; >= 0, strictly increasing).

    Raises
    ------
    ValueError
        If the grid is invalid (:func:`validate_grid`).
    """

    displacements_dpd: tuple[float, ...]

    def __post_init__(self) -> None:
        a = validate_grid(self.displacements_dpd, "displacements_dpd")
        object.__setattr__(self, "displacements_dpd", tuple(float(v) for v in a))

    @property
    def n_points(self) -> int:
        """Number of grid points P."""
        return len(self.displacements_dpd)

    def as_array(self) -> np.ndarray:
        """Displacements [P] (DPD length)."""
        return np.asarray(self.displacements_dpd, dtype=np.float64)


@dataclass(frozen=True)
class IndentationProtocol:
    """Opposed pole loads applied in order; the observable is the reduction d(F) of the axial (pole-to-pole)
    diameter (DPD length).

    Parameters
    ----------
    forces_dpd : tuple of float
        Total force per pole at each point (DPD force; >= 0, strictly increasing).
    diameter_um : float, optional
        The bubble the grid belongs to (um; informational), None if not tied to one.

    Raises
    ------
    ValueError
        If the grid is invalid (:func:`validate_grid`) or ``diameter_um`` is not a positive finite number.
    """

    forces_dpd: tuple[float, ...]
    diameter_um: float | None = None

    def __post_init__(self) -> None:
        a = validate_grid(self.forces_dpd, "forces_dpd")
        object.__setattr__(self, "forces_dpd", tuple(float(v) for v in a))
        if self.diameter_um is not None and not (math.isfinite(self.diameter_um) and self.diameter_um > 0):
            raise ValueError(f"diameter_um must be a positive finite number, got {self.diameter_um!r}")

    @property
    def n_points(self) -> int:
        """Number of grid points P."""
        return len(self.forces_dpd)

    def as_array(self) -> np.ndarray:
        """Forces [P] (DPD force)."""
        return np.asarray(self.forces_dpd, dtype=np.float64)


def published_compression_protocol() -> CompressionProtocol:
    """The published Definity grid.

    Returns
    -------
    CompressionProtocol
        15 total displacements 0, 0.12, ..., 1.68 (DPD length).
    """
    return CompressionProtocol(tuple(round(PUBLISHED_DISPLACEMENT_STEP_DPD * i, 12)
                                     for i in range(PUBLISHED_N_POINTS)))


def published_indentation_protocol(diameter_um: float) -> IndentationProtocol:
    """The published SonoVue grid: 15 forces 0 ... F_max (DPD force).

    Parameters
    ----------
    diameter_um : float
        3.2, 3.4 or 5.8 (um).

    Returns
    -------
    IndentationProtocol
        The grid, tied to ``diameter_um``.

    Raises
    ------
    ValueError
        For any other diameter.
    """
    key = None
    for d in PUBLISHED_INDENTATION_FMAX_DPD:
        if math.isclose(float(diameter_um), d, abs_tol=1e-9):
            key = d
    if key is None:
        raise ValueError(f"diameter_um must be one of {sorted(PUBLISHED_INDENTATION_FMAX_DPD)}, got {diameter_um!r}")
    fmax = PUBLISHED_INDENTATION_FMAX_DPD[key]
    n = PUBLISHED_N_POINTS - 1
    return IndentationProtocol(tuple(fmax * i / n for i in range(PUBLISHED_N_POINTS)), diameter_um=key)
