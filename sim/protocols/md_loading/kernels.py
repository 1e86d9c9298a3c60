"""Warp kernels of the MD loading protocols: ramped analytic plates, pole forces, explicit-tier anchoring and the
axial extent (DPD units).  The plate law is that of :class:`bubblecal.sim.protocols.PlateContact`.
"""

# (no "from __future__ import annotations": Warp must see the closure types of the kernel signatures)

import functools

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.common import kernel_decorator

wp = require("warp", "sim")

__all__ = ["md_loading_kernels"]


@functools.cache
def md_loading_kernels(dtype):
    """The protocol's Warp kernels for one scalar type (compiled on first launch, cached per type); ``dtype`` is
    ``wp.float32`` or ``wp.float64``. Returns a dict: ``plates``, ``pole_forces``, ``anchor_forces`` and
    ``z_extent`` kernels.
    """
    T = dtype
    V = wp.types.vector(3, T)
    kern = kernel_decorator(dtype, "mdload")

    @wp.func
    def ramp_value(state: wp.array(dtype=wp.float64), step: wp.int32) -> wp.float64:
        # state = (value_from, value_to, step0, ramp_steps)
        s = wp.float64(step) - state[2]
        u = wp.float64(1.0)
        if state[3] > wp.float64(0.0):
            u = wp.clamp(s / state[3], wp.float64(0.0), wp.float64(1.0))
        return state[0] + (state[1] - state[0]) * u

    @wp.func
    def wall_force(h: T, eps: T, sig: T, rc: T, hcap: T, cap: T) -> T:
        fm = T(0.0)
        if h < rc:
            if h <= hcap:
                fm = cap
            else:
                s2 = sig * sig / (h * h)
                s6 = s2 * s2 * s2
                fm = T(24.0) * eps * (T(2.0) * s6 * s6 - s6) / h
        return fm

    @kern
    def plates(x: wp.array(dtype=V), f: wp.array(dtype=V), vrep: wp.array(dtype=wp.int32),
               status: wp.array(dtype=wp.int32), zc: wp.array(dtype=T), state: wp.array(dtype=wp.float64),
               step: wp.array(dtype=wp.int32), lj: wp.array(dtype=T), acc: wp.array2d(dtype=wp.float64)):
        """Analytic plates z = zc +- g(step) (g ramped); capped WCA on every vertex; reactions into acc."""
        i = wp.tid()
        r = vrep[i]
        if status[r] != 0:
            return
        g = T(ramp_value(state, step[0]))
        z = x[i][2]
        ft = wall_force(zc[r] + g - z, lj[0], lj[1], lj[2], lj[3], lj[4])
        fb = wall_force(z - (zc[r] - g), lj[0], lj[1], lj[2], lj[3], lj[4])
        if ft != T(0.0) or fb != T(0.0):
            f[i] = f[i] + V(T(0.0), T(0.0), fb - ft)
            wp.atomic_add(acc, r, 0, wp.float64(ft))
            wp.atomic_add(acc, r, 1, wp.float64(fb))

    @kern
    def pole_forces(f: wp.array(dtype=V), rows: wp.array(dtype=wp.int32), sign: wp.array(dtype=T),
                    vrep: wp.array(dtype=wp.int32), status: wp.array(dtype=wp.int32),
                    state: wp.array(dtype=wp.float64), step: wp.array(dtype=wp.int32), inv_k: T):
        """Force sign * F(step)/k along z on the loaded vertices (sign -1 top, +1 bottom)."""
        j = wp.tid()
        i = rows[j]
        if status[vrep[i]] != 0:
            return
        fz = sign[j] * T(ramp_value(state, step[0])) * inv_k
        f[i] = f[i] + V(T(0.0), T(0.0), fz)

    @kern
    def anchor_forces(x: wp.array(dtype=V), v: wp.array(dtype=V), f: wp.array(dtype=V),
                      rows: wp.array(dtype=wp.int32), zref: wp.array(dtype=T), vrep: wp.array(dtype=wp.int32),
                      mass: wp.array(dtype=T), status: wp.array(dtype=wp.int32), dt: T, beta: T):
        """Explicit tier: F_z = -m (v_z + beta (z - z_ref)/dt)/dt on anchored vertices (overrides F_z)."""
        j = wp.tid()
        i = rows[j]
        r = vrep[i]
        if status[r] != 0:
            return
        fi = f[i]
        fz = -mass[r] * (v[i][2] + beta * (x[i][2] - zref[j]) / dt) / dt
        f[i] = V(fi[0], fi[1], fz)

    @kern
    def z_extent(x: wp.array(dtype=V), vrep: wp.array(dtype=wp.int32), zmax: wp.array(dtype=T),
                 zmin: wp.array(dtype=T)):
        i = wp.tid()
        r = vrep[i]
        z = x[i][2]
        if wp.isfinite(z):
            wp.atomic_max(zmax, r, z)
            wp.atomic_min(zmin, r, z)

    return {"plates": plates, "pole_forces": pole_forces, "anchor_forces": anchor_forces, "z_extent": z_extent}
