"""Per-replica health checks; a failed replica is frozen with a status while the others continue.

Checks (every ``health_every`` steps of :meth:`ParticleSystem.step`, or on demand):

* ``NAN``        any non-finite position or velocity (solvent or shell vertex) in the replica;
* ``ESCAPE``     a particle faster than ``max_speed`` (a blow-up in the making), or a shell vertex
                 farther than ``max_vertex_radius_factor`` x the reference radius from the shell's centroid;
* ``INVERSION``  a triangle whose outward normal points towards the shell's centroid, or whose area
                 collapsed below ``min_area_ratio`` x its reference area;
* ``RUPTURE``    a triangle's area strain A/A0 - 1 above ``rupture_strain``;
* ``LEAK``       more than ``max_leaks`` water particles inside the shell plus gas particles outside
                 it. Inside/outside: outside the bounding sphere of the vertices -> outside; closer to
                 the centroid than the nearest triangle -> same side as the centroid; otherwise the
                 generalized winding number over the replica's triangles (exact for closed meshes).

The first failure of a replica is kept (its status code is written into ``system.status``, which
every integrate/bounce kernel reads: the replica stops moving). :class:`HealthReport` holds the
per-replica numbers of the last check.
"""

import functools
import math
from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.common import kernel_decorator, min_image

wp = require("warp", "sim")

__all__ = ["Status", "HealthConfig", "HealthReport", "HealthMonitor"]


class Status(IntEnum):
    """Per-replica status codes written into ``system.status`` (0 = OK; any other code freezes the replica)."""

    OK = 0
    NAN = 1
    ESCAPE = 2
    INVERSION = 3
    RUPTURE = 4
    LEAK = 5


@dataclass
class HealthConfig:
    """Thresholds of :class:`HealthMonitor` (module docstring).

    Parameters
    ----------
    rupture_strain : float, optional
        Largest triangle area strain A/A0 - 1 (dimensionless).
    min_area_ratio : float, optional
        Smallest A/A0 before a triangle counts as collapsed.
    max_speed : float, optional
        Largest particle speed (DPD velocity).
    max_vertex_radius_factor : float, optional
        Largest vertex distance from the shell centroid, in units of the reference radius.
    max_leaks : int, optional
        Largest number of water particles inside plus gas particles outside a shell.
    check_leaks : bool, optional
        Count leaks at all (one pass over the solvent).
    """

    rupture_strain: float = 1.0
    min_area_ratio: float = 0.02
    max_speed: float = 500.0
    max_vertex_radius_factor: float = 3.0
    max_leaks: int = 0
    check_leaks: bool = True


@dataclass
class HealthReport:
    """Per-replica numbers of one :meth:`HealthMonitor.check`.

    Parameters
    ----------
    step : int
        ``steps_done`` of the system at the check.
    status : list of str
        :class:`Status` names per replica.
    water_inside, gas_outside : list of int
        Leak counts per replica.
    max_area_strain, min_area_ratio : list of float
        Largest A/A0 - 1 and smallest A/A0 per replica (NaN without a shell).
    n_inverted : list of int
        Inverted or collapsed triangles per replica.
    """

    step: int
    status: list[str]
    water_inside: list[int] = field(default_factory=list)
    gas_outside: list[int] = field(default_factory=list)
    max_area_strain: list[float] = field(default_factory=list)
    min_area_ratio: list[float] = field(default_factory=list)
    n_inverted: list[int] = field(default_factory=list)

    def as_dict(self) -> dict:
        """The report as a plain dict."""
        return dict(vars(self))


