"""Validation of the fidelity tiers against the published Mirheo curves and against each other.

For each diameter: the first ``--rows`` valid rows of
``<reference>/training_head_{compression,indentation}_<d>um.csv`` (read with
:func:`bubblecal.surrogates.training.read_published` + :func:`filter_curves`; indentation responses are
d = 2 * radius_dpd - axial diameter) are simulated with each requested tier (``get_tier``) at the rows'
parameters and grid, geometry from the rows' radius (3.2 um rows: radius 6.38 -> 3.19 um).  Reported per
diameter and tier: median and IQR of the relative L2 error ||y_tier - y_pub|| / ||y_pub|| over the rows,
the same against the explicit tier (the <= 3 % fidelity gate) when it ran, wall seconds, curves per
GPU-hour (ok curves / wall), statuses.  Files under ``--out``: ``tier_validation.json`` (rewritten
after every diameter, so a cut-off run keeps its finished diameters), ``curves_<d>um.csv`` (all curves)
and ``overlay_<d>um.png`` (published vs tiers, up to 4 rows).  Last stdout line: one JSON summary.

Usage (CPU smoke):
  python benchmarks/tier_validation.py --device cpu --diameters 2.1 --rows 2 --scale 0.002 --subdivisions 2 \
      --out /tmp/tv
GPU (see benchmarks/RESULTS.md for the recommended calls, each < 9 minutes):
  python benchmarks/tier_validation.py --device cuda --diameters 2.1 --rows 5 --tiers explicit --out out/tv21
Re-gate a quasi-static variant on a CPU against the explicit curves of an earlier (GPU) run of the same rows:
  python benchmarks/tier_validation.py --device cpu --tiers quasistatic --rows 4 --lhs 20 --seed 3 --diameters 3.2 \
      --indentation-convention mirheo --qs-setting first_load_ramp=6 \
      --explicit-curves benchmarks/figures/gate_indentation_3.2um_mirheo.csv --out /tmp/gr32
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

TIERS = ("explicit", "implicit", "quasistatic")
PROTOCOL_OF = {2.1: "compression", 2.9: "compression", 3.0: "compression", 3.2: "indentation", 3.4: "indentation",
               5.8: "indentation"}
# H100 rates from benchmarks/RESULTS.md (Warp DPD engine): one 3 um bubble 262 us/step (launch bound),
# 64 bubbles 1.04e9 particle-steps/s; implicit: shell force field 212 us / 64 s4 replicas + ~40 % integrate
EXPLICIT_RATE = 1.0e9
EXPLICIT_FLOOR_S = 262e-6
IMPLICIT_US_PER_REPLICA_STEP = 4.5
IMPLICIT_FLOOR_S = 150e-6


def find_reference(arg: str | None) -> Path | None:
    """The shared reference folder: ``arg``, $BUBBLECAL_SHARED_REFERENCE, $BUBBLECAL_SHARED/reference, or
    ``shared/reference`` beside / inside the checkout; None when none exists.  (Also used by the other
    benchmark scripts.)"""
    cands = [Path(arg)] if arg else []
    if os.environ.get("BUBBLECAL_SHARED_REFERENCE"):
        cands.append(Path(os.environ["BUBBLECAL_SHARED_REFERENCE"]))
    if os.environ.get("BUBBLECAL_SHARED"):
        cands.append(Path(os.environ["BUBBLECAL_SHARED"]) / "reference")
    here = Path(__file__).resolve().parents[1]
    cands += [here.parent / "shared" / "reference", here / "shared" / "reference", Path("/work/shared/reference")]
    for c in cands:
        if c.is_dir():
            return c
    return None


def _head_file(ref: Path, protocol: str, diameter: float) -> Path | None:
    for name in (f"{diameter:g}", f"{diameter:.1f}"):
        path = ref / f"training_head_{protocol}_{name}um.csv"
        if path.is_file():
            return path
    return None


def load_rows(ref: Path, diameter: float, n_rows: int, first_row: int = 1):
    """(protocol, TrainingSet of n valid rows from the first_row-th valid row on) or (protocol, None)."""
    from bubblecal.surrogates.training import filter_curves, read_published

    protocol = PROTOCOL_OF.get(diameter)
    if protocol is None:
        for p in ("compression", "indentation"):
            if _head_file(ref, p, diameter) is not None:
                protocol = p
    if protocol is None:
        return None, None
    path = _head_file(ref, protocol, diameter)
    if path is None:
        return protocol, None
    ts, _report = filter_curves(read_published(path, setup=protocol))
    start = max(0, first_row - 1)
    idx = np.arange(start, min(start + n_rows, ts.n_curves))
    if idx.size == 0:
        return protocol, None
    return protocol, ts.subset(idx)


def estimate_seconds(tier: str, mesh, n_rep: int, steps: int, device: str) -> float | None:
    """Rough H100 wall-time estimate (None on CPU)."""
    if not device.startswith("cuda"):
        return None
    nv = mesh.n_vertices
    if tier == "explicit":
        r = mesh.radius_dpd
        particles = 3.0 * (2 * r + 5) ** 2 * (2 * r + 10) + nv
        return steps * max(EXPLICIT_FLOOR_S, n_rep * particles / EXPLICIT_RATE)
    if tier == "implicit":
        return steps * max(IMPLICIT_FLOOR_S, n_rep * IMPLICIT_US_PER_REPLICA_STEP * 1e-6 * nv / 2562)
    return None


def with_lhs_rows(ts, protocol: str, diameter: float, n: int, seed: int):
    """``ts`` plus ``n`` LHS rows (seeded) from the shipped campaign's prior box for this diameter, on the
    same grid and radius; their published curve is NaN (tier-vs-tier comparison only)."""
    import dataclasses

    from bubblecal.campaigns import available_campaigns, lhs_design, load_campaign_file
    from bubblecal.data import SHELL_PARAMETERS

    names = [c for c in available_campaigns()
             if c.endswith((f"_{protocol}_{diameter:g}um", f"_{protocol}_{diameter:.1f}um"))]
    if not names:
        raise SystemExit(f"--lhs: no shipped {protocol} campaign for {diameter:g} um")
    cfg = load_campaign_file(names[0]).config
    des = lhs_design(dataclasses.replace(cfg, n_samples=n, seed=cfg.seed + 7919 * seed))
    p_new = np.stack([np.asarray(des[k], dtype=np.float64) for k in SHELL_PARAMETERS], axis=1)
    m = ts.x.shape[1]
    return dataclasses.replace(
        ts, params=np.vstack([ts.params, p_new]), radius_dpd=np.r_[ts.radius_dpd, np.full(n, ts.radius_dpd[0])],
        x=np.vstack([ts.x, np.tile(ts.x[0], (n, 1))]), y=np.vstack([ts.y, np.full((n, m), np.nan)]),
        curve_id=np.r_[ts.curve_id, [f"lhs{i + 1}" for i in range(n)]],
        # per-row extras of the published rows (e.g. yt_pa) do not exist for LHS rows
        extra={k: np.r_[v, np.full(n, np.nan if np.issubdtype(np.asarray(v).dtype, np.floating) else -1)]
               for k, v in ts.extra.items()},
        status=None if ts.status is None else np.r_[ts.status, ["ok"] * n])


def lhs_only_rows(protocol: str, diameter: float, n: int, seed: int):
    """A diameter without published rows (e.g. 3.4 um): ``n`` LHS rows of the shipped campaign's box on its
    grid and radius (tier-vs-tier comparison only)."""
    from bubblecal.campaigns import available_campaigns, load_campaign_file
    from bubblecal.data import SHELL_PARAMETERS, radius_dpd_from_diameter_um
    from bubblecal.surrogates.training import TrainingSet

    names = [c for c in available_campaigns()
             if c.endswith((f"_{protocol}_{diameter:g}um", f"_{protocol}_{diameter:.1f}um"))]
    if not names:
        raise SystemExit(f"--lhs: no shipped {protocol} campaign for {diameter:g} um")
    grid = np.asarray(load_campaign_file(names[0]).config.grid_for(diameter), dtype=np.float64)
    # one carrier row holds the grid and radius that with_lhs_rows copies; it is dropped afterwards
    carrier = TrainingSet(setup=protocol, params=np.zeros((1, len(SHELL_PARAMETERS))),
                          radius_dpd=np.array([radius_dpd_from_diameter_um(diameter)]), x=grid[None, :],
                          y=np.full((1, grid.size), np.nan), curve_id=np.array(["grid"]), source=f"lhs:{names[0]}")
    out = with_lhs_rows(carrier, protocol, diameter, n, seed)
    return out.subset(np.arange(1, out.n_curves))  # drop the grid-carrier row


def lhs_slice(ts, n_lhs: int, spec: str):
    """``ts`` (published rows, then ``n_lhs`` LHS rows last) with only LHS rows ``A..B-1`` of ``spec`` = "A:B" kept;
    the published rows stay and the kept rows keep their ``lhs<i>`` ids, so curves match the full run's rows."""
    try:
        a, b = (int(v) for v in spec.split(":"))
    except ValueError:
        raise SystemExit(f"--lhs-slice {spec!r}: expected A:B with integers 0 <= A < B <= --lhs ({n_lhs})") from None
    if not 0 <= a < b <= n_lhs:
        raise SystemExit(f"--lhs-slice {spec!r}: expected 0 <= A < B <= --lhs ({n_lhs})")
    n_pub = ts.n_curves - n_lhs
    return ts.subset(np.r_[np.arange(n_pub), n_pub + np.arange(a, b)])


