"""What a NetCDF phase file costs to write at a given number of draws, and where the time goes.

A phase result of ``--draws`` TMCMC-like float32 draws (``--distinct`` distinct particles resampled, as a final
TMCMC population is) of four shell and noise parameters, with a ``--points``-point pointwise log likelihood, is
turned into its InferenceData (``bubblecal.workflows.calibrate.phase_inference_data``) and written by ArviZ's
``to_netcdf`` (zlib-compressed), by ``bubblecal.inference.write_netcdf`` (the same layout and compression, h5py in
one open of the file), as the calibration writes it (``write_phase``: ``write_netcdf`` into a temporary file renamed
in place), then as one xarray DataTree write without compression and with zlib level 1, and as ``.npz``.  Best of
``--repeat`` per variant.

Usage::

    python benchmarks/phase_file_cost.py --draws 50000 --points 20 [--repeat 3] [--out DIR]

Prints one table (seconds, MB per variant) and one JSON line (``{"benchmark": "phase_file_cost", ...}``).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--draws", type=int, default=50_000)
    ap.add_argument("--distinct", type=int, default=2_000, help="distinct particles among the draws")
    ap.add_argument("--points", type=int, default=20, help="points of the pointwise log likelihood")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", type=Path, default=None, help="folder of the files (default: a temporary one)")
    args = ap.parse_args()

    import xarray as xr

    from bubblecal.inference import PhaseResult, write_netcdf
    from bubblecal.workflows.calibrate import phase_inference_data, write_phase

    rng = np.random.default_rng(0)
    pick = rng.integers(0, args.distinct, args.draws)
    # float32, as the samplers' draws and log likelihoods are
    samples = {k: rng.normal(size=args.distinct).astype(np.float32)[pick] for k in ("ka", "kb", "d0", "sigma_mech")}
    pointwise = {"obs": rng.normal(size=(args.distinct, args.points)).astype(np.float32)[pick]}
    loglik = rng.normal(size=args.distinct).astype(np.float32)[pick]
    result = PhaseResult("phase3_bench", samples, -10.0, 0.1, "converged", 1.0)
    folder = args.out or Path(tempfile.mkdtemp(prefix="phase_file_cost_"))
    folder.mkdir(parents=True, exist_ok=True)

    def best(fn) -> float:
        times = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t0)
        return min(times)

    idata = phase_inference_data(result, loglik, pointwise=pointwise)
    tree = xr.DataTree.from_dict({f"/{g}": getattr(idata, g) for g in idata.groups()})
    zlib1 = {f"/{g}": {v: {"zlib": True, "complevel": 1} for v in getattr(idata, g).data_vars
                       if getattr(idata, g)[v].dtype.kind in "fiub"} for g in idata.groups()}
    variants = {
        "InferenceData (build)": (lambda: phase_inference_data(result, loglik, pointwise=pointwise), None),
        "ArviZ to_netcdf (zlib)": (lambda: idata.to_netcdf(str(folder / "a0.nc")), folder / "a0.nc"),
        "write_netcdf (h5py, zlib)": (lambda: write_netcdf(idata, folder / "e.nc"), folder / "e.nc"),
        "write_phase .nc (write_netcdf)": (lambda: write_phase(folder / "a.nc", result, loglik, {}, idata=idata),
                                           folder / "a.nc"),
        "DataTree, no compression": (lambda: tree.to_netcdf(folder / "b.nc", engine="h5netcdf"), folder / "b.nc"),
        "DataTree, zlib level 1": (lambda: tree.to_netcdf(folder / "c.nc", engine="h5netcdf", encoding=zlib1),
                                   folder / "c.nc"),
        "write_phase .npz": (lambda: write_phase(folder / "d.npz", result, loglik, {}), folder / "d.npz"),
    }
    rows = []
    print(f"{'variant':<32s} {'seconds':>8s} {'MB':>6s}")
    for name, (fn, path) in variants.items():
        s = best(fn)
        mb = path.stat().st_size / 1e6 if path is not None else None
        rows.append({"variant": name, "seconds": s, "MB": mb})
        print(f"{name:<32s} {s:8.3f} {'-' if mb is None else f'{mb:6.1f}':>6s}", flush=True)
    print(json.dumps({"benchmark": "phase_file_cost", "draws": args.draws, "distinct": args.distinct,
                      "points": args.points, "rows": rows}))


if __name__ == "__main__":
    main()
