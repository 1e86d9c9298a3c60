"""Host cost of the quasi-static refill pool per curve, against the pool's size.

A pool of S compression curves on a 12-vertex shell (icosphere level 0, R = 6 DPD lengths, random k_a, 57 load
points, 500 slots) runs on the CPU device: the force evaluations are nearly free, so the wall time is the host's
handling of finished points (measuring, classifying, storing, restarting).  That cost per curve must not grow with
S: it did while every measured point rebuilt an S x P observable table (a ``dict.setdefault`` default).

    python benchmarks/qs_host_overhead.py [--sizes 2000,6000] [--minimizer cg] [--points 57]

Prints one row per pool size and one JSON line (``{"benchmark": "qs_host_overhead", ...}``).
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np


def run(n_curves: int, minimizer: str, n_points: int, slots: int = 500) -> dict:
    """One pool of ``n_curves``: wall time, per curve, and the force evaluations per curve."""
    from bubblecal.sim.engine.kernels.shell import ShellParams
    from bubblecal.sim.engine.mesh import icosphere
    from bubblecal.sim.tiers.quasistatic import FireSettings, quasistatic_compression

    rng = np.random.default_rng(0)
    params = [ShellParams(ka=float(k), kb=500.0, self_avoid=False) for k in rng.uniform(4000, 20000, n_curves)]
    t0 = time.perf_counter()
    res = quasistatic_compression(params, icosphere(6.0, 0), np.linspace(0.0, 1.2, n_points),
                                  fire=FireSettings(minimizer=minimizer), max_replicas=slots)
    wall = time.perf_counter() - t0
    return {"curves": n_curves, "ok": res.status.count("ok"), "wall_s": round(wall, 2),
            "ms_per_curve": round(1e3 * wall / n_curves, 2),
            "evaluations_per_curve": float(res.fire_steps.sum(axis=1).mean())}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="2000,6000", help="pool sizes S, comma list")
    ap.add_argument("--minimizer", default="cg", choices=("fire", "cg"))
    ap.add_argument("--points", type=int, default=57, help="load points per curve")
    args = ap.parse_args(argv)
    import warp as wp

    wp.config.quiet = True
    rows = []
    print(f"{'curves':>7s} {'ok':>6s} {'wall s':>8s} {'ms/curve':>9s} {'evals/curve':>12s}")
    for n in (int(v) for v in args.sizes.split(",")):
        row = run(n, args.minimizer, args.points)
        rows.append(row)
        print(f"{row['curves']:7d} {row['ok']:6d} {row['wall_s']:8.1f} {row['ms_per_curve']:9.2f} "
              f"{row['evaluations_per_curve']:12.0f}", flush=True)
    print(json.dumps({"benchmark": "qs_host_overhead", "minimizer": args.minimizer, "points": args.points,
                      "rows": rows}))


if __name__ == "__main__":
    main()
