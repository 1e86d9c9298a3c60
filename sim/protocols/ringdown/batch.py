"""The ringdown front end: check the request, run the tier, time it."""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence

import numpy as np

from bubblecal.data import NONLINEAR_PARAMETERS, SHELL_PARAMETERS
from bubblecal.sim.protocols.ringdown.explicit import _run_explicit
from bubblecal.sim.protocols.ringdown.implicit import _run_implicit
from bubblecal.sim.protocols.ringdown.result import RingdownBatch

__all__ = ["ringdown_batch", "RINGDOWN_TIERS"]

#: The tiers that run the ringdown protocol.
RINGDOWN_TIERS = ("explicit", "implicit")

# the nonlinear coefficients may be left out: 0 (a linear Lim shell)
_PARAM_DEFAULTS = {k: 0.0 for k in NONLINEAR_PARAMETERS}


def _check_params(params: Mapping[str, np.ndarray], seeds) -> tuple[dict[str, np.ndarray], tuple[int, ...]]:
    """The shell parameters as float64 arrays [R] (defaults filled in) and the seeds, checked."""
    if "ka" not in params or "kb" not in params:
        raise ValueError(f"ringdown params need at least 'ka' and 'kb' (DPD), got {sorted(params)}")
    out = {}
    n = None
    for k in SHELL_PARAMETERS:
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
        raise ValueError(f"ringdown params: unknown name(s) {extra}; allowed: {', '.join(SHELL_PARAMETERS)} "
                         "(mu = ka/3)")
    seeds = tuple(int(s) for s in np.atleast_1d(np.asarray(seeds)).ravel())
    if len(seeds) != n:
        raise ValueError(f"ringdown needs one seed per replica ({n}), got {len(seeds)}")
    return out, seeds


def ringdown_batch(diameter_um: float, params: Mapping[str, np.ndarray], seeds: Sequence[int], *,
                   tier: str = "explicit", device: str = "cpu", mass_factor: float = 160.0,
                   perturbation: float = 0.015, equilibration_steps: int | None = None,
                   record_steps: int | None = None, record_every: int | None = None, dt: float | None = None,
                   subdivisions: int | None = None, record_vertices: bool = False, vertex_every: int = 1,
                   max_vertices: int | None = 642, n_periods: float = 8.0, samples_per_period: int = 40,
                   health_every: int | None = None, progress=None, **tier_settings) -> RingdownBatch:
    """Ringdown of R replicas (one parameter set each) of one bubble, batched (package docstring).

    Steps are in units of ``dt``; any of ``equilibration_steps``, ``record_steps``, ``record_every`` left None
    comes from :func:`auto_schedule` with the check-7 frequencies of the batch (explicit: including the water's
    added mass), ``n_periods`` of the slowest replica and ``samples_per_period`` of the fastest.

    Parameters
    ----------
    diameter_um : float
        Bubble diameter (um), in [0.5, 20].
    params : mapping
        ``ka``, ``kb`` (required), ``b1``, ``b2``, ``a3``, ``a4`` (default 0) -> arrays [R] (ka DPD 2-D modulus,
        mu = ka / 3; kb DPD energy; the rest dimensionless).
    seeds : sequence of int
        One per replica.
    tier : str
        'explicit' or 'implicit' (:data:`RINGDOWN_TIERS`).
    device : str
        Warp device.
    mass_factor : float
        Multiplies the shell vertex mass (> 0).
    perturbation : float
        Relative radial scaling at t = 0 (0 < abs <= 0.2; negative = compression).
    equilibration_steps, record_steps, record_every : int, optional
        Steps before the perturbation, after it, and between two samples of R(t).
    dt : float, optional
        Time step (DPD time); default 1e-4 explicit (the published step), implicit from the fastest
        in-plane vertex mode (at most 1e-3).
    subdivisions : int, optional
        Icosphere level (None = the mesh's default for the diameter).
    record_vertices : bool
        Also keep vertex positions (for the PCA; memory R x T x Nv x 12 bytes).
    vertex_every : int
        Records between two kept frames (>= 1).
    max_vertices : int, optional
        Most vertices kept per frame (a coarser icosphere's; None = all).
    n_periods : float
        Slowest periods covered by an automatic record.
    samples_per_period : int
        Samples per fastest period of an automatic ``record_every``.
    health_every : int, optional
        Steps between health checks (default ~ 5,000, and at the ends of the phases).
    progress : callable, optional
        ``progress(phase: str, done_steps: int, total_steps: int)``.
    **tier_settings
        Explicit tier: ``dtype`` ('float32'), ``box`` (default (2R+5, 2R+5, 2R+10)), ``p_back`` (91),
        ``gas_density`` (3), ``rho_shell_kg_m3`` (1100), ``a_vertex_water`` (400), ``water_layer`` (2.0),
        ``pin_com`` (False), ``max_leaks`` (5 leaked particles tolerated per replica), ``check_leaks`` (True),
        ``kbt`` (1).  Implicit tier: ``dtype``, ``p0``, ``p_back``, ``p_water``, ``gamma``, ``kbt``,
        ``rho_shell_kg_m3``, ``rupture_strain`` (passed to the implicit system).

    Returns
    -------
    RingdownBatch
        The traces, statuses and settings; ``info["seconds"]`` is the wall time.

    Raises
    ------
    ValueError
        If an argument or tier setting is invalid, or no positive frequency can be predicted.
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
