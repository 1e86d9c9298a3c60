"""Athermal quasi-static tier against the published Mirheo training rows, its throughput, and old vs new FIRE.

1. Validation (skip with ``--no-validation``): for each diameter with a ``training_head_*`` file in the
   shared reference folder, the valid rows are simulated with ``get_tier("quasistatic")`` on the
   published grid (one batch) and compared with the published curves (relative L2 per curve).
2. Throughput (``--throughput 256,1024,4096``): for each setup of ``--setups`` (default
   ``compression:3.0:4`` = protocol:diameter_um:subdivision) and each R, R random parameter sets from
   the published rows' box (built-in box when the reference file is absent) run as one batch on the
   published 15-point grid with the tier's settings and the device-resident FIRE
   (:mod:`bubblecal.sim.engine.minimize_device`); reports curves per GPU-hour, the lockstep efficiency (mean
   FIRE updates per replica / FIRE iterations run) and prints progress + ETA per load point.  A run
   whose predicted time (linear in R x N_v from the previous run) exceeds ``--budget-s`` is skipped.
   OUT/quasistatic_throughput.json is rewritten after every run (partial results survive a timeout).
3. Micro (``--micro 8``): old (NumPy FIRE, host round trip per step) vs new (device FIRE, float64 and
   float32) for R replicas at subdivisions ``--micro-sub`` (default 2,3) on short grids; wall times and
   the largest curve deviation from the NumPy FIRE.

    python benchmarks/quasistatic_gpu.py --device cuda --out OUT --no-validation --throughput 256,1024,4096 \
        [--setups compression:3.0:4,indentation:5.8:5] [--dtype float32] [--budget-s 500] [--self-avoid]
    python benchmarks/quasistatic_gpu.py --device cpu --out OUT --no-validation --micro 8

Prints tables and a final JSON line; writes OUT/quasistatic_validation.json, OUT/quasistatic_throughput.json,
OUT/quasistatic_micro.json and one PNG per validated diameter.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from tier_validation import find_reference  # sibling script (benchmarks/ is on sys.path when run)

from bubblecal.sim.engine import resolve_dtype
from bubblecal.sim.tiers import CurveRequest, get_tier
from bubblecal.surrogates.training import filter_curves, read_published, relative_l2

HEADS = (("compression", 2.1), ("compression", 2.9), ("compression", 3.0),
         ("indentation", 3.2), ("indentation", 5.8))


def _reference_dir() -> Path:
    # an absent folder is fine here: every file is checked (and skipped) on its own
    return find_reference(None) or Path(__file__).resolve().parents[2] / "shared" / "reference"


def _request(setup, diameter, ts, sub, rows=None):
    rows = np.arange(ts.n_curves) if rows is None else rows
    params = {k: ts.params[rows, i] for i, k in enumerate(("ka", "kb", "b1", "b2", "a3", "a4"))}
    return CurveRequest(protocol=setup, diameter_um=diameter, grid=tuple(ts.x[0]), params=params,
                        seeds=tuple(int(r) for r in rows), subdivisions=sub)


# fallback parameter boxes (ka, kb, b1, b2, a3, a4; DPD) from the published training heads' valid rows
FALLBACK_BOX = {("compression", 3.0): ([6222.0, 128.3, 0.14, 0.01, -2.33, 0.04],
                                       [50530.0, 940.4, 2.89, 9.82, 2.75, 3.73]),
                ("indentation", 5.8): ([7450.0, 5088.0, 0.22, 0.64, -2.03, 0.10],
                                       [530469.0, 38094.0, 2.99, 9.55, 2.96, 3.96]),
                ("indentation", 3.2): ([23045.0, 8790.0, 0.04, 0.05, -2.38, 0.03],
                                       [477885.0, 28443.0, 2.94, 8.91, 2.85, 3.95])}
PARAM_KEYS = ("ka", "kb", "b1", "b2", "a3", "a4")


def _box(ref: Path, setup: str, diameter: float):
    path = ref / f"training_head_{setup}_{diameter}um.csv"
    if path.is_file():
        ts, _ = filter_curves(read_published(path, setup))
        return ts.params.min(axis=0), ts.params.max(axis=0), "published rows"
    if (setup, diameter) not in FALLBACK_BOX:
        raise SystemExit(f"no parameter box for {setup} {diameter} um (reference file {path} absent)")
    lo, hi = FALLBACK_BOX[(setup, diameter)]
    return np.asarray(lo), np.asarray(hi), "built-in box"


def throughput(args, out: Path, ref: Path, t_start: float) -> list:
    """Curves per GPU-hour of the tier (device FIRE) for each setup and batch size R."""
    from bubblecal.sim.engine import ShellParams, mesh_for_diameter
    from bubblecal.sim.protocols.loading import (
        published_compression_protocol,
        published_indentation_protocol,
    )
    from bubblecal.sim.tiers.quasistatic import (
        FireSettings,
        IdealGas,
        quasistatic_compression,
        quasistatic_indentation,
    )

    tier = get_tier("quasistatic")  # its settings (ftol, max_steps, gas, rupture) are the defaults used here
    fire = FireSettings(ftol=tier.ftol, max_steps=tier.max_steps)
    sizes = [int(v) for v in args.throughput.split(",") if v.strip()]
    runs: list = []
    last = None  # (seconds, R * Nv) of the previous run, for the ETA
    path = out / "quasistatic_throughput.json"
    print(f"{'setup':12s} {'D um':>5s} {'sub':>3s} {'Nv':>6s} {'R':>6s} {'ok':>6s} {'wall s':>8s} {'curves/h':>10s} "
          f"{'iters':>7s} {'lockstep':>8s}", flush=True)
    for spec in args.setups.split(","):
        setup, diameter, sub = spec.split(":")
        diameter, sub = float(diameter), int(sub)
        mesh = mesh_for_diameter(diameter, sub)
        lo, hi, box_src = _box(ref, setup, diameter)
        grid = (published_compression_protocol() if setup == "compression"
                else published_indentation_protocol(diameter)).as_array()
        # warm-up: compiles / loads the kernels for this device and dtype (not timed)
        _run_qs(setup, [ShellParams(ka=float(lo[0]), kb=float(lo[1]))], mesh, grid[:2], args, fire, tier,
                quasistatic_compression, quasistatic_indentation, IdealGas)
        for R in sizes:
            elapsed = time.perf_counter() - t_start
            eta = None if last is None else last[0] * R * mesh.n_vertices / last[1]
            if eta is not None and elapsed + eta > args.budget_s:
                print(f"skip {setup} {diameter} R={R}: predicted {eta:.0f} s, {args.budget_s - elapsed:.0f} s left",
                      flush=True)
                runs.append({"setup": setup, "diameter_um": diameter, "subdivisions": sub, "R": R,
                             "skipped": f"predicted {eta:.0f} s"})
                continue
            print(f"run {setup} {diameter} um s{sub} R={R}" + ("" if eta is None else f", ETA {eta:.0f} s"), flush=True)
            rng = np.random.default_rng(R)
            vals = rng.uniform(lo, hi, size=(R, 6))
            params = [ShellParams(**dict(zip(PARAM_KEYS, map(float, row), strict=True)),
                                  self_avoid=args.self_avoid) for row in vals]

            def progress(j, n, sec, R=R):
                left = sec / (j + 1) * (n - j - 1)
                print(f"  point {j + 1}/{n}  {sec:6.1f} s  ETA {left:6.1f} s", flush=True)

            t0 = time.perf_counter()
            res = _run_qs(setup, params, mesh, grid, args, fire, tier, quasistatic_compression,
                          quasistatic_indentation, IdealGas, progress=progress)
            wall = time.perf_counter() - t0
            last = (wall, R * mesh.n_vertices)
            iters = int(res.settings["fire_evaluations"])
            steps = res.fire_steps.sum(axis=1)
            n_ok = int(sum(s == "ok" for s in res.status))
            row = {"setup": setup, "diameter_um": diameter, "subdivisions": sub, "n_vertices": mesh.n_vertices,
                   "R": R, "dtype": args.dtype, "wall_s": wall, "curves_per_hour": 3600.0 * R / wall,
                   "n_ok": n_ok, "statuses": {s: res.status.count(s) for s in set(res.status)},
                   "fire_iterations": iters, "mean_fire_steps": float(steps.mean()),
                   "lockstep_efficiency": float(steps.mean() / max(iters, 1)),
                   "seconds_per_iteration": wall / max(iters, 1), "param_box": box_src, "device": args.device,
                   "self_avoid": args.self_avoid, "extrapolate": not args.no_extrapolate,
                   "sync_every": args.sync_every,
                   "max_fire_steps_point": int(res.fire_steps.max()), "n_not_converged_points": int(
                       sum(ps.count("not_converged") for ps in res.point_status))}
            runs.append(row)
            print(f"{setup:12s} {diameter:5.1f} {sub:3d} {mesh.n_vertices:6d} {R:6d} {n_ok:6d} {wall:8.1f} "
                  f"{row['curves_per_hour']:10.0f} {iters:7d} {row['lockstep_efficiency']:8.2f}", flush=True)
            path.write_text(json.dumps(runs, indent=1))
    path.write_text(json.dumps(runs, indent=1))
    return runs


def _run_qs(setup, params, mesh, grid, args, fire, tier, comp, ind, IdealGas, progress=None, minimizer="device",
            dtype=None):
    common = dict(gas=IdealGas(p0=tier.gas_p0), device=args.device,
                  dtype=resolve_dtype(args.dtype) if dtype is None else dtype, fire=fire,
                  rupture_strain=tier.rupture_strain, progress=progress)
    if minimizer == "device":
        common["sync_every"] = args.sync_every
        common["extrapolate"] = not getattr(args, "no_extrapolate", False)
    else:  # "numpy": the tests' NumPy reference FIRE
        ref = _numpy_reference()
        comp, ind = ref.reference_compression, ref.reference_indentation
    if setup == "compression":
        return comp(params, mesh, grid, **common)
    return ind(params, mesh, grid, **common)


def _numpy_reference():
    """The NumPy reference FIRE of the quasi-static tier, ``tests/sim/tiers/quasistatic/qs_reference.py`` (a test
    helper outside the package), imported by path."""
    import importlib.util
    import sys

    name = "qs_reference"
    if name not in sys.modules:
        path = Path(__file__).resolve().parents[1] / "tests" / "sim" / "tiers" / "quasistatic" / "qs_reference.py"
        spec = importlib.util.spec_from_file_location(name, path)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        sys.modules[name] = mod
    return sys.modules[name]


def micro(args, out: Path) -> list:
    """Old (NumPy FIRE) vs new (device FIRE, float64 / float32) wall time and curve deviation."""
    import warp as wp

    from bubblecal.sim.engine import ShellParams, mesh_for_diameter
    from bubblecal.sim.tiers.quasistatic import (
        FireSettings,
        IdealGas,
        quasistatic_compression,
        quasistatic_indentation,
    )

    tier = get_tier("quasistatic")
    fire = FireSettings(ftol=tier.ftol, max_steps=tier.max_steps)
    R = args.micro
    rng = np.random.default_rng(0)
    lo, hi = (np.asarray(v) for v in FALLBACK_BOX[("compression", 3.0)])
    params = [ShellParams(**dict(zip(PARAM_KEYS, map(float, row), strict=True)))
              for row in rng.uniform(lo, hi, size=(R, 6))]
    cases = (("compression", 3.0, np.array([0.0, 0.12, 0.24, 0.36]), "force"),
             ("indentation", 3.0, np.array([0.0, 200.0, 400.0, 800.0]), "displacement"))
    rows = []
    print(f"{'setup':12s} {'sub':>3s} {'Nv':>5s} {'R':>3s} {'numpy s':>8s} {'dev f64 s':>9s} {'dev f32 s':>9s} "
          f"{'dev64':>8s} {'dev32':>8s}", flush=True)
    for sub in (int(v) for v in args.micro_sub.split(",")):
        for setup, diameter, grid, key in cases:
            mesh = mesh_for_diameter(diameter, sub)
            _run_qs(setup, params[:1], mesh, grid[:2], args, fire, tier, quasistatic_compression,
                    quasistatic_indentation, IdealGas, dtype=wp.float32)  # warm-up (compile)
            _run_qs(setup, params[:1], mesh, grid[:2], args, fire, tier, quasistatic_compression,
                    quasistatic_indentation, IdealGas, dtype=wp.float64)
            res, wall = {}, {}
            for name, mz, dt in (("numpy", "numpy", wp.float64), ("f64", "device", wp.float64),
                                 ("f32", "device", wp.float32)):
                t0 = time.perf_counter()
                res[name] = _run_qs(setup, params, mesh, grid, args, fire, tier, quasistatic_compression,
                                    quasistatic_indentation, IdealGas, minimizer=mz, dtype=dt)
                wall[name] = time.perf_counter() - t0
            ref_curve = getattr(res["numpy"], key)
            ok = np.array([s == "ok" for s in res["numpy"].status])
            scale = np.max(np.abs(ref_curve[ok]), axis=1, keepdims=True) if ok.any() else 1.0
            dev = {n: float(np.nanmax(np.abs(getattr(res[n], key)[ok] - ref_curve[ok]) / scale)) if ok.any()
                   else None for n in ("f64", "f32")}
            row = {"setup": setup, "subdivisions": sub, "n_vertices": mesh.n_vertices, "R": R, "grid": grid.tolist(),
                   "wall_numpy_s": wall["numpy"], "wall_device_f64_s": wall["f64"], "wall_device_f32_s": wall["f32"],
                   "max_dev_f64_vs_numpy": dev["f64"], "max_dev_f32_vs_numpy": dev["f32"],
                   "n_ok": int(ok.sum()), "device": args.device,
                   "fire_steps": {n: int(r.fire_steps.sum()) for n, r in res.items()},
                   "same_fire_steps_f64": bool(np.array_equal(res["f64"].fire_steps, res["numpy"].fire_steps))}
            rows.append(row)
            print(f"{setup:12s} {sub:3d} {mesh.n_vertices:5d} {R:3d} {wall['numpy']:8.2f} {wall['f64']:9.2f} "
                  f"{wall['f32']:9.2f} {dev['f64'] or 0:8.1e} {dev['f32'] or 0:8.1e}", flush=True)
            (out / "quasistatic_micro.json").write_text(json.dumps(rows, indent=1))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--out", default="quasistatic_out")
    ap.add_argument("--subdivisions", type=int, default=None, help="icosphere level (default: per diameter)")
    ap.add_argument("--rows", type=int, default=16)
    ap.add_argument("--throughput", default="", help="comma list of batch sizes R (e.g. 256,1024,4096; empty: skip)")
    ap.add_argument("--setups", default="compression:3.0:4", help="protocol:diameter_um:subdivision, comma list")
    ap.add_argument("--dtype", default="float64", choices=("float64", "float32"))
    ap.add_argument("--budget-s", type=float, default=500.0, help="skip throughput runs predicted to end later")
    ap.add_argument("--sync-every", type=int, default=None, help="device FIRE iterations per host check")
    ap.add_argument("--no-validation", action="store_true")
    ap.add_argument("--self-avoid", action="store_true",
                    help="throughput runs with shell self-avoidance (the tier's default is off)")
    ap.add_argument("--no-extrapolate", action="store_true",
                    help="start every load point from the last minimum (the tier extrapolates by default)")
    ap.add_argument("--micro", type=int, default=0, help="R for the old-vs-new micro benchmark (0: skip)")
    ap.add_argument("--micro-sub", default="2,3")
    ap.add_argument("--diameters", default="", help="comma list, e.g. 2.1,3.2 (default: all heads)")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    ref = _reference_dir()
    t_start = time.perf_counter()
    summary = {"benchmark": "quasistatic_gpu", "device": args.device, "dtype": args.dtype}
    if args.micro > 0:
        summary["micro"] = micro(args, out)
    if args.throughput:
        summary["throughput"] = throughput(args, out, ref, t_start)
    if args.no_validation:
        print(json.dumps(summary))
        return
    want = {float(v) for v in args.diameters.split(",") if v}
    tier = get_tier("quasistatic", subdivisions=args.subdivisions, dtype=args.dtype, self_avoid=args.self_avoid,
                    extrapolate=not args.no_extrapolate)
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
        err = relative_l2(batch.observable[ok], pub[ok])
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
    (out / "quasistatic_validation.json").write_text(json.dumps(results, indent=1))
    print(f"{'setup':12s} {'D um':>5s} {'ok/n':>6s} {'med relL2':>9s} {'wall s':>7s}")
    for setup, d, nok, n, med, wall in rows_out:
        print(f"{setup:12s} {d:5.1f} {nok:>3d}/{n:<2d} {med if med is not None else float('nan'):9.3f} {wall:7.1f}")
    print(json.dumps({**summary, **{
        k: {kk: v[kk] for kk in ("median_rel_l2", "n_ok", "wall_s")} for k, v in results.items()}}))


if __name__ == "__main__":
    main()
