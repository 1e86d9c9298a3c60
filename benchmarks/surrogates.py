"""Surrogate benchmarks: (1) architecture-sweep wall time and known-answer accuracy, (2) JAX throughput.

Usage::

    # (1) full sweep (4 widths x 3 depths) on the synthetic known-answer set, or on a published table
    python benchmarks/surrogates.py sweep --setup compression --n-curves 400 --jobs 2 --out runs/bench_sweep
    python benchmarks/surrogates.py sweep --dataset REF/training_compression_2.1um.csv --jobs 2  # REF: published

    # (2) JAX throughput of one surrogate: 50,000 parameter sets x 24 points, vs the matmul floor
    python benchmarks/surrogates.py throughput --device cpu --n-sets 50000 --n-points 24 --hidden 128x3
    python benchmarks/surrogates.py throughput --device gpu --n-sets 50000 --n-points 24 --hidden 128x3

The throughput part needs numpy + jax only (no torch) and runs from a bare checkout (the package
is imported from the repository root when ``bubblecal`` is not installed).  Both print their table (the sweep's
per-architecture table; one throughput line) and, last, one JSON line.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _import_bubblecal() -> None:
    """Make ``import bubblecal`` work from a checkout that was never pip-installed."""
    try:
        import bubblecal  # noqa: F401
        return
    except ImportError:
        pass
    spec = importlib.util.spec_from_file_location("bubblecal", ROOT / "__init__.py",
                                                  submodule_search_locations=[str(ROOT)])
    mod = importlib.util.module_from_spec(spec)
    sys.modules["bubblecal"] = mod
    spec.loader.exec_module(mod)


def _parse_hidden(text: str) -> tuple[int, ...]:
    """'128x3' -> (128, 128, 128); '64,32' -> (64, 32)."""
    if "x" in text:
        w, d = text.split("x")
        return (int(w),) * int(d)
    return tuple(int(v) for v in text.split(","))


# ------------------------------------------------------------------------------------------------
def cmd_throughput(args) -> dict:
    os.environ.setdefault("JAX_PLATFORMS", "cuda" if args.device == "gpu" else "cpu")
    _import_bubblecal()
    import jax
    import jax.numpy as jnp
    import numpy as np

    from bubblecal.data import SHELL_PARAMETERS
    from bubblecal.surrogates import (
        Surrogate,
        flops_per_point,
        load,
        matmul_floor_forward,
        xavier_uniform_weights,
    )

    if args.weights:
        sur = load(args.weights)
    else:
        hidden = _parse_hidden(args.hidden)
        sizes = [7, *hidden, 1]
        w, b = xavier_uniform_weights(sizes, seed=0)
        md = {"setup": "compression", "diameter_um": 2.1, "radius_dpd": 4.2, "param_names": list(SHELL_PARAMETERS),
              "input_names": [*SHELL_PARAMETERS, "displacement"],
              "param_ranges": {k: [0.0, 1.0] for k in SHELL_PARAMETERS},
              "x_range": [0.0, 1.0], "holdout_score": float("nan"), "data_hash": "random-weights",
              "architecture": {"hidden": list(hidden), "activation": "tanh"}}
        sur = Surrogate(w, b, np.zeros(7), np.ones(7), np.zeros(1), np.ones(1), md)
    sizes = [sur.weights[0].shape[0]] + [int(w.shape[1]) for w in sur.weights]
    dev = jax.devices()[0]
    rng = np.random.default_rng(0)
    lo = np.array([sur.param_ranges[k][0] for k in sur.param_names])
    hi = np.array([sur.param_ranges[k][1] for k in sur.param_names])
    params = jnp.asarray(lo + rng.random((args.n_sets, 6)) * (hi - lo), dtype=jnp.float32)
    x = jnp.asarray(np.linspace(*sur.x_range, args.n_points), dtype=jnp.float32)
    n_points = args.n_sets * args.n_points

    f_sur = jax.jit(lambda p, xx: sur(p[:, None, :], xx[None, :]))
    u = jnp.asarray(rng.standard_normal((n_points, sizes[0])), dtype=jnp.float32)
    ws = [jnp.asarray(w) for w in sur.weights]
    bs = [jnp.asarray(b) for b in sur.biases]
    f_floor = jax.jit(lambda uu: matmul_floor_forward(ws, bs, uu))

    def timeit(fn, *a):
        fn(*a).block_until_ready()  # compile + warm-up
        fn(*a).block_until_ready()
        times = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            fn(*a).block_until_ready()
            times.append(time.perf_counter() - t0)
        return float(np.median(times)), float(np.min(times))

    t_sur, t_sur_min = timeit(f_sur, params, x)
    t_floor, t_floor_min = timeit(f_floor, u)
    flops = flops_per_point(sizes) * n_points
    res = {
        "benchmark": "surrogate_throughput", "device": str(dev), "platform": dev.platform,
        "jax": jax.__version__, "host": platform.node(), "cpu_count": os.cpu_count(),
        "hidden": sizes[1:-1], "n_sets": args.n_sets, "n_points_per_set": args.n_points, "n_points": n_points,
        "dtype": "float32", "repeats": args.repeats,
        "surrogate_median_s": t_sur, "surrogate_min_s": t_sur_min,
        "surrogate_points_per_s": n_points / t_sur,
        "matmul_floor_median_s": t_floor, "matmul_floor_points_per_s": n_points / t_floor,
        "ratio_surrogate_over_floor": t_sur / t_floor,
        "flops_per_point": flops_per_point(sizes), "surrogate_gflops": flops / t_sur / 1e9,
        "floor_gflops": flops / t_floor / 1e9,
    }
    print(f"[{dev.platform}] {sizes[1:-1]} MLP, {args.n_sets} sets x {args.n_points} pts = {n_points} points: "
          f"surrogate {t_sur * 1e3:.2f} ms ({n_points / t_sur:.3e} pts/s, {res['surrogate_gflops']:.1f} GFLOP/s); "
          f"matmul floor {t_floor * 1e3:.2f} ms ({n_points / t_floor:.3e} pts/s); ratio {t_sur / t_floor:.2f}")
    return res


# ------------------------------------------------------------------------------------------------
def cmd_sweep(args) -> dict:
    _import_bubblecal()
    import numpy as np

    from bubblecal.surrogates.training import (
        SweepConfig,
        TrainConfig,
        export_sweep,
        filter_curves,
        make_synthetic,
        noise_floor,
        read_dataset,
        relative_l2,
        run_sweep,
    )

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.dataset:
        path = Path(args.dataset)
        if not path.exists():
            print(f"dataset {path} not present: skipped")
            return {"benchmark": "surrogate_sweep", "skipped": f"{path} not present"}
        ts, report = filter_curves(read_dataset(path, setup=args.setup))
        print(report)
        synthetic = False
    else:
        radius = {"compression": 4.2, "indentation": 6.38}[args.setup]
        ts = make_synthetic(args.n_curves, args.setup, radius_dpd=radius, noise=args.noise, seed=args.data_seed)
        synthetic = True
    cfg = SweepConfig(widths=tuple(args.widths), depths=tuple(args.depths), holdout_frac=args.holdout_frac,
                      seed=args.seed, jobs=args.jobs,
                      train=TrainConfig(max_epochs=args.max_epochs, patience=args.patience,
                                        max_reductions=args.max_reductions, batch_size=args.batch_size,
                                        lr=args.lr, threads=1))
    res = run_sweep(ts, cfg, progress=not args.quiet)
    paths = res.write_report(out)
    npz = export_sweep(res, out / f"{ts.setup}_{ts.diameter_um:g}um.npz")
    summary = {"benchmark": "surrogate_sweep", "source": ts.source, "n_curves": ts.n_curves,
               "selected": res.best, "wall_s": res.wall_s, "jobs": args.jobs, "cpu_count": os.cpu_count(),
               "report": str(paths["markdown"]), "npz": str(npz)}
    if synthetic:
        ho = np.isin(ts.curve_id, res.holdout_set.curve_id)
        floor = noise_floor(ts, np.flatnonzero(ho))
        err_clean = relative_l2(res.holdout_pred, ts.extra["y_true"][ho])
        summary.update({"noise": args.noise, "noise_floor_median": floor,
                        "selected_over_floor": res.score / floor,
                        "selected_vs_truth_median": float(np.median(err_clean))})
    print(res.markdown())
    (out / "benchmark_summary.json").write_text(json.dumps(summary, indent=2, default=float))
    return summary


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("throughput", help="JAX surrogate throughput vs the matmul floor")
    t.add_argument("--device", choices=["cpu", "gpu"], default="cpu")
    t.add_argument("--n-sets", type=int, default=50_000)
    t.add_argument("--n-points", type=int, default=24)
    t.add_argument("--hidden", default="128x3", help="e.g. 128x3 (width x depth) or 64,64")
    t.add_argument("--weights", default=None, help="a surrogate .npz (overrides --hidden)")
    t.add_argument("--repeats", type=int, default=10)
    t.add_argument("--json-out", default=None)
    s = sub.add_parser("sweep", help="architecture sweep wall time / known-answer accuracy")
    s.add_argument("--dataset", default=None, help="published-layout table or campaign store (default: synthetic)")
    s.add_argument("--setup", choices=["compression", "indentation"], default="compression")
    s.add_argument("--n-curves", type=int, default=400)
    s.add_argument("--noise", type=float, default=0.01)
    s.add_argument("--data-seed", type=int, default=1)
    s.add_argument("--widths", type=int, nargs="+", default=[32, 64, 128, 256])
    s.add_argument("--depths", type=int, nargs="+", default=[2, 3, 4])
    s.add_argument("--holdout-frac", type=float, default=0.1)
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--jobs", type=int, default=2)
    s.add_argument("--max-epochs", type=int, default=2000)
    s.add_argument("--patience", type=int, default=40)
    s.add_argument("--max-reductions", type=int, default=3)
    s.add_argument("--batch-size", type=int, default=256)
    s.add_argument("--lr", type=float, default=1e-3)
    s.add_argument("--quiet", action="store_true")
    s.add_argument("--out", default="runs/bench_surrogate_sweep")
    s.add_argument("--json-out", default=None)
    args = ap.parse_args(argv)
    res = cmd_throughput(args) if args.cmd == "throughput" else cmd_sweep(args)
    print(json.dumps({k: v for k, v in res.items() if k != "selected"}, default=float))  # the JSON line
    if args.json_out:
        Path(args.json_out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json_out).write_text(json.dumps(res, indent=2, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
