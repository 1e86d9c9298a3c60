"""Warp kernels of the shell (membrane) forces, batched over replicas (physics.md section 3).

:class:`ShellForceField` holds R replicas' meshes, stress-free references and parameters on one
device and adds their forces into the global particle force array in a handful of launches:

* Lim in-plane forces + global area/volume constraints + back pressure: one thread per triangle,
  atomics into the three vertices (closed-form -grad W, area clamped at 1e-6);
* Kantor bending (stress-free, theta0 of the reference): one thread per edge (dihedral);
* Juelicher bending (option): edge pass (sum l_e theta_e), triangle pass (barycentric A_v), then an
  edge and a triangle force pass;
* self-avoidance: WCA Lennard-Jones between the vertices of one shell through a ``wp.HashGrid``
  built on the gathered shell vertices;
* bond viscosity (option): one thread per edge.

Geometry conventions: :mod:`bubblecal.sim.engine.mesh`; the float64 NumPy ground truth is
:mod:`bubblecal.sim.validation.shell_reference`.  Replica r's N_v,r vertices live at rows
``[offset_r, offset_r + N_v,r)`` of the global particle arrays.  Shell vertex coordinates must be
*unwrapped* (no periodic images inside one shell).  Every launch reuses buffers allocated at
construction; nothing is allocated per step (except Warp's own HashGrid reservation on first build).

Kernels come in one set per scalar type (``wp.float32`` for CUDA, ``wp.float64`` selectable for CPU
checks and also usable on CUDA), built by :func:`_kernels` and cached.

Measured on one H100 (float32, R = 6 icosphere s4 = 2,562 vertices per replica, CUDA graph replay,
Lim + Kantor + self-avoidance at the published set-up): 64 replicas 212 us per force evaluation
(per-vertex Lim+Kantor gather 77 us, self-avoidance query 63 us, position gather 7 us, HashGrid
build ~65 us); without self-avoidance 68 us (gather) vs 103 us (scatter: Lim 43 + Kantor 66 us);
256 replicas 551 us (216 us without self-avoidance); one replica 73 us (latency bound).
"""

# (no "from __future__ import annotations": Warp must see the closure types of the kernel signatures)

import functools
import math
from collections.abc import Sequence

import numpy as np
import warp as wp

from bubblecal.sim.engine.kernels.shell_params import BENDING_MODELS, FORCE_MODES, ShellParams
from bubblecal.sim.engine.mesh import ShellMesh

__all__ = ["ShellParams", "ShellForceField", "ENERGY_TERMS", "BENDING_MODELS", "AREA_CLAMP"]

#: Columns of :meth:`ShellForceField.energies` (same order as ``shell_reference.ENERGY_TERMS``).
ENERGY_TERMS = ("in_plane", "bending", "area", "volume", "back_pressure", "self_avoid")
AREA_CLAMP = 1e-6

# parameter columns of the per-replica parameter table
P_KA, P_MU, P_A3, P_A4, P_B1, P_B2 = 0, 1, 2, 3, 4, 5
P_KB_KANTOR, P_KB_JUL, P_C0 = 6, 7, 8
P_KATOT, P_KVTOT, P_PB, P_A0TOT, P_V0 = 9, 10, 11, 12, 13
P_SA_EPS, P_SA_RC, P_ETA = 14, 15, 16
N_PARAMS = 17

# energy columns
E_LIM, E_BEND, E_AREA, E_VOL, E_PB, E_SA = range(6)


