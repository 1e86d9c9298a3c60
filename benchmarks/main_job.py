"""The main job cold and warm: `bubblecal calibrate` with an empty compilation cache, then with the cache it filled.

    python benchmarks/main_job.py                                  # default main job, CPU
    python benchmarks/main_job.py --paper --device gpu --npz       # every unknown argument goes to calibrate

Each run is a fresh process with a fresh ``--out`` folder under ``--root`` (default: a temporary folder); the
compilation cache is a fresh folder (``BUBBLECAL_CACHE_DIR``) shared by the runs: the first run is cold (empty
cache), the later ones warm. ``JAX_LOG_COMPILES=1`` makes JAX log every compilation; a program read back from the
cache is logged as a hit, so "compiled" = XLA compilations minus cache hits. Prints a table and one JSON line per
run set: process wall [s], its CPU time [s] (less sensitive to a shared machine's load), calibrate's own
"done in" [s] (sampling, summaries, figures; after the plan and its preflight), programs compiled, cache hits,
seconds in XLA compilation or cache loads, entries added to the TMCMC program store (``programs/`` of the cache
folder; a warm run that adds none read all of its TMCMC programs back without tracing them), and the load average.
``--no-cache-run`` adds a run with ``--no-cache`` (the cost of the cache's writes).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

_COMPILE = re.compile(r"Finished XLA compilation of (\S+) in ([0-9.eE+-]+) sec")
_HIT = re.compile(r"Persistent compilation cache hit for '([^']+)'")
_DONE = re.compile(r"done in ([0-9.]+) s")


def run_once(label: str, calibrate_args: list[str], out: Path, cache: Path, extra: list[str]) -> dict:
    """One ``bubblecal calibrate`` process: wall, "done in", compilations and cache hits (logs kept next to out)."""
    env = {**os.environ, "BUBBLECAL_CACHE_DIR": str(cache), "JAX_LOG_COMPILES": "1", "COLUMNS": "200"}
    cmd = [sys.executable, "-m", "bubblecal.workflows.cli", "calibrate", *calibrate_args, *extra, "--out", str(out)]
    load = os.getloadavg()[0]
    usage0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = usage.ru_utime + usage.ru_stime - usage0.ru_utime - usage0.ru_stime
    out.parent.mkdir(parents=True, exist_ok=True)
    Path(f"{out}.stdout.txt").write_text(proc.stdout)
    Path(f"{out}.stderr.txt").write_text(proc.stderr)
    if proc.returncode != 0:
        raise SystemExit(f"{label}: calibrate exited with {proc.returncode}; see {out}.stderr.txt\n"
                         + proc.stderr[-3000:])
    compiles = _COMPILE.findall(proc.stderr)
    done = _DONE.findall(proc.stdout)
    return {"run": label, "wall_s": round(wall, 1), "cpu_s": round(cpu, 1),
            "done_in_s": float(done[-1]) if done else None,
            "xla_compilations": len(compiles), "cache_hits": len(_HIT.findall(proc.stderr)),
            "compiled": len(compiles) - len(_HIT.findall(proc.stderr)),
            "compile_or_load_s": round(sum(float(s) for _, s in compiles), 1),
            "load_before": round(load, 2), "load_after": round(os.getloadavg()[0], 2)}


def _stored(cache: Path) -> int:
    """Entries of the TMCMC program store under the cache folder (a warm run that adds none read every one back)."""
    return len(list((cache / "programs").glob("*.jaxprog"))) if cache.exists() else 0


def main(argv=None) -> list[dict]:
    """Run the cold and warm main jobs; print the table and a JSON line; returns the rows."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--root", type=Path, default=None, help="folder of the runs' --out folders, logs and cache")
    ap.add_argument("--warm-runs", type=int, default=1, help="runs with the filled cache")
    ap.add_argument("--no-cache-run", action="store_true", help="also run once with --no-cache")
    args, calibrate_args = ap.parse_known_args(argv)
    if "--out" in calibrate_args:
        raise SystemExit("--out is set per run; pass --root for where the runs go")
    root = args.root or Path(tempfile.mkdtemp(prefix="bubblecal_main_job_"))
    root.mkdir(parents=True, exist_ok=True)
    cache = root / "jax_cache"
    if cache.exists() and any(cache.iterdir()):
        raise SystemExit(f"{cache} is not empty: the cold run needs an empty cache (choose a new --root)")
    plan = [("cold", [])] + [(f"warm{i + 1}" if args.warm_runs > 1 else "warm", []) for i in range(args.warm_runs)]
    if args.no_cache_run:
        plan.append(("no-cache", ["--no-cache"]))
    rows = []
    for label, extra in plan:
        before = _stored(cache)
        row = run_once(label, calibrate_args, root / label, cache, extra)
        row["programs_stored"] = _stored(cache) - before
        rows.append(row)
        print(f"{label}: wall {row['wall_s']} s, cpu {row['cpu_s']} s, done in {row['done_in_s']} s, "
              f"{row['compiled']} compiled, {row['cache_hits']} cache hits, {row['programs_stored']} programs stored "
              f"(load {row['load_before']} -> {row['load_after']})", flush=True)
    cache_mb = sum(f.stat().st_size for f in cache.rglob("*") if f.is_file()) / 2**20 if cache.exists() else 0.0
    columns = [("run", "run", 9), ("wall s", "wall_s", 8), ("cpu s", "cpu_s", 8), ("done in s", "done_in_s", 10),
               ("compiled", "compiled", 9), ("hits", "cache_hits", 6), ("stored", "programs_stored", 7),
               ("compile s", "compile_or_load_s", 10),
               ("load before", "load_before", 12), ("load after", "load_after", 11)]
    print("\n" + " ".join(f"{h:>{w}}" for h, _, w in columns))
    for r in rows:
        print(" ".join(f"{r[k]!s:>{w}}" for _, k, w in columns))
    print(json.dumps({"benchmark": "main_job", "args": calibrate_args, "machine": platform.node(),
                      "cpus": os.cpu_count(), "cache_mb": round(cache_mb, 1), "root": str(root), "runs": rows}))
    return rows


if __name__ == "__main__":
    main()
