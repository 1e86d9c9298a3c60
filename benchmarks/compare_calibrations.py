"""Compare two ``bubblecal calibrate`` output folders: are the posteriors the same?

The referee of a behaviour-preserving change: run ``bubblecal calibrate`` with the same options and seed before
and after the change, then::

    python benchmarks/compare_calibrations.py BEFORE_DIR AFTER_DIR [--rtol 0]

Every phase file (``*.nc`` groups, or ``*.npz``) present in either folder is compared variable by variable, as
are the numeric columns of ``summary.csv`` / ``ess.csv`` and the config hashes and log evidences of
``manifest.json``.  Prints one table row per file (variables compared, largest absolute and relative
difference, verdict) and, last, one JSON line.  ``--shifts K`` adds the K largest shifts of the summary medians in
units of the 90 % interval widths (for two runs that differ on purpose, e.g. two surrogate choices).  Exit status 0
when everything agrees within ``--rtol`` / ``--atol`` (default: bit-identical), 1 otherwise, 2 on unusable input.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from pathlib import Path

import numpy as np

_NETCDF_GROUPS = ("posterior", "sample_stats", "log_likelihood", "observed_data", "constant_data", "prior")
_TIME_KEYS = ("seconds", "wall", "time", "created", "written", "code_version", "utc")


def _max_diff(a: np.ndarray, b: np.ndarray) -> tuple[float, float, bool]:
    """Largest absolute and relative difference of two arrays and whether their shapes and NaNs agree."""
    if a.shape != b.shape:
        return math.inf, math.inf, False
    if a.dtype.kind not in "fciub" or b.dtype.kind not in "fciub":
        return (0.0, 0.0, True) if np.array_equal(a, b) else (math.inf, math.inf, False)
    a = a.astype(np.float64)
    b = b.astype(np.float64)
    nan_a, nan_b = np.isnan(a), np.isnan(b)
    if not np.array_equal(nan_a, nan_b):
        return math.inf, math.inf, False
    ok = ~nan_a
    if not ok.any():
        return 0.0, 0.0, True
    diff = np.abs(a[ok] - b[ok])
    scale = np.maximum(np.abs(a[ok]), np.abs(b[ok]))
    rel = np.divide(diff, scale, out=np.zeros_like(diff), where=scale > 0)
    return float(diff.max()), float(rel.max()), True


def _phase_arrays(path: Path) -> dict[str, np.ndarray]:
    """Every variable of a phase file as ``{"group/name": array}``."""
    if path.suffix == ".npz":
        with np.load(path, allow_pickle=False) as z:
            return {k: np.asarray(z[k]) for k in z.files}
    import xarray as xr

    out: dict[str, np.ndarray] = {}
    for group in _NETCDF_GROUPS:
        try:
            ds = xr.open_dataset(path, group=group, engine="h5netcdf")
        except (OSError, KeyError, ValueError):
            continue
        with ds:
            for name, var in ds.data_vars.items():
                out[f"{group}/{name}"] = np.asarray(var.values)
    return out


def _csv_arrays(path: Path) -> dict[str, np.ndarray]:
    """The numeric columns of a CSV file, keyed by column name (non-numeric columns compared as text)."""
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    cols: dict[str, np.ndarray] = {}
    for name in rows[0] if rows else []:
        if any(k in name.lower() for k in _TIME_KEYS):
            continue
        values = [r[name] for r in rows]
        try:
            cols[name] = np.array([float(v) if v != "" else np.nan for v in values])
        except ValueError:
            cols[name] = np.array(values)
    return cols


def _manifest_arrays(path: Path) -> dict[str, np.ndarray]:
    """Config hashes, statuses and log evidences of every phase in a manifest."""
    phases = json.loads(path.read_text()).get("phases", {})
    out: dict[str, np.ndarray] = {}
    for name, entry in phases.items():
        for key in ("config_hash", "status", "num_draws"):
            if key in entry:
                out[f"{name}/{key}"] = np.array(entry[key])
        for key in ("log_evidence", "log_evidence_se"):
            value = entry.get(key)
            out[f"{name}/{key}"] = np.array(np.nan if value is None else value, dtype=np.float64)
    return out


def _reader(path: Path):
    if path.suffix in (".nc", ".npz"):
        return _phase_arrays
    if path.suffix == ".csv":
        return _csv_arrays
    if path.name == "manifest.json":
        return _manifest_arrays
    return None


def compare_files(a: Path, b: Path, rtol: float, atol: float) -> dict:
    """Compare one file present in both folders; returns a row of the report."""
    read = _reader(a)
    va, vb = read(a), read(b)
    names = sorted(set(va) | set(vb))
    worst_abs, worst_rel, bad = 0.0, 0.0, []
    for name in names:
        if name not in va or name not in vb:
            bad.append(f"{name} (missing on one side)")
            continue
        d_abs, d_rel, same_shape = _max_diff(np.asarray(va[name]), np.asarray(vb[name]))
        worst_abs, worst_rel = max(worst_abs, d_abs), max(worst_rel, d_rel)
        if not same_shape or (d_abs > atol and d_rel > rtol):
            bad.append(name)
    return {"file": str(a.name), "variables": len(names), "max_abs": worst_abs, "max_rel": worst_rel,
            "equal": not bad, "differing": bad[:8]}


def compare_folders(before: Path, after: Path, rtol: float = 0.0, atol: float = 0.0) -> list[dict]:
    """Compare every comparable file found under either folder (paths relative to the folders)."""
    rel = sorted({p.relative_to(before) for p in before.rglob("*") if p.is_file() and _reader(p)}
                 | {p.relative_to(after) for p in after.rglob("*") if p.is_file() and _reader(p)})
    rows = []
    for r in rel:
        a, b = before / r, after / r
        if not a.exists() or not b.exists():
            rows.append({"file": str(r), "variables": 0, "max_abs": math.inf, "max_rel": math.inf, "equal": False,
                         "differing": ["(file missing on one side)"]})
            continue
        row = compare_files(a, b, rtol, atol)
        row["file"] = str(r)
        rows.append(row)
    return rows


def median_shifts(before: Path, after: Path) -> list[dict]:
    """Per summary row (agent, dataset, parameter) of both folders' ``summary.csv``: the shift of the median in units
    of the 90 % interval width, |median_after - median_before| / mean(width_before, width_after), largest first."""
    def rows(folder: Path) -> dict:
        out = {}
        for path in sorted(folder.rglob("summary.csv")):
            with open(path, newline="", encoding="utf-8") as fh:
                for r in csv.DictReader(fh):
                    out[(str(path.parent.relative_to(folder)), r["dataset"], r["parameter"])] = r
        return out

    a, b = rows(before), rows(after)
    shifts = []
    for key in sorted(set(a) & set(b)):
        ra, rb = a[key], b[key]
        try:
            wa, wb = (float(r["q95"]) - float(r["q05"]) for r in (ra, rb))
            shift = abs(float(rb["median"]) - float(ra["median"])) / (0.5 * (wa + wb))
            ratio = wb / wa
        except (ValueError, ZeroDivisionError):
            continue
        if math.isfinite(shift):
            shifts.append({"run": key[0], "dataset": key[1], "parameter": key[2], "shift": shift,
                           "width_ratio": ratio})
    return sorted(shifts, key=lambda r: -r["shift"])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    parser.add_argument("--rtol", type=float, default=0.0, help="relative tolerance (default 0: bit-identical)")
    parser.add_argument("--atol", type=float, default=0.0, help="absolute tolerance (default 0)")
    parser.add_argument("--shifts", type=int, default=0, metavar="K",
                        help="also print the K largest median shifts of summary.csv in 90 %% widths (two runs of "
                             "different settings: how far apart are their posteriors?)")
    args = parser.parse_args(argv)
    for d in (args.before, args.after):
        if not d.is_dir():
            print(f"error: {d} is not a folder", file=sys.stderr)
            return 2
    rows = compare_folders(args.before, args.after, args.rtol, args.atol)
    if not rows:
        print(f"error: no phase, CSV or manifest files under {args.before} or {args.after}", file=sys.stderr)
        return 2
    width = max(len(r["file"]) for r in rows)
    print(f"{'file':<{width}}  {'vars':>5}  {'max |diff|':>11}  {'max rel':>9}  verdict")
    for r in rows:
        verdict = "equal" if r["equal"] else "DIFFERENT: " + ", ".join(r["differing"])
        print(f"{r['file']:<{width}}  {r['variables']:>5}  {r['max_abs']:>11.3g}  {r['max_rel']:>9.3g}  {verdict}")
    if args.shifts:
        shifts = median_shifts(args.before, args.after)
        print(f"\nmedian shifts in 90 % widths (largest {args.shifts} of {len(shifts)}); width ratio after / before")
        for r in shifts[:args.shifts]:
            print(f"  {r['run']:<32} {r['dataset']:<34} {r['parameter']:<14} {r['shift']:6.3f}  "
                  f"{r['width_ratio']:6.3f}")
        if shifts:
            print(json.dumps({"benchmark": "compare_calibrations_shifts", "rows": len(shifts),
                              "max_shift": shifts[0]["shift"],
                              "median_shift": float(np.median([r["shift"] for r in shifts]))}))
    same = all(r["equal"] for r in rows)
    print(json.dumps({"benchmark": "compare_calibrations", "files": len(rows), "equal": same,
                      "max_abs": max(r["max_abs"] for r in rows), "max_rel": max(r["max_rel"] for r in rows),
                      "rtol": args.rtol, "atol": args.atol}))
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
