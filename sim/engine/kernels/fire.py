"""Warp kernels of the device-resident batched FIRE minimiser (:mod:`bubblecal.sim.engine.minimize_device`).

Replica r owns the contiguous rows ``[row_start[r], row_start[r+1])``.  Per-row passes run with
``T`` threads per replica (launch dimension R T): thread t of replica r visits rows
``row_start[r] + t, + 2T, ...`` (coalesced on a GPU), sums locally and adds its partial sums into the
per-replica accumulators with one atomic each (T = 1 on the CPU).  Per-replica decisions (convergence,
FIRE power test, time step, mixing) run with one thread per replica.

Status codes (int32 per replica): :data:`ACTIVE`, :data:`CONVERGED`, :data:`MAX_STEPS`,
:data:`NONFINITE`, :data:`FROZEN` (not part of this minimisation).  Lengths, forces and times are in
the caller's units (DPD for the quasi-static tier); FIRE's mass is the caller's (``inv_mass`` per row).
"""

# (no "from __future__ import annotations": Warp must see the closure types of the kernel signatures)

import functools

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.common import kernel_decorator

wp = require("warp", "sim")

__all__ = ["ACTIVE", "CONVERGED", "MAX_STEPS", "NONFINITE", "FROZEN", "fire_kernels"]

ACTIVE = 0
CONVERGED = 1
MAX_STEPS = 2
NONFINITE = 3
FROZEN = 4