@functools.cache
def _health_kernels(dtype):
    """Build (once per scalar type) the finite / speed and inside-count kernels."""
    vec3 = wp.types.vector(3, dtype)
    kern = kernel_decorator(dtype, "health")


    @kern
    def finite_speed(x: wp.array(dtype=vec3), v: wp.array(dtype=vec3), rep: wp.array(dtype=wp.int32),
                     max_speed2: dtype, bad: wp.array(dtype=wp.int32), fast: wp.array(dtype=wp.int32)):
        i = wp.tid()
        p = x[i]
        u = v[i]
        r = rep[i]
        ok = wp.isfinite(p[0]) and wp.isfinite(p[1]) and wp.isfinite(p[2])
        ok = ok and wp.isfinite(u[0]) and wp.isfinite(u[1]) and wp.isfinite(u[2])
        if not ok:
            bad[r] = 1
        elif wp.dot(u, u) > max_speed2:
            fast[r] = 1

    @kern
    def inside_count(x: wp.array(dtype=vec3), typ: wp.array(dtype=wp.int32), rep: wp.array(dtype=wp.int32),
                     box: wp.array(dtype=vec3), xv: wp.array(dtype=vec3), faces: wp.array(dtype=wp.vec3i),
                     has_shell: wp.array(dtype=wp.int32), center: wp.array(dtype=vec3),
                     rmax: wp.array(dtype=dtype), rmin: wp.array(dtype=dtype), face_off: wp.array(dtype=wp.int32),
                     face_cnt: wp.array(dtype=wp.int32), water_in: wp.array(dtype=wp.int32),
                     gas_out: wp.array(dtype=wp.int32)):
        i = wp.tid()
        r = rep[i]
        t = typ[i]
        if has_shell[r] == 0 or t > 1:
            return
        c = center[r]
        L = box[r]
        d = min_image(x[i] - c, L)
        p = c + d
        dist = wp.length(d)
        inside = wp.bool(False)
        if dist >= rmax[r]:
            inside = False
        elif dist < rmin[r]:
            inside = True
        else:
            wsum = float(0.0)  # noqa: UP018 (a typed, mutable Warp loop variable)
            for k in range(face_off[r], face_off[r] + face_cnt[r]):
                f = faces[k]
                a = xv[f[0]] - p
                b = xv[f[1]] - p
                cc = xv[f[2]] - p
                la = wp.length(a)
                lb = wp.length(b)
                lc = wp.length(cc)
                num = wp.dot(a, wp.cross(b, cc))
                den = la * lb * lc + wp.dot(a, b) * lc + wp.dot(a, cc) * lb + wp.dot(b, cc) * la
                wsum += 2.0 * wp.atan2(float(num), float(den))
            inside = wsum > 2.0 * wp.pi  # winding number > 1/2
        if t == 0 and inside:
            wp.atomic_add(water_in, r, 1)
        if t == 1 and not inside:
            wp.atomic_add(gas_out, r, 1)

    return {"finite_speed": finite_speed, "inside_count": inside_count}


def _point_triangle_distance_min(c: np.ndarray, tri: np.ndarray) -> float:
    """Smallest distance from point c to a set of triangles [F,3,3] (vectorised, exact)."""
    a, b, cc = tri[:, 0] - c, tri[:, 1] - c, tri[:, 2] - c
    # distance to the plane when the projection falls inside, else to the edges
    n = np.cross(b - a, cc - a)
    nn = np.linalg.norm(n, axis=1)
    nn[nn == 0] = 1e-300
    dplane = np.abs(np.einsum("ij,ij->i", a, n)) / nn
    proj = -(np.einsum("ij,ij->i", a, n) / nn**2)[:, None] * n  # projection of origin onto plane, rel. to c
    inside = np.ones(len(tri), dtype=bool)
    for p0, p1 in ((a, b), (b, cc), (cc, a)):
        inside &= np.einsum("ij,ij->i", np.cross(p1 - p0, proj - p0), n) >= 0
    best = np.where(inside, dplane, np.inf)
    for p0, p1 in ((a, b), (b, cc), (cc, a)):
        e = p1 - p0
        t = np.clip(-np.einsum("ij,ij->i", p0, e) / np.maximum(np.einsum("ij,ij->i", e, e), 1e-300), 0, 1)
        best = np.minimum(best, np.linalg.norm(p0 + t[:, None] * e, axis=1))
    return float(best.min())


