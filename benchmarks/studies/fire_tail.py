"""Do other FIRE controls shorten the slowest quasi-static indentation curves, and at what change of the curve?

The wall time of a campaign task is set by its slowest curve (benchmarks/RESULTS.md, Quasi-static throughput): an
iteration of the slowest replica costs a fixed ~0.3 ms on an H100 however few replicas relax.  This script takes
the ``--n`` slowest curves of a campaign store (FIRE iterations in ``provenance.info.fire_steps``), re-runs them
one replica each with the quasi-static tier's settings (float64, ftol 0.05, max_steps 100,000 per point, the
store's indentation convention) under FIRE variants, and reports per variant and curve the FIRE iterations and
the relative L2 change of d(F) against the baseline variant (same controls as the store).

    python benchmarks/studies/fire_tail.py STORE [--n 3] [--quantiles 0.5,0.9] [--variants baseline,dtmax_0.1,move_0.02]
        [--device cpu] [--diameter 3.2] [--out DIR]

Variants: ``baseline`` (FireSettings defaults of the tier: dt 0.005, dt_max 0.05, max_move 0.01, ftol 0.05 and the
FIRE 2.0 constants n_delay 5, f_inc 1.1, f_dec 0.5, alpha0 0.1, f_alpha 0.99); ``dtmax_<x>``, ``move_<x>``,
``dt_<x>``, ``ftol_<x>``, ``ndelay_<n>``, ``finc_<x>``, ``fdec_<x>``, ``alpha_<x>``, ``falpha_<x>`` set one
control; combinations joined by '+'.  ``--quantiles``: also the curves at these quantiles of the store's FIRE work
(the bulk of a pool, not only its tail).
Prints a table and one JSON line last.  Iteration counts do not depend on the device.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

VARIANT_FIELDS = {"dtmax": "dt_max", "move": "max_move", "dt": "dt", "ftol": "ftol", "ndelay": "n_delay",
                  "finc": "f_inc", "fdec": "f_dec", "alpha": "alpha0", "falpha": "f_alpha"}


def parse_variant(name: str) -> dict:
    """'dtmax_0.1+move_0.02' -> {'dt_max': 0.1, 'max_move': 0.02} (FireSettings overrides)."""
    out: dict = {}
    for part in name.split("+"):
        if part == "baseline":
            continue
        key, _, value = part.partition("_")
        field = VARIANT_FIELDS.get(key)
        if field is None or not value:
            raise SystemExit(f"unknown variant part {part!r} (baseline, or <key>_<value> with key in "
                             f"{', '.join(VARIANT_FIELDS)})")
        out[field] = int(value) if field == "n_delay" else float(value)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("store")
    ap.add_argument("--n", type=int, default=3, help="the n slowest curves of the store")
    ap.add_argument("--quantiles", default="", help="comma list: also the curves at these quantiles of FIRE work")
    ap.add_argument("--variants", default="baseline,dtmax_0.1,dtmax_0.2,move_0.02")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--diameter", type=float, default=None, help="um (default: the records' radius)")
    ap.add_argument("--subdivisions", type=int, default=4)
    ap.add_argument("--out", default=None)
    args = ap.parse_args(argv)

    import warp as wp

    wp.config.quiet = True
    from bubblecal.data import CampaignStore
    from bubblecal.sim.engine import mesh_for_diameter, resolve_dtype
    from bubblecal.sim.tiers import CurveRequest, indentation_convention
    from bubblecal.sim.tiers.quasistatic import FireSettings, IdealGas, quasistatic_indentation

    recs = [r for r in CampaignStore(args.store).read(warn=False) if r["setup"] == "indentation"]
    steps = np.array([r["provenance"].get("info", {}).get("fire_steps", 0) for r in recs])
    order = np.argsort(-steps)
    picks = list(order[: args.n])
    for q in (float(v) for v in args.quantiles.split(",") if v):
        i = int(order[min(len(order) - 1, int(round((1.0 - q) * (len(order) - 1))))])
        if i not in picks:
            picks.append(i)
    slow = [recs[i] for i in picks]
    rows = []
    base_y: dict[str, np.ndarray] = {}
    t_all = time.perf_counter()
    for rec in slow:
        info = rec["provenance"].get("info", {})
        conv = indentation_convention(info.get("indentation_convention") or "bubblecal-v1")
        dia = args.diameter if args.diameter else rec["radius_dpd"] * 0.5
        mesh = mesh_for_diameter(dia, args.subdivisions)
        params = {k: np.array([v]) for k, v in rec["params"].items()}
        req = CurveRequest("indentation", dia, tuple(rec["x"]), params, (int(rec["seed"]),),
                           subdivisions=args.subdivisions)
        sp = req.shell_params(conv.name)
        for variant in args.variants.split(","):
            fire = FireSettings(**{"ftol": 0.05, "max_steps": 100_000, **parse_variant(variant)})
            t0 = time.perf_counter()
            res = quasistatic_indentation(sp, mesh, req.grid_array(), gas=IdealGas(p0=3.0), device=args.device,
                                          dtype=resolve_dtype("float64"), fire=fire, pole_patch=conv.pole_patch())
            y = res.displacement[0]
            if variant == args.variants.split(",")[0]:
                base_y[rec["sample_id"]] = y
            ref = base_y[rec["sample_id"]]
            rel = float(np.linalg.norm(y - ref) / np.linalg.norm(ref)) if np.all(np.isfinite(y)) else float("nan")
            row = {"sample_id": rec["sample_id"], "ka": rec["params"]["ka"], "kb": rec["params"]["kb"],
                   "variant": variant, "status": res.status[0], "fire_steps": int(res.fire_steps.sum()),
                   "store_fire_steps": int(info.get("fire_steps", 0)), "max_point_steps": int(res.fire_steps.max()),
                   "rel_l2_vs_first": rel, "wall_s": round(time.perf_counter() - t0, 1)}
            rows.append(row)
            print(f"{row['sample_id']}  ka {row['ka']:9.0f} kb {row['kb']:7.0f}  {variant:22s} {row['status']:13s} "
                  f"FIRE {row['fire_steps']:8d} (store {row['store_fire_steps']:8d}, "
                  f"max/point {row['max_point_steps']:6d})"
                  f"  dL2 {rel:.4f}  {row['wall_s']} s", flush=True)
    out = {"benchmark": "fire_tail", "store": args.store, "device": args.device, "rows": rows,
           "total_wall_s": round(time.perf_counter() - t_all, 1)}
    if args.out:
        from pathlib import Path

        Path(args.out).mkdir(parents=True, exist_ok=True)
        (Path(args.out) / "fire_tail.json").write_text(json.dumps(out, indent=1))
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
