"""Ringdown protocol (physics.md section 5, check 7): perturb the bubble radius, record R(t).

After equilibration every replica's shell is scaled radially by ``1 + perturbation`` about its
centroid and the free oscillation of R(t) = (3 V / 4 pi)^(1/3) (V: enclosed volume of the mesh, DPD
length^3) is recorded.  The fit R0 + c t + exp(-lam t)[A sin w_d t + B cos w_d t] lives in
:mod:`bubblecal.surrogates.ringdown` (``sim`` may not import ``surrogates``): the sweep pipeline
:mod:`bubblecal.workflows.acoustic_sweep` does the fitting and the unit conversion.

Mass scaling: the shell vertex mass is multiplied by ``mass_factor`` (160 in the published sweeps) so
that the breathing mode is slow and clean; a frequency converts back with f = f_dpd sqrt(mass_factor)
(:meth:`bubblecal.data.units.UnitSystem.frequency_to_physical`).  f ~ M^(-1/2) holds exactly only if
the shell's own inertia is the only one: :func:`breathing_mode_prediction` gives both the check-7
value (shell mass only) and an estimate with the water's added mass (explicit tier).

Tiers
-----
``explicit``: :class:`bubblecal.sim.engine.system.ParticleSystem` replicas (:func:`bubblecal.sim.engine.bubble_spec`:
shell + explicit water and ideal gas, bounce-back), R replicas in the same launches.  The
perturbation is a homothety about the shell's centroid with factor 1 + perturbation applied to the
shell vertices, the gas inside (so its density follows the volume: p V stays the isothermal N k_BT) and
the water out to the largest vertex distance R_a; beyond it the water's radial shift decays linearly
to zero over ``water_layer`` (default 2 DPD lengths).  A homothety maps inside to inside and outside to
outside exactly, and the radial map is monotone (shift slope > -1), so no particle changes side, no
particle order is swapped, and nothing needs deleting; the price is a water density excess of
~ perturbation R_a / water_layer in that layer, which leaves as a pressure pulse.  Velocities are kept.

``implicit``: :class:`bubblecal.sim.engine.implicit.ImplicitShellSystem` (shell + ideal-gas pressure-volume
law + back and ambient pressure + vertex thermostat; written by the tier module's author).  Only the
vertices are scaled; the gas law follows the volume by construction.

Status per replica is one of :data:`bubblecal.data.names.STATUSES` (explicit: from
:class:`bubblecal.sim.engine.health.HealthMonitor`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from bubblecal.data import STATUSES

__all__ = [
    "RingdownBatch",
    "ringdown_batch",
    "breathing_mode_prediction",
    "auto_schedule",
    "RINGDOWN_TIERS",
    "WATER_BULK_MODULUS_DPD",
    "WATER_MASS_DENSITY_DPD",
]

RINGDOWN_TIERS = ("explicit", "implicit")
#: Mass density of DPD water (bead mass 1 x number density 3), DPD mass / length^3.
WATER_MASS_DENSITY_DPD = 3.0
#: Isothermal bulk modulus rho dP/drho of DPD water at a = 100, rho = 3 from the check-1 pressure
#: 89.05 = rho + alpha a rho^2 (alpha = 0.0956): K = rho (1 + 2 alpha a rho) = rho + 2 (P - rho) ~ 175 DPD pressure.
WATER_BULK_MODULUS_DPD = 3.0 + 2.0 * (89.05 - 3.0)

_HEALTH_TO_STATUS = {"OK": "ok", "NAN": "failed", "ESCAPE": "unstable", "INVERSION": "unstable",
                     "RUPTURE": "ruptured", "LEAK": "failed"}
_PARAM_DEFAULTS = {"b1": 0.0, "b2": 0.0, "a3": 0.0, "a4": 0.0}


@dataclass
class RingdownBatch:
    """R ringdown traces of one diameter.

    ``t [T]``: DPD time since the perturbation (t = 0 is the first sample, taken right after it).
    ``radius [R, T]``: R(t) = (3 V / 4 pi)^(1/3) of each replica's mesh (DPD length).
    ``status [R]``: from :data:`bubblecal.data.names.STATUSES`.
    ``params``: the shell parameters (DPD; mu = ka / 3) per replica, ``seeds``: one per replica.
    ``info``: settings (tier, dt, steps, mass factor, perturbation, ...), ``vertex_mass`` (DPD mass,
    mass factor included), ``n_vertices``, ``shell_mass`` (= n_vertices x vertex_mass),
    ``radius_reference`` (mesh radius), ``radius_equilibrium [R]`` (mean R over the last 10 % of
    equilibration), ``p_gas [R]`` (ideal-gas pressure inside, DPD), ``prediction``
    (:func:`breathing_mode_prediction` per replica).
    ``vertices [R, Tv, Nv', 3]`` (float32, DPD length) and ``vertex_t [Tv]`` when recorded: every
    ``vertex_every``-th record, the first Nv' = ``vertex_indices.size`` vertices (an icosphere's first
    10 4^k + 2 vertices are the coarser icosphere of level k, so the subset stays uniform).
    """

    t: np.ndarray
    radius: np.ndarray
    status: list[str]
    params: dict[str, np.ndarray]
    seeds: tuple[int, ...]
    info: dict = field(default_factory=dict)
    vertices: np.ndarray | None = None
    vertex_t: np.ndarray | None = None
    vertex_indices: np.ndarray | None = None
    seconds: float = 0.0

    def __post_init__(self) -> None:
        self.t = np.asarray(self.t, dtype=np.float64)
        self.radius = np.asarray(self.radius, dtype=np.float64)
        R = len(self.seeds)
        if self.radius.shape != (R, self.t.size):
            raise ValueError(f"RingdownBatch.radius must have shape {(R, self.t.size)}, got {self.radius.shape}")
        bad = [s for s in self.status if s not in STATUSES]
        if len(self.status) != R or bad:
            raise ValueError(f"RingdownBatch.status must be {R} values from {STATUSES}, got {self.status!r}")

    @property
    def n_replicas(self) -> int:
        return len(self.seeds)

    @property
    def ok(self) -> np.ndarray:
        """Boolean mask [R]: status 'ok' and a finite trace."""
        return np.array([s == "ok" for s in self.status]) & np.all(np.isfinite(self.radius), axis=1)


# ------------------------------------------------------------------------------------------------
# predictions (physics.md check 7)
# ------------------------------------------------------------------------------------------------
def breathing_mode_prediction(ka, radius, p_gas, shell_mass, *, area_ratio: float = 1.0, explicit: bool = False,
                              box=None,
                              rho_water: float = WATER_MASS_DENSITY_DPD,
                              bulk_modulus: float = WATER_BULK_MODULUS_DPD) -> dict[str, np.ndarray]:
    """Breathing-mode natural angular frequency of a spherical shell (DPD units, rad per DPD time).

    Check 7 (physics.md section 6): ``omega0_sq = (16 pi ka + 12 pi R p_gas) / M``: Lim area term
    E = 8 pi ka x^2 for a radial displacement x (alpha = 2 x / R, shear and stress-free Kantor bending
    vanish for a uniform dilation) plus the isothermal gas (dp = -3 p x / R over 4 pi R^2).  ``ka`` DPD
    2-D modulus, ``radius`` R DPD length, ``p_gas`` DPD pressure, ``shell_mass`` M = N_v m_v (mass
    factor included) DPD mass.

    Mesh correction: on a triangulated sphere whose N_v equal-mass vertices lie at radius r_v the uniform
    dilation gives 16 pi ka A_mesh / (4 pi r_v^2) instead of 16 pi ka (``area_ratio`` = A_mesh / (4 pi r_v^2):
    0.928, 0.981, 0.995, 0.9988 for icosphere subdivisions 1-4); returned as ``omega0_sq_mesh``.

    With ``explicit=True`` the water's effect is estimated as well: added mass of the radial flow
    4 pi rho R^3 (1 - R / R_box) (R_box = radius of the sphere of the box volume) and the stiffness of
    compressing the periodic box's water, K (4 pi R^2)^2 / V_water; returned as ``omega0_sq_water``.
    Arrays broadcast; returns ``omega0_sq`` (check 7), ``omega0`` and, if explicit, the water terms.
    """
    ka = np.asarray(ka, dtype=np.float64)
    R = np.asarray(radius, dtype=np.float64)
    p = np.asarray(p_gas, dtype=np.float64)
    M = np.asarray(shell_mass, dtype=np.float64)
    k_shell = 16.0 * math.pi * ka
    k_gas = 12.0 * math.pi * R * p
    w2 = (k_shell + k_gas) / M
    w2m = (k_shell * float(area_ratio) + k_gas) / M
    out = {"k_shell": k_shell, "k_gas": k_gas, "shell_mass": M, "omega0_sq": w2, "omega0": np.sqrt(w2),
           "area_ratio": np.full_like(w2, float(area_ratio)), "omega0_sq_mesh": w2m}
    if explicit:
        if box is None:
            raise ValueError("breathing_mode_prediction(explicit=True) needs the box edge lengths")
        vbox = float(np.prod(np.asarray(box, dtype=np.float64)))
        r_box = (3.0 * vbox / (4.0 * math.pi)) ** (1.0 / 3.0)
        m_add = 4.0 * math.pi * rho_water * R**3 * np.clip(1.0 - R / r_box, 0.0, None)
        v_water = vbox - 4.0 / 3.0 * math.pi * R**3
        k_box = bulk_modulus * (4.0 * math.pi * R**2) ** 2 / v_water
        w2w = (k_shell + k_gas + k_box) / (M + m_add)
        out.update({"added_mass": m_add, "k_water_box": k_box, "omega0_sq_water": w2w, "omega0_water": np.sqrt(w2w)})
    return out


def auto_schedule(omega_min: float, omega_max: float, dt: float, *, n_periods: float = 8.0,
                  samples_per_period: int = 40, equilibration_periods: float = 2.0,
                  min_equilibration: int = 1000) -> dict[str, int]:
    """Step counts for a ringdown from the expected angular frequencies (rad per DPD time).

    ``record_every`` gives >= ``samples_per_period`` samples per shortest period; ``record_steps`` covers
    ``n_periods`` of the longest period; ``equilibration_steps`` ``equilibration_periods`` of it (at
    least ``min_equilibration``).  All in steps of ``dt``.
    """
    if not (omega_min > 0 and omega_max >= omega_min and dt > 0):
        raise ValueError(f"auto_schedule needs 0 < omega_min <= omega_max and dt > 0, got {omega_min}, "
                         f"{omega_max}, {dt}")
    t_short = 2.0 * math.pi / omega_max
    t_long = 2.0 * math.pi / omega_min
    every = max(1, int(t_short / (samples_per_period * dt)))
    rec = int(math.ceil(n_periods * t_long / dt / every)) * every
    eq = max(int(min_equilibration), int(math.ceil(equilibration_periods * t_long / dt)))
    return {"record_every": every, "record_steps": rec, "equilibration_steps": eq}


# ------------------------------------------------------------------------------------------------
# helpers
# ------------------------------------------------------------------------------------------------
def _check_params(params: Mapping[str, np.ndarray], seeds) -> tuple[dict[str, np.ndarray], tuple[int, ...]]:
    if "ka" not in params or "kb" not in params:
        raise ValueError(f"ringdown params need at least 'ka' and 'kb' (DPD), got {sorted(params)}")
    out = {}
    n = None
    for k in ("ka", "kb", "b1", "b2", "a3", "a4"):
        v = params.get(k, None)
        a = None if v is None else np.atleast_1d(np.asarray(v, dtype=np.float64))
        if a is not None:
            if a.ndim != 1:
                raise ValueError(f"ringdown params[{k!r}] must be 1-D [R], got shape {a.shape}")
            if n is None:
                n = a.size
            elif a.size != n:
                raise ValueError(f"ringdown params must all have the same length R, {k!r} has {a.size} != {n}")
            if not np.all(np.isfinite(a)):
                raise ValueError(f"ringdown params[{k!r}] must be finite")
        out[k] = a
    for k, d in _PARAM_DEFAULTS.items():
        if out[k] is None:
            out[k] = np.full(n, d)
    if np.any(out["ka"] <= 0) or np.any(out["kb"] < 0):
        raise ValueError("ringdown params: ka must be > 0 and kb >= 0 (DPD units)")
    extra = sorted(set(params) - set(out) - {"mu"})
    if extra:
        raise ValueError(f"ringdown params: unknown name(s) {extra}; allowed: ka, kb, b1, b2, a3, a4 (mu = ka/3)")
    seeds = tuple(int(s) for s in np.atleast_1d(np.asarray(seeds)).ravel())
    if len(seeds) != n:
        raise ValueError(f"ringdown needs one seed per replica ({n}), got {len(seeds)}")
    return out, seeds


def _divisor_at_most(n: int, cap: int) -> int:
    for d in range(min(n, cap), 0, -1):
        if n % d == 0:
            return d
    return 1


def _vertex_subset(n_vertices: int, max_vertices: int | None) -> np.ndarray:
    """First 10 4^k + 2 <= max_vertices vertex indices (a coarser icosphere); all if None."""
    if max_vertices is None or max_vertices >= n_vertices:
        return np.arange(n_vertices)
    k = 0
    while 10 * 4 ** (k + 1) + 2 <= max_vertices and 10 * 4 ** (k + 1) + 2 <= n_vertices:
        k += 1
    return np.arange(min(n_vertices, 10 * 4**k + 2))


def radius_from_volume(volume):
    """R = (3 V / 4 pi)^(1/3) (DPD length) of an enclosed volume V (DPD length^3); NaN for V <= 0."""
    v = np.asarray(volume, dtype=np.float64)
    return np.where(v > 0, np.cbrt(np.abs(3.0 * v / (4.0 * math.pi))), np.nan)


# ------------------------------------------------------------------------------------------------
# the protocol
# ------------------------------------------------------------------------------------------------

def _equilibrate(system, volumes, check, eq_steps: int, every: int, hev: int, report) -> np.ndarray:
    """Step ``eq_steps`` (``check()`` every ``hev`` steps); returns the mean R [R] over the last 10 %,
    sampled every ``every`` steps (DPD length)."""
    tail = max(every, eq_steps // 10) if eq_steps else 0
    head = eq_steps - tail
    done = 0
    while done < head:
        n = min(hev, head - done)
        system.step(n)
        done += n
        check()
        report("equilibration", done)
    r_eq = []
    while done < eq_steps:
        n = min(every, eq_steps - done)
        system.step(n)
        done += n
        r_eq.append(radius_from_volume(volumes()))
    return np.nanmean(np.array(r_eq), axis=0) if r_eq else radius_from_volume(volumes())


def _record(system, volumes, frame, vertex_every: int, check, rec_steps: int, every: int, dt: float, hev: int,
            report):
    """Record R(t) = (3 V / 4 pi)^(1/3) [R, T] (DPD length) every ``every`` steps over ``rec_steps``;
    ``frame()`` -> vertices [R, Nv', 3] every ``vertex_every``-th record when given (else None);
    ``check()`` every ``hev`` steps and at the end.  Returns (radius, frames or None, their times, last check)."""
    n_rec = rec_steps // every + 1
    radius = np.full((np.asarray(volumes()).shape[0], n_rec), np.nan)
    verts, vt = ([], []) if frame is not None else (None, None)

    def sample(k):
        radius[:, k] = radius_from_volume(volumes())
        if frame is not None and k % vertex_every == 0:
            verts.append(np.asarray(frame(), dtype=np.float32))
            vt.append(k * every * dt)

    sample(0)
    since, last = 0, None
    for k in range(1, n_rec):
        system.step(every)
        since += every
        sample(k)
        if since >= hev or k == n_rec - 1:
            last = check()
            since = 0
            report(k)
    return radius, verts, vt, last


def _replica_status(health_names, radius: np.ndarray) -> list[str]:
    """STATUSES per replica from the health verdicts; an 'ok' replica with a non-finite R(t) is 'failed'."""
    status = [_HEALTH_TO_STATUS.get(nm, "failed") for nm in health_names]
    return [("failed" if st == "ok" and not np.all(np.isfinite(radius[r])) else st) for r, st in enumerate(status)]


def _common_info(tier, diameter_um, dt, eq_steps, rec_steps, every, mass_factor, perturbation, mesh, m_v, r_equil,
                 p_gas, pred) -> dict:
    """The ``RingdownBatch.info`` entries both tiers report (DPD units)."""
    return {
        "tier": tier, "diameter_um": diameter_um, "dt": dt, "equilibration_steps": eq_steps,
        "record_steps": rec_steps, "record_every": every, "mass_factor": mass_factor,
        "perturbation": perturbation, "n_vertices": mesh.n_vertices, "vertex_mass": m_v,
        "shell_mass": mesh.n_vertices * m_v, "mesh_subdivisions": mesh.subdivisions,
        "radius_reference": mesh.radius_dpd, "radius_equilibrium": np.asarray(r_equil).tolist(),
        "p_gas": np.asarray(p_gas).tolist(), "prediction": {k: np.asarray(v).tolist() for k, v in pred.items()},
    }

def ringdown_batch(diameter_um: float, params: Mapping[str, np.ndarray], seeds: Sequence[int], *,
                   tier: str = "explicit", device: str = "cpu", mass_factor: float = 160.0,
                   perturbation: float = 0.015, equilibration_steps: int | None = None,
                   record_steps: int | None = None, record_every: int | None = None, dt: float | None = None,
                   subdivisions: int | None = None, record_vertices: bool = False, vertex_every: int = 1,
                   max_vertices: int | None = 642, n_periods: float = 8.0, samples_per_period: int = 40,
                   health_every: int | None = None, progress=None, **tier_settings) -> RingdownBatch:
    """Ringdown of R replicas (one parameter set each) of a ``diameter_um`` [um] bubble, batched.

    ``params``: ka, kb (required), b1, b2, a3, a4 (default 0) -> arrays [R] in DPD units (ka 2-D
    modulus, mu = ka / 3; kb energy); ``seeds``: one int per replica.  ``tier``: 'explicit' or
    'implicit' (module docstring).  ``mass_factor`` multiplies the shell vertex mass;
    ``perturbation`` the relative radial scaling at t = 0 (may be negative: compression).

    Steps (of ``dt`` DPD time; default 1e-4 explicit, the published step): ``equilibration_steps``
    before the perturbation, ``record_steps`` after it, R(t) sampled every ``record_every`` steps.
    Any left ``None`` comes from :func:`auto_schedule` with the check-7 frequencies of the batch
    (explicit: including the water's added mass), ``n_periods`` of the slowest replica and
    ``samples_per_period`` of the fastest.  ``record_vertices``: also keep vertex positions every
    ``vertex_every`` records for at most ``max_vertices`` vertices (PCA; memory R x T x Nv x 12 bytes).
    ``health_every``: steps between health checks (default ~ 5,000 and at the ends of the phases).
    ``progress``: optional callable ``progress(phase: str, done_steps: int, total_steps: int)``.

    Explicit-tier settings (``tier_settings``): ``dtype`` ('float32'), ``box`` (default (2R+5, 2R+5,
    2R+10)), ``p_back`` (91), ``gas_density`` (3), ``rho_shell_kg_m3`` (1100), ``a_vertex_water`` (400),
    ``water_layer`` (2.0), ``pin_com`` (False), ``max_leaks`` (5 leaked particles tolerated per replica),
    ``check_leaks`` (True).  Implicit-tier settings are passed to the implicit system.
    Returns a :class:`RingdownBatch`.
    """
    if tier not in RINGDOWN_TIERS:
        raise ValueError(f"ringdown tier must be one of {RINGDOWN_TIERS}, got {tier!r}")
    d = diameter_um
    if isinstance(d, bool) or not isinstance(d, (int, float)) or not (math.isfinite(d) and 0.5 <= d <= 20.0):
        raise ValueError(f"diameter_um must lie in [0.5, 20] um, got {d!r}")
    if not (isinstance(mass_factor, (int, float)) and math.isfinite(mass_factor) and mass_factor > 0):
        raise ValueError(f"mass_factor must be a finite number > 0, got {mass_factor!r}")
    if not (isinstance(perturbation, (int, float)) and math.isfinite(perturbation) and 0 < abs(perturbation) <= 0.2):
        raise ValueError(f"perturbation must satisfy 0 < |perturbation| <= 0.2, got {perturbation!r}")
    for name, val in (("equilibration_steps", equilibration_steps), ("record_steps", record_steps),
                      ("record_every", record_every), ("health_every", health_every)):
        if val is not None and (not isinstance(val, (int, np.integer)) or val < (0 if name == "equilibration_steps"
                                                                                   else 1)):
            raise ValueError(f"{name} must be a positive integer (or None for automatic), got {val!r}")
    if int(vertex_every) < 1:
        raise ValueError(f"vertex_every must be >= 1, got {vertex_every!r}")
    p, seeds = _check_params(params, seeds)
    runner = _run_explicit if tier == "explicit" else _run_implicit
    t0 = time.perf_counter()
    batch = runner(float(diameter_um), p, seeds, device=device, mass_factor=float(mass_factor),
                   perturbation=float(perturbation), equilibration_steps=equilibration_steps,
                   record_steps=record_steps, record_every=record_every, dt=dt, subdivisions=subdivisions,
                   record_vertices=bool(record_vertices), vertex_every=int(vertex_every), max_vertices=max_vertices,
                   n_periods=float(n_periods), samples_per_period=int(samples_per_period),
                   health_every=health_every, progress=progress, settings=dict(tier_settings))
    batch.seconds = time.perf_counter() - t0
    batch.info["seconds"] = batch.seconds
    return batch


def _schedule(pred_w, dt, equilibration_steps, record_steps, record_every, n_periods, samples_per_period):
    w = np.asarray(pred_w, dtype=np.float64)
    w = w[np.isfinite(w) & (w > 0)]
    if w.size == 0:
        raise ValueError("cannot schedule the ringdown: no positive predicted frequency")
    auto = auto_schedule(float(w.min()), float(w.max()), dt, n_periods=n_periods,
                         samples_per_period=samples_per_period)
    every = int(record_every) if record_every is not None else auto["record_every"]
    if record_steps is None:
        rec = int(math.ceil(auto["record_steps"] / every)) * every
    else:
        rec = int(record_steps)
    if rec % every:
        raise ValueError(f"record_steps ({rec}) must be a multiple of record_every ({every})")
    eq = int(equilibration_steps) if equilibration_steps is not None else auto["equilibration_steps"]
    return eq, rec, every


def _run_explicit(diameter_um, p, seeds, *, device, mass_factor, perturbation, equilibration_steps, record_steps,
                  record_every, dt, subdivisions, record_vertices, vertex_every, max_vertices, n_periods,
                  samples_per_period, health_every, progress, settings) -> RingdownBatch:
    import warp as wp

    from bubblecal.sim.engine import ParticleSystem, bubble_spec
    from bubblecal.sim.engine.health import HealthConfig, HealthMonitor
    from bubblecal.sim.engine.particles import GAS, WATER

    known = {"dtype", "box", "p_back", "gas_density", "rho_shell_kg_m3", "a_vertex_water", "water_layer", "pin_com",
             "max_leaks", "check_leaks", "kbt"}
    unknown = sorted(set(settings) - known)
    if unknown:
        raise ValueError(f"unknown explicit-tier ringdown setting(s) {unknown}; allowed: {sorted(known)}")
    dtype = settings.get("dtype", "float32")
    water_layer = float(settings.get("water_layer", 2.0))
    if not water_layer > 0:
        raise ValueError(f"water_layer must be > 0, got {water_layer}")
    dt = 1e-4 if dt is None else float(dt)
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be > 0, got {dt!r}")
    R = len(seeds)
    specs = []
    for r in range(R):
        spec = bubble_spec(diameter_um, subdivisions=subdivisions, box=settings.get("box"), seed=seeds[r],
                           ka=float(p["ka"][r]), kb=float(p["kb"][r]), p_back=float(settings.get("p_back", 91.0)),
                           gas_density=float(settings.get("gas_density", 3.0)), protocol="compression",
                           rho_shell_kg_m3=settings.get("rho_shell_kg_m3"), mass_factor=mass_factor,
                           a_vertex_water=settings.get("a_vertex_water"), kbt=float(settings.get("kbt", 1.0)),
                           b1=float(p["b1"][r]), b2=float(p["b2"][r]), a3=float(p["a3"][r]), a4=float(p["a4"][r]))
        spec.pin_com = bool(settings.get("pin_com", False))
        specs.append(spec)
    mesh = specs[0].mesh
    nv = mesh.n_vertices
    m_v = float(specs[0].pairs.mass[2])
    shell_mass = nv * m_v
    box = np.asarray(specs[0].box, dtype=np.float64)
    p_gas0 = float(settings.get("gas_density", 3.0)) * float(settings.get("kbt", 1.0))
    pred0 = breathing_mode_prediction(p["ka"], mesh.radius_dpd, p_gas0, shell_mass, explicit=True, box=box)
    eq_steps, rec_steps, every = _schedule(pred0["omega0_water"], dt, equilibration_steps, record_steps,
                                           record_every, n_periods, samples_per_period)
    hev = int(health_every) if health_every is not None else max(every, (5000 // every) * every)
    system = ParticleSystem(specs, dt=dt, device=device, dtype=dtype, chunk=_divisor_at_most(every, 50))
    monitor = HealthMonitor(HealthConfig(max_leaks=int(settings.get("max_leaks", 5)),
                                         check_leaks=bool(settings.get("check_leaks", True))))
    total = eq_steps + rec_steps

    def report(phase, done):
        if progress is not None:
            progress(phase, int(done), int(total))

    # ---- equilibration (mean R over its last 10 %) ----
    def volumes():
        return system.shell_area_volume()[1]

    r_equil = _equilibrate(system, volumes, lambda: monitor.check(system), eq_steps, every, hev, report)
    if eq_steps:
        monitor.check(system)
        report("equilibration", eq_steps)
    # gas pressure inside from the ideal-gas law (gas-gas a = 0)
    _, vol = system.shell_area_volume()
    n_gas = system.solvent_counts()[:, GAS].astype(np.float64)
    kbt = np.asarray(system.kbt_np, dtype=np.float64)
    p_gas = n_gas * kbt / vol

    # ---- perturbation: homothety of shell + gas + near water about the centroid ----
    npf = system.np_dtype
    xv = system.xv.numpy().astype(np.float64)
    x = system.x.numpy().astype(np.float64)
    rep = system.rep.numpy()
    typ = system.typ.numpy()
    status_now = system.status_numpy()
    s = float(perturbation)
    for r in range(R):
        if status_now[r] != 0:
            continue
        o, n = int(system.vertex_offset[r]), int(system.vertex_count[r])
        c = xv[o:o + n].mean(axis=0)
        dv = xv[o:o + n] - c
        r_a = float(np.linalg.norm(dv, axis=1).max())
        xv[o:o + n] = c + (1.0 + s) * dv
        L = system.boxes[r]
        sel = np.flatnonzero(rep == r)
        dx = x[sel] - c
        dx -= L * np.round(dx / L)
        dist = np.linalg.norm(dx, axis=1)
        is_gas = typ[sel] == GAS
        is_water = typ[sel] == WATER
        # gas: the homothety (stays inside); water: homothety up to r_a, then a linear taper to 0
        shift = np.where(dist <= r_a, s * dist, s * r_a * np.clip(1.0 - (dist - r_a) / water_layer, 0.0, 1.0))
        shift = np.where(is_gas, s * dist, np.where(is_water, shift, 0.0))
        unit = dx / np.maximum(dist, 1e-12)[:, None]
        newx = c + dx + unit * shift[:, None]
        x[sel] = newx - L * np.floor(newx / L)
    system.xv.assign(xv.astype(npf))
    system.x.assign(x.astype(npf))
    system.rebuild()
    rep_after = monitor.check(system) if bool(settings.get("check_leaks", True)) else None

    # ---- record ----
    vidx = _vertex_subset(nv, max_vertices) if record_vertices else None

    def frame():
        allv = system.xv.numpy()
        return np.stack([allv[int(system.vertex_offset[r]) + vidx] for r in range(R)])

    radius, verts, vt, _ = _record(
        system, lambda: system.shell_area_volume()[1], frame if record_vertices else None, vertex_every,
        lambda: monitor.check(system), rec_steps, every, dt, hev, lambda k: report("record", eq_steps + k * every))
    final = monitor.reports[-1] if monitor.reports else None
    names = final.status if final is not None else ["OK"] * R
    status = _replica_status(names, radius)
    pred = breathing_mode_prediction(p["ka"], r_equil, p_gas, shell_mass, explicit=True, box=box,
                                     area_ratio=mesh.area() / (4.0 * math.pi * mesh.radius_dpd**2))
    info = {
        **_common_info("explicit", diameter_um, dt, eq_steps, rec_steps, every, mass_factor, perturbation, mesh, m_v,
                       r_equil, p_gas, pred),
        "box": box.tolist(),
        "n_particles": int(system.N), "device": str(system.device), "dtype": str(np.dtype(npf)),
        "water_layer": water_layer, "pin_com": bool(settings.get("pin_com", False)),
        "health_after_perturbation": None if rep_after is None else rep_after.as_dict(),
        "health_final": None if final is None else final.as_dict(),
        "neighbor_rebuilds": int(system.n_rebuilds), "warp_version": wp.config.version,
    }
    return RingdownBatch(t=np.arange(radius.shape[1]) * every * dt, radius=radius, status=status, params=p, seeds=seeds,
                         info=info, vertices=None if verts is None else np.stack(verts, axis=1),
                         vertex_t=None if vt is None else np.asarray(vt), vertex_indices=vidx)


def _run_implicit(diameter_um, p, seeds, *, device, mass_factor, perturbation, equilibration_steps, record_steps,
                  record_every, dt, subdivisions, record_vertices, vertex_every, max_vertices, n_periods,
                  samples_per_period, health_every, progress, settings) -> RingdownBatch:
    from bubblecal.sim.engine import (
        HealthThresholds,
        ImplicitShellSystem,
        default_vertex_friction,
        shell_params_from_arrays,
    )
    from bubblecal.sim.engine.mesh import mesh_for_diameter
    from bubblecal.sim.engine.particles import RHO_SHELL_KG_M3

    known = {"dtype", "p0", "p_back", "p_water", "gamma", "kbt", "rho_shell_kg_m3", "rupture_strain"}
    unknown = sorted(set(settings) - known)
    if unknown:
        raise ValueError(f"unknown implicit-tier ringdown setting(s) {unknown}; allowed: {sorted(known)}")
    mesh = mesh_for_diameter(diameter_um, subdivisions)
    nv = mesh.n_vertices
    m_v = mesh.vertex_mass(float(settings.get("rho_shell_kg_m3", RHO_SHELL_KG_M3)), mass_factor=mass_factor)
    shell_mass = nv * m_v
    if dt is None:
        # fastest in-plane vertex mode omega_max ~ sqrt(12 ka / m_v): dt = 0.1 / omega_max, at most 1e-3
        dt = min(1e-3, 0.1 * math.sqrt(m_v / (12.0 * float(np.max(p["ka"])))))
    dt = float(dt)
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be > 0, got {dt!r}")
    p0 = float(settings.get("p0", 3.0))
    pred0 = breathing_mode_prediction(p["ka"], mesh.radius_dpd, p0, shell_mass)
    eq_steps, rec_steps, every = _schedule(pred0["omega0"], dt, equilibration_steps, record_steps, record_every,
                                           n_periods, samples_per_period)
    hev = int(health_every) if health_every is not None else max(every, (5000 // every) * every)
    params = shell_params_from_arrays(p)
    gamma = settings.get("gamma")
    gamma = default_vertex_friction(mesh) if gamma is None else float(gamma)
    system = ImplicitShellSystem(mesh, params, p0=p0, p_back=float(settings.get("p_back", 91.0)),
                                 p_water=settings.get("p_water"), kbt=float(settings.get("kbt", 1.0)), gamma=gamma,
                                 vertex_mass=m_v, dt=dt, device=device, dtype=settings.get("dtype", "float32"),
                                 seed=list(seeds), pin_com=True, chunk=_divisor_at_most(every, 50))
    thresholds = HealthThresholds(rupture_strain=float(settings.get("rupture_strain", 1.0)))
    total = eq_steps + rec_steps

    def report(phase, done):
        if progress is not None:
            progress(phase, int(done), int(total))

    r_equil = _equilibrate(system, system.volumes, lambda: system.check_health(thresholds), eq_steps, every, hev,
                           report)
    p_gas = system.gas_pressure()
    h_eq = system.check_health(thresholds)
    report("equilibration", eq_steps)

    # perturbation: homothety of every live shell about its centroid (the gas law follows V)
    x = np.asarray(system.vertices(), dtype=np.float64)
    live = np.array([nm == "OK" for nm in h_eq["status"]])
    c = x.mean(axis=1, keepdims=True)
    x = np.where(live[:, None, None], c + (1.0 + float(perturbation)) * (x - c), x)
    system.set_vertices(x)

    vidx = _vertex_subset(nv, max_vertices) if record_vertices else None
    radius, verts, vt, health = _record(
        system, system.volumes, (lambda: np.asarray(system.vertices())[:, vidx]) if record_vertices else None,
        vertex_every, lambda: system.check_health(thresholds), rec_steps, every, dt, hev,
        lambda k: report("record", eq_steps + k * every))
    health = health or h_eq
    status = _replica_status(health["status"], radius)
    pred = breathing_mode_prediction(p["ka"], r_equil, p_gas, shell_mass,
                                     area_ratio=mesh.area() / (4.0 * math.pi * mesh.radius_dpd**2))
    info = {
        **_common_info("implicit", diameter_um, dt, eq_steps, rec_steps, every, mass_factor, perturbation, mesh, m_v,
                       r_equil, p_gas, pred),
        "device": str(system.device), "system": system.settings(),
        "health_final": {k: (np.asarray(v).tolist() if not isinstance(v, list) else v) for k, v in health.items()},
    }
    info["system"].pop("n_vertices", None)
    return RingdownBatch(t=np.arange(radius.shape[1]) * every * dt, radius=radius, status=status, params=p, seeds=seeds,
                         info=info, vertices=None if verts is None else np.stack(verts, axis=1),
                         vertex_t=None if vt is None else np.asarray(vt), vertex_indices=vidx)