class HealthMonitor:
    """Runs the checks on a :class:`~bubblecal.sim.engine.system.ParticleSystem` and freezes failed replicas.

    Parameters
    ----------
    config : HealthConfig, optional
        Thresholds (default :class:`HealthConfig`).

    Attributes
    ----------
    reports : list of HealthReport
        One per :meth:`check`.
    """

    def __init__(self, config: HealthConfig | None = None):
        self.config = config or HealthConfig()
        self.reports: list[HealthReport] = []

    def check(self, system) -> HealthReport:
        """Check every replica, write the first failure of each live one into ``system.status`` (synchronises).

        Parameters
        ----------
        system : ParticleSystem
            The system to check.

        Returns
        -------
        HealthReport
            Also appended to :attr:`reports`.
        """
        cfg = self.config
        R, dev = system.R, system.device
        k = _health_kernels(system.dtype)
        status = system.status.numpy().copy()
        new = np.zeros(R, dtype=np.int64)
        bad = wp.zeros(R, dtype=wp.int32, device=dev)
        fast = wp.zeros(R, dtype=wp.int32, device=dev)
        ms2 = cfg.max_speed**2
        wp.launch(k["finite_speed"], dim=system.N, inputs=[system.x, system.v, system.rep, ms2, bad, fast], device=dev)
        if system.Nv:
            wp.launch(k["finite_speed"], dim=system.Nv, inputs=[system.xv, system.vv, system.vrep, ms2, bad, fast],
                      device=dev)
        bad_np, fast_np = bad.numpy(), fast.numpy()
        new[(new == 0) & (bad_np != 0)] = Status.NAN
        new[(new == 0) & (fast_np != 0)] = Status.ESCAPE

        strain = [float("nan")] * R
        amin = [float("nan")] * R
        ninv = [0] * R
        water_in = [0] * R
        gas_out = [0] * R
        if system.Nv:
            xv_all = system.xv.numpy().astype(np.float64)
            centers = np.zeros((R, 3))
            rmax = np.zeros(R)
            rmin = np.zeros(R)
            has = np.zeros(R, dtype=np.int32)
            for r in system.shell_replicas:
                o, n = int(system.vertex_offset[r]), int(system.vertex_count[r])
                fo, fn = int(system.face_offset[r]), int(system.face_count[r])
                xv = xv_all[o:o + n]
                faces = system.faces_np[fo:fo + fn] - o
                if not np.all(np.isfinite(xv)):
                    if new[r] == 0:
                        new[r] = Status.NAN
                    continue
                c = xv.mean(axis=0)
                tri = xv[faces]
                nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
                area = 0.5 * np.linalg.norm(nrm, axis=1)
                a0 = system.ref_area_tri[fo:fo + fn]
                ratio = area / a0
                strain[r] = float(ratio.max() - 1.0)
                amin[r] = float(ratio.min())
                outward = np.einsum("ij,ij->i", nrm, tri.mean(axis=1) - c)
                ninv[r] = int(np.sum((outward <= 0) | (ratio < cfg.min_area_ratio)))
                r_ref = float(np.sqrt(a0.sum() / (4 * math.pi)))
                if new[r] == 0 and np.max(np.linalg.norm(xv - c, axis=1)) > cfg.max_vertex_radius_factor * r_ref:
                    new[r] = Status.ESCAPE
                if new[r] == 0 and ninv[r] > 0:
                    new[r] = Status.INVERSION
                if new[r] == 0 and strain[r] > cfg.rupture_strain:
                    new[r] = Status.RUPTURE
                centers[r] = c
                rmax[r] = float(np.max(np.linalg.norm(xv - c, axis=1))) + 1e-3
                rmin[r] = max(0.0, _point_triangle_distance_min(c, tri) - 1e-3)
                has[r] = 1
            if cfg.check_leaks:
                npf = system.np_dtype
                win = wp.zeros(R, dtype=wp.int32, device=dev)
                gout = wp.zeros(R, dtype=wp.int32, device=dev)
                arr = functools.partial(wp.array, device=dev)
                wp.launch(k["inside_count"], dim=system.N,
                          inputs=[system.x, system.typ, system.rep, system.box, system.xv, system.faces,
                                  arr(has, dtype=wp.int32), arr(centers.astype(npf), dtype=system.vec3),
                                  arr(rmax.astype(npf), dtype=system.dtype), arr(rmin.astype(npf), dtype=system.dtype),
                                  arr(system.face_offset.astype(np.int32), dtype=wp.int32),
                                  arr(system.face_count.astype(np.int32), dtype=wp.int32), win, gout], device=dev)
                water_in = [int(c) for c in win.numpy()]
                gas_out = [int(c) for c in gout.numpy()]
                for r in system.shell_replicas:
                    if new[r] == 0 and water_in[r] + gas_out[r] > cfg.max_leaks:
                        new[r] = Status.LEAK
        changed = (status == 0) & (new != 0)
        if changed.any():
            status[changed] = new[changed]
            system.status.assign(status.astype(np.int32))
        rep = HealthReport(step=int(system.steps_done), status=[Status(int(s)).name for s in status],
                           water_inside=water_in, gas_outside=gas_out, max_area_strain=strain,
                           min_area_ratio=amin, n_inverted=ninv)
        self.reports.append(rep)
        return rep
