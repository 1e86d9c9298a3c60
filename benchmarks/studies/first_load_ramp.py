"""FIRE work of quasi-static indentation curves with the first-load ramp (``first_load_ramp``), against a store.

    python benchmarks/studies/first_load_ramp.py STORE [--n 30] [--seed 1] [--ramp 6] [--device cpu]

Re-runs ``--n`` random curves of an indentation campaign store or export (one batch, the store's diameter and
indentation convention, the tier's FIRE settings: float64, ftol 0.05, max_steps 100,000 per point) with the
first positive force reached through ``--ramp`` halvings, and compares with the stored records: total FIRE
iterations (the ratio is the saving; iteration counts do not depend on the device, and with ``--ramp 0`` this CPU
reproduced 28 of 30 stored totals exactly), statuses, and the relative L2 change of d(F) of the curves 'ok' in
both.  Prints one JSON line.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("store")
    ap.add_argument("--n", type=int, default=30)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--ramp", type=int, default=6)
    ap.add_argument("--device", default="cpu")
    args = ap.parse_args(argv)
    import warp as wp

    wp.config.quiet = True
    from bubblecal.data import CampaignStore
    from bubblecal.sim.engine import mesh_for_diameter, resolve_dtype
    from bubblecal.sim.tiers import CurveRequest, indentation_convention
    from bubblecal.sim.tiers.quasistatic import FireSettings, IdealGas, quasistatic_indentation

    recs = [r for r in CampaignStore(args.store).read(warn=False) if r["setup"] == "indentation"]
    pick = [recs[i] for i in np.random.default_rng(args.seed).choice(len(recs), args.n, replace=False)]
    info = pick[0]["provenance"].get("info", {})
    conv = indentation_convention(info.get("indentation_convention") or "bubblecal-v1")
    dia = pick[0]["radius_dpd"] * 0.5
    sub = int(info.get("mesh_subdivisions") or 4)
    params = {k: np.array([r["params"][k] for r in pick]) for k in pick[0]["params"]}
    req = CurveRequest("indentation", dia, tuple(pick[0]["x"]), params, tuple(int(r["seed"]) for r in pick),
                       subdivisions=sub)
    t0 = time.perf_counter()
    res = quasistatic_indentation(req.shell_params(conv.name), mesh_for_diameter(dia, sub), req.grid_array(),
                                  gas=IdealGas(p0=3.0), device=args.device, dtype=resolve_dtype("float64"),
                                  fire=FireSettings(ftol=0.05, max_steps=100_000), pole_patch=conv.pole_patch(),
                                  first_load_ramp=args.ramp)
    stored = np.array([r["provenance"]["info"]["fire_steps"] for r in pick], dtype=float)
    total = res.fire_steps.sum(axis=1)
    y = np.array([r["y"] for r in pick], dtype=float)
    both_ok = np.array([s == "ok" and r["status"] == "ok" for s, r in zip(res.status, pick, strict=True)])
    rel = np.linalg.norm(res.displacement - y, axis=1) / np.linalg.norm(y, axis=1)
    out = {"benchmark": "first_load_ramp", "store": args.store, "n": args.n, "seed": args.seed, "ramp": args.ramp,
           "device": args.device, "wall_s": round(time.perf_counter() - t0, 1),
           "fire_iterations": int(total.sum()), "stored_fire_iterations": int(stored.sum()),
           "ratio_of_sums": float(total.sum() / stored.sum()), "median_ratio": float(np.median(total / stored)),
           "same_status": int(sum(s == r["status"] for s, r in zip(res.status, pick, strict=True))),
           "rel_l2_vs_stored": {"n": int(both_ok.sum()), "median": float(np.median(rel[both_ok])),
                                "p90": float(np.percentile(rel[both_ok], 90)), "max": float(rel[both_ok].max())}
           if both_ok.any() else None}
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
