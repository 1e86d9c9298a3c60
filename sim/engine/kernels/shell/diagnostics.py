"""Shell health indicators per replica: triangle area strain and dihedral-angle change.

Read by :meth:`ShellForceField.health`; thresholds are the caller's (e.g. the implicit system's health check).
"""

# (no "from __future__ import annotations": Warp must see the closure types of the kernel signatures)

import functools

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.common import kernel_decorator
from bubblecal.sim.engine.kernels.shell.geometry import geometry_funcs

wp = require("warp", "sim")

__all__ = ["diagnostic_kernels"]


@functools.cache
def diagnostic_kernels(dtype) -> dict:
    """Build (once per scalar type) the health kernels; ``dtype`` is ``wp.float32`` or ``wp.float64``. Returns a
    dict: ``"health_tris"`` (``out[r, 0]`` max |A/A0 - 1|, ``out[r, 1]`` min A/A0) and ``"health_edges"``
    (``out[r, 2]`` max |theta - theta0| in radians, wrapped to [0, pi]).
    """
    T = dtype
    V = wp.vec3d if T is wp.float64 else wp.vec3f
    V4 = wp.vec4d if T is wp.float64 else wp.vec4f
    kern = kernel_decorator(dtype, "shell")
    dihedral = geometry_funcs(dtype)["dihedral"]

    @kern
    def health_tris(x: wp.array(dtype=V), tri: wp.array(dtype=wp.vec3i), ref: wp.array(dtype=V4),
                    tri_rep: wp.array(dtype=wp.int32), out: wp.array2d(dtype=T)):
        t = wp.tid()
        r = tri_rep[t]
        idx = tri[t]
        x0 = x[idx[0]]
        ratio = T(0.5) * wp.length(wp.cross(x[idx[1]] - x0, x[idx[2]] - x0)) / ref[t][3]
        wp.atomic_max(out, r, 0, wp.abs(ratio - T(1.0)))
        wp.atomic_min(out, r, 1, ratio)

    @kern
    def health_edges(x: wp.array(dtype=V), dih: wp.array(dtype=wp.vec4i), theta0: wp.array(dtype=T),
                     edge_rep: wp.array(dtype=wp.int32), out: wp.array2d(dtype=T)):
        e = wp.tid()
        q = dih[e]
        theta, ga, gb, gc, gd = dihedral(x[q[0]], x[q[1]], x[q[2]], x[q[3]])
        d = theta - theta0[e]
        # wrap to (-pi, pi]
        if d > T(3.141592653589793):
            d = d - T(6.283185307179586)
        if d < T(-3.141592653589793):
            d = d + T(6.283185307179586)
        wp.atomic_max(out, edge_rep[e], 2, wp.abs(d))

    return {"health_tris": health_tris, "health_edges": health_edges}
