"""benchmarks/studies/water_curvature.py: the parameter row it writes carries the energy lam * M."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("warp")


def _energy(field_mod, mesh, params, x):
    ff = field_mod.ShellForceField([mesh], params, device="cpu")
    energies, forces = ff.energy_forces_numpy(x)
    return float(energies.sum()), forces


def test_the_added_energy_is_lam_times_the_mean_curvature(load_script, monkeypatch):
    mod = load_script("benchmarks/studies/water_curvature.py")
    import bubblecal.sim.engine.kernels.shell.field as field
    from bubblecal.sim.engine import ShellParams, icosphere

    radius, lam, kb_j = 6.0, 40.0, 5.0
    mesh = icosphere(radius, 3)
    params = [ShellParams(ka=1000.0, kb=50.0, self_avoid=False)]
    x = mesh.vertices.astype(float)
    e0, f0 = _energy(field, mesh, params, x)
    monkeypatch.setattr(field, "param_row", field.param_row)  # undone after the test
    mod.install(lam, kb_j)
    e1, f1 = _energy(field, mesh, params, x)
    area = mesh.area()
    tau = lam * lam / (8.0 * kb_j)
    # Juelicher at c0: 2 kb_j sum A H^2 - 2 kb_j c0 M + tau A, with sum A H^2 = 4 pi and M = 4 pi R on a sphere;
    # the cancelling area term 2 tau (A - 2 A)^2 / (4 A) = tau A / 2
    expected = 8.0 * math.pi * kb_j + lam * 4.0 * math.pi * radius + tau * area + tau * area / 2.0
    assert e1 - e0 == pytest.approx(expected, rel=0.02)
    # forces: the tension tau and the cancelling -tau leave lam M and the Juelicher bending (sum A H^2 does not
    # depend on R), so the added force is radial, inward, and sums to -dE/dR = -4 pi lam
    df = f1 - f0
    unit = x / np.linalg.norm(x, axis=1, keepdims=True)
    radial = np.einsum("ij,ij->i", df, unit)
    assert np.all(radial < 0)
    assert np.linalg.norm(df - radial[:, None] * unit) < 1e-2 * np.linalg.norm(df)  # discrete normals
    assert radial.sum() == pytest.approx(-4.0 * math.pi * lam, rel=0.01)


def test_bad_constants_are_refused(load_script):
    mod = load_script("benchmarks/studies/water_curvature.py")
    from bubblecal.sim.engine.kernels.shell.layout import N_PARAMS, P_KB_JUL

    with pytest.raises(ValueError, match="kb_j"):
        mod.curvature_row(np.zeros(N_PARAMS), 1.0, 10.0, 0.0)
    row = np.zeros(N_PARAMS)
    row[P_KB_JUL] = 1.0
    with pytest.raises(ValueError, match="already"):
        mod.curvature_row(row, 1.0, 10.0, 1.0)
