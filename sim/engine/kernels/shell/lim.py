"""Lim in-plane triangle forces (docs/physics.md section 3), with the global constraints and inside pressures.

W_t = A0 [(ka/2)(alpha^2 + a3 alpha^3 + a4 alpha^4) + mu (beta + b1 alpha beta + b2 beta^2)] per triangle,
alpha = A/A0 - 1 (area strain), beta the shear invariant; the forces are the closed-form -grad W on the three
corners, with the current area clamped at :data:`~bubblecal.sim.engine.kernels.shell.layout.AREA_CLAMP`.
The same pass adds the global area / volume constraints, the back pressure and an optional inside gas
(:mod:`bubblecal.sim.engine.kernels.shell.constraints`): they act through dA/dx and dV/dx, which this triangle
already has.  Forces in DPD force units (k_BT / r_c), energies in k_BT.
"""

# (no "from __future__ import annotations": Warp must see the closure types of the kernel signatures)

import functools

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.common import kernel_decorator
from bubblecal.sim.engine.kernels.shell.constraints import constraint_kernels
from bubblecal.sim.engine.kernels.shell.layout import (
    AREA_CLAMP,
    E_LIM,
    P_A0TOT,
    P_A3,
    P_A4,
    P_B1,
    P_B2,
    P_KA,
    P_KATOT,
    P_KVTOT,
    P_MU,
    P_PB,
    P_V0,
)

wp = require("warp", "sim")

__all__ = ["lim_kernels"]


@functools.cache
def lim_kernels(dtype) -> dict:
    """Build (once per scalar type) the Lim triangle function and its scatter kernel; ``dtype`` is ``wp.float32`` or
    ``wp.float64``. Returns a dict: ``"lim_triangle"`` (Warp function: forces on the three corners of one
    triangle and its energy W) and ``"lim_kernel"`` (one thread per triangle, atomics into the three vertices).
    """
    T = dtype
    V = wp.vec3d if T is wp.float64 else wp.vec3f
    V4 = wp.vec4d if T is wp.float64 else wp.vec4f
    kern = kernel_decorator(dtype, "shell")
    clamp_a = T(AREA_CLAMP)
    gas_pressure = constraint_kernels(dtype)["gas_pressure"]

    @wp.func
    def lim_triangle(x: wp.array(dtype=V), idx: wp.vec3i, rf: V4, params: wp.array2d(dtype=T), r: wp.int32,
                     avr: wp.array2d(dtype=T), use_global: wp.int32, pex: T):
        """Lim (+ global area/volume, back pressure) forces on the 3 corners of one triangle, and W.

        ``pex``: a pressure inside the shell (DPD pressure, e.g. the quasi-static tier's ideal gas minus
        the ambient one) acting as -pex dV/dx, added here because dV/dx is this triangle's normal / 6.
        """
        x0 = x[idx[0]]
        x12 = x[idx[1]] - x0
        x13 = x[idx[2]] - x0
        n = wp.cross(x12, x13)
        nn = wp.length(n)
        half = T(0.5)
        area_raw = half * nn
        area = wp.max(area_raw, clamp_a)
        l1sq = rf[0]
        l2sq = rf[1]
        d0 = rf[2]
        a0 = rf[3]
        ka = params[r, P_KA]
        mu = params[r, P_MU]
        a3 = params[r, P_A3]
        a4 = params[r, P_A4]
        b1 = params[r, P_B1]
        b2 = params[r, P_B2]
        one = T(1.0)
        two = T(2.0)
        alpha = area / a0 - one
        num = l1sq * wp.dot(x13, x13) + l2sq * wp.dot(x12, x12) - two * d0 * wp.dot(x12, x13)
        inv8 = one / (T(8.0) * a0 * area)
        beta = num * inv8 - one
        alpha2 = alpha * alpha
        dw_da = a0 * (half * ka * (two * alpha + T(3.0) * a3 * alpha2 + T(4.0) * a4 * alpha2 * alpha)
                      + mu * b1 * beta)
        dw_db = a0 * mu * (one + b1 * alpha + two * b2 * beta)
        # coefficient of dA/dx in the total derivative: dW/dalpha / A0 - dW/dbeta (beta+1)/A
        coef_a = dw_da / a0 - dw_db * (beta + one) / area
        if area_raw <= clamp_a:
            coef_a = T(0.0)
        # global constraints and back pressure (per replica)
        coef_v = T(0.0)
        if use_global != 0:
            a_tot = avr[r, 0]
            v_tot = avr[r, 1]
            a0t = params[r, P_A0TOT]
            v0t = params[r, P_V0]
            coef_a = coef_a + params[r, P_KATOT] * (a_tot - a0t) / a0t
            coef_v = params[r, P_KVTOT] * (v_tot - v0t) / v0t - params[r, P_PB]
        coef_v = coef_v - pex
        nhat = n / wp.max(nn, T(1.0e-30))
        x23 = x13 - x12
        ga0 = half * wp.cross(nhat, x23)
        ga1 = -half * wp.cross(nhat, x13)
        ga2 = half * wp.cross(nhat, x12)
        gn1 = two * l2sq * x12 - two * d0 * x13
        gn2 = two * l1sq * x13 - two * d0 * x12
        cb = dw_db * inv8
        cv = coef_v / T(6.0)
        f1 = -(coef_a * ga1 + cb * gn1 + cv * n)
        f2 = -(coef_a * ga2 + cb * gn2 + cv * n)
        f0 = -(coef_a * ga0 - cb * (gn1 + gn2) + cv * n)
        w = a0 * (half * ka * (alpha2 + a3 * alpha2 * alpha + a4 * alpha2 * alpha2)
                  + mu * (beta + b1 * alpha * beta + b2 * beta * beta))
        return f0, f1, f2, w

    @kern
    def lim_kernel(x: wp.array(dtype=V), f: wp.array(dtype=V), tri: wp.array(dtype=wp.vec3i),
                   ref: wp.array(dtype=V4), tri_rep: wp.array(dtype=wp.int32),
                   params: wp.array2d(dtype=T), avr: wp.array2d(dtype=T), use_global: wp.int32,
                   energy: wp.array2d(dtype=T), want_energy: wp.int32, skip: wp.array(dtype=wp.int32),
                   gas: wp.array2d(dtype=T), gvol: wp.array(dtype=T), gas_on: wp.int32):
        t = wp.tid()
        r = tri_rep[t]
        if skip[r] != 0:
            return
        idx = tri[t]
        f0, f1, f2, w = lim_triangle(x, idx, ref[t], params, r, avr, use_global, gas_pressure(gas, gvol, gas_on, r))
        wp.atomic_add(f, idx[0], f0)
        wp.atomic_add(f, idx[1], f1)
        wp.atomic_add(f, idx[2], f2)
        if want_energy != 0:
            wp.atomic_add(energy, r, E_LIM, w)

    return {"lim_triangle": lim_triangle, "lim_kernel": lim_kernel}
