"""Load-point schedules of the quasi-static chain: lock-step (the batch at the same point) and replica-asynchronous
(every replica at its own point), with slot refill from a pool of parameter sets and compaction of the last
relaxing curves.  The async schedule follows exactly the FIRE iterates of the lock-step one: same curves, same
FIRE steps.

A chain backend (:class:`~bubblecal.sim.tiers.quasistatic.backends._DeviceChain`) provides ``R``,
``minimize(j, alive) -> (status, steps, fmax)``, ``point_state(j) -> (finite_rows, max_area_strain, volume,
observables)``, ``reset_failed(mask)``, ``x_final()`` and ``n_evaluations``; the asynchronous schedule also uses
its ``fire``, ``fire_settings``, ``start_rows``, ``load_samples``, ``row_positions``, ``take_over`` and ``nv``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from bubblecal.sim.tiers.quasistatic.settings import (
    _FAILED,
    STATUS_NONFINITE,
    STATUS_NOT_CONVERGED,
    STATUS_OK,
    STATUS_RUPTURED,
)

if TYPE_CHECKING:
    from bubblecal.sim.engine.kernels.shell import ShellParams
    from bubblecal.sim.tiers.quasistatic.backends import _DeviceChain

__all__: list[str] = []


def _result_tables(n: int, n_points: int):
    """Empty per-curve results of a chain of ``n`` curves: statuses, per-point statuses, FIRE steps, fmax, area
    strain, volume (NaN until measured) and the observables dict (filled per key as they come)."""
    return ([STATUS_OK] * n, [[STATUS_OK] * n_points for _ in range(n)], np.zeros((n, n_points), dtype=np.int64),
            np.full((n, n_points), np.nan), np.full((n, n_points), np.nan), np.full((n, n_points), np.nan),
            {})


def _obs_table(obs: dict, key: str, n: int, n_points: int) -> np.ndarray:
    """The [n, n_points] table of observable ``key`` in ``obs``, created (NaN) on first use: allocated once, not per
    point (a ``setdefault`` default is built on every call, an O(n) cost per measured point)."""
    table = obs.get(key)
    if table is None:
        table = obs[key] = np.full((n, n_points), np.nan)
    return table


def _run_chain(backend, n_points: int, rupture_strain: float, set_point: Callable[[int], None] | None = None,
               progress: Callable[[int, int, float], None] | None = None, stop_unstable: bool = False) -> dict:
    """Chain the load points in lock-step on ``backend`` (module docstring); returns per-replica/point arrays
    and statuses.  ``progress(j, n_points, seconds)`` after every point.
    ``stop_unstable``: a 'not_converged' point ends the replica's curve (:class:`FireSettings`)."""
    from bubblecal.sim.engine.minimize import STATUS_CONVERGED, STATUS_NONFINITE

    R = backend.R
    terminal = _terminal(stop_unstable)
    status, point_status, steps, fmax, strain, volume, obs = _result_tables(R, n_points)
    t0 = time.perf_counter()
    for j in range(n_points):
        alive = np.array([s not in terminal for s in status])
        if not alive.any():
            for r in range(R):
                point_status[r][j:] = [status[r]] * (n_points - j)
            break
        if set_point is not None:
            set_point(j)
        fstatus, fsteps, ffmax = backend.minimize(j, alive)
        finite_rows, eps, vols, m = backend.point_state(j)
        for r in range(R):
            if not alive[r]:
                point_status[r][j] = status[r]
                continue
            if fstatus[r] == STATUS_NONFINITE or not finite_rows[r]:
                ps = STATUS_NONFINITE
            elif eps[r] > rupture_strain:
                ps = STATUS_RUPTURED
            elif fstatus[r] != STATUS_CONVERGED:
                ps = STATUS_NOT_CONVERGED
            else:
                ps = STATUS_OK
            point_status[r][j] = ps
            if ps in terminal or status[r] == STATUS_OK:
                status[r] = ps if ps != STATUS_OK else status[r]
            steps[r, j] = fsteps[r]
            fmax[r, j] = ffmax[r]
            if ps in terminal:
                continue
            strain[r, j] = eps[r]
            volume[r, j] = vols[r]
            for k, v in m.items():
                _obs_table(obs, k, R, n_points)[r, j] = v[r]
        # failed replicas restart from (and stay frozen at) the reference so their rows stay finite
        backend.reset_failed(np.array([s in terminal for s in status]))
        if progress is not None:
            progress(j, n_points, time.perf_counter() - t0)
    return {"status": status, "point_status": point_status, "fire_steps": steps, "fmax": fmax,
            "max_area_strain": strain, "volume": volume, "obs": obs, "x": backend.x_final(),
            "fire_evaluations": int(backend.n_evaluations)}


