"""Physical plausibility bounds of every measured quantity a user's file carries (defined once, here).

A value can be a finite, non-negative number and still no AFM or acoustic measurement of a microbubble: a force
of 1e300, a curve whose forces are all zero, a resonance at 1e300 MHz. Such values pass a format check and
then make the likelihood non-finite, so the readers (:func:`bubblecal.data.load_curve`,
:func:`bubblecal.data.load_acoustic_table`) refuse them with the quantity, its unit and the allowed range.
The bounds are generous on purpose (docs/data-formats.md, "Plausibility bounds"): they bracket every AFM
cantilever and every ultrasound contrast agent by orders of magnitude, and only catch what cannot be a
measurement (a unit slip by 1e3 still passes; 1e9 does not).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PlausibleRange", "PLAUSIBLE_RANGES", "plausibility_problems"]


@dataclass(frozen=True)
class PlausibleRange:
    """Allowed values of one measured quantity, in its physical unit.

    Parameters
    ----------
    quantity : str
        'force', 'displacement', 'diameter' or 'resonance_frequency'.
    unit : str
        Physical unit of ``lo``, ``hi`` and ``min_largest`` ("nN", "nm", "um", "MHz").
    lo, hi : float
        Every value must lie in [lo, hi].
    min_largest : float
        The largest value of one curve or table column must reach this (an all-zero force curve carries no signal).
    why : str
        One line saying what the bounds bracket.
    """

    quantity: str
    unit: str
    lo: float
    hi: float
    min_largest: float
    why: str

    def describe(self) -> str:
        """``"[lo, hi] unit"``, e.g. ``"[0, 1e+04] nN"``."""
        return f"[{self.lo:g}, {self.hi:g}] {self.unit}"


#: Plausible ranges per quantity (physical units; docs/data-formats.md "Plausibility bounds").
PLAUSIBLE_RANGES: dict[str, PlausibleRange] = {
    "force": PlausibleRange("force", "nN", 0.0, 1.0e4, 1.0e-3,
                            "AFM forces on a microbubble: pN to tens of nN; 10 uN bends the stiffest cantilevers"),
    "displacement": PlausibleRange("displacement", "nm", 0.0, 1.0e5, 0.1,
                                   "deformations of a bubble of at most 100 um; 0.1 nm is below AFM resolution"),
    "diameter": PlausibleRange("diameter", "um", 0.1, 100.0, 0.1,
                               "contrast-agent microbubbles are 0.5-10 um; 0.1-100 um brackets any of them"),
    "resonance_frequency": PlausibleRange("resonance_frequency", "MHz", 0.01, 200.0, 0.01,
                                          "bubble resonances lie at 0.1-30 MHz; 10 kHz-200 MHz brackets them"),
}


def plausibility_problems(quantity: str, values_physical, labels: list[str], shown=None,
                          shown_unit: str | None = None) -> list[str]:
    """Problems of one column of values against :data:`PLAUSIBLE_RANGES` (one line per value out of range).

    Parameters
    ----------
    quantity : str
        A key of :data:`PLAUSIBLE_RANGES`.
    values_physical : array_like
        The column in the quantity's physical unit (nN, nm, um, MHz); NaN entries (already reported as
        unreadable) are skipped.
    labels : list of str
        Where each value sits, e.g. ``"row 3 (line 4), column 'force_dpd'"``; same length as the values.
    shown : array_like, optional
        The values as written in the file (e.g. in DPD units) for the message; default ``values_physical``.
    shown_unit : str, optional
        Unit of ``shown`` (e.g. "DPD force"); default the quantity's physical unit.

    Returns
    -------
    list of str
        Empty when every value is plausible and the largest reaches ``min_largest``.

    Raises
    ------
    KeyError
        ``quantity`` is not a key of :data:`PLAUSIBLE_RANGES`.
    """
    rng = PLAUSIBLE_RANGES[quantity]
    phys = np.asarray(values_physical, dtype=float)
    written = phys if shown is None else np.asarray(shown, dtype=float)
    unit = shown_unit or rng.unit
    problems = []
    for k in np.flatnonzero(np.isfinite(phys) & ((phys < rng.lo) | (phys > rng.hi))):
        converted = "" if shown is None else f" (= {phys[k]:.4g} {rng.unit})"
        problems.append(f"{labels[k]}: {quantity} {written[k]:g} {unit}{converted} is outside the plausible range "
                        f"{rng.describe()} ({rng.why})")
    finite = phys[np.isfinite(phys)]
    if finite.size and not problems and finite.max() < rng.min_largest:
        problems.append(f"every {quantity} is below {rng.min_largest:g} {rng.unit} (largest {finite.max():.4g} "
                        f"{rng.unit}): the {quantity} column carries no signal (plausible range {rng.describe()})")
    return problems
