"""Ringdown sweep benchmark: one 28-k_a sweep per agent, wall time, sweeps per GPU-hour, check 7, f ~ M^-1/2.

    python benchmarks/ringdown.py --device cuda --out DIR [--tier implicit|explicit] [--n-ka 28]
        [--agents definity sonovue] [--definity-diameter 4.68] [--sonovue-diameter 2.6]
        [--mass-check 4] [--subdivisions N] [--n-periods 8] [--dt DT]

For each agent: :func:`bubblecal.workflows.acoustic_sweep.ringdown_sweep` at mass factor 160 over the
agent's acoustic k_a range (all k_a values batched into one launch sequence), fitted and converted to
MHz, the f_res^2(k_a) quadratic with leave-one-out errors, the check-7 ratio (2 pi f_0)^2 / omega0^2
(median, range) and -- with ``--mass-check K`` -- K of the k_a values again at mass factor 40: the
median ratio f_0(40) / f_0(160) (2 if f ~ M^-1/2).  Before simulating it prints a cost estimate
(steps from the automatic schedule; explicit tier: ~1e9 particle-steps/s on an H100 (benchmarks/RESULTS.md:
2.3e9 fluid, bubbles ~2.3x costlier)).  Writes per agent the sweep's CSV/JSON/PNG/npz into
``DIR/<agent>/`` and ``DIR/ringdown_benchmark.json``; prints a table and a final JSON line.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

DEFAULT_DIAMETERS = {"definity": 4.68, "sonovue": 2.6}
EXPLICIT_PARTICLE_STEPS_PER_S = {"cuda": 1.0e9, "cpu": 2.3e5}


def estimate(agent: str, diameter: float, ka: np.ndarray, tier: str, device: str, kw: dict) -> dict:
    """Steps and a rough wall-time estimate of one sweep (see the module docstring)."""
    from bubblecal.sim.engine import mesh_for_diameter
    from bubblecal.sim.protocols.ringdown import auto_schedule, breathing_mode_prediction

    mesh = mesh_for_diameter(diameter, kw.get("subdivisions"))
    mv = mesh.vertex_mass(mass_factor=160.0)
    M = mesh.n_vertices * mv
    R = mesh.radius_dpd
    if tier == "explicit":
        box = (2 * R + 5, 2 * R + 5, 2 * R + 10)
        pred = breathing_mode_prediction(ka, R, 3.0, M, explicit=True, box=box)["omega0_water"]
        dt = kw.get("dt") or 1e-4
        particles = 3.0 * float(np.prod(box)) * ka.size
    else:
        pred = breathing_mode_prediction(ka, R, 3.0, M)["omega0"]
        dt = kw.get("dt") or min(1e-3, 0.1 * math.sqrt(mv / (12.0 * float(ka.max()))))
        particles = float(mesh.n_vertices * ka.size)
    sched = auto_schedule(float(pred.min()), float(pred.max()), dt, n_periods=kw.get("n_periods", 8.0))
    steps = sched["equilibration_steps"] + sched["record_steps"]
    dev = "cuda" if device.startswith("cuda") else "cpu"
    if tier == "explicit":
        seconds = steps * particles / EXPLICIT_PARTICLE_STEPS_PER_S[dev]
    else:  # launch-bound: ~10 launches per step (~4 us each in a CUDA graph; ~0.6 ms per step on a loaded CPU)
        seconds = steps * (4e-5 if dev == "cuda" else 6e-4) + steps * particles * (2e-10 if dev == "cuda" else 2e-8)
    return {"agent": agent, "diameter_um": diameter, "n_vertices": mesh.n_vertices, "dt": dt, "steps": steps,
            "particles": particles, "estimate_s": seconds, **sched}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--tier", default="implicit", choices=("implicit", "explicit"))
    ap.add_argument("--agents", nargs="+", default=["definity", "sonovue"], choices=("definity", "sonovue"))
    ap.add_argument("--definity-diameter", type=float, default=DEFAULT_DIAMETERS["definity"])
    ap.add_argument("--sonovue-diameter", type=float, default=DEFAULT_DIAMETERS["sonovue"])
    ap.add_argument("--n-ka", type=int, default=28)
    ap.add_argument("--mass-check", type=int, default=4, help="k_a values re-run at mass factor 40 (0 = skip)")
    ap.add_argument("--subdivisions", type=int, default=None)
    ap.add_argument("--n-periods", type=float, default=8.0)
    ap.add_argument("--dt", type=float, default=None)
    ap.add_argument("--equilibration-steps", type=int, default=None)
    ap.add_argument("--max-estimate", type=float, default=500.0,
                    help="refuse to start when the total estimate exceeds this many seconds (0 = no limit)")
    a = ap.parse_args(argv)

    import warp as wp

    wp.config.quiet = True
    from bubblecal.workflows.acoustic_sweep import (
        default_ka_values,
        fit_sweep,
        ringdown_sweep,
        write_sweep_outputs,
    )

    a.out.mkdir(parents=True, exist_ok=True)
    diam = {"definity": a.definity_diameter, "sonovue": a.sonovue_diameter}
    kw = {k: v for k, v in dict(subdivisions=a.subdivisions, dt=a.dt, n_periods=a.n_periods,
                                equilibration_steps=a.equilibration_steps).items() if v is not None}
    plans = []
    for agent in a.agents:
        ka = default_ka_values(agent, a.n_ka)
        est = estimate(agent, diam[agent], ka, a.tier, a.device, kw)
        if a.mass_check:
            sub = ka[np.linspace(0, ka.size - 1, a.mass_check).round().astype(int)]
            est40 = estimate(agent, diam[agent], sub, a.tier, a.device, kw)
            est["estimate_s"] += est40["estimate_s"] / 2.0  # omega doubles: about half the steps
        plans.append((agent, ka, est))
        print(f"plan {agent} {diam[agent]:g} um [{a.tier}, {a.device}]: {ka.size} k_a, N_v {est['n_vertices']}, "
              f"dt {est['dt']:.3g}, {est['steps']} steps (eq {est['equilibration_steps']}, record "
              f"{est['record_steps']} every {est['record_every']}), ~{est['estimate_s']:.0f} s", flush=True)
    total = sum(p[2]["estimate_s"] for p in plans)
    print(f"estimated total ~{total:.0f} s", flush=True)
    if a.max_estimate and total > a.max_estimate:
        print(f"estimate {total:.0f} s exceeds --max-estimate {a.max_estimate:g} s; reduce --n-ka / --n-periods / "
              f"--agents or raise the limit", flush=True)
        return 2
    results = []
    t_all = time.perf_counter()
    for agent, ka, est in plans:
        def prog(msg):
            print(msg, flush=True)

        t0 = time.perf_counter()
        res = ringdown_sweep(agent, diam[agent], ka, tier=a.tier, device=a.device, mass_factor=160.0, seed=1,
                             progress=prog, **kw)
        wall = time.perf_counter() - t0
        fit = fit_sweep(res)[res.diameter_um] if res.valid.sum() >= 3 else None
        write_sweep_outputs(res, a.out / agent, fit=fit)
        s = res.summary()
        row = {"agent": agent, "diameter_um": diam[agent], "tier": a.tier, "device": a.device, "n_ka": int(ka.size),
               "n_valid": s["n_valid"], "wall_s": wall, "sweeps_per_gpu_hour": 3600.0 / wall,
               "estimate_s": est["estimate_s"], "steps": res.batch_info[0]["equilibration_steps"]
               + res.batch_info[0]["record_steps"], "dt": res.batch_info[0]["dt"],
               "n_vertices": res.batch_info[0]["n_vertices"],
               "check7_ratio_median": s["check7_ratio_median"], "check7_ratio_range": s["check7_ratio_range"],
               "check7_ratio_mesh_median": s["check7_ratio_mesh_median"],
               "loo_median": None if fit is None else fit.loo_median, "loo_max": None if fit is None else fit.loo_max,
               "f_res_MHz_range": [float(np.nanmin(res.column("f_res_MHz"))),
                                   float(np.nanmax(res.column("f_res_MHz")))],
               "r2_min": float(np.nanmin(res.column("r2"))), "mass_ratio_40_160": None}
        if a.mass_check:
            idx = np.linspace(0, ka.size - 1, a.mass_check).round().astype(int)
            t1 = time.perf_counter()
            res40 = ringdown_sweep(agent, diam[agent], ka[idx], tier=a.tier, device=a.device, mass_factor=40.0,
                                   seed=1, progress=prog, **kw)
            f40 = res40.column("f_0_dpd")
            f160 = res.column("f_0_dpd")[idx]
            ratio = f40 / f160
            row.update({"mass_ratio_40_160": float(np.nanmedian(ratio)), "mass_ratios": ratio.tolist(),
                        "mass_check_s": time.perf_counter() - t1})
            write_sweep_outputs(res40, a.out / f"{agent}_mass40", plot=False)
        results.append(row)
        (a.out / "ringdown_benchmark.json").write_text(json.dumps(results, indent=1, default=float))
    print()
    hdr = ("agent", "d [um]", "tier", "k_a", "valid", "wall [s]", "sweeps/GPU-h", "check-7 ratio", "mesh-corr.",
           "f(40)/f(160)", "LOO med [%]", "f_res [MHz]")
    print(" | ".join(hdr))
    for r in results:
        print(" | ".join([r["agent"], f"{r['diameter_um']:g}", r["tier"], str(r["n_ka"]), str(r["n_valid"]),
                          f"{r['wall_s']:.1f}", f"{r['sweeps_per_gpu_hour']:.1f}", f"{r['check7_ratio_median']:.4f}",
                          f"{r['check7_ratio_mesh_median']:.4f}",
                          "-" if r["mass_ratio_40_160"] is None else f"{r['mass_ratio_40_160']:.4f}",
                          "-" if r["loo_median"] is None else f"{100 * r['loo_median']:.3f}",
                          f"{r['f_res_MHz_range'][0]:.3g}-{r['f_res_MHz_range'][1]:.3g}"]))
    final = {"benchmark": "ringdown", "device": a.device, "tier": a.tier, "total_s": time.perf_counter() - t_all,
             "load_average": os.getloadavg()[0], "python": sys.version.split()[0], "results": results}
    print(json.dumps(final, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
