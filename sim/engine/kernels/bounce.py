"""Bounce-back of solvent particles on moving triangles (docs/physics.md section 4).

Called after the drift. For every solvent particle that has candidate triangles (CSR lists built with
the neighbour lists) the step segment ``p(t) = x_old + t (x_new - x_old)`` is intersected with each
candidate triangle whose vertices move linearly from their old to their new positions over the step:
the signed volume ``g(t) = (p(t) - a(t)) . ((b(t) - a(t)) x (c(t) - a(t)))`` changes sign across the
step when the particle crosses the triangle's plane; its root is found by bisection (the cubic can have
several roots; a particle that crosses twice in one step, in and out, is not seen -- as in Mirheo), and
the crossing counts when the point lies inside the triangle at that time. The earliest crossing wins.

Response (momentum conserving):

* the particle is put back on its original side, a distance ``eps`` off the triangle at its new
  position (same barycentric point);
* its new velocity is the triangle's local velocity ``u`` (barycentric interpolation of the vertex
  velocities over the step) plus a thermal kick away from the surface: a Rayleigh-distributed normal
  component (the flux-weighted Maxwellian, so a resting wall is an exact thermal wall: pressure
  n kBT) and Gaussian tangential components, all of variance kBT/m;
* the particle's momentum change ``dp`` is removed from the three vertices with the barycentric
  weights (``dv_k = -w_k dp / m_v``), so the total momentum is unchanged;
* per replica, the outward normal impulse ``-dp . n_out`` and the number of bounces are accumulated
  (pressure measurements).

The kick's random numbers come from the particle's persistent id and the step.
"""


import functools

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.common import kernel_decorator, min_image

wp = require("warp", "sim")


