"""The unit system: its defining constants, the derived base units and the default instance.

The conversion methods come from :mod:`bubblecal.data.units.quantities` (lengths, forces, moduli, pressure,
time, frequency, bubble size) and :mod:`bubblecal.data.units.shell` (Young's modulus and the shell constants).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bubblecal.data.units.quantities import _QuantityConversions
from bubblecal.data.units.shell import _ShellConversions

__all__ = ["K_BOLTZMANN", "UnitSystem", "DEFAULT_UNITS", "radius_dpd_from_diameter_um"]

#: Boltzmann constant used by Mirheo's parameter file [J/K].
K_BOLTZMANN = 1.3805e-23


@dataclass(frozen=True)
class UnitSystem(_QuantityConversions, _ShellConversions):
    """Frozen description of the DPD unit system and the shell's force scale.

    Parameters
    ----------
    length_m : float
        Length unit u_l = DPD cutoff r_c [m].
    temperature_K : float
        Temperature T [K]; the energy unit is u_e = k_B T.
    k_boltzmann : float
        Boltzmann constant [J/K].
    rho_water : float
        Water density [kg/m^3]; sets the mass and time units.
    fscale : float
        Dimensionless force scale of shell quantities (experiment -> simulation).
    shell_thickness_m : float
        Shell thickness h [m].
    poisson : float
        Poisson ratio nu of the shell [-], in (-1, 0.5].
    number_density : float
        DPD water number density [1/u_l^3].

    Raises
    ------
    ValueError
        If a constant other than ``poisson`` is not a positive finite number, or ``poisson`` lies outside
        (-1, 0.5].
    """

    length_m: float = 0.25e-6
    temperature_K: float = 300.0
    k_boltzmann: float = K_BOLTZMANN
    rho_water: float = 997.0
    fscale: float = 0.0074
    shell_thickness_m: float = 5e-9
    poisson: float = 0.5
    number_density: float = 3.0

    def __post_init__(self) -> None:
        for name in ("length_m", "temperature_K", "k_boltzmann", "rho_water", "fscale",
                     "shell_thickness_m", "number_density"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"UnitSystem.{name} must be a positive finite number, got {value!r}")
        if not (-1.0 < self.poisson < 0.5 + 1e-12):
            raise ValueError(f"UnitSystem.poisson must lie in (-1, 0.5], got {self.poisson!r}")

    # ----- base units -------------------------------------------------------------------
    @property
    def energy_J(self) -> float:
        """Energy unit u_e = k_B T [J]."""
        return self.k_boltzmann * self.temperature_K

    @property
    def mass_kg(self) -> float:
        """Mass unit u_m = rho_water u_l^3 / number_density [kg]."""
        return self.rho_water * self.length_m**3 / self.number_density

    @property
    def time_s(self) -> float:
        """Time unit u_t = sqrt(u_m u_l^2 / u_e) [s]."""
        return math.sqrt(self.mass_kg * self.length_m**2 / self.energy_J)

    @property
    def force_N(self) -> float:
        """Force unit u_e/u_l [N] (without fscale)."""
        return self.energy_J / self.length_m

    @property
    def modulus2d_N_per_m(self) -> float:
        """2-D modulus unit u_e/u_l^2 [N/m] (without fscale)."""
        return self.energy_J / self.length_m**2

    @property
    def pressure_Pa(self) -> float:
        """Pressure unit u_e/u_l^3 [Pa] (solvent pressure; fscale does not apply)."""
        return self.energy_J / self.length_m**3

    @property
    def yt_per_ka(self) -> float:
        """Published sampling variable per unit k_a: Yt [Pa] = yt_per_ka * k_a [Pa per DPD 2-D modulus]."""
        return self.modulus2d_N_per_m / (self.shell_thickness_m * self.fscale)


#: The unit system of the published data; use it unless you know why not.
DEFAULT_UNITS = UnitSystem()


def radius_dpd_from_diameter_um(diameter_um: float, units: UnitSystem = DEFAULT_UNITS) -> float:
    """Bubble diameter [um] -> DPD radius [DPD length].

    Parameters
    ----------
    diameter_um : float
        Bubble diameter [um].
    units : UnitSystem
        The unit system (default :data:`DEFAULT_UNITS`: 2.1 um -> 4.2).

    Returns
    -------
    float
        Bubble radius [DPD length].
    """
    return float(units.radius_dpd(diameter_um))
