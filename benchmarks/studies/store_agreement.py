"""How far apart are two stores of one design (e.g. the same design run with FIRE and with the CG)?

For the design points both stores hold, this script cross-tabulates their statuses and, over the curves 'ok' in
both, reports the largest relative deviation of each curve (max over its points of abs(a - b) over the curve's
largest abs(b)) as quantiles, the curves farthest apart, and in each store how many 'ok' curves fall back below
their running maximum by more than 5 % and 10 % of their largest response (the training filter drops the 10 %
ones).

    python benchmarks/studies/store_agreement.py STORE_A STORE_B [--worst 5]

STORE_B is the reference of the deviations.  Prints a table and one JSON line last.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter

import numpy as np


def _curves(path: str) -> dict[str, dict]:
    """sample_id -> {'status', 'y' [P]} of the final record of each design point."""
    from bubblecal.data.store import CampaignStore

    out = {}
    for r in CampaignStore(path).read(warn=False):
        out[r["sample_id"]] = {"status": r["status"], "y": np.asarray(r["y"], dtype=float)}
    return out


def falls(y: np.ndarray) -> float:
    """Largest fall below the running maximum, over the curve's largest abs response (0 for a rising curve)."""
    y = y[np.isfinite(y)]
    if y.size < 2:
        return 0.0
    scale = float(np.max(np.abs(y)))
    return float(np.max(np.maximum.accumulate(y) - y) / scale) if scale > 0 else 0.0


def compare(a: dict[str, dict], b: dict[str, dict], worst: int = 5) -> dict:
    """The agreement summary of two stores' curves (module docstring)."""
    common = sorted(set(a) & set(b))
    table = Counter((a[i]["status"], b[i]["status"]) for i in common)
    dev = {}
    for i in common:
        if a[i]["status"] == b[i]["status"] == "ok":
            ya, yb = a[i]["y"], b[i]["y"]
            scale = float(np.nanmax(np.abs(yb)))
            if scale > 0 and ya.shape == yb.shape:
                dev[i] = float(np.nanmax(np.abs(ya - yb)) / scale)
    d = np.array(list(dev.values()))
    q = {f"q{int(p * 1000) / 10:g}": float(np.quantile(d, p)) for p in (0.5, 0.9, 0.99, 0.999)} if d.size else {}
    far = sorted(dev.items(), key=lambda kv: -kv[1])[:worst]
    fall = {}
    for name, s in (("a", a), ("b", b)):
        f = np.array([falls(v["y"]) for v in s.values() if v["status"] == "ok"])
        fall[name] = {"ok": int(f.size), "fall_gt_5pct": int(np.sum(f > 0.05)), "fall_gt_10pct": int(np.sum(f > 0.10))}
    return {"n_common": len(common), "only_a": len(set(a) - set(b)), "only_b": len(set(b) - set(a)),
            "status_pairs": {f"{sa}/{sb}": n for (sa, sb), n in sorted(table.items())},
            "n_ok_both": int(d.size), "max_rel_deviation": {**q, "max": float(d.max()) if d.size else None,
                                                            "gt_1pct": int(np.sum(d > 0.01)),
                                                            "gt_5pct": int(np.sum(d > 0.05))},
            "farthest": [{"sample_id": i, "deviation": v} for i, v in far], "falls": fall}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("store_a")
    ap.add_argument("store_b", help="the reference")
    ap.add_argument("--worst", type=int, default=5, help="list this many farthest curves")
    args = ap.parse_args(argv)
    res = compare(_curves(args.store_a), _curves(args.store_b), args.worst)
    print(f"design points in both: {res['n_common']} (only A {res['only_a']}, only B {res['only_b']})")
    print("| status A / status B | curves |\n|---|---|")
    for k, n in res["status_pairs"].items():
        print(f"| {k} | {n} |")
    m = res["max_rel_deviation"]
    print(f"ok in both: {res['n_ok_both']}; largest deviation per curve: "
          + ", ".join(f"{k} {v:.3g}" for k, v in m.items() if v is not None))
    for w in res["farthest"]:
        print(f"  {w['sample_id']}: {w['deviation']:.3g}")
    for k, f in res["falls"].items():
        print(f"store {k.upper()}: {f['ok']} ok, falling back > 5 %: {f['fall_gt_5pct']}, > 10 %: {f['fall_gt_10pct']}")
    print(json.dumps({"store_a": args.store_a, "store_b": args.store_b, **res}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
