"""Load-point schedules of the quasi-static chain: async vs lock-step, stopping at max_steps, slot refill and
compaction (bubblecal.sim.tiers.quasistatic.schedule).

CPU, float64, subdivision-2 icospheres (162 vertices), R = 6 DPD lengths.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("warp")

from bubblecal.sim.engine.kernels.shell import ShellParams  # noqa: E402
from bubblecal.sim.engine.mesh import icosphere  # noqa: E402
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


def _mixed_case(protocol: str, extra_points: tuple = ()):
    """Replicas of very different stiffness that reach their points at different FIRE iterations; one hits
    max_steps at some point and one ruptures (rupture_strain 0.5): (params, run, grid, observable name, fire)."""
    p = [_p(), _p(ka=KA / 4), ShellParams(ka=KA / 8, kb=KB, b1=0.7, b2=0.75, a3=-2.0, a4=8.0, self_avoid=False),
         _p(ka=200.0, kb=5.0)]
    if protocol == "compression":
        return p, quasistatic_compression, [0.0, 0.12, 0.24, 0.36, 0.48, *extra_points], "force", \
            FireSettings(max_steps=400)
    return p, quasistatic_indentation, [0.0, 10.0, 20.0, 40.0, 2000.0, *extra_points], "displacement", \
        FireSettings(max_steps=600)


@pytest.mark.parametrize("protocol", ["compression", "indentation"])
def test_async_schedule_same_iterates_as_lockstep(mesh, protocol):
    # every replica of the mixed set must follow exactly its lock-step iterates
    p, run, grid, key, fire = _mixed_case(protocol)
    lock = run(p, mesh, grid, fire=fire, schedule="lockstep", rupture_strain=0.5)
    asy = run(p, mesh, grid, fire=fire, rupture_strain=0.5)
    assert asy.settings["schedule"] == "async" and lock.settings["schedule"] == "lockstep"
    assert asy.status == lock.status
    assert len(set(lock.status)) >= 2, lock.status  # the set really mixes verdicts
    assert asy.point_status == lock.point_status
    np.testing.assert_array_equal(asy.fire_steps, lock.fire_steps)
    np.testing.assert_array_equal(getattr(asy, key), getattr(lock, key))
    np.testing.assert_array_equal(asy.volume, lock.volume)
    np.testing.assert_array_equal(asy.max_area_strain, lock.max_area_strain)
    np.testing.assert_array_equal(asy.x_final, lock.x_final)
    # slot refill: 4 parameter sets through 2 slots (softest first) give the same iterates, in input order
    seen = []
    pool = run(p, mesh, grid, fire=fire, rupture_strain=0.5, max_replicas=2,
               progress=lambda k, n, t: seen.append((k, n)))
    assert pool.settings["max_replicas"] == 2
    assert seen == [(k, len(p)) for k in range(len(p))]
    assert pool.status == lock.status and pool.point_status == lock.point_status
    np.testing.assert_array_equal(pool.fire_steps, lock.fire_steps)
    np.testing.assert_array_equal(getattr(pool, key), getattr(lock, key))
    np.testing.assert_array_equal(pool.volume, lock.volume)
    np.testing.assert_array_equal(pool.x_final, lock.x_final)


@pytest.mark.parametrize("protocol", ["compression", "indentation"])
def test_stop_at_max_steps_ends_the_curve_and_keeps_the_rest_bit_identical(mesh, protocol):
    # the same mixed set as above: with stop_at_max_steps the not-converged curve ends at its first max_steps point
    # (that point and the later ones NaN, no more FIRE work), its converged prefix and every other curve unchanged
    import dataclasses

    # indentation: a point after the one that hits max_steps, so that stopping saves work
    p, run, grid, key, fire = _mixed_case(protocol, () if protocol == "compression" else (2100.0,))
    stop = dataclasses.replace(fire, stop_at_max_steps=True)
    base = run(p, mesh, grid, fire=fire, rupture_strain=0.5)
    assert "not_converged" in base.status, base.status
    runs = {"lockstep": run(p, mesh, grid, fire=stop, schedule="lockstep", rupture_strain=0.5),
            "async": run(p, mesh, grid, fire=stop, rupture_strain=0.5),
            "refill": run(p, mesh, grid, fire=stop, rupture_strain=0.5, max_replicas=2)}
    for name, r in runs.items():
        assert r.settings["fire"]["stop_at_max_steps"] is True
        assert r.status == base.status, name
        y, y0 = getattr(r, key), getattr(base, key)
        for i, st in enumerate(base.status):
            if st != "not_converged":
                assert r.point_status[i] == base.point_status[i], name
                np.testing.assert_array_equal(r.fire_steps[i], base.fire_steps[i])
                np.testing.assert_array_equal(y[i], y0[i])
                continue
            j = base.point_status[i].index("not_converged")
            assert r.point_status[i] == base.point_status[i][:j] + ["not_converged"] * (len(grid) - j), name
            np.testing.assert_array_equal(y[i, :j], y0[i, :j])  # the converged prefix, bit for bit
            assert np.all(np.isnan(y[i, j:])) and np.all(np.isfinite(y0[i, j:]))
            np.testing.assert_array_equal(r.fire_steps[i, :j + 1], base.fire_steps[i, :j + 1])
            assert np.all(r.fire_steps[i, j + 1:] == 0) and r.fire_steps[i].sum() < base.fire_steps[i].sum()
    for name in ("async", "refill"):
        np.testing.assert_array_equal(runs[name].fire_steps, runs["lockstep"].fire_steps)
        np.testing.assert_array_equal(getattr(runs[name], key), getattr(runs["lockstep"], key))


def test_compacting_the_last_curves_keeps_their_iterates(mesh, monkeypatch):
    import bubblecal.sim.tiers.quasistatic.schedule as qs
    from bubblecal.sim.tiers.quasistatic.backends import _DeviceChain

    p = [_p(), _p(ka=KA / 4), ShellParams(ka=KA / 8, kb=KB, b1=0.7, b2=0.75, a3=-2.0, a4=8.0, self_avoid=False),
         _p(ka=KA / 2), _p(ka=200.0, kb=5.0)]
    grid, fire = [0.0, 10.0, 20.0, 40.0, 2000.0], FireSettings(max_steps=600)
    lock = quasistatic_indentation(p, mesh, grid, fire=fire, schedule="lockstep", rupture_strain=0.5)
    moves = []
    take_over = _DeviceChain.take_over

    def spy(self, old, slots):
        moves.append((old.R, self.R))
        return take_over(self, old, slots)

    monkeypatch.setattr(_DeviceChain, "take_over", spy)
    monkeypatch.setattr(qs, "_COMPACT_MIN", 1)
    monkeypatch.setattr(qs, "_COMPACT_BELOW", 0.75)
    pool = quasistatic_indentation(p, mesh, grid, fire=fire, rupture_strain=0.5, max_replicas=4)
    assert moves and all(new < old for old, new in moves), moves  # the batch really shrank
    assert pool.status == lock.status and pool.point_status == lock.point_status
    np.testing.assert_array_equal(pool.fire_steps, lock.fire_steps)
    np.testing.assert_array_equal(pool.displacement, lock.displacement)
    np.testing.assert_array_equal(pool.x_final, lock.x_final)


def test_max_replicas_validated(mesh):
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="max_replicas"):
            quasistatic_indentation([_p()], mesh, [0.0], max_replicas=bad)
    with pytest.raises(ValueError, match="max_replicas"):
        quasistatic_indentation([_p()], mesh, [0.0], schedule="lockstep", max_replicas=1)


def test_set_params_rows_keeps_the_field_consistent(mesh):
    import warp as wp

    from bubblecal.sim.engine.kernels.shell import ShellForceField

    a, b = _p(), ShellParams(ka=KA / 3, kb=2 * KB, b1=0.5, self_avoid=False)
    ff = ShellForceField(mesh, [a, a], device="cpu", dtype=wp.float64)
    fresh = ShellForceField(mesh, [a, b], device="cpu", dtype=wp.float64)
    ff.set_params_rows([1], [b])
    np.testing.assert_array_equal(ff.param_table, fresh.param_table)
    x = 1.01 * ff.reference_positions()
    np.testing.assert_array_equal(ff.energy_forces_numpy(x)[1], fresh.energy_forces_numpy(x)[1])
    with pytest.raises(ValueError, match="self-avoidance is off"):
        ff.set_params_rows([0], [ShellParams(ka=KA, kb=KB, self_avoid=True)])
    with pytest.raises(ValueError, match="distinct"):
        ff.set_params_rows([1, 1], [a, b])
    with pytest.raises(ValueError, match="rows"):
        ff.set_params_rows([0], [a, b])


def test_schedule_validated(mesh, qs_reference):
    with pytest.raises(ValueError, match="schedule"):
        quasistatic_indentation([_p()], mesh, [0.0], schedule="eager")
    with pytest.raises(ValueError, match="async"):  # the NumPy reference FIRE runs lock-step only
        qs_reference.reference_indentation([_p()], mesh, [0.0], schedule="async")
