"""The shell kernels of every force family, and the launch sequence of one force (and energy) evaluation.

Order: global areas / volumes (when a constraint needs them), Lim + Kantor (per-vertex gather, or per-element
scatter which also accumulates energies), Juelicher bending (four passes, five with energies), self-avoidance
(grid positions, hash-grid build, pair forces), bond viscosity (when velocities are given).
"""

# (no "from __future__ import annotations": Warp must see the closure types of the kernel signatures)

import functools

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.shell.bending import bending_kernels
from bubblecal.sim.engine.kernels.shell.constraints import constraint_kernels
from bubblecal.sim.engine.kernels.shell.diagnostics import diagnostic_kernels
from bubblecal.sim.engine.kernels.shell.gather import gather_kernels
from bubblecal.sim.engine.kernels.shell.lim import lim_kernels
from bubblecal.sim.engine.kernels.shell.self_avoid import self_avoid_kernels
from bubblecal.sim.engine.kernels.shell.viscosity import viscosity_kernels

wp = require("warp", "sim")

__all__ = ["shell_kernels", "launch_forces"]


@functools.cache
def shell_kernels(dtype) -> dict:
    """Every shell kernel of one scalar type (built once per type), name -> ``wp.Kernel``; ``dtype`` is
    ``wp.float32`` or ``wp.float64``. Returns a dict: The kernels of all force families; the shared Warp
    functions are left out.
    """
    out = {}
    for family in (lim_kernels, bending_kernels, gather_kernels, constraint_kernels, self_avoid_kernels,
                   viscosity_kernels, diagnostic_kernels):
        out.update({k: v for k, v in family(dtype).items() if isinstance(v, wp.Kernel)})
    return out


def launch_forces(ff, x: wp.array, f: wp.array, v, energy: wp.array, want_energy: int, skip=None,
                  with_gas: bool = False) -> None:
    """Launch every active force family of ``ff`` once, adding into ``f`` (and ``energy``).

    Parameters
    ----------
    ff : ShellForceField
        The field whose device tables and kernels are used.
    x, f : wp.array of vec3
        Positions (DPD length) and forces to add into (DPD force); checked by the caller.
    v : wp.array of vec3 or None
        Velocities (DPD velocity) for bond viscosity; None skips it.
    energy : wp.array2d
        [R, 6] energy accumulator (k_BT), or a dummy when ``want_energy`` is 0.
    want_energy : int
        1: also accumulate energies (forces then always use the scatter kernels).
    skip : wp.array of int32, optional
        [R] replicas without Lim, Kantor and self-avoidance forces (default: none).
    with_gas : bool, optional
        Include the inside gas bound by :meth:`ShellForceField.set_gas`.
    """
    k, dev = ff._k, ff.device
    skip = ff._no_skip if skip is None else skip
    gas = [ff._gas, ff._gas_vol, int(ff._gas_on and with_gas)]
    if ff.use_constraints_av:
        ff._avr.zero_()
        wp.launch(k["area_volume_kernel"], dim=ff.n_triangles,
                  inputs=[x, ff._tri, ff._tri_rep, ff._goff, ff._avr], device=dev)
    if ff.force_mode == "gather" and not want_energy:
        wp.launch(k["vertex_gather_kernel"], dim=ff.n_shell_vertices,
                  inputs=[x, f, ff._gidx, ff._vrep, ff._tri, ff._ref, ff._tri_start, ff._tri_slot,
                          ff._dih, ff._cs0, ff._dih_start, ff._dih_slot, ff._params, ff._avr,
                          int(ff.use_global), int(ff.use_kantor), skip, *gas], device=dev)
    else:
        wp.launch(k["lim_kernel"], dim=ff.n_triangles,
                  inputs=[x, f, ff._tri, ff._ref, ff._tri_rep, ff._params, ff._avr,
                          int(ff.use_global), energy, want_energy, skip, *gas], device=dev)
        if ff.use_kantor:
            wp.launch(k["kantor_kernel"], dim=ff.n_edges,
                      inputs=[x, f, ff._dih, ff._cs0, ff._edge_rep, ff._params, energy,
                              want_energy, skip], device=dev)
    if ff.use_juelicher:
        ff._msum.zero_()
        ff._avert.zero_()
        common = [ff._goff, ff._coff, ff._params, ff._msum]
        wp.launch(k["jul_accum_edges"], dim=ff.n_edges, inputs=[x, ff._dih, ff._edge_rep, *common], device=dev)
        wp.launch(k["tri_accum_vertex_area"], dim=ff.n_triangles,
                  inputs=[x, ff._tri, ff._tri_rep, ff._goff, ff._coff, ff._params, ff._avert],
                  device=dev)
        wp.launch(k["jul_force_edges"], dim=ff.n_edges,
                  inputs=[x, f, ff._dih, ff._edge_rep, *common, ff._avert], device=dev)
        wp.launch(k["jul_force_tris"], dim=ff.n_triangles,
                  inputs=[x, f, ff._tri, ff._tri_rep, *common, ff._avert], device=dev)
        if want_energy:
            wp.launch(k["jul_energy"], dim=ff.n_shell_vertices,
                      inputs=[ff._vrep, ff._params, ff._msum, ff._avert, energy], device=dev)
    if ff.use_self_avoid:
        wp.launch(k["grid_positions_kernel"], dim=ff.n_shell_vertices,
                  inputs=[x, ff._gidx, ff._vrep, ff._anchor, ff._slot, ff._xs], device=dev)
        ff._grid.build(ff._xs, ff.sa_cell)
        wp.launch(k["self_avoid_kernel"], dim=ff.n_shell_vertices,
                  inputs=[ff._grid.id, ff._xs, x, f, ff._gidx, ff._vrep, ff._params,
                          ff.sa_query_radius, energy, want_energy, skip], device=dev)
    if ff.use_viscosity and v is not None:
        wp.launch(k["bond_viscosity_kernel"], dim=ff.n_edges,
                  inputs=[x, v, f, ff._dih, ff._edge_rep, ff._params], device=dev)