@functools.cache
def fire_kernels(dtype):
    """Build (once per scalar type) the FIRE kernels; ``dtype`` is ``wp.float32`` or ``wp.float64``. Returns a dict:
    Name -> ``wp.Kernel`` (reset, restart, row passes, replica update, Euler step, mixing).
    """
    T = dtype
    V = wp.vec3d if T is wp.float64 else wp.vec3f
    kern = kernel_decorator(T, "fire")

    @wp.func
    def clear_accumulators(r: wp.int32, fmax_acc: wp.array(dtype=T), fsq_acc: wp.array(dtype=T),
                           pow_acc: wp.array(dtype=T), nonfin_acc: wp.array(dtype=wp.int32),
                           vsq_acc: wp.array(dtype=T), mean_acc: wp.array(dtype=V)):
        """Zero replica r's reductions (refilled by the row passes of the next iteration)."""
        fmax_acc[r] = T(0.0)
        fsq_acc[r] = T(0.0)
        pow_acc[r] = T(0.0)
        nonfin_acc[r] = 0
        vsq_acc[r] = T(0.0)
        mean_acc[r] = V()

    @kern
    def reset_kernel(active: wp.array(dtype=wp.int32), status: wp.array(dtype=wp.int32),
                     iters: wp.array(dtype=wp.int32), steps: wp.array(dtype=wp.int32),
                     dt_r: wp.array(dtype=T), alpha_r: wp.array(dtype=T), npos: wp.array(dtype=wp.int32),
                     down: wp.array(dtype=wp.int32), fmax_out: wp.array(dtype=T),
                     fmax_acc: wp.array(dtype=T), fsq_acc: wp.array(dtype=T), pow_acc: wp.array(dtype=T),
                     nonfin_acc: wp.array(dtype=wp.int32), vsq_acc: wp.array(dtype=T),
                     mean_acc: wp.array(dtype=V), dt0: T, alpha0: T):
        r = wp.tid()
        if active[r] != 0:
            status[r] = ACTIVE
        else:
            status[r] = FROZEN
        iters[r] = 0
        steps[r] = 0
        dt_r[r] = dt0
        alpha_r[r] = alpha0
        npos[r] = 0
        down[r] = 0
        fmax_out[r] = T(0.0)
        clear_accumulators(r, fmax_acc, fsq_acc, pow_acc, nonfin_acc, vsq_acc, mean_acc)

    @kern
    def restart_kernel(flag: wp.array(dtype=wp.int32), status: wp.array(dtype=wp.int32),
                       iters: wp.array(dtype=wp.int32), steps: wp.array(dtype=wp.int32),
                       dt_r: wp.array(dtype=T), alpha_r: wp.array(dtype=T), npos: wp.array(dtype=wp.int32),
                       down: wp.array(dtype=wp.int32), fmax_out: wp.array(dtype=T), dt0: T, alpha0: T):
        """Fresh FIRE state (ACTIVE) for flagged replicas only; the others run on untouched."""
        r = wp.tid()
        if flag[r] == 0:
            return
        status[r] = ACTIVE
        iters[r] = 0
        steps[r] = 0
        dt_r[r] = dt0
        alpha_r[r] = alpha0
        npos[r] = 0
        down[r] = 0
        fmax_out[r] = T(0.0)

    @kern
    def zero_rows_kernel(v: wp.array(dtype=V), row_start: wp.array(dtype=wp.int32), flag: wp.array(dtype=wp.int32),
                         nthr: wp.int32):
        """v <- 0 on the rows of flagged replicas (a restarted replica starts at rest)."""
        tid = wp.tid()
        r = tid // nthr
        t = tid - r * nthr
        if flag[r] == 0:
            return
        for i in range(row_start[r] + t, row_start[r + 1], nthr):
            v[i] = V()

    @kern
    def mean_accum_kernel(f: wp.array(dtype=V), row_start: wp.array(dtype=wp.int32),
                          status: wp.array(dtype=wp.int32), nthr: wp.int32, mean_acc: wp.array(dtype=V)):
        tid = wp.tid()
        r = tid // nthr
        t = tid - r * nthr
        if status[r] != ACTIVE:
            return
        s = V()
        for i in range(row_start[r] + t, row_start[r + 1], nthr):
            s = s + f[i]
        wp.atomic_add(mean_acc, r, s)

    @kern
    def project_reduce_kernel(f: wp.array(dtype=V), v: wp.array(dtype=V), free: wp.array(dtype=V),
                              row_start: wp.array(dtype=wp.int32), status: wp.array(dtype=wp.int32),
                              nthr: wp.int32, mean_comps: V, mean_acc: wp.array(dtype=V),
                              fmax_acc: wp.array(dtype=T), fsq_acc: wp.array(dtype=T),
                              pow_acc: wp.array(dtype=T), nonfin_acc: wp.array(dtype=wp.int32)):
        """Subtract the replica's mean force (masked components), zero the fixed components, reduce."""
        tid = wp.tid()
        r = tid // nthr
        t = tid - r * nthr
        if status[r] != ACTIVE:
            return
        a = row_start[r]
        b = row_start[r + 1]
        shift = wp.cw_mul(mean_acc[r], mean_comps) / T(b - a)
        fm = T(0.0)
        fsq = T(0.0)
        pw = T(0.0)
        nf = wp.int32(0)
        for i in range(a + t, b, nthr):
            fi = wp.cw_mul(f[i] - shift, free[i])
            f[i] = fi
            n2 = wp.dot(fi, fi)
            if wp.isfinite(n2):
                fm = wp.max(fm, wp.sqrt(n2))
                fsq = fsq + n2
                pw = pw + wp.dot(fi, v[i])
            else:
                nf = nf + 1
        wp.atomic_max(fmax_acc, r, fm)
        wp.atomic_add(fsq_acc, r, fsq)
        wp.atomic_add(pow_acc, r, pw)
        if nf > 0:
            wp.atomic_add(nonfin_acc, r, nf)

    @kern
    def replica_kernel(status: wp.array(dtype=wp.int32), iters: wp.array(dtype=wp.int32),
                       max_steps: wp.array(dtype=wp.int32), tol: wp.array(dtype=T),
                       fmax_acc: wp.array(dtype=T), fsq_acc: wp.array(dtype=T), pow_acc: wp.array(dtype=T),
                       nonfin_acc: wp.array(dtype=wp.int32), vsq_acc: wp.array(dtype=T),
                       mean_acc: wp.array(dtype=V), fmax_out: wp.array(dtype=T), steps: wp.array(dtype=wp.int32),
                       dt_r: wp.array(dtype=T), alpha_r: wp.array(dtype=T), npos: wp.array(dtype=wp.int32),
                       down: wp.array(dtype=wp.int32), fnorm: wp.array(dtype=T), dt_max: T, dt_min: T,
                       f_inc: T, f_dec: T, alpha0: T, f_alpha: T, n_delay: wp.int32):
        """Convergence test, then the FIRE 2.0 power test of one replica; clears its accumulators."""
        r = wp.tid()
        fm = fmax_acc[r]
        fsq = fsq_acc[r]
        pw = pow_acc[r]
        nf = nonfin_acc[r]
        clear_accumulators(r, fmax_acc, fsq_acc, pow_acc, nonfin_acc, vsq_acc, mean_acc)
        if status[r] != ACTIVE:
            return
        it = iters[r]
        if nf > 0:
            status[r] = NONFINITE
            return
        fmax_out[r] = fm
        if fm <= tol[r]:
            status[r] = CONVERGED
            return
        steps[r] = it
        if it >= max_steps[0]:
            status[r] = MAX_STEPS
            return
        iters[r] = it + 1
        if pw > T(0.0):
            n = npos[r] + 1
            npos[r] = n
            down[r] = 0
            if n > n_delay:
                dt_r[r] = wp.min(dt_r[r] * f_inc, dt_max)
                alpha_r[r] = alpha_r[r] * f_alpha
        else:
            npos[r] = 0
            dt_r[r] = wp.max(dt_r[r] * f_dec, dt_min)
            alpha_r[r] = alpha0
            down[r] = 1
        fnorm[r] = wp.sqrt(fsq)

    @kern
    def euler_kernel(x: wp.array(dtype=V), v: wp.array(dtype=V), f: wp.array(dtype=V), free: wp.array(dtype=V),
                     inv_mass: wp.array(dtype=T), row_start: wp.array(dtype=wp.int32),
                     status: wp.array(dtype=wp.int32), nthr: wp.int32, dt_r: wp.array(dtype=T),
                     down: wp.array(dtype=wp.int32), vsq_acc: wp.array(dtype=T)):
        """FIRE 2.0 half-step correction on an uphill step, then v += dt F / m; sums |v|^2."""
        tid = wp.tid()
        r = tid // nthr
        t = tid - r * nthr
        if status[r] != ACTIVE:
            return
        dt = dt_r[r]
        back = down[r] != 0
        vs = T(0.0)
        for i in range(row_start[r] + t, row_start[r + 1], nthr):
            vi = v[i]
            if back:
                x[i] = x[i] - (T(0.5) * dt) * vi
                vi = V()
            vi = wp.cw_mul(vi + (dt * inv_mass[i]) * f[i], free[i])
            v[i] = vi
            vs = vs + wp.dot(vi, vi)
        wp.atomic_add(vsq_acc, r, vs)

    @kern
    def mix_move_kernel(x: wp.array(dtype=V), v: wp.array(dtype=V), f: wp.array(dtype=V), free: wp.array(dtype=V),
                        row_start: wp.array(dtype=wp.int32), status: wp.array(dtype=wp.int32), nthr: wp.int32,
                        dt_r: wp.array(dtype=T), alpha_r: wp.array(dtype=T), fnorm: wp.array(dtype=T),
                        vsq_acc: wp.array(dtype=T), max_move: T):
        """Velocity mixing v = (1-a) v + a |v|/|F| F, capped move, x += dt v; clears F for the next step."""
        tid = wp.tid()
        r = tid // nthr
        t = tid - r * nthr
        a = row_start[r]
        b = row_start[r + 1]
        if status[r] != ACTIVE:
            for i in range(a + t, b, nthr):
                f[i] = V()
            return
        dt = dt_r[r]
        al = alpha_r[r]
        fn = fnorm[r]
        scale = T(0.0)
        if fn > T(0.0):
            scale = wp.sqrt(vsq_acc[r]) / fn
        c = al * scale
        for i in range(a + t, b, nthr):
            fi = f[i]
            vi = wp.cw_mul((T(1.0) - al) * v[i] + c * fi, free[i])
            v[i] = vi
            dx = dt * vi
            if max_move > T(0.0):
                dn = wp.length(dx)
                if dn > max_move:
                    dx = dx * (max_move / dn)
            x[i] = x[i] + dx
            f[i] = V()

    return {k: val for k, val in locals().items() if isinstance(val, wp.Kernel)}
