"""Warp shell kernels (bubblecal.sim.engine.kernels.shell) against the float64 NumPy reference and FD."""

from __future__ import annotations

import numpy as np
import pytest

wp = pytest.importorskip("warp")
wp.config.quiet = True

from bubblecal.sim.engine import (  # noqa: E402
    ENERGY_TERMS,
    ShellForceField,
    ShellParams,
    icosphere,
)
from bubblecal.sim.validation import shell_reference as sr  # noqa: E402

P_KANTOR = ShellParams(ka=10.0, mu=4.0, a3=-2.0, a4=8.0, b1=0.7, b2=0.75, kb=3.0, ka_tot=5.0, kv_tot=7.0,
                       p_back=2.0, self_avoid_cutoff=1.0, self_avoid_epsilon=0.5)
P_JUL = ShellParams(ka=7.0, kb=2.0, bending="juelicher", c0=0.3, self_avoid=False, p_back=1.0)


def two_replicas(dtype, sub=2, seed=0):
    m = icosphere(2.0, sub)
    rng = np.random.default_rng(seed)
    xa = m.vertices + 0.05 * rng.standard_normal(m.vertices.shape)
    xb = m.vertices + 0.05 * rng.standard_normal(m.vertices.shape) + np.array([10.0, 0.0, 0.0])
    offsets = [5, 5 + m.n_vertices + 3]
    ff = ShellForceField([m, m.translated([10.0, 0.0, 0.0])], [P_KANTOR, P_JUL], device="cpu", dtype=dtype,
                         offsets=offsets)
    x = np.zeros((ff.n_rows_min + 2, 3))
    x[offsets[0]:offsets[0] + m.n_vertices] = xa
    x[offsets[1]:offsets[1] + m.n_vertices] = xb
    return m, ff, x, offsets


@pytest.mark.parametrize("dtype,tol", [(wp.float64, 1e-12), (wp.float32, 2e-5)])
def test_batched_kernels_match_reference(dtype, tol):
    m, ff, x, offsets = two_replicas(dtype)
    e, f = ff.energy_forces_numpy(x)
    assert e.shape == (2, len(ENERGY_TERMS))
    for r, (o, p) in enumerate(zip(offsets, [P_KANTOR, P_JUL], strict=True)):
        xr = x[o:o + m.n_vertices]
        mr = m if r == 0 else m.translated([10.0, 0.0, 0.0])
        fr = sr.shell_forces(xr, mr, p)
        er = sr.shell_energies(xr, mr, p)
        assert np.abs(f[o:o + m.n_vertices] - fr).max() / np.abs(fr).max() < tol
        np.testing.assert_allclose(e[r], er, rtol=max(tol, 1e-9) * 10, atol=tol * np.abs(er).max())
    # rows outside the shells stay untouched
    mask = np.ones(x.shape[0], bool)
    for o in offsets:
        mask[o:o + m.n_vertices] = False
    assert np.all(f[mask] == 0.0)
    # areas / volumes
    xa = wp.array(x, dtype=ff.vec3, device="cpu")
    a, v = ff.areas_volumes(xa)
    for r, o in enumerate(offsets):
        assert a[r] == pytest.approx(m.area(x[o:o + m.n_vertices]), rel=tol * 10)
        assert v[r] == pytest.approx(m.volume(x[o:o + m.n_vertices]), rel=tol * 10)


def test_accumulate_forces_adds_into_f():
    m, ff, x, offsets = two_replicas(wp.float64)
    xw = wp.array(x, dtype=wp.vec3d, device="cpu")
    f0 = np.ones_like(x)
    fw = wp.array(f0, dtype=wp.vec3d, device="cpu")
    ff.accumulate_forces(xw, fw)
    _, f = ff.energy_forces_numpy(x, with_energy=False)
    np.testing.assert_allclose(fw.numpy(), f0 + f, rtol=1e-12, atol=1e-12)
    with pytest.raises(TypeError):
        ff.accumulate_forces(wp.array(x, dtype=wp.vec3f, device="cpu"), fw)
    with pytest.raises(ValueError, match="rows"):
        ff.accumulate_forces(wp.zeros(3, dtype=wp.vec3d, device="cpu"), fw)


def _fd_check(p, sub, term_col, seed=3):
    m = icosphere(1.5, sub)
    rng = np.random.default_rng(seed)
    x = m.vertices + 0.06 * rng.standard_normal(m.vertices.shape)
    ff = ShellForceField(m, [p], device="cpu", dtype=wp.float64)
    _, f = ff.energy_forces_numpy(x, with_energy=False)
    f_fd = sr.finite_difference_forces(lambda y: ff.energy_forces_numpy(y)[0][0].sum(), x, h=1e-6)
    assert np.abs(f_fd).max() > 1e-3
    assert np.abs(f - f_fd).max() / np.abs(f_fd).max() < 1e-6


