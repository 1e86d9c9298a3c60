"""Icosphere shell meshes and their stress-free reference state (NumPy float64).

The input mesh *is* the stress-free reference of the shell (physics.md section 3): every reference
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

from bubblecal.data.units import DEFAULT_UNITS, UnitSystem
from bubblecal.sim.engine.particles import RHO_SHELL_KG_M3

__all__ = [
    "ShellMesh",
    "icosphere",
    "diameter_to_radius_dpd",
    "mesh_for_diameter",
    "n_vertices_for_subdivisions",
    "build_shell_mesh",
    "triangle_areas",
    "mesh_volume",
    "dihedral_angles",
    "lim_reference",
    "pole_patches",
    "SUBDIVISION_5_ABOVE_UM",
]

#: Above this diameter [um] :func:`mesh_for_diameter` uses subdivision 5 (physics.md section 3).
SUBDIVISION_5_ABOVE_UM = 5.0


def n_vertices_for_subdivisions(subdivisions: int) -> int:
    """Number of vertices of an icosphere: N_v = 10 * 4^s + 2."""
    return 10 * 4 ** int(subdivisions) + 2


# ----------------------------------------------------------------------------------------------
# geometry helpers (vectorised, float64)
# ----------------------------------------------------------------------------------------------
def triangle_areas(x: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Per-triangle area [Nt]."""
    x = np.asarray(x, dtype=np.float64)
    n = np.cross(x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]])
    return 0.5 * np.linalg.norm(n, axis=1)


def mesh_volume(x: np.ndarray, faces: np.ndarray) -> float:
    """Enclosed volume of a closed, outward-oriented triangulation (divergence theorem).

    Computed relative to the vertex centroid, which keeps float rounding small far from the origin.
    """
    x = np.asarray(x, dtype=np.float64)
    x = x - x.mean(axis=0)
    x0, x1, x2 = x[faces[:, 0]], x[faces[:, 1]], x[faces[:, 2]]
    return float(np.sum(np.einsum("ij,ij->i", x0, np.cross(x1, x2))) / 6.0)


def dihedral_angles(x: np.ndarray, dihedrals: np.ndarray) -> np.ndarray:
    """Signed dihedral angle per edge (convention in the module docstring), in (-pi, pi]."""
    x = np.asarray(x, dtype=np.float64)
    a, b, c, d = (x[dihedrals[:, k]] for k in range(4))
    e = b - a
    n1 = np.cross(e, c - a)
    n2 = np.cross(-e, d - b)
    el = np.linalg.norm(e, axis=1)
    cos_t = np.einsum("ij,ij->i", n1, n2)
    sin_t = np.einsum("ij,ij->i", np.cross(n1, n2), e) / el
    return np.arctan2(sin_t, cos_t)


def lim_reference(x: np.ndarray, faces: np.ndarray) -> dict[str, np.ndarray]:
    """Lim reference per triangle: l1, l2 (edge lengths of e1 = X1-X0, e2 = X2-X0), d0 = e1.e2, A0."""
    x = np.asarray(x, dtype=np.float64)
    e1 = x[faces[:, 1]] - x[faces[:, 0]]
    e2 = x[faces[:, 2]] - x[faces[:, 0]]
    return {
        "l1": np.linalg.norm(e1, axis=1),
        "l2": np.linalg.norm(e2, axis=1),
        "d0": np.einsum("ij,ij->i", e1, e2),
        "A0": 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1),
    }


