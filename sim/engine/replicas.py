"""Replica descriptions of the explicit-solvent engine and the particles they start with.

A :class:`ReplicaSpec` describes one replica of :class:`~bubblecal.sim.engine.system.ParticleSystem`: its
periodic box, DPD pair table, temperature, seed, solvent densities and optional shell.  Set-up
(:meth:`ReplicaSpec.build_particles`): water is placed uniformly at number density ``water_density`` in the box
outside the shell and ideal gas at ``gas_density`` inside it (particles on the wrong side of the reference mesh
are deleted; the set-up mesh is the convex icosphere, so a half-space test is exact); velocities are Maxwellian
at the replica's k_BT with zero total momentum of the mobile solvent.  :func:`bubble_spec` is the published
bubble.  Units: DPD (length r_c = 250 nm, energy k_BT, water bead mass 1).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bubblecal.sim.engine.kernels.shell.params import ShellParams
from bubblecal.sim.engine.mesh import ShellMesh, mesh_for_diameter
from bubblecal.sim.engine.particles import (
    GAS,
    P_BACK_DEFAULT,
    RHO_SHELL_KG_M3,
    WALL,
    WATER,
    PairTable,
    published_pair_table,
)

__all__ = ["ReplicaSpec", "inside_convex_mesh", "bubble_spec"]


def inside_convex_mesh(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray, chunk: int = 4096) -> np.ndarray:
    """Boolean mask of points strictly inside a convex, outward-oriented triangulation.

    Points outside the vertices' bounding sphere are outside and points inside the inscribed sphere
    (distance to the nearest face plane) are inside; only the band between is tested face by face.

    Parameters
    ----------
    points : numpy.ndarray
        [N, 3] query points (any length unit, the same as ``vertices``).
    vertices : numpy.ndarray
        [N_v, 3] mesh vertices.
    faces : numpy.ndarray
        [N_t, 3] outward-oriented triangles.
    chunk : int, optional
        Points tested against all faces at once (memory bound).

    Returns
    -------
    numpy.ndarray
        [N] bool.
    """
    pts = np.asarray(points, dtype=np.float64)
    a = vertices[faces[:, 0]]
    n = np.cross(vertices[faces[:, 1]] - a, vertices[faces[:, 2]] - a)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    off = np.einsum("ij,ij->i", n, a)
    c = vertices.mean(axis=0)
    r_out = np.linalg.norm(vertices - c, axis=1).max()
    r_in = float(np.min(off - n @ c))  # > 0 when c is inside the convex mesh
    d = np.linalg.norm(pts - c, axis=1)
    out = d < r_in
    band = np.nonzero((d >= r_in) & (d <= r_out))[0]
    for s in range(0, len(band), chunk):
        idx = band[s:s + chunk]
        out[idx] = np.all(pts[idx] @ n.T - off[None, :] < 0.0, axis=1)
    return out


@dataclass
class ReplicaSpec:
    """Description of one replica (DPD units).

    Parameters
    ----------
    box : sequence of float
        Periodic box edge lengths (DPD length).
    pairs : PairTable
        a, gamma, s per type pair and the per-type masses; the vertex mass is ``pairs.mass[VERTEX]`` unless
        ``vertex_mass`` is given.
    kbt : float, optional
        Thermal energy (k_BT units).
    seed : int, optional
        Seed of the set-up and of the replica's random forces.
    water_density : float, optional
        Number density of water outside the shell (0 = none).
    gas_density : float, optional
        Number density of the ideal gas inside the shell (in the whole box without a shell).
    mesh : ShellMesh, optional
        Shell centred at the origin, placed at ``center``; None = no shell.
    center : sequence of float, optional
        Shell centre (DPD length); default the box centre.
    shell : ShellParams, optional
        Membrane parameters (required with a mesh).
    vertex_mass : float, optional
        DPD mass of a shell vertex.
    frozen_shell : bool, optional
        Vertex inverse mass 0: the shell is a fixed wall.
    pin_com : bool, optional
        Remove the shell's mean velocity every step.
    extra_positions, extra_types, extra_velocities : numpy.ndarray, optional
        Additional particles, e.g. wall slabs (types default to ``WALL``, velocities to 0).
    temperature_init : float, optional
        Initial k_BT of the velocities (default ``kbt``).
    water_gap : float, optional
        No water is placed within this distance (DPD length) outside the shell's circumsphere at set-up: the
        vertex-water repulsion a = 400 would otherwise crush the shell in the first steps; the water closes
        the gap within a few hundred steps.
    label : str, optional
        Free-form name.
    """

    box: Sequence[float]
    pairs: PairTable
    kbt: float = 1.0
    seed: int = 0
    water_density: float = 3.0
    gas_density: float = 0.0
    mesh: ShellMesh | None = None
    center: Sequence[float] | None = None
    shell: ShellParams | None = None
    vertex_mass: float | None = None
    frozen_shell: bool = False
    pin_com: bool = False
    extra_positions: np.ndarray | None = None
    extra_types: np.ndarray | None = None
    extra_velocities: np.ndarray | None = None
    temperature_init: float | None = None
    water_gap: float = 0.5
    label: str = ""

    def build_particles(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """Initial particles of this replica (float64, DPD units).

        Returns
        -------
        positions, types, velocities : numpy.ndarray
            Solvent [N, 3] positions, [N] int32 types and [N, 3] velocities.
        vertices : numpy.ndarray or None
            [N_v, 3] shell vertex positions (the mesh moved to ``center``), or None without a mesh.
        """
        rng = np.random.default_rng(self.seed)
        box = np.asarray(self.box, dtype=np.float64)
        vol = float(np.prod(box))
        pos, typ = [], []
        verts = None
        center = box / 2 if self.center is None else np.asarray(self.center, dtype=np.float64)
        if self.mesh is not None:
            verts = np.asarray(self.mesh.vertices, dtype=np.float64) + center
        if self.water_density > 0:
            n = int(round(self.water_density * vol))
            p = rng.uniform(0, 1, (n, 3)) * box
            if verts is not None:
                keep = ~inside_convex_mesh(p, verts, self.mesh.faces)
                if self.water_gap > 0:
                    rad = np.linalg.norm(verts - center, axis=1).max()
                    keep &= np.linalg.norm(p - center, axis=1) > rad + self.water_gap
                p = p[keep]
            pos.append(p)
            typ.append(np.full(len(p), WATER))
        if self.gas_density > 0:
            if verts is None:
                n = int(round(self.gas_density * vol))
                p = rng.uniform(0, 1, (n, 3)) * box
            else:
                lo, hi = verts.min(axis=0), verts.max(axis=0)
                n = int(round(self.gas_density * float(np.prod(hi - lo))))
                p = lo + rng.uniform(0, 1, (n, 3)) * (hi - lo)
                p = p[inside_convex_mesh(p, verts, self.mesh.faces)]
            pos.append(p)
            typ.append(np.full(len(p), GAS))
        if self.extra_positions is not None:
            ep = np.asarray(self.extra_positions, dtype=np.float64).reshape(-1, 3)
            et = (np.full(len(ep), WALL) if self.extra_types is None
                  else np.asarray(self.extra_types, dtype=np.int64).reshape(-1))
            pos.append(ep)
            typ.append(et)
        x = np.concatenate(pos) if pos else np.zeros((0, 3))
        t = np.concatenate(typ).astype(np.int32) if typ else np.zeros(0, dtype=np.int32)
        kt = self.kbt if self.temperature_init is None else self.temperature_init
        m = np.asarray(self.pairs.mass, dtype=np.float64)[t]
        v = rng.normal(0.0, 1.0, (len(x), 3)) * np.sqrt(kt / m)[:, None]
        if self.extra_positions is not None:
            ne = len(np.asarray(self.extra_positions).reshape(-1, 3))
            v[len(x) - ne:] = (0.0 if self.extra_velocities is None
                               else np.asarray(self.extra_velocities, dtype=np.float64).reshape(-1, 3))
        mobile = t != WALL
        if mobile.sum() > 1:  # zero total momentum of the mobile solvent
            p_tot = (m[mobile, None] * v[mobile]).sum(axis=0)
            v[mobile] -= p_tot / m[mobile].sum()
        return x, t, v, verts


def bubble_spec(diameter_um: float = 3.0, subdivisions: int | None = None, box=None, seed: int = 0,
                ka: float = 5584.0, kb: float = 389.23, p_back: float = P_BACK_DEFAULT, gas_density: float = 3.0,
                protocol: str = "compression", rho_shell_kg_m3: float | None = None, mass_factor: float = 1.0,
                a_vertex_water: float | None = None, kbt: float = 1.0, fsi_friction_factor: float = 1.0,
                a_water: float = 100.0, **shell_kwargs) -> ReplicaSpec:
    """A bubble at the published parameters (docs/physics.md sections 2-3) in explicit water and gas.

    Parameters
    ----------
    diameter_um : float, optional
        Bubble diameter (um).
    subdivisions : int, optional
        Icosphere subdivision (default 4, 5 above 5 um).
    box : sequence of float, optional
        Box edge lengths (DPD length); default ``(2R+5, 2R+5, 2R+10)`` (17 x 17 x 22 for 3 um).
    seed : int, optional
        Replica seed.
    ka, kb : float, optional
        Area-dilation modulus (DPD 2-D modulus; 5,584 is E = 10 MPa) and bending constant (k_BT); mu = ka / 3.
    p_back : float, optional
        Outward back pressure (DPD pressure).
    gas_density : float, optional
        Number density of the ideal gas inside (a choice; default 3).
    protocol : str, optional
        ``"compression"`` or ``"indentation"``: the vertex-water repulsion and the default shell density.
    rho_shell_kg_m3 : float, optional
        Shell density (kg/m^3); default 1100 for compression, x5 for indentation.
    mass_factor : float, optional
        Factor on the vertex mass rho_shell h A / N_v.
    a_vertex_water : float, optional
        Overrides the protocol's vertex-water repulsion (DPD force).
    kbt : float, optional
        Thermal energy (k_BT units).
    fsi_friction_factor : float, optional
        Factor on the vertex-solvent dissipative coefficients (:func:`published_pair_table`).
    a_water : float, optional
        Water-water repulsion (DPD force; :func:`published_pair_table`).
    **shell_kwargs
        Further :class:`ShellParams` fields.

    Returns
    -------
    ReplicaSpec
        With the published pair table (gamma_fsi from the mesh's vertex density) and water at number density 3.

    Raises
    ------
    ValueError
        On an unknown protocol or invalid shell parameters.
    """
    mesh = mesh_for_diameter(diameter_um, subdivisions)
    R = mesh.radius_dpd
    if box is None:
        box = (2 * R + 5.0, 2 * R + 5.0, 2 * R + 10.0)
    if rho_shell_kg_m3 is None:
        rho_shell_kg_m3 = RHO_SHELL_KG_M3 * (5.0 if protocol == "indentation" else 1.0)
    m_v = mesh.vertex_mass(rho_shell_kg_m3, mass_factor=mass_factor)
    tab = published_pair_table(mesh.n_vertices / mesh.area(), protocol, m_vertex=m_v,
                               rho_gas_number=gas_density, a_vertex_water=a_vertex_water,
                               fsi_friction_factor=fsi_friction_factor, a_water=a_water)
    return ReplicaSpec(box=box, pairs=tab, kbt=kbt, seed=seed, water_density=3.0, gas_density=gas_density,
                       mesh=mesh, shell=ShellParams(ka=ka, kb=kb, p_back=p_back, **shell_kwargs))