def test_fd_lim_kernel():
    _fd_check(ShellParams(ka=20.0, mu=9.0, a3=-2.0, a4=8.0, b1=0.7, b2=0.75, self_avoid=False), 1, 0)


def test_fd_kantor_kernel():
    _fd_check(ShellParams(ka=1e-9, mu=0.0, kb=5.0, self_avoid=False), 2, 1)


def test_fd_juelicher_kernel():
    _fd_check(ShellParams(ka=1e-9, mu=0.0, kb=5.0, c0=0.4, bending="juelicher", self_avoid=False), 1, 1)


def test_fd_constraints_and_self_avoid_kernel():
    _fd_check(ShellParams(ka=1e-9, mu=0.0, ka_tot=30.0, kv_tot=20.0, p_back=3.0, self_avoid_cutoff=1.0,
                          self_avoid_epsilon=0.3), 1, 2)


def test_zero_force_at_reference_float32():
    m = icosphere(6.0, 3)
    p = ShellParams(ka=16751.0, kb=500.0)
    ff = ShellForceField(m, [p], device="cpu", dtype=wp.float32)
    _, f = ff.energy_forces_numpy(m.vertices, with_energy=False)
    assert np.abs(f).max() < 1e-4 * 16751.0 * 0.01 * m.min_edge_length()


def test_bond_viscosity():
    m = icosphere(1.0, 1)
    p = ShellParams(ka=1.0, bond_viscosity=2.5, self_avoid=False)
    ff = ShellForceField(m, [p], device="cpu", dtype=wp.float64)
    rng = np.random.default_rng(1)
    v = rng.standard_normal(m.vertices.shape)
    xw = wp.array(m.vertices, dtype=wp.vec3d, device="cpu")
    vw = wp.array(v, dtype=wp.vec3d, device="cpu")
    fw = wp.zeros(m.n_vertices, dtype=wp.vec3d, device="cpu")
    ff.accumulate_forces(xw, fw, vw)
    expect = np.zeros_like(v)
    a, b = m.edges[:, 0], m.edges[:, 1]
    e = m.vertices[b] - m.vertices[a]
    e /= np.linalg.norm(e, axis=1, keepdims=True)
    fa = 2.5 * np.einsum("ij,ij->i", v[b] - v[a], e)[:, None] * e
    np.add.at(expect, a, fa)
    np.add.at(expect, b, -fa)
    np.testing.assert_allclose(fw.numpy(), expect, atol=1e-12)
    # dissipative: the power is never positive
    assert np.sum(expect * v) <= 0


def test_constructor_validation():
    m = icosphere(1.0, 1)
    with pytest.raises(ValueError, match="overlap"):
        ShellForceField([m, m], [P_KANTOR, P_KANTOR], offsets=[0, 10], device="cpu")
    with pytest.raises(ValueError, match="dtype"):
        ShellForceField(m, [P_KANTOR], device="cpu", dtype=wp.float16)
    with pytest.raises(ValueError, match="meshes"):
        ShellForceField([m, m, m], [P_KANTOR, P_KANTOR], device="cpu")


@pytest.mark.parametrize("kwargs,field", [
    (dict(ka=0.0), "ka"), (dict(ka=1.0, mu=-1.0), "mu"), (dict(ka=1.0, kb=-1.0), "kb"),
    (dict(ka=1.0, bending="helfrich"), "bending"), (dict(ka=1.0, self_avoid_cutoff=0.0), "self_avoid_cutoff"),
    (dict(ka=1.0, ka_tot=-2.0), "ka_tot"), (dict(ka=1.0, a3=float("nan")), "a3"),
    (dict(ka=1.0, self_avoid=1), "self_avoid"), (dict(ka=1.0, bond_viscosity=-1.0), "bond_viscosity"),
])
def test_params_validation_names_field(kwargs, field):
    with pytest.raises(ValueError, match=f"ShellParams.{field} "):
        ShellParams(**kwargs)


def test_params_defaults():
    p = ShellParams(ka=300.0)
    assert p.mu == pytest.approx(100.0)
    assert p.bending == "kantor" and p.self_avoid and p.self_avoid_cutoff == 0.8
    assert p.ka_tot == p.kv_tot == p.p_back == p.bond_viscosity == 0.0


def _cuda_available() -> bool:
    try:
        wp.init()
        return wp.is_cuda_available()
    except Exception:  # pragma: no cover
        return False


