"""Kick-drift integrator (one force evaluation per step): v += F/m dt, x += v dt.

Masses enter as per-replica, per-type inverse masses (``inv_mass[rep * 4 + type]``); an inverse
mass of 0 freezes a particle's velocity (wall particles move with the velocity they were given, and
a shell with vertex inverse mass 0 is held fixed). A replica whose ``status`` is non-zero (failed
health check) is frozen: nothing of it is integrated any more.

Optional per-replica centre-of-mass pinning of the shell: after the kick the mass-weighted mean
vertex velocity is removed (the bubble's centre-of-mass velocity is pinned, docs/physics.md section 5).

Every integrate kernel also records, per replica, whether any particle has moved more than
``skin / 2`` from its position at the last neighbour-list build (``overrun`` flag), and the maximum
displacement and speed (used to schedule the next rebuild).
"""


import functools

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.common import kernel_decorator

wp = require("warp", "sim")


@functools.cache
def integrate_kernels(dtype):
    """Build (once per scalar type) the kick-drift kernels (module docstring); ``dtype`` is ``wp.float32`` or
    ``wp.float64``. Returns a dict: ``kick_drift_solvent``, ``kick_vertices``, ``drift_vertices``,
    ``motion_stats``, ``increment``.
    """
    vec3 = wp.types.vector(3, dtype)
    kern = kernel_decorator(dtype, "integ")

    @kern
    def kick_drift_solvent(x: wp.array(dtype=vec3), v: wp.array(dtype=vec3), f: wp.array(dtype=vec3),
                           typ: wp.array(dtype=wp.int32), rep: wp.array(dtype=wp.int32),
                           inv_mass: wp.array(dtype=dtype), status: wp.array(dtype=wp.int32), dt: dtype,
                           xref: wp.array(dtype=vec3), half_skin2: dtype, overrun: wp.array(dtype=wp.int32)):
        i = wp.tid()
        r = rep[i]
        if status[r] != 0:
            return
        im = inv_mass[r * 4 + typ[i]]
        vi = v[i] + f[i] * (im * dt)
        v[i] = vi
        xi = x[i] + vi * dt
        x[i] = xi
        d = xi - xref[i]
        if wp.dot(d, d) > half_skin2:
            overrun[r] = 1

    @kern
    def kick_vertices(v: wp.array(dtype=vec3), f: wp.array(dtype=vec3), vrep: wp.array(dtype=wp.int32),
                      inv_mass: wp.array(dtype=dtype), status: wp.array(dtype=wp.int32), dt: dtype,
                      pin: wp.array(dtype=wp.int32), mom: wp.array(dtype=vec3)):
        i = wp.tid()
        r = vrep[i]
        if status[r] != 0:
            return
        im = inv_mass[r * 4 + 2]
        vi = v[i] + f[i] * (im * dt)
        v[i] = vi
        if pin[r] != 0:
            wp.atomic_add(mom, r, vi)

    @kern
    def drift_vertices(x: wp.array(dtype=vec3), v: wp.array(dtype=vec3), xold: wp.array(dtype=vec3),
                       vrep: wp.array(dtype=wp.int32), status: wp.array(dtype=wp.int32), dt: dtype,
                       pin: wp.array(dtype=wp.int32), mom: wp.array(dtype=vec3), nvert: wp.array(dtype=wp.int32),
                       xref: wp.array(dtype=vec3), half_skin2: dtype, overrun: wp.array(dtype=wp.int32)):
        i = wp.tid()
        r = vrep[i]
        xi = x[i]
        xold[i] = xi
        if status[r] != 0:
            return
        vi = v[i]
        if pin[r] != 0:
            vi = vi - mom[r] / dtype(nvert[r])
            v[i] = vi
        xi = xi + vi * dt
        x[i] = xi
        d = xi - xref[i]
        if wp.dot(d, d) > half_skin2:
            overrun[r] = 1

    @kern
    def motion_stats(x: wp.array(dtype=vec3), v: wp.array(dtype=vec3), xref: wp.array(dtype=vec3),
                     rep: wp.array(dtype=wp.int32), status: wp.array(dtype=wp.int32),
                     disp2: wp.array(dtype=dtype), speed2: wp.array(dtype=dtype)):
        """Max squared displacement since the last build and max squared speed, over live replicas."""
        i = wp.tid()
        if status[rep[i]] != 0:
            return
        d = x[i] - xref[i]
        vi = v[i]
        dd = wp.dot(d, d)
        vv = wp.dot(vi, vi)
        # read before the atomic: most threads skip it (one address, heavy contention otherwise)
        if wp.isfinite(dd) and dd > disp2[0]:
            wp.atomic_max(disp2, 0, dd)
        if wp.isfinite(vv) and vv > speed2[0]:
            wp.atomic_max(speed2, 0, vv)

    @kern
    def increment(step: wp.array(dtype=wp.int32)):
        step[0] = step[0] + 1

    return {"kick_drift_solvent": kick_drift_solvent, "kick_vertices": kick_vertices,
            "drift_vertices": drift_vertices, "motion_stats": motion_stats, "increment": increment}
