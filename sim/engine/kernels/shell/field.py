"""Shell (membrane) forces of R replicas on one device, batched into a handful of launches.

:class:`ShellForceField` holds R replicas' meshes, stress-free references and parameters and adds their forces
into a global particle force array (docs/physics.md section 3).  The force families live in their own modules
of :mod:`bubblecal.sim.engine.kernels.shell`: Lim in-plane forces with the global area / volume constraints
and pressures (``lim``, ``constraints``), Kantor / Juelicher bending (``bending``), the per-vertex gather of
Lim + Kantor (``gather``), self-avoidance (``self_avoid``), bond viscosity (``viscosity``) and the health
indicators (``diagnostics``); the measurement methods are in ``measure``.  The float64 NumPy ground truth
is :mod:`bubblecal.sim.validation.shell_reference`.

Replica r's N_v,r vertices live at rows ``[offset_r, offset_r + N_v,r)`` of the global particle arrays; shell
vertex coordinates must be *unwrapped* (no periodic images inside one shell).  Every launch reuses buffers
allocated at construction; nothing is allocated per step (except Warp's own HashGrid reservation on first
build).  Units: DPD (length r_c = 250 nm, energy k_BT, force k_BT / r_c).
"""

# (no "from __future__ import annotations": Warp must see the closure types of the kernel signatures)

from collections.abc import Sequence

import numpy as np

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.shell.launch import launch_forces, shell_kernels
from bubblecal.sim.engine.kernels.shell.layout import (
    ENERGY_TERMS,
    P_ETA,
    P_KATOT,
    P_KB_JUL,
    P_KB_KANTOR,
    P_KVTOT,
    P_PB,
    P_SA_EPS,
    P_SA_RC,
)
from bubblecal.sim.engine.kernels.shell.measure import ShellFieldMeasurements
from bubblecal.sim.engine.kernels.shell.params import FORCE_MODES, ShellParams
from bubblecal.sim.engine.kernels.shell.self_avoid import self_avoid_grid_plan
from bubblecal.sim.engine.kernels.shell.topology import pack_topology, param_row, resolve_replicas, vertex_csr
from bubblecal.sim.engine.mesh import ShellMesh

wp = require("warp", "sim")

__all__ = ["ShellForceField"]