@functools.cache
def bounce_kernels(dtype):
    """Build (once per scalar type) the bounce-back kernel (module docstring); ``dtype`` is ``wp.float32`` or
    ``wp.float64``. Returns a dict: ``bounce`` (name -> ``wp.Kernel``).
    """
    vec3 = wp.types.vector(3, dtype)
    kern = kernel_decorator(dtype, "bounce")


    @wp.func
    def signed_vol(p: vec3, a: vec3, b: vec3, c: vec3) -> dtype:
        return wp.dot(p - a, wp.cross(b - a, c - a))

    @kern
    def bounce(x: wp.array(dtype=vec3), v: wp.array(dtype=vec3), typ: wp.array(dtype=wp.int32),
               rep: wp.array(dtype=wp.int32), pid: wp.array(dtype=wp.int32),
               row: wp.array(dtype=wp.int32), cols: wp.array(dtype=wp.int32),
               xv_old: wp.array(dtype=vec3), xv: wp.array(dtype=vec3), vv: wp.array(dtype=vec3),
               faces: wp.array(dtype=wp.vec3i), box: wp.array(dtype=vec3), mass: wp.array(dtype=dtype),
               inv_mass: wp.array(dtype=dtype),
               kbt: wp.array(dtype=dtype), seeds: wp.array(dtype=wp.int32), step: wp.array(dtype=wp.int32),
               status: wp.array(dtype=wp.int32), dt: dtype, eps: dtype,
               impulse: wp.array(dtype=wp.float64), nbounce: wp.array(dtype=wp.int32)):
        i = wp.tid()
        s0 = row[i]
        s1 = row[i + 1]
        if s0 == s1:
            return
        r = rep[i]
        if status[r] != 0:
            return
        ti = typ[i]
        if ti == 3:  # walls do not bounce
            return
        L = box[r]
        xn = x[i]
        vo = v[i]
        xo = xn - vo * dt
        best_t = dtype(2.0)
        best_k = wp.int32(-1)
        best_side = dtype(0.0)
        best_w1 = dtype(0.0)
        best_w2 = dtype(0.0)
        for k in range(s0, s1):
            tri = cols[k]
            fc = faces[tri]
            ao = xv_old[fc[0]]
            an = xv[fc[0]]
            # triangle images relative to vertex a (min image), particle relative to a's old position
            bo = ao + min_image(xv_old[fc[1]] - ao, L)
            co = ao + min_image(xv_old[fc[2]] - ao, L)
            bn = an + min_image(xv[fc[1]] - an, L)
            cn = an + min_image(xv[fc[2]] - an, L)
            p0 = ao + min_image(xo - ao, L)
            p1 = p0 + (xn - xo)
            g0 = signed_vol(p0, ao, bo, co)
            g1 = signed_vol(p1, an, bn, cn)
            if g0 * g1 < dtype(0.0) or (g1 == dtype(0.0) and g0 != dtype(0.0)):
                lo = dtype(0.0)
                hi = dtype(1.0)
                glo = g0
                for _it in range(24):
                    mid = dtype(0.5) * (lo + hi)
                    om = dtype(1.0) - mid
                    gm = signed_vol(p0 * om + p1 * mid, ao * om + an * mid, bo * om + bn * mid, co * om + cn * mid)
                    if gm * glo > dtype(0.0):
                        lo = mid
                        glo = gm
                    else:
                        hi = mid
                t = hi
                om = dtype(1.0) - t
                pt = p0 * om + p1 * t
                at = ao * om + an * t
                e1 = (bo * om + bn * t) - at
                e2 = (co * om + cn * t) - at
                q = pt - at
                d11 = wp.dot(e1, e1)
                d12 = wp.dot(e1, e2)
                d22 = wp.dot(e2, e2)
                q1 = wp.dot(q, e1)
                q2 = wp.dot(q, e2)
                den = d11 * d22 - d12 * d12
                if den > dtype(0.0):
                    w1 = (d22 * q1 - d12 * q2) / den
                    w2 = (d11 * q2 - d12 * q1) / den
                    tol = dtype(-1.0e-6)
                    if w1 >= tol and w2 >= tol and w1 + w2 <= dtype(1.0) - tol and t < best_t:
                        best_t = t
                        best_k = tri
                        best_w1 = w1
                        best_w2 = w2
                        best_side = wp.sign(g0)
        if best_k < 0:
            return
        fc = faces[best_k]
        w1 = best_w1
        w2 = best_w2
        w0 = dtype(1.0) - w1 - w2
        an = xv[fc[0]]
        bn = an + min_image(xv[fc[1]] - an, L)
        cn = an + min_image(xv[fc[2]] - an, L)
        ao = xv_old[fc[0]]
        bo = ao + min_image(xv_old[fc[1]] - ao, L)
        co = ao + min_image(xv_old[fc[2]] - ao, L)
        nrm = wp.cross(bn - an, cn - an)
        nl = wp.length(nrm)
        if nl <= dtype(0.0):
            return
        nrm = nrm / nl
        if best_side == dtype(0.0):
            best_side = dtype(-1.0) if wp.dot(xn - an, nrm) > dtype(0.0) else dtype(1.0)
        side = nrm * best_side  # unit vector towards the original side
        u = ((an - ao) * w0 + (bn - bo) * w1 + (cn - co) * w2) / dt
        m = mass[r * 4 + ti]
        sd = wp.sqrt(kbt[r] / m)
        st = wp.rand_init(seeds[r] + 7919, step[0])
        st = wp.rand_init(wp.int32(st), pid[i])
        # tangent basis
        tref = vec3(dtype(1.0), dtype(0.0), dtype(0.0))
        if wp.abs(nrm[0]) > dtype(0.9):
            tref = vec3(dtype(0.0), dtype(1.0), dtype(0.0))
        t1 = wp.normalize(wp.cross(nrm, tref))
        t2 = wp.cross(nrm, t1)
        u1 = dtype(wp.randf(st))
        vnorm = sd * wp.sqrt(dtype(-2.0) * wp.log(dtype(1.0) - u1 * dtype(0.999999)))
        g1r = dtype(wp.randn(st))
        g2r = dtype(wp.randn(st))
        vnew = u + side * vnorm + t1 * (sd * g1r) + t2 * (sd * g2r)
        pnew = an * w0 + bn * w1 + cn * w2
        # back into the particle's own periodic image
        xi = xn + min_image(pnew - xn, L) + side * eps
        x[i] = xi
        v[i] = vnew
        dp = (vnew - vo) * m
        inv = inv_mass[r * 4 + 2]
        if inv > dtype(0.0):
            wp.atomic_sub(vv, fc[0], dp * (w0 * inv))
            wp.atomic_sub(vv, fc[1], dp * (w1 * inv))
            wp.atomic_sub(vv, fc[2], dp * (w2 * inv))
        wp.atomic_add(impulse, r, wp.float64(-wp.dot(dp, nrm)))
        wp.atomic_add(nbounce, r, 1)

    return {"bounce": bounce}
