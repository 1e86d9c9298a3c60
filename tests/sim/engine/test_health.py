"""Health checks: a failed replica is frozen with a status; the others continue."""

from __future__ import annotations

import numpy as np
import pytest

wp = pytest.importorskip("warp")
wp.config.quiet = True

from bubblecal.sim.engine import (  # noqa: E402
    WATER,
    HealthMonitor,
    ParticleSystem,
    ReplicaSpec,
    Status,
    fluid_pair_table,
    published_pair_table,
)


def _bubble_spec(seed=0, extra=None):
    from bubblecal.sim.engine import ShellParams, icosphere

    mesh = icosphere(2.0, 2)
    tab = published_pair_table(mesh.n_vertices / mesh.area(), m_vertex=mesh.vertex_mass())
    return ReplicaSpec(box=(7.0, 7.0, 7.0), pairs=tab, gas_density=3.0, water_density=1.0, mesh=mesh,
                       shell=ShellParams(ka=500.0, kb=50.0), seed=seed, extra_positions=extra,
                       extra_types=None if extra is None else np.full(len(extra), WATER))


def test_nan_replica_is_frozen_others_continue():
    specs = [ReplicaSpec(box=(4.0, 4.0, 4.0), pairs=fluid_pair_table(), seed=k) for k in range(3)]
    ps = ParticleSystem(specs, dt=0.01)
    ps.step(2)
    v = ps.v.numpy()
    rep = ps.rep.numpy()
    v[np.nonzero(rep == 1)[0][0]] = np.nan
    ps.v.assign(v)
    hm = HealthMonitor()
    report = hm.check(ps)
    assert report.status == ["OK", "NAN", "OK"]
    before = ps.x.numpy().copy()
    order_before = ps.pid.numpy().copy()
    ps.step(10)
    # compare in persistent-id order
    xb = before[np.argsort(order_before)]
    xa = ps.x.numpy()[np.argsort(ps.pid.numpy())]
    r = ps.solvent_numpy()["replica"]
    # frozen replica: positions unchanged (modulo the wrap into the box); others moved
    L = 4.0
    d = xa - xb
    d -= L * np.round(d / L)
    frozen = np.abs(d[r == 1])
    assert np.nanmax(frozen) == 0.0
    assert np.abs(d[r == 0]).max() > 0 and np.abs(d[r == 2]).max() > 0
    assert ps.status_numpy().tolist() == [0, int(Status.NAN), 0]


def test_rupture_inversion_and_leak_detected():
    leak = np.array([[3.5, 3.5, 3.5]])  # a water particle at the centre of the shell
    ps = ParticleSystem([_bubble_spec(0), _bubble_spec(1), _bubble_spec(2), _bubble_spec(3, extra=leak)], dt=1e-4)
    xv = ps.xv.numpy()
    for r, fn in ((1, lambda p, c: c + 1.6 * (p - c)),       # area strain 1.56 > 1: rupture
                  (2, lambda p, c: c + (p - c) * np.array([1.0, 1.0, -1.0]))):  # mirror: inverted normals
        o, n = int(ps.vertex_offset[r]), int(ps.vertex_count[r])
        c = xv[o:o + n].mean(axis=0)
        xv[o:o + n] = fn(xv[o:o + n], c)
    ps.xv.assign(xv)
    report = HealthMonitor().check(ps)
    assert report.status == ["OK", "RUPTURE", "INVERSION", "LEAK"]
    assert report.water_inside[3] == 1 and report.water_inside[0] == 0