def _edges_and_dihedrals(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Unique edges (a < b) and their dihedral quadruples (a, b, c, d); raises on a non-manifold mesh."""
    f = np.asarray(faces, dtype=np.int64)
    # directed half-edges (i -> j) with the opposite vertex k, in each face's cyclic order
    src = np.concatenate([f[:, 0], f[:, 1], f[:, 2]])
    dst = np.concatenate([f[:, 1], f[:, 2], f[:, 0]])
    opp = np.concatenate([f[:, 2], f[:, 0], f[:, 1]])
    key = src * n_vertices + dst
    if np.unique(key).size != key.size:
        raise ValueError("mesh is not consistently oriented or not manifold (a directed edge repeats)")
    lookup = dict(zip(key.tolist(), opp.tolist(), strict=True))
    forward = src < dst
    a, b, c = src[forward], dst[forward], opp[forward]
    try:
        d = np.array([lookup[int(bb) * n_vertices + int(aa)] for aa, bb in zip(a, b, strict=True)],
                     dtype=np.int64)
    except KeyError as exc:  # an edge with one face only
        raise ValueError("mesh is not closed (an edge has a single adjacent face)") from exc
    order = np.lexsort((b, a))
    edges = np.stack([a, b], axis=1)[order]
    dih = np.stack([a, b, c, d], axis=1)[order]
    if 2 * edges.shape[0] != 3 * f.shape[0]:
        raise ValueError("mesh is not closed: 2 N_e != 3 N_t")
    return edges.astype(np.int32), dih.astype(np.int32)


@dataclass(frozen=True, eq=False)
class ShellMesh:
    """A closed triangulated shell and its stress-free reference state (all NumPy, float64).

    Attributes: ``vertices [Nv,3]`` (the reference positions, DPD lengths), ``faces [Nt,3] int32``
    (outward), ``edges [Ne,2] int32``, ``dihedrals [Ne,4] int32`` (see module docstring),
    ``l1, l2, d0, A0 [Nt]`` (Lim reference), ``theta0 [Ne]`` (reference dihedral angles),
    ``radius_dpd`` (nominal radius; 0 for a mesh that is not an icosphere), ``subdivisions``
    (-1 when unknown).
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
        return int(self.vertices.shape[0])

    @property
    def n_faces(self) -> int:
        return int(self.faces.shape[0])

    @property
    def n_edges(self) -> int:
        return int(self.edges.shape[0])

    # ----- reference geometry -------------------------------------------------------------------
    def area(self, x: np.ndarray | None = None) -> float:
        """Total area of the reference (or of positions ``x``)."""
        return float(np.sum(triangle_areas(self.vertices if x is None else x, self.faces)))

    def volume(self, x: np.ndarray | None = None) -> float:
        """Enclosed volume of the reference (or of positions ``x``)."""
        return mesh_volume(self.vertices if x is None else x, self.faces)

    def vertex_areas(self, x: np.ndarray | None = None) -> np.ndarray:
        """Barycentric vertex areas A_v = sum of adjacent triangle areas / 3 [Nv]."""
        at = triangle_areas(self.vertices if x is None else x, self.faces)
        out = np.zeros(self.n_vertices)
        for k in range(3):
            np.add.at(out, self.faces[:, k], at / 3.0)
        return out

    def edge_lengths(self, x: np.ndarray | None = None) -> np.ndarray:
        x = self.vertices if x is None else np.asarray(x, dtype=np.float64)
        return np.linalg.norm(x[self.edges[:, 1]] - x[self.edges[:, 0]], axis=1)

    def min_edge_length(self) -> float:
        """Shortest reference edge (sets the self-avoidance cut-off)."""
        if "min_edge" not in self._cache:
            self._cache["min_edge"] = float(self.edge_lengths().min())
        return self._cache["min_edge"]

    def euler_characteristic(self) -> int:
        return self.n_vertices - self.n_edges + self.n_faces

    def vertex_mass(self, density_kg_m3: float = RHO_SHELL_KG_M3, thickness_m: float | None = None,
                    mass_factor: float = 1.0, units: UnitSystem = DEFAULT_UNITS) -> float:
        """Mass of one vertex [DPD mass]: rho_shell h A_mesh u_l^2 / (u_m N_v), times ``mass_factor``.

        physics.md section 2 (rho_shell = 1100 kg/m^3; x5 in the published indentation set) and
        section 5 (mass factor 160 for ringdown runs).
        """
        h = units.shell_thickness_m if thickness_m is None else thickness_m
        if density_kg_m3 <= 0 or h <= 0 or mass_factor <= 0:
            raise ValueError("vertex_mass: density, thickness and mass_factor must be > 0")
        m = density_kg_m3 * h * self.area() * units.length_m**2 / (units.mass_kg * self.n_vertices)
        return float(m * mass_factor)

    def translated(self, shift) -> ShellMesh:
        """The same mesh with its vertices (reference) shifted by ``shift``."""
        return build_shell_mesh(self.vertices + np.asarray(shift, dtype=np.float64), self.faces,
                                radius_dpd=self.radius_dpd, subdivisions=self.subdivisions)


def build_shell_mesh(vertices: np.ndarray, faces: np.ndarray, *, radius_dpd: float = 0.0,
                     subdivisions: int = -1) -> ShellMesh:
    """Build a :class:`ShellMesh` from any closed outward-oriented triangulation (stress-free)."""
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int32)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise ValueError("vertices must be [Nv,3] and faces [Nt,3]")
    edges, dih = _edges_and_dihedrals(f, v.shape[0])
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
    """Icosphere (``trimesh.creation.icosphere``) of radius ``radius_dpd`` [DPD length].

    All vertices lie on the sphere; N_v = 10 * 4^subdivisions + 2.
    """
    import trimesh

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


