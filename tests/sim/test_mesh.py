"""Icosphere mesh invariants and reference state (bubblecal.sim.mesh)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bubblecal.sim.mesh import (
    build_shell_mesh,
    diameter_to_radius_dpd,
    dihedral_angles,
    icosphere,
    mesh_for_diameter,
    n_vertices_for_subdivisions,
)


@pytest.mark.parametrize("s", [0, 1, 2, 3])
def test_counts_euler_orientation(s):
    m = icosphere(2.5, s)
    assert m.n_vertices == n_vertices_for_subdivisions(s) == 10 * 4**s + 2
    assert m.n_faces == 20 * 4**s
    assert m.n_edges == 30 * 4**s
    assert m.euler_characteristic() == 2
    assert m.faces.dtype == np.int32 and m.edges.dtype == np.int32 and m.dihedrals.dtype == np.int32
    x = m.vertices
    np.testing.assert_allclose(np.linalg.norm(x, axis=1), 2.5, rtol=1e-12)
    n = np.cross(x[m.faces[:, 1]] - x[m.faces[:, 0]], x[m.faces[:, 2]] - x[m.faces[:, 0]])
    assert np.all(np.einsum("ij,ij->i", n, x[m.faces].mean(axis=1)) > 0)  # outward
    assert m.volume() > 0


def test_dihedral_convention():
    m = icosphere(1.0, 2)
    faces = {tuple(np.roll(f, k)) for f in m.faces.tolist() for k in range(3)}
    for a, b, c, d in m.dihedrals.tolist():
        assert a < b
        assert (a, b, c) in faces and (b, a, d) in faces
    np.testing.assert_array_equal(m.edges, m.dihedrals[:, :2])
    assert np.all(m.theta0 > 0)  # convex
    # flat patch -> 0; folding one side down (convex ridge) -> positive
    x = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0]], dtype=float)
    q = np.array([[0, 1, 2, 3]])
    assert abs(dihedral_angles(x, q)[0]) < 1e-15
    x[2, 2] = x[3, 2] = -0.1
    assert dihedral_angles(x, q)[0] > 0


def test_reference_quantities_and_areas():
    m = icosphere(3.0, 3)
    e1 = m.vertices[m.faces[:, 1]] - m.vertices[m.faces[:, 0]]
    e2 = m.vertices[m.faces[:, 2]] - m.vertices[m.faces[:, 0]]
    np.testing.assert_allclose(m.l1, np.linalg.norm(e1, axis=1))
    np.testing.assert_allclose(m.l2, np.linalg.norm(e2, axis=1))
    np.testing.assert_allclose(m.d0, np.einsum("ij,ij->i", e1, e2))
    np.testing.assert_allclose(m.A0, 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1))
    assert math.isclose(m.vertex_areas().sum(), m.area(), rel_tol=1e-12)
    assert math.isclose(m.A0.sum(), m.area(), rel_tol=1e-12)
    assert 0.99 < m.volume() / (4 / 3 * math.pi * 27) < 1.0
    assert 0.99 < m.area() / (4 * math.pi * 9) < 1.0
    # translation invariance of the volume
    assert math.isclose(m.volume(m.vertices + 100.0), m.volume(), rel_tol=1e-10)
    assert not m.vertices.flags.writeable


def test_diameter_and_subdivision_choice():
    assert diameter_to_radius_dpd(2.1) == pytest.approx(4.2)
    assert diameter_to_radius_dpd(3.0) == pytest.approx(6.0)
    m = mesh_for_diameter(3.0)
    assert m.subdivisions == 4 and m.n_vertices == 2562 and m.radius_dpd == pytest.approx(6.0)
    assert mesh_for_diameter(2.1, subdivisions=2).n_vertices == 162
    assert mesh_for_diameter(5.8).n_vertices == 10242  # subdivision 5 above 5 um
    with pytest.raises(ValueError, match="diameter_um"):
        diameter_to_radius_dpd(-1.0)
    with pytest.raises(ValueError, match="radius_dpd"):
        icosphere(0.0, 2)
    with pytest.raises(ValueError, match="subdivisions"):
        icosphere(1.0, -1)


def test_vertex_mass():
    m = icosphere(6.0, 2)
    m1 = m.vertex_mass()
    assert m1 > 0
    assert m.vertex_mass(mass_factor=160.0) == pytest.approx(160.0 * m1)
    assert m.vertex_mass(density_kg_m3=5500.0) == pytest.approx(5.0 * m1)


def test_build_rejects_bad_meshes():
    m = icosphere(1.0, 1)
    with pytest.raises(ValueError, match="outward"):
        build_shell_mesh(m.vertices, m.faces[:, [0, 2, 1]])
    with pytest.raises(ValueError, match="closed"):
        build_shell_mesh(m.vertices, m.faces[:-1])
