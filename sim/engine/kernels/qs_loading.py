"""Warp kernels of the quasi-static tier's loads and observables (docs/physics.md section 5), batched over replicas.

Used by :mod:`bubblecal.sim.tiers.quasistatic` with the device FIRE
(:mod:`bubblecal.sim.engine.minimize_device`); all replicas share one mesh (local topology): vertex v of
replica r sits at row ``row_start[r] + v``.  DPD units throughout.

* ``volume_kernel``: enclosed volume per replica (sum over triangles of x0.(x1 x x2)/6, relative to
  the replica's first vertex), atomic per thread chunk.
* ``pole_load_kernel``: adds the pole loads on the loaded rows only.
* ``plate_force_kernel``: adds, per row, the capped WCA force of two analytic plates z = top_r (pushing down)
  and z = bottom_r (pushing up), or their thermal mean force (:mod:`bubblecal.sim.tiers.quasistatic.thermal_contact`).
  The ideal-gas force rides on the shell's own triangle pass (``ShellForceField.set_gas``).
* Observables: plate reactions and contacts, axial extent and loaded-patch heights, non-finite rows,
  and the reset of failed replicas to their reference rows.
* ``extrapolate_kernel`` / ``extrapolate_rows_kernel``: linear predictor of the next load point's state from
  the last two minima (all replicas at one point / each replica at its own point).
"""

# (no "from __future__ import annotations": Warp must see the closure types of the kernel signatures)

import functools

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.common import kernel_decorator
from bubblecal.sim.engine.kernels.fire import ACTIVE

wp = require("warp", "sim")

__all__ = ["qs_kernels", "PLATE_TOP", "PLATE_BOTTOM", "PLATE_CONTACTS", "AX_ZMAX", "AX_ZMIN", "AX_TOP", "AX_BOTTOM"]

# columns of the observable tables
PLATE_TOP, PLATE_BOTTOM, PLATE_CONTACTS = 0, 1, 2
AX_ZMAX, AX_ZMIN, AX_TOP, AX_BOTTOM = 0, 1, 2, 3


