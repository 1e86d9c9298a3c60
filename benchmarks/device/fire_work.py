"""Per-store FIRE work and statuses of campaign stores (a throughput diagnosis on the lent GPU).

    python3 benchmarks/device/fire_work.py STORE [STORE ...]

Prints per store: records, statuses, median / p90 / max FIRE iterations per curve (provenance.info.fire_steps),
task compute seconds, and one JSON line.
"""

from __future__ import annotations

import json
import sys
from collections import Counter

import numpy as np


def main(argv=None) -> int:
    from bubblecal.data.store import CampaignStore

    out = {}
    for path in (argv if argv is not None else sys.argv[1:]):
        recs = CampaignStore(path).read(warn=False)
        steps = np.array([r["provenance"].get("info", {}).get("fire_steps", np.nan) for r in recs], dtype=float)
        tasks = {r["provenance"].get("task"): r["provenance"].get("task_compute_s") for r in recs}
        row = {"records": len(recs), "status": dict(Counter(r["status"] for r in recs)),
               "fire_steps_median": float(np.nanmedian(steps)) if len(recs) else None,
               "fire_steps_p90": float(np.nanpercentile(steps, 90)) if len(recs) else None,
               "fire_steps_max": float(np.nanmax(steps)) if len(recs) else None,
               "fire_steps_sum": float(np.nansum(steps)), "task_compute_s": tasks}
        print(path, row)
        out[path] = row
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