class ShellForceField(ShellFieldMeasurements):
    """Shell forces of R replicas batched into the same launches.

    Parameters
    ----------
    meshes_or_mesh : ShellMesh or sequence of ShellMesh
        One mesh for all replicas, or a list of R meshes; a mesh's vertices are the stress-free reference of
        its replica (DPD length).
    params_per_replica : ShellParams or sequence of ShellParams
        R parameter sets (or one, used for every mesh), DPD units.
    device : str, optional
        Warp device (``"cpu"``, ``"cuda"``, ``"cuda:0"``).
    dtype : warp scalar type, optional
        ``wp.float32`` (GPU default) or ``wp.float64`` (CPU checks); the particle arrays passed in must be
        ``wp.array(dtype=wp.vec3f)`` or ``wp.array(dtype=wp.vec3d)`` accordingly.
    offsets : sequence of int, optional
        First particle row of each replica's vertices (default: packed from row 0).
    force_mode : str, optional
        One of :data:`FORCE_MODES`: ``"gather"`` (Lim and Kantor forces summed per vertex by one thread, no
        atomics; each element is evaluated by each of its vertices), ``"scatter"`` (one thread per triangle /
        edge with atomics) or ``"auto"`` (default: gather on CUDA, scatter on the CPU, the faster mode on each;
        benchmarks/RESULTS.md).  Energies always use scatter.

    Raises
    ------
    ValueError
        On an unknown ``force_mode`` or ``dtype``, no replicas, mismatched mesh / parameter counts or
        overlapping or negative ``offsets``.
    TypeError
        When ``params_per_replica`` holds something other than :class:`ShellParams`.

    Notes
    -----
    Methods add forces (:meth:`accumulate_forces`), report energies per replica and term (:meth:`energies`,
    columns :data:`ENERGY_TERMS`), total areas / volumes (:meth:`areas_volumes`) and per-replica health
    indicators (:meth:`health`: area strain, dihedral change).
    """

    def __init__(self, meshes_or_mesh: ShellMesh | Sequence[ShellMesh],
                 params_per_replica: ShellParams | Sequence[ShellParams], device: str | None = "cpu",
                 dtype=wp.float32, offsets: Sequence[int] | None = None, force_mode: str = "auto"):
        if force_mode not in FORCE_MODES:
            raise ValueError(f"force_mode must be one of {FORCE_MODES}, got {force_mode!r}")
        if dtype not in (wp.float32, wp.float64):
            raise ValueError(f"dtype must be wp.float32 or wp.float64, got {dtype!r}")
        self.meshes, self.params, offsets, nv = resolve_replicas(meshes_or_mesh, params_per_replica, offsets)
        self.n_replicas = R = len(self.meshes)
        self.offsets = offsets
        self.n_vertices = nv
        self.n_rows_min = int(np.max(offsets + nv))
        self.dtype = dtype
        self.vec3 = wp.vec3d if dtype is wp.float64 else wp.vec3f
        self.device = wp.get_device(device)
        if force_mode == "auto":
            force_mode = "gather" if self.device.is_cuda else "scatter"
        self.force_mode = force_mode
        self._k = shell_kernels(dtype)

        top = pack_topology(self.meshes, offsets)
        tri, dih, coff, tri_rep, edge_rep, theta0 = (top[k] for k in ("tri", "dih", "coff", "tri_rep", "edge_rep",
                                                                      "theta0"))
        self.area0 = np.array([m.area() for m in self.meshes])
        self.volume0 = np.array([m.volume() for m in self.meshes])
        table = np.stack([self._param_row(r, p) for r, p in enumerate(self.params)]).astype(np.float64)
        self.param_table = table
        self.use_kantor = bool(np.any(table[:, P_KB_KANTOR] != 0))
        self.use_juelicher = bool(np.any(table[:, P_KB_JUL] != 0))
        self.use_global = bool(np.any(table[:, [P_KATOT, P_KVTOT, P_PB]] != 0))
        self.use_constraints_av = bool(np.any(table[:, [P_KATOT, P_KVTOT]] != 0))
        self.use_self_avoid = bool(np.any(table[:, P_SA_EPS] != 0))
        self.use_viscosity = bool(np.any(table[:, P_ETA] != 0))

        dev = self.device
        self._tri = wp.array(tri.astype(np.int32), dtype=wp.vec3i, device=dev)
        self._dih = wp.array(dih.astype(np.int32), dtype=wp.vec4i, device=dev)
        self._tri_rep = wp.array(tri_rep.astype(np.int32), dtype=wp.int32, device=dev)
        self._edge_rep = wp.array(edge_rep.astype(np.int32), dtype=wp.int32, device=dev)
        self._vrep = wp.array(top["vrep"].astype(np.int32), dtype=wp.int32, device=dev)
        self._gidx = wp.array(top["gidx"].astype(np.int32), dtype=wp.int32, device=dev)
        self._goff = wp.array(offsets.astype(np.int32), dtype=wp.int32, device=dev)
        self._coff = wp.array(coff.astype(np.int32), dtype=wp.int32, device=dev)
        self._ref = wp.array(top["ref"], dtype=wp.vec4d if dtype is wp.float64 else wp.vec4f, device=dev)
        self._theta0 = wp.array(theta0, dtype=dtype, device=dev)
        # (cos, sin) theta0: the Kantor kernels need no atan2 / sin (kantor_edge)
        self._cs0 = wp.array(np.stack([np.cos(theta0), np.sin(theta0)], axis=1),
                             dtype=wp.vec2d if dtype is wp.float64 else wp.vec2f, device=dev)
        self._params = wp.array(table, dtype=dtype, device=dev)
        self._avr = wp.zeros((R, 2), dtype=dtype, device=dev)
        self._health = wp.zeros((R, 3), dtype=dtype, device=dev)
        self._energy = wp.zeros((R, len(ENERGY_TERMS)), dtype=dtype, device=dev)
        self._dummy_energy = wp.zeros((1, len(ENERGY_TERMS)), dtype=dtype, device=dev)
        self._no_skip = wp.zeros(R, dtype=wp.int32, device=dev)
        self._skip = self._no_skip
        self._gas = wp.zeros((1, 2), dtype=dtype, device=dev)
        self._gas_vol = wp.ones(1, dtype=dtype, device=dev)
        self._gas_on = 0
        n_shell = int(nv.sum())
        self.n_shell_vertices = n_shell
        self._msum = wp.zeros(n_shell, dtype=dtype, device=dev)
        self._avert = wp.zeros(n_shell, dtype=dtype, device=dev)
        self._xs = wp.zeros(n_shell, dtype=wp.vec3, device=dev)
        self._grid = None
        plan = self_avoid_grid_plan(self.meshes, offsets, float(np.max(table[:, P_SA_RC])))
        self.sa_query_radius, self.sa_cell = plan.query_radius, plan.cell
        self._anchor = wp.array(plan.anchors, dtype=wp.vec2i, device=dev)
        self._slot = wp.array(plan.slots, dtype=wp.vec3, device=dev)
        if self.use_self_avoid:
            self._grid = wp.HashGrid(*plan.dims, device=dev)
        # vertex -> incident elements (CSR) for the gather kernel; codes = element * 4 + corner/role
        comp_t = tri - offsets[tri_rep][:, None] + coff[tri_rep][:, None]
        comp_d = dih - offsets[edge_rep][:, None] + coff[edge_rep][:, None]
        i32 = dict(dtype=wp.int32, device=dev)
        self._tri_start, self._tri_slot = (wp.array(a, **i32) for a in vertex_csr(comp_t, n_shell))
        self._dih_start, self._dih_slot = (wp.array(a, **i32) for a in vertex_csr(comp_d, n_shell))
        self.n_triangles = tri.shape[0]
        self.n_edges = dih.shape[0]
        # each replica's triangles and edges are one contiguous block (pack_topology concatenates the meshes)
        self._tri_first = np.searchsorted(tri_rep, np.arange(R))
        self._edge_first = np.searchsorted(edge_rep, np.arange(R))
        # NumPy <-> Warp staging for the NumPy convenience interface (CPU / tests / minimiser)
        self._np_x = None
        self._scratch_f = None

    # ------------------------------------------------------------------------------------------
    def _param_row(self, r: int, p: ShellParams) -> np.ndarray:
        """Row ``r`` of the device parameter table for :class:`ShellParams` ``p`` (on replica r's mesh)."""
        return param_row(p, self.meshes[r], self.area0[r], self.volume0[r])

    def set_params_rows(self, rows: Sequence[int] | np.ndarray, params: Sequence[ShellParams]) -> None:
        """Give replicas new parameters in place (e.g. reuse a finished replica's slot for the next sample).

        CUDA graphs see the change (the same device array is rewritten).

        Parameters
        ----------
        rows : sequence of int
            Distinct replica indices in [0, R).
        params : sequence of ShellParams
            One parameter set per row (DPD units).

        Raises
        ------
        ValueError
            When the counts differ, a row is out of range or repeated, the new parameters switch on a term
            the field was built without (Kantor / Juelicher bending, global constraints and back pressure,
            self-avoidance, bond viscosity: those kernels are chosen at construction), or a self-avoidance
            cut-off exceeds the field's search radius.
        """
        rows = np.asarray(rows, dtype=np.int64).reshape(-1)
        if len(rows) != len(params):
            raise ValueError(f"{len(rows)} rows but {len(params)} parameter sets")
        if len(rows) == 0:
            return
        if rows.min() < 0 or rows.max() >= self.n_replicas or len(np.unique(rows)) != len(rows):
            raise ValueError(f"rows must be distinct replica indices in [0, {self.n_replicas})")
        new = np.stack([self._param_row(int(r), p) for r, p in zip(rows, params, strict=True)])
        for col, on, what in ((P_KB_KANTOR, self.use_kantor, "Kantor bending"),
                              (P_KB_JUL, self.use_juelicher, "Juelicher bending"),
                              (P_SA_EPS, self.use_self_avoid, "self-avoidance"),
                              (P_ETA, self.use_viscosity, "bond viscosity")):
            if not on and np.any(new[:, col] != 0):
                raise ValueError(f"set_params_rows: {what} is off in this field (built without it)")
        if not self.use_global and np.any(new[:, [P_KATOT, P_KVTOT, P_PB]] != 0):
            raise ValueError("set_params_rows: global area/volume constraints and back pressure are off in this field")
        if self.use_self_avoid and np.any(new[:, P_SA_RC] * 1.001 > self.sa_query_radius * (1 + 1e-12)):
            raise ValueError("set_params_rows: a self-avoidance cut-off exceeds the field's search radius")
        self.param_table[rows] = new
        for r, p in zip(rows, params, strict=True):
            self.params[int(r)] = p
        self._params.assign(self.param_table.astype(np.float64 if self.dtype is wp.float64 else np.float32))

    def set_reference_rows(self, rows: Sequence[int] | np.ndarray, meshes: Sequence[ShellMesh],
                           params: Sequence[ShellParams]) -> None:
        """Give replicas new stress-free references of the same topology, and their parameters, in place.

        A slot of a refill pool can so take a sample of another diameter (a scaled mesh of the same level); the
        Lim reference, the reference dihedrals and the parameter rows that depend on the mesh are rewritten.

        Parameters
        ----------
        rows : sequence of int
            Distinct replica indices in [0, R).
        meshes : sequence of ShellMesh
            One reference per row, with the faces and dihedral list of the row's current mesh (DPD length).
        params : sequence of ShellParams
            One parameter set per row (DPD units), as :meth:`set_params_rows`.

        Raises
        ------
        ValueError
            When the counts differ, a mesh's topology differs from its row's, or the field uses self-avoidance
            (its hash grid is planned for the construction meshes); else as :meth:`set_params_rows`.
        """
        rows = np.asarray(rows, dtype=np.int64).reshape(-1)
        if len(rows) != len(meshes):
            raise ValueError(f"{len(rows)} rows but {len(meshes)} meshes")
        if self.use_self_avoid:
            raise ValueError("set_reference_rows: not with self-avoidance (its grid is planned for the first meshes)")
        for r, m in zip(rows, meshes, strict=True):
            old = self.meshes[int(r)]
            if not (np.array_equal(m.faces, old.faces) and np.array_equal(m.dihedrals, old.dihedrals)):
                raise ValueError(f"set_reference_rows: the mesh for row {int(r)} has another topology")
        if len(rows) == 0:
            return
        # only the rows' blocks travel to the device (a refill pool calls this often), converted from float64 as
        # at construction
        for r, m in zip(rows, meshes, strict=True):
            r = int(r)
            _write_block(self._ref, self._tri_first[r], np.stack([m.l1**2, m.l2**2, m.d0, m.A0], axis=1))
            _write_block(self._theta0, self._edge_first[r], m.theta0)
            _write_block(self._cs0, self._edge_first[r], np.stack([np.cos(m.theta0), np.sin(m.theta0)], axis=1))
            self.meshes[r] = m
            self.area0[r], self.volume0[r] = m.area(), m.volume()
        self.set_params_rows(rows, params)

    def _check_array(self, a, name: str) -> None:
        """Raise unless ``a`` is a vec3 array of this field's dtype and device with enough rows."""
        if not wp.types.types_equal(a.dtype, self.vec3):
            raise TypeError(f"{name} must be a wp.array of {self.vec3.__name__}, got {a.dtype.__name__}")
        if a.device != self.device:
            raise ValueError(f"{name} lives on {a.device}, the shell field on {self.device}")
        if a.shape[0] < self.n_rows_min:
            raise ValueError(f"{name} has {a.shape[0]} rows, the shells need {self.n_rows_min}")

    def accumulate_forces(self, x: wp.array, f: wp.array, v: wp.array | None = None) -> None:
        """Add the shell forces of every replica into ``f`` (``f`` is not cleared).

        Parameters
        ----------
        x : wp.array of vec3
            Particle positions (DPD length), at least ``n_rows_min`` rows.
        f : wp.array of vec3
            Forces to add into (DPD force).
        v : wp.array of vec3, optional
            Particle velocities (DPD velocity), needed only for bond viscosity.

        Raises
        ------
        TypeError, ValueError
            When an array has the wrong dtype, device or too few rows.
        """
        self._check_array(x, "x")
        self._check_array(f, "f")
        if v is not None:
            self._check_array(v, "v")
        launch_forces(self, x, f, v, self._dummy_energy, 0, self._skip, with_gas=True)

    def set_skip(self, skip: wp.array | None) -> None:
        """Bind a per-replica skip flag read by :meth:`accumulate_forces` at launch time.

        Replicas whose entry is nonzero get no Lim, Kantor or self-avoidance forces; a batched minimiser binds
        its status array once, so converged replicas cost almost nothing while the slowest ones finish (and
        CUDA graphs see its updates).  The Juelicher and bond-viscosity terms are never skipped; energies
        ignore the binding.

        Parameters
        ----------
        skip : wp.array of int32 or None
            [R] flags on this field's device; None unbinds.

        Raises
        ------
        ValueError
            On a wrong dtype, shape or device.
        """
        if skip is None:
            self._skip = self._no_skip
            return
        if skip.dtype != wp.int32 or skip.shape != (self.n_replicas,) or skip.device != self.device:
            raise ValueError(f"skip must be an int32 array of shape ({self.n_replicas},) on {self.device}")
        self._skip = skip

    def set_gas(self, gas: wp.array | None, volume: wp.array | None = None) -> None:
        """Bind an inside gas to :meth:`accumulate_forces`.

        Replica r's shell then also feels the pressure ``gas[r, 0] / volume[r] - gas[r, 1]`` (DPD pressure)
        through dV/dx = (sum of the incident triangles' normals) / 6, which the Lim pass already computes.
        Both arrays are read at launch time (CUDA graphs see the caller's updates); energies never include
        the gas.

        Parameters
        ----------
        gas : wp.array or None
            [R, 2] of the field's dtype: p0 V0 (DPD energy) and the ambient pressure; None unbinds.
        volume : wp.array, optional
            [R] enclosed volumes (DPD length^3), which the caller updates before each call.

        Raises
        ------
        ValueError
            On a wrong dtype, shape or device.
        """
        if gas is None:
            self._gas_on = 0
            return
        R = self.n_replicas
        if gas.dtype != self.dtype or gas.shape != (R, 2) or gas.device != self.device:
            raise ValueError(f"gas must be a {self.dtype.__name__} array of shape ({R}, 2) on {self.device}")
        if volume is None or volume.dtype != self.dtype or volume.shape != (R,) or volume.device != self.device:
            raise ValueError(f"volume must be a {self.dtype.__name__} array of shape ({R},) on {self.device}")
        self._gas, self._gas_vol, self._gas_on = gas, volume, 1


def _write_block(dest: wp.array, first: int, values: np.ndarray) -> None:
    """Overwrite ``len(values)`` rows of ``dest`` from row ``first`` (values converted to ``dest``'s type)."""
    src = wp.array(values, dtype=dest.dtype, device=dest.device)
    wp.copy(dest, src, dest_offset=int(first), count=len(values))
