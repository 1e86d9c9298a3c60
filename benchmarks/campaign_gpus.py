"""Campaign throughput on one GPU vs several: the same campaign slice with ``--gpus 1``, then ``--gpus 2``.

Each run is ``bubblecal sim campaign NAME --gpus G --limit N --store FRESH --no-progress`` in a child process with
a time limit, into a fresh store; a short untimed warm-up run first compiles and caches the Warp kernels.  For every
run: the ok records, the wall time (first submit to last record written, the summary's ``wall_seconds``; the
cluster start is reported apart), ok records per GPU-hour (ok / (wall x G)) and the speed-up over the first run
(ok / wall against ok / wall).

    python benchmarks/campaign_gpus.py definity_compression_2.9um --limit 7500          # the lent 2 x H100 host
    python benchmarks/campaign_gpus.py definity_compression_1.5-8um --limit 3000 \\
        --diameter 1.5 --diameter 1.6 ...                                                # a slice over the diameter
    python benchmarks/campaign_gpus.py tests/campaigns/tiny_campaign.toml --limit 2 --device-free   # CPU smoke run

Choosing the slice: the tasks of both runs should cost the same.  ``definity_compression_2.9um`` holds two tasks of
3,750 points, so ``--limit 7500`` gives one GPU the two tasks in turn and two GPUs one each.  A slice smaller than
one task is one task on one GPU and is split in two on two GPUs (each then pays the refill pool's tail, the last
curves running in a nearly empty pool); slices over the whole diameter range carry the large bubbles' slow curves
(minutes each), which set the wall time of short runs.

Prints one line per run as it finishes, then a table and, last, one JSON line; ``--out DIR`` keeps the stores,
the logs and ``campaign_gpus.json``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CLI = "import sys; from bubblecal.workflows.cli import main; sys.exit(main())"


def run_once(name: str, store: Path, gpus: int, limit: int, diameters: list[float], timeout_s: float,
             log: Path, device_free: bool) -> dict:
    """One campaign run in a child process; its summary (``ok``, ``wall_s``, ...) or why there is none."""
    cmd = [sys.executable, "-c", CLI, "sim", "campaign", name, "--store", str(store), "--limit", str(limit),
           "--no-progress"]
    cmd += ["--workers", str(gpus)] if device_free else ["--gpus", str(gpus)]
    for d in diameters:
        cmd += ["--diameter", str(d)]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s, check=False)
        out, rc = proc.stdout + proc.stderr, proc.returncode
    except subprocess.TimeoutExpired as exc:
        out = (exc.stdout or b"").decode() if isinstance(exc.stdout, bytes) else (exc.stdout or "")
        rc = "timeout"
    process_s = time.perf_counter() - t0
    log.write_text(" ".join(cmd) + "\n\n" + out)
    row = {"gpus": gpus, "limit": limit, "rc": rc, "process_s": round(process_s, 1), "store": str(store)}
    summary = next((json.loads(line) for line in reversed(out.splitlines()) if line.startswith("{")), None)
    if rc != 0 or summary is None:
        row["error"] = (f"timed out after {timeout_s:.0f} s" if rc == "timeout" else
                        f"exit {rc}: " + " ".join(out.strip().splitlines()[-3:])[:400])
        return row
    ok = int(summary["counts"].get("ok", 0))
    wall = float(summary["wall_seconds"])
    row.update(ok=ok, written=int(summary["n_written"]), tasks=int(summary["n_tasks"]),
               workers=int(summary["n_workers"]), wall_s=round(wall, 2),
               startup_s=round(float(summary["startup_seconds"]), 2),
               compute_s=round(float(summary["compute_seconds"]), 2),
               ok_per_hour=round(ok / wall * 3600) if wall > 0 else None,
               ok_per_gpu_hour=round(ok / (wall * gpus) * 3600) if wall > 0 else None)
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("name", nargs="?", default="definity_compression_2.9um", help="shipped campaign name or TOML")
    ap.add_argument("--limit", type=int, default=7500, help="samples per run (each run: a fresh store)")
    ap.add_argument("--gpus", type=int, nargs="+", default=[1, 2], help="GPU counts, in order (first = baseline)")
    ap.add_argument("--diameter", type=float, action="append", default=[], help="only this level [um] (repeatable)")
    ap.add_argument("--warmup", type=int, default=4, help="samples of the untimed warm-up run (0: none)")
    ap.add_argument("--budget-s", type=float, default=570.0, help="time for all runs together [s]")
    ap.add_argument("--out", type=Path, default=None, help="folder for stores, logs and the JSON (default: temp)")
    ap.add_argument("--device-free", action="store_true",
                    help="CPU smoke test of this script: --workers G instead of --gpus G (the file's device)")
    args = ap.parse_args(argv)
    out = args.out or Path(tempfile.mkdtemp(prefix="campaign_gpus-"))
    out.mkdir(parents=True, exist_ok=True)
    run_dir = Path(tempfile.mkdtemp(prefix="run-", dir=out))  # fresh stores on every call
    t_end = time.perf_counter() + args.budget_s
    print(f"campaign {args.name}, {args.limit} samples per run, GPUs {args.gpus}; stores under {run_dir}", flush=True)
    if args.warmup:
        w = run_once(args.name, run_dir / "warmup.store", args.gpus[0], args.warmup, args.diameter,
                     t_end - time.perf_counter(), run_dir / "warmup.log", args.device_free)
        print(f"warm-up ({args.warmup} samples): {w.get('error') or 'done'} in {w['process_s']} s", flush=True)
    rows = []
    for g in args.gpus:
        left = t_end - time.perf_counter()
        if left < 10:
            rows.append({"gpus": g, "error": "no time left in --budget-s"})
            continue
        row = run_once(args.name, run_dir / f"gpus{g}.store", g, args.limit, args.diameter, left,
                       run_dir / f"gpus{g}.log", args.device_free)
        rows.append(row)
        print(json.dumps(row), flush=True)
    base = rows[0] if rows and rows[0].get("ok_per_hour") else None
    for r in rows:
        if base and r.get("ok_per_hour"):
            r["speedup"] = round(r["ok_per_hour"] / base["ok_per_hour"], 3)
    print(f"\n{'GPUs':>4} {'tasks':>5} {'ok':>6} {'wall s':>8} {'start s':>7} {'ok/GPU-h':>9} {'speed-up':>8}")
    for r in rows:
        if "error" in r:
            print(f"{r['gpus']:>4}  {r['error']}")
            continue
        print(f"{r['gpus']:>4} {r['tasks']:>5} {r['ok']:>6} {r['wall_s']:>8.1f} {r['startup_s']:>7.1f} "
              f"{r['ok_per_gpu_hour']:>9} {r.get('speedup', float('nan')):>8.3f}")
    result = {"benchmark": "campaign_gpus", "campaign": args.name, "limit": args.limit, "diameters": args.diameter,
              "rows": rows, "speedup": rows[-1].get("speedup") if len(rows) > 1 else None}
    (out / "campaign_gpus.json").write_text(json.dumps(result, indent=1))
    print(json.dumps(result))
    return 0 if all("error" not in r for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
