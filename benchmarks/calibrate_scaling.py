"""Cost of `bubblecal calibrate --data` against the number of bubbles: wall time, CPU time and peak memory.

    python benchmarks/calibrate_scaling.py --bubbles 1,10,50                       # 2 CPU cores, default N
    python benchmarks/calibrate_scaling.py --bubbles 1,10,50,200 --device gpu --paper --npz

For each bubble count K the script writes a tidy curves file of K compression bubbles of one agent at random
diameters (uniform in ``--diameters``) and, with ``--resonance`` (default on), one resonance row per bubble; then
runs ``bubblecal calibrate --data ... --acoustic ...`` in a fresh process with a fresh ``--out`` folder and an empty
compilation cache (cold: compilation counted); ``--warm`` runs each count once more with the cache it filled. The
curves are drawn from the shipped network over the diameter at parameters from a population inside the Definity
reduced priors, with the likelihood's relative noise; they serve the timing only (the validity study with quasi-
static curves is ``benchmarks/synthetic_population.py``). Every argument the script does not know goes to
``calibrate`` (``--population``, ``--paper``, ``--device``, ``--npz``, ``--no-figures``, ...).

Prints a table (K, datasets, wall [s], CPU [s], calibrate's "done in" [s], peak RSS [MiB], wall per bubble) and one
JSON line ``{"benchmark": "calibrate_scaling", ...}`` with the growth exponent b of wall ~ K^b between the two largest
counts.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import platform
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

_DONE = re.compile(r"done in ([0-9.]+) s")
#: JAX_PLATFORMS of the calibrate children (this process draws the curves on the CPU: see main)
_CHILD_PLATFORMS = os.environ.get("JAX_PLATFORMS")
AGENT = "scaling"


def write_bubbles(folder: Path, n: int, seed: int, diameters: tuple[float, float], resonance: bool,
                  points: int = 20) -> tuple[Path, Path | None]:
    """A tidy curves file of ``n`` compression bubbles (and a resonance file, one row each) drawn from the network.

    Parameters
    ----------
    folder : Path
        Where ``curves.csv`` and ``resonance.csv`` go.
    n : int
        Bubbles.
    seed : int
        Seed of the draws.
    diameters : (float, float)
        Range of the bubble diameters [um].
    resonance : bool
        Also write one resonance row per bubble (from the Definity acoustic law at the bubble's k_a).
    points : int
        Retained points per bubble.

    Returns
    -------
    (Path, Path or None)
        The curves file and the resonance file.
    """
    from bubblecal.data import DEFAULT_UNITS
    from bubblecal.priors import load_priors
    from bubblecal.surrogates import load_bundle
    from bubblecal.surrogates.bundle import default_bundle_path
    from bubblecal.surrogates.features import radius_of_diameter

    rng = np.random.default_rng(seed)
    bundle = load_bundle(default_bundle_path(must_exist=True))
    spec = load_priors("definity_reduced")
    net = bundle.over_diameter["compression"]
    (ka_lo, ka_hi), (kb_lo, kb_hi) = spec.parameters["ka"].prior.as_tuple(), spec.parameters["kb"].prior.as_tuple()
    law = bundle.acoustic_law.get("definity") if resonance else None
    folder.mkdir(parents=True, exist_ok=True)
    curves = folder / "curves.csv"
    res_rows = []
    with curves.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["bubble", "agent", "protocol", "diameter_um", "displacement_nm", "force_nN", "retained"])
        for i in range(n):
            d = float(np.round(rng.uniform(*diameters), 3))
            # a population inside the hyperprior boxes of the Definity priors (m, tau at their centres)
            ka = float(np.clip(rng.normal(np.mean(spec.parameters["ka"].hyper_m.as_tuple()),
                                          np.mean(spec.parameters["ka"].hyper_tau.as_tuple())), ka_lo, ka_hi))
            kb = float(np.clip(rng.normal(np.mean(spec.parameters["kb"].hyper_m.as_tuple()),
                                          np.mean(spec.parameters["kb"].hyper_tau.as_tuple())), kb_lo, kb_hi))
            d0 = float(rng.uniform(0.05, 0.3))
            sur = net.at_diameter(d)
            x = np.linspace(0.02, 0.9, points) * sur.loading_range_per_size[1] * 2 * float(radius_of_diameter(d))
            y = np.maximum(np.asarray(sur(np.array([ka, kb, 0.0, 0.0, 0.0, 0.0]), x)), 0.0)
            y = np.abs(y * (1.0 + 0.05 * rng.standard_normal(points)))  # the likelihood's relative noise, 5 %
            x = x + d0  # the measured displacement counts from before contact
            for xi, yi in zip(DEFAULT_UNITS.dpd_to_nm(x), DEFAULT_UNITS.dpd_to_nN(y), strict=True):
                w.writerow([f"b{i + 1:04d}", AGENT, "compression", d, f"{float(xi):.6g}", f"{float(yi):.6g}", 1])
            if law is not None:
                f = float(np.asarray(law.f_res(np.array(ka), d)).ravel()[0]) * (1.0 + 0.05 * rng.standard_normal())
                res_rows.append((d, f))
    res = None
    if res_rows:
        res = folder / "resonance.csv"
        res.write_text("agent,diameter_um,frequency_MHz\n" + "".join(f"{AGENT},{d},{f:.6g}\n" for d, f in res_rows))
    return curves, res


def run_count(n: int, root: Path, seed: int, diameters, resonance: bool, extra: list[str], warm: bool = False) -> dict:
    """Write the files of ``n`` bubbles and run calibrate on them in a fresh process (empty compilation cache;
    ``warm``: again, into a new ``--out``, with the cache the first run filled)."""
    folder = root / f"k{n}"
    if warm:
        curves, res = folder / "curves.csv", (folder / "resonance.csv" if resonance else None)
    else:
        curves, res = write_bubbles(folder, n, seed, diameters, resonance)
    env = {**os.environ, "BUBBLECAL_CACHE_DIR": str(folder / "jax_cache"), "COLUMNS": "200"}
    env.pop("JAX_PLATFORMS", None)
    if _CHILD_PLATFORMS is not None:
        env["JAX_PLATFORMS"] = _CHILD_PLATFORMS
    cmd = [sys.executable, "-m", "bubblecal.workflows.cli", "calibrate", "--data", str(curves),
           *(["--acoustic", str(res)] if res is not None else []), *extra,
           "--out", str(folder / ("out_warm" if warm else "out"))]
    # peak RSS of this child alone: RUSAGE_CHILDREN keeps the maximum over every child so far, so measure it
    # through a wrapper that reports its own child's figure
    wrapper = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:]); "
               "print('MAXRSS', resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr); "
               "sys.exit(r.returncode)")
    usage0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", wrapper, *cmd], env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    suffix = "_warm" if warm else ""
    (folder / f"stdout{suffix}.txt").write_text(proc.stdout)
    (folder / f"stderr{suffix}.txt").write_text(proc.stderr)
    if proc.returncode != 0:
        raise SystemExit(f"K = {n}: calibrate exited with {proc.returncode}; see {folder}/stderr{suffix}.txt\n"
                         + proc.stderr[-3000:])
    rss = re.findall(r"MAXRSS (\d+)", proc.stderr)
    done = _DONE.findall(proc.stdout)
    datasets = n + (n if res is not None else 0)
    return {"bubbles": n, "cache": "warm" if warm else "cold", "datasets": datasets, "wall_s": round(wall, 1),
            "cpu_s": round(usage.ru_utime + usage.ru_stime - usage0.ru_utime - usage0.ru_stime, 1),
            "done_in_s": float(done[-1]) if done else None,
            "peak_rss_mib": round(int(rss[-1]) / 1024, 1) if rss else None,
            "wall_per_bubble_s": round(wall / n, 2)}


def growth_exponent(rows: list[dict]) -> float | None:
    """b in wall ~ K^b between the two largest bubble counts of the cold runs (None with fewer than two)."""
    cold = [r for r in rows if r.get("cache", "cold") == "cold"]
    if len(cold) < 2:
        return None
    a, b = sorted(cold, key=lambda r: r["bubbles"])[-2:]
    return round(math.log(b["wall_s"] / a["wall_s"]) / math.log(b["bubbles"] / a["bubbles"]), 3)


def main(argv=None) -> list[dict]:
    """Run every bubble count; print the table and the JSON line; returns the rows."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bubbles", default="1,10,50", help="comma-separated bubble counts")
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--diameters", default="1.8,6.0", help="range of the bubble diameters [um]")
    ap.add_argument("--no-resonance", action="store_true", help="curves only (no resonance rows)")
    ap.add_argument("--root", type=Path, default=None, help="folder of the runs (default: a temporary folder)")
    ap.add_argument("--warm", action="store_true", help="run each count again with the compilation cache it filled")
    args, extra = ap.parse_known_args(argv)
    if "--out" in extra or "--data" in extra:
        raise SystemExit("--out and --data are set per run")
    counts = [int(k) for k in args.bubbles.split(",")]
    # JAX on a GPU would reserve most of its memory in this process while the calibrate children run
    os.environ["JAX_PLATFORMS"] = "cpu"
    diameters = tuple(float(v) for v in args.diameters.split(","))
    root = args.root or Path(tempfile.mkdtemp(prefix="bubblecal_scaling_"))
    rows = []
    for n in counts:
        for warm in (False, True) if args.warm else (False,):
            rows.append(run_count(n, root, args.seed, diameters, not args.no_resonance, extra, warm=warm))
            print(json.dumps(rows[-1]), flush=True)
    print(f"\n{'bubbles':>8} {'cache':>6} {'datasets':>9} {'wall [s]':>9} {'CPU [s]':>9} {'done in':>9} "
          f"{'RSS [MiB]':>10} {'s/bubble':>9}")
    for r in rows:
        print(f"{r['bubbles']:>8} {r['cache']:>6} {r['datasets']:>9} {r['wall_s']:>9} {r['cpu_s']:>9} "
              f"{r['done_in_s']!s:>9} {r['peak_rss_mib']!s:>10} {r['wall_per_bubble_s']:>9}")
    print(json.dumps({"benchmark": "calibrate_scaling", "calibrate_args": extra, "rows": rows,
                      "growth_exponent": growth_exponent(rows), "machine": platform.node(),
                      "cpus": os.cpu_count(), "date": time.strftime("%Y-%m-%d")}))
    return rows


if __name__ == "__main__":
    main()