@functools.cache
def _kernels(dtype):
    """Build (once per scalar type) the shell kernels; returns a dict name -> kernel."""
    T = dtype
    V = wp.vec3d if T is wp.float64 else wp.vec3f
    V4 = wp.vec4d if T is wp.float64 else wp.vec4f
    V2 = wp.vec2d if T is wp.float64 else wp.vec2f
    module = f"bubblecal_shell_{'f64' if T is wp.float64 else 'f32'}"
    kern = functools.partial(wp.kernel, enable_backward=False, module=module)
    clamp_a = T(AREA_CLAMP)

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

    @wp.func
    def gas_pressure(gas: wp.array2d(dtype=T), gvol: wp.array(dtype=T), gas_on: wp.int32, r: wp.int32):
        """Inside pressure of replica r: p0 V0 / V - p_ambient (``gas[r] = (p0 V0, p_ambient)``), or 0."""
        p = T(0.0)
        if gas_on != 0:
            p = gas[r, 0] / gvol[r] - gas[r, 1]
        return p

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

    @wp.func
    def dihedral_terms(xa: V, xb: V, xc: V, xd: V):
        """(y, x) with theta = atan2(y, x), and the gradients of theta with respect to a, b, c, d (mesh.py
        convention): y = ((n1 x n2) . e) / |e|, x = n1 . n2, so sin / cos theta need no atan2."""
        e = xb - xa
        n1 = wp.cross(e, xc - xa)
        n2 = wp.cross(xd - xb, e)
        el2 = wp.dot(e, e)
        el = wp.sqrt(el2)
        n1sq = wp.max(wp.dot(n1, n1), T(1.0e-30))
        n2sq = wp.max(wp.dot(n2, n2), T(1.0e-30))
        ys = wp.dot(wp.cross(n1, n2), e) / el
        xs = wp.dot(n1, n2)
        gc = -(el / n1sq) * n1
        gd = -(el / n2sq) * n2
        sc = wp.dot(xc - xa, e) / el2
        sd = wp.dot(xd - xa, e) / el2
        one = T(1.0)
        ga = -(one - sc) * gc - (one - sd) * gd
        gb = -sc * gc - sd * gd
        return ys, xs, ga, gb, gc, gd

    @wp.func
    def dihedral(xa: V, xb: V, xc: V, xd: V):
        """theta and its gradients with respect to a, b, c, d (mesh.py convention)."""
        ys, xs, ga, gb, gc, gd = dihedral_terms(xa, xb, xc, xd)
        return wp.atan2(ys, xs), ga, gb, gc, gd

    @wp.func
    def kantor_edge(xa: V, xb: V, xc: V, xd: V, cs0: V2):
        """sin(theta - theta0), cos(theta - theta0) and the gradients of theta (a, b, c, d) of one edge.

        ``cs0 = (cos theta0, sin theta0)``.  Same theta as :func:`dihedral` without atan2 / sin / cos:
        (sin, cos) theta come from the two normals directly (the transcendental functions were most of
        the gather kernel's float64 time on the CPU).
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

    @kern
    def gather_kernel(x: wp.array(dtype=V), gidx: wp.array(dtype=wp.int32), vrep: wp.array(dtype=wp.int32),
                      anchor: wp.array(dtype=wp.vec2i), slot: wp.array(dtype=wp.vec3), xs: wp.array(dtype=wp.vec3)):
        # shell vertices relative to their replica's centre (midpoint of an antipodal vertex pair,
        # exact under rigid motions), moved to the replica's own slot of the search grid
        s = wp.tid()
        r = vrep[s]
        ab = anchor[r]
        c = T(0.5) * (x[ab[0]] + x[ab[1]])
        xs[s] = wp.vec3(x[gidx[s]] - c) + slot[r]

    @kern
    def self_avoid_kernel(grid: wp.uint64, xs: wp.array(dtype=wp.vec3), x: wp.array(dtype=V),
                          f: wp.array(dtype=V), gidx: wp.array(dtype=wp.int32), vrep: wp.array(dtype=wp.int32),
                          params: wp.array2d(dtype=T), query_radius: float, energy: wp.array2d(dtype=T),
                          want_energy: wp.int32, skip: wp.array(dtype=wp.int32)):
        s = wp.tid()
        r = vrep[s]
        eps = params[r, P_SA_EPS]
        if eps == T(0.0) or skip[r] != 0:
            return
        rc = params[r, P_SA_RC]
        rc2 = rc * rc
        sig6 = rc2 * rc2 * rc2 / T(2.0)
        gi = gidx[s]
        xi = x[gi]
        fi = V()
        en = T(0.0)
        neighbors = wp.hash_grid_query(grid, xs[s], query_radius)
        for j in neighbors:
            if j != s and vrep[j] == r:
                d = xi - x[gidx[j]]
                r2 = wp.dot(d, d)
                if r2 < rc2:
                    s6 = sig6 / (r2 * r2 * r2)
                    fi = fi + (T(24.0) * eps * (T(2.0) * s6 * s6 - s6) / r2) * d
                    en = en + T(0.5) * (T(4.0) * eps * (s6 * s6 - s6) + eps)
        f[gi] = f[gi] + fi
        if want_energy != 0:
            wp.atomic_add(energy, r, E_SA, en)

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

    return {k: v for k, v in locals().items() if isinstance(v, wp.Kernel)}


def _as_list(obj, n: int | None, what: str) -> list:
    if isinstance(obj, (list, tuple)):
        return list(obj)
    if n is None:
        raise ValueError(f"{what}: give a list")
    return [obj] * n


class ShellForceField:
    """Shell forces of R replicas batched into the same launches.

    Args:
        meshes_or_mesh: one :class:`ShellMesh` for all replicas, or a list of R meshes (its
            vertices are the stress-free reference of that replica).
        params_per_replica: list of R :class:`ShellParams` (or one, used for every mesh).
        device: Warp device (``"cpu"``, ``"cuda"``, ``"cuda:0"``).
        dtype: ``wp.float32`` (GPU default) or ``wp.float64`` (CPU checks); the particle arrays
            passed in must be ``wp.array(dtype=wp.vec3f)`` (float32) or ``wp.array(dtype=wp.vec3d)`` (float64).
        offsets: first particle row of each replica's vertices (default: packed from row 0).
        force_mode: ``"gather"`` (Lim and Kantor forces summed per vertex by one thread, no
            atomics; each element is evaluated by each of its vertices: 1.5-1.7x faster on an
            H100), ``"scatter"`` (one thread per triangle / edge with atomics: 3x faster on CPU)
            or ``"auto"`` (default: gather on CUDA, scatter on CPU).  Energies always use scatter.

    Methods add forces (``accumulate_forces``), report energies per replica and term
    (``energies``, columns :data:`ENERGY_TERMS`), total areas / volumes (``areas_volumes``) and
    per-replica health indicators (``health``: area strain, dihedral change).
    """

    def __init__(self, meshes_or_mesh: ShellMesh | Sequence[ShellMesh],
                 params_per_replica: ShellParams | Sequence[ShellParams], device: str | None = "cpu",
                 dtype=wp.float32, offsets: Sequence[int] | None = None, force_mode: str = "auto"):
        if force_mode not in FORCE_MODES:
            raise ValueError(f"force_mode must be one of {FORCE_MODES}, got {force_mode!r}")
        if dtype not in (wp.float32, wp.float64):
            raise ValueError(f"dtype must be wp.float32 or wp.float64, got {dtype!r}")
        n_rep = len(params_per_replica) if isinstance(params_per_replica, (list, tuple)) else (
            len(meshes_or_mesh) if isinstance(meshes_or_mesh, (list, tuple)) else 1)
        self.meshes: list[ShellMesh] = _as_list(meshes_or_mesh, n_rep, "meshes")
        self.params: list[ShellParams] = _as_list(params_per_replica, n_rep, "params_per_replica")
        if len(self.meshes) != len(self.params):
            raise ValueError(f"{len(self.meshes)} meshes but {len(self.params)} parameter sets")
        for p in self.params:
            if not isinstance(p, ShellParams):
                raise TypeError(f"params_per_replica must hold ShellParams, got {type(p).__name__}")
        self.n_replicas = R = len(self.meshes)
        if R == 0:
            raise ValueError("no replicas")
        nv = np.array([m.n_vertices for m in self.meshes], dtype=np.int64)
        if offsets is None:
            offsets = np.concatenate([[0], np.cumsum(nv)[:-1]])
        offsets = np.asarray(offsets, dtype=np.int64)
        if offsets.shape != (R,) or np.any(offsets < 0):
            raise ValueError("offsets must hold one non-negative row per replica")
        order = np.argsort(offsets)
        if np.any(offsets[order][1:] < (offsets + nv)[order][:-1]):
            raise ValueError("replica vertex ranges overlap")
        self.offsets = offsets
        self.n_vertices = nv
        self.n_rows_min = int(np.max(offsets + nv))
        self.dtype = dtype
        self.vec3 = wp.vec3d if dtype is wp.float64 else wp.vec3f
        self.device = wp.get_device(device)
        if force_mode == "auto":
            force_mode = "gather" if self.device.is_cuda else "scatter"
        self.force_mode = force_mode
        self._k = _kernels(dtype)
        npf = np.float64

        # ----- topology, packed over replicas (global particle rows) -----
        coff = np.concatenate([[0], np.cumsum(nv)[:-1]])
        tri = np.concatenate([m.faces.astype(np.int64) + o for m, o in zip(self.meshes, offsets, strict=True)])
        dih = np.concatenate([m.dihedrals.astype(np.int64) + o for m, o in zip(self.meshes, offsets, strict=True)])
        tri_rep = np.concatenate([np.full(m.n_faces, r) for r, m in enumerate(self.meshes)])
        edge_rep = np.concatenate([np.full(m.n_edges, r) for r, m in enumerate(self.meshes)])
        vrep = np.concatenate([np.full(m.n_vertices, r) for r, m in enumerate(self.meshes)])
        gidx = np.concatenate([np.arange(n) + o for n, o in zip(nv, offsets, strict=True)])
        ref = np.concatenate([np.stack([m.l1**2, m.l2**2, m.d0, m.A0], axis=1) for m in self.meshes])
        theta0 = np.concatenate([m.theta0 for m in self.meshes])

        self.area0 = np.array([m.area() for m in self.meshes])
        self.volume0 = np.array([m.volume() for m in self.meshes])
        table = np.stack([self._param_row(r, p) for r, p in enumerate(self.params)]).astype(npf)
        self.param_table = table
        self.use_kantor = bool(np.any(table[:, P_KB_KANTOR] != 0))
        self.use_juelicher = bool(np.any(table[:, P_KB_JUL] != 0))
        self.use_global = bool(np.any(table[:, [P_KATOT, P_KVTOT, P_PB]] != 0))
        self.use_constraints_av = bool(np.any(table[:, [P_KATOT, P_KVTOT]] != 0))
        self.use_self_avoid = bool(np.any(table[:, P_SA_EPS] != 0))
        self.use_viscosity = bool(np.any(table[:, P_ETA] != 0))

        dev = self.device
        self._tri = wp.array(tri.astype(np.int32), dtype=wp.vec3i, device=dev)
        self._dih = wp.array(dih.astype(np.int32), dtype=wp.vec4i, device=dev)
        self._tri_rep = wp.array(tri_rep.astype(np.int32), dtype=wp.int32, device=dev)
        self._edge_rep = wp.array(edge_rep.astype(np.int32), dtype=wp.int32, device=dev)
        self._vrep = wp.array(vrep.astype(np.int32), dtype=wp.int32, device=dev)
        self._gidx = wp.array(gidx.astype(np.int32), dtype=wp.int32, device=dev)
        self._goff = wp.array(offsets.astype(np.int32), dtype=wp.int32, device=dev)
        self._coff = wp.array(coff.astype(np.int32), dtype=wp.int32, device=dev)
        self._ref = wp.array(ref, dtype=wp.vec4d if dtype is wp.float64 else wp.vec4f, device=dev)
        self._theta0 = wp.array(theta0, dtype=dtype, device=dev)
        # (cos, sin) theta0: the Kantor kernels need no atan2 / sin (kantor_edge)
        self._cs0 = wp.array(np.stack([np.cos(theta0), np.sin(theta0)], axis=1),
                             dtype=wp.vec2d if dtype is wp.float64 else wp.vec2f, device=dev)
        self._params = wp.array(table, dtype=dtype, device=dev)
        self._avr = wp.zeros((R, 2), dtype=dtype, device=dev)
        self._health = wp.zeros((R, 3), dtype=dtype, device=dev)
        self._energy = wp.zeros((R, len(ENERGY_TERMS)), dtype=dtype, device=dev)
        self._dummy_energy = wp.zeros((1, len(ENERGY_TERMS)), dtype=dtype, device=dev)
        self._no_skip = wp.zeros(R, dtype=wp.int32, device=dev)
        self._skip = self._no_skip
        self._gas = wp.zeros((1, 2), dtype=dtype, device=dev)
        self._gas_vol = wp.ones(1, dtype=dtype, device=dev)
        self._gas_on = 0
        n_shell = int(nv.sum())
        self.n_shell_vertices = n_shell
        self._msum = wp.zeros(n_shell, dtype=dtype, device=dev)
        self._avert = wp.zeros(n_shell, dtype=dtype, device=dev)
        self._xs = wp.zeros(n_shell, dtype=wp.vec3, device=dev)
        self._grid = None
        self._setup_self_avoid_grid(offsets)
        # vertex -> incident elements (CSR) for the gather kernel; codes = element * 4 + corner/role
        rep_of_t = tri_rep
        comp_t = tri - offsets[rep_of_t][:, None] + coff[rep_of_t][:, None]
        comp_d = dih - offsets[edge_rep][:, None] + coff[edge_rep][:, None]
        self._tri_start, self._tri_slot = self._csr(comp_t, n_shell, dev)
        self._dih_start, self._dih_slot = self._csr(comp_d, n_shell, dev)
        self.n_triangles = tri.shape[0]
        self.n_edges = dih.shape[0]
        # NumPy <-> Warp staging for the NumPy convenience interface (CPU / tests / minimiser)
        self._np_x = None
        self._scratch_f = None

    # ------------------------------------------------------------------------------------------
    def _param_row(self, r: int, p: ShellParams) -> np.ndarray:
        """Row ``r`` of the device parameter table for :class:`ShellParams` ``p`` (on replica r's mesh)."""
        m = self.meshes[r]
        row = np.zeros(N_PARAMS)
        row[[P_KA, P_MU, P_A3, P_A4, P_B1, P_B2]] = [p.ka, p.mu, p.a3, p.a4, p.b1, p.b2]
        row[P_KB_KANTOR] = p.kb if p.bending == "kantor" else 0.0
        row[P_KB_JUL] = p.kb if p.bending == "juelicher" else 0.0
        row[P_C0] = p.c0
        row[[P_KATOT, P_KVTOT, P_PB]] = [p.ka_tot, p.kv_tot, p.p_back]
        row[P_A0TOT] = self.area0[r]
        row[P_V0] = self.volume0[r]
        row[P_SA_EPS] = p.self_avoid_epsilon if p.self_avoid else 0.0
        row[P_SA_RC] = p.self_avoid_cutoff * m.min_edge_length()
        row[P_ETA] = p.bond_viscosity
        return row

    def set_params_rows(self, rows: Sequence[int] | np.ndarray, params: Sequence[ShellParams]) -> None:
        """Give replicas ``rows`` new :class:`ShellParams` (DPD units) in place, e.g. to reuse a finished
        replica's slot for the next sample of a batch; CUDA graphs see the change (same device array).

        The new parameters may not switch on a term the field was built without (Kantor / Juelicher
        bending, global constraints, self-avoidance, bond viscosity): those kernels are chosen at
        construction.  Raises ValueError otherwise.
        """
        rows = np.asarray(rows, dtype=np.int64).reshape(-1)
        if len(rows) != len(params):
            raise ValueError(f"{len(rows)} rows but {len(params)} parameter sets")
        if len(rows) == 0:
            return
        if rows.min() < 0 or rows.max() >= self.n_replicas or len(np.unique(rows)) != len(rows):
            raise ValueError(f"rows must be distinct replica indices in [0, {self.n_replicas})")
        new = np.stack([self._param_row(int(r), p) for r, p in zip(rows, params, strict=True)])
        for col, on, what in ((P_KB_KANTOR, self.use_kantor, "Kantor bending"),
                              (P_KB_JUL, self.use_juelicher, "Juelicher bending"),
                              (P_SA_EPS, self.use_self_avoid, "self-avoidance"),
                              (P_ETA, self.use_viscosity, "bond viscosity")):
            if not on and np.any(new[:, col] != 0):
                raise ValueError(f"set_params_rows: {what} is off in this field (built without it)")
        if not self.use_global and np.any(new[:, [P_KATOT, P_KVTOT, P_PB]] != 0):
            raise ValueError("set_params_rows: global area/volume constraints and back pressure are off in this field")
        if self.use_self_avoid and np.any(new[:, P_SA_RC] * 1.001 > self.sa_query_radius * (1 + 1e-12)):
            raise ValueError("set_params_rows: a self-avoidance cut-off exceeds the field's search radius")
        self.param_table[rows] = new
        for r, p in zip(rows, params, strict=True):
            self.params[int(r)] = p
        self._params.assign(self.param_table.astype(np.float64 if self.dtype is wp.float64 else np.float32))

    @staticmethod
    def _csr(elements: np.ndarray, n_vertices: int, device):
        n_el, k = elements.shape
        vert = elements.reshape(-1)
        code = (np.repeat(np.arange(n_el, dtype=np.int64), k) * 4 + np.tile(np.arange(k), n_el))
        order = np.argsort(vert, kind="stable")
        start = np.zeros(n_vertices + 1, dtype=np.int64)
        np.cumsum(np.bincount(vert, minlength=n_vertices), out=start[1:])
        if code.max(initial=0) >= 2**31:
            raise ValueError("too many shell elements for 32-bit element codes")
        return (wp.array(start.astype(np.int32), dtype=wp.int32, device=device),
                wp.array(code[order].astype(np.int32), dtype=wp.int32, device=device))

    def _setup_self_avoid_grid(self, offsets) -> None:
        """Search grid of the self-avoidance: every replica gets its own slot of a 3-D lattice.

        Replicas usually share coordinates (each in its own box), so their vertices are moved into
        disjoint slots (centre = midpoint of an antipodal vertex pair, slot width 3 R_max + 2 cells,
        room for 50 % deformation); the hash grid (cell = 2 x the largest cut-off, at most 128 cells
        per axis) then rarely aliases two replicas into one cell.  Aliasing only costs time: pairs
        are filtered by replica and by the true distance.
        """
        R = self.n_replicas
        anchors = np.zeros((R, 2), dtype=np.int32)
        ext = 0.0
        for r, (m, o) in enumerate(zip(self.meshes, offsets, strict=True)):
            v = m.vertices
            b = int(np.argmax(np.linalg.norm(v - v[0], axis=1)))
            anchors[r] = (o, o + b)
            c = 0.5 * (v[0] + v[b])
            ext = max(ext, float(np.max(np.abs(v - c))))
        self.sa_query_radius = float(np.max(self.param_table[:, P_SA_RC])) * 1.001
        self.sa_cell = 2.0 * self.sa_query_radius
        n_axis = int(math.ceil(R ** (1.0 / 3.0) - 1e-9))
        slot_cells = int(math.ceil((3.0 * ext) / self.sa_cell)) + 2
        width = slot_cells * self.sa_cell
        ijk = np.stack(np.unravel_index(np.arange(R), (n_axis, n_axis, n_axis)), axis=1)
        self._anchor = wp.array(anchors, dtype=wp.vec2i, device=self.device)
        self._slot = wp.array((ijk + 0.5) * width, dtype=wp.vec3, device=self.device)
        if self.use_self_avoid:
            used = [int(ijk[:, k].max()) + 1 for k in range(3)]
            dims = [int(min(128, max(4, u * slot_cells))) for u in used]
            self._grid = wp.HashGrid(*dims, device=self.device)

    def _check_array(self, a, name: str) -> None:
        if not wp.types.types_equal(a.dtype, self.vec3):
            raise TypeError(f"{name} must be a wp.array of {self.vec3.__name__}, got {a.dtype.__name__}")
        if a.device != self.device:
            raise ValueError(f"{name} lives on {a.device}, the shell field on {self.device}")
        if a.shape[0] < self.n_rows_min:
            raise ValueError(f"{name} has {a.shape[0]} rows, the shells need {self.n_rows_min}")

    def _launch_forces(self, x, f, v, energy, want_energy: int, skip=None, with_gas: bool = False) -> None:
        k, dev = self._k, self.device
        skip = self._no_skip if skip is None else skip
        gas = [self._gas, self._gas_vol, int(self._gas_on and with_gas)]
        if self.use_constraints_av:
            self._avr.zero_()
            wp.launch(k["area_volume_kernel"], dim=self.n_triangles,
                      inputs=[x, self._tri, self._tri_rep, self._goff, self._avr], device=dev)
        if self.force_mode == "gather" and not want_energy:
            wp.launch(k["vertex_gather_kernel"], dim=self.n_shell_vertices,
                      inputs=[x, f, self._gidx, self._vrep, self._tri, self._ref, self._tri_start, self._tri_slot,
                              self._dih, self._cs0, self._dih_start, self._dih_slot, self._params, self._avr,
                              int(self.use_global), int(self.use_kantor), skip, *gas], device=dev)
        else:
            wp.launch(k["lim_kernel"], dim=self.n_triangles,
                      inputs=[x, f, self._tri, self._ref, self._tri_rep, self._params, self._avr,
                              int(self.use_global), energy, want_energy, skip, *gas], device=dev)
            if self.use_kantor:
                wp.launch(k["kantor_kernel"], dim=self.n_edges,
                          inputs=[x, f, self._dih, self._cs0, self._edge_rep, self._params, energy,
                                  want_energy, skip], device=dev)
        if self.use_juelicher:
            self._msum.zero_()
            self._avert.zero_()
            common = [self._goff, self._coff, self._params, self._msum]
            wp.launch(k["jul_accum_edges"], dim=self.n_edges, inputs=[x, self._dih, self._edge_rep, *common], device=dev)
            wp.launch(k["tri_accum_vertex_area"], dim=self.n_triangles,
                      inputs=[x, self._tri, self._tri_rep, self._goff, self._coff, self._params, self._avert],
                      device=dev)
            wp.launch(k["jul_force_edges"], dim=self.n_edges,
                      inputs=[x, f, self._dih, self._edge_rep, *common, self._avert], device=dev)
            wp.launch(k["jul_force_tris"], dim=self.n_triangles,
                      inputs=[x, f, self._tri, self._tri_rep, *common, self._avert], device=dev)
            if want_energy:
                wp.launch(k["jul_energy"], dim=self.n_shell_vertices,
                          inputs=[self._vrep, self._params, self._msum, self._avert, energy], device=dev)
        if self.use_self_avoid:
            wp.launch(k["gather_kernel"], dim=self.n_shell_vertices,
                      inputs=[x, self._gidx, self._vrep, self._anchor, self._slot, self._xs], device=dev)
            self._grid.build(self._xs, self.sa_cell)
            wp.launch(k["self_avoid_kernel"], dim=self.n_shell_vertices,
                      inputs=[self._grid.id, self._xs, x, f, self._gidx, self._vrep, self._params,
                              self.sa_query_radius, energy, want_energy, skip], device=dev)
        if self.use_viscosity and v is not None:
            wp.launch(k["bond_viscosity_kernel"], dim=self.n_edges,
                      inputs=[x, v, f, self._dih, self._edge_rep, self._params], device=dev)

    def accumulate_forces(self, x: wp.array, f: wp.array, v: wp.array | None = None) -> None:
        """Add the shell forces of every replica into ``f`` (atomics; ``f`` is not cleared).

        ``v`` (particle velocities) is needed only for bond viscosity.
        """
        self._check_array(x, "x")
        self._check_array(f, "f")
        if v is not None:
            self._check_array(v, "v")
        self._launch_forces(x, f, v, self._dummy_energy, 0, self._skip, with_gas=True)

    def set_skip(self, skip: wp.array | None) -> None:
        """Bind a per-replica int32 device array [R]: :meth:`accumulate_forces` adds no Lim, Kantor or
        self-avoidance forces for replicas whose entry is nonzero (read at launch time, so a minimiser's
        status array can be bound once and CUDA graphs see its updates).  None unbinds.  Why: a batched
        minimiser's converged replicas cost almost nothing while the slowest ones finish.  The Juelicher
        and bond-viscosity terms are never skipped; energies ignore the binding."""
        if skip is None:
            self._skip = self._no_skip
            return
        if skip.dtype != wp.int32 or skip.shape != (self.n_replicas,) or skip.device != self.device:
            raise ValueError(f"skip must be an int32 array of shape ({self.n_replicas},) on {self.device}")
        self._skip = skip

    def set_gas(self, gas: wp.array | None, volume: wp.array | None = None) -> None:
        """Bind an inside gas to :meth:`accumulate_forces`: replica r's shell also feels the pressure
        ``gas[r, 0] / volume[r] - gas[r, 1]`` (DPD pressure; ``gas`` [R, 2] holds p0 V0 and the ambient
        pressure, ``volume`` [R] the enclosed volumes, DPD length^3, which the caller updates before each call:
        read at launch time, so CUDA graphs see the updates).  Why here: the force is that pressure times
        dV/dx = (sum of the incident triangles' normals) / 6, which the Lim pass already computes.  None unbinds;
        energies never include it."""
        if gas is None:
            self._gas_on = 0
            return
        R = self.n_replicas
        if gas.dtype != self.dtype or gas.shape != (R, 2) or gas.device != self.device:
            raise ValueError(f"gas must be a {self.dtype.__name__} array of shape ({R}, 2) on {self.device}")
        if volume is None or volume.dtype != self.dtype or volume.shape != (R,) or volume.device != self.device:
            raise ValueError(f"volume must be a {self.dtype.__name__} array of shape ({R},) on {self.device}")
        self._gas, self._gas_vol, self._gas_on = gas, volume, 1

    def areas_volumes(self, x: wp.array) -> tuple[np.ndarray, np.ndarray]:
        """Total area A[R] and enclosed volume V[R] of every replica's shell (synchronises)."""
        self._check_array(x, "x")
        self._avr.zero_()
        wp.launch(self._k["area_volume_kernel"], dim=self.n_triangles,
                  inputs=[x, self._tri, self._tri_rep, self._goff, self._avr], device=self.device)
        avr = self._avr.numpy().astype(np.float64)
        return avr[:, 0].copy(), avr[:, 1].copy()

    def health(self, x: wp.array) -> dict[str, np.ndarray]:
        """Per-replica shell health indicators (synchronises); thresholds are the caller's choice.

        ``max_area_strain`` max_t |A_t/A0_t - 1| (rupture / over-stretch), ``min_area_ratio``
        min_t A_t/A0_t (collapse; <= 0 never happens as areas are unsigned, so also watch
        ``max_dihedral_change``), ``max_dihedral_change`` max_e |theta_e - theta0_e| in radians
        (a triangle folded over its neighbour, i.e. an inversion, gives values near pi).
        Non-finite positions give NaN or meaningless values: test positions for NaN first.
        """
        self._check_array(x, "x")
        init = np.zeros((self.n_replicas, 3))
        init[:, 1] = np.inf if self.dtype is wp.float64 else np.finfo(np.float32).max
        self._health.assign(init)
        wp.launch(self._k["health_tris"], dim=self.n_triangles,
                  inputs=[x, self._tri, self._ref, self._tri_rep, self._health], device=self.device)
        wp.launch(self._k["health_edges"], dim=self.n_edges,
                  inputs=[x, self._dih, self._theta0, self._edge_rep, self._health], device=self.device)
        h = self._health.numpy().astype(np.float64)
        return {"max_area_strain": h[:, 0].copy(), "min_area_ratio": h[:, 1].copy(),
                "max_dihedral_change": h[:, 2].copy()}

    def energies(self, x: wp.array) -> np.ndarray:
        """Energy per replica and term [R, 6], columns :data:`ENERGY_TERMS` (synchronises).

        The constraint and back-pressure columns are evaluated in float64 on the host from the
        device areas / volumes: ka_tot (A-A0)^2/(2A0), kv_tot (V-V0)^2/(2V0), -p_back (V-V0).
        """
        self._check_array(x, "x")
        if self._scratch_f is None or self._scratch_f.shape[0] != x.shape[0]:
            self._scratch_f = wp.zeros_like(x)
        self._energy.zero_()
        self._launch_forces(x, self._scratch_f, None, self._energy, 1)
        return self._finish_energies(x)

    def _finish_energies(self, x: wp.array) -> np.ndarray:
        e = self._energy.numpy().astype(np.float64)
        a, vol = self.areas_volumes(x)
        t = self.param_table
        e[:, E_AREA] = t[:, P_KATOT] * (a - self.area0) ** 2 / (2 * self.area0)
        e[:, E_VOL] = t[:, P_KVTOT] * (vol - self.volume0) ** 2 / (2 * self.volume0)
        e[:, E_PB] = -t[:, P_PB] * (vol - self.volume0)
        return e

    # ----- NumPy convenience (CPU checks, minimiser callbacks) ---------------------------------
    def reference_positions(self, n_rows: int | None = None) -> np.ndarray:
        """A [n_rows, 3] float64 array with every replica's reference vertices at its rows."""
        n = self.n_rows_min if n_rows is None else n_rows
        x = np.zeros((n, 3))
        for m, o in zip(self.meshes, self.offsets, strict=True):
            x[o:o + m.n_vertices] = m.vertices
        return x

    def energy_forces_numpy(self, x: np.ndarray, with_energy: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Evaluate (energies [R, 6], forces [N, 3]) for NumPy positions (copies to/from the device)."""
        x = np.ascontiguousarray(x, dtype=np.float64)
        if self._np_x is None or self._np_x.shape[0] != x.shape[0]:
            self._np_x = wp.zeros(x.shape[0], dtype=self.vec3, device=self.device)
            self._np_f = wp.zeros(x.shape[0], dtype=self.vec3, device=self.device)
        self._np_x.assign(x.astype(np.float32 if self.dtype is wp.float32 else np.float64))
        self._np_f.zero_()
        self._energy.zero_()
        self._launch_forces(self._np_x, self._np_f, None, self._energy if with_energy else self._dummy_energy,
                            int(with_energy))
        f = self._np_f.numpy().astype(np.float64)
        if not with_energy:
            return np.zeros((self.n_replicas, len(ENERGY_TERMS))), f
        return self._finish_energies(self._np_x), f

