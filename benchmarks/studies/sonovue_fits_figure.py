"""The figure of ``sonovue_fits.py``: one PNG per bubble diameter, one column per calibration run.

Top: force [nN] against depth [nm] with the data, the 90 % posterior-predictive band and its median, the surrogate
and the quasi-static simulation at the phase-3 MAP, and the simulation at the posterior draws.  Bottom: the residuals
along the curve, data − predictive median and surrogate − simulation at the MAP [nm].  Imported by the study
script; ``draw(rows, folder)`` returns the written paths (``folder/sonovue_fits_<D>um.png``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _key(row) -> str:
    """The bubble size of a row as in the file name (the published diameter, one decimal)."""
    return f"{round(row['diameter_um'], 1):.1f}"


def draw(rows: list[dict], folder: Path) -> list[Path]:
    """Write one figure per bubble diameter (module docstring); returns the paths."""
    from bubblecal.workflows.plotting import new_figure, save_figure

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for key in dict.fromkeys(_key(r) for r in rows):
        group = [r for r in rows if _key(r) == key]
        fig, axes = new_figure(2, len(group), figsize=(4.2 * len(group), 5.6), squeeze=False,
                               gridspec_kw={"height_ratios": [2.2, 1.0]})
        for j, r in enumerate(group):
            a = r["_arrays"]
            f = a["force_nN"]
            ax = axes[0][j]
            ax.fill_betweenx(f, a["lower_nm"], a["upper_nm"], color="#9ecae1", alpha=0.6, lw=0,
                             label="90 % predictive band")
            ax.plot(a["median_nm"], f, color="#08519c", lw=1.2, label="predictive median")
            qs = a.get("qs_nm", np.full((1, f.size), np.nan))
            for i in range(1, qs.shape[0]):
                ax.plot(qs[i], f, color="#d1495b", lw=0.6, alpha=0.35,
                        label="QS at posterior draws" if i == 1 else None)
            ax.plot(a["surrogate_nm"][0], f, "--", color="k", lw=1.0, label="surrogate at MAP")
            ax.plot(qs[0], f, "s", color="#d1495b", ms=2.5, label="QS at MAP (mirheo)")
            if "qs_v1_nm" in a:
                ax.plot(a["qs_v1_nm"], f, "x", color="#6a3d9a", ms=3, label="QS at MAP (bubblecal-v1)")
            ax.plot(a["data_nm"], f, "o", ms=3.2, mfc="white", mec="k", label="AFM data")
            ax.set_title(f"{r['label']}: {r['curve']}\nCRPS {r['crps_nm']:.2f} nm, sigma {r['noise_median']:.3f}",
                         fontsize=8)
            ax.set_xlabel("depth [nm]")
            ax.set_ylabel("force [nN]")
            ax.legend(fontsize=6, loc="upper left")
            bx = axes[1][j]
            bx.axhline(0.0, color="0.6", lw=0.6)
            bx.plot(a["data_nm"], a["data_nm"] - a["median_nm"], "o-", ms=2.5, lw=0.8, color="#08519c",
                    label="data − predictive median")
            bx.plot(a["data_nm"], a["surrogate_nm"][0] - qs[0], "s-", ms=2.5, lw=0.8, color="#d1495b",
                    label="surrogate − QS at MAP")
            bx.plot(a["data_nm"], a["data_nm"] - qs[0], ".:", ms=2.5, lw=0.8, color="0.3",
                    label="data − QS at MAP")
            bx.set_xlabel("data depth [nm]")
            bx.set_ylabel("residual [nm]")
            bx.legend(fontsize=6)
            lim = np.nanmax(np.abs([a["data_nm"] - a["median_nm"], a["surrogate_nm"][0] - qs[0]]))
            bx.set_ylim(-1.25 * lim, 1.25 * lim)
        paths.append(save_figure(fig, folder / f"sonovue_fits_{key}um.png", dpi=90))
    return paths
