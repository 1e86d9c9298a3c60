"""Networks over the diameter on the curves of held-out diameter bands, overall and in a corner of k_a.

    python benchmarks/studies/network_corner.py STORE --bands 4.3-4.7,6.6-7.0 --ka 3000-30000 \
        --surrogate A.npz [--surrogate B.npz ...]

Reads the 'ok' curves of a campaign store (the sweep's default filter), keeps those whose diameter lies in one of
``--bands`` (the leave-diameters-out bands no network of the sweep trained on), and scores each network bound to
each curve's diameter: relative L2 per curve (||y_hat - y||_2 / ||y||_2 over its finite points), median and p90
over all the band curves and over those with ``--ka`` LO < k_a < HI (where the SonoVue posteriors lie).  Prints
a table and a final JSON line.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from bubblecal.surrogates import load
from bubblecal.surrogates.training import diameter_bands, filter_curves, read_dataset


def surrogate_errors(sur, ts) -> np.ndarray:
    """Relative L2 error of ``sur`` on every curve of ``ts`` (each at its own diameter)."""
    err = np.full(ts.n_curves, np.nan)
    valid = ts.point_mask()
    for i in range(ts.n_curves):
        m = valid[i]
        y_hat = np.asarray(sur(ts.params[i], ts.x[i][m], ts.diameters_um[i]))
        err[i] = np.linalg.norm(y_hat - ts.y[i][m]) / np.linalg.norm(ts.y[i][m])
    return err


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("store")
    ap.add_argument("--bands", required=True, help="held-out diameter bands [um], e.g. 4.3-4.7,6.6-7.0")
    ap.add_argument("--ka", default="3000-30000", help="the corner LO-HI of k_a [DPD]")
    ap.add_argument("--surrogate", action="append", required=True, help="a network over the diameter (.npz)")
    args = ap.parse_args()
    bands = tuple(tuple(float(v) for v in b.split("-")) for b in args.bands.split(",") if b)
    lo, hi = (float(v) for v in args.ka.split("-"))
    ts, _ = filter_curves(read_dataset(args.store))
    ts = ts.subset(diameter_bands(ts.diameters_um, bands))
    corner = (ts.params[:, 0] > lo) & (ts.params[:, 0] < hi)
    rows = []
    print(f"{ts.n_curves} curves in the bands {args.bands} um, {int(corner.sum())} with {lo:g} < ka < {hi:g}")
    print(f"{'network':48s} {'median':>8s} {'p90':>8s} {'corner median':>14s} {'corner p90':>11s}")
    for path in args.surrogate:
        err = surrogate_errors(load(path), ts)
        row = {"surrogate": path, "median": float(np.nanmedian(err)), "p90": float(np.nanquantile(err, 0.9)),
               "corner_median": float(np.nanmedian(err[corner])), "corner_p90": float(np.nanquantile(err[corner], 0.9)),
               "n": int(ts.n_curves), "n_corner": int(corner.sum())}
        rows.append(row)
        print(f"{path:48s} {100 * row['median']:7.3f}% {100 * row['p90']:7.3f}% {100 * row['corner_median']:13.3f}% "
              f"{100 * row['corner_p90']:10.3f}%", flush=True)
    print(json.dumps({"study": "network_corner", "store": args.store, "bands": args.bands, "ka": args.ka,
                      "rows": rows}))


if __name__ == "__main__":
    main()
