"""Which convention difference explains the size-dependent indentation gap to the published Mirheo curves?

Answer (benchmarks/RESULTS.md, archive 2026-11-25, "the 5.8 um gap found"): the loaded pole patch.  The published
curves' compliance exponents (d/F ~ ka^a kb^b over the rows) are matched only with ~7 loaded vertices per pole on the
subdivision-4 mesh (the pole vertex and its first ring) and kernel kb = published kb: the tier's
``indentation_convention = "mirheo"`` (variant ``mirheo``).

At 3.2 um the quasi-static tier (kb x KB_KERNEL_SCALE["indentation"] = 2/3) matches the published Mirheo
d(F) to 1.00 +- 0.02; at 5.8 um it is 13-15 % stiffer (benchmarks/RESULTS.md, archive, "Gate at 5.8 um").
This script runs the quasi-static tier on a few valid published rows of both diameters (3.2 um = control)
for a set of variants and reports, per variant and diameter, the ratio d_ours / d_published per loading
point, reduced to the median over points ``--points`` (default 5-15, 1-based) per row, then the median
over rows.

Variants (``--variants``, comma list; default all of VARIANTS):
  baseline       the tier as shipped (gas p0 = 3, kb x 2/3, k = floor(0.01 N_v), radius from the row)
  gas_p0_0       no internal gas stiffness (IdealGas p0 = 0)
  gas_p0_x2      gas p0 doubled (6)
  kb_x0.5/kb_x2  kernel kb x 0.5 / x 2 relative to the baseline (i.e. published kb x 1/3, x 4/3)
  ka_x0.8        ka x 0.8 (mu = ka / 3 follows)
  kfrac_<f>      loaded fraction per pole f instead of 0.01 (k = floor(f N_v) vertices)
  sub<s>         icosphere subdivision s instead of ``--subdivisions``
  R_nominal      mesh radius from the nominal diameter (5.8 -> 11.6, 3.2 -> 6.4) instead of the rows' radius
  mirheo         the tier's indentation_convention = "mirheo" (vertices within 4.6 deg of a pole: 7 at subdivision 4,
                 19 at 5; kernel kb = published kb)
  dp_<p>         gas pressure p above the ambient at the reference (the tier's ``overpressure``)
  a+b            combination, e.g. kfrac_0.003+kb_x1.5 (kb_x1.5 = kernel kb equal to the published kb)
Analysis-only (no extra simulation, from the baseline curves):
  pubref_F0      published d taken relative to the published F = 0 axial diameter (instead of 2 radius)

Usage:
  python benchmarks/studies/mirheo_gap_58.py --device cpu --rows58 1,2,3 --rows32 1,2 --variants baseline,gas_p0_0
  python benchmarks/studies/mirheo_gap_58.py --device cuda --rows58 1-8 --rows32 1-4        # GPU: more rows
Prints one table (variant x diameter: median ratio, per-row ratios, statuses, wall s) and one JSON line last.
Reuses the row loading of benchmarks/tier_validation.py (read_published + filter_curves).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for tier_validation.py
from tier_validation import find_reference, load_rows  # noqa: E402  (benchmark script)

VARIANTS = {
    "baseline": {},
    "gas_p0_0": {"gas_p0": 0.0},
    "gas_p0_x2": {"gas_p0": 6.0},
    "kb_x0.5": {"kb": 0.5},
    "kb_x2": {"kb": 2.0},
    "ka_x0.8": {"ka": 0.8},
    "kfrac_0.005": {"fraction_loaded": 0.005},
    "kfrac_0.003": {"fraction_loaded": 0.003},
    "kfrac_0.02": {"fraction_loaded": 0.02},
    "sub3": {"subdivisions": 3},
    "sub5": {"subdivisions": 5},
    "R_nominal": {"nominal_radius": True},
    "mirheo": {"convention": "mirheo"},
}
ANALYSIS_ONLY = ("pubref_F0",)


def variant_spec(name: str) -> dict:
    """Settings of a variant: a VARIANTS key, a generic kfrac_<f> / sub<s> / kb_x<f> / ka_x<f> / gas_p0_<p> / dp_<p>,
    or several joined by '+' (e.g. kfrac_0.003+kb_x1.5)."""
    spec: dict = {}
    for part in name.split("+"):
        if part in VARIANTS:
            spec.update(VARIANTS[part])
        elif part.startswith("kfrac_"):
            spec["fraction_loaded"] = float(part[6:])
        elif part.startswith("sub"):
            spec["subdivisions"] = int(part[3:])
        elif part.startswith("kb_x"):
            spec["kb"] = float(part[4:])
        elif part.startswith("ka_x"):
            spec["ka"] = float(part[4:])
        elif part.startswith("gas_p0_"):
            spec["gas_p0"] = float(part[7:])
        elif part.startswith("dp_"):
            spec["overpressure"] = float(part[3:])
        else:
            raise ValueError(f"unknown variant {part!r}")
    return spec


def parse_rows(spec: str) -> list[int]:
    """'1,2,5-7' -> [1, 2, 5, 6, 7] (1-based valid-row numbers)."""
    out: list[int] = []
    for part in spec.split(","):
        part = part.strip()
        if not part:
            continue
        if "-" in part:
            a, b = part.split("-")
            out += list(range(int(a), int(b) + 1))
        else:
            out.append(int(part))
    return out


@contextlib.contextmanager
def loaded_fraction(fraction: float | None):
    """Temporarily make the tier's indentation use ``fraction_loaded=fraction`` (the tier does not expose it)."""
    import bubblecal.sim.tiers.quasistatic as qs

    if fraction is None:
        yield
        return
    orig = qs.quasistatic_indentation

    def patched(*a, **kw):
        kw.pop("fraction_loaded", None)
        kw["pole_patch"] = {"fraction": fraction}
        return orig(*a, **kw)

    qs.quasistatic_indentation = patched
    try:
        yield
    finally:
        qs.quasistatic_indentation = orig


