"""Particle types, per-type-pair DPD parameters and masses (docs/physics.md section 2).

Types (integers stored per particle):

====  ===========  ===========================================================
id    name         role
====  ===========  ===========================================================
0     ``water``    solvent outside the shell (a = 100, gamma = 3.5, s = 0.25)
1     ``gas``      ideal gas inside the shell (a = 0, gamma = 11, s = 0.5)
2     ``vertex``   shell vertex (lives in the vertex arrays, not the solvent arrays)
3     ``wall``     frozen particles (plates); never integrated
====  ===========  ===========================================================

A :class:`PairTable` holds the symmetric (a, gamma, s) matrices of one replica. Pairs with
``a == 0 and gamma == 0`` do not interact (water-gas in the published set, where the shell
separates them anyway). ``s`` shapes the dissipative and random weights only; the conservative
weight is always linear.

The fluid-structure friction follows docs/physics.md section 2:
``gamma_fsi = fscale 2 eta (2k+1)(2k+2)(2k+3)(2k+4) / (3 pi r_c^4 rho n_s)`` with k = s = 0.5,
``n_s`` the number of vertices per unit area of the membrane and ``rho`` the number density of the
fluid on that side. Viscosities are converted with the unit system of :mod:`bubblecal.data.units`
(viscosity unit = pressure unit x time unit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bubblecal.data import DEFAULT_UNITS, UnitSystem

WATER, GAS, VERTEX, WALL = 0, 1, 2, 3
N_TYPES = 4
TYPE_NAMES = ("water", "gas", "vertex", "wall")

#: Published water viscosity in DPD units (docs/physics.md section 2).
ETA_WATER_DPD = 379.3
#: Gas viscosity [Pa s] (docs/physics.md section 2).
ETA_GAS_PA_S = 1.86e-5
#: Published gas mass density [kg/m^3] of the compression set.
RHO_GAS_KG_M3 = 11.2
#: Shell mass density [kg/m^3].
RHO_SHELL_KG_M3 = 1100.0
#: Published back pressure (DPD pressure, docs/physics.md section 3).
P_BACK_DEFAULT = 91.0

__all__ = [
    "WATER", "GAS", "VERTEX", "WALL", "N_TYPES", "TYPE_NAMES", "PairTable", "viscosity_to_dpd",
    "gamma_fsi", "gas_mass", "vertex_mass", "published_pair_table", "fluid_pair_table",
    "ETA_WATER_DPD", "ETA_GAS_PA_S", "RHO_GAS_KG_M3", "RHO_SHELL_KG_M3", "P_BACK_DEFAULT",
]


def viscosity_to_dpd(eta_pa_s: float, units: UnitSystem = DEFAULT_UNITS) -> float:
    """Dynamic viscosity in Pa s -> DPD units (u_e u_t / u_l^3).

    Parameters
    ----------
    eta_pa_s : float
        Viscosity (Pa s).
    units : UnitSystem, optional
        Unit system.

    Returns
    -------
    float
        Viscosity (DPD pressure x DPD time).
    """
    return float(eta_pa_s) / (units.pressure_Pa * units.time_s)


def gamma_fsi(eta_dpd: float, rho: float, n_s: float, s: float = 0.5, units: UnitSystem = DEFAULT_UNITS,
              rc: float = 1.0) -> float:
    """Fluid-structure dissipative coefficient of docs/physics.md section 2.

    gamma_fsi = fscale 2 eta (2k+1)(2k+2)(2k+3)(2k+4) / (3 pi r_c^4 rho n_s).

    Parameters
    ----------
    eta_dpd : float
        Fluid viscosity (DPD units).
    rho : float
        Fluid number density (1 / DPD length^3).
    n_s : float
        Vertices per unit membrane area (1 / DPD length^2).
    s : float, optional
        The exponent k of the dissipative weight (0.5 in the published sets).
    units : UnitSystem, optional
        Unit system (its force scale ``fscale``).
    rc : float, optional
        Cut-off radius (DPD length).

    Returns
    -------
    float
        gamma (DPD mass / DPD time).
    """
    k = float(s)
    num = units.fscale * 2.0 * eta_dpd * (2 * k + 1) * (2 * k + 2) * (2 * k + 3) * (2 * k + 4)
    return num / (3.0 * math.pi * rc**4 * rho * n_s)


def gas_mass(rho_gas_kg_m3: float = RHO_GAS_KG_M3, units: UnitSystem = DEFAULT_UNITS) -> float:
    """Mass of a gas bead, rho_gas / rho_water (water bead mass 1).

    Parameters
    ----------
    rho_gas_kg_m3 : float, optional
        Gas mass density (kg/m^3).
    units : UnitSystem, optional
        Unit system (water density).

    Returns
    -------
    float
        Bead mass (DPD mass).
    """
    return float(rho_gas_kg_m3) / units.rho_water


def vertex_mass(area_mesh_dpd: float, n_vertices: int, rho_shell_kg_m3: float = RHO_SHELL_KG_M3,
                mass_factor: float = 1.0, units: UnitSystem = DEFAULT_UNITS) -> float:
    """Shell vertex mass rho_shell h A_mesh u_l^2 / (u_m N_v) x mass_factor (docs/physics.md section 2).

    Parameters
    ----------
    area_mesh_dpd : float
        Mesh area (DPD length^2).
    n_vertices : int
        Number of vertices.
    rho_shell_kg_m3 : float, optional
        Shell density (kg/m^3).
    mass_factor : float, optional
        Factor on the mass.
    units : UnitSystem, optional
        Unit system (shell thickness h, u_l, u_m).

    Returns
    -------
    float
        Vertex mass (DPD mass).
    """
    m = rho_shell_kg_m3 * units.shell_thickness_m * area_mesh_dpd * units.length_m**2 / (units.mass_kg * n_vertices)
    return float(m * mass_factor)


@dataclass
class PairTable:
    """Symmetric per-type-pair DPD parameters and per-type masses of one replica.

    Parameters
    ----------
    a : numpy.ndarray, optional
        [N_TYPES, N_TYPES] conservative amplitudes (DPD force); default 0.
    gamma : numpy.ndarray, optional
        [N_TYPES, N_TYPES] dissipative coefficients (DPD mass / time); default 0.
    s : numpy.ndarray, optional
        [N_TYPES, N_TYPES] exponents of the dissipative / random weight; default 0.5.
    mass : numpy.ndarray, optional
        [N_TYPES] bead masses (DPD mass); default 1.
    """

    a: np.ndarray = field(default_factory=lambda: np.zeros((N_TYPES, N_TYPES)))
    gamma: np.ndarray = field(default_factory=lambda: np.zeros((N_TYPES, N_TYPES)))
    s: np.ndarray = field(default_factory=lambda: np.full((N_TYPES, N_TYPES), 0.5))
    mass: np.ndarray = field(default_factory=lambda: np.ones(N_TYPES))

    def set(self, t1: int, t2: int, a: float, gamma: float, s: float) -> PairTable:
        """Set the (a, gamma, s) of the pair of types (t1, t2), symmetrically.

        Parameters
        ----------
        t1, t2 : int
            Particle types (``WATER``, ``GAS``, ``VERTEX``, ``WALL``).
        a : float
            Conservative amplitude (DPD force).
        gamma : float
            Dissipative coefficient (DPD mass / time).
        s : float
            Weight exponent.

        Returns
        -------
        PairTable
            ``self``.
        """
        for i, j in ((t1, t2), (t2, t1)):
            self.a[i, j] = a
            self.gamma[i, j] = gamma
            self.s[i, j] = s
        return self

    def copy(self) -> PairTable:
        """An independent copy."""
        return PairTable(self.a.copy(), self.gamma.copy(), self.s.copy(), self.mass.copy())

    def validate(self) -> None:
        """Check shapes, symmetry and ranges.

        Raises
        ------
        ValueError
            When a matrix is not N_TYPES x N_TYPES, not symmetric or not finite, gamma < 0, s <= 0, or a water, gas
            or vertex mass is not positive.
        """
        for name in ("a", "gamma", "s"):
            m = np.asarray(getattr(self, name), dtype=float)
            if m.shape != (N_TYPES, N_TYPES):
                raise ValueError(f"PairTable.{name} must be {N_TYPES}x{N_TYPES}")
            if not np.allclose(m, m.T):
                raise ValueError(f"PairTable.{name} must be symmetric")
            if not np.all(np.isfinite(m)):
                raise ValueError(f"PairTable.{name} must be finite")
        if np.any(self.gamma < 0) or np.any(self.s <= 0):
            raise ValueError("gamma must be >= 0 and s > 0")
        if np.any(self.mass[[WATER, GAS, VERTEX]] <= 0):
            raise ValueError("masses of water, gas and vertex must be > 0")

    def as_dict(self) -> dict:
        """The table as nested lists (JSON-friendly)."""
        return {"a": self.a.tolist(), "gamma": self.gamma.tolist(), "s": self.s.tolist(), "mass": self.mass.tolist()}


def fluid_pair_table(a: float = 25.0, gamma: float = 4.5, s: float = 0.5) -> PairTable:
    """A single-component water fluid (the equation-of-state checks); all other pairs inert.

    Parameters
    ----------
    a : float, optional
        Water-water conservative amplitude (DPD force).
    gamma : float, optional
        Water-water dissipative coefficient (DPD mass / time).
    s : float, optional
        Weight exponent.

    Returns
    -------
    PairTable
    """
    t = PairTable()
    t.set(WATER, WATER, a, gamma, s)
    return t


def published_pair_table(
    n_s: float,
    protocol: str = "compression",
    *,
    a_vertex_water: float | None = None,
    rho_water_number: float = 3.0,
    rho_gas_number: float = 3.0,
    rho_gas_kg_m3: float = RHO_GAS_KG_M3,
    m_vertex: float = 1.0,
    fsi_friction_factor: float = 1.0,
    a_water: float = 100.0,
    units: UnitSystem = DEFAULT_UNITS,
) -> PairTable:
    """The published interaction set (docs/physics.md section 2).

    water-water (100, 3.5, 0.25); gas-gas (0, 11, 0.5); water-gas none; vertex-water (400 compression / 40
    indentation, a choice overridable with ``a_vertex_water``; gamma_fsi; 0.5); vertex-gas (0, gamma_fsi,gas, 0.5).

    Parameters
    ----------
    n_s : float
        Vertices per unit membrane area (1 / DPD length^2).
    protocol : str, optional
        ``"compression"`` or ``"indentation"``.
    a_vertex_water : float, optional
        Overrides the vertex-water amplitude (DPD force).
    rho_water_number : float, optional
        Water number density (enters gamma_fsi).
    rho_gas_number : float, optional
        Gas number density (a choice, default 3; enters gamma_fsi,gas; 0: no gas, no vertex-gas friction).
    rho_gas_kg_m3 : float, optional
        Gas mass density (kg/m^3; sets the gas bead mass).
    m_vertex : float, optional
        Vertex mass (DPD mass).
    fsi_friction_factor : float, optional
        Multiplies both vertex-solvent dissipative coefficients (gamma_fsi of water and gas); the thermostat's
        pairs keep fluctuation-dissipation, so an equilibrium observable does not depend on it, only how fast the
        shell reaches it.
    a_water : float, optional
        Water-water repulsion (DPD force; the published 100 gives a bulk pressure of about 94 at density 3, which
        the back pressure balances: change both together).
    units : UnitSystem, optional
        Unit system.

    Returns
    -------
    PairTable

    Raises
    ------
    ValueError
        On an unknown protocol, a ``fsi_friction_factor`` that is not > 0 or an ``a_water`` that is not finite
        and >= 0.
    """
    if protocol not in ("compression", "indentation"):
        raise ValueError("protocol must be 'compression' or 'indentation'")
    if not fsi_friction_factor > 0:
        raise ValueError(f"fsi_friction_factor must be > 0, got {fsi_friction_factor!r}")
    if not (math.isfinite(a_water) and a_water >= 0):
        raise ValueError(f"a_water must be a finite repulsion >= 0 (DPD force), got {a_water!r}")
    ff = float(fsi_friction_factor)
    if a_vertex_water is None:
        a_vertex_water = 400.0 if protocol == "compression" else 40.0
    t = PairTable()
    t.set(WATER, WATER, float(a_water), 3.5, 0.25)
    t.set(GAS, GAS, 0.0, 11.0, 0.5)
    t.set(VERTEX, WATER, a_vertex_water, ff * gamma_fsi(ETA_WATER_DPD, rho_water_number, n_s, 0.5, units), 0.5)
    eta_gas = viscosity_to_dpd(ETA_GAS_PA_S, units)
    # no gas particles (rho 0, a shell held by its back pressure alone): no vertex-gas pair to weight
    g_gas = ff * gamma_fsi(eta_gas, rho_gas_number, n_s, 0.5, units) if rho_gas_number > 0 else 0.0
    t.set(VERTEX, GAS, 0.0, g_gas, 0.5)
    t.mass[:] = [1.0, gas_mass(rho_gas_kg_m3, units), m_vertex, 1.0]
    return t
