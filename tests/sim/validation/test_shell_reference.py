"""Finite-difference tests of the NumPy float64 shell reference (bubblecal.sim.validation.shell_reference)."""

from __future__ import annotations

import numpy as np
import pytest

from bubblecal.sim.engine import ShellParams, icosphere
from bubblecal.sim.validation import shell_reference as sr

P = ShellParams(ka=10.0, mu=4.0, a3=-2.0, a4=8.0, b1=0.7, b2=0.75, kb=3.0, c0=0.3, ka_tot=5.0, kv_tot=7.0,
                p_back=2.0, self_avoid_cutoff=1.0, self_avoid_epsilon=0.5)


@pytest.fixture(scope="module")
def perturbed():
    m = icosphere(2.0, 1)
    rng = np.random.default_rng(0)
    return m, m.vertices + 0.08 * rng.standard_normal(m.vertices.shape)




TERMS = {
    "lim": (sr.lim_energy, sr.lim_forces),
    "kantor": (sr.kantor_energy, sr.kantor_forces),
    "juelicher": (sr.juelicher_energy, sr.juelicher_forces),
    "constraints": (lambda x, m, p: sum(sr.constraint_energies(x, m, p)), sr.constraint_forces),
    "self_avoid": (sr.self_avoid_energy, sr.self_avoid_forces),
}


@pytest.mark.parametrize("term", list(TERMS))
def test_forces_are_minus_gradient(perturbed, term):
    m, x = perturbed
    energy, forces = TERMS[term]
    f = forces(x, m, P)
    g = sr.finite_difference_forces(lambda y: energy(y, m, P), x)
    assert np.max(np.abs(g)) > 1e-3  # the term is exercised
    assert np.max(np.abs(f - g)) / np.max(np.abs(g)) < 1e-6
    np.testing.assert_allclose(f.sum(axis=0), 0.0, atol=1e-10 * np.abs(f).max())
    torque = np.cross(x, f).sum(axis=0)
    np.testing.assert_allclose(torque, 0.0, atol=1e-10 * np.abs(f).max() * np.abs(x).max())


def test_lim_per_triangle_net_force_and_torque(perturbed):
    m, x = perturbed
    ft = sr.lim_triangle_forces(x, m, P)
    xc = x[m.faces]
    s = np.abs(ft).max()
    assert np.abs(ft.sum(axis=1)).max() < 1e-12 * s
    assert np.abs(np.cross(xc, ft).sum(axis=1)).max() < 1e-12 * s * np.abs(x).max()


def test_zero_force_and_energy_at_reference():
    m = icosphere(6.0, 2)
    p = ShellParams(ka=16751.0, kb=500.0, a3=-2, a4=8, b1=0.7, b2=0.75, ka_tot=10, kv_tot=10)
    assert np.abs(sr.shell_forces(m.vertices, m, p)).max() < 1e-9
    np.testing.assert_allclose(sr.shell_energies(m.vertices, m, p), 0.0, atol=1e-9)


def test_lim_beta_is_shear_invariant():
    """beta = (l1 - l2)^2 / (2 l1 l2): 0 for isotropic scaling, the analytic value for a pure shear."""
    m = icosphere(1.0, 1)
    p = ShellParams(ka=0.0 + 1.0, mu=1.0, self_avoid=False)
    # isotropic scaling: beta = 0, alpha = lam^2 - 1
    w = sr.lim_energy(1.1 * m.vertices, m, p, per_triangle=True)
    np.testing.assert_allclose(w, m.A0 * 0.5 * (1.21 - 1) ** 2, rtol=1e-12)


def test_juelicher_sphere_numbers():
    m = icosphere(1.3, 3)
    e = sr.juelicher_energy(m.vertices, m, ShellParams(ka=1.0, kb=1.0))
    assert abs(e - 25.180) < 1e-3
