"""A network over the diameter at the published diameters: against the published Mirheo rows, beside the per-diameter
surrogates.

For every ``<reference>/training_head_<setup>_<D>um.csv`` (the published explicit-solvent training rows: compression
2.1 / 2.9 / 3.0 um, indentation 3.2 / 5.8 um) the script evaluates, on the rows inside both training boxes,

* the network over the diameter bound to the rows' diameter (``Surrogate.at_diameter``), and
* the bundle's per-diameter surrogate at that diameter (``Bundle.get``, default: the shipped bundle),

and reports the median relative L2 error of each against the published curves, and the gap in percentage points.
The gates: the network's median <= 5 % and at most 0.5 points above the per-diameter surrogate's.

    python benchmarks/diameter_surrogate_validation.py --surrogate compression_1.5-8um.npz \
        [--surrogate indentation_1.5-8um.npz] [--bundle DIR] [--reference DIR]

Prints a table and a final JSON line; skips cleanly (exit 0) when the reference folder is absent.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # benchmarks/, for tier_validation.py
from tier_validation import find_reference  # noqa: E402  (benchmark script)

GATE_MEDIAN = 0.05
GATE_GAP_PP = 0.5


def score(sur, ts) -> tuple[np.ndarray, np.ndarray]:
    """(inside mask, per-curve relative L2 over the rows) of a surrogate on a published row set."""
    from bubblecal.surrogates.training import relative_l2

    inside = np.all(np.asarray(sur.in_training_box(ts.params[:, None, :], ts.x)), axis=1)
    y_hat = np.asarray(sur(ts.params[:, None, :], ts.x), dtype=np.float64)
    return inside, relative_l2(y_hat, ts.y)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--surrogate", action="append", required=True, help="a network over the diameter (.npz)")
    ap.add_argument("--bundle", default=None, help="bundle with the per-diameter surrogates (default: shipped)")
    ap.add_argument("--reference", default=None)
    args = ap.parse_args(argv)

    from bubblecal.surrogates import default_bundle_path, load, load_bundle
    from bubblecal.surrogates.training import filter_curves, read_published

    ref = find_reference(args.reference)
    if ref is None:
        print("reference folder absent: skipped")
        print(json.dumps({"benchmark": "diameter_surrogate_validation", "skipped": True}))
        return 0
    bundle = load_bundle(args.bundle or default_bundle_path(must_exist=True))
    rows = []
    print(f"{'setup':12s} {'D um':>5s} {'rows':>5s} {'scored':>6s} {'over D':>8s} {'per D':>8s} {'gap pp':>7s} gates")
    for path in args.surrogate:
        wide = load(path)
        if not wide.over_diameter:
            raise SystemExit(f"{path}: not a network over the diameter")
        for f in sorted(Path(ref).glob(f"training_head_{wide.setup}_*um.csv")):
            ts, _ = filter_curves(read_published(f, wide.setup))
            d = ts.diameter_um
            nominal = float(f.stem.rsplit("_", 1)[1].removesuffix("um"))
            per = bundle.get(wide.setup, nominal)
            in_w, err_w = score(wide.at_diameter(d), ts)
            in_p, err_p = score(per, ts)
            both = in_w & in_p
            med_w, med_p = float(np.median(err_w[both])), float(np.median(err_p[both]))
            gap = 100 * (med_w - med_p)
            ok = med_w <= GATE_MEDIAN and gap <= GATE_GAP_PP
            rows.append({"setup": wide.setup, "diameter_um": nominal, "data_diameter_um": d, "rows": ts.n_curves,
                         "scored": int(both.sum()), "median_over_diameter": med_w, "median_per_diameter": med_p,
                         "gap_pp": gap, "passes": bool(ok), "surrogate": str(path), "per_diameter": str(per.path)})
            print(f"{wide.setup:12s} {nominal:5.2g} {ts.n_curves:5d} {int(both.sum()):6d} {100 * med_w:7.2f}% "
                  f"{100 * med_p:7.2f}% {gap:+7.2f} {'pass' if ok else 'FAIL'}")
    print(json.dumps({"benchmark": "diameter_surrogate_validation", "gates": {"median": GATE_MEDIAN,
                                                                              "gap_pp": GATE_GAP_PP},
                      "rows": rows}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
