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


@pytest.mark.parametrize("max_replicas", [None, 2])
def test_one_pool_of_two_sizes_equals_one_run_per_size(max_replicas):
    small, large = mesh_for_diameter(2.0, 2), mesh_for_diameter(3.0, 2)
    ps = [params(16751.0), params(4000.0), params(9000.0, 50.0), params(2500.0), params(12000.0), params(6000.0)]
    sizes = [small, large, small, large, large, small]
    mixed = quasistatic_indentation(ps, small, GRID, fire=FIRE, meshes=sizes, max_replicas=max_replicas,
                                    first_load_ramp=2)
    for mesh in (small, large):
        idx = [i for i, m in enumerate(sizes) if m is mesh]
        alone = quasistatic_indentation([ps[i] for i in idx], mesh, GRID, fire=FIRE, first_load_ramp=2)
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
