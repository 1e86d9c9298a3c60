"""What a smaller quasi-static ``max_steps`` would cost and save, from a campaign's own records.

A quasi-static record carries ``fire_steps_chain``: the FIRE updates of every chain point (the ramp's sub-points
included).  With ``stop_unstable`` a point that reaches ``max_steps`` ends its curve as 'unstable'; a smaller cap
therefore changes nothing but which curves end early: a curve is kept 'ok' exactly when every point converged within
the cap, with the same iterates (the same curve), and a cut curve costs its steps up to the cut point plus the cap.
This prints, per cap: ok curves kept and lost, where the lost ones sit in k_b and k_a, the pool's FIRE work relative
to the run's, and the largest per-curve work (the pool's tail is set by its longest curves).

    python benchmarks/studies/max_steps_study.py STORE [--caps 100000,50000,40000,30000,20000]

Input: a campaign store folder or its ``.jsonl.gz`` export, made with ``stop_unstable = true`` and a cap at least as
large as every cap asked for.  Last stdout line: one JSON summary.
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np


def read_records(path: str) -> list[dict]:
    """Records of a campaign store folder or of its read-only ``.jsonl.gz`` export."""
    from bubblecal.data import CampaignStore

    return CampaignStore(path).read(warn=False)


def cap_curves(chains: list[np.ndarray], ok: np.ndarray, cap: int) -> tuple[np.ndarray, np.ndarray]:
    """FIRE work of each curve (updates) and whether it stays 'ok' under a per-point cap ``cap``: the first point
    past the cap ends its curve after ``cap`` updates there (``stop_unstable``); a curve stays 'ok' when it was 'ok'
    and every point converged within the cap."""
    work = np.empty(len(chains))
    kept = np.zeros(len(chains), dtype=bool)
    for i, c in enumerate(chains):
        over = np.nonzero(c > cap)[0]
        if over.size:
            work[i] = c[:over[0]].sum() + cap
        else:
            work[i] = c.sum()
            kept[i] = ok[i]
    return work, kept


def chains_of(records: list[dict]) -> list[np.ndarray]:
    """Per record, its FIRE updates per chain point (``provenance.info.fire_steps_chain``); SystemExit if absent."""
    if not records or any("fire_steps_chain" not in r.get("provenance", {}).get("info", {}) for r in records):
        raise SystemExit("a record lacks provenance.info.fire_steps_chain (the per-point FIRE updates that "
                         "quasi-static records streamed by an async slot-refill run hold)")
    return [np.asarray(r["provenance"]["info"]["fire_steps_chain"], dtype=np.int64) for r in records]


def study(records: list[dict], caps: list[int]) -> dict:
    """Per cap (FIRE updates per chain point): ok kept / lost, lost curves' k_b (range, median) and k_a range (DPD
    units), FIRE work relative to the records' own, and the largest / 99.9th-percentile per-curve work (FIRE
    updates).  Records without ``fire_steps_chain`` are left out."""
    rows = [r for r in records if "fire_steps_chain" in r.get("provenance", {}).get("info", {})]
    chains = chains_of(rows)
    settings = rows[0]["provenance"]["info"].get("settings", {})
    run_cap = int(settings.get("fire", {}).get("max_steps", 0)) or None
    if run_cap is not None and any(c > run_cap for c in caps):
        raise SystemExit(f"caps {caps} exceed the run's own max_steps ({run_cap}): the records cannot say what a "
                         "larger cap would do")
    ok = np.array([r["status"] == "ok" for r in rows])
    kb = np.array([r["params"]["kb"] for r in rows], dtype=np.float64)
    ka = np.array([r["params"]["ka"] for r in rows], dtype=np.float64)
    base = float(sum(int(c.sum()) for c in chains))
    out = {"n_records": len(rows), "ok": int(ok.sum()), "run_max_steps": run_cap, "caps": []}
    for cap in caps:
        work, kept = cap_curves(chains, ok, cap)
        lost = ok & ~kept
        out["caps"].append({
            "max_steps": int(cap), "ok": int(kept.sum()), "lost": int(lost.sum()),
            "lost_kb": [float(kb[lost].min()), float(kb[lost].max())] if lost.any() else None,
            "lost_kb_median": float(np.median(kb[lost])) if lost.any() else None,
            "lost_ka": [float(ka[lost].min()), float(ka[lost].max())] if lost.any() else None,
            "work_fraction": float(work.sum() / base) if base else 1.0,
            "max_curve_work": int(work.max()), "p999_curve_work": float(np.percentile(work, 99.9))})
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("records", help="campaign store folder or its .jsonl.gz export (quasi-static records)")
    ap.add_argument("--caps", default="100000,50000,40000,30000,20000", help="comma list of max_steps values")
    args = ap.parse_args(argv)
    try:
        caps = [int(v) for v in args.caps.split(",") if v.strip()]
    except ValueError:
        raise SystemExit(f"--caps {args.caps!r}: expected a comma list of integers") from None
    if not caps or min(caps) < 1:
        raise SystemExit(f"--caps {args.caps!r}: expected integers >= 1")
    res = study(read_records(args.records), caps)
    print(f"{res['n_records']} records, {res['ok']} ok (run max_steps {res['run_max_steps']})")
    print(f"{'max_steps':>9} {'ok':>6} {'lost':>5} {'lost k_b range':>20} {'median':>7} {'FIRE work':>9} "
          f"{'max curve':>10} {'p99.9 curve':>11}")
    for c in res["caps"]:
        kb = f"{c['lost_kb'][0]:.0f}-{c['lost_kb'][1]:.0f}" if c["lost_kb"] else "-"
        med = f"{c['lost_kb_median']:.0f}" if c["lost_kb_median"] is not None else "-"
        print(f"{c['max_steps']:>9} {c['ok']:>6} {c['lost']:>5} {kb:>20} {med:>7} {c['work_fraction']:>9.3f} "
              f"{c['max_curve_work']:>10} {c['p999_curve_work']:>11.0f}")
    print(json.dumps({"benchmark": "max_steps_study", "source": str(args.records), **res}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
