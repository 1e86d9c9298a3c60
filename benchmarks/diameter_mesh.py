"""Mesh level across the diameter: quasi-static curves of the same shells at subdivision 4 and 5.

For each campaign and diameter, the first ``--n`` design points of that diameter level (the campaign's own
Latin hypercube, tier settings and loading grid) run with the quasi-static tier at subdivision 4 and at 5;
the table gives the relative L2 between the two levels' curves (||y4 - y5|| / ||y5|| over a curve's points,
curves 'ok' at both levels), median [max].  At ``mesh_for_diameter``'s switch (5 um) this is the jump a
curve would take where the mesh level changes; the rule and the figures: docs/physics.md section 3.

Usage::

    python benchmarks/diameter_mesh.py [--campaigns A,B] [--diameters 5.0,8.0] [--n 16] [--device cuda]
                                       [--json FILE]

Prints one table and one JSON line (``{"benchmark": "diameter_mesh", ...}``).
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from bubblecal.campaigns import design_points, load_campaign_file
from bubblecal.data import SHELL_PARAMETERS
from bubblecal.sim.tiers import CurveRequest, get_tier

CAMPAIGNS = "definity_compression_1.5-8um,sonovue_indentation_1.5-8um_mirheo"


def level_curves(name: str, diameter_um: float, n: int, subdivisions: int, device: str) -> dict:
    """Curves of the first ``n`` design points of one diameter level at one mesh level."""
    config = load_campaign_file(name).config
    design = design_points(config)
    idx = np.nonzero(np.isclose(design["diameter_um"], diameter_um))[0][:n]
    if len(idx) == 0:
        raise SystemExit(f"{name}: no design point at {diameter_um} um (levels {config.diameters[0]} .. "
                         f"{config.diameters[-1]})")
    settings = config.physics_tier_settings()
    tier = get_tier(config.tier, **{**settings, "subdivisions": subdivisions})
    request = CurveRequest(protocol=config.protocol, diameter_um=float(diameter_um),
                           grid=config.grid_for(float(diameter_um)),
                           params={k: np.asarray(design[k][idx]) for k in SHELL_PARAMETERS},
                           seeds=tuple(int(s) for s in design["seed"][idx]), subdivisions=subdivisions)
    t0 = time.perf_counter()
    batch = tier.run(request, device)
    return {"y": np.asarray(batch.observable, dtype=np.float64), "status": list(batch.status),
            "seconds": time.perf_counter() - t0}


def compare_levels(coarse: dict, fine: dict) -> dict:
    """Relative L2 of the coarse against the fine curves (both 'ok')."""
    ok = [i for i, (a, b) in enumerate(zip(coarse["status"], fine["status"], strict=True)) if a == b == "ok"]
    rel = [float(np.linalg.norm(coarse["y"][i] - fine["y"][i]) / np.linalg.norm(fine["y"][i])) for i in ok]
    return {"n_ok": len(ok), "n": len(coarse["status"]),
            "median_rel_l2": float(np.median(rel)) if rel else None,
            "max_rel_l2": float(np.max(rel)) if rel else None,
            "seconds_sub4": coarse["seconds"], "seconds_sub5": fine["seconds"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--campaigns", default=CAMPAIGNS, help="comma-separated campaign names or files")
    ap.add_argument("--diameters", default="5.0,8.0", help="comma-separated diameter levels [um]")
    ap.add_argument("--n", type=int, default=16, help="design points per diameter")
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--json", default=None, help="also write the rows to this file")
    args = ap.parse_args()
    rows = []
    print(f"{'campaign':40s} {'D [um]':>7s} {'ok/n':>7s} {'median':>8s} {'max':>8s} {'s (4)':>7s} {'s (5)':>7s}")
    for name in [c for c in args.campaigns.split(",") if c]:
        for d in (float(v) for v in args.diameters.split(",") if v):
            row = {"campaign": name, "diameter_um": d,
                   **compare_levels(level_curves(name, d, args.n, 4, args.device),
                                    level_curves(name, d, args.n, 5, args.device))}
            rows.append(row)
            med = "-" if row["median_rel_l2"] is None else f"{100 * row['median_rel_l2']:.2f}%"
            mx = "-" if row["max_rel_l2"] is None else f"{100 * row['max_rel_l2']:.2f}%"
            print(f"{name:40s} {d:7.2f} {row['n_ok']:>3d}/{row['n']:<3d} {med:>8s} {mx:>8s} "
                  f"{row['seconds_sub4']:7.1f} {row['seconds_sub5']:7.1f}", flush=True)
    line = {"benchmark": "diameter_mesh", "device": args.device, "n": args.n, "rows": rows}
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(line, fh, indent=1)
    print(json.dumps(line))


if __name__ == "__main__":
    main()