@pytest.mark.gpu
@pytest.mark.skipif(not _cuda_available(), reason="needs CUDA")
def test_cuda_float32_matches_reference_and_graph_capture():
    m = icosphere(6.0, 3)
    rng = np.random.default_rng(5)
    reps = 4
    x = np.concatenate([m.vertices + 0.02 * rng.standard_normal(m.vertices.shape) + 20.0 * r for r in range(reps)])
    meshes = [m.translated([20.0 * r] * 3) for r in range(reps)]
    params = [ShellParams(ka=16751.0, kb=500.0 + r, self_avoid_cutoff=1.0) for r in range(reps - 1)]
    params.append(ShellParams(ka=5000.0, kb=300.0, bending="juelicher", kv_tot=100.0, p_back=91.0))
    ff = ShellForceField(meshes, params, device="cuda", dtype=wp.float32)
    e, f = ff.energy_forces_numpy(x)
    for r in range(reps):
        sl = slice(r * m.n_vertices, (r + 1) * m.n_vertices)
        fr = sr.shell_forces(x[sl], meshes[r], params[r])
        assert np.abs(f[sl] - fr).max() / np.abs(fr).max() < 1e-4
        er = sr.shell_energies(x[sl], meshes[r], params[r])
        np.testing.assert_allclose(e[r, :5], er[:5], rtol=1e-3, atol=1e-3 * np.abs(er).max())
    xw = wp.array(x, dtype=wp.vec3f, device="cuda")
    fw = wp.zeros_like(xw)
    ff.accumulate_forces(xw, fw)  # warm-up (HashGrid reservation)
    with wp.ScopedCapture(device="cuda") as cap:
        fw.zero_()
        ff.accumulate_forces(xw, fw)
    wp.capture_launch(cap.graph)
    np.testing.assert_allclose(fw.numpy(), f, rtol=1e-5, atol=1e-3)


def test_health_indicators():
    m = icosphere(2.0, 2)
    ff = ShellForceField([m, m.translated([9.0, 0, 0])], [ShellParams(ka=1.0)] * 2, device="cpu", dtype=wp.float64)
    x = np.concatenate([m.vertices, m.vertices + 9.0 * np.array([1.0, 0, 0])])
    x[m.n_vertices:] = 9.0 * np.array([1.0, 0, 0]) + 1.1 * m.vertices  # replica 1 stretched by 10 %
    x[0] = -0.2 * m.vertices[0]                                          # replica 0: vertex pushed through
    h = ff.health(wp.array(x, dtype=wp.vec3d, device="cpu"))
    assert h["max_area_strain"][1] == pytest.approx(0.21, rel=1e-9)
    assert h["min_area_ratio"][1] == pytest.approx(1.21, rel=1e-9)
    assert h["max_dihedral_change"][1] < 1e-9
    assert h["max_dihedral_change"][0] > 1.0  # folded triangles


def test_replicas_sharing_coordinates_do_not_interact():
    """Replicas in their own boxes share coordinates; self-avoidance must stay within one shell."""
    m = icosphere(2.0, 2)
    rng = np.random.default_rng(7)
    p = ShellParams(ka=10.0, kb=3.0, self_avoid_cutoff=1.0, self_avoid_epsilon=0.5)
    xa = m.vertices + 0.05 * rng.standard_normal(m.vertices.shape)
    xb = 1.9 * m.vertices + 0.05 * rng.standard_normal(m.vertices.shape)  # far outside its grid slot
    ff = ShellForceField([m, m, m], [p, p, p], device="cpu", dtype=wp.float64)
    e, f = ff.energy_forces_numpy(np.concatenate([xa, xb, xa]))
    n = m.n_vertices
    for r, xr in enumerate([xa, xb, xa]):
        fr = sr.shell_forces(xr, m, p)
        assert np.abs(f[r * n:(r + 1) * n] - fr).max() / np.abs(fr).max() < 1e-12
        assert e[r, 5] == pytest.approx(sr.self_avoid_energy(xr, m, p), rel=1e-12)
    assert e[0, 5] > 0


@pytest.mark.parametrize("dtype,tol", [(wp.float64, 1e-12), (wp.float32, 1e-5)])
def test_gather_and_scatter_modes_agree(dtype, tol):
    m, ff, x, offsets = two_replicas(dtype)
    assert ff.force_mode == "scatter"  # auto on CPU
    ff.force_mode = "gather"
    _, f_gather = ff.energy_forces_numpy(x, with_energy=False)
    _, f_scatter = ff.energy_forces_numpy(x, with_energy=True)  # energies use the scatter kernels
    assert np.abs(f_gather - f_scatter).max() / np.abs(f_scatter).max() < tol
    with pytest.raises(ValueError, match="force_mode"):
        ShellForceField(m, [P_KANTOR], device="cpu", force_mode="both")


