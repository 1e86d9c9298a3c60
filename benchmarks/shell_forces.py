"""Shell force throughput on one GPU (bubblecal.sim.engine.kernels.shell.ShellForceField).

R = 6 icosphere (subdivision 4, 2,562 vertices) per replica, published parameters (ka = 16,751,
kb = 500, Kantor, self-avoidance on), float32.  All replicas share coordinates, as in the particle
system (each replica in its own box).  Prints a table of the per-evaluation time (eager and CUDA-graph replay)
and the per-kernel split, then one JSON line.
Usage: ``python benchmarks/shell_forces.py [--device cuda] [--out results.json]``.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import warp as wp

from bubblecal.sim.engine import ShellForceField, ShellParams, icosphere


def bench(reps: int, device: str, self_avoid: bool = True, mode: str = "auto", iters: int = 200) -> dict:
    m = icosphere(6.0, 4)
    p = ShellParams(ka=16751.0, kb=500.0, self_avoid=self_avoid)
    ff = ShellForceField([m] * reps, [p] * reps, device=device, dtype=wp.float32, force_mode=mode)
    rng = np.random.default_rng(0)
    x = np.concatenate([m.vertices] * reps) + 0.01 * rng.standard_normal((reps * m.n_vertices, 3))
    xw = wp.array(x, dtype=wp.vec3f, device=device)
    fw = wp.zeros_like(xw)
    ff.accumulate_forces(xw, fw)
    wp.synchronize()
    out = {"replicas": reps, "vertices": reps * m.n_vertices, "self_avoid": self_avoid, "mode": ff.force_mode}
    t = time.perf_counter()
    for _ in range(iters):
        ff.accumulate_forces(xw, fw)
    wp.synchronize()
    out["eager_us"] = (time.perf_counter() - t) / iters * 1e6
    if wp.get_device(device).is_cuda:
        with wp.ScopedCapture(device=device) as cap:
            for _ in range(10):
                ff.accumulate_forces(xw, fw)
        wp.capture_launch(cap.graph)
        wp.synchronize()
        t = time.perf_counter()
        for _ in range(iters // 10):
            wp.capture_launch(cap.graph)
        wp.synchronize()
        out["graph_us"] = (time.perf_counter() - t) / iters * 1e6
        with wp.ScopedTimer("split", print=False, cuda_filter=wp.TIMING_KERNEL, synchronize=True) as tm:
            for _ in range(20):
                ff.accumulate_forces(xw, fw)
        split: dict[str, float] = {}
        for r in tm.timing_results:
            name = r.name.split("__locals__")[-1].rsplit("_", 1)[0]
            split[name] = split.get(name, 0.0) + r.elapsed / 20 * 1e3
        out["kernel_us"] = split
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    wp.config.quiet = True
    wp.init()
    rows = []
    print(f"{'replicas':>8} {'self_avoid':>10} {'mode':>8} {'eager us':>9} {'graph us':>9}  kernel us", flush=True)
    for reps, sa, mode in [(1, True, "auto"), (64, True, "auto"), (64, False, "gather"), (64, False, "scatter"),
                           (256, True, "auto"), (256, False, "gather")]:
        row = bench(reps, args.device, sa, mode)
        rows.append(row)
        split = ", ".join(f"{k} {v:.1f}" for k, v in row.get("kernel_us", {}).items())
        print(f"{row['replicas']:>8} {row['self_avoid']!s:>10} {row['mode']:>8} {row['eager_us']:>9.1f} "
              f"{row.get('graph_us', float('nan')):>9.1f}  {split}", flush=True)
    print(json.dumps({"benchmark": "shell_forces", "device": args.device, "rows": rows}), flush=True)
    if args.out:
        with open(args.out, "w") as fh:
            json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main()
