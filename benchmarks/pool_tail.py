"""Which curves make a quasi-static campaign pool's tail: FIRE work per record status of shipped sets.

    python benchmarks/pool_tail.py data/training/sonovue_indentation_3.2um_mirheo.jsonl.gz [...] [--top 20]

Per set: the statuses of the ``--top`` slowest curves (FIRE iterations, ``provenance.info.fire_steps``), the
slowest curve of each status, and the share of all FIRE work spent on curves the training does not use
('unstable', 'failed').  Prints a table and one JSON line last.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter

import numpy as np

STATUSES = ("ok", "unstable", "ruptured", "failed")


def tail_report(path: str, top: int = 20) -> dict:
    """FIRE work by status of one campaign store or export (iterations, dimensionless counts)."""
    from bubblecal.data.store import CampaignStore

    recs = CampaignStore(path).read()
    work = np.array([float(r["provenance"]["info"]["fire_steps"]) for r in recs])
    status = np.array([r["status"] for r in recs])
    slow = np.argsort(-work)[:top]
    unused = np.isin(status, ("unstable", "failed"))
    return {"records": len(recs), "top": top, "top_statuses": dict(Counter(status[slow].tolist())),
            "slowest_by_status": {s: int(work[status == s].max()) for s in STATUSES if (status == s).any()},
            "work_total": float(work.sum()), "unused_work_share": float(work[unused].sum() / work.sum())}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("stores", nargs="+")
    ap.add_argument("--top", type=int, default=20)
    args = ap.parse_args(argv)
    out = {}
    print(f"{'set':48s} {'top statuses':40s} slowest ok / unstable / ruptured / failed   unused work")
    for p in args.stores:
        r = out[p] = tail_report(p, args.top)
        sl = " / ".join(f"{r['slowest_by_status'].get(s, 0):,}" for s in STATUSES)
        print(f"{p.split('/')[-1]:48s} {str(r['top_statuses']):40s} {sl:42s} {100 * r['unused_work_share']:.1f} %")
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
