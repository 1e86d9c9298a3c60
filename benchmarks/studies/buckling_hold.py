"""Does a thermal MD shell buckle if it is held past the quasi-static kink long enough?

The quasi-static compression curves of 3-8 um shells bend where the shell buckles; the explicit and implicit tiers
follow the unbuckled branch to the end of their protocol (benchmarks/RESULTS.md, "Training sets over the diameter";
docs/decisions.md, "Buckling in the compression designs over the diameter").  This study loads design points of one
diameter level to a plate travel ``--depth`` (a fraction of the diameter, past the kink) in ``--ramp-points`` steps
and then holds it: ``--hold-points`` more load points at the same travel (each 1e-4 DPD length deeper, since a grid
must increase), so the MD tier's per-point means form a time series of the force at fixed depth.  The quasi-static
tier gives the equilibrium force at that travel.  A force that relaxes to the quasi-static one means the MD tiers
only lag behind it (the quasi-static curve is the slow-loading limit); a force that stays means they do not buckle.

Usage::

    python benchmarks/studies/buckling_hold.py --diameter 7.0 --points 13,285 --depth 0.14 --tier implicit \
        --scale 0.25 --device cuda --out hold.json
    python benchmarks/studies/buckling_hold.py --diameter 1.8 --points 3 --depth 0.1 --tier implicit \
        --scale 0.002 --subdivisions 2 --ramp-points 3 --hold-points 3 --device cpu       # CPU smoke

Prints the force per hold point over the quasi-static force (one row per design point) and one JSON line
(``{"study": "buckling_hold", ...}``).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

CAMPAIGN = "definity_compression_1.5-8um"
#: travel added per hold point [DPD length] (a loading grid must increase)
HOLD_STEP = 1e-4


def hold_grid(diameter_um: float, depth_fraction: float, ramp_points: int, hold_points: int) -> np.ndarray:
    """Total plate travel per load point [DPD length]: a ramp from 0 to the depth, then the hold points."""
    from bubblecal.surrogates import radius_of_diameter

    depth = depth_fraction * 2.0 * float(radius_of_diameter(diameter_um))
    ramp = np.linspace(0.0, depth, ramp_points + 1)
    hold = depth + HOLD_STEP * np.arange(1, hold_points + 1)
    return np.concatenate([ramp, hold])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--diameter", type=float, default=7.0, help="diameter level of the design [um]")
    ap.add_argument("--points", default="13,285", help="design point indices (comma-separated)")
    ap.add_argument("--depth", type=float, default=0.14, help="held plate travel as a fraction of the diameter")
    ap.add_argument("--ramp-points", type=int, default=8, help="load points from 0 to the depth")
    ap.add_argument("--hold-points", type=int, default=12, help="load points at the depth")
    ap.add_argument("--tier", default="implicit", choices=("implicit", "explicit"), help="the MD tier")
    ap.add_argument("--scale", type=float, default=0.25, help="MD protocol scale (steps per point)")
    ap.add_argument("--subdivisions", type=int, default=None, help="mesh level (default: the campaign's)")
    ap.add_argument("--box-pad", type=float, default=None,
                    help="explicit tier: periodic box (2R+pad, 2R+pad, 2R+pad+5) [DPD length] (default: the tier's: 5)")
    ap.add_argument("--md-setting", action="append", default=[], metavar="KEY=VALUE",
                    help="an MD tier setting (e.g. fsi_friction_factor=0.1, a_vertex_water=40); repeatable")
    ap.add_argument("--qs-setting", action="append", default=[], metavar="KEY=VALUE",
                    help="a quasi-static tier setting over the campaign's (e.g. gas_p0=0); repeatable")
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--out", type=Path, default=None, help="JSON file of every curve")
    args = ap.parse_args()

    from bubblecal.campaigns import design_points, load_campaign_file, parse_tier_settings
    from bubblecal.data import SHELL_PARAMETERS
    from bubblecal.sim.tiers import CurveRequest, get_tier

    cfg = load_campaign_file(CAMPAIGN).config
    design = design_points(cfg)
    points = [int(v) for v in args.points.split(",") if v]
    grid = hold_grid(args.diameter, args.depth, args.ramp_points, args.hold_points)
    request = CurveRequest(protocol="compression", diameter_um=args.diameter, grid=tuple(grid),
                           params={k: np.asarray(design[k][points]) for k in SHELL_PARAMETERS},
                           seeds=tuple(int(s) for s in design["seed"][points]),
                           subdivisions=args.subdivisions or cfg.subdivisions)
    out = {}
    qs_overrides = parse_tier_settings(args.qs_setting)
    qs = get_tier("quasistatic", **{**cfg.physics_tier_settings(), **qs_overrides})
    md_settings = {"scale": args.scale, **parse_tier_settings(args.md_setting)}
    if args.box_pad is not None:
        from bubblecal.surrogates import radius_of_diameter

        side = 2.0 * float(radius_of_diameter(args.diameter)) + args.box_pad
        md_settings["box"] = (side, side, side + 5.0)
    for name, tier in (("quasistatic", qs), (args.tier, get_tier(args.tier, **md_settings))):
        t0 = time.perf_counter()
        batch = tier.run(request, args.device)
        out[name] = {"force": np.asarray(batch.observable, float), "status": list(batch.status),
                     "seconds": time.perf_counter() - t0}
        print(f"{name}: {out[name]['seconds']:.1f} s, {out[name]['status']}", flush=True)
    hold = slice(args.ramp_points + 1, None)
    q = out["quasistatic"]["force"][:, hold]
    md = out[args.tier]["force"][:, hold]
    ratio = md / q
    print(f"held travel {grid[args.ramp_points]:.3f} DPD length ({args.depth:g} D); {args.tier} / quasi-static per "
          "hold point:")
    for i, row in zip(points, ratio, strict=True):
        print(f"  point {i}: " + " ".join(f"{v:.3f}" for v in row), flush=True)
    line = {"study": "buckling_hold", "campaign": CAMPAIGN, "diameter_um": args.diameter, "points": points,
            "depth_fraction": args.depth, "tier": args.tier, "scale": args.scale, "box": md_settings.get("box"),
            "md_settings": {k: v for k, v in md_settings.items() if k not in ("scale", "box")},
            "qs_settings": qs_overrides,
            "ratio_first_hold": ratio[:, 0].tolist(), "ratio_last_hold": ratio[:, -1].tolist(),
            "seconds": {k: v["seconds"] for k, v in out.items()}}
    if args.out:
        args.out.write_text(json.dumps({**line, "grid": grid.tolist(),
                                        "curves": {k: {"force": v["force"].tolist(), "status": v["status"]}
                                                   for k, v in out.items()}}, indent=1))
    print(json.dumps(line))


if __name__ == "__main__":
    main()
