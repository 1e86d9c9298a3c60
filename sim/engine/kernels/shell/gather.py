"""Per-vertex gather of the Lim and Kantor forces: one thread per shell vertex, no atomics.

Each vertex walks its incident triangles and dihedrals (CSR lists built by
:mod:`bubblecal.sim.engine.kernels.shell.topology`) and sums its own share of every element's force, so each
element is evaluated once per vertex it touches; the result is written once per vertex.  The forces are the
same as those of the scatter kernels of :mod:`~bubblecal.sim.engine.kernels.shell.lim` and
:mod:`~bubblecal.sim.engine.kernels.shell.bending` (DPD force units); which mode is faster depends on the
device (docs/decisions.md).
"""

# (no "from __future__ import annotations": Warp must see the closure types of the kernel signatures)

import functools

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.common import kernel_decorator
from bubblecal.sim.engine.kernels.shell.bending import bending_kernels
from bubblecal.sim.engine.kernels.shell.constraints import constraint_kernels
from bubblecal.sim.engine.kernels.shell.layout import P_KB_KANTOR
from bubblecal.sim.engine.kernels.shell.lim import lim_kernels

wp = require("warp", "sim")

__all__ = ["gather_kernels"]


@functools.cache
def gather_kernels(dtype) -> dict:
    """Build (once per scalar type) the per-vertex Lim + Kantor gather kernel; ``dtype`` is ``wp.float32`` or
    ``wp.float64``. Returns a dict: ``"vertex_gather_kernel"``.
    """
    T = dtype
    V = wp.vec3d if T is wp.float64 else wp.vec3f
    V4 = wp.vec4d if T is wp.float64 else wp.vec4f
    V2 = wp.vec2d if T is wp.float64 else wp.vec2f
    kern = kernel_decorator(dtype, "shell")
    lim_triangle = lim_kernels(dtype)["lim_triangle"]
    gas_pressure = constraint_kernels(dtype)["gas_pressure"]
    kantor_edge = bending_kernels(dtype)["kantor_edge"]

    @kern
    def vertex_gather_kernel(x: wp.array(dtype=V), f: wp.array(dtype=V), gidx: wp.array(dtype=wp.int32),
                             vrep: wp.array(dtype=wp.int32), tri: wp.array(dtype=wp.vec3i),
                             ref: wp.array(dtype=V4), tri_start: wp.array(dtype=wp.int32),
                             tri_slot: wp.array(dtype=wp.int32), dih: wp.array(dtype=wp.vec4i),
                             cs0: wp.array(dtype=V2), dih_start: wp.array(dtype=wp.int32),
                             dih_slot: wp.array(dtype=wp.int32), params: wp.array2d(dtype=T),
                             avr: wp.array2d(dtype=T), use_global: wp.int32, do_kantor: wp.int32,
                             skip: wp.array(dtype=wp.int32), gas: wp.array2d(dtype=T), gvol: wp.array(dtype=T),
                             gas_on: wp.int32):
        """Lim (+ constraints, inside gas) and Kantor forces gathered per vertex: no atomics, one write per vertex.

        ``tri_slot`` / ``dih_slot`` encode (element id) * 4 + (the vertex's corner / role).
        """
        s = wp.tid()
        r = vrep[s]
        if skip[r] != 0:
            return
        pex = gas_pressure(gas, gvol, gas_on, r)
        fi = V()
        for k in range(tri_start[s], tri_start[s + 1]):
            code = tri_slot[k]
            t = code >> 2
            corner = code & 3
            f0, f1, f2, w = lim_triangle(x, tri[t], ref[t], params, r, avr, use_global, pex)
            if corner == 0:
                fi = fi + f0
            elif corner == 1:
                fi = fi + f1
            else:
                fi = fi + f2
        kb = params[r, P_KB_KANTOR]
        if do_kantor != 0 and kb != T(0.0):
            for k in range(dih_start[s], dih_start[s + 1]):
                code = dih_slot[k]
                e = code >> 2
                role = code & 3
                q = dih[e]
                sdt, cdt, ga, gb, gc, gd = kantor_edge(x[q[0]], x[q[1]], x[q[2]], x[q[3]], cs0[e])
                coef = -kb * sdt
                if role == 0:
                    fi = fi + coef * ga
                elif role == 1:
                    fi = fi + coef * gb
                elif role == 2:
                    fi = fi + coef * gc
                else:
                    fi = fi + coef * gd
        g = gidx[s]
        f[g] = f[g] + fi

    return {"vertex_gather_kernel": vertex_gather_kernel}
