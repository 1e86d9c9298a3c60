"""The acoustic law continuous in the diameter (bubblecal.surrogates.fit_law) beside the classical shelled bubble.

    python benchmarks/studies/resonance_law.py [--rows A_rows.csv ...] [--old B_rows.csv ...]

Default: the 1.5-8 um ringdown rows of both agents (data/training/*_ringdown_1.5-8um_rows.csv) as the fit set and
the earlier rows (data/training/{definity,sonovue}_ringdown_rows.csv) as an independent campaign.  Prints

1. every candidate form of bubblecal.surrogates.LAW_FORMS: in-sample and leave-diameters-out relative errors of
   f_res (each diameter left out; the 3.5-4.5 um band left out);
2. the chosen form (DEFAULT_LAW_FORM) per left-out diameter, and without the softest k_a (SonoVue 617 DPD);
3. the law against the earlier campaign's rows: inside its diameter range (cross-check) and beyond (8.67-11.2 um);
4. law vs classical f0 (bubblecal.surrogates.classical_f0) at 2 / 4 / 8 um for three k_a, d ln f / d ln D of both
   and of the published observations (bubblecal.data.acoustic_observations), and the k_a the law reads from each
   observed bubble inside its range (a size trend there is what a calibration carried across sizes would absorb);

then one JSON line.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from bubblecal.data import DEFAULT_UNITS, acoustic_observations
from bubblecal.surrogates import (
    DEFAULT_LAW_FORM,
    AcousticLawSurrogate,
    classical_f0,
    compare_forms,
    diameter_exponent,
    fit_law,
)
from bubblecal.surrogates.law_fit import holdout_errors
from bubblecal.workflows.acoustic_sweep import law_rows, sweeps_from_rows_csv

ROOT = Path(__file__).resolve().parents[2]
TRAINING = ROOT / "data" / "training"
KA_REF = (5_000.0, 15_000.0, 30_000.0)
D_REF = (2.0, 4.0, 8.0)


def _pct(x) -> str:
    return f"{100 * x:6.2f}"


def rows_of(path: Path):
    """(agent, diameter_um, ka, f_res_MHz) of a rows CSV (valid rows)."""
    sweeps = sweeps_from_rows_csv(path)
    return (sweeps[0].agent, *law_rows(sweeps))


def ka_from_frequency(sur: AcousticLawSurrogate, f_obs: float, d: float):
    """The k_a [DPD] at which the law gives f_obs at diameter d (None outside the law's k_a range or f range)."""
    lo, hi = sur.ka_ranges(d)
    ka = np.linspace(lo, hi, 4001)
    f = np.asarray(sur.f_res(ka, d))
    if not (np.all(np.diff(f) > 0) and f[0] <= f_obs <= f[-1]):
        return None
    return float(np.interp(f_obs, f, ka))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rows", nargs="*", default=[str(p) for p in sorted(TRAINING.glob("*_ringdown_1.5-8um_rows.csv"))])
    ap.add_argument("--old", nargs="*", default=[str(TRAINING / f"{a}_ringdown_rows.csv") for a in ("definity",
                                                                                                      "sonovue")])
    args = ap.parse_args()
    out: dict = {"benchmark": "resonance_law", "form": DEFAULT_LAW_FORM, "agents": {}}
    old = {a: (d, k, f) for a, d, k, f in (rows_of(Path(p)) for p in args.old if Path(p).exists())}
    for path in args.rows:
        agent, d, ka, f = rows_of(Path(path))
        res: dict = {"rows": Path(path).name, "n": int(d.size), "diameters": [float(d.min()), float(d.max())]}
        print(f"\n== {agent}: {d.size} rows, {np.unique(d).size} diameters {d.min():g}-{d.max():g} um ==")
        print(f"{'form':22s} {'n_c':>3s} {'in-sample med [max] %':>22s} {'LDO med [max] %':>19s} "
              f"{'band 3.5-4.5 med [max] %':>25s}")
        forms = compare_forms(d, ka, f)
        for name, v in forms.items():
            b = v["bands"][0]
            ins = v["in_sample"]
            print(f"{name:22s} {v['n_coefficients']:3d} {_pct(ins['median'])} [{_pct(ins['max'])}]"
                  f"      {_pct(v['ldo_median'])} [{_pct(v['ldo_max'])}]     {_pct(b['median'])} [{_pct(b['max'])}]")
        res["forms"] = forms
        law = fit_law(d, ka, f, DEFAULT_LAW_FORM)
        sur = AcousticLawSurrogate(law, name=agent)
        res["coefficients"] = list(law.coefficients)
        per_d = law.holdout["per_diameter"]
        print(f"{DEFAULT_LAW_FORM}, each diameter left out: " + ", ".join(
            f"{p['diameter_um']:g}: {100 * p['median']:.2f} [{100 * p['max']:.2f}]" for p in per_d))
        stiff = ka > 1000.0
        e = np.concatenate([holdout_errors(d, ka, f, d == v)[stiff[d == v]] for v in np.unique(d)])
        res["ldo_ka_above_1000"] = {"median": float(np.median(e)), "max": float(e.max())}
        print(f"  same, errors at ka > 1,000 DPD only: median {100 * np.median(e):.2f} % max {100 * e.max():.2f} %")
        if agent in old:
            do, ko, fo = old[agent]
            err = np.abs(law_predict_any(sur, ko, do) / fo - 1)
            inside = do <= d.max()
            res["old_rows"] = {"inside": {"diameters": np.unique(do[inside]).tolist(),
                                          "median": float(np.median(err[inside])), "max": float(err[inside].max())}}
            print(f"  earlier campaign inside {do[inside].min():g}-{do[inside].max():g} um ({inside.sum()} rows): "
                  f"median {100 * np.median(err[inside]):.2f} % max {100 * err[inside].max():.2f} %")
            if (~inside).any():
                per = {float(v): (float(np.median(err[do == v])), float(err[do == v].max())) for v in
                       np.unique(do[~inside])}
                res["old_rows"]["extrapolated"] = {f"{k:g}": list(v) for k, v in per.items()}
                print("  extrapolated to the earlier campaign's larger bubbles: " + ", ".join(
                    f"{k:g} um {100 * m:.2f} [{100 * x:.2f}] %" for k, (m, x) in per.items()))
        dd = np.linspace(2.0, 8.0, 25)
        comp = []
        print(f"{'ka [DPD]':>9s} {'chi [N/m]':>9s} {'law f(2/4/8 um) MHz':>24s} {'exp.':>6s} "
              f"{'classical f0(2/4/8 um)':>24s} {'exp.':>6s}")
        for k in KA_REF:
            fl, fc = np.asarray(sur.f_res(k, dd)), classical_f0(k, dd)
            row = {"ka": k, "chi_N_per_m": float(DEFAULT_UNITS.modulus2d_to_physical(k)),
                   "law_MHz": [float(sur.f_res(k, x)) for x in D_REF], "law_exponent": diameter_exponent(dd, fl),
                   "classical_MHz": [float(classical_f0(k, x)) for x in D_REF],
                   "classical_exponent": diameter_exponent(dd, fc)}
            comp.append(row)
            print(f"{k:9.0f} {row['chi_N_per_m']:9.3f} {' / '.join(f'{v:.2f}' for v in row['law_MHz']):>24s} "
                  f"{row['law_exponent']:6.2f} {' / '.join(f'{v:.2f}' for v in row['classical_MHz']):>24s} "
                  f"{row['classical_exponent']:6.2f}")
        res["comparison"] = comp
        obs = acoustic_observations(agent)
        d_o = np.array([o.diameter_um for o in obs])
        f_o = np.array([o.frequency_MHz for o in obs])
        res["observed_exponent"] = {"n": len(obs), "exponent": diameter_exponent(d_o, f_o)}
        lo, hi = law.diameter_range
        ka_hat = [(float(x), ka_from_frequency(sur, float(y), float(x))) for x, y in zip(d_o, f_o, strict=True)
                  if lo <= x <= hi]
        ok = [(x, k) for x, k in ka_hat if k is not None]
        res["ka_read_from_observations"] = ka_hat
        trend = diameter_exponent([x for x, _ in ok], [k for _, k in ok]) if len({x for x, _ in ok}) > 1 else None
        res["ka_read_exponent"] = trend
        print(f"published observations: d ln f / d ln D = {res['observed_exponent']['exponent']:.2f} ({len(obs)} "
              f"bubbles); k_a the law reads from each bubble in {lo:g}-{hi:g} um: " +
              ", ".join(f"{x:g} um {k:.0f}" if k is not None else f"{x:g} um -" for x, k in ka_hat) +
              (f" (d ln k_a / d ln D = {trend:.2f})" if trend is not None else ""))
        out["agents"][agent] = res
    print(json.dumps(out))


def law_predict_any(sur: AcousticLawSurrogate, ka, d) -> np.ndarray:
    """The law's f_res [MHz] at any diameter, extrapolating beyond its range (the study only)."""
    return np.sqrt(np.maximum(np.asarray(sur.law.f_res_squared(ka, d)), 0.0))


if __name__ == "__main__":
    main()
