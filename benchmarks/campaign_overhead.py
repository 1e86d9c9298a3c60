"""Dask campaign overhead: the same tasks run serially in-process vs through ``run_campaign`` on a LocalCluster.

Two kinds of task:

* ``--mode loop`` (default): a fixed-duration compute loop (``synthetic_simulate(work_seconds=d)``): each task
  burns ``d`` seconds of wall time whatever the machine's load, so the serial time is exactly ``N d`` and the
  ideal campaign wall with W workers is ``N d / W``.  Swept over ``--durations``.
* ``--mode quasistatic``: real work, the quasi-static tier (``--subdivisions`` 1-2, ``--replicas`` per task,
  published compression grid) on ``--device``.

Overhead of a campaign = 1 - (serial compute) / (W x campaign wall), the campaign wall measured from the
first submit to the last record written (fsync'ed store appends included; cluster start-up reported apart,
``startup_s``, and folded into ``overhead_incl_startup_pct``).  ``inside_pct`` is the overhead seen from the
per-task compute seconds measured inside the tasks.

    python benchmarks/campaign_overhead.py --durations 0.05 0.2 1 --tasks 16 --workers 1 2 --out results/campaign
    python benchmarks/campaign_overhead.py --mode quasistatic --subdivisions 2 --replicas 16 --tasks 8 \
        --workers 1 --device cuda --out results/campaign_gpu          # GPU machine (needs dask installed)

Prints a table and, last, one JSON line; ``--out`` gets ``campaign_overhead.json``.
"""

from __future__ import annotations

import argparse
import functools
import json
import logging
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from bubblecal.campaigns import (
    CampaignConfig,
    make_tasks,
    run_campaign,
    simulate_task,
    synthetic_simulate,
)

BOX = {"ka": (5580.0, 27900.0), "kb": (100.0, 1000.0), "b1": (0.0, 3.0), "b2": (0.0, 10.0), "a3": (-2.5, 3.0),
       "a4": (0.0, 4.0)}


def _config(store: Path, n_tasks: int, replicas: int, device: str, subdivisions: int | None,
            tier: str) -> CampaignConfig:
    return CampaignConfig(name="bench", protocol="compression", diameter_um=2.1, ranges=BOX,
                          n_samples=n_tasks * replicas, seed=1, tier=tier, replicas_per_task=replicas, device=device,
                          subdivisions=subdivisions, store=str(store))


def _serial(config: CampaignConfig, simulate) -> tuple[float, float]:
    """(seconds for all tasks in-process, seconds of a warm-up task excluded from it)."""
    tasks = make_tasks(config, range(config.n_design))
    t0 = time.perf_counter()
    simulate(tasks[0])  # warm-up (Warp module load, imports): not part of the serial time
    warm = time.perf_counter() - t0
    t0 = time.perf_counter()
    for task in tasks:
        simulate(task)
    return time.perf_counter() - t0, warm


def _campaign(config: CampaignConfig, simulate, workers: int) -> dict:
    from distributed import Client, LocalCluster

    t0 = time.perf_counter()
    cluster = LocalCluster(n_workers=workers, processes=True, threads_per_worker=1, dashboard_address=":0",
                           silence_logs=logging.ERROR)
    client = Client(cluster)
    startup = time.perf_counter() - t0
    try:
        s = run_campaign(config, client=client, simulate=simulate, progress=False)
    finally:
        client.close()
        cluster.close()
    assert s.n_written == config.n_design, s.as_dict()
    return {"wall_s": s.wall_seconds, "startup_s": startup, "compute_s": s.compute_seconds,
            "task_median_s": float(np.median(s.task_seconds)), "inside_pct": 100 * s.overhead_fraction}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mode", choices=("loop", "quasistatic"), default="loop")
    ap.add_argument("--durations", type=float, nargs="+", default=[0.05, 0.2, 1.0],
                    help="loop mode: seconds per task")
    ap.add_argument("--tasks", type=int, default=16, help="tasks per measurement")
    ap.add_argument("--replicas", type=int, default=4, help="replicas (samples) per task")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2], help="LocalCluster worker counts")
    ap.add_argument("--device", default="cpu", help="quasistatic mode: Warp device (cpu, cuda)")
    ap.add_argument("--subdivisions", type=int, default=1, help="quasistatic mode: icosphere level")
    ap.add_argument("--out", type=Path, default=None, help="folder for campaign_overhead.json")
    args = ap.parse_args(argv)

    rows = []
    cases = ([("loop", d) for d in args.durations] if args.mode == "loop" else [("quasistatic", None)])
    n_runs = len(cases) * len(args.workers)
    t_bench = time.perf_counter()
    done = 0
    for mode, duration in cases:
        if mode == "loop":
            simulate = functools.partial(synthetic_simulate, work_seconds=duration)
            tier, sub = "quasistatic", None
        else:
            simulate = simulate_task
            tier, sub = "quasistatic", args.subdivisions
        with tempfile.TemporaryDirectory() as tmp:
            cfg = _config(Path(tmp) / "serial", args.tasks, args.replicas, args.device, sub, tier)
            serial, warm = _serial(cfg, simulate)
            for w in args.workers:
                cfg = _config(Path(tmp) / f"w{w}", args.tasks, args.replicas, args.device, sub, tier)
                c = _campaign(cfg, simulate, w)
                ideal = serial / w
                row = {"mode": mode, "task_s": serial / args.tasks, "tasks": args.tasks, "replicas": args.replicas,
                       "workers": w, "serial_s": serial, "warmup_s": warm, **c, "ideal_wall_s": ideal,
                       "overhead_pct": 100 * (1 - serial / (w * c["wall_s"])),
                       "overhead_incl_startup_pct": 100 * (1 - serial / (w * (c["wall_s"] + c["startup_s"])))}
                rows.append(row)
                done += 1
                el = time.perf_counter() - t_bench
                print(f"[{done}/{n_runs}] {mode} task {row['task_s']:.3f} s, {w} worker(s): overhead "
                      f"{row['overhead_pct']:.1f} %  (elapsed {el:.0f} s, ETA {el / done * (n_runs - done):.0f} s)",
                      flush=True)
    hdr = (f"{'mode':<12}{'task s':>8}{'tasks':>6}{'W':>3}{'serial s':>10}{'wall s':>9}{'ideal s':>9}"
           f"{'start s':>8}{'overhead %':>11}{'+start %':>9}{'inside %':>9}")
    print(hdr)
    print("-" * len(hdr))
    for r in rows:
        print(f"{r['mode']:<12}{r['task_s']:>8.3f}{r['tasks']:>6d}{r['workers']:>3d}{r['serial_s']:>10.2f}"
              f"{r['wall_s']:>9.2f}{r['ideal_wall_s']:>9.2f}{r['startup_s']:>8.2f}{r['overhead_pct']:>11.1f}"
              f"{r['overhead_incl_startup_pct']:>9.1f}{r['inside_pct']:>9.1f}")
    result = {"benchmark": "campaign_overhead", "mode": args.mode, "device": args.device, "cpu_count": os.cpu_count(),
              "load_average_at_end": os.getloadavg()[0], "rows": rows}
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "campaign_overhead.json").write_text(json.dumps(result, indent=2))
    print(json.dumps(result))
    return result


if __name__ == "__main__":
    main()
