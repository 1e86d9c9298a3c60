"""Bending forces (docs/physics.md section 3): stress-free Kantor dihedral and Juelicher mean-curvature energies.

* Kantor: E = kb sum_e [1 - cos(theta_e - theta0_e)], one thread per edge (dihedral); theta0 is the reference
  angle, passed as (cos theta0, sin theta0).
* Juelicher: E = 2 kb sum_v A_v (H_v - c0/2)^2 with H_v = sum_e l_e theta_e / (4 A_v) and the barycentric vertex
  area A_v: an edge pass (sum l_e theta_e per vertex), a triangle pass (A_v), then an edge and a triangle
  force pass (and a vertex pass for the energy).

kb in DPD energy (k_BT), c0 in 1 / DPD length; forces in DPD force units.
"""

# (no "from __future__ import annotations": Warp must see the closure types of the kernel signatures)

import functools

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.common import kernel_decorator
from bubblecal.sim.engine.kernels.shell.geometry import geometry_funcs
from bubblecal.sim.engine.kernels.shell.layout import E_BEND, P_C0, P_KB_JUL, P_KB_KANTOR

wp = require("warp", "sim")

__all__ = ["bending_kernels"]


@functools.cache
def bending_kernels(dtype) -> dict:
    """Build (once per scalar type) the Kantor and Juelicher bending kernels; ``dtype`` is ``wp.float32`` or
    ``wp.float64``. Returns a dict: ``"kantor_edge"`` (Warp function: sin / cos (theta - theta0) and the
    gradients of theta of one edge), ``"kantor_kernel"``, and the Juelicher passes ``"jul_accum_edges"``,
    ``"tri_accum_vertex_area"``, ``"jul_force_edges"``, ``"jul_force_tris"``, ``"jul_energy"``.
    """
    T = dtype
    V = wp.vec3d if T is wp.float64 else wp.vec3f
    V2 = wp.vec2d if T is wp.float64 else wp.vec2f
    kern = kernel_decorator(dtype, "shell")
    geo = geometry_funcs(dtype)
    dihedral_terms = geo["dihedral_terms"]
    dihedral = geo["dihedral"]

    @wp.func
    def kantor_edge(xa: V, xb: V, xc: V, xd: V, cs0: V2):
        """sin(theta - theta0), cos(theta - theta0) and the gradients of theta (a, b, c, d) of one edge.

        ``cs0 = (cos theta0, sin theta0)``.  Same theta as ``dihedral`` without atan2 / sin / cos:
        (sin, cos) theta come from the two normals directly (docs/decisions.md).
        """
        ys, xs, ga, gb, gc, gd = dihedral_terms(xa, xb, xc, xd)
        h = wp.sqrt(ys * ys + xs * xs)
        st = T(0.0)
        ct = T(1.0)  # atan2(0, 0) = 0
        if h > T(0.0):
            st = ys / h
            ct = xs / h
        return st * cs0[0] - ct * cs0[1], ct * cs0[0] + st * cs0[1], ga, gb, gc, gd

    @kern
    def kantor_kernel(x: wp.array(dtype=V), f: wp.array(dtype=V), dih: wp.array(dtype=wp.vec4i),
                      cs0: wp.array(dtype=V2), edge_rep: wp.array(dtype=wp.int32),
                      params: wp.array2d(dtype=T), energy: wp.array2d(dtype=T), want_energy: wp.int32,
                      skip: wp.array(dtype=wp.int32)):
        e = wp.tid()
        r = edge_rep[e]
        kb = params[r, P_KB_KANTOR]
        if kb == T(0.0) or skip[r] != 0:
            return
        q = dih[e]
        sd, cd, ga, gb, gc, gd = kantor_edge(x[q[0]], x[q[1]], x[q[2]], x[q[3]], cs0[e])
        coef = -kb * sd
        wp.atomic_add(f, q[0], coef * ga)
        wp.atomic_add(f, q[1], coef * gb)
        wp.atomic_add(f, q[2], coef * gc)
        wp.atomic_add(f, q[3], coef * gd)
        if want_energy != 0:
            wp.atomic_add(energy, r, E_BEND, kb * (T(1.0) - cd))

    @kern
    def jul_accum_edges(x: wp.array(dtype=V), dih: wp.array(dtype=wp.vec4i), edge_rep: wp.array(dtype=wp.int32),
                        goff: wp.array(dtype=wp.int32), coff: wp.array(dtype=wp.int32),
                        params: wp.array2d(dtype=T), msum: wp.array(dtype=T)):
        e = wp.tid()
        r = edge_rep[e]
        if params[r, P_KB_JUL] == T(0.0):
            return
        q = dih[e]
        theta, ga, gb, gc, gd = dihedral(x[q[0]], x[q[1]], x[q[2]], x[q[3]])
        lt = wp.length(x[q[1]] - x[q[0]]) * theta
        sh = coff[r] - goff[r]
        wp.atomic_add(msum, q[0] + sh, lt)
        wp.atomic_add(msum, q[1] + sh, lt)

    @kern
    def tri_accum_vertex_area(x: wp.array(dtype=V), tri: wp.array(dtype=wp.vec3i), tri_rep: wp.array(dtype=wp.int32),
                              goff: wp.array(dtype=wp.int32), coff: wp.array(dtype=wp.int32),
                              params: wp.array2d(dtype=T), avert: wp.array(dtype=T)):
        t = wp.tid()
        r = tri_rep[t]
        if params[r, P_KB_JUL] == T(0.0):
            return
        idx = tri[t]
        x0 = x[idx[0]]
        a3 = wp.length(wp.cross(x[idx[1]] - x0, x[idx[2]] - x0)) / T(6.0)
        sh = coff[r] - goff[r]
        wp.atomic_add(avert, idx[0] + sh, a3)
        wp.atomic_add(avert, idx[1] + sh, a3)
        wp.atomic_add(avert, idx[2] + sh, a3)

    @wp.func
    def jul_coefs(m: T, av: T, kb: T, c0: T):
        h = m / (T(4.0) * av)
        hc = h - T(0.5) * c0
        return kb * hc, T(2.0) * kb * (T(0.25) * c0 * c0 - h * h), T(2.0) * kb * av * hc * hc

    @kern
    def jul_force_edges(x: wp.array(dtype=V), f: wp.array(dtype=V), dih: wp.array(dtype=wp.vec4i),
                        edge_rep: wp.array(dtype=wp.int32), goff: wp.array(dtype=wp.int32),
                        coff: wp.array(dtype=wp.int32), params: wp.array2d(dtype=T),
                        msum: wp.array(dtype=T), avert: wp.array(dtype=T)):
        e = wp.tid()
        r = edge_rep[e]
        kb = params[r, P_KB_JUL]
        if kb == T(0.0):
            return
        c0 = params[r, P_C0]
        q = dih[e]
        sh = coff[r] - goff[r]
        cm_a, ca_a, en_a = jul_coefs(msum[q[0] + sh], avert[q[0] + sh], kb, c0)
        cm_b, ca_b, en_b = jul_coefs(msum[q[1] + sh], avert[q[1] + sh], kb, c0)
        ce = cm_a + cm_b
        xa = x[q[0]]
        xb = x[q[1]]
        theta, ga, gb, gc, gd = dihedral(xa, xb, x[q[2]], x[q[3]])
        ev = xb - xa
        le = wp.length(ev)
        eh = ev / le
        wp.atomic_add(f, q[0], -ce * (le * ga - theta * eh))
        wp.atomic_add(f, q[1], -ce * (le * gb + theta * eh))
        wp.atomic_add(f, q[2], -ce * le * gc)
        wp.atomic_add(f, q[3], -ce * le * gd)

    @kern
    def jul_force_tris(x: wp.array(dtype=V), f: wp.array(dtype=V), tri: wp.array(dtype=wp.vec3i),
                       tri_rep: wp.array(dtype=wp.int32), goff: wp.array(dtype=wp.int32),
                       coff: wp.array(dtype=wp.int32), params: wp.array2d(dtype=T),
                       msum: wp.array(dtype=T), avert: wp.array(dtype=T)):
        t = wp.tid()
        r = tri_rep[t]
        kb = params[r, P_KB_JUL]
        if kb == T(0.0):
            return
        c0 = params[r, P_C0]
        idx = tri[t]
        sh = coff[r] - goff[r]
        cm0, ca0, en0 = jul_coefs(msum[idx[0] + sh], avert[idx[0] + sh], kb, c0)
        cm1, ca1, en1 = jul_coefs(msum[idx[1] + sh], avert[idx[1] + sh], kb, c0)
        cm2, ca2, en2 = jul_coefs(msum[idx[2] + sh], avert[idx[2] + sh], kb, c0)
        ct = (ca0 + ca1 + ca2) / T(3.0)
        x0 = x[idx[0]]
        x1 = x[idx[1]]
        x2 = x[idx[2]]
        n = wp.cross(x1 - x0, x2 - x0)
        nhat = n / wp.max(wp.length(n), T(1.0e-30))
        half = T(0.5)
        wp.atomic_add(f, idx[0], -ct * half * wp.cross(nhat, x2 - x1))
        wp.atomic_add(f, idx[1], -ct * half * wp.cross(nhat, x0 - x2))
        wp.atomic_add(f, idx[2], -ct * half * wp.cross(nhat, x1 - x0))

    @kern
    def jul_energy(vrep: wp.array(dtype=wp.int32), params: wp.array2d(dtype=T), msum: wp.array(dtype=T),
                   avert: wp.array(dtype=T), energy: wp.array2d(dtype=T)):
        s = wp.tid()
        r = vrep[s]
        kb = params[r, P_KB_JUL]
        if kb == T(0.0):
            return
        cm, ca, en = jul_coefs(msum[s], avert[s], kb, params[r, P_C0])
        wp.atomic_add(energy, r, E_BEND, en)

    return {"kantor_edge": kantor_edge, "kantor_kernel": kantor_kernel, "jul_accum_edges": jul_accum_edges,
            "tri_accum_vertex_area": tri_accum_vertex_area, "jul_force_edges": jul_force_edges,
            "jul_force_tris": jul_force_tris, "jul_energy": jul_energy}