def point_ratio(y: np.ndarray, pub: np.ndarray, pts: slice) -> tuple[np.ndarray, np.ndarray]:
    """(per-row median over ``pts`` of y / pub, per-point median over rows of y / pub)."""
    r = y[:, pts] / pub[:, pts]
    return np.nanmedian(r, axis=1), np.nanmedian(r, axis=0)


def compliance_exponents(y: np.ndarray, x: np.ndarray, ka: np.ndarray, kb: np.ndarray, pts: slice):
    """Least-squares fit log(median_pts d/F) = a log ka + b log kb + c over the finite rows -> (a, b) or None
    (Reissner point load: a = b = -1/2; a stretching-dominated response has |a| > |b|)."""
    c = np.nanmedian(y[:, pts] / x[:, pts], axis=1)
    m = np.isfinite(c) & (c > 0)
    if m.sum() < 3:
        return None
    A = np.c_[np.log(ka[m]), np.log(kb[m]), np.ones(int(m.sum()))]
    coef, *_ = np.linalg.lstsq(A, np.log(c[m]), rcond=None)
    return [round(float(coef[0]), 3), round(float(coef[1]), 3)]


def run_variant(name: str, spec: dict, diameter: float, ts, args) -> dict:
    from bubblecal.data import SHELL_PARAMETERS
    from bubblecal.sim.engine import mesh_for_diameter
    from bubblecal.sim.tiers import CurveRequest, get_tier
    from bubblecal.surrogates.training import diameter_um_from_radius

    dia = diameter if spec.get("nominal_radius") else diameter_um_from_radius(float(np.median(ts.radius_dpd)))
    sub = int(spec.get("subdivisions", args.subdivisions))
    tier = get_tier("quasistatic", subdivisions=sub, dtype=args.dtype, gas_p0=float(spec.get("gas_p0", 3.0)),
                    overpressure=float(spec.get("overpressure", 0.0)),
                    indentation_convention=spec.get("convention", "bubblecal-v1"))
    params = {k: ts.params[:, j].copy() for j, k in enumerate(SHELL_PARAMETERS)}
    params["ka"] *= float(spec.get("ka", 1.0))
    params["kb"] *= float(spec.get("kb", 1.0))
    req = CurveRequest(protocol="indentation", diameter_um=dia, grid=tuple(ts.x[0]), params=params,
                       seeds=tuple(range(ts.n_curves)), subdivisions=sub)
    t0 = time.perf_counter()
    with loaded_fraction(spec.get("fraction_loaded")):
        batch = tier.run(req, device=args.device)
    wall = time.perf_counter() - t0
    mesh = mesh_for_diameter(dia, sub)
    from bubblecal.sim.engine import pole_patches
    from bubblecal.sim.tiers import indentation_convention

    patch = ({"fraction": float(spec["fraction_loaded"])} if "fraction_loaded" in spec
             else indentation_convention(spec.get("convention", "bubblecal-v1")).pole_patch())
    return {"variant": name, "diameter": diameter, "geometry_um": dia, "radius_dpd_mesh": mesh.radius_dpd,
            "n_vertices": mesh.n_vertices, "k_loaded": len(pole_patches(mesh.vertices, **patch)[0]),
            "y": batch.observable, "status": list(batch.status), "wall_s": wall,
            "fire_steps": batch.info.get("fire_steps")}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--rows58", default="1,2,3", help="valid 5.8 um rows (1-based, e.g. 1,2,3 or 1-8)")
    ap.add_argument("--rows32", default="1,2", help="valid 3.2 um rows (control)")
    ap.add_argument("--diameters", default="5.8,3.2")
    ap.add_argument("--variants", default=",".join(list(VARIANTS) + list(ANALYSIS_ONLY)))
    ap.add_argument("--subdivisions", type=int, default=4)
    ap.add_argument("--dtype", default="float64", choices=("float64", "float32"))
    ap.add_argument("--points", default="5-15", help="1-based loading points for the median ratio")
    ap.add_argument("--budget-s", type=float, default=2400.0, help="skip remaining variants after this wall time")
    ap.add_argument("--reference", default=None)
    ap.add_argument("--out", default=None, help="optional folder for mirheo_gap_58.json (+ curves)")
    args = ap.parse_args(argv)

    import warp as wp

    wp.config.quiet = True
    ref = find_reference(args.reference)
    if ref is None:
        print("reference folder not found")
        print(json.dumps({"skipped": "no reference"}))
        return 0
    p0, p1 = (int(v) for v in args.points.split("-"))
    pts = slice(p0 - 1, p1)
    variants = [v.strip() for v in args.variants.split(",") if v.strip()]
    for v in variants:
        if v not in ANALYSIS_ONLY:
            try:
                variant_spec(v)
            except ValueError as exc:
                ap.error(str(exc))
    row_spec = {5.8: parse_rows(args.rows58), 3.2: parse_rows(args.rows32)}
    t_all = time.perf_counter()
    results: dict = {}
    table = []
    for d in (float(x) for x in args.diameters.split(",") if x.strip()):
        rows = row_spec.get(d) or [1, 2]
        protocol, ts_all = load_rows(ref, d, max(rows), 1)
        if ts_all is None:
            print(f"{d:g} um: no rows")
            continue
        ts = ts_all.subset(np.array([r - 1 for r in rows if r - 1 < ts_all.n_curves]))
        pub = ts.y  # d = 2 radius - axial diameter (read_published)
        exp_pub = compliance_exponents(pub, ts.x, ts.params[:, 0], ts.params[:, 1], pts)
        results[f"{d:g}"] = {"exponents_published": exp_pub, "rows": rows, "ka": ts.params[:, 0].tolist(),
                             "kb": ts.params[:, 1].tolist(),
                             "published": pub.tolist(), "grid": ts.x[0].tolist(), "variants": {}}
        print(f"=== {d:g} um: rows {rows}, ka {np.round(ts.params[:, 0]).tolist()}, kb "
              f"{np.round(ts.params[:, 1]).tolist()}; published compliance ~ ka^a kb^b, (a, b) = {exp_pub}",
              flush=True)
        base = None
        for v in variants:
            if v in ANALYSIS_ONLY:
                continue
            if time.perf_counter() - t_all > args.budget_s:
                print(f"  {v}: skipped (budget)", flush=True)
                continue
            spec = variant_spec(v)
            print(f"  {v} ...", flush=True)
            r = run_variant(v, spec, d, ts, args)
            ok = np.array([s == "ok" for s in r["status"]])
            y = np.where(ok[:, None], r["y"], np.nan)
            per_row, per_point = point_ratio(y, pub, pts)
            med = float(np.nanmedian(per_row)) if np.isfinite(per_row).any() else None
            # the validation metric: relative L2 over the whole curve, median over rows
            rel_l2 = np.linalg.norm(y - pub, axis=1) / np.linalg.norm(pub, axis=1)
            med_l2 = float(np.nanmedian(rel_l2)) if np.isfinite(rel_l2).any() else None
            expo = compliance_exponents(y, ts.x, ts.params[:, 0], ts.params[:, 1], pts)
            entry = {"median_ratio": med, "median_rel_l2": med_l2, "row_rel_l2": rel_l2.tolist(), "exponents": expo,
                     "row_ratios": per_row.tolist(), "point_ratios": per_point.tolist(),
                     "status": r["status"], "wall_s": r["wall_s"], "n_vertices": r["n_vertices"],
                     "k_loaded": r["k_loaded"], "radius_dpd_mesh": r["radius_dpd_mesh"], "spec": spec,
                     "fire_steps": r["fire_steps"], "curves": r["y"].tolist()}
            results[f"{d:g}"]["variants"][v] = entry
            table.append((v, d, med, per_row, r["status"], r["wall_s"], r["n_vertices"], r["k_loaded"], expo, med_l2))
            print(f"  {v:<12} {d:4g} um  median ratio {med if med is None else round(med, 4)}  rows "
                  f"{np.round(per_row, 4).tolist()}  Nv {r['n_vertices']} k {r['k_loaded']}  "
                  f"(a, b) {expo}  rel L2 {med_l2 if med_l2 is None else round(med_l2, 4)}  {r['wall_s']:.1f} s  "
                  f"{r['status']}", flush=True)
            if v == "baseline":
                base = y
            if args.out:
                Path(args.out).mkdir(parents=True, exist_ok=True)
                (Path(args.out) / "mirheo_gap_58.json").write_text(json.dumps(results, indent=1))
        if "pubref_F0" in variants and base is not None:
            pub0 = pub - pub[:, :1]  # published d relative to its own F = 0 axial diameter
            per_row, per_point = point_ratio(base, pub0, pts)
            med = float(np.nanmedian(per_row))
            results[f"{d:g}"]["variants"]["pubref_F0"] = {"median_ratio": med, "row_ratios": per_row.tolist(),
                                                          "point_ratios": per_point.tolist(), "wall_s": 0.0,
                                                          "published_d_at_F0": pub[:, 0].tolist()}
            table.append(("pubref_F0", d, med, per_row, ["(analysis)"], 0.0, None, None, None, None))
    total = time.perf_counter() - t_all
    print(f"\nd_ours / d_published, median over points {args.points} per row, then over rows "
          f"(device {args.device}, sub {args.subdivisions}, {args.dtype})")
    print("(a, b): fitted compliance exponents d/F ~ ka^a kb^b over the rows; published: "
          + ", ".join(f"{d} um {r['exponents_published']}" for d, r in results.items()))
    print(f"{'variant':<13} {'D um':>5} {'median':>7}  {'per row':<44} {'Nv':>6} {'k':>4} {'(a, b)':>16} "
          f"{'rel L2':>7} {'wall s':>7}  status")
    for v, d, med, per_row, st, wall, nv, k, expo, l2 in table:
        ms = "-" if med is None else f"{med:.3f}"
        ls = "-" if l2 is None else f"{l2:.3f}"
        print(f"{v:<13} {d:5g} {ms:>7}  {str(np.round(per_row, 3).tolist()):<44} {nv!s:>6} {k!s:>4} "
              f"{str(expo):>16} {ls:>7} {wall:7.1f}  {','.join(st)}")
    compact = {d: {v: {"median_ratio": None if e["median_ratio"] is None else round(e["median_ratio"], 4),
                       "median_rel_l2": None if e.get("median_rel_l2") is None else round(e["median_rel_l2"], 4),
                       "exponents": e.get("exponents"), "wall_s": round(e["wall_s"], 1)}
                   for v, e in r["variants"].items()}
               for d, r in results.items()}
    if args.out:
        (Path(args.out) / "mirheo_gap_58.json").write_text(json.dumps(results, indent=1))
    print(json.dumps({"benchmark": "mirheo_gap_58", "device": args.device, "subdivisions": args.subdivisions,
                      "dtype": args.dtype, "points": args.points, "rows58": row_spec[5.8], "rows32": row_spec[3.2],
                      "exponents_published": {d: r["exponents_published"] for d, r in results.items()},
                      "results": compact, "total_wall_s": round(total, 1)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
