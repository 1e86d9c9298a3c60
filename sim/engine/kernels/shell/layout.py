"""Warp-free layout shared by the shell kernels, :class:`ShellForceField` and the NumPy reference.

The device parameter table holds one row of ``N_PARAMS`` columns per replica (``P_*`` column indices,
DPD units); the device energy table one row of ``len(ENERGY_TERMS)`` columns (``E_*`` indices).
"""

__all__ = ["ENERGY_TERMS", "AREA_CLAMP", "N_PARAMS"]

#: Columns of :meth:`ShellForceField.energies` and of the NumPy reference's ``shell_energies``.
ENERGY_TERMS = ("in_plane", "bending", "area", "volume", "back_pressure", "self_avoid")
#: Lower clamp of the current triangle area in the Lim energy (DPD length^2, docs/physics.md section 3).
AREA_CLAMP = 1e-6

# parameter columns of the per-replica parameter table
P_KA, P_MU, P_A3, P_A4, P_B1, P_B2 = 0, 1, 2, 3, 4, 5
P_KB_KANTOR, P_KB_JUL, P_C0 = 6, 7, 8
P_KATOT, P_KVTOT, P_PB, P_A0TOT, P_V0 = 9, 10, 11, 12, 13
P_SA_EPS, P_SA_RC, P_ETA = 14, 15, 16
#: Number of columns of the per-replica parameter table.
N_PARAMS = 17

# energy columns
E_LIM, E_BEND, E_AREA, E_VOL, E_PB, E_SA = range(6)
