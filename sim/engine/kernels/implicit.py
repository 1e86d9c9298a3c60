"""Warp kernels of the implicit-solvent shell system (:mod:`bubblecal.sim.engine.implicit`), batched over replicas.

Per-replica table columns (``tab[r, T_*]``, DPD units): ``T_NKT`` N_g k_BT of the inside gas (DPD energy),
``T_PEXT`` p_water - p_back (DPD pressure), ``T_KBT`` k_BT, ``T_GAMMA`` Langevin friction (DPD mass / time),
``T_MASS`` vertex mass, ``T_NV`` vertex count; ``T_NFREE`` is unused.  The integrator is BAOAB: the first
half kick, half drift and exact Ornstein-Uhlenbeck step in one kernel (``kick_drift_thermo``), the second half
drift (``drift_half``, after removing the mean velocity when the centre of mass is pinned), then the forces and
the second half kick (``finish_kick``).
"""

# (no "from __future__ import annotations": Warp must see the closure types of the kernel signatures)

import functools

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.common import kernel_decorator

wp = require("warp", "sim")

__all__ = ["implicit_kernels", "N_TAB", "T_NKT", "T_PEXT", "T_KBT", "T_GAMMA", "T_MASS", "T_NV", "T_NFREE"]

# per-replica table columns
T_NKT, T_PEXT, T_KBT, T_GAMMA, T_MASS, T_NV, T_NFREE = range(7)
N_TAB = 7


