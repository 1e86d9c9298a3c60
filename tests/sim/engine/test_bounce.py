"""Bounce-back on moving triangles: particles keep their side, momentum is conserved."""

from __future__ import annotations

import numpy as np
import pytest

wp = pytest.importorskip("warp")
wp.config.quiet = True

from bubblecal.sim.engine import (  # noqa: E402
    GAS,
    WATER,
    HealthConfig,
    HealthMonitor,
    ParticleSystem,
    ReplicaSpec,
    inside_convex_mesh,
    published_pair_table,
)


def _shell_params():
    from bubblecal.sim.engine import ShellParams

    return ShellParams(ka=500.0, kb=50.0, self_avoid=False)


def test_single_particle_bounces_off_frozen_shell():
    from bubblecal.sim.engine import icosphere

    mesh = icosphere(2.0, 2)
    tab = published_pair_table(mesh.n_vertices / mesh.area(), m_vertex=mesh.vertex_mass())
    # one gas particle at the centre flying outward fast, one water particle outside flying inward
    x = np.array([[4.0, 4.0, 4.0], [4.0, 4.0, 6.6]])
    v = np.array([[30.0, 5.0, 0.0], [0.0, 0.0, -30.0]])
    spec = ReplicaSpec(box=(8.0, 8.0, 8.0), pairs=tab, water_density=0.0, mesh=mesh, shell=_shell_params(),
                       frozen_shell=True, extra_positions=x, extra_types=np.array([GAS, WATER]), extra_velocities=v)
    ps = ParticleSystem([spec], dt=1e-3, skin=0.4, chunk=5)
    ps.v.assign(v.astype(np.float32))
    verts = mesh.vertices + 4.0
    for _ in range(40):
        ps.step(5)
        sol = ps.solvent_numpy()
        inside = inside_convex_mesh(sol["x"], verts, mesh.faces)
        assert inside[0] and not inside[1]
    assert ps.nbounce.numpy()[0] >= 2


def test_bounce_conserves_momentum_with_mobile_shell():
    from bubblecal.sim.engine import icosphere

    mesh = icosphere(2.0, 2)
    tab = published_pair_table(mesh.n_vertices / mesh.area(), m_vertex=1.0)
    tab.set(GAS, GAS, 0.0, 0.0, 0.5)
    tab.gamma[:] = 0.0  # no pair thermostat: the only momentum exchange besides the shell is bounce-back
    tab.a[:] = 0.0
    tab.mass[GAS] = 0.2
    spec = ReplicaSpec(box=(7.0, 7.0, 7.0), pairs=tab, water_density=3.0, gas_density=6.0, mesh=mesh,
                       shell=_shell_params(), seed=3, temperature_init=3.0)
    ps = ParticleSystem([spec], dt=1e-3, skin=0.4, chunk=10)
    p0 = ps.total_momentum()[0]
    ps.step(300)
    p1 = ps.total_momentum()[0]
    assert ps.nbounce.numpy()[0] > 50
    sol = ps.solvent_numpy()
    m = ps.mass_np[0, sol["type"]]
    scale = np.sum(m[:, None] * np.abs(sol["v"]))
    assert np.linalg.norm(p1 - p0) < 1e-5 * scale
    rep = HealthMonitor(HealthConfig()).check(ps)
    assert rep.water_inside == [0] and rep.gas_outside == [0]
    assert rep.status == ["OK"]


def test_momentum_round_off_in_float64_fluid_and_bubble():
    """float64 on CPU: pairs (symmetric random numbers), shell, vertex-solvent pairs and bounce-back
    together conserve each replica's total momentum to round-off."""
    from bubblecal.sim.engine import bubble_spec, fluid_pair_table

    specs = [ReplicaSpec(box=(5.0, 5.0, 5.0), pairs=fluid_pair_table(25.0, 4.5, 0.5), seed=1),
             bubble_spec(1.0, 2, box=(6.0, 6.0, 6.0), seed=2)]
    ps = ParticleSystem(specs, dt=1e-4, dtype="float64")
    p0 = ps.total_momentum()
    ps.step(400)
    dp = np.linalg.norm(ps.total_momentum() - p0, axis=1)
    assert ps.nbounce.numpy()[1] > 0
    assert np.all(dp < 1e-10), dp
