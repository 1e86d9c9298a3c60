"""The published study through the measured-bubbles path: ``calibrate --data`` on the tidy files vs ``calibrate``.

    python benchmarks/published_via_data.py --root OUT [calibrate args, e.g. --population 2000]

Runs ``bubblecal calibrate --surrogates per-diameter`` (the published study on its per-diameter surrogates,
Definity's acoustic rows as one dataset)
and ``bubblecal calibrate --data data/reference/published_curves.csv --acoustic data/reference/published_resonance.csv``
(the same curves as measured bubbles: networks over the diameter, one acoustic dataset per resonance row) with the
same seed and settings, then compares per bubble the phase-3 MAP and posterior mean of k_a (matched by agent and
the nearest diameter within 0.1 um: the published path names SonoVue's bubbles by their nominal diameter). The
criterion: every MAP k_a within 10 % of the published path's. Prints a table and one JSON
line ``{"benchmark": "published_via_data", ...}``; exit status 1 when a bubble misses the criterion.
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CURVES = REPO / "data" / "reference" / "published_curves.csv"
RESONANCE = REPO / "data" / "reference" / "published_resonance.csv"
#: Largest relative gap of a bubble's MAP k_a between the two paths.
MAP_RTOL = 0.10


def ka_rows(summary: Path) -> dict[tuple[str, float], dict]:
    """(agent, diameter rounded to 0.01 um) -> the k_a row of every loading curve in ``summary.csv``."""
    out = {}
    with summary.open(newline="") as fh:
        for row in csv.DictReader(fh):
            if row["parameter"] == "ka" and row["kind"] in ("compression", "indentation"):
                out[(row["agent"], round(float(row["diameter_um"]), 2))] = row
    return out


def compare(published: dict, via_data: dict, rtol: float = MAP_RTOL) -> list[dict]:
    """One row per bubble of ``published``: MAP and mean of k_a on both paths, the relative MAP gap and the verdict.

    Parameters
    ----------
    published, via_data : dict
        :func:`ka_rows` of the two runs.
    rtol : float
        Largest accepted relative MAP gap.

    Returns
    -------
    list of dict

    Raises
    ------
    SystemExit
        If a published bubble has no counterpart in the other run.
    """
    rows = []
    for key, pub in sorted(published.items()):
        near = [k for k in via_data if k[0] == key[0] and abs(k[1] - key[1]) <= 0.1]
        if not near:
            raise SystemExit(f"no bubble of {key[0]} at {key[1]} um in the --data run (has {sorted(via_data)})")
        dat = via_data[min(near, key=lambda k: abs(k[1] - key[1]))]
        gap = float(dat["map"]) / float(pub["map"]) - 1.0
        rows.append({"agent": key[0], "diameter_um": key[1], "map_published": float(pub["map"]),
                     "map_data": float(dat["map"]), "mean_published": float(pub["mean"]),
                     "mean_data": float(dat["mean"]), "map_gap": round(gap, 4), "pass": abs(gap) <= rtol})
    return rows


def _run(args: list[str], out: Path) -> Path:
    cmd = [sys.executable, "-m", "bubblecal.workflows.cli", "calibrate", *args, "--out", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    out.mkdir(parents=True, exist_ok=True)
    (out / "stdout.txt").write_text(proc.stdout)
    (out / "stderr.txt").write_text(proc.stderr)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} exited with {proc.returncode}:\n{proc.stderr[-3000:]}")
    return out


def main(argv=None) -> list[dict]:
    """Run both paths, print the table and the JSON line; returns the rows."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--root", type=Path, required=True, help="folder of the two runs")
    args, extra = ap.parse_known_args(argv)
    pub = _run(["--surrogates", "per-diameter", *extra], args.root / "published")
    dat = _run(["--data", str(CURVES), "--acoustic", str(RESONANCE), *extra], args.root / "via_data")
    published = {}
    for summary in sorted(pub.glob("*/*/summary.csv")):
        published.update(ka_rows(summary))
    via_data = {}
    for summary in sorted(dat.glob("*/*/summary.csv")):
        via_data.update(ka_rows(summary))
    rows = compare(published, via_data)
    print(f"{'agent':>9} {'D [um]':>7} {'MAP pub':>10} {'MAP data':>10} {'gap':>7} {'mean pub':>10} {'mean data':>10}")
    for r in rows:
        print(f"{r['agent']:>9} {r['diameter_um']:>7} {r['map_published']:>10.0f} {r['map_data']:>10.0f} "
              f"{r['map_gap']:>+7.1%} {r['mean_published']:>10.0f} {r['mean_data']:>10.0f}"
              + ("" if r["pass"] else "  MISS"))
    ok = all(r["pass"] for r in rows)
    print(json.dumps({"benchmark": "published_via_data", "calibrate_args": extra, "map_rtol": MAP_RTOL,
                      "rows": rows, "pass": ok}))
    if not ok:
        raise SystemExit(1)
    return rows


if __name__ == "__main__":
    main()
