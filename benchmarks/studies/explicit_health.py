"""Why an explicit-tier curve of a design over the diameter ended 'failed': its health verdicts, point by point.

Runs the explicit tier (the campaign's indentation convention, MD protocol scale ``--scale``) on design points of a
campaign over the diameter, all of one diameter level, and prints per curve its status, the health check that
stopped it and the load point it came at (``NAN``: non-finite positions; ``LEAK``: solvent across the shell;
``RUPTURE``: an over-stretched edge), the MD steps and seconds, the observable and its standard error per point,
and one JSON line (``{"study": "explicit_health", ...}``).

Usage::

    python benchmarks/studies/explicit_health.py --campaign sonovue_indentation_1.5-8um_mirheo --points 15,51 \\
        --device cuda --scale 0.25 [--setting KEY=VALUE ...] [--verbose]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np


def main() -> None:
    from bubblecal.campaigns import design_points, load_campaign_file, parse_tier_settings
    from bubblecal.data import SHELL_PARAMETERS
    from bubblecal.sim.tiers import CurveRequest, get_tier

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--campaign", required=True, help="shipped campaign over the diameter")
    ap.add_argument("--points", required=True, help="design point indices of one diameter level (comma-separated)")
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--scale", type=float, default=0.25, help="MD protocol scale")
    ap.add_argument("--setting", action="append", default=[], metavar="KEY=VALUE", help="explicit-tier setting")
    ap.add_argument("--verbose", action="store_true", help="print the tier's progress per load point")
    args = ap.parse_args()
    config = load_campaign_file(args.campaign).config
    design = design_points(config)
    idx = np.asarray([int(v) for v in args.points.split(",")])
    diameters = np.unique(np.asarray(design["diameter_um"])[idx])
    if len(diameters) != 1:
        raise SystemExit(f"--points {args.points}: from {len(diameters)} diameter levels ({diameters}); give one")
    d = float(diameters[0])
    request = CurveRequest(protocol=config.protocol, diameter_um=d, grid=tuple(config.grid_for(d)),
                           params={k: np.asarray(design[k][idx]) for k in SHELL_PARAMETERS},
                           seeds=tuple(int(s) for s in design["seed"][idx]), subdivisions=config.subdivisions)
    settings = {k: v for k, v in config.tier_settings.items() if k == "indentation_convention"}
    settings |= parse_tier_settings(args.setting)
    t0 = time.perf_counter()
    batch = get_tier("explicit", scale=args.scale, verbose=args.verbose, **settings).run(request, args.device)
    seconds = time.perf_counter() - t0
    info = batch.info
    sem = info.get("axial_sem", info.get("force_sem"))
    rows = []
    for r, i in enumerate(idx.tolist()):
        row = {"point": i, "status": batch.status[r], "health": (info.get("health") or [None] * len(idx))[r],
               "params": {k: float(design[k][i]) for k in SHELL_PARAMETERS},
               "observable": np.asarray(batch.observable[r], dtype=float).tolist(),
               "sem": None if sem is None else np.asarray(sem[r], dtype=float).tolist()}
        rows.append(row)
        print(f"point {i}: {row['status']}  health {row['health']}  k_a {row['params']['ka']:.0f} "
              f"k_b {row['params']['kb']:.0f}", flush=True)
        print("   observable " + " ".join(f"{v:.4g}" for v in row["observable"]))
        if row["sem"] is not None:
            print("   s.e.       " + " ".join(f"{v:.2g}" for v in row["sem"]))
    print(f"diameter {d} um, {len(idx)} curves, {info.get('md_steps')} MD steps, {seconds:.1f} s")
    print(json.dumps({"study": "explicit_health", "campaign": args.campaign, "diameter_um": d, "scale": args.scale,
                      "settings": settings, "md_steps": info.get("md_steps"), "seconds": seconds, "rows": rows},
                     default=str))


if __name__ == "__main__":
    main()
