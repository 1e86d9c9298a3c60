"""DPD <-> physical unit conversions: the single source of every conversion factor.

Conventions follow the Mirheo set-up that produced the published training data
(``shared/docs/physics.md`` section 1):

* length unit  u_l = cutoff r_c = 0.25 um (so a bubble of diameter D um has DPD radius D/0.5);
* energy unit  u_e = k_B T at T = 300 K (k_B = 1.3805e-23 J/K, the value of Mirheo's parameter file);
* mass unit    u_m = rho_water u_l^3 / 3 (a water bead has mass 1 at number density 3);
* time unit    u_t = sqrt(u_m u_l^2 / u_e).

**Which water density the time unit uses, and why.** The default is rho_water = 997 kg/m^3, the
value in the simulation parameter file (``parameters-default.emb.yaml``) from which every other
DPD constant of the published set-up was derived, giving u_t = 8.852 us (1/u_t = 0.11296 MHz).
The published PCA frequency table instead used rho = 1000 kg/m^3 (u_t = 8.866 us, 0.15 % longer);
pass ``UnitSystem(rho_water=1000.0)`` to reproduce those numbers exactly.

**Force scale.** Shell quantities carry the factor ``fscale`` = 0.0074 between experiment and
simulation: a physical force F [N] is F_dpd = fscale F / (u_e/u_l), so 1 nN = 446.698 DPD force.
The same factor applies to everything measured on the shell (force, stiffness = force/length,
2-D moduli k_a and mu, bending modulus k_b, Young's modulus).  It does not apply to time,
frequency, length, or to the solvent's thermodynamic pressure (units u_e/u_l^3 = 0.265 Pa).

**Moduli.** With shell thickness h = 5 nm and Poisson ratio nu = 1/2:
k_a = fscale E h / (2(1-nu)) / (u_e/u_l^2);  mu = fscale E h / (2(1+nu)) / (u_e/u_l^2) = k_a/3;
k_b = fscale (2/sqrt 3) E h^3 / (12 (1-nu^2)) / u_e  (2/sqrt 3: Kantor discretisation on a
triangulated sphere).  So E = 10 MPa <-> k_a = 5,584 and the published sampling variable
Yt [Pa] = 1790.92 k_a (= E at nu = 1/2).

**Ringdown mass scale.** Ringdown runs multiply the shell mass by ``mass_factor`` (160 in the
published sweeps); a frequency measured in such a run is converted with f = f_dpd sqrt(M)/u_t.

Parameter names used across the package (one name from TOML to surrogate input):
``ka`` (stretching modulus, DPD 2-D modulus units), ``kb`` (bending, DPD energy), ``b1, b2, a3, a4``
(dimensionless Lim coefficients), ``d0`` (contact/indentation offset, DPD length), ``sigma``,
``sigma_mech``, ``sigma_ac`` (dimensionless relative noise amplitudes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Boltzmann constant used by Mirheo's parameter file [J/K].
K_BOLTZMANN = 1.3805e-23

__all__ = ["K_BOLTZMANN", "UnitSystem", "DEFAULT_UNITS", "radius_dpd_from_diameter_um"]


@dataclass(frozen=True)
class UnitSystem:
    """Frozen description of the DPD unit system and the shell's force scale.

    Attributes (SI units unless stated): ``length_m`` u_l [m]; ``temperature_K`` T [K];
    ``k_boltzmann`` [J/K]; ``rho_water`` [kg/m^3] (sets the mass and time units);
    ``fscale`` dimensionless force scale of shell quantities; ``shell_thickness_m`` h [m];
    ``poisson`` nu [-]; ``number_density`` DPD water number density [1/u_l^3].
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
        """Published sampling variable per unit k_a: Yt[Pa] = yt_per_ka * k_a [Pa per DPD modulus]."""
        return self.modulus2d_N_per_m / (self.shell_thickness_m * self.fscale)

    # ----- length -------------------------------------------------------------------------
    def length_to_dpd(self, length_m):
        """Length [m] -> DPD length [u_l]."""
        return np.asarray(length_m, dtype=float) / self.length_m

    def length_to_physical(self, length_dpd):
        """DPD length [u_l] -> length [m]."""
        return np.asarray(length_dpd, dtype=float) * self.length_m

    def nm_to_dpd(self, length_nm):
        """Length [nm] -> DPD length [u_l] (1 DPD length = 250 nm)."""
        return self.length_to_dpd(np.asarray(length_nm, dtype=float) * 1e-9)

    def dpd_to_nm(self, length_dpd):
        """DPD length [u_l] -> length [nm]."""
        return self.length_to_physical(length_dpd) * 1e9

    # ----- force --------------------------------------------------------------------------
    def force_to_dpd(self, force_N):
        """Shell force [N] -> DPD force (fscale applied): F_dpd = fscale F / (u_e/u_l)."""
        return self.fscale * np.asarray(force_N, dtype=float) / self.force_N

    def force_to_physical(self, force_dpd):
        """DPD force -> shell force [N] (inverse of :meth:`force_to_dpd`)."""
        return np.asarray(force_dpd, dtype=float) * self.force_N / self.fscale

    def nN_to_dpd(self, force_nN):
        """Force [nN] -> DPD force (1 nN = 446.698 DPD force at the defaults)."""
        return self.force_to_dpd(np.asarray(force_nN, dtype=float) * 1e-9)

    def dpd_to_nN(self, force_dpd):
        """DPD force -> force [nN]."""
        return self.force_to_physical(force_dpd) * 1e9

    # ----- stiffness (force per length) -----------------------------------------------------
    def stiffness_to_dpd(self, stiffness_N_per_m):
        """Spring stiffness [N/m] -> DPD force per DPD length (fscale applied)."""
        return self.fscale * np.asarray(stiffness_N_per_m, dtype=float) / (self.force_N / self.length_m)

    def stiffness_to_physical(self, stiffness_dpd):
        """DPD force per DPD length -> stiffness [N/m]."""
        return np.asarray(stiffness_dpd, dtype=float) * (self.force_N / self.length_m) / self.fscale

    # ----- 2-D modulus ----------------------------------------------------------------------
    def modulus2d_to_dpd(self, modulus_N_per_m):
        """2-D modulus (k_a, mu) [N/m] -> DPD units (fscale applied)."""
        return self.fscale * np.asarray(modulus_N_per_m, dtype=float) / self.modulus2d_N_per_m

    def modulus2d_to_physical(self, modulus_dpd):
        """DPD 2-D modulus -> [N/m]."""
        return np.asarray(modulus_dpd, dtype=float) * self.modulus2d_N_per_m / self.fscale

    # ----- pressure -------------------------------------------------------------------------
    def pressure_to_dpd(self, pressure_Pa):
        """Solvent pressure [Pa] -> DPD pressure (u_e/u_l^3; no fscale)."""
        return np.asarray(pressure_Pa, dtype=float) / self.pressure_Pa

    def pressure_to_physical(self, pressure_dpd):
        """DPD pressure -> [Pa]."""
        return np.asarray(pressure_dpd, dtype=float) * self.pressure_Pa

    # ----- time and frequency ---------------------------------------------------------------
    def time_to_dpd(self, time_s):
        """Time [s] -> DPD time [u_t]."""
        return np.asarray(time_s, dtype=float) / self.time_s

    def time_to_physical(self, time_dpd):
        """DPD time [u_t] -> time [s]."""
        return np.asarray(time_dpd, dtype=float) * self.time_s

    def frequency_to_physical(self, frequency_dpd, mass_factor: float = 1.0):
        """Frequency [cycles per u_t] measured with shell mass x mass_factor -> real frequency [Hz].

        f = f_dpd sqrt(mass_factor) / u_t: the ringdown runs with a heavier shell (f ~ M^-1/2).
        """
        if mass_factor <= 0:
            raise ValueError(f"mass_factor must be > 0, got {mass_factor}")
        return np.asarray(frequency_dpd, dtype=float) * math.sqrt(mass_factor) / self.time_s

    def frequency_to_dpd(self, frequency_Hz, mass_factor: float = 1.0):
        """Real frequency [Hz] -> frequency [cycles per u_t] in a run with shell mass x mass_factor."""
        if mass_factor <= 0:
            raise ValueError(f"mass_factor must be > 0, got {mass_factor}")
        return np.asarray(frequency_Hz, dtype=float) * self.time_s / math.sqrt(mass_factor)

    def angular_to_physical_Hz(self, omega_dpd, mass_factor: float = 1.0):
        """Angular frequency [rad per u_t] -> frequency [Hz]: f = omega sqrt(M) / (2 pi u_t)."""
        return self.frequency_to_physical(np.asarray(omega_dpd, dtype=float) / (2 * math.pi), mass_factor)

    # ----- Young's modulus <-> shell constants -----------------------------------------------
    def young_to_ka(self, E_Pa):
        """Young's modulus E [Pa] -> stretching modulus k_a [DPD 2-D modulus]."""
        E = np.asarray(E_Pa, dtype=float)
        return self.modulus2d_to_dpd(E * self.shell_thickness_m / (2.0 * (1.0 - self.poisson)))

    def ka_to_young(self, ka):
        """Stretching modulus k_a [DPD] -> Young's modulus E [Pa]."""
        return self.modulus2d_to_physical(ka) * 2.0 * (1.0 - self.poisson) / self.shell_thickness_m

    def young_to_mu(self, E_Pa):
        """Young's modulus E [Pa] -> shear modulus mu [DPD 2-D modulus] (= k_a/3 at nu = 1/2)."""
        E = np.asarray(E_Pa, dtype=float)
        return self.modulus2d_to_dpd(E * self.shell_thickness_m / (2.0 * (1.0 + self.poisson)))

    def young_to_kb(self, E_Pa):
        """Young's modulus E [Pa] -> Kantor bending constant k_b [DPD energy, k_BT]."""
        E = np.asarray(E_Pa, dtype=float)
        h = self.shell_thickness_m
        kappa = E * h**3 / (12.0 * (1.0 - self.poisson**2))
        return self.fscale * (2.0 / math.sqrt(3.0)) * kappa / self.energy_J

    def kb_to_young(self, kb):
        """Kantor bending constant k_b [DPD] -> Young's modulus E [Pa] (inverse of young_to_kb)."""
        h = self.shell_thickness_m
        kappa = np.asarray(kb, dtype=float) * self.energy_J / (self.fscale * 2.0 / math.sqrt(3.0))
        return kappa * 12.0 * (1.0 - self.poisson**2) / h**3

    def kb_to_bending_kBT(self, kb):
        """Kantor constant k_b [DPD] -> continuum bending modulus kappa [k_B T] = k_b sqrt(3)/(2 fscale)."""
        return np.asarray(kb, dtype=float) * math.sqrt(3.0) / (2.0 * self.fscale)

    def bending_kBT_to_kb(self, kappa_kBT):
        """Continuum bending modulus kappa [k_B T] -> Kantor constant k_b [DPD]."""
        return np.asarray(kappa_kBT, dtype=float) * 2.0 * self.fscale / math.sqrt(3.0)

    def ka_to_yt(self, ka):
        """k_a [DPD] -> published sampling variable Yt [Pa] (= 1790.92 k_a at the defaults)."""
        return np.asarray(ka, dtype=float) * self.yt_per_ka

    def yt_to_ka(self, yt_Pa):
        """Published sampling variable Yt [Pa] -> k_a [DPD]."""
        return np.asarray(yt_Pa, dtype=float) / self.yt_per_ka

    # ----- geometry -----------------------------------------------------------------------
    def radius_dpd(self, diameter_um):
        """Bubble diameter [um] -> DPD radius [u_l] (2.1 um -> 4.2 at u_l = 0.25 um)."""
        return np.asarray(diameter_um, dtype=float) * 1e-6 / (2.0 * self.length_m)


#: The unit system of the published data; use it unless you know why not.
DEFAULT_UNITS = UnitSystem()


def radius_dpd_from_diameter_um(diameter_um: float, units: UnitSystem = DEFAULT_UNITS) -> float:
    """Bubble diameter [um] -> DPD radius [u_l]."""
    return float(units.radius_dpd(diameter_um))
