"""GPU-only engine tests (run on the lent GPU machine: pytest -m gpu tests/sim)."""

from __future__ import annotations

import numpy as np
import pytest

wp = pytest.importorskip("warp")
wp.config.quiet = True

pytestmark = pytest.mark.gpu


@pytest.fixture(scope="module")
def cuda():
    wp.init()
    if not wp.get_cuda_device_count():
        pytest.skip("no CUDA device")
    return "cuda:0"


def test_graph_and_plain_launches_agree(cuda):
    from bubblecal.sim.engine import ParticleSystem, ReplicaSpec, fluid_pair_table

    spec = ReplicaSpec(box=(6.0, 6.0, 6.0), pairs=fluid_pair_table(25.0, 4.5, 0.5), seed=3)
    a = ParticleSystem([spec], dt=1e-3, device=cuda, chunk=10, use_graph=True)
    b = ParticleSystem([spec], dt=1e-3, device=cuda, chunk=10, use_graph=False)
    a.step(100)
    b.step(100)
    assert a._chunks.graph is not None
    np.testing.assert_allclose(a.solvent_numpy()["x"], b.solvent_numpy()["x"], atol=1e-3)


def test_bubble_batch_on_gpu_no_leaks(cuda):
    from bubblecal.sim.engine import HealthMonitor, ParticleSystem, bubble_spec

    specs = [bubble_spec(1.5, 3, box=(9.0, 9.0, 9.0), seed=k) for k in range(4)]
    ps = ParticleSystem(specs, dt=1e-4, device=cuda, skin=0.4, chunk=10)
    ps.step(2000)
    rep = HealthMonitor().check(ps)
    assert rep.status == ["OK"] * 4
    assert sum(rep.water_inside) + sum(rep.gas_outside) == 0
