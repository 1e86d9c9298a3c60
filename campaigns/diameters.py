"""Diameters and loading grids of a campaign: the levels of a diameter range and the grid at each diameter.

A Latin-hypercube design may take the bubble diameter D as one of its dimensions (``[ranges] diameter_um =
[lo, hi]`` in a campaign file).  Each design point's D is one of the *levels* lo, lo + step, ..., hi
(``diameter_step_um``): the points of one level share one mesh, and the hypercube's strata of D map evenly
onto the levels, so every level holds n / n_levels points (rounded up or down).  On one mesh level
(``subdivisions`` set) the quasi-static tier runs several levels in one refill pool
(:attr:`CampaignConfig.pools_levels`), each curve as in a run of its own size.  The
loading grid must mean the same thing at every D: compression displacements are fractions of the diameter
(``loading_fractions``), indentation forces are absolute (an AFM's set point is a force).  The rules and the
measurements behind them: docs/physics.md section 5.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from bubblecal.campaigns.errors import CampaignConfigError

__all__ = [
    "DIAMETER_DESIGN_RANGE_UM",
    "MAX_COMPRESSION_FRACTION",
    "diameter_levels",
    "level_of_unit",
    "fraction_grid",
    "check_loading_fractions",
    "check_loading",
    "published_grid",
]

#: Diameters [um] a diameter-range design may span: the range of the diameter-aware training sets, over which the
#: quasi-static tier's conventions are checked against the explicit tier (docs/physics.md sections 5 and 7).
DIAMETER_DESIGN_RANGE_UM = (1.5, 8.0)
#: The deepest compression a fraction grid may reach (total plate displacement / diameter): the plates meet at 1.
MAX_COMPRESSION_FRACTION = 0.5
#: The finest level spacing [um] (levels are rounded to this).
_MIN_STEP_UM = 0.01


def diameter_levels(lo: float, hi: float, step: float) -> tuple[float, ...]:
    """The diameter levels lo, lo + step, ..., hi of a diameter-range design.

    Parameters
    ----------
    lo, hi : float
        The range [um], ``DIAMETER_DESIGN_RANGE_UM[0] <= lo < hi <= DIAMETER_DESIGN_RANGE_UM[1]``.
    step : float
        Level spacing [um], >= 0.01, dividing ``hi - lo`` into a whole number of steps.

    Returns
    -------
    tuple of float
        The levels [um], rounded to 0.01 um.

    Raises
    ------
    CampaignConfigError
        ``ranges.diameter_um`` outside the supported range or not increasing; ``diameter_step_um`` not a
        positive divisor of the range.
    """
    rlo, rhi = DIAMETER_DESIGN_RANGE_UM
    for v in (lo, hi):
        if not (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and rlo <= v <= rhi):
            raise CampaignConfigError("ranges.diameter_um", f"must be [lo, hi] within [{rlo:g}, {rhi:g}] um (the "
                                                            f"range of the diameter-aware training sets), got "
                                                            f"[{lo!r}, {hi!r}]")
    if not lo < hi:
        raise CampaignConfigError("ranges.diameter_um", f"needs lo < hi [um], got [{lo:g}, {hi:g}]; a single "
                                                        "diameter is [campaign].diameter_um")
    if not (isinstance(step, (int, float)) and not isinstance(step, bool) and math.isfinite(step)
            and step >= _MIN_STEP_UM):
        raise CampaignConfigError("diameter_step_um", f"must be a number >= {_MIN_STEP_UM:g} um, got {step!r}")
    n_steps = (hi - lo) / step
    if abs(n_steps - round(n_steps)) > 1e-6 * max(1.0, n_steps):
        raise CampaignConfigError("diameter_step_um", f"{step:g} um does not divide the range [{lo:g}, {hi:g}] um "
                                                      "into whole steps")
    n = int(round(n_steps)) + 1
    return tuple(round(lo + i * step, 2) for i in range(n))


def level_of_unit(u: np.ndarray, n_levels: int) -> np.ndarray:
    """Level index of one Latin-hypercube column: stratum i of n maps to level floor(i * n_levels / n).

    Every level then holds n // n_levels or n // n_levels + 1 of the n points.

    Parameters
    ----------
    u : numpy.ndarray
        The column's n hypercube coordinates in [0, 1) (one per stratum [i/n, (i+1)/n)).
    n_levels : int
        Number of diameter levels.

    Returns
    -------
    numpy.ndarray
        int64 level indices in [0, n_levels).
    """
    u = np.asarray(u, dtype=np.float64)
    n = u.size
    stratum = np.minimum((u * n).astype(np.int64), n - 1)
    return np.minimum(stratum * n_levels // n, n_levels - 1)


def fraction_grid(fractions: Sequence[float], diameter_um: float) -> tuple[float, ...]:
    """Compression total displacements [DPD length] of a grid given as fractions of the diameter.

    Parameters
    ----------
    fractions : Sequence[float]
        Total plate displacement / diameter, increasing, in [0, :data:`MAX_COMPRESSION_FRACTION`].
    diameter_um : float
        Bubble diameter [um].

    Returns
    -------
    tuple of float
        ``fraction * 2 * radius_dpd(diameter_um)`` (``bubblecal.data.units``).
    """
    from bubblecal.data.units import DEFAULT_UNITS

    diameter_dpd = 2.0 * float(DEFAULT_UNITS.radius_dpd(diameter_um))
    return tuple(float(f) * diameter_dpd for f in fractions)


def check_loading_fractions(protocol: str, fractions) -> tuple[float, ...]:
    """Validate ``loading_fractions``: compression only, >= 2 increasing values in [0, 0.5].

    Parameters
    ----------
    protocol : str
        The campaign protocol.
    fractions : Sequence[float]
        Total plate displacement / diameter at each load point.

    Returns
    -------
    tuple of float
        The fractions as floats.

    Raises
    ------
    CampaignConfigError
        Field ``loading_fractions``: not compression, or the values are not >= 2 increasing numbers in
        [0, :data:`MAX_COMPRESSION_FRACTION`].
    """
    if protocol != "compression":
        raise CampaignConfigError("loading_fractions", f"applies to compression only (displacement as a fraction "
                                                       f"of the diameter); {protocol} takes loading_grid")
    a = _increasing(fractions)
    if a is None or a[-1] > MAX_COMPRESSION_FRACTION:
        raise CampaignConfigError("loading_fractions", f">= 2 strictly increasing fractions of the diameter in "
                                                       f"[0, {MAX_COMPRESSION_FRACTION:g}] needed, got {fractions!r}")
    return tuple(float(v) for v in a)


def published_grid(protocol: str, diameter_um: float) -> tuple[float, ...]:
    """The published loading grid of a compression or indentation protocol.

    Parameters
    ----------
    protocol : str
        'compression' or 'indentation'.
    diameter_um : float
        Bubble diameter [um].

    Returns
    -------
    tuple of float
        Total displacements [DPD length] or forces per pole [DPD force].

    Raises
    ------
    ValueError
        No published indentation grid at this diameter.
    """
    from bubblecal.sim.protocols.loading import (
        published_compression_protocol,
        published_indentation_protocol,
    )

    if protocol == "compression":
        return published_compression_protocol().displacements_dpd
    return published_indentation_protocol(diameter_um).forces_dpd


def _increasing(values) -> np.ndarray | None:
    """``values`` as floats when they are >= 2 finite, non-negative, strictly increasing numbers, else None."""
    ok = isinstance(values, (list, tuple)) and len(values) >= 2 and all(
        isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) and math.isfinite(v)
        for v in values)
    a = np.asarray(values, dtype=float) if ok else None
    return a if ok and not (np.any(a < 0) or np.any(np.diff(a) <= 0)) else None


def _check_absolute_grid(protocol: str, grid) -> tuple[float, ...]:
    """An explicit loading grid: >= 2 finite, non-negative, strictly increasing numbers."""
    a = _increasing(grid)
    if a is None:
        unit = "DPD length" if protocol == "compression" else "DPD force"
        raise CampaignConfigError("loading_grid", f">= 2 finite, non-negative, strictly increasing values [{unit}] "
                                                  f"needed, got {grid!r}")
    return tuple(float(v) for v in a)


def check_loading(config) -> tuple[tuple[float, ...] | None, tuple[float, ...] | None]:
    """Validate the loading grid of a campaign at every one of its diameters.

    Ringdown takes no grid; a compression design over a diameter range needs ``loading_fractions`` (an absolute
    displacement does not scale with the diameter), an indentation one an explicit ``loading_grid`` of forces;
    a single-diameter design without either takes the published grid, which must exist at its diameter.

    Parameters
    ----------
    config : CampaignConfig
        The campaign (its protocol, diameters, ``loading_grid`` and ``loading_fractions``).

    Returns
    -------
    tuple
        ``(loading_grid, loading_fractions)`` normalised to tuples of float (or None).

    Raises
    ------
    CampaignConfigError
        Field ``loading_grid`` or ``loading_fractions``: the grid is missing, malformed or does not scale.
    """
    grid, fractions, protocol = config.loading_grid, config.loading_fractions, config.protocol
    if fractions is not None:
        fractions = check_loading_fractions(protocol, fractions)
        if grid is not None:
            raise CampaignConfigError("loading_grid", "give either loading_grid (absolute) or loading_fractions "
                                                      "(fractions of the diameter), not both")
        return None, fractions
    if protocol == "ringdown":
        if grid is not None:
            raise CampaignConfigError("loading_grid", "ringdown records R(t); it takes no loading grid")
        return None, None
    span = config.diameter_range_um
    if span is not None and protocol == "compression":
        lo, hi = span
        raise CampaignConfigError("loading_fractions", f"a compression design over {lo:g} - {hi:g} um needs its "
                                                       "displacements as fractions of the diameter (an absolute grid "
                                                       f"does not scale: one displacement is {hi / lo:.2g}x deeper "
                                                       f"at {lo:g} um than at {hi:g} um)")
    if grid is not None:
        return _check_absolute_grid(protocol, grid), None
    if span is not None:
        raise CampaignConfigError("loading_grid", f"an indentation design over {span[0]:g} - {span[1]:g} um needs "
                                                  "loading_grid (forces per pole, DPD force, the same at every "
                                                  "diameter): published grids exist at 3.2, 3.4 and 5.8 um only")
    for dia in config.diameters:
        try:
            published_grid(protocol, dia)
        except ValueError as exc:
            raise CampaignConfigError("loading_grid", f"no published grid for {protocol} at {dia:g} um ({exc}); "
                                                      "give loading_grid explicitly") from None
    return None, None
