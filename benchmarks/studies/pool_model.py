"""Model of a quasi-static slot-refill pool's wall time from its curves' FIRE work and measured iteration costs.

    python benchmarks/studies/pool_model.py STORE [STORE ...] --costs benchmarks/figures/qs_iteration_cost_h100.jsonl
        [--slots 500,1000] [--threads-tag TEXT ...] [--max-steps 40000,30000]

Replays the schedule of ``quasistatic_*(..., max_replicas=R)`` (softest k_a first; a finished slot takes the next
curve; once the pool is empty and at most 1/8 of the slots relax, they move to a batch of their own size while
that batch has more than 8 slots) with each curve's total FIRE iterations from the store, and charges each batch
iteration the measured ms of ``benchmarks/qs_iteration_cost.py`` for its size and relaxing count (linear in the
relaxing count between one and all, linear in between measured sizes).  Host work (point measurements, refills)
is not modelled: against measured pools the model was 8-19 % short (benchmarks/RESULTS.md).  ``--max-steps``: also model
smaller per-point FIRE caps from the records' ``fire_steps_chain`` (``max_steps_study.py`` here: a cut curve
costs its steps up to the cut plus the cap, and counts as 'ok' only if every point converged within the cap).  A
``--threads-tag`` matches a cost line's ``threads_per_replica`` or ``kernels`` text.  Prints a table and a JSON line.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # sibling study scripts
from fire_work import load_work  # noqa: E402
from max_steps_study import cap_curves, chains_of  # noqa: E402

COMPACT_BELOW, COMPACT_MIN = 0.125, 8  # as bubblecal.sim.tiers.quasistatic.schedule


def cost_table(lines: Sequence[dict], tag: str | None = None) -> dict[int, tuple[float, float]]:
    """Batch size -> (ms per iteration with all relaxing, with one relaxing) from qs_iteration_cost JSON lines
    (CUDA-graph rows; ``tag``: only lines whose ``threads_per_replica`` or ``kernels`` text contains it; later
    lines win)."""
    table: dict[int, list] = {}
    for d in lines:
        if tag is not None and tag not in f"{d.get('threads_per_replica', '')} {d.get('kernels', '')}":
            continue
        for r in d["rows"]:
            if not r["graph"]:
                continue
            e = table.setdefault(int(r["replicas"]), [None, None])
            e[0 if r["active"] == r["replicas"] else 1] = float(r["ms_per_iteration"])
    return {R: (a, a if o is None else o) for R, (a, o) in sorted(table.items()) if a is not None}


def iteration_cost(table: dict[int, tuple[float, float]]) -> Callable[[int, int], float]:
    """ms per batch iteration for a batch of R slots with k relaxing (see the module docstring)."""
    sizes = np.array(sorted(table), dtype=float)
    alls = np.array([table[int(R)][0] for R in sizes])
    ones = np.array([table[int(R)][1] for R in sizes])

    def cost(R: int, k: int) -> float:
        a = float(np.interp(R, sizes, alls, right=alls[-1] * R / sizes[-1]))
        o = float(np.interp(R, sizes, ones))
        return o + (a - o) * (k - 1) / max(R - 1, 1)

    return cost


def pool_seconds(steps: np.ndarray, ka: np.ndarray, slots: int, cost: Callable[[int, int], float]) -> float:
    """Modelled wall seconds of one pool: curves of ``steps`` FIRE iterations, ``slots`` relaxing at once."""
    work = np.asarray(steps, dtype=float)[np.argsort(ka, kind="stable")]
    S = len(work)
    nxt = min(slots, S)
    left = work[:nxt].copy()
    R, t = slots, 0.0
    while left.size:
        m = left.min()
        t += m * cost(R, left.size) * 1e-3
        left = left[left > m] - m
        if nxt < S:
            take = min(S - nxt, R - left.size)
            left = np.concatenate([left, work[nxt:nxt + take]])
            nxt += take
        if nxt >= S and 0 < left.size <= COMPACT_BELOW * R and R > COMPACT_MIN:
            R = left.size
    return t


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("stores", nargs="+")
    ap.add_argument("--costs", required=True, help="JSON lines of benchmarks/qs_iteration_cost.py")
    ap.add_argument("--slots", default="500,1000")
    ap.add_argument("--threads-tag", action="append", default=None,
                    help="cost lines whose threads_per_replica or kernels text contains this (repeat: one table each)")
    ap.add_argument("--max-steps", default="", help="comma list of per-point FIRE caps to model (records need "
                    "fire_steps_chain); the run's own cap is always modelled")
    args = ap.parse_args(argv)
    try:
        caps = [int(v) for v in args.max_steps.split(",") if v.strip()]
    except ValueError:
        raise SystemExit(f"--max-steps {args.max_steps!r}: expected a comma list of integers >= 1") from None
    if any(c < 1 for c in caps):
        raise SystemExit(f"--max-steps {args.max_steps!r}: expected a comma list of integers >= 1")
    lines = [json.loads(s) for s in Path(args.costs).read_text().splitlines() if s.strip()]
    tags = args.threads_tag or sorted({str(d.get("threads_per_replica")) for d in lines})
    base = cost_table(lines, tags[0])
    out = []
    for path in args.stores:
        recs, steps, status, ka = load_work(path)
        fin = np.isfinite(steps)
        variants = [(None, steps[fin], int(np.sum(status == "ok")))]
        if caps:
            chains = chains_of([r for r, f in zip(recs, fin, strict=True) if f])
            for cap in caps:
                work, kept = cap_curves(chains, status[fin] == "ok", cap)
                variants.append((cap, work, int(kept.sum())))
        for tag in tags:
            table = {**base, **cost_table(lines, tag)}  # sizes measured only before keep those costs
            for R in (int(s) for s in args.slots.split(",")):
                for cap, work, ok in variants:
                    t = pool_seconds(work, ka[fin], R, iteration_cost(table))
                    out.append({"store": path, "threads": tag, "slots": R, "max_steps": cap, "model_s": t, "ok": ok,
                                "ok_per_gpu_hour": ok / t * 3600.0})
                    cap_s = "run's" if cap is None else str(cap)
                    print(f"{Path(path).name:<32} {tag[:40]:<40} R={R:<5d} max_steps {cap_s:>6} {t:7.0f} s  "
                          f"{ok / t * 3600:9,.0f} ok/GPU-h")
    print(json.dumps({"benchmark": "pool_model", "rows": out}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
