"""Global area / volume constraints and the inside pressure of the shell (docs/physics.md section 3).

U_A = ka_tot (A - A0)^2 / (2 A0), U_V = kv_tot (V - V0)^2 / (2 V0) and the back pressure p_b act on every
vertex through dA/dx and dV/dx, which the Lim triangle pass (:mod:`bubblecal.sim.engine.kernels.shell.lim`)
already computes: this module supplies the per-replica totals A, V (one pass over the triangles) and the
optional inside gas pressure (DPD pressure) bound by :meth:`ShellForceField.set_gas`.
"""

# (no "from __future__ import annotations": Warp must see the closure types of the kernel signatures)

import functools

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.common import kernel_decorator

wp = require("warp", "sim")

__all__ = ["constraint_kernels"]


@functools.cache
def constraint_kernels(dtype) -> dict:
    """Build (once per scalar type) the area / volume kernel and the gas-pressure function; ``dtype`` is
    ``wp.float32`` or ``wp.float64``. Returns a dict: ``"area_volume_kernel"`` (one thread per triangle: ``avr[r]
    += (A_t, V_t)``, DPD length^2 and length^3, volumes relative to the replica's first vertex) and
    ``"gas_pressure"`` (Warp function: p0 V0 / V - p_ambient of replica r, or 0 when no gas is bound).
    """
    T = dtype
    V = wp.vec3d if T is wp.float64 else wp.vec3f
    kern = kernel_decorator(dtype, "shell")

    @wp.func
    def gas_pressure(gas: wp.array2d(dtype=T), gvol: wp.array(dtype=T), gas_on: wp.int32, r: wp.int32):
        """Inside pressure of replica r: p0 V0 / V - p_ambient (``gas[r] = (p0 V0, p_ambient)``), or 0."""
        p = T(0.0)
        if gas_on != 0:
            p = gas[r, 0] / gvol[r] - gas[r, 1]
        return p

    @kern
    def area_volume_kernel(x: wp.array(dtype=V), tri: wp.array(dtype=wp.vec3i), tri_rep: wp.array(dtype=wp.int32),
                           goff: wp.array(dtype=wp.int32), avr: wp.array2d(dtype=T)):
        t = wp.tid()
        r = tri_rep[t]
        idx = tri[t]
        c = x[goff[r]]
        x0 = x[idx[0]] - c
        x1 = x[idx[1]] - c
        x2 = x[idx[2]] - c
        wp.atomic_add(avr, r, 0, T(0.5) * wp.length(wp.cross(x1 - x0, x2 - x0)))
        wp.atomic_add(avr, r, 1, wp.dot(x0, wp.cross(x1, x2)) / T(6.0))

    return {"gas_pressure": gas_pressure, "area_volume_kernel": area_volume_kernel}
