"""One quasi-static indentation pool over several bubble sizes gives, bit for bit, the curves of one run per size.

CPU, float64, subdivision-2 icospheres (162 vertices) at 2.0 and 3.0 um (radius 4 and 6 DPD lengths).
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("warp")

from bubblecal.sim.engine.kernels.shell import ShellParams  # noqa: E402
from bubblecal.sim.engine.mesh import icosphere, mesh_for_diameter  # noqa: E402
from bubblecal.sim.tiers.quasistatic import FireSettings, quasistatic_indentation  # noqa: E402

GRID = [0.0, 20.0, 40.0, 80.0]
FIRE = FireSettings(max_steps=4000)


def params(ka: float, kb: float = 500.0) -> ShellParams:
    return ShellParams(ka=ka, kb=kb, self_avoid=False)


@pytest.mark.parametrize("max_replicas, single", [(None, False), (2, False), (2, True)])
def test_one_pool_of_two_sizes_equals_one_run_per_size(max_replicas, single):
    import warp as wp

    dtype = wp.float32 if single else None  # float32: the swapped references are rounded as at construction
    fire = FireSettings(max_steps=4000, ftol=0.5) if single else FIRE
    small, large = mesh_for_diameter(2.0, 2), mesh_for_diameter(3.0, 2)
    ps = [params(16751.0), params(4000.0), params(9000.0, 50.0), params(2500.0), params(12000.0), params(6000.0)]
    sizes = [small, large, small, large, large, small]
    mixed = quasistatic_indentation(ps, small, GRID, fire=fire, meshes=sizes, max_replicas=max_replicas,
                                    first_load_ramp=2, dtype=dtype)
    for mesh in (small, large):
        idx = [i for i, m in enumerate(sizes) if m is mesh]
        alone = quasistatic_indentation([ps[i] for i in idx], mesh, GRID, fire=fire, first_load_ramp=2, dtype=dtype)
        assert [mixed.status[i] for i in idx] == alone.status
        np.testing.assert_array_equal(mixed.displacement[idx], alone.displacement)
        np.testing.assert_array_equal(mixed.fire_steps[idx], alone.fire_steps)
        np.testing.assert_array_equal(mixed.axial_diameter0[idx], alone.axial_diameter0)
        nv = mesh.n_vertices
        x = mixed.x_final.reshape(len(ps), nv, 3)[idx].reshape(-1, 3)
        np.testing.assert_array_equal(x, alone.x_final)


def test_references_must_share_the_topology():
    with pytest.raises(ValueError, match="meshes: 1 references for 2"):
        quasistatic_indentation([params(5000.0)] * 2, icosphere(4.0, 2), GRID, meshes=[icosphere(4.0, 2)])
    with pytest.raises(ValueError, match="topology"):
        quasistatic_indentation([params(5000.0)] * 2, icosphere(4.0, 2), GRID,
                                meshes=[icosphere(4.0, 2), icosphere(4.0, 1)])


@pytest.mark.parametrize("thermal", [False, True])
def test_one_compression_pool_of_two_sizes_equals_one_run_per_size(thermal):
    from bubblecal.sim.tiers.quasistatic import ThermalContact, quasistatic_compression

    small, large = mesh_for_diameter(2.0, 2), mesh_for_diameter(3.0, 2)
    ps = [params(16751.0), params(4000.0), params(9000.0, 50.0), params(2500.0), params(12000.0)]
    sizes = [small, large, small, large, large]
    fractions = np.array([0.0, 0.01, 0.02])  # total displacement / diameter (4 DPD lengths per um)
    grid = {id(small): fractions * 8.0, id(large): fractions * 12.0}
    contact = ThermalContact() if thermal else None
    mixed = quasistatic_compression(ps, small, [grid[id(m)] for m in sizes], meshes=sizes, fire=FIRE,
                                    thermal=contact, max_replicas=2)
    for mesh in (small, large):
        idx = [i for i, m in enumerate(sizes) if m is mesh]
        alone = quasistatic_compression([ps[i] for i in idx], mesh, grid[id(mesh)], fire=FIRE, thermal=contact)
        assert [mixed.status[i] for i in idx] == alone.status
        np.testing.assert_array_equal(mixed.force[idx], alone.force)
        np.testing.assert_array_equal(mixed.fire_steps[idx], alone.fire_steps)
        np.testing.assert_array_equal(mixed.plate_z[idx], np.tile(alone.plate_z, (len(idx), 1)))
        np.testing.assert_array_equal(mixed.displacements[idx], np.tile(alone.displacements, (len(idx), 1)))
    assert np.all(mixed.force[:, -1] > mixed.force[:, 1])  # the plates press harder as they close


def test_compression_chains_of_different_lengths_are_refused():
    from bubblecal.sim.tiers.quasistatic import quasistatic_compression

    small, large = mesh_for_diameter(2.0, 2), mesh_for_diameter(3.0, 2)
    with pytest.raises(ValueError, match="chains of different lengths"):
        quasistatic_compression([params(5000.0)] * 2, small, [[0.0, 0.1], [0.0, 0.5]], meshes=[small, large])


@pytest.mark.parametrize("several_sizes", [False, True])
def test_compression_reports_each_curve_as_it_finishes(several_sizes):
    from bubblecal.sim.tiers.quasistatic import ThermalContact, compression_pools, quasistatic_compression

    small, large = mesh_for_diameter(2.0, 2), mesh_for_diameter(3.0, 2)
    ps = [params(16751.0), params(4000.0), params(9000.0, 50.0)]
    rows = {}
    kw = dict(fire=FIRE, thermal=ThermalContact(), max_replicas=2, on_curve=lambda i, row: rows.setdefault(i, row))
    if several_sizes:  # two chain lengths (0.018 D steps: one plate sub-step at 2 um, two at 3 um): two pools
        sizes = [small, large, large]
        grids = [np.array([0.0, 0.018, 0.036]) * 4.0 * d for d in (2.0, 3.0, 3.0)]
        res = compression_pools(ps, small, sizes, np.array(grids), **kw)
    else:
        res = quasistatic_compression(ps, small, [0.0, 0.08, 0.16], **kw)
    assert sorted(rows) == [0, 1, 2]
    for i, row in rows.items():
        assert row["status"] == res.status[i] and row["point_status"] == res.point_status[i]
        np.testing.assert_array_equal(row["force"], res.force[i])
        np.testing.assert_array_equal(row["force_bottom"], res.force_bottom[i])
        np.testing.assert_array_equal(row["fire_steps"], res.fire_steps[i])
        assert "fire_evaluations" not in row["settings"] and "fire_evaluations" in res.settings


def test_pole_rings_that_round_in_another_order_are_one_patch():
    """At 1.5 and 1.7 um (subdivision 4, 4.6 deg caps) the first ring's vertices tie in distance to the pole and
    sort in another order; the loaded sets are equal, so one pool takes both sizes."""
    from bubblecal.sim.engine import pole_patches
    from bubblecal.sim.tiers.quasistatic.indentation import _anchored_equator, _replica_meshes

    small, other = mesh_for_diameter(1.5, 4), mesh_for_diameter(1.7, 4)
    order = [pole_patches(m.vertices, cap_deg=4.6)[0] for m in (small, other)]
    assert not np.array_equal(*order) and np.array_equal(*(np.sort(o) for o in order))
    refs = _replica_meshes([small, other], small, 2, {"cap_deg": 4.6}, _anchored_equator(small))
    assert refs == [small, other]
