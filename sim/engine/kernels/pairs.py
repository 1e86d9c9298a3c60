"""DPD pair forces (docs/physics.md section 2) as Warp kernels, for float32 or float64.

For r = |r_ij| < r_c = 1, e = r_ij / r, w = (1 - r)^s:

    F_ij = e [ a (1 - r) - gamma w^2 (e . v_ij) + sigma w theta_ij / sqrt(dt) ],  sigma = sqrt(2 gamma kBT)

The conservative weight is always linear; ``s`` shapes only the dissipative/random weights.
``theta_ij`` is a uniform random number of zero mean and unit variance (in [-sqrt 3, sqrt 3], as in
Mirheo) drawn from a hash of ``(seed, step, min(id_i, id_j), max(id_i, id_j))`` of the particles'
*persistent* ids, so both members of a pair draw the same number no matter which thread computes it
or how the arrays were sorted. The sign of the random term is a convention (theta is symmetric).

Parameters live in flat per-replica tables indexed ``rep * 16 + t_i * 4 + t_j`` (4 types); sigma is
precomputed per entry (it carries the replica's kBT).

Solvent-solvent forces are evaluated per particle over a full (both-direction) Verlet list and
written without atomics (each pair is computed twice, bit-identically up to the sign, so the total
force cancels to round-off). Vertex-solvent forces are evaluated per vertex over a vertex->solvent
list; the reaction is atomically added to the solvent particle.
"""


import functools

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.common import kernel_decorator, min_image

wp = require("warp", "sim")

#: Offset added to vertex indices to form their persistent ids in the pair hash.
VERTEX_ID_OFFSET = 1 << 30
SQRT3 = 1.7320508075688772


@wp.func
def step_key(seed: wp.int32, step: wp.int32) -> wp.int32:
    """Hash of (seed, step), computed once per thread.

    Parameters
    ----------
    seed : wp.int32
        Replica seed.
    step : wp.int32
        Step counter.

    Returns
    -------
    wp.int32
    """
    return wp.int32(wp.rand_init(seed, step))


@wp.func
def pair_uniform_keyed(key: wp.int32, i: wp.int32, j: wp.int32) -> float:
    """Uniform [0, 1) number shared by the pair (i, j) at this step (symmetric in i, j).

    Parameters
    ----------
    key : wp.int32
        :func:`step_key` of this step.
    i, j : wp.int32
        Persistent particle ids.

    Returns
    -------
    float
    """
    lo = wp.min(i, j)
    hi = wp.max(i, j)
    s1 = wp.rand_init(key, lo)
    s2 = wp.rand_init(wp.int32(s1), hi)
    return wp.randf(s2)


@wp.func
def pair_uniform(seed: wp.int32, step: wp.int32, i: wp.int32, j: wp.int32) -> float:
    """Uniform [0, 1) number shared by the pair (i, j) at this step: hash of (seed, step, min, max).

    Parameters
    ----------
    seed, step : wp.int32
        Replica seed and step counter.
    i, j : wp.int32
        Persistent particle ids.

    Returns
    -------
    float
    """
    return pair_uniform_keyed(step_key(seed, step), i, j)


@wp.func
def weight_pow(wc: wp.float32, s: wp.float32) -> wp.float32:
    """(1 - r)^s with fast paths for the published exponents 1/2 and 1/4 (float32 overload).

    Parameters
    ----------
    wc : wp.float32
        1 - r / r_c (dimensionless).
    s : wp.float32
        Exponent.

    Returns
    -------
    wp.float32
    """
    if s == wp.float32(0.5):
        return wp.sqrt(wc)
    if s == wp.float32(0.25):
        return wp.sqrt(wp.sqrt(wc))
    return wp.pow(wc, s)