@pytest.mark.parametrize("mode", ["scatter", "gather"])
def test_skip_binding_drops_only_flagged_replicas(mode):
    m, ff, x, offsets = two_replicas(wp.float64)
    P_K2 = ShellParams(ka=10.0, mu=4.0, kb=3.0, self_avoid_cutoff=1.0, self_avoid_epsilon=0.5)
    ff = ShellForceField([m, m.translated([10.0, 0.0, 0.0])], [P_KANTOR, P_K2], device="cpu", dtype=wp.float64,
                         offsets=offsets, force_mode=mode)
    xa = wp.array(x, dtype=ff.vec3, device="cpu")
    full = wp.zeros_like(xa)
    ff.accumulate_forces(xa, full)
    skip = wp.array(np.array([0, 1], dtype=np.int32), dtype=wp.int32, device="cpu")
    ff.set_skip(skip)
    part = wp.zeros_like(xa)
    ff.accumulate_forces(xa, part)
    f_full, f_part = full.numpy(), part.numpy()
    a, b = offsets[0], offsets[1]
    n = m.n_vertices
    np.testing.assert_array_equal(f_part[a:a + n], f_full[a:a + n])
    assert np.abs(f_full[b:b + n]).max() > 0
    assert np.all(f_part[b:b + n] == 0.0)
    # the binding is read at launch time: flipping the flag restores the forces
    skip.assign(np.array([0, 0], dtype=np.int32))
    part.zero_()
    ff.accumulate_forces(xa, part)
    np.testing.assert_array_equal(part.numpy(), f_full)
    e_before = ff.energies(xa)
    skip.assign(np.array([1, 1], dtype=np.int32))
    np.testing.assert_array_equal(ff.energies(xa), e_before)  # energies ignore the binding
    ff.set_skip(None)
    with pytest.raises(ValueError, match="skip must be an int32"):
        ff.set_skip(wp.zeros(3, dtype=wp.int32, device="cpu"))


@pytest.mark.parametrize("mode", ["scatter", "gather"])
def test_gas_binding_adds_minus_p_dv_dx(mode):
    """set_gas: the inside gas acts as -(p0 V0 / V - p_amb) dV/dx; checked against the volume's finite-difference
    gradient (float64, two replicas with their own gas), and only through accumulate_forces."""
    m, _, x, offsets = two_replicas(wp.float64)
    ff = ShellForceField([m, m.translated([10.0, 0.0, 0.0])], [P_KANTOR, P_JUL], device="cpu", dtype=wp.float64,
                         offsets=offsets, force_mode=mode)
    xa = wp.array(x, dtype=ff.vec3, device="cpu")
    plain = wp.zeros_like(xa)
    ff.accumulate_forces(xa, plain)
    _, vols = ff.areas_volumes(xa)
    gas = wp.array(np.array([[3.0 * 30.0, 1.0], [2.0 * 40.0, 0.5]]), dtype=wp.float64, device="cpu")
    vol = wp.array(vols, dtype=wp.float64, device="cpu")
    ff.set_gas(gas, vol)
    with_gas = wp.zeros_like(xa)
    ff.accumulate_forces(xa, with_gas)
    g = gas.numpy()
    n, h = m.n_vertices, 1e-6
    for r, o in enumerate(offsets):
        p = g[r, 0] / vols[r] - g[r, 1]
        xr = x[o:o + n]
        dvdx = np.zeros_like(xr)
        for i in range(n):
            for k in range(3):
                xp, xm = xr.copy(), xr.copy()
                xp[i, k] += h
                xm[i, k] -= h
                dvdx[i, k] = (m.volume(xp) - m.volume(xm)) / (2 * h)
        added = with_gas.numpy()[o:o + n] - plain.numpy()[o:o + n]
        assert np.abs(added - p * dvdx).max() < 1e-7 * np.abs(p * dvdx).max()
    # energies never include it; unbinding restores the plain forces
    ff.set_gas(None)
    again = wp.zeros_like(xa)
    ff.accumulate_forces(xa, again)
    np.testing.assert_array_equal(again.numpy(), plain.numpy())
    with pytest.raises(ValueError, match="gas must be"):
        ff.set_gas(wp.zeros((3, 2), dtype=wp.float64, device="cpu"), vol)
    with pytest.raises(ValueError, match="volume must be"):
        ff.set_gas(gas, None)
