"""MD loading protocols (physics.md section 5) for the two thermal fidelity tiers: ``explicit`` (shell +
explicit water and gas, :class:`bubblecal.sim.engine.system.ParticleSystem`) and ``implicit`` (shell +
ideal-gas / back / ambient pressures + Langevin vertices, :class:`bubblecal.sim.engine.implicit.ImplicitShellSystem`).
Both register themselves in :mod:`bubblecal.sim.tiers` (``get_tier('explicit' | 'implicit', **settings)``).

Protocols (same grids and conventions as :class:`bubblecal.sim.tiers.QuasistaticTier`):

* **Compression**: two analytic plates z = z_c +- g, g = h0 + gap - d/2 (h0 = max |z - z_c| of the reference
  mesh = R, ``gap`` = 1 = the LJ range: the plates just touch the reference at d = 0), acting on shell
  vertices only through the capped repulsive LJ of :class:`bubblecal.sim.tiers.quasistatic.PlateContact`
  (eps 1000, sigma 2^(-1/6), r_c 1, force capped at 1e4 per vertex) -- the same law, evaluated in a Warp
  kernel.  For each grid point the plates move symmetrically (each by half of the increment of the TOTAL
  displacement d) linearly over ``ramp_steps``, then stay for ``hold_steps``; the reaction forces on both
  plates are accumulated every step and read every ``sample_every`` steps (block means).  Observable
  F(d) = mean over the hold of (top + bottom) plate force (positive = compressive; the SUM of both plates,
  :data:`bubblecal.sim.tiers.DISPLACEMENT_CONVENTION`).  The bubble's centre-of-mass velocity is pinned.
* **Indentation**: a force -F/k (top) and +F/k (bottom) along z on each of the k = max(1, floor(0.01 N_v))
  top-most / bottom-most reference vertices, ramped linearly between grid points over ``ramp_steps`` and
  held ``hold_steps``; centre of mass pinned; equator vertices (|z - z_c| < 0.25 l_min of the reference)
  anchored in z.  Axial extent H = max z - min z over the vertices, sampled every ``sample_every`` steps;
  observable d(F) = 2 R - mean(H over the last 90 % of the hold's samples), with R the mesh's nominal
  radius (``radius_dpd`` = D/0.5): the published training tables define the initial diameter as 2 * radius
  (reference README section (c), :func:`bubblecal.surrogates.training.read_published`), not as the
  measured H(0).
* Points are chained (each starts from the previous state); a grid point equal to the previous load (the
  first point at 0) is held without a ramp.  Before the first point the system is equilibrated for
  ``equilibration_steps``.
* Status per replica: health checks after the equilibration and after every point
  (:mod:`bubblecal.sim.engine.health` for the explicit tier: non-finite, escape, inversion, rupture by area
  strain, leaks; :meth:`ImplicitShellSystem.check_health` for the implicit tier) mapped to
  :data:`bubblecal.data.names.STATUSES` by :data:`STATUS_MAP`; a failed replica is frozen and its later
  observables are NaN.  ``max_seconds`` turns the replicas still running into 'timeout'.

Defaults = the published protocol (40,000 ramp + 20,000 hold steps per point, samples every 400 steps,
dt = 1e-4); ``scale`` multiplies every step count (tests and smoke runs), see :class:`ProtocolSteps`.

Anchoring in the explicit tier is done through the force: an anchored vertex gets F_z = -m (v_z +
beta (z - z_ref)/dt)/dt, which zeroes its z velocity at the next kick and pulls it back to z_ref
(beta = 0.1); the implicit system anchors natively.
"""

# (no "from __future__ import annotations": Warp must see the closure types of the kernel signatures)

import dataclasses
import functools
import math
import time

import numpy as np
import warp as wp

