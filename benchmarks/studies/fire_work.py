"""Per-store FIRE work and statuses of campaign stores (a throughput diagnosis; runs anywhere).

    python benchmarks/studies/fire_work.py STORE [STORE ...] [--top 20]

Prints per store: records, statuses, median / p90 / max / sum of FIRE iterations per curve
(provenance.info.fire_steps), task compute seconds, and which curves make a pool's tail: the statuses of the
``--top`` slowest curves, the slowest curve of each status and the share of all FIRE work spent on curves the
training does not use ('unstable', 'failed'); then one JSON line.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter

import numpy as np

STATUSES = ("ok", "unstable", "ruptured", "failed")


def load_work(path: str) -> tuple[list, np.ndarray, np.ndarray, np.ndarray]:
    """Records of a campaign store or export and, per record, FIRE iterations (NaN where not recorded), status
    and k_a (DPD units)."""
    from bubblecal.data import CampaignStore

    recs = CampaignStore(path).read(warn=False)
    steps = np.array([r["provenance"].get("info", {}).get("fire_steps", np.nan) for r in recs], dtype=float)
    status = np.array([r["status"] for r in recs])
    ka = np.array([r["params"]["ka"] for r in recs], dtype=float)
    return recs, steps, status, ka


def fire_work(path: str, top: int = 20) -> dict:
    """FIRE work (iterations, dimensionless counts) by record of one campaign store or export."""
    recs, steps, status, _ = load_work(path)
    tasks = {r["provenance"].get("task"): r["provenance"].get("task_compute_s") for r in recs}
    have = len(recs) > 0 and np.isfinite(steps).any()
    slow = np.argsort(-np.nan_to_num(steps, nan=-1.0))[:top]
    unused = np.isin(status, ("unstable", "failed"))
    return {"records": len(recs), "status": dict(Counter(status.tolist())),
            "fire_steps_median": float(np.nanmedian(steps)) if have else None,
            "fire_steps_p90": float(np.nanpercentile(steps, 90)) if have else None,
            "fire_steps_max": float(np.nanmax(steps)) if have else None,
            "fire_steps_sum": float(np.nansum(steps)), "task_compute_s": tasks,
            "top": top, "top_statuses": dict(Counter(status[slow].tolist())),
            "slowest_by_status": {s: int(np.nanmax(steps[status == s])) for s in STATUSES
                                  if have and np.isfinite(steps[status == s]).any()},
            "unused_work_share": float(np.nansum(steps[unused]) / np.nansum(steps)) if have else None}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("stores", nargs="+")
    ap.add_argument("--top", type=int, default=20, help="the slowest curves whose statuses are counted")
    args = ap.parse_args(argv)
    out = {}
    for path in args.stores:
        row = out[path] = fire_work(path, args.top)
        print(path, {k: v for k, v in row.items() if k not in ("top_statuses", "slowest_by_status",
                                                                 "unused_work_share")})
        share = row["unused_work_share"]
        print(f"  tail: {row['top']} slowest {row['top_statuses']}; slowest "
              + " / ".join(f"{s} {row['slowest_by_status'].get(s, 0):,}" for s in STATUSES)
              + f"; unstable + failed work {'-' if share is None else f'{100 * share:.1f} %'}")
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
