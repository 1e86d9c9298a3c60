"""Warp kernels of the device-resident batched nonlinear CG (:mod:`bubblecal.sim.engine.minimize_device_cg`).

The rules are those of the NumPy reference :func:`bubblecal.sim.engine.minimize_cg.cg_minimize`.  Row layout,
threads per replica and status codes are those of the FIRE kernels (:mod:`bubblecal.sim.engine.kernels.fire`).  One
iteration is one force evaluation at the replica's current point; the replica kernel then decides, per replica, what
the row passes do next (:data:`MOVE`, :data:`NEW_ALONG_F`, :data:`NEW_LINE`).  The current point is always
``x``: a trial step moves it by the difference of the trial steps along ``d``.
"""

# (no "from __future__ import annotations": Warp must see the closure types of the kernel signatures)

import functools

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.common import kernel_decorator
from bubblecal.sim.engine.kernels.fire import ACTIVE, CONVERGED, FROZEN, MAX_STEPS, NONFINITE

wp = require("warp", "sim")

__all__ = ["cg_kernels", "IDLE", "MOVE", "NEW_ALONG_F", "NEW_LINE"]

#: row actions after an evaluation: none; x += delta d; a line along F (d = F, f_b = F, x += delta d); a line along
#: F + beta d (d, f_b updated and max |d| reduced first, x moves in a second pass)
IDLE = 0
MOVE = 1
NEW_ALONG_F = 2
NEW_LINE = 3

# fields of the per-replica line state ``ls [R, 10]`` (_APREV: the last line's final step times its slope)
_A1, _ALO, _GLO, _AHI, _GHI, _SLOPE, _FSQB, _DN, _DELTA, _APREV = range(10)


