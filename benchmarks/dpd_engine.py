"""Benchmark of the Warp DPD engine: particle-steps per second, kernel time split, memory per particle.

Cases:
  (i)   pure DPD fluid, rho = 3, ~10^6 particles (published water (100, 3.5, 0.25));
  (ii)  one 3 um bubble (R = 6, 2,562 vertices) in explicit water and gas, 17 x 17 x 22 box;
  (iii) 64 such bubbles batched as replicas in the same launches.

For each: particle-steps per second (solvent + vertices) over a timed run with the production
time step (1e-4) -- the neighbour lists are rebuilt whenever a particle may have moved skin/2, which
the run counts -- plus the kernel time split (each phase launched alone, timed with CUDA events),
and device memory per particle (bytes held by the system's arrays; and the device's used-memory
delta where the driver reports it).

Usage:
  python benchmarks/dpd_engine.py --device cuda --out results.json
  python benchmarks/dpd_engine.py --device cpu --quick         # smoke test on a CPU
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

import warp as wp

wp.config.quiet = True

from bubblecal.sim.engine import (  # noqa: E402
    ParticleSystem,
    ReplicaSpec,
    bubble_spec,
    published_pair_table,
)


def _free_mem(dev) -> int | None:
    try:
        return int(dev.free_memory)
    except Exception:
        return None


def _sync(dev) -> None:
    wp.synchronize_device(dev)


def time_phases(ps: ParticleSystem, reps: int = 20) -> dict[str, float]:
    """Mean milliseconds per call of each phase, launched alone (events on CUDA, wall clock on CPU)."""
    dev = ps.device
    phases = {
        "pair_forces (solvent)": lambda: wp.launch(
            ps.kp["solvent_forces"], dim=ps.N,
            inputs=[ps.x, ps.v, ps.typ, ps.rep, ps.pid, ps.nbr, ps.ncount, ps.box, ps.tab_a, ps.tab_g, ps.tab_s,
                    ps.tab_sig, ps.seeds, ps.step_counter, 1.0 / math.sqrt(ps.dt), ps.f], device=dev),
    }
    if ps.Nv:
        phases["vertex-solvent pairs"] = lambda: wp.launch(
            ps.kp["vertex_solvent_forces"], dim=ps.Nv,
            inputs=[ps.xv, ps.vv, ps.vrep, ps.x, ps.v, ps.typ, ps.pid, ps.vnbr, ps.vcount, ps.box, ps.tab_a,
                    ps.tab_g, ps.tab_s, ps.tab_sig, ps.seeds, ps.step_counter, 1.0 / math.sqrt(ps.dt), ps.fv, ps.f],
            device=dev)
        phases["shell forces"] = lambda: ps.shell_field.accumulate_forces(ps.xv, ps.fv, ps.vv)
    phases["integrate (+bounce)"] = ps._integrate
    phases["neighbour rebuild"] = ps.rebuild
    out = {}
    for name, fn in phases.items():
        fn()
        _sync(dev)
        if dev.is_cuda:
            e0 = wp.Event(device=dev, enable_timing=True)
            e1 = wp.Event(device=dev, enable_timing=True)
            wp.record_event(e0)
            for _ in range(reps):
                fn()
            wp.record_event(e1)
            _sync(dev)
            out[name] = wp.get_event_elapsed_time(e0, e1) / reps
        else:
            t0 = time.perf_counter()
            for _ in range(reps):
                fn()
            out[name] = (time.perf_counter() - t0) * 1e3 / reps
    return out


def run_case(name: str, specs, dt: float, steps: int, device: str, chunk: int, skin: float,
             phase_reps: int) -> dict:
    dev = wp.get_device(device)
    _sync(dev)
    free0 = _free_mem(dev)
    t0 = time.perf_counter()
    ps = ParticleSystem(specs, dt=dt, device=device, skin=skin, chunk=chunk)
    setup_s = time.perf_counter() - t0
    n_total = ps.N + ps.Nv
    # warm-up: compile, first rebuild, graph capture, initial transient
    ps.step(max(2 * chunk, min(steps // 5, 2000)))
    _sync(dev)
    free1 = _free_mem(dev)
    rb0 = ps.n_rebuilds
    ps.timers.clear()
    t0 = time.perf_counter()
    ps.step(steps)
    _sync(dev)
    wall = time.perf_counter() - t0
    rate = n_total * steps / wall
    res = {
        "case": name, "device": str(dev), "dt": dt, "steps": steps, "replicas": ps.R, "n_solvent": ps.N,
        "n_vertices": ps.Nv, "n_particles": n_total, "wall_s": wall, "particle_steps_per_s": rate,
        "steps_per_s": steps / wall, "us_per_step": 1e6 * wall / steps, "rebuilds": ps.n_rebuilds - rb0,
        "steps_per_rebuild": steps / max(1, ps.n_rebuilds - rb0), "overruns": ps.n_overruns,
        "setup_s": setup_s, "array_bytes_per_particle": ps.memory_bytes() / n_total,
        "nbr_capacity": int(ps.nbr.shape[0]), "use_graph": ps.use_graph, "timers_s": dict(ps.timers),
        "status": ps.status_numpy().tolist()[:8],
    }
    if free0 is not None and free1 is not None:
        res["device_used_bytes_per_particle"] = (free0 - free1) / n_total
    res["phase_ms"] = time_phases(ps, phase_reps)
    del ps
    return res


def fluid_specs(n_target: int, seed: int = 1):
    L = (n_target / 3.0) ** (1 / 3)
    tab = published_pair_table(5.7)  # only water-water matters here
    return [ReplicaSpec(box=(L, L, L), pairs=tab, seed=seed, water_density=3.0)]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--quick", action="store_true", help="small sizes (CPU smoke test)")
    ap.add_argument("--cases", default="i,ii,iii")
    ap.add_argument("--steps", type=int, default=None)
    ap.add_argument("--fluid-n", type=int, default=1_000_000)
    ap.add_argument("--replicas", type=int, default=64)
    ap.add_argument("--fluid-dt", type=float, default=1e-4)
    ap.add_argument("--chunk", type=int, default=20, help="steps per captured graph, fluid")
    ap.add_argument("--bubble-chunk", type=int, default=10, help="steps per captured graph, bubbles (fast gas)")
    ap.add_argument("--out", default=None)
    args = ap.parse_args(argv)
    wp.init()
    cases = args.cases.split(",")
    results = []
    if args.quick:
        fluid_n, reps, steps, diam, sub = 20_000, 2, args.steps or 100, 1.5, 3
    else:
        fluid_n, reps, steps, diam, sub = args.fluid_n, args.replicas, args.steps or 2000, 3.0, 4
    box = None if not args.quick else (9.0, 9.0, 9.0)
    if "i" in cases:
        results.append(run_case("(i) DPD fluid rho=3", fluid_specs(fluid_n), args.fluid_dt, steps, args.device,
                                args.chunk, 0.3, 10))
        print(json.dumps(results[-1]), flush=True)
    if "i-dt1e-3" in cases:
        results.append(run_case("(i) DPD fluid rho=3, dt=1e-3", fluid_specs(fluid_n), 1e-3, steps, args.device,
                                args.chunk, 0.3, 10))
        print(json.dumps(results[-1]), flush=True)
    if "ii" in cases:
        results.append(run_case("(ii) one 3 um bubble", [bubble_spec(diam, sub, box=box, seed=1)], 1e-4,
                                steps * 5, args.device, args.bubble_chunk, 0.4, 50))
        print(json.dumps(results[-1]), flush=True)
    if "iii" in cases:
        specs = [bubble_spec(diam, sub, box=box, seed=100 + k) for k in range(reps)]
        results.append(run_case(f"(iii) {reps} bubbles batched", specs, 1e-4, steps, args.device,
                                args.bubble_chunk, 0.4, 10))
        print(json.dumps(results[-1]), flush=True)
    by = {r["case"][:4]: r for r in results}
    summary = {}
    if "(i) " in by and "(iii" in by:
        summary["iii_vs_i_per_particle"] = by["(i) "]["particle_steps_per_s"] / by["(iii"]["particle_steps_per_s"]
    payload = {"results": results, "summary": summary, "gpu": str(wp.get_device(args.device))}
    if args.out:
        with open(args.out, "w") as fh:
            json.dump(payload, fh, indent=1)
    print("\n| case | particles | steps/rebuild | particle-steps/s | µs/step | bytes/particle |")
    print("|---|---|---|---|---|---|")
    for r in results:
        print(f"| {r['case']} | {r['n_particles']:,} | {r['steps_per_rebuild']:.0f} | {r['particle_steps_per_s']:.3g} "
              f"| {r['us_per_step']:.1f} | {r['array_bytes_per_particle']:.0f} |")
    for r in results:
        tot = sum(r["phase_ms"].values())
        split = ", ".join(f"{k} {v:.3f} ms" for k, v in r["phase_ms"].items())
        print(f"{r['case']}: {split} (sum {tot:.3f} ms)")
    print(json.dumps({"summary": summary}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
