"""Athermal quasi-static tier against the published Mirheo training rows, and its throughput.

For each diameter with a ``training_head_*`` file in the shared reference folder, the valid rows
(filtered like training data) are simulated with ``get_tier("quasistatic")`` on the published grid
(one batch of all rows) and compared with the published curves (relative L2 per curve over the
whole grid).  Then ``--throughput R`` random parameter sets from the rows' box are run as one batch
at one diameter to measure curves per GPU-hour.

    python benchmarks/quasistatic_gpu.py --device cuda --out OUT [--subdivisions 4] [--throughput 256]

Prints a table and a final JSON line; writes OUT/quasistatic_validation.json and one PNG per diameter.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

from bubblecal.sim.tiers import CurveRequest, get_tier
from bubblecal.surrogates.dataset import filter_curves, read_published

HEADS = (("compression", 2.1), ("compression", 2.9), ("compression", 3.0),
         ("indentation", 3.2), ("indentation", 5.8))


def _reference_dir() -> Path:
    return Path(os.environ.get("BUBBLECAL_SHARED_REFERENCE",
                               Path(__file__).resolve().parents[2] / "shared" / "reference"))


def _request(setup, diameter, ts, sub, rows=None):
    rows = np.arange(ts.n_curves) if rows is None else rows
    params = {k: ts.params[rows, i] for i, k in enumerate(("ka", "kb", "b1", "b2", "a3", "a4"))}
    return CurveRequest(protocol=setup, diameter_um=diameter, grid=tuple(ts.x[0]), params=params,
                        seeds=tuple(int(r) for r in rows), subdivisions=sub)


def rel_l2(sim, pub):
    """Relative L2 distance per curve, ||sim - pub|| / ||pub|| (dimensionless)."""
    return np.linalg.norm(sim - pub, axis=1) / np.linalg.norm(pub, axis=1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--out", default="quasistatic_out")
    ap.add_argument("--subdivisions", type=int, default=None, help="icosphere level (default: per diameter)")
    ap.add_argument("--rows", type=int, default=16)
    ap.add_argument("--throughput", type=int, default=0, help="random sets for the throughput run (0: skip)")
    ap.add_argument("--diameters", default="", help="comma list, e.g. 2.1,3.2 (default: all heads)")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    ref = _reference_dir()
    want = {float(v) for v in args.diameters.split(",") if v}
    tier = get_tier("quasistatic", subdivisions=args.subdivisions)
    rows_out, results = [], {}
    for setup, diameter in HEADS:
        if want and diameter not in want:
            continue
        path = ref / f"training_head_{setup}_{diameter}um.csv"
        if not path.is_file():
            print(f"skip {path} (absent)")
            continue
        ts, rep = filter_curves(read_published(path, setup))
        ts_rows = np.arange(min(args.rows, ts.n_curves))
        t0 = time.perf_counter()
        batch = tier.run(_request(setup, diameter, ts, args.subdivisions, ts_rows), device=args.device)
        wall = time.perf_counter() - t0
        pub = ts.y[ts_rows]
        ok = batch.ok
        err = rel_l2(batch.observable[ok], pub[ok])
        ratio = np.nanmedian(batch.observable[ok][:, 1:] / pub[ok][:, 1:], axis=0)
        res = {"setup": setup, "diameter_um": diameter, "n": int(ts_rows.size), "n_ok": int(ok.sum()),
               "median_rel_l2": float(np.median(err)) if err.size else None,
               "iqr_rel_l2": [float(np.percentile(err, 25)), float(np.percentile(err, 75))] if err.size else None,
               "median_ratio_by_point": ratio.tolist(), "wall_s": wall,
               "n_vertices": batch.info["n_vertices"], "statuses": batch.status}
        results[f"{setup}_{diameter}"] = res
        rows_out.append((setup, diameter, res["n_ok"], res["n"], res["median_rel_l2"], wall))
        print(f"{setup:12s} {diameter:4.1f} um  ok {res['n_ok']}/{res['n']}  median rel L2 "
              f"{res['median_rel_l2']:.3f}  wall {wall:.1f} s  Nv {res['n_vertices']}", flush=True)
        try:
            import matplotlib

            matplotlib.use("Agg")
            import matplotlib.pyplot as plt

            fig, ax = plt.subplots(figsize=(4.5, 3.4))
            for k in range(min(4, ts_rows.size)):
                (line,) = ax.plot(ts.x[k], pub[k], "o", ms=3)
                ax.plot(ts.x[k], batch.observable[k], "-", color=line.get_color())
            ax.set_xlabel("displacement d [DPD]" if setup == "compression" else "force F [DPD]")
            ax.set_ylabel("force F [DPD]" if setup == "compression" else "displacement d [DPD]")
            ax.set_title(f"{setup} {diameter} um: Mirheo (dots) vs quasi-static (lines)", fontsize=8)
            fig.tight_layout()
            fig.savefig(out / f"qs_vs_mirheo_{setup}_{diameter}um.png", dpi=130)
            plt.close(fig)
        except ImportError:
            pass
        (out / "quasistatic_validation.json").write_text(json.dumps(results, indent=1))
    if args.throughput > 0:
        setup, diameter = "compression", 3.0
        ts, _ = filter_curves(read_published(ref / "training_head_compression_3.0um.csv", setup))
        lo, hi = ts.params.min(axis=0), ts.params.max(axis=0)
        rng = np.random.default_rng(0)
        params = {k: rng.uniform(lo[i], hi[i], args.throughput)
                  for i, k in enumerate(("ka", "kb", "b1", "b2", "a3", "a4"))}
        req = CurveRequest(protocol=setup, diameter_um=diameter, grid=tuple(ts.x[0]), params=params,
                           seeds=tuple(range(args.throughput)), subdivisions=args.subdivisions)
        t0 = time.perf_counter()
        batch = tier.run(req, device=args.device)
        wall = time.perf_counter() - t0
        results["throughput"] = {"R": args.throughput, "wall_s": wall, "n_ok": int(batch.ok.sum()),
                                 "curves_per_hour": 3600 * args.throughput / wall,
                                 "n_vertices": batch.info["n_vertices"]}
        print(f"throughput: {args.throughput} curves in {wall:.1f} s -> {3600 * args.throughput / wall:.0f} "
              f"curves/h (ok {batch.ok.sum()})", flush=True)
    (out / "quasistatic_validation.json").write_text(json.dumps(results, indent=1))
    print(f"{'setup':12s} {'D um':>5s} {'ok/n':>6s} {'med relL2':>9s} {'wall s':>7s}")
    for setup, d, nok, n, med, wall in rows_out:
        print(f"{setup:12s} {d:5.1f} {nok:>3d}/{n:<2d} {med if med is not None else float('nan'):9.3f} {wall:7.1f}")
    print(json.dumps({"benchmark": "quasistatic_gpu", "device": args.device, **{
        k: {kk: v[kk] for kk in ("median_rel_l2", "n_ok", "wall_s")} for k, v in results.items() if k != "throughput"},
        "throughput": results.get("throughput")}))


if __name__ == "__main__":
    main()