def _terminal(stop_unstable: bool) -> tuple[str, ...]:
    """Point verdicts that end a replica's curve."""
    return _FAILED + ((STATUS_NOT_CONVERGED,) if stop_unstable else ())


def _classify(fire_code: int, finite: bool, eps: float, rupture_strain: float) -> str:
    """Point verdict of one replica from its FIRE status code, finiteness and max area strain."""
    from bubblecal.sim.engine.kernels.fire import CONVERGED, NONFINITE

    if fire_code == NONFINITE or not finite:
        return STATUS_NONFINITE
    if eps > rupture_strain:
        return STATUS_RUPTURED
    return STATUS_OK if fire_code == CONVERGED else STATUS_NOT_CONVERGED


def _run_chain_async(backend: _DeviceChain, n_points: int, rupture_strain: float,
                     assign: Callable[[np.ndarray], None],
                     progress: Callable[[int, int, float], None] | None = None,
                     batch_fraction: float = 0.05, samples: Sequence[ShellParams] | None = None,
                     compact: Callable[[_DeviceChain, np.ndarray, list], tuple] | None = None,
                     compact_below: float = 0.125, compact_min: int = 8,
                     on_finish: Callable[[int, dict], None] | None = None, stop_unstable: bool = False,
                     load_slots: Callable[[_DeviceChain, np.ndarray, np.ndarray], None] | None = None) -> dict:
    """Chain the load points with every replica at its own point (device FIRE only).

    A replica that stops (converged, ``max_steps`` or non-finite) is measured, then restarted at its next
    point while the others go on relaxing, so no replica waits for the batch's slowest one at every point
    (lock-step: the sum over points of the slowest replica's FIRE steps; here: the slowest replica's own
    sum).  Each replica follows exactly the FIRE iterates of the lock-step chain: same curves, same steps.
    Stopped replicas are measured in groups of at least ``batch_fraction`` of those still running (or
    when none is running) to keep host round trips rare.  ``assign(j)`` sets each slot's load (plate
    positions or pole force) of point ``j[r]``.

    ``samples`` (S >= R parameter sets, the first R already loaded in the backend's R slots): a slot whose
    sample has finished its curve takes the next pending sample (reference shape, point 0), so the batch
    runs at full occupancy until the pool is empty; the wall time then follows the pool's total FIRE
    work instead of its slowest sample.  Each sample's iterates are those it would have had in its own
    slot.  ``progress(k, S, seconds)`` then counts finished samples (k = samples finished - 1).
    ``compact(backend, slots, held) -> (new backend, new assign)`` (``held``: the pool indices of the slots'
    samples): once the pool is empty and at most ``compact_below`` of the slots (and more than
    ``compact_min`` slots in all) still relax, they move to a batch of their own size
    (an iteration of a big batch costs a fixed floor however few of its replicas
    relax; same iterates).  ``on_finish(s, row)``: called as soon as sample (or replica) ``s`` has
    finished its curve, with its ``status``, ``point_status``, ``fire_steps`` [P] and ``obs`` {name: [P]}
    (a campaign writes the record at once, so an interrupted batch keeps its finished curves).
    ``stop_unstable``: a 'not_converged' point ends the curve (its slot is free at once).
    ``load_slots(backend, slots, k)`` (with ``samples``): give the refilled slots the samples ``k`` (pool
    indices) -- their parameters and, for a pool of several bubble sizes, their references and loads; default
    ``backend.load_samples(slots, [samples[i] for i in k])``.
    Returns the dict of :func:`_run_chain`, rows = samples.
    """
    from bubblecal.sim.engine.kernels.fire import ACTIVE

    R = backend.R
    stream = samples is not None
    S = len(samples) if stream else R
    if S < R:
        raise ValueError(f"samples: {S} parameter sets for {R} slots")
    fs = backend.fire_settings
    terminal = _terminal(stop_unstable)
    status, point_status, steps, fmax, strain, volume, obs = _result_tables(S, n_points)
    x_out = np.zeros((S * backend.nv, 3)) if stream else None
    sample = np.arange(R)  # sample held by each slot
    next_sample = R
    n_finished = 0
    j = np.zeros(R, dtype=np.int64)
    done = np.zeros(R, dtype=bool)
    fire = backend.fire
    t0 = time.perf_counter()
    fire.begin(ftol=fs.ftol, max_steps=fs.max_steps)
    assign(j)
    backend.start_rows(j, ~done)
    reported = 0
    while not done.all():
        code = fire.advance()
        backend.n_evaluations += fire.sync_every
        waiting = (code != ACTIVE) & ~done
        n_wait, n_run = int(waiting.sum()), int((~done).sum())
        if n_wait == 0 or (n_wait < n_run and n_wait < max(1, math.ceil(batch_fraction * n_run))):
            continue
        fsteps, ffmax = fire.replica_report()
        finite_rows, eps, vols, m = backend.point_state(-1)
        failed = np.zeros(R, dtype=bool)
        for r in np.nonzero(waiting)[0]:
            jr, s_ = int(j[r]), int(sample[r])
            ps = _classify(int(code[r]), bool(finite_rows[r]), float(eps[r]), rupture_strain)
            point_status[s_][jr] = ps
            steps[s_, jr] = fsteps[r]
            fmax[s_, jr] = ffmax[r]
            if ps in terminal:
                status[s_] = ps
                point_status[s_][jr + 1:] = [ps] * (n_points - jr - 1)
                failed[r] = done[r] = True
                continue
            if ps != STATUS_OK and status[s_] == STATUS_OK:
                status[s_] = ps
            strain[s_, jr] = eps[r]
            volume[s_, jr] = vols[r]
            for key, v in m.items():
                _obs_table(obs, key, S, n_points)[s_, jr] = v[r]
            j[r] = jr + 1
            done[r] = j[r] >= n_points
        # failed replicas return to (and stay frozen at) the reference so their rows stay finite
        backend.reset_failed(failed)
        restart = waiting & ~done
        finished = np.nonzero(waiting & done)[0]
        if on_finish is not None:
            for r in finished:
                s_ = int(sample[r])
                on_finish(s_, {"status": status[s_], "point_status": list(point_status[s_]),
                               "fire_steps": steps[s_].copy(), "obs": {k: v[s_].copy() for k, v in obs.items()}})
        if stream:
            for r in finished:
                x_out[sample[r] * backend.nv:(sample[r] + 1) * backend.nv] = backend.row_positions(int(r))
            n_finished += len(finished)
            refill = finished[:max(0, S - next_sample)]
            if len(refill):
                new = np.arange(next_sample, next_sample + len(refill))
                next_sample += len(refill)
                if load_slots is None:
                    backend.load_samples(refill, [samples[int(k)] for k in new])
                else:
                    load_slots(backend, refill, new)
                sample[refill], j[refill], done[refill] = new, 0, False
                restart[refill] = True
        assign(np.minimum(j, n_points - 1))
        backend.start_rows(j, restart)
        n_left = int((~done).sum())
        if (compact is not None and stream and next_sample >= S and 0 < n_left <= compact_below * R
                and R > compact_min):
            keep = np.nonzero(~done)[0]
            backend, assign = compact(backend, keep, [int(k) for k in sample[keep]])
            fire = backend.fire
            R = backend.R
            sample, j, done = sample[keep], j[keep], np.zeros(R, dtype=bool)
        if progress is not None and stream:
            for k in range(reported, n_finished):
                progress(k, S, time.perf_counter() - t0)
            reported = n_finished
        elif progress is not None:
            finished_pt = int(np.min(np.where(done, n_points, j)))
            for jj in range(reported, finished_pt):
                progress(jj, n_points, time.perf_counter() - t0)
            reported = max(reported, finished_pt)
    return {"status": status, "point_status": point_status, "fire_steps": steps, "fmax": fmax,
            "max_area_strain": strain, "volume": volume, "obs": obs,
            "x": x_out if stream else backend.x_final(), "fire_evaluations": int(backend.n_evaluations)}