@functools.cache
def implicit_kernels(dtype) -> dict:
    """Build (once per scalar type) the implicit-system kernels; ``dtype`` is ``wp.float32`` or ``wp.float64``.
    Returns a dict: ``volume_kernel``, ``pressure_kernel`` (p dV/dx per triangle corner), ``force_sum_kernel``,
    ``finish_kick``, ``kick_drift_thermo``, ``drift_half``, ``increment``, ``kinetic_kernel``.
    """
    T = dtype
    V = wp.types.vector(3, T)
    kern = kernel_decorator(dtype, "implicit")

    @kern
    def volume_kernel(x: wp.array(dtype=V), tri: wp.array(dtype=wp.vec3i), tri_rep: wp.array(dtype=wp.int32),
                      goff: wp.array(dtype=wp.int32), vol: wp.array(dtype=T)):
        t = wp.tid()
        r = tri_rep[t]
        idx = tri[t]
        c = x[goff[r]]
        wp.atomic_add(vol, r, wp.dot(x[idx[0]] - c, wp.cross(x[idx[1]] - c, x[idx[2]] - c)) / T(6.0))

    @kern
    def pressure_kernel(x: wp.array(dtype=V), f: wp.array(dtype=V), tri: wp.array(dtype=wp.vec3i),
                        tri_rep: wp.array(dtype=wp.int32), tab: wp.array2d(dtype=T), vol: wp.array(dtype=T),
                        status: wp.array(dtype=wp.int32)):
        t = wp.tid()
        r = tri_rep[t]
        if status[r] != 0:
            return
        idx = tri[t]
        x0 = x[idx[0]]
        n = wp.cross(x[idx[1]] - x0, x[idx[2]] - x0)
        v = wp.max(vol[r], T(1.0e-12))
        p = tab[r, T_NKT] / v - tab[r, T_PEXT]
        fc = (p / T(6.0)) * n  # p dV/dx per corner (translation-invariant form, exact for closed meshes)
        wp.atomic_add(f, idx[0], fc)
        wp.atomic_add(f, idx[1], fc)
        wp.atomic_add(f, idx[2], fc)

    @kern
    def force_sum_kernel(f: wp.array(dtype=V), fext: wp.array(dtype=V), vrep: wp.array(dtype=wp.int32),
                         fsum: wp.array(dtype=V)):
        i = wp.tid()
        wp.atomic_add(fsum, vrep[i], f[i] + fext[i])

    @kern
    def finish_kick(v: wp.array(dtype=V), f: wp.array(dtype=V), fext: wp.array(dtype=V),
                    fstore: wp.array(dtype=V), vrep: wp.array(dtype=wp.int32), anchor: wp.array(dtype=wp.int32),
                    tab: wp.array2d(dtype=T), fsum: wp.array(dtype=V), pin: wp.int32,
                    status: wp.array(dtype=wp.int32), dt: T):
        # second half of B: v += F dt / (2 m), F with the replica's mean removed (pinned COM)
        i = wp.tid()
        r = vrep[i]
        if status[r] != 0:
            return
        ft = f[i] + fext[i]
        if pin != 0:
            ft = ft - fsum[r] / tab[r, T_NV]
        if anchor[i] != 0:
            ft = V(ft[0], ft[1], T(0.0))
        fstore[i] = ft
        v[i] = v[i] + ft * (T(0.5) * dt / tab[r, T_MASS])

    @kern
    def kick_drift_thermo(x: wp.array(dtype=V), v: wp.array(dtype=V), fstore: wp.array(dtype=V),
                          vrep: wp.array(dtype=wp.int32), anchor: wp.array(dtype=wp.int32),
                          tab: wp.array2d(dtype=T), seeds: wp.array(dtype=wp.int32),
                          step: wp.array(dtype=wp.int32), mom: wp.array(dtype=V), pin: wp.int32,
                          status: wp.array(dtype=wp.int32), dt: T, local: wp.array(dtype=wp.int32)):
        # B (first half) A (half drift) O (exact OU)
        i = wp.tid()
        r = vrep[i]
        if status[r] != 0:
            return
        m = tab[r, T_MASS]
        half = T(0.5) * dt
        vi = v[i] + fstore[i] * (half / m)
        xi = x[i] + vi * half
        g = tab[r, T_GAMMA]
        kt = tab[r, T_KBT]
        if g > T(0.0):
            c1 = wp.exp(-g * dt / m)
            amp = wp.sqrt(wp.max(T(1.0) - c1 * c1, T(0.0)) * kt / m)
            st = wp.rand_init(seeds[r], step[0])
            st = wp.rand_init(wp.int32(st), local[i])
            xi_n = V(T(wp.randn(st)), T(wp.randn(st)), T(wp.randn(st)))
            vi = c1 * vi + amp * xi_n
        if anchor[i] != 0:
            vi = V(vi[0], vi[1], T(0.0))
        v[i] = vi
        x[i] = xi
        if pin != 0:
            wp.atomic_add(mom, r, vi)

    @kern
    def drift_half(x: wp.array(dtype=V), v: wp.array(dtype=V), vrep: wp.array(dtype=wp.int32),
                   anchor: wp.array(dtype=wp.int32), tab: wp.array2d(dtype=T), mom: wp.array(dtype=V),
                   pin: wp.int32, status: wp.array(dtype=wp.int32), dt: T):
        # (pinned: remove the replica's mean velocity) A (second half drift)
        i = wp.tid()
        r = vrep[i]
        if status[r] != 0:
            return
        vi = v[i]
        if pin != 0:
            vm = mom[r] / tab[r, T_NV]
            if anchor[i] != 0:
                vm = V(vm[0], vm[1], T(0.0))
            vi = vi - vm
            v[i] = vi
        x[i] = x[i] + vi * (T(0.5) * dt)

    @kern
    def increment(step: wp.array(dtype=wp.int32)):
        step[0] = step[0] + 1

    @kern
    def kinetic_kernel(v: wp.array(dtype=V), vrep: wp.array(dtype=wp.int32), tab: wp.array2d(dtype=T),
                       out: wp.array(dtype=wp.float64)):
        i = wp.tid()
        r = vrep[i]
        vi = v[i]
        wp.atomic_add(out, r, wp.float64(tab[r, T_MASS] * wp.dot(vi, vi)))

    return {k: v for k, v in locals().items() if isinstance(v, wp.Kernel)}
