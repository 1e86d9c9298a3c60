"""Load grids of the quasi-static chain: the first-load ramp (bubblecal.sim.tiers.quasistatic.grids).

CPU, float64, subdivision-2 icospheres (162 vertices), R = 6 DPD lengths.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("warp")

from bubblecal.sim.engine.kernels.shell import ShellParams  # noqa: E402
from bubblecal.sim.engine.mesh import icosphere  # noqa: E402
from bubblecal.sim.tiers.quasistatic import quasistatic_indentation  # noqa: E402

KA, KB = 16751.0, 500.0  # the Reissner check's parameter set (physics.md 6.5)


@pytest.fixture(scope="module")
def mesh():
    return icosphere(6.0, 2)


def _p(ka=KA, kb=KB):
    return ShellParams(ka=ka, kb=kb, self_avoid=False)


def test_ramp_grid_inserts_halvings_before_the_first_positive_load():
    from bubblecal.sim.tiers.quasistatic.grids import _ramp_grid, _sum_substeps

    full, keep = _ramp_grid(np.array([0.0, 10.0, 20.0]), 3)
    np.testing.assert_array_equal(full, [0.0, 1.25, 2.5, 5.0, 10.0, 20.0])
    np.testing.assert_array_equal(keep, [0, 4, 5])
    np.testing.assert_array_equal(_sum_substeps(np.array([0, 1, 2, 3, 4, 5]), keep), [0, 10, 5])
    full, keep = _ramp_grid(np.array([4.0, 8.0]), 2)  # no unloaded point: the ramp starts from zero load
    np.testing.assert_array_equal(full, [1.0, 2.0, 4.0, 8.0])
    np.testing.assert_array_equal(keep, [2, 3])
    for grid, n in (([0.0, 5.0], 0), ([0.0, 0.0], 4)):
        full, keep = _ramp_grid(np.array(grid), n)
        np.testing.assert_array_equal(full, grid)
        np.testing.assert_array_equal(keep, np.arange(len(grid)))


@pytest.mark.parametrize("schedule", ["async", "lockstep"])
def test_first_load_ramp_is_the_grid_with_its_sub_points(mesh, schedule):
    """The ramp runs the chain on the grid with the halvings and reports the requested points only: bit for bit
    the run on the full grid, FIRE steps of a point including its sub-points'; the curve itself moves only within
    the FIRE tolerance against no ramp."""
    p = [_p(), _p(ka=KA / 4, kb=2 * KB)]
    grid, n = [0.0, 10.0, 20.0, 40.0], 3
    full = [0.0, 1.25, 2.5, 5.0, 10.0, 20.0, 40.0]
    rows = {}
    ramp = quasistatic_indentation(p, mesh, grid, first_load_ramp=n, schedule=schedule,
                                   on_curve=(lambda i, row: rows.__setitem__(i, row)) if schedule == "async" else None)
    ref = quasistatic_indentation(p, mesh, full, schedule=schedule)
    keep = [0, 4, 5, 6]
    np.testing.assert_array_equal(ramp.forces, grid)
    np.testing.assert_array_equal(ramp.displacement, ref.displacement[:, keep])
    assert ramp.status == ref.status == ["ok", "ok"]
    np.testing.assert_array_equal(ramp.fire_steps[:, 1], ref.fire_steps[:, 1:5].sum(axis=1))
    np.testing.assert_array_equal(ramp.fire_steps.sum(axis=1), ref.fire_steps.sum(axis=1))
    assert ramp.settings["first_load_ramp"] == n
    if schedule == "async":
        for i in range(2):
            np.testing.assert_array_equal(rows[i]["displacement"], ramp.displacement[i])
            np.testing.assert_array_equal(rows[i]["fire_steps"], ramp.fire_steps[i])
            assert rows[i]["point_status"] == ramp.point_status[i]
    plain = quasistatic_indentation(p, mesh, grid, schedule=schedule)
    rel = np.linalg.norm(ramp.displacement - plain.displacement, axis=1) / np.linalg.norm(plain.displacement, axis=1)
    assert np.all(rel < 0.02), rel
    with pytest.raises(ValueError, match="first_load_ramp"):
        quasistatic_indentation(p, mesh, grid, first_load_ramp=-1)
