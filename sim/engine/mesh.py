"""Icosphere shell meshes and their stress-free reference state (NumPy float64).

The input mesh *is* the stress-free reference of the shell (docs/physics.md section 3): every reference
quantity the shell forces need (Lim triangle data, Kantor dihedral angles) is computed here once.

Conventions (the Warp kernels in :mod:`bubblecal.sim.engine.kernels.shell` and the NumPy reference in
:mod:`bubblecal.sim.validation.shell_reference` rely on them):

* ``faces[t] = (v0, v1, v2)`` is outward oriented: ``(x1 - x0) x (x2 - x0)`` points out of the shell.
* ``edges[e] = (a, b)`` with ``a < b``; ``dihedrals[e] = (a, b, c, d)`` with the same ``a, b``, where
  ``(a, b, c)`` and ``(b, a, d)`` are the two adjacent faces, both in outward (cyclic) order, so that
  ``c`` is opposite the edge in the face that runs a -> b and ``d`` in the face that runs b -> a.
* The dihedral angle ``theta_e`` is the angle between the outward normals ``n1 = (b-a) x (c-a)`` and
  ``n2 = (a-b) x (d-b)``, signed positive where the surface is convex (a sphere has all
  ``theta_e > 0``); ``theta_e = 0`` on a flat patch.
* Lim reference per triangle: ``e1 = X1 - X0`` (length ``l1``), ``e2 = X2 - X0`` (length ``l2``),
  ``d0 = e1 . e2``, ``A0 = |e1 x e2| / 2``.
* :meth:`ShellMesh.vertex_areas` is the barycentric area ``A_v = sum_{t ∋ v} A_t / 3`` (the
  convention of Juelicher's discretisation as used in Mirheo; it sums exactly to the mesh area).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bubblecal._extras import require
from bubblecal.data import DEFAULT_UNITS, UnitSystem
from bubblecal.sim.engine.geometry import (
    dihedral_angles,
    edges_and_dihedrals,
    lim_reference,
    mesh_volume,
    triangle_areas,
)
from bubblecal.sim.engine.particles import RHO_SHELL_KG_M3

__all__ = [
    "ShellMesh",
    "icosphere",
    "diameter_to_radius_dpd",
    "mesh_for_diameter",
    "n_vertices_for_subdivisions",
    "build_shell_mesh",
    "SUBDIVISION_5_ABOVE_UM",
]

#: Above this diameter [um] :func:`mesh_for_diameter` uses subdivision 5 (docs/physics.md section 3).
SUBDIVISION_5_ABOVE_UM = 5.0


def n_vertices_for_subdivisions(subdivisions: int) -> int:
    """Number of vertices of an icosphere, N_v = 10 * 4^s + 2.

    Parameters
    ----------
    subdivisions : int
        Subdivision level s.

    Returns
    -------
    int
    """
    return 10 * 4 ** int(subdivisions) + 2


@dataclass(frozen=True, eq=False)
class ShellMesh:
    """A closed triangulated shell and its stress-free reference state (all NumPy, float64).

    Build it with :func:`build_shell_mesh`, :func:`icosphere` or :func:`mesh_for_diameter`; the arrays are
    read-only.

    Attributes
    ----------
    vertices : numpy.ndarray
        [N_v, 3] reference positions (DPD length).
    faces : numpy.ndarray
        [N_t, 3] int32 outward-oriented triangles.
    edges : numpy.ndarray
        [N_e, 2] int32 edges (a < b).
    dihedrals : numpy.ndarray
        [N_e, 4] int32 quadruples (a, b, c, d) (module docstring).
    l1, l2, d0, A0 : numpy.ndarray
        [N_t] Lim reference (DPD length, length^2).
    theta0 : numpy.ndarray
        [N_e] reference dihedral angles (radians).
    radius_dpd : float
        Nominal radius (DPD length; 0 for a mesh that is not an icosphere).
    subdivisions : int
        Icosphere subdivision level (-1 when unknown).
    """

    vertices: np.ndarray
    faces: np.ndarray
    edges: np.ndarray
    dihedrals: np.ndarray
    l1: np.ndarray
    l2: np.ndarray
    d0: np.ndarray
    A0: np.ndarray
    theta0: np.ndarray
    radius_dpd: float = 0.0
    subdivisions: int = -1
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    # ----- sizes ------------------------------------------------------------------------------
    @property
    def n_vertices(self) -> int:
        """Number of vertices N_v."""
        return int(self.vertices.shape[0])

    @property
    def n_faces(self) -> int:
        """Number of triangles N_t."""
        return int(self.faces.shape[0])

    @property
    def n_edges(self) -> int:
        """Number of edges N_e."""
        return int(self.edges.shape[0])

    # ----- reference geometry -------------------------------------------------------------------
    def area(self, x: np.ndarray | None = None) -> float:
        """Total area of the reference, or of positions ``x`` on this mesh.

        Parameters
        ----------
        x : numpy.ndarray, optional
            [N_v, 3] positions (DPD length); default the reference.

        Returns
        -------
        float
            Area (DPD length^2).
        """
        return float(np.sum(triangle_areas(self.vertices if x is None else x, self.faces)))

    def volume(self, x: np.ndarray | None = None) -> float:
        """Enclosed volume of the reference, or of positions ``x`` on this mesh.

        Parameters
        ----------
        x : numpy.ndarray, optional
            [N_v, 3] positions (DPD length); default the reference.

        Returns
        -------
        float
            Volume (DPD length^3).
        """
        return mesh_volume(self.vertices if x is None else x, self.faces)

    def vertex_areas(self, x: np.ndarray | None = None) -> np.ndarray:
        """Barycentric vertex areas A_v = sum of the adjacent triangle areas / 3.

        Parameters
        ----------
        x : numpy.ndarray, optional
            [N_v, 3] positions (DPD length); default the reference.

        Returns
        -------
        numpy.ndarray
            [N_v] areas (DPD length^2); they sum to the mesh area.
        """
        at = triangle_areas(self.vertices if x is None else x, self.faces)
        out = np.zeros(self.n_vertices)
        for k in range(3):
            np.add.at(out, self.faces[:, k], at / 3.0)
        return out

    def edge_lengths(self, x: np.ndarray | None = None) -> np.ndarray:
        """Length of every edge.

        Parameters
        ----------
        x : numpy.ndarray, optional
            [N_v, 3] positions (DPD length); default the reference.

        Returns
        -------
        numpy.ndarray
            [N_e] lengths (DPD length).
        """
        x = self.vertices if x is None else np.asarray(x, dtype=np.float64)
        return np.linalg.norm(x[self.edges[:, 1]] - x[self.edges[:, 0]], axis=1)

    def min_edge_length(self) -> float:
        """Shortest reference edge (DPD length; it scales the self-avoidance cut-off), computed once.

        Returns
        -------
        float
        """
        if "min_edge" not in self._cache:
            self._cache["min_edge"] = float(self.edge_lengths().min())
        return self._cache["min_edge"]

    def euler_characteristic(self) -> int:
        """N_v - N_e + N_t (2 for a closed sphere-like shell).

        Returns
        -------
        int
        """
        return self.n_vertices - self.n_edges + self.n_faces

    def vertex_mass(self, density_kg_m3: float = RHO_SHELL_KG_M3, thickness_m: float | None = None,
                    mass_factor: float = 1.0, units: UnitSystem = DEFAULT_UNITS) -> float:
        """Mass of one vertex, rho_shell h A_mesh u_l^2 / (u_m N_v) x ``mass_factor``.

        docs/physics.md section 2 (rho_shell = 1100 kg/m^3; x5 in the published indentation set) and section 5
        (mass factor 160 for ringdown runs).

        Parameters
        ----------
        density_kg_m3 : float, optional
            Shell density rho_shell (kg/m^3).
        thickness_m : float, optional
            Shell thickness h (m); default the unit system's.
        mass_factor : float, optional
            Factor on the mass (dimensionless).
        units : UnitSystem, optional
            Unit system (u_l, u_m).

        Returns
        -------
        float
            Vertex mass (DPD mass).

        Raises
        ------
        ValueError
            When density, thickness or mass factor is not positive.
        """
        h = units.shell_thickness_m if thickness_m is None else thickness_m
        if density_kg_m3 <= 0 or h <= 0 or mass_factor <= 0:
            raise ValueError("vertex_mass: density, thickness and mass_factor must be > 0")
        m = density_kg_m3 * h * self.area() * units.length_m**2 / (units.mass_kg * self.n_vertices)
        return float(m * mass_factor)

    def translated(self, shift) -> ShellMesh:
        """The same mesh with its vertices (reference) shifted.

        Parameters
        ----------
        shift : array_like
            [3] shift (DPD length).

        Returns
        -------
        ShellMesh
        """
        return build_shell_mesh(self.vertices + np.asarray(shift, dtype=np.float64), self.faces,
                                radius_dpd=self.radius_dpd, subdivisions=self.subdivisions)


def build_shell_mesh(vertices: np.ndarray, faces: np.ndarray, *, radius_dpd: float = 0.0,
                     subdivisions: int = -1) -> ShellMesh:
    """Build a :class:`ShellMesh` from any closed outward-oriented triangulation (the stress-free reference).

    Parameters
    ----------
    vertices : numpy.ndarray
        [N_v, 3] reference positions (DPD length).
    faces : numpy.ndarray
        [N_t, 3] outward-oriented triangles.
    radius_dpd : float, optional
        Nominal radius (DPD length; 0 = not an icosphere).
    subdivisions : int, optional
        Icosphere level (-1 = unknown).

    Returns
    -------
    ShellMesh

    Raises
    ------
    ValueError
        On wrong shapes, a mesh that is not closed, manifold or consistently oriented, a degenerate triangle or
        inward-facing triangles.
    """
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int32)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise ValueError("vertices must be [Nv,3] and faces [Nt,3]")
    edges, dih = edges_and_dihedrals(f, v.shape[0])
    ref = lim_reference(v, f)
    if np.any(ref["A0"] <= 0):
        raise ValueError("degenerate reference triangle (zero area)")
    if mesh_volume(v, f) <= 0:
        raise ValueError("faces are not outward oriented (negative enclosed volume)")
    theta0 = dihedral_angles(v, dih)
    for arr in (v, f, edges, dih, theta0, *ref.values()):
        arr.setflags(write=False)
    return ShellMesh(vertices=v, faces=f, edges=edges, dihedrals=dih, l1=ref["l1"], l2=ref["l2"],
                     d0=ref["d0"], A0=ref["A0"], theta0=theta0, radius_dpd=float(radius_dpd),
                     subdivisions=int(subdivisions))


def icosphere(radius_dpd: float, subdivisions: int, center=(0.0, 0.0, 0.0)) -> ShellMesh:
    """Icosphere (``trimesh.creation.icosphere``) with every vertex on the sphere.

    Parameters
    ----------
    radius_dpd : float
        Radius (DPD length, > 0).
    subdivisions : int
        Subdivision level in [0, 7]; N_v = 10 * 4^subdivisions + 2.
    center : array_like, optional
        [3] centre (DPD length).

    Returns
    -------
    ShellMesh

    Raises
    ------
    ValueError
        On a non-positive radius or a subdivision level out of range.
    """
    trimesh = require("trimesh", "sim")

    if not (isinstance(radius_dpd, (int, float)) and math.isfinite(radius_dpd) and radius_dpd > 0):
        raise ValueError(f"radius_dpd must be a positive finite number, got {radius_dpd!r}")
    if not (isinstance(subdivisions, (int, np.integer)) and 0 <= subdivisions <= 7):
        raise ValueError(f"subdivisions must be an integer in [0, 7], got {subdivisions!r}")
    tm = trimesh.creation.icosphere(subdivisions=int(subdivisions), radius=1.0)
    v = np.asarray(tm.vertices, dtype=np.float64)
    v = v / np.linalg.norm(v, axis=1, keepdims=True) * float(radius_dpd)
    v = v + np.asarray(center, dtype=np.float64)
    f = np.asarray(tm.faces, dtype=np.int32)
    # make every face outward (trimesh already does; this guards against version changes)
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    flip = np.einsum("ij,ij->i", n, v[f].mean(axis=1) - np.asarray(center)) < 0
    f[flip] = f[flip][:, [0, 2, 1]]
    mesh = build_shell_mesh(v, f, radius_dpd=radius_dpd, subdivisions=int(subdivisions))
    assert mesh.n_vertices == n_vertices_for_subdivisions(subdivisions)
    return mesh


def diameter_to_radius_dpd(diameter_um: float, units: UnitSystem = DEFAULT_UNITS) -> float:
    """Bubble diameter -> radius in DPD length (D / 0.5 at u_l = 0.25 um), via :mod:`bubblecal.data.units`.

    Parameters
    ----------
    diameter_um : float
        Diameter (um, > 0).
    units : UnitSystem, optional
        Unit system.

    Returns
    -------
    float
        Radius (DPD length).

    Raises
    ------
    ValueError
        On a non-positive or non-finite diameter.
    """
    if not (math.isfinite(diameter_um) and diameter_um > 0):
        raise ValueError(f"diameter_um must be a positive finite number, got {diameter_um!r}")
    return float(units.radius_dpd(diameter_um))


def mesh_for_diameter(diameter_um: float, subdivisions: int | None = None,
                      units: UnitSystem = DEFAULT_UNITS, center=(0.0, 0.0, 0.0)) -> ShellMesh:
    """Icosphere for a bubble diameter: subdivision 4 (2,562 vertices), 5 above 5 um unless given.

    Parameters
    ----------
    diameter_um : float
        Diameter (um).
    subdivisions : int, optional
        Subdivision level (default by diameter, :data:`SUBDIVISION_5_ABOVE_UM`).
    units : UnitSystem, optional
        Unit system.
    center : array_like, optional
        [3] centre (DPD length).

    Returns
    -------
    ShellMesh
        With ``radius_dpd`` set.

    Raises
    ------
    ValueError
        On an invalid diameter or subdivision level.
    """
    if subdivisions is None:
        subdivisions = 5 if diameter_um > SUBDIVISION_5_ABOVE_UM else 4
    return icosphere(diameter_to_radius_dpd(diameter_um, units), subdivisions, center=center)
