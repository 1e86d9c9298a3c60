"""The classical shelled-bubble resonance (linearised Marmottant model, de Jong-type shell), a physics baseline.

    f0 = 1 / (2 pi R) sqrt( (3 kappa p0 + 2 (3 kappa - 1) sigma / R + 4 chi / R) / rho )

R the bubble radius [m], rho the liquid density [kg/m^3] (the water's inertia carries the mode: added mass
~ rho R^3), p0 the ambient pressure [Pa], kappa the polytropic exponent of the gas [-], sigma the shell's surface
tension at rest [N/m] and chi the shell's elastic (area-dilation) modulus [N/m], here the stretching modulus
k_a converted to N/m (:meth:`bubblecal.data.UnitSystem.modulus2d_to_physical`; k_a 5,584 DPD = 0.05 N/m). Shell
viscosity only damps and does not enter f0. The DPD implicit tier carries no liquid inertia; comparing the two
scalings over the diameter is the point (docs/decisions.md).
"""

from __future__ import annotations

import numpy as np

from bubblecal.data import DEFAULT_UNITS, UnitSystem

__all__ = ["classical_f0", "diameter_exponent", "P0_PA", "KAPPA_POLYTROPIC", "SIGMA_REST_N_PER_M"]

#: Ambient pressure p0 [Pa] (one standard atmosphere).
P0_PA = 101_325.0
#: Polytropic exponent kappa [-] of the perfluorocarbon / SF6 gas core (adiabatic, Marmottant's value).
KAPPA_POLYTROPIC = 1.07
#: Shell surface tension at rest sigma(R0) [N/m]: a tension-free shell (the elastic regime at its buckling radius).
SIGMA_REST_N_PER_M = 0.0


def classical_f0(ka, diameter_um, *, kappa: float = KAPPA_POLYTROPIC, sigma_N_per_m: float = SIGMA_REST_N_PER_M,
                 p0_Pa: float = P0_PA, rho_kg_m3: float | None = None, units: UnitSystem = DEFAULT_UNITS):
    """Linear resonance frequency of a shelled bubble [MHz] (module docstring for the formula).

    Parameters
    ----------
    ka : float or array_like
        Shell stretching modulus [DPD 2-D modulus]; chi = ka in N/m through ``units``.
    diameter_um : float or array_like
        Bubble diameter [um]; broadcasts against ``ka``.
    kappa : float
        Polytropic exponent of the gas [-].
    sigma_N_per_m : float
        Shell surface tension at rest [N/m].
    p0_Pa : float
        Ambient pressure [Pa].
    rho_kg_m3 : float or None
        Liquid density [kg/m^3] (None: ``units.rho_water``, 997 kg/m^3).
    units : UnitSystem
        The DPD unit system.

    Returns
    -------
    numpy.ndarray
        f0 [MHz].

    Raises
    ------
    ValueError
        For a non-positive diameter, density or pressure.
    """
    rho = units.rho_water if rho_kg_m3 is None else float(rho_kg_m3)
    r = 0.5e-6 * np.asarray(diameter_um, dtype=float)
    if np.any(~(r > 0)) or not rho > 0 or not p0_Pa > 0:
        raise ValueError(f"classical_f0 needs diameters > 0 um, rho > 0 and p0 > 0 (got diameter(s) "
                         f"{np.asarray(diameter_um).ravel()[:4]}, rho {rho}, p0 {p0_Pa})")
    chi = units.modulus2d_to_physical(ka)
    stiff = 3.0 * kappa * p0_Pa + 2.0 * (3.0 * kappa - 1.0) * sigma_N_per_m / r + 4.0 * chi / r
    return np.sqrt(stiff / rho) / (2.0 * np.pi * r) / 1e6


def diameter_exponent(diameter_um, f_MHz) -> float:
    """d ln f / d ln D: the slope of a least-squares line through (ln D, ln f).

    Parameters
    ----------
    diameter_um : array_like
        Diameters [um] (at least two distinct).
    f_MHz : array_like
        Frequencies [MHz] (> 0).

    Returns
    -------
    float
        The exponent (-1 for f ~ 1/D).

    Raises
    ------
    ValueError
        For fewer than two distinct diameters or a non-positive frequency.
    """
    d, f = np.asarray(diameter_um, dtype=float), np.asarray(f_MHz, dtype=float)
    if np.unique(d).size < 2 or np.any(~(f > 0)) or np.any(~(d > 0)):
        raise ValueError("diameter_exponent needs >= 2 distinct positive diameters and positive frequencies")
    return float(np.polyfit(np.log(d), np.log(f), 1)[0])
