"""Warp kernels of the quasi-static tier's loads and observables (physics.md section 5), batched over replicas.

Used by :mod:`bubblecal.sim.experiments.quasistatic` with the device FIRE
(:mod:`bubblecal.sim.minimize_device`); all replicas share one mesh (local topology): vertex v of
replica r sits at row ``row_start[r] + v``.  DPD units throughout.

* ``volume_kernel``: enclosed volume per replica (sum over triangles of x0.(x1 x x2)/6, relative to
  the replica's first vertex), atomic per thread chunk.
* ``load_force_kernel``: adds, per row, the ideal-gas force (p0 V0 / V - p_ambient) dV/dx (dV/dx_v =
  sum over the incident triangles of n_t / 6, n_t = (x1 - x0) x (x2 - x0), gathered through a CSR),
  a per-replica scalar load times a per-row vector (pole loads), and the capped WCA force of two
  analytic plates z = top_r (pushing down) and z = bottom_r (pushing up).
* Observables: plate reactions and contacts, axial extent and loaded-patch heights, non-finite rows,
  and the reset of failed replicas to their reference rows.
* ``extrapolate_kernel`` / ``extrapolate_rows_kernel``: linear predictor of the next load point's state from
  the last two minima (all replicas at one point / each replica at its own point).
"""

# (no "from __future__ import annotations": Warp must see the closure types of the kernel signatures)

import functools

import warp as wp

from bubblecal.sim.kernels.common import kernel_decorator
from bubblecal.sim.kernels.fire import ACTIVE

__all__ = ["qs_kernels", "PLATE_TOP", "PLATE_BOTTOM", "PLATE_CONTACTS", "AX_ZMAX", "AX_ZMIN", "AX_TOP", "AX_BOTTOM"]

# columns of the observable tables
PLATE_TOP, PLATE_BOTTOM, PLATE_CONTACTS = 0, 1, 2
AX_ZMAX, AX_ZMIN, AX_TOP, AX_BOTTOM = 0, 1, 2, 3


@functools.cache
def qs_kernels(dtype):
    """Build (once per scalar type) the loading / observable kernels; dict name -> kernel."""
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
    def load_force_kernel(x: wp.array(dtype=V), f: wp.array(dtype=V), row_start: wp.array(dtype=wp.int32),
                          status: wp.array(dtype=wp.int32), nthr: wp.int32, tri: wp.array(dtype=wp.vec3i),
                          vt_start: wp.array(dtype=wp.int32), vt_tri: wp.array(dtype=wp.int32),
                          vol: wp.array(dtype=T), gas: wp.array2d(dtype=T), gas_on: wp.int32,
                          load: wp.array(dtype=T), unit: wp.array(dtype=V), load_on: wp.int32,
                          plates: wp.array2d(dtype=T), plate_on: wp.int32, eps: T, sig: T, rc: T, hcap: T, cap: T):
        """f += gas + pole load + plate forces for the rows of active replicas.

        Shared mesh: ``tri`` local vertex indices, ``vt_start`` / ``vt_tri`` the local vertex ->
        triangle CSR; ``gas[r] = (p0 V0, p_ambient)``; ``plates[r] = (z_top, z_bottom)``.
        """
        tid = wp.tid()
        r = tid // nthr
        t = tid - r * nthr
        if status[r] != ACTIVE:
            return
        dp = T(0.0)
        if gas_on != 0:
            dp = gas[r, 0] / vol[r] - gas[r, 1]
        ld = T(0.0)
        if load_on != 0:
            ld = load[r]
        ztop = plates[r, 0]
        zbot = plates[r, 1]
        sixth = T(1.0) / T(6.0)
        o = row_start[r]
        for i in range(o + t, row_start[r + 1], nthr):
            fi = f[i]
            if gas_on != 0:
                li = i - o
                g = V()
                for k in range(vt_start[li], vt_start[li + 1]):
                    q = tri[vt_tri[k]]
                    x0 = x[q[0] + o]
                    g = g + wp.cross(x[q[1] + o] - x0, x[q[2] + o] - x0)
                fi = fi + (dp * sixth) * g
            if load_on != 0:
                fi = fi + ld * unit[i]
            if plate_on != 0:
                z = x[i][2]
                fz = plate_force(z - zbot, eps, sig, rc, hcap, cap) - plate_force(ztop - z, eps, sig, rc, hcap, cap)
                fi = fi + V(T(0.0), T(0.0), fz)
            f[i] = fi

    @kern
    def plate_obs_kernel(x: wp.array(dtype=V), row_rep: wp.array(dtype=wp.int32), plates: wp.array2d(dtype=T),
                         eps: T, sig: T, rc: T, hcap: T, cap: T, out: wp.array2d(dtype=T)):
        """Per replica: force on the top plate, on the bottom plate, vertices within rc of the top plate."""
        i = wp.tid()
        r = row_rep[i]
        z = x[i][2]
        ht = plates[r, 0] - z
        wp.atomic_add(out, r, PLATE_TOP, plate_force(ht, eps, sig, rc, hcap, cap))
        wp.atomic_add(out, r, PLATE_BOTTOM, plate_force(z - plates[r, 1], eps, sig, rc, hcap, cap))
        if ht < rc:
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
