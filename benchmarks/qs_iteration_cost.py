"""Cost of one batched FIRE iteration of the quasi-static tier vs the number of relaxing replicas.

The slot-refill chain's wall time is (FIRE iterations) x (cost per iteration); the last curves of a pool run
with few replicas relaxing, so this measures whether an iteration gets cheaper when most replicas are idle
(finished replicas skip every kernel's work) and what CUDA-graph replay saves over plain launches.

    python benchmarks/qs_iteration_cost.py --device cuda [--replicas 500] [--diameter 3.2] [--iters 2000]
        [--profile 100] [--force-mode gather|scatter]

Prints a table (ms per iteration by active replicas and graph on/off) and one JSON line.  ``--profile N``
also times N plain-launch iterations per row kernel by kernel (CUDA events, Warp's ScopedTimer): the GPU time of
each kernel per iteration and their sum, against the wall time per iteration (the rest is launch latency).
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--replicas", type=int, default=500)
    ap.add_argument("--diameter", type=float, default=3.2)
    ap.add_argument("--subdivisions", type=int, default=4)
    ap.add_argument("--iters", type=int, default=2000)
    ap.add_argument("--active", default="all,50,5,1")
    ap.add_argument("--profile", type=int, default=0, help="iterations timed kernel by kernel (CUDA only)")
    from bubblecal.sim.engine import FORCE_MODES

    ap.add_argument("--force-mode", default="auto", choices=FORCE_MODES,
                    help="shell forces per vertex (gather, the GPU default) or per element with atomics (scatter)")
    args = ap.parse_args(argv)
    import warp as wp

    from bubblecal.sim.engine import ShellParams, mesh_for_diameter
    from bubblecal.sim.protocols.loading import published_indentation_protocol
    from bubblecal.sim.tiers.quasistatic import FireSettings, IdealGas
    from bubblecal.sim.tiers.quasistatic.backends import _DeviceChain

    mesh = mesh_for_diameter(args.diameter, args.subdivisions)
    R, nv = args.replicas, mesh.n_vertices
    rng = np.random.default_rng(0)
    ka = np.exp(rng.uniform(np.log(2e3), np.log(4e5), R))
    kb = rng.uniform(500, 20000, R)
    params = [ShellParams(ka=float(k), kb=float(b), self_avoid=False) for k, b in zip(ka, kb, strict=True)]
    forces = np.asarray(published_indentation_protocol(args.diameter).forces_dpd)
    z0 = mesh.vertices[:, 2]
    k = max(1, int(0.01 * nv))
    order = np.argsort(z0)
    unit = np.zeros((nv, 3))
    unit[order[::-1][:k], 2], unit[order[:k], 2] = -1.0 / k, 1.0 / k
    tag = np.zeros(nv, dtype=np.int32)
    tag[order[::-1][:k]], tag[order[:k]] = 1, -1
    free = np.ones((nv, 3), dtype=bool)
    free[np.abs(z0 - z0.mean()) < 0.25 * mesh.min_edge_length(), 2] = False
    rows = []
    for graph in (True, False):
        fire = FireSettings(ftol=1e-30, max_steps=10**9, force_mode=args.force_mode)  # nobody converges while we time
        dc = _DeviceChain(params, mesh, IdealGas(), args.device, None, fire, free_v=free,
                          remove_mean=(True, True, True), unit=unit, tag=tag, use_graph=graph, loads=forces)
        dc.set_load_rows(np.full(R, forces[5]))
        for a in args.active.split(","):
            n_act = R if a == "all" else min(R, int(a))
            flags = np.zeros(R, dtype=bool)
            flags[:n_act] = True
            dc.fire.begin(ftol=fire.ftol, max_steps=fire.max_steps)
            dc.start_rows(np.zeros(R, dtype=np.int64), flags)
            for _ in range(4):  # warm-up (first chunk plain, second captured)
                dc.fire.advance()
            n_chunks = max(1, args.iters // dc.fire.sync_every)
            wp.synchronize_device(dc.device)
            t0 = time.perf_counter()
            for _ in range(n_chunks):
                dc.fire.advance()
            wp.synchronize_device(dc.device)
            ms = 1e3 * (time.perf_counter() - t0) / (n_chunks * dc.fire.sync_every)
            row = {"graph": bool(dc.fire.use_graph), "requested_graph": graph, "force_mode": dc.ff.force_mode,
                   "active": n_act, "replicas": R,
                   "n_vertices": nv, "ms_per_iteration": ms, "us_per_active_replica_iteration": 1e3 * ms / n_act}
            if args.profile and not graph:
                row["kernels_us_per_iteration"] = _kernel_profile(wp, dc, args.profile)
                row["kernels_sum_us"] = sum(row["kernels_us_per_iteration"].values())
                by_kernel = ", ".join(f"{k} {v:.1f}" for k, v in row["kernels_us_per_iteration"].items())
                print(f"  GPU us per iteration by kernel (sum {row['kernels_sum_us']:.1f} us of {1e3 * ms:.1f} us "
                      f"wall): {by_kernel}")
            rows.append(row)
            print(f"graph={dc.fire.use_graph!s:5} active={n_act:5d}/{R}: {ms:.4f} ms per iteration "
                  f"({1e3 * ms / n_act:.2f} us per active replica-iteration)", flush=True)
    print(json.dumps({"benchmark": "qs_iteration_cost", "device": args.device, "diameter_um": args.diameter,
                      "subdivisions": args.subdivisions, "rows": rows}))
    return 0


def _kernel_profile(wp, dc, n_iters: int) -> dict:
    """GPU microseconds per iteration of each kernel (and memset / memcpy) over ``n_iters`` plain iterations,
    largest first (empty on the CPU: CUDA activity timing only)."""
    wp.synchronize_device(dc.device)
    # results are collected only with cuda_filter set; print=False skips Warp's own report
    with wp.ScopedTimer("fire", print=False, cuda_filter=wp.TIMING_ALL, synchronize=True) as timer:
        for _ in range(n_iters):
            dc.fire._iteration()
    acc: dict[str, float] = {}
    for r in timer.timing_results:
        acc[r.name] = acc.get(r.name, 0.0) + r.elapsed  # ms
    return dict(sorted(((k, 1e3 * v / n_iters) for k, v in acc.items()), key=lambda kv: -kv[1]))


if __name__ == "__main__":
    raise SystemExit(main())
