"""Icosphere mesh invariants and reference state (bubblecal.sim.engine.mesh)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bubblecal.sim.engine import (
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


def test_pole_patches_fraction_keeps_the_top_most_vertices_and_the_cap_is_mesh_independent():
    from bubblecal.sim.engine import pole_patches

    m4 = icosphere(11.5, 4, center=(1.0, -2.0, 3.0))
    top, bottom = pole_patches(m4.vertices, fraction=0.01)
    order = np.argsort(m4.vertices[:, 2], kind="stable")  # physics.md: k = floor(0.01 N_v) by z
    assert len(top) == 25 and set(top) == set(order[::-1][:25]) and set(bottom) == set(order[:25])
    # the Mirheo patch: the pole vertex and its first ring at subdivision 4, two full rings at 5
    counts = {s: len(pole_patches(icosphere(11.5, s).vertices, cap_deg=4.6)[0]) for s in (3, 4, 5)}
    assert counts == {3: 1, 4: 7, 5: 19}
    m5 = icosphere(11.5, 5, center=(1.0, -2.0, 3.0))
    for m in (m4, m5):
        top, bottom = pole_patches(m.vertices, cap_deg=4.6)
        c = m.vertices.mean(axis=0)
        u = (m.vertices - c) / np.linalg.norm(m.vertices - c, axis=1)[:, None]
        polar_top = np.degrees(np.arccos(np.clip(u[top, 2], -1, 1)))
        assert polar_top[0] == pytest.approx(0.0, abs=1e-9) and polar_top.max() <= 4.6  # pole first, all in the cap
        assert len(bottom) == len(top) and np.all(u[bottom, 2] < -0.99)
        outside = np.setdiff1d(np.arange(m.n_vertices), np.concatenate([top, bottom]))
        assert np.degrees(np.arccos(np.abs(u[outside, 2]).max())) > 5.4  # the next ring is well outside
    assert len(pole_patches(m4.vertices, cap_deg=0.0)[0]) == 1  # the pole vertex alone
    with pytest.raises(ValueError, match="exactly one of fraction"):
        pole_patches(m4.vertices, fraction=0.01, cap_deg=4.6)
    with pytest.raises(ValueError, match="exactly one of fraction"):
        pole_patches(m4.vertices)
    with pytest.raises(ValueError, match=r"cap_deg must lie in \[0, 90\)"):
        pole_patches(m4.vertices, cap_deg=95.0)
    with pytest.raises(ValueError, match=r"fraction must lie in \(0, 0.5\)"):
        pole_patches(m4.vertices, fraction=0.7)
    # a cloud whose two caps hold different numbers of vertices cannot share one 1/k weight
    lopsided = np.array([[0, 0, 1.0], [0.02, 0, 0.9998], [0, 0, -1.0], [1.0, 0, 0], [-1.0, 0, 0]])
    with pytest.raises(ValueError, match=r"the pole patches differ in size \(2 top, 1 bottom vertices\)"):
        pole_patches(lopsided, cap_deg=4.6)
