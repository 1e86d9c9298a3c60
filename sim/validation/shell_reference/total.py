"""Every shell energy term and the total conservative shell force, float64 NumPy (DPD units)."""

from __future__ import annotations

import numpy as np

from bubblecal.sim.engine import ShellMesh, ShellParams
from bubblecal.sim.validation.shell_reference.bending import (
    juelicher_energy,
    juelicher_forces,
    kantor_energy,
    kantor_forces,
)
from bubblecal.sim.validation.shell_reference.constraints import constraint_energies, constraint_forces
from bubblecal.sim.validation.shell_reference.lim import lim_energy, lim_forces
from bubblecal.sim.validation.shell_reference.self_avoid import self_avoid_energy, self_avoid_forces

__all__ = ["shell_energies", "shell_forces"]


def shell_energies(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> np.ndarray:
    """Every energy term, in the order of :data:`bubblecal.sim.engine.ENERGY_TERMS`.

    Parameters
    ----------
    x : numpy.ndarray
        [N_v, 3] positions (DPD length).
    mesh : ShellMesh
        The shell and its stress-free reference.
    p : ShellParams
        Membrane parameters (DPD units).

    Returns
    -------
    numpy.ndarray
        [6] energies (k_BT).
    """
    x = np.asarray(x, dtype=np.float64)
    eb = kantor_energy(x, mesh, p) if p.bending == "kantor" else juelicher_energy(x, mesh, p)
    ea, ev, ep = constraint_energies(x, mesh, p)
    return np.array([lim_energy(x, mesh, p), eb, ea, ev, ep, self_avoid_energy(x, mesh, p)])


def shell_forces(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> np.ndarray:
    """Total conservative shell force -dE/dx on the vertices.

    Parameters
    ----------
    x : numpy.ndarray
        [N_v, 3] positions (DPD length).
    mesh : ShellMesh
        The shell and its stress-free reference.
    p : ShellParams
        Membrane parameters (DPD units).

    Returns
    -------
    numpy.ndarray
        [N_v, 3] (DPD force).
    """
    x = np.asarray(x, dtype=np.float64)
    fb = kantor_forces(x, mesh, p) if p.bending == "kantor" else juelicher_forces(x, mesh, p)
    return (lim_forces(x, mesh, p) + fb + constraint_forces(x, mesh, p) + self_avoid_forces(x, mesh, p))