def rel_l2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise ||a - b|| / ||b|| (NaN where a row is not finite)."""
    num = np.linalg.norm(a - b, axis=1)
    den = np.linalg.norm(b, axis=1)
    out = num / np.where(den > 0, den, np.nan)
    out[~np.all(np.isfinite(a), axis=1)] = np.nan
    return out


def stats(e: np.ndarray) -> dict:
    e = e[np.isfinite(e)]
    if e.size == 0:
        return {"n": 0, "median": None, "iqr": None}
    q1, med, q3 = np.percentile(e, [25, 50, 75])
    return {"n": int(e.size), "median": float(med), "iqr": [float(q1), float(q3)]}


def overlay(path: Path, diameter: float, protocol: str, x: np.ndarray, y_pub: np.ndarray, curves: dict) -> None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # pragma: no cover
        return
    n = min(4, len(y_pub))
    fig, axes = plt.subplots(1, n, figsize=(4 * n, 3.4), squeeze=False)
    styles = {"explicit": "o-", "implicit": "s--", "quasistatic": "^:"}
    for i in range(n):
        ax = axes[0, i]
        ax.plot(x[i], y_pub[i], "k-", lw=2, label="published (Mirheo)")
        for t, y in curves.items():
            ax.plot(x[i], y[i], styles.get(t, "x-"), ms=3, label=t)
        ax.set_title(f"{diameter:g} um row {i + 1}")
        ax.set_xlabel("d [DPD length]" if protocol == "compression" else "F [DPD force]")
        ax.set_ylabel("F (both plates) [DPD force]" if protocol == "compression" else "d [DPD length]")
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def explicit_from_csv(path: str, ts) -> np.ndarray:
    """The explicit tier's curves [rows, points] from an earlier run's ``curves_<d>um.csv`` (columns row, point, x,
    ..., explicit) for the same rows: re-gating a cheaper tier variant without re-running the explicit tier."""
    import csv

    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows or "explicit" not in rows[0]:
        raise SystemExit(f"--explicit-curves {path}: no 'explicit' column")
    n_rows, n_pts = max(int(r["row"]) for r in rows), max(int(r["point"]) for r in rows)
    if (n_rows, n_pts) != ts.x.shape:
        raise SystemExit(f"--explicit-curves {path}: {n_rows} rows x {n_pts} points, this run has "
                         f"{ts.x.shape[0]} x {ts.x.shape[1]} (same --rows / --lhs / --seed / --diameters needed)")
    y, x = np.full(ts.x.shape, np.nan), np.full(ts.x.shape, np.nan)
    for r in rows:
        i, j = int(r["row"]) - 1, int(r["point"]) - 1
        y[i, j], x[i, j] = float(r["explicit"]), float(r["x"])
    if not np.allclose(x, ts.x, rtol=1e-9, atol=1e-9):
        raise SystemExit(f"--explicit-curves {path}: its loading grids differ from this run's rows")
    return y


def write_diameter_files(out: Path, d: float, protocol: str, ts, y_pub: np.ndarray, curves: dict, res: dict,
                         summary: dict) -> None:
    """curves_<d>um.csv (every finished tier), overlay_<d>um.png and tier_validation.json for diameter ``d``."""
    tiers = list(curves)
    header = ["row", "point", "x", "published"] + tiers
    lines = [",".join(header)]
    for i in range(ts.n_curves):
        for j in range(ts.x.shape[1]):
            lines.append(",".join([str(i + 1), str(j + 1), repr(float(ts.x[i, j])), repr(float(y_pub[i, j]))]
                                  + [repr(float(curves[t][i, j])) for t in tiers]))
    (out / f"curves_{d:g}um.csv").write_text("\n".join(lines) + "\n")
    overlay(out / f"overlay_{d:g}um.png", d, protocol, ts.x, y_pub, curves)
    summary["diameters"][f"{d:g}"] = res
    (out / "tier_validation.json").write_text(json.dumps(summary, indent=1))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--diameters", default="2.1,3.2", help="comma list of um (2.1, 2.9, 3.0 compression; 3.2, 5.8 "
                                                            "indentation)")
    ap.add_argument("--rows", type=int, default=5, help="first N valid rows per diameter")
    ap.add_argument("--first-row", type=int, default=1, help="start at this valid row (1-based; split runs)")
    ap.add_argument("--tiers", default="explicit,implicit,quasistatic")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--scale", type=float, default=1.0, help="multiplies every MD step count (smoke runs)")
    ap.add_argument("--replicas", type=int, default=0, help="rows per batch (0 = all rows in one batch)")
    ap.add_argument("--subdivisions", type=int, default=None, help="mesh level (default: 4, 5 above 5 um)")
    ap.add_argument("--implicit-dt", type=float, default=1e-4, help="time step of the implicit tier")
    ap.add_argument("--max-seconds", type=float, default=None, help="per tier and diameter; the rest -> 'timeout'")
    ap.add_argument("--reference", default=None, help="folder with training_head_*.csv")
    ap.add_argument("--out", default="tier_validation_out")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--plan-only", action="store_true", help="print the cost estimate and exit")
    ap.add_argument("--lhs", type=int, default=0,
                    help="add N Latin-hypercube parameter sets from the diameter's shipped campaign prior box "
                         "(tier-vs-tier rows: no published curve; the <= 3 %% gate needs >= 20 per diameter)")
    ap.add_argument("--lhs-slice", default=None, metavar="A:B",
                    help="keep only LHS rows A..B-1 (0-based) of the --lhs design: a long run of part of an earlier "
                         "run's rows (same --lhs / --seed), e.g. the published protocol length on the gate's rows")
    ap.add_argument("--qs-subdivisions", default="",
                    help="comma list of extra mesh levels for the quasi-static tier (e.g. 3): reported as "
                         "quasistatic_s<level> beside the tier at the common mesh")
    ap.add_argument("--qs-dtype", default="float64", choices=("float64", "float32"))
    ap.add_argument("--qs-thermal", action="store_true",
                    help="also run the quasi-static tier with the thermal plate contact (compression), reported as "
                         "quasistatic_thermal (and quasistatic_thermal_s<level> for --qs-subdivisions)")
    ap.add_argument("--max-replicas", type=int, default=None, help="quasi-static slot refill (execution only)")
    ap.add_argument("--qs-setting", action="append", default=[], metavar="KEY=VALUE",
                    help="extra quasi-static tier setting (JSON value), e.g. first_load_ramp=6; repeatable")
    ap.add_argument("--explicit-curves", default=None, metavar="CSV",
                    help="take the explicit tier's curves from an earlier run's curves_<d>um.csv (same rows; one "
                         "diameter) instead of simulating them")
    ap.add_argument("--indentation-convention", default=None,
                    help="every tier's indentation convention (bubblecal.sim.tiers.INDENTATION_CONVENTIONS; "
                         "default: the tiers' default, bubblecal-v1)")
    args = ap.parse_args(argv)

    import warp as wp

    wp.config.quiet = True
    from bubblecal.data import SHELL_PARAMETERS
    from bubblecal.sim.engine.mesh import mesh_for_diameter
    from bubblecal.sim.protocols import ProtocolSteps, steps_per_curve
    from bubblecal.sim.tiers import CurveRequest, get_tier
    from bubblecal.surrogates.training import diameter_um_from_radius

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    tiers = [t.strip() for t in args.tiers.split(",") if t.strip()]
    for t in tiers:
        if t not in TIERS:
            ap.error(f"--tiers: unknown tier {t!r} (choose from {TIERS})")
    if args.explicit_curves and "explicit" not in tiers:
        tiers.append("explicit")
    if args.explicit_curves and len([d for d in args.diameters.split(",") if d.strip()]) != 1:
        ap.error("--explicit-curves: one diameter per run")
    qs_extra = {}
    for kv in args.qs_setting:
        key, sep, value = kv.partition("=")
        if not sep:
            ap.error(f"--qs-setting {kv!r}: expected KEY=VALUE")
        try:
            qs_extra[key] = json.loads(value)
        except json.JSONDecodeError:
            qs_extra[key] = value  # a plain string
    tiers.sort(key=TIERS.index)  # explicit first: the others are compared with it
    extra_qs = [int(v) for v in args.qs_subdivisions.split(",") if v.strip()]
    if args.qs_thermal:
        tiers += ["quasistatic_thermal"]
    if extra_qs:
        tiers += [f"quasistatic_s{v}" for v in extra_qs]
        if args.qs_thermal:
            tiers += [f"quasistatic_thermal_s{v}" for v in extra_qs]
    diameters = [float(d) for d in args.diameters.split(",") if d.strip()]
    ref = find_reference(args.reference)
    summary = {"device": args.device, "scale": args.scale, "rows": args.rows, "tiers": tiers,
               "indentation_convention": args.indentation_convention or "tier default",
               "qs_settings": qs_extra, "explicit_curves": args.explicit_curves,
               "reference": str(ref) if ref else None, "diameters": {}, "started": time.strftime("%Y-%m-%d %H:%M:%S")}
    if ref is None:
        print("reference folder not found: nothing to validate (skipped)")
        print(json.dumps({"skipped": "no reference"}))
        return 0
    steps = ProtocolSteps().scaled(args.scale)

    # ---- up-front cost estimate
    plan = []
    for d in diameters:
        protocol, ts = load_rows(ref, d, args.rows, args.first_row)
        if ts is None and protocol is not None and args.lhs > 0:
            ts = lhs_only_rows(protocol, d, args.lhs, args.seed)
            print(f"{d:g} um: no training_head rows in {ref}: {args.lhs} LHS rows only (tier vs tier)")
        elif ts is None:
            print(f"{d:g} um: no training_head rows for it in {ref} -> skipped")
            continue
        elif args.lhs > 0:
            ts = with_lhs_rows(ts, protocol, d, args.lhs, args.seed)
        if args.lhs > 0 and args.lhs_slice:
            ts = lhs_slice(ts, args.lhs, args.lhs_slice)
        dia = diameter_um_from_radius(float(np.median(ts.radius_dpd)))
        mesh = mesh_for_diameter(dia, args.subdivisions)
        n_steps = steps_per_curve(steps, ts.x[0])
        plan.append((d, protocol, ts, dia, mesh, n_steps))
        rep = args.replicas or ts.n_curves
        n_batches = math.ceil(ts.n_curves / rep)
        for t in tiers:
            est = estimate_seconds(t, mesh, rep, n_steps, args.device)
            est_s = f"~{est * n_batches:.0f} s (H100 estimate)" if est is not None else "(no estimate)"
            print(f"plan {d:g} um {protocol}: {ts.n_curves} rows, mesh s{mesh.subdivisions} ({mesh.n_vertices} v), "
                  f"{n_steps} MD steps/curve, tier {t}: {n_batches} batch(es) of {rep} {est_s}", flush=True)
    if args.plan_only:
        print(json.dumps({"plan_only": True, "diameters": [p[0] for p in plan]}))
        return 0
    t_all = time.perf_counter()
    for k, (d, protocol, ts, dia, mesh, n_steps) in enumerate(plan):
        print(f"=== {d:g} um ({protocol}, geometry {dia:.3f} um, {ts.n_curves} rows) "
              f"[{k + 1}/{len(plan)}, {time.perf_counter() - t_all:.0f} s so far]", flush=True)
        y_pub = ts.y
        res: dict = {"protocol": protocol, "geometry_um": dia, "n_rows": ts.n_curves, "mesh_vertices": mesh.n_vertices,
                     "md_steps_per_curve": n_steps, "tiers": {}}
        curves: dict[str, np.ndarray] = {}
        rep = args.replicas or ts.n_curves
        for t in tiers:
            settings: dict = {"subdivisions": mesh.subdivisions}
            if args.indentation_convention:
                settings["indentation_convention"] = args.indentation_convention
            tier_name = t
            if t.startswith("quasistatic_"):
                tier_name = "quasistatic"
                if "_s" in t:
                    settings["subdivisions"] = int(t.rsplit("_s", 1)[1])
                settings["thermal_contact"] = t.startswith("quasistatic_thermal")
            if tier_name == "quasistatic":
                settings["dtype"] = args.qs_dtype
                settings.update(qs_extra)
                if args.max_replicas:
                    settings["max_replicas"] = args.max_replicas
            if t == "explicit" and args.explicit_curves:
                y = explicit_from_csv(args.explicit_curves, ts)
                curves[t] = y
                status = ["ok" if np.all(np.isfinite(row)) else "from_csv_not_finite" for row in y]
                res["tiers"][t] = {"wall_s": 0.0, "status": status, "health": [None] * len(status),
                                   "source": args.explicit_curves, "curves_per_gpu_hour": None,
                                   "rel_l2_vs_published": stats(rel_l2(y, y_pub)),
                                   "rel_l2_rows": [None if not np.isfinite(v) else float(v) for v in rel_l2(y, y_pub)]}
                continue
            if t in ("explicit", "implicit"):
                settings.update(scale=args.scale, verbose=True, max_seconds=args.max_seconds)
            if t == "implicit":
                settings["dt"] = args.implicit_dt
            tier = get_tier(tier_name, **settings)
            y = np.full_like(y_pub, np.nan)
            status: list[str] = []
            health: list = []  # MD tiers: the health check behind a non-ok status (NAN, LEAK, ...) and its point
            t0 = time.perf_counter()
            for b0 in range(0, ts.n_curves, rep):
                idx = np.arange(b0, min(ts.n_curves, b0 + rep))
                params = {name: ts.params[idx, j] for j, name in enumerate(SHELL_PARAMETERS)}
                req = CurveRequest(protocol=protocol, diameter_um=dia, grid=tuple(ts.x[idx[0]]), params=params,
                                   seeds=tuple(args.seed + 1000 * k + int(i) for i in idx),
                                   subdivisions=settings["subdivisions"])
                print(f"  {t}: rows {idx[0] + 1}-{idx[-1] + 1} ...", flush=True)
                batch = tier.run(req, device=args.device)
                y[idx] = batch.observable
                status += list(batch.status)
                health += list(batch.info.get("health") or [None] * len(batch.status))
                el = time.perf_counter() - t0
                eta = el / (idx[-1] + 1) * (ts.n_curves - idx[-1] - 1)
                print(f"  {t}: {idx[-1] + 1}/{ts.n_curves} rows, {el:.1f} s, ETA {eta:.0f} s, status {batch.status}",
                      flush=True)
            wall = time.perf_counter() - t0
            curves[t] = y
            n_ok = sum(s == "ok" for s in status)
            entry = {"wall_s": wall, "status": status, "health": health,
                     "curves_per_gpu_hour": n_ok / wall * 3600 if wall > 0 else None,
                     "rel_l2_vs_published": stats(rel_l2(y, y_pub)),
                     "rel_l2_rows": [None if not np.isfinite(v) else float(v) for v in rel_l2(y, y_pub)]}
            if t != "explicit" and "explicit" in curves:
                entry["rel_l2_vs_explicit"] = stats(rel_l2(y, curves["explicit"]))
                entry["gate_3pct_vs_explicit"] = (entry["rel_l2_vs_explicit"]["median"] is not None
                                                  and entry["rel_l2_vs_explicit"]["median"] <= 0.03)
            res["tiers"][t] = entry
            # rewrite the files after every tier: a run cut off by a wall-clock cap keeps its finished tiers
            write_diameter_files(out, d, protocol, ts, y_pub, curves, res, summary)
        write_diameter_files(out, d, protocol, ts, y_pub, curves, res, summary)
        print_table(d, res)
    summary["total_wall_s"] = time.perf_counter() - t_all
    (out / "tier_validation.json").write_text(json.dumps(summary, indent=1))
    compact = {d: {t: {"med_vs_pub": e["rel_l2_vs_published"]["median"],
                       "med_vs_explicit": e.get("rel_l2_vs_explicit", {}).get("median"),
                       "wall_s": round(e["wall_s"], 1), "curves_per_gpu_hour": e["curves_per_gpu_hour"],
                       "ok": sum(s == "ok" for s in e["status"])} for t, e in r["tiers"].items()}
               for d, r in summary["diameters"].items()}
    print(json.dumps({"device": args.device, "scale": args.scale, "results": compact,
                      "total_wall_s": round(summary["total_wall_s"], 1)}))
    return 0


def print_table(d: float, res: dict) -> None:
    print(f"\n{d:g} um ({res['protocol']}), {res['n_rows']} rows, {res['md_steps_per_curve']} MD steps/curve")
    print(f"{'tier':<12} {'relL2 vs pub (median [IQR])':<32} {'relL2 vs explicit':<28} {'wall s':>8} "
          f"{'curves/GPU-h':>12}  status")
    for t, e in res["tiers"].items():
        def fmt(s):
            if not s or s.get("median") is None:
                return "-"
            return f"{s['median']:.4f} [{s['iqr'][0]:.4f}, {s['iqr'][1]:.4f}]"
        cph = e["curves_per_gpu_hour"]
        print(f"{t:<12} {fmt(e['rel_l2_vs_published']):<32} {fmt(e.get('rel_l2_vs_explicit')):<28} "
              f"{e['wall_s']:>8.1f} {cph if cph is None else round(cph, 1)!s:>12}  {','.join(e['status'])}")
    print(flush=True)


if __name__ == "__main__":
    sys.exit(main())