@functools.cache
def qs_kernels(dtype):
    """Build (once per scalar type) the loading and observable kernels; ``dtype`` is ``wp.float32`` or
    ``wp.float64``. Returns a dict: Name -> ``wp.Kernel``.
    """
    T = dtype
    V = wp.vec3d if T is wp.float64 else wp.vec3f
    kern = kernel_decorator(T, "qs_loading")

    @wp.func
    def plate_force(h: T, eps: T, sig: T, rc: T, hcap: T, cap: T):
        """Capped repulsive LJ (WCA) magnitude at plate distance h (>= 0, pushes away from the plate)."""
        out = T(0.0)
        if h <= hcap:
            out = cap
        elif h < rc:
            s2 = sig / h
            s6 = s2 * s2 * s2 * s2 * s2 * s2
            out = T(24.0) * eps * (T(2.0) * s6 * s6 - s6) / h
        return out

    @wp.func
    def mills(z: T):
        """Inverse Mills ratio phi(z) / Phi(z) (asymptotic series below z = -8, where erfc underflows in float32)."""
        m = T(0.0)
        if z < T(-8.0):
            iz2 = T(1.0) / (z * z)
            m = -z / (T(1.0) - iz2 + T(3.0) * iz2 * iz2 - T(15.0) * iz2 * iz2 * iz2)
        elif z < T(12.0):
            m = T(0.7978845608028654) * wp.exp(T(-0.5) * z * z) / wp.erfc(-z * T(0.7071067811865476))
        return m

    @wp.func
    def psi_exact(g: T):
        """Psi(g) = M(z) with z + M(z) = g: Newton from the convex side (thermal_contact._psi_exact)."""
        z = g
        if g < T(1.0):
            z = T(-1.0) / g
        for _ in range(8):
            m = mills(z)
            d = wp.max(T(1.0) - m * (z + m), T(1.0e-30))
            z = z - (z + m - g) / d
        return mills(z)

    @wp.func
    def thermal_force(h: T, s: T, hw: T, kT: T, cap: T, p0: T, dp0: T):
        """Mean wall force (kT / s) Psi((h - hw) / s) of a vertex at mean plate distance h fluctuating with
        rms s (sim/tiers/quasistatic/thermal_contact.py); linear below g = 0.05 (``p0``, ``dp0``), capped."""
        g = (h - hw) / s
        p = T(0.0)
        if g < T(0.05):
            p = p0 + dp0 * (g - T(0.05))
        elif g < T(12.0):
            p = psi_exact(g)
        return wp.min(kT / s * p, cap)

    @wp.func
    def plate_push(h: T, thermal: wp.int32, s: T, hw: T, kT: T, p0: T, dp0: T, eps: T, sig: T, rc: T, hcap: T,
                   cap: T):
        """Plate force magnitude on a vertex at distance h: athermal WCA or the thermal mean force."""
        out = T(0.0)
        if thermal != 0:
            out = thermal_force(h, s, hw, kT, cap, p0, dp0)
        else:
            out = plate_force(h, eps, sig, rc, hcap, cap)
        return out

    @kern
    def volume_kernel(x: wp.array(dtype=V), tri: wp.array(dtype=wp.vec3i), row_start: wp.array(dtype=wp.int32),
                      status: wp.array(dtype=wp.int32), all_rep: wp.int32, nthr: wp.int32, vol: wp.array(dtype=T)):
        """vol[r] += enclosed volume of replica r (shared mesh: ``tri`` holds local vertex indices)."""
        tid = wp.tid()
        r = tid // nthr
        t = tid - r * nthr
        if all_rep == 0 and status[r] != ACTIVE:
            return
        o = row_start[r]
        c = x[o]
        s = T(0.0)
        for k in range(t, tri.shape[0], nthr):
            q = tri[k]
            s = s + wp.dot(x[q[0] + o] - c, wp.cross(x[q[1] + o] - c, x[q[2] + o] - c))
        wp.atomic_add(vol, r, s / T(6.0))

    @kern
    def pole_load_kernel(f: wp.array(dtype=V), row_start: wp.array(dtype=wp.int32), status: wp.array(dtype=wp.int32),
                         loaded: wp.array(dtype=wp.int32), load: wp.array(dtype=T), unit: wp.array(dtype=V)):
        """f += load[r] unit[i] on the loaded rows only (``loaded``: the local rows whose unit vector is nonzero;
        one thread per (replica, loaded row)): the pole patches are ~0.5 % of the rows."""
        tid = wp.tid()
        n = loaded.shape[0]
        r = tid // n
        if status[r] != ACTIVE:
            return
        i = row_start[r] + loaded[tid - r * n]
        f[i] = f[i] + load[r] * unit[i]

    @kern
    def plate_force_kernel(x: wp.array(dtype=V), f: wp.array(dtype=V), row_start: wp.array(dtype=wp.int32),
                           status: wp.array(dtype=wp.int32), nthr: wp.int32, plates: wp.array2d(dtype=T),
                           eps: T, sig: T, rc: T, hcap: T, cap: T,
                           tsig: wp.array(dtype=T), thermal: wp.int32, hw: T, kT: T, p0: T, dp0: T):
        """f += plate forces for the rows of active replicas.

        ``plates[r] = (z_top, z_bottom)``; ``thermal`` != 0: the plates act through the thermal mean force
        (rms fluctuation ``tsig[r]``, hard wall at ``hw``).
        """
        tid = wp.tid()
        r = tid // nthr
        t = tid - r * nthr
        if status[r] != ACTIVE:
            return
        ztop = plates[r, 0]
        zbot = plates[r, 1]
        s_r = tsig[r]
        for i in range(row_start[r] + t, row_start[r + 1], nthr):
            z = x[i][2]
            fz = (plate_push(z - zbot, thermal, s_r, hw, kT, p0, dp0, eps, sig, rc, hcap, cap)
                  - plate_push(ztop - z, thermal, s_r, hw, kT, p0, dp0, eps, sig, rc, hcap, cap))
            f[i] = f[i] + V(T(0.0), T(0.0), fz)

    @kern
    def plate_obs_kernel(x: wp.array(dtype=V), row_rep: wp.array(dtype=wp.int32), plates: wp.array2d(dtype=T),
                         eps: T, sig: T, rc: T, hcap: T, cap: T, tsig: wp.array(dtype=T), thermal: wp.int32,
                         hw: T, kT: T, p0: T, dp0: T, out: wp.array2d(dtype=T)):
        """Per replica: force on the top plate, on the bottom plate, vertices within range of the top plate
        (rc; thermal: also within hw + 3 rms fluctuations)."""
        i = wp.tid()
        r = row_rep[i]
        z = x[i][2]
        ht = plates[r, 0] - z
        s_r = tsig[r]
        wp.atomic_add(out, r, PLATE_TOP, plate_push(ht, thermal, s_r, hw, kT, p0, dp0, eps, sig, rc, hcap, cap))
        hb = z - plates[r, 1]
        wp.atomic_add(out, r, PLATE_BOTTOM, plate_push(hb, thermal, s_r, hw, kT, p0, dp0, eps, sig, rc, hcap, cap))
        reach = rc
        if thermal != 0:
            reach = wp.max(rc, hw + T(3.0) * s_r)
        if ht < reach:
            wp.atomic_add(out, r, PLATE_CONTACTS, T(1.0))

    @kern
    def axial_obs_kernel(x: wp.array(dtype=V), row_rep: wp.array(dtype=wp.int32), tag: wp.array(dtype=wp.int32),
                         out: wp.array2d(dtype=T)):
        """Per replica: max z, min z, sum of z over rows tagged 1 (top patch) and -1 (bottom patch)."""
        i = wp.tid()
        r = row_rep[i]
        z = x[i][2]
        wp.atomic_max(out, r, AX_ZMAX, z)
        wp.atomic_min(out, r, AX_ZMIN, z)
        tg = tag[i]
        if tg == 1:
            wp.atomic_add(out, r, AX_TOP, z)
        elif tg == -1:
            wp.atomic_add(out, r, AX_BOTTOM, z)

    @kern
    def nonfinite_kernel(x: wp.array(dtype=V), row_rep: wp.array(dtype=wp.int32), out: wp.array(dtype=wp.int32)):
        i = wp.tid()
        xi = x[i]
        if not (wp.isfinite(xi[0]) and wp.isfinite(xi[1]) and wp.isfinite(xi[2])):
            wp.atomic_add(out, row_rep[i], 1)

    @kern
    def reset_rows_kernel(x: wp.array(dtype=V), x_ref: wp.array(dtype=V), row_rep: wp.array(dtype=wp.int32),
                          flag: wp.array(dtype=wp.int32)):
        i = wp.tid()
        if flag[row_rep[i]] != 0:
            x[i] = x_ref[i]

    @kern
    def extrapolate_kernel(x: wp.array(dtype=V), x_prev: wp.array(dtype=V), row_rep: wp.array(dtype=wp.int32),
                           flag: wp.array(dtype=wp.int32), c: T):
        """Start of the next load point: x <- x + c (x - x_prev) on flagged replicas; x_prev <- old x
        everywhere (so it always holds the last converged state)."""
        i = wp.tid()
        xi = x[i]
        if flag[row_rep[i]] != 0:
            x[i] = xi + c * (xi - x_prev[i])
        x_prev[i] = xi

    @kern
    def extrapolate_rows_kernel(x: wp.array(dtype=V), x_prev: wp.array(dtype=V), row_rep: wp.array(dtype=wp.int32),
                                flag: wp.array(dtype=wp.int32), coef: wp.array(dtype=T)):
        """Per-replica predictor (replica-asynchronous chains): on flagged replicas only,
        x <- x + coef[r] (x - x_prev) and x_prev <- old x."""
        i = wp.tid()
        r = row_rep[i]
        if flag[r] == 0:
            return
        xi = x[i]
        x[i] = xi + coef[r] * (xi - x_prev[i])
        x_prev[i] = xi

    return {k: val for k, val in locals().items() if isinstance(val, wp.Kernel)}
