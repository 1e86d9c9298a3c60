"""Quasi-static campaign throughput on a stratified sample of a shipped design over the diameter, checked against
the shipped records.

The first ``--per-level`` design points of every diameter level (a level's points are in Latin-hypercube order, so
they are a random subset of it) run as one campaign task, in the campaign's refill pools (one pool per plate
sub-step count), on one device: the records the campaign would write for them.  Reported per setting: ok curves,
wall time from the task's start to its last curve, ok curves per device-hour, the seconds by which 10 / 50 / 90 / 99
/ 100 % of the curves had finished, the pool's rate while full (curves between the 10 % and 90 % marks over that
time: what a pool much larger than its slots runs at, without its tail), the FIRE work per curve, and the
curves' relative L2 against the shipped store's records of the same design points (median, p99, max over the curves
ok in both; statuses that differ are counted).  ``--reference`` first runs the sample under tight overrides (e.g.
the CG at a 25x smaller force tolerance) and compares every setting, and the shipped store, with those curves: how
far each minimiser's stopping point lies from the minimum, and which samples lie farthest.  ``--setting`` runs the
sample once per value, each a comma list of tier overrides (``dtype=float32,max_replicas=2000``); ``-`` is the
campaign as shipped.

    python benchmarks/campaign_sample_throughput.py --campaign definity_compression_1.5-8um --per-level 40 \
        --setting - --setting dtype=float32 --device cuda [--diameters 1.5,2.0] [--out OUT.json]

Prints one table row per setting and one JSON line last (``{"benchmark": "campaign_sample_throughput", ...}``).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def parse_setting(text: str) -> dict:
    """'dtype=float32,max_replicas=2000' -> tier overrides, each value read as the campaign's ``--tier-setting``
    reads it (:func:`bubblecal.campaigns.parse_tier_settings`); '-' or '' -> none."""
    from bubblecal.campaigns import parse_tier_settings

    if text in ("", "-"):
        return {}
    try:
        return parse_tier_settings(text.split(","))
    except ValueError as exc:
        raise SystemExit(f"--setting: {exc}") from None


def stored_curves(campaign: str) -> dict:
    """sample id -> (y, status) of the latest record of every sample in the shipped store."""
    from bubblecal.data.store import CampaignStore

    path = REPO / "data" / "training" / f"{campaign}.jsonl.gz"
    return {rec["sample_id"]: (np.asarray(rec["y"], dtype=float), rec["status"])
            for rec in CampaignStore(path).read(warn=False)}


def sample_indices(design: dict, per_level: int, levels: list[float] | None = None) -> list[int]:
    """The first ``per_level`` design indices of every diameter level (or of ``levels`` [um]), in increasing order."""
    d = np.asarray(design["diameter_um"], dtype=float)
    chosen = np.unique(d) if not levels else [lvl for lvl in np.unique(d) if np.any(np.isclose(lvl, levels))]
    return [int(i) for lvl in chosen for i in np.nonzero(d == lvl)[0][:per_level]]


def compare(curves: dict, reference: dict) -> list:
    """Each sample of ``curves`` that ``reference`` also holds (both sample id -> (y, status)): [sample id, relative
    L2 (NaN unless ok in both), status, reference status]."""
    rows = []
    for sid, (y, status) in curves.items():
        if sid not in reference:
            continue
        ref_y, ref_status = reference[sid]
        ok = status == "ok" and ref_status == "ok"
        rows.append([sid, float(np.linalg.norm(y - ref_y) / np.linalg.norm(ref_y)) if ok else float("nan"), status,
                     ref_status])
    return rows


def rel_stats(rows: list) -> dict | None:
    """Median, p99 and max relative L2 over the :func:`compare` rows ok in both, or None when none is."""
    rel = [r[1] for r in rows if not np.isnan(r[1])]
    if not rel:
        return None
    return {"median": float(np.median(rel)), "p99": float(np.quantile(rel, 0.99)), "max": float(np.max(rel))}


def rel_l2(curves: dict, reference: dict) -> dict | None:
    """:func:`rel_stats` of ``curves`` against ``reference``."""
    return rel_stats(compare(curves, reference))


def worst(rows: list, n: int = 3) -> list:
    """The ``n`` :func:`compare` rows farthest from the reference, then those whose ok-ness differs."""
    differ = [r for r in rows if (r[2] == "ok") != (r[3] == "ok")]
    ranked = sorted((r for r in rows if not np.isnan(r[1])), key=lambda r: -r[1])[:n]
    return ranked + differ


def run_setting(campaign: str, overrides: dict, per_level: int, device: str, stored: dict,
                levels: list[float] | None = None) -> dict:
    """One run of the sample under ``overrides``: counts, timings and the comparison with ``stored``; the curves
    (sample id -> (y, status)) under the key ``curves_by_sample``."""
    import dataclasses

    from bubblecal.campaigns import design_points, load_campaign_file
    from bubblecal.campaigns.tasks import make_tasks, simulate_task

    cf = load_campaign_file(campaign, tier_overrides=overrides)
    config = dataclasses.replace(cf.config, device=device, replicas_per_task=10**9)
    design = design_points(config)
    idx = sample_indices(design, per_level, levels)
    (task,) = make_tasks(config, idx, design)
    finished = []
    t0 = time.perf_counter()
    result = simulate_task(task, on_curve=lambda *a: finished.append(time.perf_counter() - t0))
    wall = time.perf_counter() - t0
    ok = [s == "ok" for s in result.status]
    curves = {sid: (np.asarray(y, dtype=float), status)
              for sid, y, status in zip(task.sample_ids, result.y, result.status, strict=True)}
    rows = compare(curves, stored)
    steps = np.asarray(result.info.get("fire_steps", [np.nan]), dtype=float)
    t_done = np.sort(np.asarray(finished)) if finished else np.full(1, np.nan)
    q = {f"{int(100 * f)}%": round(float(np.quantile(t_done, f)), 1) for f in (0.1, 0.5, 0.9, 0.99, 1.0)}
    # the pool's rate while it is full: curves finished between the 10 % and 90 % marks over that time
    span = q["90%"] - q["10%"]
    steady = 0.8 * len(t_done) / span * 3600.0 if len(t_done) >= 10 and span > 0 else None  # too few to tell
    return {"overrides": overrides, "curves": len(idx), "ok": int(sum(ok)), "wall_s": round(wall, 1),
            "last_curve_s": round(max(finished), 1) if finished else None, "finished_at_s": q,
            "steady_curves_per_hour": None if steady is None else round(steady),
            "ok_per_hour": round(sum(ok) / wall * 3600.0),
            "fire_steps_mean": float(np.nanmean(steps)),
            "status_differs": sum((r[2] == "ok") != (r[3] == "ok") for r in rows),
            "rel_l2_vs_store": rel_stats(rows), "worst_vs_store": worst(rows),
            "curves_by_sample": curves}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--campaign", default="definity_compression_1.5-8um")
    ap.add_argument("--per-level", type=int, default=40, help="design points per diameter level")
    ap.add_argument("--setting", action="append", default=None,
                    help="comma list of tier overrides, or '-' for the campaign as shipped (repeatable)")
    ap.add_argument("--diameters", default="", help="only these levels [um], comma list (default: every level)")
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--reference", default=None,
                    help="tier overrides of a tight reference run (e.g. minimizer=cg,ftol=0.002): every setting and "
                         "the shipped store are also compared with its curves")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    import warp as wp

    wp.config.quiet = True
    wp.init()
    device_name = wp.get_device(args.device).name
    stored = stored_curves(args.campaign)
    levels = [float(v) for v in args.diameters.split(",") if v]
    reference = None
    if args.reference:
        ref_row = run_setting(args.campaign, parse_setting(args.reference), args.per_level, args.device, stored,
                              levels)
        reference = ref_row.pop("curves_by_sample")
        print(f"reference {args.reference}: {ref_row['ok']}/{ref_row['curves']} ok in {ref_row['wall_s']} s",
              flush=True)
    sample = {sid: stored[sid] for sid in reference} if reference else {}
    store_vs_reference = rel_l2(sample, reference) if reference else None
    if reference:
        print(f"shipped store vs reference: {store_vs_reference}", flush=True)
    rows = []
    print(f"{'setting':<34s} {'ok/curves':>11s} {'wall s':>7s} {'ok/h':>8s} {'FIRE/curve':>10s} "
          f"{'dL2 med / p99 / max vs store':>30s} {'status differs':>14s}", flush=True)
    for text in args.setting or ["-"]:
        row = run_setting(args.campaign, parse_setting(text), args.per_level, args.device, stored, levels)
        curves = row.pop("curves_by_sample")
        row["setting"] = text
        if reference:
            vs_ref = compare(curves, reference)
            row["rel_l2_vs_reference"], row["worst_vs_reference"] = rel_stats(vs_ref), worst(vs_ref)
            print(f"    vs reference: {row['rel_l2_vs_reference']}; worst: {row['worst_vs_reference'][:3]}", flush=True)
        rows.append(row)
        r = row["rel_l2_vs_store"] or {"median": np.nan, "p99": np.nan, "max": np.nan}
        print(f"{text:<34s} {row['ok']:>5d}/{row['curves']:<5d} {row['wall_s']:7.1f} {row['ok_per_hour']:8d} "
              f"{row['fire_steps_mean']:10.0f} {100 * r['median']:9.4f} / {100 * r['p99']:.4f} / "
              f"{100 * r['max']:.4f} % {row['status_differs']:14d}", flush=True)
        print(f"    finished by (s): {row['finished_at_s']}; while full: {row['steady_curves_per_hour']} curves/h",
              flush=True)
        out = {"benchmark": "campaign_sample_throughput", "device": device_name, "campaign": args.campaign,
               "per_level": args.per_level, "reference": args.reference, "store_vs_reference": store_vs_reference,
               "rows": rows}
        if args.out:
            args.out.write_text(json.dumps(out, indent=1))
    print(json.dumps(out))


if __name__ == "__main__":
    main()