@wp.func
def weight_pow(wc: wp.float64, s: wp.float64) -> wp.float64:  # noqa: F811 (float64 overload)
    """(1 - r)^s with fast paths for the published exponents 1/2 and 1/4 (float64 overload)."""
    if s == wp.float64(0.5):
        return wp.sqrt(wc)
    if s == wp.float64(0.25):
        return wp.sqrt(wp.sqrt(wc))
    return wp.pow(wc, s)


@wp.func
def wrap_delta(d: float, L: float) -> float:
    """Minimum-image difference ``d`` in a periodic length ``L`` (DPD length)."""
    return d - L * wp.round(d / L)


@functools.cache
def pair_kernels(dtype):
    """Build (once per scalar type) the DPD pair-force kernels; ``dtype`` is ``wp.float32`` or ``wp.float64``.
    Returns a dict: The kernels ``solvent_forces``, ``vertex_solvent_forces``, ``solvent_virial`` and the Warp
    functions ``min_image`` and ``dpd_pair``.
    """
    vec3 = wp.types.vector(3, dtype)
    kern = kernel_decorator(dtype, "pairs")


    @wp.func
    def min_image_inv(d: vec3, L: vec3, invL: vec3) -> vec3:
        return vec3(d[0] - L[0] * wp.round(d[0] * invL[0]),
                    d[1] - L[1] * wp.round(d[1] * invL[1]),
                    d[2] - L[2] * wp.round(d[2] * invL[2]))

    @wp.func
    def dpd_pair(d: vec3, dv: vec3, a: dtype, g: dtype, s: dtype, sig: dtype, theta: dtype,
                 inv_sqrt_dt: dtype) -> vec3:
        """Force on i from j given d = x_i - x_j (min image), dv = v_i - v_j; zero beyond r_c = 1."""
        r2 = wp.dot(d, d)
        out = vec3(dtype(0.0), dtype(0.0), dtype(0.0))
        if r2 < dtype(1.0) and r2 > dtype(1.0e-12):
            r = wp.sqrt(r2)
            e = d / r
            wc = dtype(1.0) - r
            wd = weight_pow(wc, s)
            fm = a * wc - g * wd * wd * wp.dot(e, dv) + sig * wd * theta * inv_sqrt_dt
            out = e * fm
        return out

    @kern
    def solvent_forces(
        x: wp.array(dtype=vec3), v: wp.array(dtype=vec3), typ: wp.array(dtype=wp.int32),
        rep: wp.array(dtype=wp.int32), pid: wp.array(dtype=wp.int32),
        nbr: wp.array2d(dtype=wp.int32), ncount: wp.array(dtype=wp.int32),
        box: wp.array(dtype=vec3), tab_a: wp.array(dtype=dtype), tab_g: wp.array(dtype=dtype),
        tab_s: wp.array(dtype=dtype), tab_sig: wp.array(dtype=dtype), seeds: wp.array(dtype=wp.int32),
        step: wp.array(dtype=wp.int32), inv_sqrt_dt: dtype, f: wp.array(dtype=vec3),
    ):
        i = wp.tid()
        r = rep[i]
        L = box[r]
        invL = vec3(dtype(1.0) / L[0], dtype(1.0) / L[1], dtype(1.0) / L[2])
        xi = x[i]
        vi = v[i]
        base = r * 16 + typ[i] * 4
        pi = pid[i]
        key = step_key(seeds[r], step[0])
        fi = vec3(dtype(0.0), dtype(0.0), dtype(0.0))
        n = ncount[i]
        for k in range(n):
            j = nbr[k, i]
            d = min_image_inv(xi - x[j], L, invL)
            r2 = wp.dot(d, d)
            if r2 < dtype(1.0) and r2 > dtype(1.0e-12):
                idx = base + typ[j]
                a = tab_a[idx]
                g = tab_g[idx]
                if a != dtype(0.0) or g != dtype(0.0):
                    rr = wp.sqrt(r2)
                    e = d / rr
                    wc = dtype(1.0) - rr
                    wd = weight_pow(wc, tab_s[idx])
                    theta = dtype(SQRT3) * (dtype(2.0) * dtype(pair_uniform_keyed(key, pi, pid[j])) - dtype(1.0))
                    fm = a * wc - g * wd * wd * wp.dot(e, vi - v[j]) + tab_sig[idx] * wd * theta * inv_sqrt_dt
                    fi = fi + e * fm
        f[i] = fi

    @kern
    def vertex_solvent_forces(
        xv: wp.array(dtype=vec3), vv: wp.array(dtype=vec3), vrep: wp.array(dtype=wp.int32),
        x: wp.array(dtype=vec3), v: wp.array(dtype=vec3), typ: wp.array(dtype=wp.int32),
        pid: wp.array(dtype=wp.int32), vnbr: wp.array2d(dtype=wp.int32), vcount: wp.array(dtype=wp.int32),
        box: wp.array(dtype=vec3), tab_a: wp.array(dtype=dtype), tab_g: wp.array(dtype=dtype),
        tab_s: wp.array(dtype=dtype), tab_sig: wp.array(dtype=dtype), seeds: wp.array(dtype=wp.int32),
        step: wp.array(dtype=wp.int32), inv_sqrt_dt: dtype, fv: wp.array(dtype=vec3), f: wp.array(dtype=vec3),
    ):
        i = wp.tid()
        r = vrep[i]
        L = box[r]
        xi = xv[i]
        vi = vv[i]
        base = r * 16 + 2 * 4  # type VERTEX = 2
        pi = i + VERTEX_ID_OFFSET
        key = step_key(seeds[r], step[0])
        fi = vec3(dtype(0.0), dtype(0.0), dtype(0.0))
        for k in range(vcount[i]):
            j = vnbr[k, i]
            idx = base + typ[j]
            a = tab_a[idx]
            g = tab_g[idx]
            if a != dtype(0.0) or g != dtype(0.0):
                d = min_image(xi - x[j], L)
                theta = dtype(SQRT3) * (dtype(2.0) * dtype(pair_uniform_keyed(key, pi, pid[j])) - dtype(1.0))
                fij = dpd_pair(d, vi - v[j], a, g, tab_s[idx], tab_sig[idx], theta, inv_sqrt_dt)
                fi = fi + fij
                wp.atomic_sub(f, j, fij)
        fv[i] = fv[i] + fi

    @kern
    def solvent_virial(
        x: wp.array(dtype=vec3), v: wp.array(dtype=vec3), typ: wp.array(dtype=wp.int32),
        rep: wp.array(dtype=wp.int32), nbr: wp.array2d(dtype=wp.int32), ncount: wp.array(dtype=wp.int32),
        box: wp.array(dtype=vec3), tab_a: wp.array(dtype=dtype), mass: wp.array(dtype=dtype),
        virial: wp.array(dtype=wp.float64), kinetic: wp.array(dtype=wp.float64),
    ):
        """Per replica: sum_pairs r_ij . F^C_ij (each pair counted once) and sum_i m v_i^2."""
        i = wp.tid()
        r = rep[i]
        L = box[r]
        xi = x[i]
        ti = typ[i]
        base = r * 16 + ti * 4
        w = dtype(0.0)
        for k in range(ncount[i]):
            j = nbr[k, i]
            d = min_image(xi - x[j], L)
            r2 = wp.dot(d, d)
            if r2 < dtype(1.0) and r2 > dtype(1.0e-12):
                rr = wp.sqrt(r2)
                w = w + tab_a[base + typ[j]] * (dtype(1.0) - rr) * rr
        vi = v[i]
        wp.atomic_add(virial, r, wp.float64(dtype(0.5) * w))
        wp.atomic_add(kinetic, r, wp.float64(mass[r * 4 + ti] * wp.dot(vi, vi)))

    return {"min_image": min_image, "dpd_pair": dpd_pair, "solvent_forces": solvent_forces,
            "vertex_solvent_forces": vertex_solvent_forces, "solvent_virial": solvent_virial}
