"""The acoustic law at one diameter: a least-squares quadratic of f_res^2 in k_a, with leave-one-out errors.

    f_res(k_a; d)^2 = a0 + a1 k_a + a2 k_a^2,     f_res in **physical MHz**, k_a in **DPD units**

The quadratic has a free intercept and is fitted in a scaled variable k_a / max|k_a| for conditioning. One
:class:`DiameterFit` per simulated diameter makes an :class:`~bubblecal.surrogates.AcousticSurrogate`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field

import numpy as np

__all__ = ["DiameterFit", "fit_quadratic"]


@dataclass
class DiameterFit:
    """Quadratic f_res^2 = a0 + a1 ka + a2 ka^2 at one diameter, with its leave-one-out errors.

    Parameters
    ----------
    diameter_um : float
        Bubble diameter [um].
    a0, a1, a2 : float
        Coefficients [MHz^2, MHz^2 per DPD 2-D modulus, MHz^2 per (DPD 2-D modulus)^2].
    ka_min, ka_max : float
        Fitted k_a range [DPD 2-D modulus].
    n_points : int
        Points fitted.
    loo_rel_errors : list of float
        Leave-one-out relative errors of f_res (empty for fewer than 4 points).
    meta : dict
        Provenance.
    """

    diameter_um: float
    a0: float
    a1: float
    a2: float
    ka_min: float
    ka_max: float
    n_points: int
    loo_rel_errors: list[float]
    meta: dict = field(default_factory=dict)

    @property
    def loo_max(self) -> float:
        """Largest leave-one-out relative error (NaN when none)."""
        return float(np.max(self.loo_rel_errors)) if self.loo_rel_errors else float("nan")

    @property
    def loo_median(self) -> float:
        """Median leave-one-out relative error (NaN when none)."""
        return float(np.median(self.loo_rel_errors)) if self.loo_rel_errors else float("nan")

    def to_dict(self) -> dict:
        """Every field plus ``loo_max`` and ``loo_median`` (an entry of the JSON file's ``diameters``)."""
        d = asdict(self)
        d.update({"loo_max": self.loo_max, "loo_median": self.loo_median})
        return d


def fit_quadratic(ka, f_res, diameter_um: float, meta: Mapping | None = None) -> DiameterFit:
    """Least-squares quadratic of f_res^2 against ka (free intercept) plus leave-one-out relative errors.

    Pairs with a non-finite value or f_res <= 0 are dropped; LOO errors are |f_hat - f| / f of f_res.

    Parameters
    ----------
    ka : array_like
        Stretching moduli [DPD 2-D modulus].
    f_res : array_like
        Resonance frequencies [MHz] (physical, mass factor applied).
    diameter_um : float
        Bubble diameter [um].
    meta : Mapping, optional
        Provenance stored with the fit.

    Returns
    -------
    DiameterFit
        The coefficients, the fitted k_a range and the LOO errors.

    Raises
    ------
    ValueError
        For fewer than 3 distinct k_a values with finite f_res > 0.
    """
    ka = np.asarray(ka, dtype=float)
    f = np.asarray(f_res, dtype=float)
    ok = np.isfinite(ka) & np.isfinite(f) & (f > 0)
    ka, f = ka[ok], f[ok]
    if ka.size < 3 or np.unique(ka).size < 3:
        raise ValueError(f"diameter {diameter_um} um: need >= 3 distinct ka values with finite f_res > 0, "
                         f"got {np.unique(ka).size}")
    # fit in a scaled variable for conditioning, then convert back
    s = float(np.max(np.abs(ka)))
    q = np.polynomial.polynomial.polyfit(ka / s, f**2, 2)
    a0, a1, a2 = q[0], q[1] / s, q[2] / s**2
    loo = []
    if ka.size >= 4:
        for i in range(ka.size):
            m = np.arange(ka.size) != i
            qi = np.polynomial.polynomial.polyfit(ka[m] / s, f[m] ** 2, 2)
            f2 = qi[0] + qi[1] * ka[i] / s + qi[2] * (ka[i] / s) ** 2
            loo.append(float(abs(math.sqrt(max(f2, 0.0)) - f[i]) / f[i]))
    return DiameterFit(diameter_um=float(diameter_um), a0=float(a0), a1=float(a1), a2=float(a2),
                       ka_min=float(ka.min()), ka_max=float(ka.max()), n_points=int(ka.size), loo_rel_errors=loo,
                       meta=dict(meta or {}))
