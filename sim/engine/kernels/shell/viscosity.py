"""Bond viscosity of the shell: a dissipative force along every edge (off unless ``bond_viscosity`` > 0).

F_a = eta ((v_b - v_a) . e) e on vertex a and the opposite on b, e the unit edge vector; eta in DPD mass / time,
velocities in DPD velocity units.
"""

# (no "from __future__ import annotations": Warp must see the closure types of the kernel signatures)

import functools

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.common import kernel_decorator
from bubblecal.sim.engine.kernels.shell.layout import P_ETA

wp = require("warp", "sim")

__all__ = ["viscosity_kernels"]


@functools.cache
def viscosity_kernels(dtype) -> dict:
    """Build (once per scalar type) the bond-viscosity kernel; ``dtype`` is ``wp.float32`` or ``wp.float64``.
    Returns a dict: ``"bond_viscosity_kernel"`` (one thread per edge, atomics into its two vertices).
    """
    T = dtype
    V = wp.vec3d if T is wp.float64 else wp.vec3f
    kern = kernel_decorator(dtype, "shell")

    @kern
    def bond_viscosity_kernel(x: wp.array(dtype=V), v: wp.array(dtype=V), f: wp.array(dtype=V),
                              dih: wp.array(dtype=wp.vec4i), edge_rep: wp.array(dtype=wp.int32),
                              params: wp.array2d(dtype=T)):
        e = wp.tid()
        r = edge_rep[e]
        eta = params[r, P_ETA]
        if eta == T(0.0):
            return
        q = dih[e]
        d = x[q[1]] - x[q[0]]
        eh = d / wp.length(d)
        fa = (eta * wp.dot(v[q[1]] - v[q[0]], eh)) * eh
        wp.atomic_add(f, q[0], fa)
        wp.atomic_sub(f, q[1], fa)

    return {"bond_viscosity_kernel": bond_viscosity_kernel}
