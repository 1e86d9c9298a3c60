"""Files of one sweep: CSV (one row per k_a), JSON (rows, fit, settings), traces (NPZ) and a PNG."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from bubblecal.data import jsonable
from bubblecal.workflows.acoustic_sweep.fit import fit_sweep
from bubblecal.workflows.acoustic_sweep.sweep import ROW_FIELDS, SweepResult
from bubblecal.workflows.plotting import new_figure, save_figure

__all__ = ["write_sweep_outputs"]


def write_sweep_outputs(result: SweepResult, out_dir: str | Path, fit=None, plot: bool = True) -> dict[str, Path]:
    """Write ``ringdown_<agent>_<d>um.csv`` / ``.json`` / ``.png`` (and ``_traces.npz``) into ``out_dir``.

    Parameters
    ----------
    result : SweepResult
        One diameter's sweep.
    out_dir : str or Path
        Output folder (created).
    fit : bubblecal.surrogates.acoustic.DiameterFit or None
        The quadratic to draw and store (None: :func:`~bubblecal.workflows.acoustic_sweep.fit_sweep` when
        at least 3 rows are valid).
    plot : bool
        Also draw the PNG (R(t) with fits; f_res² against k_a with the quadratic).

    Returns
    -------
    dict of str to Path
        'csv', 'json', 'npz' (and 'png').
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    stem = f"ringdown_{result.agent}_{result.diameter_um:g}um"
    if fit is None and result.valid.sum() >= 3:
        fit = fit_sweep(result)[result.diameter_um]
    paths = {"csv": out / f"{stem}.csv", "json": out / f"{stem}.json", "npz": out / f"{stem}_traces.npz"}
    with open(paths["csv"], "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=list(ROW_FIELDS))
        w.writeheader()
        for r in result.rows:
            w.writerow({k: (f"{v:.10g}" if isinstance(v, float) else v) for k, v in r.items()})
    doc = {"summary": result.summary(), "settings": result.settings, "rows": result.rows,
           "fit": None if fit is None else fit.to_dict(),
           "units": {"ka": "DPD 2-D modulus", "kb": "DPD energy", "f_*_MHz": "MHz (sqrt(mass_factor) applied)",
                     "f_*_dpd": "cycles per DPD time", "lam_dpd": "1 / DPD time", "omega0_check7": "rad / DPD time",
                     "radius_equilibrium": "DPD length", "p_gas": "DPD pressure"},
           "batch_info": [{k: v for k, v in b.items() if k not in ("health_final", "health_after_perturbation")}
                          for b in result.batch_info]}
    paths["json"].write_text(json.dumps(jsonable(doc, nonfinite_as_none=True), indent=1))
    lens = {t.size for t, _ in result.traces}
    if len(lens) == 1 and result.traces:
        np.savez_compressed(paths["npz"], t=result.traces[0][0], radius=np.stack([r for _, r in result.traces]),
                            ka=result.column("ka"))
    else:
        np.savez_compressed(paths["npz"], **{f"t_{i}": t for i, (t, _) in enumerate(result.traces)},
                            **{f"radius_{i}": r for i, (_, r) in enumerate(result.traces)}, ka=result.column("ka"))
    if plot:
        paths["png"] = out / f"{stem}.png"
        _plot(result, fit, paths["png"])
    return paths


def _plot(result: SweepResult, fit, path: Path) -> None:
    """Three R(t) traces with their fits, and f_res² [MHz²] against k_a with the quadratic (PNG, 110 dpi)."""
    fig, (ax1, ax2) = new_figure(1, 2, figsize=(12, 4.5))
    n = len(result.rows)
    picks = sorted({0, n // 2, n - 1}) if n else []
    for i in picks:
        t, r = result.traces[i]
        (line,) = ax1.plot(t, r, ".", ms=2, label=f"k_a = {result.rows[i]['ka']:.0f}")
        f = result.fits[i]
        if f is not None:
            ax1.plot(t, f.predict(t), "-", lw=1, color=line.get_color())
    ax1.set_xlabel("t [DPD time]")
    ax1.set_ylabel("R(t) = (3V/4pi)^(1/3) [DPD length]")
    ax1.set_title(f"{result.agent} {result.diameter_um:g} um, {result.tier}: ringdown + damped-sine fit")
    ax1.legend(fontsize=8)
    ka = result.column("ka")
    f = result.column("f_res_MHz")
    ok = result.valid
    ax2.plot(ka[ok], f[ok] ** 2, "o", label="simulated f_res^2")
    if (~ok).any():
        ax2.plot(ka[~ok], np.where(np.isfinite(f[~ok]), f[~ok] ** 2, np.nan), "x", color="grey", label="invalid")
    if fit is not None:
        kk = np.linspace(ka.min(), ka.max(), 200)
        ax2.plot(kk, fit.a0 + fit.a1 * kk + fit.a2 * kk**2, "-",
                 label=f"quadratic (LOO median {100 * fit.loo_median:.2f} %)")
    ax2.set_xlabel("k_a [DPD]")
    ax2.set_ylabel("f_res^2 [MHz^2]")
    ax2.set_title(f"mass factor {result.mass_factor:g} (undone: f x sqrt(M))")
    ax2.legend(fontsize=8)
    save_figure(fig, path, dpi=110)

