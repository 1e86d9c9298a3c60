"""Per-replica physical settings of the implicit-solvent shell system (Warp-free).

:func:`implicit_settings` turns the scalar-or-per-replica arguments of
:class:`~bubblecal.sim.engine.implicit.ImplicitShellSystem` into checked [R] arrays: gas content, pressures,
temperature, Langevin friction, vertex mass and seeds (DPD units; docs/physics.md section 7).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bubblecal.sim.engine.mesh import ShellMesh
from bubblecal.sim.engine.particles import VERTEX, WATER, published_pair_table

__all__ = ["GAS_P0_DEFAULT", "default_vertex_friction", "ImplicitSettings", "implicit_settings"]

#: Gas pressure at the reference volume (= number density 3 at k_BT = 1, the explicit tier's choice).
GAS_P0_DEFAULT = 3.0


def default_vertex_friction(mesh: ShellMesh, protocol: str = "compression") -> float:
    """Langevin friction of one vertex: gamma_fsi rho_w pi / 18 (about 2.2 for a 3 um subdivision-4 bubble).

    gamma_fsi is the published vertex-water DPD friction for this mesh's vertex density
    (:func:`bubblecal.sim.engine.particles.published_pair_table`); pi/18 rho_w = the integral of the s = 1/2
    dissipative weight w^2 = 1 - r over a half-space of water at number density rho_w = 3, projected
    on one direction (1/3).

    Parameters
    ----------
    mesh : ShellMesh
        The shell (its vertex density sets gamma_fsi).
    protocol : str, optional
        ``"compression"`` or ``"indentation"`` (published pair table).

    Returns
    -------
    float
        Friction in DPD mass / DPD time.
    """
    tab = published_pair_table(mesh.n_vertices / mesh.area(), protocol)
    return float(tab.gamma[VERTEX, WATER] * 3.0 * math.pi / 18.0)


def _per_replica(value, R: int, name: str, allow_none: bool = False) -> np.ndarray | None:
    """A scalar or [R] value as a finite float64 array [R] (ValueError otherwise)."""
    if value is None:
        if allow_none:
            return None
        raise ValueError(f"{name} must be given")
    a = np.atleast_1d(np.asarray(value, dtype=np.float64))
    if a.size == 1:
        a = np.full(R, float(a[0]))
    if a.shape != (R,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be a finite scalar or one value per replica ({R}), got shape {a.shape}")
    return a


@dataclass(frozen=True)
class ImplicitSettings:
    """Checked per-replica settings ([R] float64 arrays unless stated; DPD units).

    Attributes
    ----------
    gas_number : numpy.ndarray
        Ideal-gas particle number N_g (NaN where k_BT = 0 and the gas was given by ``p0``).
    nkt : numpy.ndarray
        N_g k_BT (DPD energy).
    p_back, p_water : numpy.ndarray
        Outward back and inward ambient pressures (DPD pressure).
    kbt : numpy.ndarray
        Thermal energy (k_BT units).
    gamma : numpy.ndarray
        Langevin friction per vertex (DPD mass / time).
    vertex_mass : numpy.ndarray
        DPD mass per vertex.
    seeds : numpy.ndarray
        [R] int64 seeds as given (or derived from the base seed).
    hashed_seeds : numpy.ndarray
        [R] int32 seeds of the device random streams.
    """

    gas_number: np.ndarray
    nkt: np.ndarray
    p_back: np.ndarray
    p_water: np.ndarray
    kbt: np.ndarray
    gamma: np.ndarray
    vertex_mass: np.ndarray
    seeds: np.ndarray
    hashed_seeds: np.ndarray


def implicit_settings(meshes: Sequence[ShellMesh], volume0: np.ndarray, *, gas_number, p0, p_back, p_water, kbt,
                      gamma, vertex_mass, seed) -> ImplicitSettings:
    """Check and expand the physical arguments of an implicit system to one value per replica.

    Parameters
    ----------
    meshes : sequence of ShellMesh
        One reference mesh per replica (R = its length).
    volume0 : numpy.ndarray
        [R] reference enclosed volumes (DPD length^3).
    gas_number, p0, p_back, p_water, kbt, gamma, vertex_mass, seed
        As in :class:`~bubblecal.sim.engine.implicit.ImplicitShellSystem` (scalars or [R]).

    Returns
    -------
    ImplicitSettings

    Raises
    ------
    ValueError
        On a value that is not finite, not one per replica, or negative (``vertex_mass``: not positive).
    """
    R = len(meshes)
    kbt_a = _per_replica(kbt, R, "kbt")
    if np.any(kbt_a < 0):
        raise ValueError("kbt must be >= 0")
    if gas_number is None:
        p0_a = _per_replica(p0, R, "p0")
        if np.any(p0_a < 0):
            raise ValueError("p0 must be >= 0 (DPD pressure)")
        nkt = p0_a * volume0
        gas_number_a = np.where(kbt_a > 0, nkt / np.where(kbt_a > 0, kbt_a, 1.0), np.nan)
    else:
        gas_number_a = _per_replica(gas_number, R, "gas_number")
        if np.any(gas_number_a < 0):
            raise ValueError("gas_number must be >= 0")
        nkt = gas_number_a * kbt_a
    pb = _per_replica(p_back, R, "p_back")
    pw = pb + nkt / volume0 if p_water is None else _per_replica(p_water, R, "p_water")
    g = (_per_replica(default_vertex_friction(meshes[0]), R, "gamma") if gamma is None
         else _per_replica(gamma, R, "gamma"))
    if np.any(g < 0):
        raise ValueError("gamma must be >= 0 (DPD mass / time)")
    mv = (np.array([m.vertex_mass() for m in meshes]) if vertex_mass is None
          else _per_replica(vertex_mass, R, "vertex_mass"))
    if np.any(mv <= 0):
        raise ValueError("vertex_mass must be > 0")
    seeds = (np.asarray(seed, dtype=np.int64).reshape(-1) if np.ndim(seed) else
             np.asarray([int(seed) * 7919 + r for r in range(R)], dtype=np.int64))
    if seeds.shape != (R,):
        raise ValueError(f"seed must be an int or one int per replica ({R})")
    hashed = np.array([np.random.SeedSequence([int(s) % (2**63), r]).generate_state(1)[0] % (2**30)
                       for r, s in enumerate(seeds)], dtype=np.int32)
    return ImplicitSettings(gas_number=gas_number_a, nkt=nkt, p_back=pb, p_water=pw, kbt=kbt_a, gamma=g,
                            vertex_mass=mv, seeds=seeds, hashed_seeds=hashed)
