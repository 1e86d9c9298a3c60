"""A surrogate trained on bubblecal's own simulations, evaluated on the published Mirheo training rows.

For the valid rows of ``<reference>/training_head_<setup>_<diameter>um.csv`` (the published explicit-solvent
curves), the surrogate predicts the curve at the row's parameters and loading grid; reported: median and IQR of
the relative L2 error ||y_surrogate - y_published|| / ||y_published|| over the rows inside the surrogate's
training box (rows outside are counted, not scored), the median ratio per loading point, and the same numbers
for the surrogate's own grouped-holdout score (from its metadata) for comparison.

    python benchmarks/studies/own_surrogate_vs_published.py --surrogate OUT/indentation_3.2um.npz --setup indentation \
        --diameter 3.2 [--reference DIR]

Prints a table and a final JSON line; skips cleanly (exit 0) when the reference file is absent.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for tier_validation.py
from tier_validation import find_reference  # noqa: E402  (benchmark script)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--surrogate", required=True)
    ap.add_argument("--setup", required=True, choices=("compression", "indentation"))
    ap.add_argument("--diameter", required=True, type=float)
    ap.add_argument("--reference", default=None)
    args = ap.parse_args(argv)

    from bubblecal.surrogates import load
    from bubblecal.surrogates.training import filter_curves, read_published, relative_l2

    ref = Path(args.reference) if args.reference else find_reference(None)
    path = Path(ref or ".") / f"training_head_{args.setup}_{args.diameter:g}um.csv"
    if ref is None or not path.is_file():
        print(f"reference file {path} absent: skipped")
        print(json.dumps({"skipped": str(path)}))
        return 0
    ts, _ = filter_curves(read_published(path, args.setup))
    sur = load(args.surrogate)
    inside = np.all(sur.in_training_box(ts.params[:, None, :], ts.x), axis=1)
    y_hat = np.asarray(sur(ts.params[:, None, :], ts.x), dtype=np.float64)
    err = relative_l2(y_hat[inside], ts.y[inside])
    ratio = np.median(y_hat[inside][:, 1:] / ts.y[inside][:, 1:], axis=0) if inside.any() else np.array([])
    md = sur.metadata
    out = {"surrogate": str(args.surrogate), "reference": str(path), "rows": int(ts.n_curves),
           "rows_inside_box": int(inside.sum()),
           "median_rel_l2_vs_published": float(np.median(err)) if err.size else None,
           "iqr_rel_l2_vs_published": [float(v) for v in np.percentile(err, [25, 75])] if err.size else None,
           "median_ratio_by_point": [round(float(v), 4) for v in ratio],
           "holdout_median_rel_l2": md.get("holdout_score"), "training_source": md.get("data_source")}
    print(f"{'rows':>5s} {'inside box':>10s} {'median relL2 vs Mirheo':>24s} {'IQR':>18s} {'own holdout':>12s}")
    iqr = out["iqr_rel_l2_vs_published"]
    med = out["median_rel_l2_vs_published"]
    print(f"{out['rows']:5d} {out['rows_inside_box']:10d} {med if med is None else f'{med:.4f}':>24s} "
          f"{'-' if iqr is None else f'[{iqr[0]:.4f}, {iqr[1]:.4f}]':>18s} {str(md.get('holdout_score')):>12s}")
    print("median ratio surrogate / published per point (2..P):", out["median_ratio_by_point"])
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
