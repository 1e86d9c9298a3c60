"""The outcome of an architecture sweep and its report: table, JSON, the median held-out curve.

:class:`SweepResult` holds one row per architecture (grouped holdout and, for a network over the diameter, the
leave-diameters-out scores), the selected model and both sides of the split; :meth:`SweepResult.write_report`
writes ``sweep_report.md``, ``sweep_report.json`` and ``heldout_curve.png``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from bubblecal.surrogates.axes import X_INFO, Y_INFO
from bubblecal.surrogates.features import network_inputs, response_scale
from bubblecal.surrogates.training.dataset import TrainingSet
from bubblecal.surrogates.training.holdout import FAST_MEDIAN_FACTOR, FAST_P90_FACTOR, MIN_SCORED_POINTS, fast_choice
from bubblecal.surrogates.training.train import TrainedMLP

if TYPE_CHECKING:
    from bubblecal.surrogates.training.sweep import SweepConfig

__all__ = ["SweepResult"]


def _truncated(ts: TrainingSet) -> np.ndarray:
    """(n,) True for curves with a non-finite point (failure-truncated prefixes)."""
    return ~np.all(ts.point_mask(), axis=1)


def _nan_to_none(values) -> list:
    """Floats with non-finite values as None (strict JSON)."""
    return [None if not np.isfinite(v) else float(v) for v in np.asarray(values, dtype=float)]



@dataclass
class SweepResult:
    """Outcome of :func:`run_sweep`: one row per architecture and the selected model.

    Parameters
    ----------
    rows : list of dict
        Per architecture: ``hidden``, ``width``, ``depth``, ``n_params``, the :func:`error_summary` fields,
        ``best_val_loss``, ``epochs``, ``stop_reason``, ``wall_s``, ``device``.
    best_index : int
        Index of the selected architecture.
    best_model : TrainedMLP
        The selected model.
    train_set, holdout_set : TrainingSet
        The two sides of the grouped split.
    holdout_errors : numpy.ndarray, shape (n_holdout,)
        Per-curve errors of the selected model.
    holdout_pred : numpy.ndarray, shape (n_holdout, m)
        Its predictions on the held-out curves.
    config : SweepConfig
        The settings.
    data_hash : str
        Hash of the whole (filtered) data set.
    wall_s : float
        Sweep wall time [s].
    models : list of TrainedMLP
        Every trained architecture, in row order.
    ldo_set : TrainingSet or None
        The curves of the held-out diameter bands (a network over the diameter with ``ldo_bands``).
    ldo_errors : numpy.ndarray or None
        Per-curve errors of the selected model on them.
    offgrid_set : TrainingSet or None
        Curves at loading points off the training grid that took part in the selection.
    """

    rows: list[dict]
    best_index: int
    best_model: TrainedMLP
    train_set: TrainingSet
    holdout_set: TrainingSet
    holdout_errors: np.ndarray
    holdout_pred: np.ndarray
    config: SweepConfig
    data_hash: str
    wall_s: float
    models: list[TrainedMLP] = field(default_factory=list)
    ldo_set: TrainingSet | None = None
    ldo_errors: np.ndarray | None = None
    offgrid_set: TrainingSet | None = None

    @property
    def best(self) -> dict:
        """The selected row."""
        return self.rows[self.best_index]

    @property
    def fast_index(self) -> int | None:
        """Index of the fast twin of the selection (:func:`~bubblecal.surrogates.training.fast_choice`), or None."""
        return fast_choice(self.rows, self.best_index)

    @property
    def score(self) -> float:
        """Held-out median relative L2 error of the selected model."""
        return float(self.best["holdout_median"])

    @property
    def inputs(self) -> str:
        """The networks' input kind (``'raw'`` or ``'diameter'``)."""
        return self.config.inputs

    def predict(self, ts: TrainingSet, i: int, x: np.ndarray) -> np.ndarray:
        """The selected model's response along ``x`` for curve ``i`` of ``ts`` (its parameters and size).

        Parameters
        ----------
        ts : TrainingSet
            The curves.
        i : int
            Curve index.
        x : numpy.ndarray, shape (k,)
            Loading coordinate [DPD length or DPD force].

        Returns
        -------
        numpy.ndarray, shape (k,)
            Response [DPD force or DPD length].
        """
        p = np.repeat(ts.params[i:i + 1], x.size, axis=0)
        d = np.full(x.size, ts.diameters_um[i]) if self.inputs == "diameter" else None
        u = network_inputs(self.inputs, p, x, d, log_inputs=self.config.log_inputs)
        return self.best_model.predict(u) * response_scale(self.inputs, ts.setup, p, d)

    def as_dict(self) -> dict:
        """Everything as plain JSON (``sweep_report.json``)."""
        return {
            "selected": self.best, "fast": None if self.fast_index is None else self.rows[self.fast_index],
            "rows": self.rows, "config": self.config.as_dict(),
            "data_hash": self.data_hash, "setup": self.train_set.setup,
            "diameter_um": self.train_set.diameter_um, "source": self.train_set.source,
            "n_curves_train": self.train_set.n_curves, "n_curves_holdout": self.holdout_set.n_curves,
            "n_points_train": self.train_set.n_valid_points, "n_points_holdout": self.holdout_set.n_valid_points,
            "truncation_train": self.train_set.truncation_summary(),
            "truncation_holdout": self.holdout_set.truncation_summary(),
            "holdout_curve_ids": self.holdout_set.curve_id.tolist(),
            "holdout_errors_selected": _nan_to_none(self.holdout_errors), "wall_s": self.wall_s,
            "inputs": self.inputs, "log_inputs": list(self.config.log_inputs),
            **({} if self.ldo_set is None else {
                "n_curves_ldo": self.ldo_set.n_curves, "ldo_bands_um": [list(b) for b in self.config.ldo_bands],
                "ldo_errors_selected": _nan_to_none(self.ldo_errors)}),
            **({} if self.offgrid_set is None else {
                "n_curves_offgrid": self.offgrid_set.n_curves, "offgrid_source": self.offgrid_set.source}),
            "metric": "median over held-out curves of ||y_hat - y||_2 / ||y||_2 (finite points; curves with < "
                      f"{MIN_SCORED_POINTS} finite points skipped)",
        }

    def markdown(self) -> str:
        """The report table (``sweep_report.md``)."""
        ts = self.train_set
        d = ts.diameters_um
        size = (f"{d.min():g}-{d.max():g} um (one network over the diameter)" if self.inputs == "diameter"
                else f"{ts.diameter_um:g} um")
        ldo = self.ldo_set is not None
        lines = [
            f"# Surrogate architecture sweep: {ts.setup}, {size}",
            "",
            f"- data: `{ts.source}` (sha256 {self.data_hash[:16]}...), {ts.n_curves} training curves, "
            f"{self.holdout_set.n_curves} held-out curves (grouped holdout, seed {self.config.seed}, "
            f"fraction {self.config.holdout_frac})",
            f"- points: {ts.n_valid_points} training, {self.holdout_set.n_valid_points} held out; failure-truncated "
            f"prefix curves (NaN tails): {int(_truncated(ts).sum())} training, "
            f"{int(_truncated(self.holdout_set).sum())} held out",
            "- score: median over held-out curves of ||y_hat - y||_2 / ||y||_2 (per curve, over its finite points; "
            f"{self.best.get('holdout_n_skipped', 0)} curve(s) with < {MIN_SCORED_POINTS} finite points skipped)",
            f"- sweep wall time: {self.wall_s:.1f} s ({self.config.jobs} job(s), "
            f"{self.config.train.threads} torch thread(s) each); training time summed over architectures "
            f"{sum(r['wall_s'] for r in self.rows):.0f} s on "
            f"{', '.join(sorted({r.get('device', 'cpu') for r in self.rows}))}",
        ]
        if self.config.log_inputs:
            lines.append(f"- inputs: {', '.join(self.config.log_inputs)} as natural logarithms")
        if ldo:
            bands = ", ".join(f"{lo:g}-{hi:g}" for lo, hi in self.config.ldo_bands)
            lines.append(f"- leave-diameters-out: {self.ldo_set.n_curves} curves in the bands {bands} um never "
                         "trained on; the selection takes the worse of the two medians")
        og = self.offgrid_set is not None
        if og:
            lines.append(f"- off the grid: {self.offgrid_set.n_curves} curves at loading points between the training "
                         f"grid's ({self.offgrid_set.source}); the selection takes the worst of the medians")
        ldo_head, ldo_rule = (" LDO median | LDO p90 |", "---|---|") if ldo else ("", "")
        if og:
            ldo_head, ldo_rule = ldo_head + " off-grid median | off-grid p90 |", ldo_rule + "---|---|"
        lines += ["", f"| hidden | params | holdout median | holdout p90 |{ldo_head} best val MSE (std.) | epochs | "
                      "stop | wall s |",
                  f"|---|---|---|---|{ldo_rule}---|---|---|---|"]
        for i, r in enumerate(self.rows):
            mark = " **(selected)**" if i == self.best_index else ""
            ldo_cells = f" {r['ldo_median']:.4%} | {r['ldo_p90']:.4%} |" if ldo else ""
            if og:
                ldo_cells += f" {r['offgrid_median']:.4%} | {r['offgrid_p90']:.4%} |"
            lines.append(f"| {r['width']}x{r['depth']}{mark} | {r['n_params']} | {r['holdout_median']:.4%} | "
                         f"{r['holdout_p90']:.4%} |{ldo_cells} {r['best_val_loss']:.3g} | {r['epochs']} | "
                         f"{r['stop_reason']} | {r['wall_s']:.1f} |")
        b = self.best
        lines += ["", f"Selected: {b['width']}x{b['depth']} with held-out median relative L2 "
                      f"{b['holdout_median']:.4%}" + (f", leave-diameters-out {b['ldo_median']:.4%}" if ldo else "")
                  + (f", off the grid {b['offgrid_median']:.4%}." if og else ".")]
        fast = self.fast_index
        if fast is not None:
            f = self.rows[fast]
            lines.append(f"Fast twin: {f['width']}x{f['depth']} (the smallest architecture within "
                         f"{FAST_MEDIAN_FACTOR:g}x the selection's worst median and {FAST_P90_FACTOR:g}x its held-out "
                         f"p90; export it with --widths {f['width']} --depths {f['depth']}).")
        if b.get("holdout_n_prefix"):
            lines.append(f"Held-out failure-truncated prefix curves: {b['holdout_n_prefix']}, median relative L2 "
                         f"{b['holdout_median_prefix']:.4%}.")
        lines.append("")
        return "\n".join(lines)

    def plot(self, path: str | Path) -> Path:
        """Plot the held-out curve nearest the median error, plus the error histogram.

        Parameters
        ----------
        path : str or Path
            Output image (``heldout_curve.png`` in a report).

        Returns
        -------
        Path
            ``path``.
        """
        from matplotlib.figure import Figure  # no pyplot: the caller's backend stays theirs

        ts = self.holdout_set
        errs = self.holdout_errors
        scored = np.isfinite(errs)
        i = int(np.nanargmin(np.where(scored, np.abs(errs - np.median(errs[scored])), np.nan)))
        xv = ts.x[i][ts.point_mask()[i]]
        xs = np.linspace(xv.min(), xv.max(), 200)
        fig = Figure(figsize=(10, 4))
        ax1, ax2 = fig.subplots(1, 2)
        ax1.plot(ts.x[i], ts.y[i], "o", label="held-out data")
        ax1.plot(xs, self.predict(ts, i, xs), "-", label="surrogate")
        ax1.set_xlabel(f"{X_INFO[ts.setup][0]} [{X_INFO[ts.setup][1]}]")
        ax1.set_ylabel(f"{Y_INFO[ts.setup][0]} [{Y_INFO[ts.setup][1]}]")
        ax1.set_title(f"{ts.curve_id[i]}: rel. L2 {self.holdout_errors[i]:.3%}", fontsize=9)
        ax1.legend()
        ax2.hist(errs[scored] * 100, bins=min(30, max(5, int(scored.sum()) // 3)))
        ax2.axvline(np.median(errs[scored]) * 100, color="k", ls="--", label="median")
        ax2.set_xlabel("per-curve relative L2 error [%]")
        ax2.set_ylabel("held-out curves")
        ax2.legend()
        b = self.best
        fig.suptitle(f"{ts.setup} {ts.diameters_um[i]:g} um, selected {b['width']}x{b['depth']}")
        fig.tight_layout()
        path = Path(path)
        fig.savefig(path, dpi=110)
        return path

    def write_report(self, out_dir: str | Path) -> dict[str, Path]:
        """Write ``sweep_report.md``, ``sweep_report.json`` and ``heldout_curve.png`` into ``out_dir``.

        Parameters
        ----------
        out_dir : str or Path
            Report folder (created when missing).

        Returns
        -------
        dict of str to Path
            The files, keyed ``markdown``, ``json``, ``plot``.
        """
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        paths = {"markdown": out / "sweep_report.md", "json": out / "sweep_report.json",
                 "plot": out / "heldout_curve.png"}
        paths["markdown"].write_text(self.markdown())
        paths["json"].write_text(json.dumps(self.as_dict(), indent=2, default=float))
        self.plot(paths["plot"])
        return paths