# the last relaxing curves of an emptied pool move to a batch of their own size when at most this fraction of the
# slots (and more than _COMPACT_MIN slots in all) still relax: an iteration of a big batch costs a fixed floor
# however few of its slots relax (benchmarks/qs_iteration_cost.py measures it)
_COMPACT_BELOW = 0.125
_COMPACT_MIN = 8


def _run_device_async(dc_factory: Callable[[np.ndarray], _DeviceChain], params: list, n_points: int,
                      rupture_strain: float, assign_factory: Callable[[_DeviceChain], Callable],
                      max_replicas: int | None, progress,
                      on_finish: Callable[[int, dict], None] | None = None, stop_unstable: bool = False,
                      load_slots: Callable[[_DeviceChain, np.ndarray, np.ndarray], None] | None = None) -> dict:
    """Async chain over ``params``; with ``max_replicas`` < len(params) at most that many slots run at once
    and finished slots take the next sample, softest (smallest k_a) first: FIRE work grows as k_a falls,
    so starting the longest chains first keeps the pool's tail short.  Rows come back in ``params`` order.
    ``dc_factory(idx)``: a chain for ``params[idx]``.  ``on_finish(i, row)``: each finished curve at once (``i``
    indexes ``params``).  ``load_slots(backend, slots, idx)``: give slots the samples ``params[idx]`` (default:
    their parameters; a pool of several sizes also swaps references and loads)."""
    S = len(params)
    if max_replicas is None or max_replicas >= S:
        dc = dc_factory(np.arange(S))
        return _run_chain_async(dc, n_points, rupture_strain, assign_factory(dc), progress=progress,
                                on_finish=on_finish, stop_unstable=stop_unstable)
    order = np.argsort([p.ka for p in params], kind="stable")
    pool = [params[int(i)] for i in order]
    dc = dc_factory(order[:max_replicas])

    def compact(old: _DeviceChain, slots: np.ndarray, held: list):
        new = dc_factory(order[np.asarray(held, dtype=np.int64)])
        new.take_over(old, slots)
        return new, assign_factory(new)

    refill = None if load_slots is None else (lambda b, slots, k: load_slots(b, slots, order[np.asarray(k)]))
    finish = None if on_finish is None else (lambda s, row: on_finish(int(order[s]), row))
    out = _run_chain_async(dc, n_points, rupture_strain, assign_factory(dc), progress=progress, samples=pool,
                           compact=compact, compact_below=_COMPACT_BELOW, compact_min=_COMPACT_MIN,
                           on_finish=finish, stop_unstable=stop_unstable, load_slots=refill)
    inv = np.empty(S, dtype=np.int64)
    inv[order] = np.arange(S)
    nv = dc.nv
    back = dict(out)
    for k in ("fire_steps", "fmax", "max_area_strain", "volume"):
        back[k] = out[k][inv]
    back["status"] = [out["status"][int(i)] for i in inv]
    back["point_status"] = [out["point_status"][int(i)] for i in inv]
    back["obs"] = {k: v[inv] for k, v in out["obs"].items()}
    back["x"] = out["x"].reshape(S, nv, 3)[inv].reshape(-1, 3)
    return back
