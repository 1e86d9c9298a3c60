"""Unit sniffing for a tidy curve file: one bubble's values that look like another unit than the column's.

A force column in newtons or pN, a displacement in um or m, a diameter in nm or m: each is a likely slip when
typing a file by hand, and each puts a whole bubble out of scale at once. The bounds here only name the unit that
was probably meant; :data:`~bubblecal.data.PLAUSIBLE_RANGES` still decides what is allowed.
"""

from __future__ import annotations

import numpy as np

__all__ = ["bubble_problems"]

#: (column, test on the bubble's finite values, the unit probably meant, factor to the column's unit).
#: Tests run in order; the first that fires names the column's problem.
_SNIFFS = (
    ("force_nN", lambda v, d: v.max() < 1e-6, "newtons (N)", "nN = N x 1e9"),
    ("force_nN", lambda v, d: np.median(v) > 1e3, "pN", "nN = pN / 1000"),
    ("displacement_nm", lambda v, d: v.max() < 1e-5, "metres (m)", "nm = m x 1e9"),
    ("displacement_nm", lambda v, d: v.max() < 0.05 and d >= 0.1, "um", "nm = um x 1000"),
    ("diameter_um", lambda v, d: v.max() < 1e-4, "metres (m)", "um = m x 1e6"),
    ("diameter_um", lambda v, d: v.max() > 100.0, "nm", "um = nm / 1000"),
)
_NAMES = {"force_nN": ("forces", "nN"), "displacement_nm": ("displacements", "nm"), "diameter_um": ("diameter", "um")}


def bubble_problems(bubble: str, columns: dict[str, np.ndarray], rows: list[int]) -> list[tuple[str, str]]:
    """Columns of one bubble whose values look like another unit, with a message naming the probable unit.

    Parameters
    ----------
    bubble : str
        The bubble's id (for the message).
    columns : dict of str to numpy.ndarray
        ``diameter_um`` [um], ``displacement_nm`` [nm] and ``force_nN`` [nN] of the bubble's rows (NaN where a
        cell was unreadable).
    rows : list of int
        The 1-based data rows of the bubble.

    Returns
    -------
    list of (str, str)
        (column, message) per column that looks like another unit; empty when none does.
    """
    diameter = columns["diameter_um"][np.isfinite(columns["diameter_um"])]
    d = float(np.median(diameter)) if diameter.size else float("nan")
    out = []
    span = f"rows {rows[0]}-{rows[-1]}" if len(rows) > 1 else f"row {rows[0]}"
    for column, test, meant, factor in _SNIFFS:
        values = columns[column][np.isfinite(columns[column])]
        if not values.size or any(c == column for c, _ in out) or not test(values, d):
            continue
        what, unit = _NAMES[column]
        out.append((column, f"bubble {bubble!r} ({span}), column {column!r}: {what} {values.min():.3g} to "
                            f"{values.max():.3g} look like {meant}: give {unit} ({factor})"))
    return out
