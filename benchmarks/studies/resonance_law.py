"""A resonance law continuous in the diameter, from the ringdown rows, beside the classical shelled-bubble model.

    python benchmarks/studies/resonance_law.py [ROWS.csv ...]    (default: data/training/*_ringdown_rows.csv)

Fits, per agent and jointly, the linear least-squares law

    f_res^2 D^2 = a0 + a1 D + (b0 + b1 D) ka + c ka^2          (f_res [MHz], D [um], ka [DPD])

suggested by the implicit tier's breathing mode (the shell's own inertia, mass proportional to its area: f^2 ~
ka / D^2 plus a gas term), and scores it by leaving one diameter out at a time (relative error of f_res at the
left-out diameter).  Beside it, the classical linear shelled-bubble resonance (de Jong / Marmottant elastic regime,
liquid inertia): f0 = 1 / (2 pi R) sqrt((3 kappa p0 + 4 chi / R) / rho), chi = ka in N/m (the 2-D area modulus,
``bubblecal.data.units``), kappa = 1, p0 = 101.325 kPa, rho = 998 kg/m^3, and the published acoustic observations'
diameter exponent.  Prints tables and a JSON line.
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import numpy as np

from bubblecal.data import DEFAULT_UNITS

ROOT = Path(__file__).resolve().parents[2]
P0, RHO, KAPPA = 101_325.0, 998.0, 1.0


def read_rows(path: Path) -> dict:
    """diameter_um, ka, f_res_MHz of the fitted ('ok') rows of one ringdown table."""
    rows = [r for r in csv.DictReader(open(path)) if r["status"] == "ok" and r["fit_success"] == "True"]
    return {k: np.array([float(r[k]) for r in rows]) for k in ("diameter_um", "ka", "f_res_MHz")}


def design(d: np.ndarray, ka: np.ndarray) -> np.ndarray:
    """Columns of the law: 1, D, ka, D ka, ka^2."""
    return np.stack([np.ones_like(d), d, ka, d * ka, ka**2], axis=1)


def fit(d, ka, f) -> np.ndarray:
    """Least-squares coefficients of f^2 D^2 on :func:`design`."""
    return np.linalg.lstsq(design(d, ka), f**2 * d**2, rcond=None)[0]


def predict(c, d, ka) -> np.ndarray:
    """f_res [MHz] of the law (NaN where f^2 <= 0)."""
    f2 = design(d, ka) @ c / d**2
    return np.sqrt(np.where(f2 > 0, f2, np.nan))


def leave_diameters_out(d, ka, f) -> dict:
    """Relative error of f_res at each left-out diameter (the law fitted to the others)."""
    errs = {}
    for dia in np.unique(d):
        m = d == dia
        c = fit(d[~m], ka[~m], f[~m])
        errs[float(dia)] = np.abs(predict(c, d[m], ka[m]) / f[m] - 1)
    return errs


def classical_f0(ka_dpd, d_um) -> np.ndarray:
    """Linear shelled-bubble resonance [MHz] with chi = ka [N/m] and water inertia."""
    chi = DEFAULT_UNITS.modulus2d_to_physical(ka_dpd)
    r = np.asarray(d_um) * 0.5e-6
    return np.sqrt((3 * KAPPA * P0 + 4 * chi / r) / RHO) / (2 * np.pi * r) / 1e6


def slope_log(d, f) -> float:
    """d ln f / d ln D of a least-squares line."""
    return float(np.polyfit(np.log(d), np.log(f), 1)[0])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rows", nargs="*", default=[str(p) for p in sorted((ROOT / "data" / "training").glob(
        "*_ringdown_rows.csv"))])
    args = ap.parse_args()
    sets = {Path(p).name.split("_")[0]: read_rows(Path(p)) for p in args.rows}
    sets["joint"] = {k: np.concatenate([s[k] for s in list(sets.values())]) for k in ("diameter_um", "ka", "f_res_MHz")}
    out = {}
    print(f"{'rows':10s} {'n':>5s} {'D [um]':>12s} {'in-sample':>18s} {'leave-one-diameter-out':>28s}")
    for name, s in sets.items():
        d, ka, f = s["diameter_um"], s["ka"], s["f_res_MHz"]
        c = fit(d, ka, f)
        ins = np.abs(predict(c, d, ka) / f - 1)
        ldo = leave_diameters_out(d, ka, f) if np.unique(d).size > 2 else {}
        all_ldo = np.concatenate(list(ldo.values())) if ldo else np.array([np.nan])
        out[name] = {"coefficients": c.tolist(), "n": int(d.size), "diameters": np.unique(d).tolist(),
                     "in_sample_median": float(np.median(ins)), "in_sample_max": float(np.max(ins)),
                     "ldo_median": float(np.nanmedian(all_ldo)), "ldo_max": float(np.nanmax(all_ldo)),
                     "ldo_worst_diameter": max(ldo, key=lambda k: np.nanmax(ldo[k])) if ldo else None}
        o = out[name]
        print(f"{name:10s} {d.size:5d} {d.min():5.2f}-{d.max():5.2f} {100 * o['in_sample_median']:7.2f} "
              f"[{100 * o['in_sample_max']:5.2f}] % {100 * o['ldo_median']:12.2f} [{100 * o['ldo_max']:5.2f}] % "
              f"(worst at {o['ldo_worst_diameter']})")
    # the diameter dependence at fixed ka: DPD law, classical model, published observations
    ka_ref = np.array([5_000.0, 15_000.0, 30_000.0])
    dd = np.linspace(2.0, 8.0, 13)
    c = np.array(out["joint"]["coefficients"])
    print(f"\n{'ka [DPD]':>9s} {'chi [N/m]':>9s} {'DPD law: f(2 / 4 / 8 um) MHz':>32s} {'exp.':>6s} "
          f"{'classical f0(2 / 4 / 8 um)':>30s} {'exp.':>6s}")
    comp = []
    for k in ka_ref:
        fl, fc = predict(c, dd, np.full_like(dd, k)), classical_f0(k, dd)
        row = {"ka": float(k), "chi_N_per_m": float(DEFAULT_UNITS.modulus2d_to_physical(k)),
               "law_MHz": [float(fl[i]) for i in (0, 4, 12)], "law_exponent": slope_log(dd, fl),
               "classical_MHz": [float(fc[i]) for i in (0, 4, 12)], "classical_exponent": slope_log(dd, fc)}
        comp.append(row)
        print(f"{k:9.0f} {row['chi_N_per_m']:9.3f} {' / '.join(f'{v:.2f}' for v in row['law_MHz']):>32s} "
              f"{row['law_exponent']:6.2f} {' / '.join(f'{v:.2f}' for v in row['classical_MHz']):>30s} "
              f"{row['classical_exponent']:6.2f}")
    obs = ROOT.parent / "shared" / "reference" / "acoustic_observations_published.csv"
    observed = {}
    if obs.exists():
        rows = list(csv.DictReader(open(obs)))
        for agent in sorted({r["agent"] for r in rows}):
            sel = [r for r in rows if r["agent"] == agent]
            dd_o = np.array([float(r["diameter_um"]) for r in sel])
            ff_o = np.array([float(r["resonance_frequency_MHz"]) for r in sel])
            observed[agent] = {"n": len(sel), "exponent": slope_log(dd_o, ff_o)}
        print("published observations, d ln f / d ln D: " +
              ", ".join(f"{a} {v['exponent']:.2f} ({v['n']} bubbles)" for a, v in observed.items()))
    print(json.dumps({"benchmark": "resonance_law", "laws": out, "comparison": comp, "observed": observed}))


if __name__ == "__main__":
    main()