@functools.cache
def cg_kernels(dtype):
    """Build (once per scalar type) the CG kernels; ``dtype`` is ``wp.float32`` or ``wp.float64``.

    Returns
    -------
    dict
        Name -> ``wp.Kernel``.
    """
    T = dtype
    V = wp.vec3d if T is wp.float64 else wp.vec3f
    kern = kernel_decorator(T, "cg")

    @wp.func
    def first_step(a_slope_prev: T, slope: T, dn: T, first_alpha: T, first_move: T, grow: T):
        """A line's first trial step: the last line's step scaled by the slopes, capped (the first line: small)."""
        if a_slope_prev > T(0.0):
            return wp.min(a_slope_prev / slope, grow * first_move / dn)
        return wp.min(first_alpha, first_move / dn)

    @kern
    def reset_kernel(flag: wp.array(dtype=wp.int32), only_flagged: wp.int32, status: wp.array(dtype=wp.int32),
                     iters: wp.array(dtype=wp.int32), steps: wp.array(dtype=wp.int32),
                     trials: wp.array(dtype=wp.int32), action: wp.array(dtype=wp.int32),
                     fmax_out: wp.array(dtype=T), beta: wp.array(dtype=T)):
        """Fresh CG state: flagged replicas ACTIVE at their first evaluation; the others FROZEN
        (``only_flagged`` = 0) or untouched (``only_flagged`` = 1)."""
        r = wp.tid()
        if flag[r] == 0:
            if only_flagged == 0:
                status[r] = FROZEN
                action[r] = IDLE
            return
        status[r] = ACTIVE
        iters[r] = 0
        steps[r] = 0
        trials[r] = -1  # the next evaluation is the start point's
        action[r] = IDLE
        fmax_out[r] = T(0.0)
        beta[r] = T(0.0)

    @kern
    def project_reduce_kernel(f: wp.array(dtype=V), d: wp.array(dtype=V), f_b: wp.array(dtype=V),
                              free: wp.array(dtype=V), row_start: wp.array(dtype=wp.int32),
                              status: wp.array(dtype=wp.int32), nthr: wp.int32, mean_comps: V,
                              mean_acc: wp.array(dtype=V), red: wp.array2d(dtype=T),
                              nonfin_acc: wp.array(dtype=wp.int32)):
        """Remove the replica's mean force (masked components), zero the fixed ones; reduce
        ``red[r] = (max |F_i|, F.F, F.d, F.f_b)``."""
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
        fd = T(0.0)
        fb = T(0.0)
        nf = wp.int32(0)
        for i in range(a + t, b, nthr):
            fi = wp.cw_mul(f[i] - shift, free[i])
            f[i] = fi
            n2 = wp.dot(fi, fi)
            if wp.isfinite(n2):
                fm = wp.max(fm, wp.sqrt(n2))
                fsq = fsq + n2
                fd = fd + wp.dot(fi, d[i])
                fb = fb + wp.dot(fi, f_b[i])
            else:
                nf = nf + 1
        wp.atomic_max(red, r, 0, fm)
        wp.atomic_add(red, r, 1, fsq)
        wp.atomic_add(red, r, 2, fd)
        wp.atomic_add(red, r, 3, fb)
        if nf > 0:
            wp.atomic_add(nonfin_acc, r, nf)

    @kern
    def replica_kernel(status: wp.array(dtype=wp.int32), iters: wp.array(dtype=wp.int32),
                       steps: wp.array(dtype=wp.int32), trials: wp.array(dtype=wp.int32),
                       action: wp.array(dtype=wp.int32), max_steps: wp.array(dtype=wp.int32),
                       tol: wp.array(dtype=T), red: wp.array2d(dtype=T), nonfin_acc: wp.array(dtype=wp.int32),
                       mean_acc: wp.array(dtype=V), fmax_out: wp.array(dtype=T), beta_r: wp.array(dtype=T),
                       ls: wp.array2d(dtype=T), first_alpha: T, first_move: T, grow: T, accept: T,
                       max_trials: wp.int32):
        """Tests of the evaluated point, then the line search's decision (the reference's ``next_trial`` and the
        new direction); clears the replica's accumulators."""
        r = wp.tid()
        fm = red[r, 0]
        fsq = red[r, 1]
        g1 = red[r, 2]
        gb = red[r, 3]
        nf = nonfin_acc[r]
        for c in range(4):
            red[r, c] = T(0.0)
        nonfin_acc[r] = 0
        mean_acc[r] = V()
        action[r] = IDLE
        if status[r] != ACTIVE:
            return
        if nf > 0:
            status[r] = NONFINITE
            return
        fmax_out[r] = fm
        if fm <= tol[r]:
            status[r] = CONVERGED
            return
        it = iters[r]
        steps[r] = it
        if it >= max_steps[0]:
            status[r] = MAX_STEPS
            return
        iters[r] = it + 1
        tr = trials[r] + 1
        if tr > 0 and (wp.abs(g1) > accept * ls[r, _SLOPE] and tr < max_trials):
            trials[r] = tr  # go on along this line
            a1 = ls[r, _A1]
            a_lo = ls[r, _ALO]
            g_lo = ls[r, _GLO]
            a_hi = ls[r, _AHI]
            g_hi = ls[r, _GHI]
            an = T(0.0)
            if g1 > T(0.0) and a_hi < T(0.0):  # no bracket: extrapolate, at most doubling the step
                gr = T(2.0) * (a1 - a_lo)
                if g_lo > g1:
                    gr = wp.min(gr, (a1 - a_lo) * g1 / (g_lo - g1))
                an = a1 + wp.min(gr, grow * first_move / ls[r, _DN])
                ls[r, _ALO] = a1
                ls[r, _GLO] = g1
            else:
                if g1 > T(0.0):
                    a_lo = a1
                    g_lo = g1
                else:
                    a_hi = a1
                    g_hi = g1
                an = a_lo + g_lo * (a_hi - a_lo) / (g_lo - g_hi)
                ls[r, _ALO] = a_lo
                ls[r, _GLO] = g_lo
                ls[r, _AHI] = a_hi
                ls[r, _GHI] = g_hi
            ls[r, _DELTA] = an - a1
            ls[r, _A1] = an
            action[r] = MOVE
            return
        # a new line: along F on the first evaluation, else F + beta d (Polak-Ribiere+, restart when not downhill)
        beta = T(0.0)
        slope = fsq
        ls[r, _APREV] = T(0.0)
        if tr > 0:
            ls[r, _APREV] = ls[r, _A1] * ls[r, _SLOPE]  # the last line's step times its slope
            beta = wp.max(T(0.0), (fsq - gb) / ls[r, _FSQB])
            slope = fsq + beta * g1
            if slope <= T(0.0):
                beta = T(0.0)
                slope = fsq
        trials[r] = 0
        beta_r[r] = beta
        ls[r, _SLOPE] = slope
        ls[r, _FSQB] = fsq
        ls[r, _ALO] = T(0.0)
        ls[r, _GLO] = slope
        ls[r, _AHI] = T(-1.0)
        ls[r, _GHI] = T(0.0)
        if beta == T(0.0):
            ls[r, _DN] = fm
            a1 = first_step(ls[r, _APREV], slope, fm, first_alpha, first_move, grow)
            ls[r, _A1] = a1
            ls[r, _DELTA] = a1
            action[r] = NEW_ALONG_F
        else:
            action[r] = NEW_LINE

    @kern
    def direction_kernel(x: wp.array(dtype=V), f: wp.array(dtype=V), d: wp.array(dtype=V), f_b: wp.array(dtype=V),
                         row_start: wp.array(dtype=wp.int32), action: wp.array(dtype=wp.int32), nthr: wp.int32,
                         beta_r: wp.array(dtype=T), ls: wp.array2d(dtype=T), dn_acc: wp.array(dtype=T)):
        """Carry out the replica's action on its rows (a new line's max |d| into ``dn_acc``); clears F."""
        tid = wp.tid()
        r = tid // nthr
        t = tid - r * nthr
        a = row_start[r]
        b = row_start[r + 1]
        act = action[r]
        if act == MOVE or act == NEW_ALONG_F:
            delta = ls[r, _DELTA]
            for i in range(a + t, b, nthr):
                if act == NEW_ALONG_F:
                    d[i] = f[i]
                    f_b[i] = f[i]
                x[i] = x[i] + delta * d[i]
                f[i] = V()
        elif act == NEW_LINE:
            beta = beta_r[r]
            dm = T(0.0)
            for i in range(a + t, b, nthr):
                di = f[i] + beta * d[i]
                d[i] = di
                f_b[i] = f[i]
                dm = wp.max(dm, wp.length(di))
                f[i] = V()
            wp.atomic_max(dn_acc, r, dm)
        else:
            for i in range(a + t, b, nthr):
                f[i] = V()

    @kern
    def first_step_kernel(action: wp.array(dtype=wp.int32), ls: wp.array2d(dtype=T), dn_acc: wp.array(dtype=T),
                          first_alpha: T, first_move: T, grow: T):
        """The first trial step of a new line along F + beta d, from its max |d|."""
        r = wp.tid()
        if action[r] != NEW_LINE:
            return
        dn = dn_acc[r]
        dn_acc[r] = T(0.0)
        a1 = first_step(ls[r, _APREV], ls[r, _SLOPE], dn, first_alpha, first_move, grow)
        ls[r, _DN] = dn
        ls[r, _A1] = a1
        ls[r, _DELTA] = a1

    @kern
    def line_move_kernel(x: wp.array(dtype=V), d: wp.array(dtype=V), row_start: wp.array(dtype=wp.int32),
                         action: wp.array(dtype=wp.int32), nthr: wp.int32, ls: wp.array2d(dtype=T)):
        """x += a1 d on the rows of replicas that began a line along F + beta d."""
        tid = wp.tid()
        r = tid // nthr
        t = tid - r * nthr
        if action[r] != NEW_LINE:
            return
        delta = ls[r, _DELTA]
        for i in range(row_start[r] + t, row_start[r + 1], nthr):
            x[i] = x[i] + delta * d[i]

    return {k: val for k, val in locals().items() if isinstance(val, wp.Kernel)}