from bubblecal.sim.engine import pole_patches
from bubblecal.sim.engine.kernels.common import kernel_decorator
from bubblecal.sim.tiers import (
    DEFAULT_INDENTATION_CONVENTION,
    DISPLACEMENT_CONVENTION,
    CurveBatch,
    CurveRequest,
    indentation_convention,
    register_tier,
)
from bubblecal.sim.tiers.quasistatic import PlateContact, _cap_distance

__all__ = ["ProtocolSteps", "ImplicitTier", "ExplicitTier", "STATUS_MAP", "run_md_protocol", "steps_per_curve"]

#: health Status name -> bubblecal.data.names.STATUSES
STATUS_MAP = {"OK": "ok", "NAN": "failed", "ESCAPE": "unstable", "INVERSION": "unstable", "RUPTURE": "ruptured",
              "LEAK": "failed"}
ANCHOR_BETA = 0.1


@dataclasses.dataclass(frozen=True)
class ProtocolSteps:
    """Step counts of one curve (published defaults); ``scaled(s)`` multiplies them (>= 1 sample kept).

    ``ramp_steps`` per load increment, ``hold_steps`` per point, ``sample_every`` (steps between
    samples), ``equilibration_steps`` before the first point (*choice*: 20,000 = 2 DPD time units),
    ``discard_fraction`` of the hold's indentation samples dropped before averaging (0.1).
    """

    ramp_steps: int = 40_000
    hold_steps: int = 20_000
    sample_every: int = 400
    equilibration_steps: int = 20_000
    discard_fraction: float = 0.1

    def __post_init__(self) -> None:
        for name in ("ramp_steps", "hold_steps", "sample_every", "equilibration_steps"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
                raise ValueError(f"ProtocolSteps.{name} must be an integer >= 0, got {v!r}")
        if self.sample_every < 1 or self.hold_steps < self.sample_every:
            raise ValueError("ProtocolSteps: need sample_every >= 1 and hold_steps >= sample_every")
        if not (0.0 <= self.discard_fraction < 1.0):
            raise ValueError(f"ProtocolSteps.discard_fraction must lie in [0, 1), got {self.discard_fraction!r}")

    def scaled(self, scale: float) -> "ProtocolSteps":
        """Every step count x ``scale`` (sample_every too, >= 1; hold >= one sample)."""
        if not (math.isfinite(scale) and scale > 0):
            raise ValueError(f"scale must be a positive number, got {scale!r}")
        if scale == 1.0:
            return self
        se = max(1, int(round(self.sample_every * scale)))
        return dataclasses.replace(self, ramp_steps=int(round(self.ramp_steps * scale)),
                                   hold_steps=max(se, int(round(self.hold_steps * scale / se)) * se),
                                   sample_every=se,
                                   equilibration_steps=int(round(self.equilibration_steps * scale)))


def steps_per_curve(steps: ProtocolSteps, grid) -> int:
    """Total MD steps of one chained curve on ``grid`` (ramps skipped where the load does not change)."""
    g = np.asarray(grid, dtype=np.float64)
    n_ramps = int(np.sum(np.diff(np.concatenate([[0.0], g])) != 0))
    return steps.equilibration_steps + n_ramps * steps.ramp_steps + len(g) * steps.hold_steps


# ------------------------------------------------------------------------------------------------
# kernels
# ------------------------------------------------------------------------------------------------
@functools.cache
def _kernels(dtype):
    T = dtype
    V = wp.types.vector(3, T)
    kern = kernel_decorator(dtype, "mdload")

    @wp.func
    def ramp_value(state: wp.array(dtype=wp.float64), step: wp.int32) -> wp.float64:
        # state = (value_from, value_to, step0, ramp_steps)
        s = wp.float64(step) - state[2]
        u = wp.float64(1.0)
        if state[3] > wp.float64(0.0):
            u = wp.clamp(s / state[3], wp.float64(0.0), wp.float64(1.0))
        return state[0] + (state[1] - state[0]) * u

    @wp.func
    def wall_force(h: T, eps: T, sig: T, rc: T, hcap: T, cap: T) -> T:
        fm = T(0.0)
        if h < rc:
            if h <= hcap:
                fm = cap
            else:
                s2 = sig * sig / (h * h)
                s6 = s2 * s2 * s2
                fm = T(24.0) * eps * (T(2.0) * s6 * s6 - s6) / h
        return fm

    @kern
    def plates(x: wp.array(dtype=V), f: wp.array(dtype=V), vrep: wp.array(dtype=wp.int32),
               status: wp.array(dtype=wp.int32), zc: wp.array(dtype=T), state: wp.array(dtype=wp.float64),
               step: wp.array(dtype=wp.int32), lj: wp.array(dtype=T), acc: wp.array2d(dtype=wp.float64)):
        """Analytic plates z = zc +- g(step) (g ramped); capped WCA on every vertex; reactions into acc."""
        i = wp.tid()
        r = vrep[i]
        if status[r] != 0:
            return
        g = T(ramp_value(state, step[0]))
        z = x[i][2]
        ft = wall_force(zc[r] + g - z, lj[0], lj[1], lj[2], lj[3], lj[4])
        fb = wall_force(z - (zc[r] - g), lj[0], lj[1], lj[2], lj[3], lj[4])
        if ft != T(0.0) or fb != T(0.0):
            f[i] = f[i] + V(T(0.0), T(0.0), fb - ft)
            wp.atomic_add(acc, r, 0, wp.float64(ft))
            wp.atomic_add(acc, r, 1, wp.float64(fb))

    @kern
    def pole_forces(f: wp.array(dtype=V), rows: wp.array(dtype=wp.int32), sign: wp.array(dtype=T),
                    vrep: wp.array(dtype=wp.int32), status: wp.array(dtype=wp.int32),
                    state: wp.array(dtype=wp.float64), step: wp.array(dtype=wp.int32), inv_k: T):
        """Force sign * F(step)/k along z on the loaded vertices (sign -1 top, +1 bottom)."""
        j = wp.tid()
        i = rows[j]
        if status[vrep[i]] != 0:
            return
        fz = sign[j] * T(ramp_value(state, step[0])) * inv_k
        f[i] = f[i] + V(T(0.0), T(0.0), fz)

    @kern
    def anchor_forces(x: wp.array(dtype=V), v: wp.array(dtype=V), f: wp.array(dtype=V),
                      rows: wp.array(dtype=wp.int32), zref: wp.array(dtype=T), vrep: wp.array(dtype=wp.int32),
                      mass: wp.array(dtype=T), status: wp.array(dtype=wp.int32), dt: T, beta: T):
        """Explicit tier: F_z = -m (v_z + beta (z - z_ref)/dt)/dt on anchored vertices (overrides F_z)."""
        j = wp.tid()
        i = rows[j]
        r = vrep[i]
        if status[r] != 0:
            return
        fi = f[i]
        fz = -mass[r] * (v[i][2] + beta * (x[i][2] - zref[j]) / dt) / dt
        f[i] = V(fi[0], fi[1], fz)

    @kern
    def z_extent(x: wp.array(dtype=V), vrep: wp.array(dtype=wp.int32), zmax: wp.array(dtype=T),
                 zmin: wp.array(dtype=T)):
        i = wp.tid()
        r = vrep[i]
        z = x[i][2]
        if wp.isfinite(z):
            wp.atomic_max(zmax, r, z)
            wp.atomic_min(zmin, r, z)

    return {"plates": plates, "pole_forces": pole_forces, "anchor_forces": anchor_forces, "z_extent": z_extent}


# ------------------------------------------------------------------------------------------------
# adapters: one interface over the two systems
# ------------------------------------------------------------------------------------------------
class _ImplicitAdapter:
    def __init__(self, system, thresholds):
        self.s = system
        self.th = thresholds
        self.x, self.vrep, self.status = system.x, system.vrep, system.status
        self.step_counter = system.step_counter
        self.device, self.dtype, self.np_dtype = system.device, system.dtype, system.np_dtype
        self.R = system.R
        self.zc = np.zeros(self.R)  # meshes are centred at the origin
        self.offsets, self.counts = system.offsets, system.n_vertices

    def f(self):
        return self.s.f

    def add_callback(self, cb):
        self.s.add_force_callback(lambda _s: cb())

    def anchor(self, rows: np.ndarray) -> None:
        mask = np.zeros(self.s.N, dtype=bool)
        mask[rows] = True
        self.s.set_anchor_z(mask)

    def advance(self, n: int) -> None:
        if n > 0:
            self.s.step(n)

    def health(self) -> list[str]:
        return self.s.check_health(self.th)["status"]

    def positions(self) -> np.ndarray:
        return self.s.x.numpy().astype(np.float64)


class _ExplicitAdapter:
    def __init__(self, system, monitor):
        from bubblecal.sim.engine.particles import VERTEX

        self.s = system
        self.monitor = monitor
        self.x, self.vrep, self.status = system.xv, system.vrep, system.status
        self.step_counter = system.step_counter
        self.device, self.dtype, self.np_dtype = system.device, system.dtype, system.np_dtype
        self.R = system.R
        self.zc = np.array([(np.asarray(sp.box, float) / 2 if sp.center is None else np.asarray(sp.center, float))[2]
                            for sp in system.specs])
        self.offsets, self.counts = system.vertex_offset, system.vertex_count
        self.mass = wp.array(system.mass_np[:, VERTEX].astype(self.np_dtype), dtype=self.dtype, device=self.device)

    def f(self):
        return self.s.fv

    def add_callback(self, cb):
        self.s.force_callbacks.append(lambda _s: cb())

    def anchor(self, rows: np.ndarray) -> None:
        k = _kernels(self.dtype)
        zref = self.s.xv.numpy()[rows, 2].astype(self.np_dtype)
        rows_w = wp.array(rows.astype(np.int32), dtype=wp.int32, device=self.device)
        zref_w = wp.array(zref, dtype=self.dtype, device=self.device)
        s = self.s
        dt, beta = self.dtype(s.dt), self.dtype(ANCHOR_BETA)

        def cb():
            wp.launch(k["anchor_forces"], dim=len(rows),
                      inputs=[s.xv, s.vv, s.fv, rows_w, zref_w, s.vrep, self.mass, s.status, dt, beta],
                      device=self.device)

        self._anchor_cb = cb  # added last, after the pole forces (it overrides F_z)

    def finalize_callbacks(self):
        if getattr(self, "_anchor_cb", None) is not None:
            self.add_callback(self._anchor_cb)

    def advance(self, n: int) -> None:
        if n > 0:
            self.s.step(n)

    def health(self) -> list[str]:
        return self.monitor.check(self.s).status

    def positions(self) -> np.ndarray:
        return self.s.xv.numpy().astype(np.float64)


# ------------------------------------------------------------------------------------------------
# the protocol (shared by both tiers)
# ------------------------------------------------------------------------------------------------
def run_md_protocol(adapter, mesh, protocol: str, grid: np.ndarray, steps: ProtocolSteps,
                    contact: PlateContact = PlateContact(), pole_patch: dict | None = None,
                    max_seconds: float | None = None, progress=None) -> dict:
    """Run the chained protocol on an adapted system; returns observables [R, P] and per-point data.

    ``mesh``: the (shared) reference mesh, centred at the origin (DPD length); ``grid``: total
    displacements (compression, DPD length) or forces per pole (indentation, DPD force).  ``pole_patch``:
    keyword arguments of :func:`bubblecal.sim.engine.pole_patches` (default ``{"fraction": 0.01}``).
    """
    t0 = time.perf_counter()
    k = _kernels(adapter.dtype)
    dev, R, P = adapter.device, adapter.R, len(grid)
    z0 = mesh.vertices[:, 2]
    state = wp.array(np.zeros(4), dtype=wp.float64, device=dev)
    status = ["ok"] * R
    point_status = [["ok"] * P for _ in range(R)]
    # the health check's own verdict (e.g. NAN vs LEAK, both 'failed') and the point it came at, per replica
    health = [None] * R
    obs = np.full((R, P), np.nan)
    extra: dict[str, np.ndarray] = {}
    offsets = np.asarray(adapter.offsets, dtype=np.int64)
    N = int(np.max(offsets + np.asarray(adapter.counts)))

    if protocol == "compression":
        h0 = float(np.max(np.abs(z0 - z0.mean())))
        hcap = _cap_distance(contact.epsilon, contact.sigma, contact.force_cap)
        lj = wp.array(np.array([contact.epsilon, contact.sigma, contact.cutoff, hcap, contact.force_cap],
                               dtype=adapter.np_dtype), dtype=adapter.dtype, device=dev)
        zc = wp.array(adapter.zc.astype(adapter.np_dtype), dtype=adapter.dtype, device=dev)
        acc = wp.zeros((R, 2), dtype=wp.float64, device=dev)
        values = h0 + contact.gap - np.asarray(grid) / 2.0  # plate half-gap g per point
        start_value = h0 + contact.gap
        if np.any(values <= 0.5 * contact.cutoff):
            raise ValueError(f"compression grid too large for this bubble: d must stay below {2 * h0:.3f}")

        def plates_cb():
            wp.launch(k["plates"], dim=N, inputs=[adapter.x, adapter.f(), adapter.vrep, adapter.status, zc, state,
                                                  adapter.step_counter, lj, acc], device=dev)

        adapter.add_callback(plates_cb)
        extra["force_top"] = np.full((R, P), np.nan)
        extra["force_bottom"] = np.full((R, P), np.nan)
        extra["force_sem"] = np.full((R, P), np.nan)
    else:
        top, bottom = pole_patches(mesh.vertices, **(pole_patch or {"fraction": 0.01}))
        kk = len(top)
        rows = np.concatenate([np.concatenate([o + top, o + bottom]) for o in offsets]).astype(np.int32)
        sign = np.tile(np.concatenate([-np.ones(kk), np.ones(kk)]), R).astype(adapter.np_dtype)
        rows_w = wp.array(rows, dtype=wp.int32, device=dev)
        sign_w = wp.array(sign, dtype=adapter.dtype, device=dev)
        inv_k = adapter.dtype(1.0 / kk)

        def poles_cb():
            wp.launch(k["pole_forces"], dim=len(rows), inputs=[adapter.f(), rows_w, sign_w, adapter.vrep,
                                                               adapter.status, state, adapter.step_counter, inv_k],
                      device=dev)

        adapter.add_callback(poles_cb)
        equator = np.nonzero(np.abs(z0 - z0.mean()) < 0.25 * mesh.min_edge_length())[0]
        adapter.anchor(np.concatenate([o + equator for o in offsets]).astype(np.int64))
        values = np.asarray(grid, dtype=np.float64)
        start_value = 0.0
        zmax = wp.zeros(R, dtype=adapter.dtype, device=dev)
        zmin = wp.zeros(R, dtype=adapter.dtype, device=dev)
        big = 1e30 if adapter.dtype is wp.float64 else 3e38
        d_ref = 2.0 * float(mesh.radius_dpd if mesh.radius_dpd > 0 else np.max(z0) - np.min(z0))
        extra["axial_diameter"] = np.full((R, P), np.nan)
        extra["axial_sem"] = np.full((R, P), np.nan)

        def extent():
            zmax.fill_(-big)
            zmin.fill_(big)
            wp.launch(k["z_extent"], dim=N, inputs=[adapter.x, adapter.vrep, zmax, zmin], device=dev)
            return zmax.numpy().astype(np.float64) - zmin.numpy().astype(np.float64)
    if hasattr(adapter, "finalize_callbacks"):
        adapter.finalize_callbacks()

    def set_ramp(v_from, v_to, n_ramp):
        state.assign(np.array([v_from, v_to, float(adapter_steps[0]), float(n_ramp)]))

    adapter_steps = [0]  # steps advanced so far (the device step counter starts at 0)

    def advance(n):
        adapter.advance(n)
        adapter_steps[0] += n

    def apply_health(j_done: int, where: str | None = None):
        names = adapter.health()
        for r, nm in enumerate(names):
            ts = STATUS_MAP.get(nm, "failed")
            if status[r] == "ok" and ts != "ok":
                status[r] = ts
                health[r] = {"check": nm, "at": where or f"point {j_done + 1}"}
                for jj in range(max(j_done, 0), P):
                    point_status[r][jj] = ts
                if j_done >= 0 and j_done < P:
                    obs[r, j_done:] = np.nan

    def timed_out() -> bool:
        return max_seconds is not None and time.perf_counter() - t0 > max_seconds

    set_ramp(start_value, start_value, 0)
    advance(steps.equilibration_steps)
    apply_health(0, "equilibration")
    h_eq = extent() if protocol == "indentation" else None
    prev = start_value
    n_samples = steps.hold_steps // steps.sample_every
    for j in range(P):
        if timed_out():
            for r in range(R):
                if status[r] == "ok":
                    status[r] = "timeout"
                    for jj in range(j, P):
                        point_status[r][jj] = "timeout"
            break
        target = float(values[j])
        ramp = steps.ramp_steps if target != prev else 0
        set_ramp(prev, target, ramp)
        advance(ramp)
        set_ramp(target, target, 0)
        samples = []
        if protocol == "compression":
            acc.zero_()
            last = np.zeros((R, 2))
            for _ in range(n_samples):
                advance(steps.sample_every)
                a = acc.numpy().copy()
                samples.append((a - last) / steps.sample_every)
                last = a
            s = np.asarray(samples)  # [S, R, 2] block means
            top, bot = s[:, :, 0].mean(axis=0), s[:, :, 1].mean(axis=0)
            tot = s.sum(axis=2)
            obs[:, j] = top + bot
            extra["force_top"][:, j] = top
            extra["force_bottom"][:, j] = bot
            extra["force_sem"][:, j] = tot.std(axis=0, ddof=1) / math.sqrt(len(tot)) if len(tot) > 1 else np.nan
        else:
            for _ in range(n_samples):
                advance(steps.sample_every)
                samples.append(extent())
            s = np.asarray(samples)  # [S, R]
            keep = s[int(math.floor(steps.discard_fraction * len(s))):] if len(s) > 1 else s
            obs[:, j] = d_ref - keep.mean(axis=0)
            extra["axial_diameter"][:, j] = keep.mean(axis=0)
            extra["axial_sem"][:, j] = keep.std(axis=0, ddof=1) / math.sqrt(len(keep)) if len(keep) > 1 else np.nan
        prev = target
        apply_health(j)
        if progress is not None:
            progress(j + 1, P, time.perf_counter() - t0)
    for r in range(R):
        if status[r] != "ok":
            for j in range(P):
                if point_status[r][j] != "ok":
                    obs[r, j] = np.nan
    out = {"observable": obs, "status": status, "point_status": point_status, "health": health,
           "steps": adapter_steps[0],
           "seconds": time.perf_counter() - t0, **{k_: v.tolist() for k_, v in extra.items()}}
    if h_eq is not None:
        out["axial_diameter_equilibrated"] = h_eq.tolist()
        out["initial_diameter_reference"] = d_ref
    return out


# ------------------------------------------------------------------------------------------------
# tiers
# ------------------------------------------------------------------------------------------------
def _vertex_mass(mesh, protocol: str, mass_factor: float = 1.0) -> float:
    from bubblecal.sim.engine.particles import RHO_SHELL_KG_M3

    rho = RHO_SHELL_KG_M3 * (5.0 if protocol == "indentation" else 1.0)
    return mesh.vertex_mass(rho, mass_factor=mass_factor)


@dataclasses.dataclass
class _MDTierBase:
    subdivisions: int | None = None
    ramp_steps: int = 40_000
    hold_steps: int = 20_000
    sample_every: int = 400
    equilibration_steps: int = 20_000
    scale: float = 1.0
    dt: float = 1e-4
    kbt: float = 1.0
    contact: PlateContact = PlateContact()
    dtype: str = "float32"
    rupture_strain: float = 1.0
    max_seconds: float | None = None
    verbose: bool = False
    indentation_convention: str = DEFAULT_INDENTATION_CONVENTION

    def __post_init__(self) -> None:
        indentation_convention(self.indentation_convention)  # a bad name fails before any set-up

    def _convention(self):
        return indentation_convention(self.indentation_convention)

    def protocol_steps(self) -> ProtocolSteps:
        """The step counts this tier runs (published counts x ``scale``)."""
        return ProtocolSteps(ramp_steps=self.ramp_steps, hold_steps=self.hold_steps, sample_every=self.sample_every,
                             equilibration_steps=self.equilibration_steps).scaled(self.scale)

    def _mesh(self, request: CurveRequest):
        from bubblecal.sim.engine.mesh import mesh_for_diameter

        sub = self.subdivisions if self.subdivisions is not None else request.subdivisions
        return mesh_for_diameter(request.diameter_um, sub)

    def _progress(self):
        if not self.verbose:
            return None

        def cb(j, P, sec):
            eta = sec / j * (P - j)
            print(f"  [{self.name}] point {j}/{P}  {sec:.1f} s  ETA {eta:.1f} s", flush=True)

        return cb

    def _batch(self, request, mesh, out, info, t0) -> CurveBatch:
        steps = self.protocol_steps()
        info.update({"tier": self.name, "mesh_subdivisions": mesh.subdivisions, "n_vertices": mesh.n_vertices,
                     "displacement_convention": DISPLACEMENT_CONVENTION if request.protocol == "compression" else None,
                     "protocol_steps": dataclasses.asdict(steps), "dt": self.dt, "md_steps": out["steps"],
                     "indentation_convention": self.indentation_convention if request.protocol == "indentation"
                     else None,
                     "point_status": out["point_status"], "health": out["health"], "contact": {**dataclasses.asdict(self.contact),
                                                                      "cutoff": self.contact.cutoff}})
        for key in ("force_top", "force_bottom", "force_sem", "axial_diameter", "axial_sem",
                    "axial_diameter_equilibrated", "initial_diameter_reference"):
            if key in out:
                info[key] = out[key]
        return CurveBatch(tier=self.name, request=request, observable=out["observable"], status=out["status"],
                          info=info, seconds=time.perf_counter() - t0)


@dataclasses.dataclass
class ImplicitTier(_MDTierBase):
    """Implicit-solvent MD tier: :class:`bubblecal.sim.engine.implicit.ImplicitShellSystem` (shell + ideal gas
    p0 V0/V + back pressure ``p_back`` - ambient ``p_water`` (None = balanced at the reference) +
    Langevin vertices, friction ``gamma`` (None = published vertex-water estimate)) under the protocols of
    this module.  All R replicas of a request run in the same launches (one mesh)."""

    p0: float = 3.0
    p_back: float = 91.0
    p_water: float | None = None
    gamma: float | None = None
    mass_factor: float = 1.0
    name: str = "implicit"

    def run(self, request: CurveRequest, device: str = "cpu") -> CurveBatch:
        """Simulate ``request`` (units: :class:`CurveRequest`) on Warp ``device``."""
        from bubblecal.sim.engine import (
            HealthThresholds,
            ImplicitShellSystem,
            default_vertex_friction,
        )

        t0 = time.perf_counter()
        mesh = self._mesh(request)
        gamma = default_vertex_friction(mesh, request.protocol) if self.gamma is None else self.gamma
        system = ImplicitShellSystem(mesh, request.shell_params(self.indentation_convention), p0=self.p0, p_back=self.p_back,
                                     p_water=self.p_water, kbt=self.kbt, gamma=gamma,
                                     vertex_mass=_vertex_mass(mesh, request.protocol, self.mass_factor), dt=self.dt,
                                     device=device, dtype=self.dtype, seed=list(request.seeds), pin_com=True)
        adapter = _ImplicitAdapter(system, HealthThresholds(rupture_strain=self.rupture_strain))
        out = run_md_protocol(adapter, mesh, request.protocol, request.grid_array(), self.protocol_steps(),
                              self.contact, pole_patch=self._convention().pole_patch(),
                              max_seconds=self.max_seconds, progress=self._progress())
        info = {"system": system.settings(), "memory_bytes": system.memory_bytes()}
        info["system"].pop("n_vertices", None)
        return self._batch(request, mesh, out, info, t0)


@dataclasses.dataclass
class ExplicitTier(_MDTierBase):
    """Explicit-solvent MD tier: R :func:`bubblecal.sim.engine.bubble_spec` replicas (published water,
    gas at ``gas_density``, bounce-back, per-replica shell parameters, back pressure ``p_back``) in one
    :class:`bubblecal.sim.engine.system.ParticleSystem`, under the protocols of this module.  ``box`` (None =
    (2R+5, 2R+5, 2R+10)), ``a_vertex_water`` (None = 400 compression / 40 indentation), ``water_gap``,
    ``chunk`` (engine steps per CUDA graph), ``health_leaks`` (count leaks at every health check)."""

    gas_density: float = 3.0
    p_back: float = 91.0
    box: tuple | None = None
    a_vertex_water: float | None = None
    water_gap: float = 0.5
    mass_factor: float = 1.0
    chunk: int = 20
    health_leaks: bool = True
    name: str = "explicit"

    def run(self, request: CurveRequest, device: str = "cpu") -> CurveBatch:
        """Simulate ``request`` (units: :class:`CurveRequest`) on Warp ``device``."""
        from bubblecal.sim.engine import ParticleSystem, bubble_spec
        from bubblecal.sim.engine.health import HealthConfig, HealthMonitor

        t0 = time.perf_counter()
        mesh = self._mesh(request)
        specs = []
        for p, seed in zip(request.shell_params(self.indentation_convention), request.seeds, strict=True):
            sp = bubble_spec(request.diameter_um, mesh.subdivisions, box=self.box, seed=seed, ka=p.ka, kb=p.kb,
                             p_back=self.p_back, gas_density=self.gas_density, protocol=request.protocol,
                             mass_factor=self.mass_factor, a_vertex_water=self.a_vertex_water, kbt=self.kbt,
                             mu=p.mu, b1=p.b1, b2=p.b2, a3=p.a3, a4=p.a4)
            sp.pin_com = True
            sp.water_gap = self.water_gap
            specs.append(sp)
        system = ParticleSystem(specs, dt=self.dt, device=device, dtype=self.dtype, chunk=self.chunk)
        monitor = HealthMonitor(HealthConfig(rupture_strain=self.rupture_strain, check_leaks=self.health_leaks))
        adapter = _ExplicitAdapter(system, monitor)
        out = run_md_protocol(adapter, mesh, request.protocol, request.grid_array(), self.protocol_steps(),
                              self.contact, pole_patch=self._convention().pole_patch(),
                              max_seconds=self.max_seconds, progress=self._progress())
        counts = system.solvent_counts()
        info = {"n_particles": int(system.N + system.Nv), "solvent_counts": counts.tolist(),
                "box": list(map(float, specs[0].box)), "memory_bytes": system.memory_bytes(),
                "health_last": monitor.reports[-1].as_dict() if monitor.reports else None}
        return self._batch(request, mesh, out, info, t0)


register_tier("implicit", ImplicitTier)
register_tier("explicit", ExplicitTier)
