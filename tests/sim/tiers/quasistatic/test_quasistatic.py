"""Athermal quasi-static tier: indentation, compression, and the device chain against the NumPy reference.

CPU, float64, subdivision-2 icospheres (162 vertices), R = 6 DPD lengths.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("warp")

from bubblecal.sim.engine.kernels.shell import ShellParams  # noqa: E402
from bubblecal.sim.engine.mesh import icosphere  # noqa: E402
from bubblecal.sim.protocols import (  # noqa: E402
    CompressionProtocol,
    IndentationProtocol,
    PlateContact,
    published_indentation_protocol,
)
from bubblecal.sim.tiers.quasistatic import (  # noqa: E402
    FireSettings,
    quasistatic_compression,
    quasistatic_indentation,
)

KA, KB = 16751.0, 500.0  # the Reissner check's parameter set (physics.md 6.5)


@pytest.fixture(scope="module")
def mesh():
    return icosphere(6.0, 2)


def _p(ka=KA, kb=KB):
    return ShellParams(ka=ka, kb=kb, self_avoid=False)


@pytest.fixture(scope="module")
def indentation(mesh):
    return quasistatic_indentation([_p(), _p(ka=KA / 4)], mesh, [0.0, 10.0, 20.0, 40.0])


@pytest.fixture(scope="module")
def compression(mesh):
    return quasistatic_compression([_p(), _p(ka=KA / 4)], mesh, [0.0, 0.12, 0.24, 0.36])

@pytest.mark.parametrize("bad", [[0.0, 1.0, 1.0], [0.0, 2.0, 1.0], [-1.0, 0.0, 1.0], [0.0, np.nan], []])
def test_bad_grids_name_the_field(bad, mesh):
    with pytest.raises(ValueError, match="forces_dpd"):
        IndentationProtocol(tuple(bad))
    with pytest.raises(ValueError, match="displacements_dpd"):
        CompressionProtocol(tuple(bad))
    with pytest.raises(ValueError, match="forces_dpd"):
        quasistatic_indentation([_p()], mesh, bad)
    with pytest.raises(ValueError, match="displacements_dpd"):
        quasistatic_compression([_p()], mesh, bad)


def test_bad_other_inputs(mesh):
    with pytest.raises(ValueError, match="rupture_strain"):
        quasistatic_indentation([_p()], mesh, [0.0], rupture_strain=-1.0)
    with pytest.raises(ValueError, match="params"):
        quasistatic_indentation([], mesh, [0.0])
    with pytest.raises(ValueError, match="displacements_dpd"):
        quasistatic_compression([_p()], mesh, [0.0, 20.0])  # plates would cross
    with pytest.raises(ValueError, match="force_cap"):
        PlateContact(force_cap=0.0)


# ----- indentation ----------------------------------------------------------------------------
def test_indentation_zero_load_and_status(indentation):
    r = indentation
    assert r.status == ["ok", "ok"]
    assert all(s == "ok" for row in r.point_status for s in row)
    assert np.all(r.displacement[:, 0] == 0.0) and np.all(r.fire_steps[:, 0] == 0)
    assert r.settings["k_loaded_per_pole"] == 1  # floor(0.01 * 162)
    assert r.settings["n_equator_anchored"] == 16
    assert np.all(r.fmax <= FireSettings().ftol)


def test_indentation_linear_regime_and_reissner_range(indentation):
    d = indentation.displacement
    assert np.all(np.diff(d, axis=1) > 0)  # monotone
    assert np.allclose(d[:, 2] / d[:, 1], 2.0, rtol=0.03)  # linear for small loads
    # stiffness per pole F / (d/2): the Reissner check's s3 value is 2,783 (s4 3,044); s2 sits a bit lower
    k = 20.0 / (d[0, 2] / 2)
    assert 2200.0 < k < 3400.0, k


def test_indentation_stiffer_replica_indents_less(indentation):
    d = indentation.displacement
    assert np.all(d[0, 1:] < d[1, 1:])


def test_indentation_batched_equals_single_and_reproducible(mesh, indentation):
    single = quasistatic_indentation([_p(ka=KA / 4)], mesh, [0.0, 10.0, 20.0, 40.0])
    assert np.allclose(single.displacement[0], indentation.displacement[1], rtol=1e-3, atol=1e-5)
    again = quasistatic_indentation([_p(ka=KA / 4)], mesh, [0.0, 10.0, 20.0, 40.0])
    assert np.array_equal(again.displacement, single.displacement)


def test_indentation_rupture_and_not_converged_status(mesh):
    r = quasistatic_indentation([_p(), _p()], mesh, [0.0, 50.0, 100.0], rupture_strain=1e-4)
    assert r.status == ["ruptured", "ruptured"]
    assert r.point_status[0] == ["ok", "ruptured", "ruptured"]
    assert np.all(np.isnan(r.displacement[:, 1:])) and np.all(np.isfinite(r.x_final))
    r = quasistatic_indentation([_p()], mesh, [0.0, 50.0], fire=FireSettings(max_steps=3))
    assert r.status == ["not_converged"] and r.point_status[0] == ["ok", "not_converged"]
    assert np.isfinite(r.displacement[0, 1])


# ----- compression ----------------------------------------------------------------------------
def test_compression_zero_and_balance(compression):
    c = compression
    assert c.status == ["ok", "ok"]
    assert np.all(c.force[:, 0] == 0.0) and np.all(c.force_bottom[:, 0] == 0.0)
    # one plate's reaction balances the other's (shell and gas forces sum to zero)
    scale = c.force[:, 1:]
    assert np.allclose(c.force_bottom[:, 1:], scale, rtol=1e-3, atol=0.05 * 162)
    assert np.all(np.diff(c.force, axis=1) > 0)
    assert np.all(c.force[0, 1:] > c.force[1, 1:])  # stiffer replica pushes back harder
    # plates move d/2 each
    assert np.allclose(c.plate_z[0] - c.plate_z, np.array([0.0, 0.12, 0.24, 0.36]) / 2)


def test_compression_small_load_matches_indentation_stiffness(compression, indentation):
    # one contact vertex per pole at small d: the plate acts like a point load, so F / (d/2) should
    # be close to the point-load stiffness (the plate's LJ layer takes a little of d)
    k_plate = compression.force[0, 1] / 0.06
    k_point = 20.0 / (indentation.displacement[0, 2] / 2)
    assert 0.6 * k_point < k_plate < 1.05 * k_point, (k_plate, k_point)


@pytest.mark.slow
def test_indentation_close_to_published_training_row(shared_reference):
    # first row of the 3.2 um SonoVue training table (explicit-solvent Mirheo, s4 mesh) vs this tier at s3:
    # measured 0.87 (this tier is ~13 % stiffer at F_max); accept 0.75-1.05
    import csv

    with open(shared_reference / "training_head_indentation_3.2um.csv") as fh:
        row = next(iter(csv.DictReader(fh)))
    p = ShellParams(ka=float(row["ka_dpd"]), kb=float(row["kb_dpd"]), b1=float(row["b1"]), b2=float(row["b2"]),
                    a3=float(row["a3"]), a4=float(row["a4"]), self_avoid=False)
    diam = np.array([float(row[f"axial_diameter_dpd_{j:02d}"]) for j in range(1, 16)])
    r = quasistatic_indentation([p], icosphere(float(row["radius_dpd"]), 3),
                                published_indentation_protocol(3.2).as_array())
    assert r.status == ["ok"]
    ratio = r.displacement[0, -1] / (diam[0] - diam[-1])
    assert 0.75 < ratio < 1.05, ratio


# ----- device-resident FIRE (default) vs the NumPy reference FIRE ----------------------------------
@pytest.mark.parametrize("protocol", ["compression", "indentation"])
def test_device_minimizer_reproduces_numpy_fire(mesh, protocol, qs_reference):
    p = [_p(), ShellParams(ka=KA / 4, kb=KB, b1=0.7, b2=0.75, a3=-2.0, a4=8.0, self_avoid=False)]
    if protocol == "compression":
        run, ref_run, grid, key = quasistatic_compression, qs_reference.reference_compression, [0.0, 0.12, 0.24], \
            "force"
    else:
        run, ref_run, grid, key = quasistatic_indentation, qs_reference.reference_indentation, [0.0, 20.0, 40.0], \
            "displacement"
    ref = ref_run(p, mesh, grid)  # the NumPy reference FIRE (tests/sim/tiers/quasistatic/qs_reference.py)
    dev = run(p, mesh, grid, extrapolate=False)  # device FIRE, float64, same start points as the reference
    assert dev.settings["minimizer"] == "device" and ref.settings["minimizer"] == "numpy"
    assert dev.status == ref.status == ["ok", "ok"]
    np.testing.assert_array_equal(dev.fire_steps, ref.fire_steps)  # same FIRE iterates (float64, CPU)
    np.testing.assert_allclose(getattr(dev, key), getattr(ref, key), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(dev.volume, ref.volume, rtol=1e-12)
    np.testing.assert_allclose(dev.max_area_strain, ref.max_area_strain, rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(dev.x_final, ref.x_final, atol=1e-9)
    if protocol == "compression":
        np.testing.assert_allclose(dev.force_bottom, ref.force_bottom, rtol=1e-9, atol=1e-12)
        np.testing.assert_array_equal(dev.n_contacts, ref.n_contacts)
    else:
        np.testing.assert_allclose(dev.d_patch, ref.d_patch, rtol=1e-9, atol=1e-12)


def test_device_minimizer_float32_close_to_float64(mesh, compression, indentation):
    wp = pytest.importorskip("warp")
    c32 = quasistatic_compression([_p(), _p(ka=KA / 4)], mesh, [0.0, 0.12, 0.24, 0.36], dtype=wp.float32)
    i32 = quasistatic_indentation([_p(), _p(ka=KA / 4)], mesh, [0.0, 10.0, 20.0, 40.0], dtype=wp.float32)
    assert c32.status == i32.status == ["ok", "ok"] and c32.settings["dtype"] == "float32"
    # measured (s2, ftol 0.05): compression 4.2e-4, indentation 7.3e-4 of the curve's largest value
    for a, b in ((c32.force, compression.force), (i32.displacement, indentation.displacement)):
        assert np.max(np.abs(a - b)) < 1e-2 * np.max(np.abs(b))


@pytest.mark.parametrize("protocol", ["compression", "indentation"])
def test_extrapolated_start_same_minima_fewer_iterations(mesh, protocol):
    p = [_p(), _p(ka=KA / 4)]
    if protocol == "compression":
        run, grid, key = quasistatic_compression, [0.0, 0.12, 0.24, 0.36, 0.48], "force"
    else:
        run, grid, key = quasistatic_indentation, [0.0, 10.0, 20.0, 30.0, 40.0], "displacement"
    fire = FireSettings(ftol=0.005)  # these loads are small: FIRE's absolute tolerance must be too
    plain = run(p, mesh, grid, extrapolate=False, fire=fire)
    pred = run(p, mesh, grid, fire=fire)
    assert pred.settings["start"] == "linear extrapolation" and plain.settings["start"] == "previous minimum"
    assert pred.status == plain.status == ["ok", "ok"]
    # same minima up to FIRE's stopping tolerance (measured <= 1.5e-3 of the curve maximum on s3 3.0 um rows
    # at ftol 0.05; here 10x tighter tolerance, 10x smaller loads)
    a, b = getattr(pred, key), getattr(plain, key)
    assert np.max(np.abs(a - b)) < 2e-3 * np.max(np.abs(b))
    # the predictor pays off from the third point on (it needs two minima)
    assert pred.fire_steps[:, 2:].sum() < plain.fire_steps[:, 2:].sum()
    np.testing.assert_array_equal(pred.fire_steps[:, :2], plain.fire_steps[:, :2])


def test_minimizer_choice_validated(mesh):
    # the device chain is the package's only minimiser: a minimizer choice is refused
    with pytest.raises(TypeError, match="minimizer"):
        quasistatic_indentation([_p()], mesh, [0.0], minimizer="scipy")


def test_force_mode_gather_and_scatter_give_the_same_curve():
    """The device chain's shell forces per vertex (gather, the GPU default) or per element (scatter, the CPU
    default) are the same forces up to the summation order: the same indentation curve to FIRE's tolerance."""
    mesh = icosphere(3.0, 2)
    p = ShellParams(ka=400.0, kb=20.0, self_avoid=False)
    curves = {}
    for mode in ("scatter", "gather"):
        res = quasistatic_indentation([p], mesh, [0.0, 20.0, 40.0], device="cpu",
                                      fire=FireSettings(ftol=1e-4, max_steps=20_000, force_mode=mode))
        assert res.status == ["ok"]
        curves[mode] = res.displacement[0]
    np.testing.assert_allclose(curves["gather"], curves["scatter"], rtol=1e-5, atol=1e-8)
    with pytest.raises(ValueError, match="force_mode"):
        FireSettings(force_mode="fused")
    from bubblecal.sim.tiers import QuasistaticTier

    with pytest.raises(ValueError, match="force_mode"):
        QuasistaticTier(force_mode="both")
