"""The fidelity gate where no published curve exists: explicit tier against quasi-static at new diameters.

For each diameter level, the first ``--n`` design points of a campaign over the diameter (its Latin hypercube,
loading grid, tier settings and mesh level) run with the campaign's quasi-static tier and with the explicit-solvent
tier (the same mesh level and indentation convention, MD protocol scale ``--scale``).  Reported per diameter: the
median [IQR] relative L2 of quasi-static against explicit over the curves 'ok' in both (the gate: median <= 3 %),
statuses and wall seconds.  ``--out`` receives ``diameter_gate.json`` (rewritten after every diameter) and
``curves_<campaign>_<d>um.csv``.  ``--reference implicit`` compares with the solvent-free thermal tier instead
(to separate the solvent's share of a gap), ``--ref-subdivisions`` gives the reference its own mesh level, and
``--qs-store`` takes the quasi-static curves from the campaign's finished store (the same design points) instead of
re-running them; ``--reference-curves`` takes the reference tier's curves from an earlier run's CSV, so that a
quasi-static variant (``--qs-setting KEY=VALUE``, e.g. ``overpressure=4.95``) is gated on a CPU against GPU curves;
``--ref-setting KEY=VALUE`` sets the reference tier (e.g. the explicit tier's ``p_back``).

Usage::

    python benchmarks/diameter_gate.py --campaign definity_compression_1.5-8um --diameters 1.8,4.5,7.0 --n 8 \
        --device cuda --scale 0.25 --out OUT
    python benchmarks/diameter_gate.py --campaign sonovue_indentation_1.5-8um_mirheo --diameters 1.8 --n 2 \
        --device cpu --scale 0.002 --subdivisions 2 --out /tmp/gate      # CPU smoke
    python benchmarks/diameter_gate.py --campaign definity_compression_1.5-8um --diameters 7.0 --n 8 --device cpu \
        --qs-setting overpressure=4.95 \
        --reference-curves benchmarks/figures/gate_diameter/curves_definity_compression_1.5-8um_7um_explicit.csv

Prints one table and one JSON line (``{"benchmark": "diameter_gate", ...}``).
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from bubblecal.campaigns import design_points, load_campaign_file, parse_tier_settings
from bubblecal.data import SHELL_PARAMETERS
from bubblecal.sim.tiers import CurveRequest, get_tier

#: explicit-tier settings that the campaign's quasi-static settings carry over
SHARED = ("indentation_convention",)


@lru_cache(maxsize=2)
def _store_records(path: str) -> dict:
    """sample id -> (x, y, status) of every record of a store, read once per process (a level's batches share it)."""
    from bubblecal.data.store import CampaignStore

    return {rec["sample_id"]: (rec["x"], rec["y"], rec["status"]) for rec in CampaignStore(path).iter_records()}


def stored_curves(path: str, config, idx: np.ndarray, grid: tuple) -> dict:
    """The quasi-static curves of design points ``idx`` from a finished campaign store (same design, same grid)."""
    records = _store_records(path)
    y = np.full((len(idx), len(grid)), np.nan)
    status = ["missing"] * len(idx)
    for k, i in enumerate(idx):
        rec = records.get(f"{config.name}-{i:06d}")
        if rec is None:
            continue
        if not np.allclose(rec[0], grid):
            raise SystemExit(f"{path}: {config.name}-{i:06d} has another loading grid than the design")
        y[k], status[k] = np.asarray(rec[1], dtype=float), rec[2]
    return {"y": y, "status": status, "seconds": 0.0}


def stored_reference(path: str, idx, n_points: int) -> dict:
    """The reference-tier rows (tier other than ``quasistatic``) of design points ``idx`` from a gate CSV."""
    rows = {}
    with open(path) as fh:
        header = fh.readline().rstrip("\n").split(",")
        if len(header) != 3 + n_points:
            raise SystemExit(f"{path}: {len(header) - 3} load points, the level has {n_points}")
        for line in fh:
            cells = line.rstrip("\n").split(",")
            if cells[1] != "quasistatic":
                rows[int(cells[0])] = (np.asarray(cells[3:], dtype=float), cells[2])
    missing = [int(i) for i in idx if int(i) not in rows]
    if missing:
        raise SystemExit(f"{path}: no reference curve of design points {missing}")
    return {"y": np.stack([rows[int(i)][0] for i in idx]), "status": [rows[int(i)][1] for i in idx], "seconds": 0.0}


def run_level(config, diameter_um: float, n: int, device: str, scale: float, subdivisions: int | None,
              start: int = 0, reference: str = "explicit", ref_subdivisions: int | None = None,
              qs_store: str | None = None, qs_overrides: dict | None = None,
              reference_curves: str | None = None, ref_overrides: dict | None = None,
              qs_shift: dict | None = None) -> dict:
    """Quasi-static and reference-tier curves of design points ``start`` .. ``start + n - 1`` of one level.

    The reference-tier result is stored under the key ``"explicit"`` whichever tier it is (the CSV names it);
    ``qs_shift`` adds a constant to shell parameters of the quasi-static run only (e.g. ``{"kb": 300.0}``).
    """
    design = design_points(config)
    idx = np.nonzero(np.isclose(design["diameter_um"], diameter_um))[0][start:start + n]
    if len(idx) == 0:
        raise SystemExit(f"{config.name}: no design point at {diameter_um} um")
    sub = subdivisions if subdivisions is not None else config.subdivisions
    ref_sub = ref_subdivisions if ref_subdivisions is not None else sub
    grid = config.grid_for(float(diameter_um))
    request = CurveRequest(protocol=config.protocol, diameter_um=float(diameter_um), grid=grid,
                           params={k: np.asarray(design[k][idx]) for k in SHELL_PARAMETERS},
                           seeds=tuple(int(s) for s in design["seed"][idx]), subdivisions=sub)
    qs_request = replace(request, params={k: v + (qs_shift or {}).get(k, 0.0) for k, v in request.params.items()})
    qs_settings = config.physics_tier_settings() | (qs_overrides or {})
    md_settings = {k: v for k, v in config.tier_settings.items() if k in SHARED} | (ref_overrides or {})
    out = {"indices": idx.tolist(), "grid": list(request.grid)}
    if qs_store:
        out["quasistatic"] = stored_curves(qs_store, config, idx, tuple(grid))
    else:
        t0 = time.perf_counter()
        batch = get_tier("quasistatic", **qs_settings).run(qs_request, device)
        out["quasistatic"] = {"y": np.asarray(batch.observable, dtype=float), "status": list(batch.status),
                              "seconds": time.perf_counter() - t0}
    if reference_curves:
        out["explicit"] = stored_reference(reference_curves, idx, len(grid))
    else:
        t0 = time.perf_counter()
        ref_request = replace(request, subdivisions=ref_sub)
        batch = get_tier(reference, scale=scale, **md_settings).run(ref_request, device)
        out["explicit"] = {"y": np.asarray(batch.observable, dtype=float), "status": list(batch.status),
                           "seconds": time.perf_counter() - t0}
    ok = [i for i in range(len(idx)) if out["quasistatic"]["status"][i] == out["explicit"]["status"][i] == "ok"]
    yq, ye = out["quasistatic"]["y"], out["explicit"]["y"]
    out["rel_l2"] = [float(np.linalg.norm(yq[i] - ye[i]) / np.linalg.norm(ye[i])) for i in ok]
    return out


def merge(parts: list[dict]) -> dict:
    """One level's result from its batches: indices, curves and statuses concatenated, and its summary."""
    res = {"indices": sum((r["indices"] for r in parts), []), "grid": parts[0]["grid"],
           "rel_l2": sum((r["rel_l2"] for r in parts), [])}
    for name in ("quasistatic", "explicit"):
        res[name] = {"y": np.concatenate([r[name]["y"] for r in parts]),
                     "status": sum((r[name]["status"] for r in parts), []),
                     "seconds": sum(r[name]["seconds"] for r in parts)}
    rel = np.asarray(res["rel_l2"])
    res["summary"] = {"n_ok": len(rel), "n": len(res["indices"]),
                      "median": float(np.median(rel)) if len(rel) else None,
                      "iqr": [float(v) for v in np.quantile(rel, [0.25, 0.75])] if len(rel) else None}
    return res


def write_curves(path: Path, res: dict, protocol: str, reference: str = "explicit") -> None:
    """One CSV row per curve and tier: design index, tier, status, then the curve."""
    unit = "force" if protocol == "compression" else "depth"
    with open(path, "w") as fh:
        fh.write("index,tier,status," + ",".join(f"{unit}_at_{g:g}" for g in res["grid"]) + "\n")
        for tier in ("quasistatic", "explicit"):
            for i, row in zip(res["indices"], res[tier]["y"], strict=True):
                status = res[tier]["status"][res["indices"].index(i)]
                label = reference if tier == "explicit" else tier
                fh.write(f"{i},{label},{status}," + ",".join(f"{v:.9g}" for v in row) + "\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--campaign", required=True, help="a campaign over the diameter (name or file)")
    ap.add_argument("--diameters", default="1.8,4.5,7.0", help="comma-separated levels [um]")
    ap.add_argument("--n", type=int, default=8, help="design points per diameter")
    ap.add_argument("--start", type=int, default=0, help="first design point of each level (to split a level)")
    ap.add_argument("--batch", type=int, default=0,
                    help="run a level's points in batches of this many, writing the outputs after each (0: one batch)")
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--scale", type=float, default=0.25, help="explicit MD protocol scale")
    ap.add_argument("--subdivisions", type=int, default=None, help="mesh level (default: the campaign's)")
    ap.add_argument("--reference", default="explicit", choices=("explicit", "implicit"), help="reference tier")
    ap.add_argument("--ref-subdivisions", type=int, default=None, help="the reference's mesh level (default: QS's)")
    ap.add_argument("--qs-store", default=None, help="take the quasi-static curves from this finished store")
    ap.add_argument("--qs-setting", action="append", default=[], metavar="KEY=VALUE",
                    help="override a quasi-static tier setting of the campaign (repeatable)")
    ap.add_argument("--qs-shift", action="append", default=[], metavar="KEY=VALUE",
                    help="add VALUE to the shell parameter KEY of the quasi-static run only, e.g. kb=300 (repeatable)")
    ap.add_argument("--ref-setting", action="append", default=[], metavar="KEY=VALUE",
                    help="a setting of the reference tier, e.g. p_back=86.05 (repeatable)")
    ap.add_argument("--reference-curves", default=None, metavar="CSV",
                    help="take the reference tier's curves from an earlier run's curves CSV (one diameter)")
    ap.add_argument("--out", default="diameter_gate_out")
    args = ap.parse_args()
    try:  # the campaigns' own KEY=VALUE parser (values read as TOML)
        qs_overrides, ref_overrides = parse_tier_settings(args.qs_setting), parse_tier_settings(args.ref_setting)
        qs_shift = {k: float(v) for k, v in parse_tier_settings(args.qs_shift).items()}
    except ValueError as exc:
        raise SystemExit(str(exc)) from exc
    config = load_campaign_file(args.campaign).config
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    print(f"{'campaign':36s} {'D [um]':>6s} {'ok/n':>6s} {'median':>8s} {'IQR':>16s} {'QS s':>7s} {'MD s':>7s}")
    batch = args.batch if args.batch > 0 else args.n
    tag = f"_from{args.start}" if args.start else ""
    for d in (float(v) for v in args.diameters.split(",") if v):
        parts = []
        for first in range(args.start, args.start + args.n, batch):
            parts.append(run_level(config, d, min(batch, args.start + args.n - first), args.device, args.scale,
                                   args.subdivisions, start=first, reference=args.reference,
                                   ref_subdivisions=args.ref_subdivisions, qs_store=args.qs_store,
                                   qs_overrides=qs_overrides, reference_curves=args.reference_curves,
                                   ref_overrides=ref_overrides, qs_shift=qs_shift))
            res = merge(parts)
            write_curves(out / f"curves_{config.name}_{d:g}um{tag}.csv", res, config.protocol, args.reference)
            print(f"  {d:g} um: {len(res['indices'])} of {args.n} points done", flush=True)
        s = res["summary"]
        row = {"diameter_um": d, **s, "seconds_quasistatic": res["quasistatic"]["seconds"],
               "seconds_explicit": res["explicit"]["seconds"], "status_explicit": res["explicit"]["status"],
               "rel_l2": res["rel_l2"]}
        rows.append(row)
        med = "-" if s["median"] is None else f"{100 * s['median']:.2f}%"
        iqr = "-" if s["iqr"] is None else f"[{100 * s['iqr'][0]:.2f}, {100 * s['iqr'][1]:.2f}]%"
        print(f"{config.name:36s} {d:6.2f} {s['n_ok']:>2d}/{s['n']:<3d} {med:>8s} {iqr:>16s} "
              f"{row['seconds_quasistatic']:7.1f} {row['seconds_explicit']:7.1f}", flush=True)
        line = {"benchmark": "diameter_gate", "campaign": config.name, "device": args.device, "scale": args.scale,
                "n": args.n, "start": args.start, "reference": args.reference,
                "ref_subdivisions": args.ref_subdivisions, "qs_store": args.qs_store, "qs_settings": qs_overrides,
                "ref_settings": ref_overrides, "qs_shift": qs_shift, "reference_curves": args.reference_curves,
                "rows": rows}
        (out / f"diameter_gate{tag}.json").write_text(json.dumps(line, indent=1))
    print(json.dumps(line))


if __name__ == "__main__":
    main()