def pole_patches(vertices: np.ndarray, *, fraction: float | None = None,
                 cap_deg: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Vertex indices (top, bottom) that carry the indentation pole forces, each sorted by distance to its pole.

    ``vertices``: reference positions [N_v, 3] (DPD length); poles on the z axis through their mean.
    ``fraction``: the k = max(1, floor(fraction N_v)) top-most and bottom-most vertices by z (physics.md's
    convention).  ``cap_deg``: every vertex within ``cap_deg`` degrees of polar angle from a pole (at least
    the pole-most one): a patch of the same size on every mesh level (4.6 deg = the pole vertex and its first
    ring at subdivision 4, two rings at 5), where a vertex fraction grows a partial ring on finer meshes.
    Exactly one of the two is given.  Both patches have the same size (the callers weight every loaded vertex
    by 1/k): a mesh whose caps differ raises ValueError.
    """
    if (fraction is None) == (cap_deg is None):
        raise ValueError("give exactly one of fraction (loaded vertices / N_v) and cap_deg (polar cap, degrees)")
    v = np.asarray(vertices, dtype=np.float64)
    z = v[:, 2]
    if fraction is not None:
        if not (0 < fraction < 0.5):
            raise ValueError(f"fraction must lie in (0, 0.5), got {fraction!r}")
        k = max(1, int(math.floor(fraction * len(v))))
        order = np.argsort(z, kind="stable")  # stable: the published convention's vertex choice, bit for bit
        return order[::-1][:k], order[:k]
    if not (math.isfinite(cap_deg) and 0 <= cap_deg < 90):
        raise ValueError(f"cap_deg must lie in [0, 90) degrees, got {cap_deg!r}")
    u = v - v.mean(axis=0)
    cos_polar = u[:, 2] / np.linalg.norm(u, axis=1)
    cos_cap = math.cos(math.radians(cap_deg))
    out = []
    for sign in (1.0, -1.0):
        c = sign * cos_polar
        idx = np.nonzero(c >= cos_cap - 1e-12)[0]
        if idx.size == 0:  # a coarse mesh without a vertex in the cap: the pole-most vertex alone
            idx = np.array([int(np.argmax(c))])
        out.append(idx[np.argsort(-c[idx], kind="stable")])
    if len(out[0]) != len(out[1]):
        raise ValueError(f"the pole patches differ in size ({len(out[0])} top, {len(out[1])} bottom vertices)")
    return out[0], out[1]


def diameter_to_radius_dpd(diameter_um: float, units: UnitSystem = DEFAULT_UNITS) -> float:
    """Bubble diameter [um] -> DPD radius (= D / 0.5 at u_l = 0.25 um), via :mod:`bubblecal.data.units`."""
    if not (math.isfinite(diameter_um) and diameter_um > 0):
        raise ValueError(f"diameter_um must be a positive finite number, got {diameter_um!r}")
    return float(units.radius_dpd(diameter_um))


def mesh_for_diameter(diameter_um: float, subdivisions: int | None = None,
                      units: UnitSystem = DEFAULT_UNITS, center=(0.0, 0.0, 0.0)) -> ShellMesh:
    """Icosphere for a bubble diameter: subdivision 4 (2,562 vertices), 5 above 5 um unless given."""
    if subdivisions is None:
        subdivisions = 5 if diameter_um > SUBDIVISION_5_ABOVE_UM else 4
    return icosphere(diameter_to_radius_dpd(diameter_um, units), subdivisions, center=center)
