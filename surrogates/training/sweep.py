"""Architecture sweep with a grouped parameter-set holdout. Imports torch (through training).

Whole curves (parameter sets) are held out: a seeded random ``holdout_frac`` of the curves never enters
training or the pointwise validation split. Each architecture (width x depth hidden layers, tanh) is trained
on the remaining curves with :func:`bubblecal.surrogates.training.train_mlp` and scored on the held-out
curves (:mod:`bubblecal.surrogates.training.holdout`) by

    score = median over held-out curves of ||y_hat - y||_2 / ||y||_2   (per curve, over its finite points)

Curves may be failure-truncated prefixes (NaN tails, :func:`bubblecal.surrogates.training.filter_curves` with
``keep_failed_prefix``): training uses the finite points only, each held-out curve is scored on its finite
points, and a held-out curve with too few finite points is skipped (counted in the
rows as ``holdout_n_skipped``). The rows also give the median over the held-out prefix curves alone.

The architecture with the lowest score is selected (ties: fewer parameters). Reports: ``sweep_report.md``
(table), ``sweep_report.json`` (everything, incl. per-curve errors of the selection) and ``heldout_curve.png``
(the held-out curve whose error is nearest the median). Trained architectures can be checkpointed
(:mod:`bubblecal.surrogates.training.checkpoints`) so that an interrupted sweep resumes.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from bubblecal.surrogates.axes import X_INFO, Y_INFO
from bubblecal.surrogates.training.checkpoints import (
    checkpoint_key,
    checkpoint_path,
    load_checkpoint,
    save_checkpoint,
)
from bubblecal.surrogates.training.dataset import DatasetError, TrainingSet
from bubblecal.surrogates.training.holdout import (
    MIN_SCORED_POINTS,
    curve_errors,
    error_summary,
    grouped_holdout,
)
from bubblecal.surrogates.training.train import TrainConfig, TrainedMLP, train_mlp

__all__ = ["SweepConfig", "SweepResult", "run_sweep", "MIN_SWEEP_CURVES"]

#: Fewest curves a sweep accepts (default of ``SweepConfig.min_curves``).
MIN_SWEEP_CURVES = 20


@dataclass(frozen=True)
class SweepConfig:
    """Sweep settings: the architecture grid, the holdout and the training settings.

    Parameters
    ----------
    widths : tuple of int
        Hidden-layer widths tried.
    depths : tuple of int
        Numbers of hidden layers tried (every width at every depth).
    holdout_frac : float
        Fraction of the curves held out, in (0, 1).
    seed : int
        Seed of the grouped split and of every training run.
    min_curves : int
        Fewest curves accepted.
    jobs : int
        Architectures trained in parallel processes (one torch thread each).
    train : TrainConfig
        Training settings of every architecture.
    """

    widths: tuple[int, ...] = (32, 64, 128, 256)
    depths: tuple[int, ...] = (2, 3, 4)
    holdout_frac: float = 0.1
    seed: int = 0
    min_curves: int = MIN_SWEEP_CURVES
    jobs: int = 1
    train: TrainConfig = field(default_factory=TrainConfig)

    def architectures(self) -> list[tuple[int, ...]]:
        """Hidden-layer widths of every architecture, depth-major (e.g. ``(32, 32)``, ``(64, 64)``, ...)."""
        return [(int(w),) * int(d) for d in self.depths for w in self.widths]

    def as_dict(self) -> dict:
        """The settings as a plain dict (training settings included)."""
        d = asdict(self)
        d["train"] = self.train.as_dict()
        return d


def _truncated(ts: TrainingSet) -> np.ndarray:
    """(n,) True for curves with a non-finite point (failure-truncated prefixes)."""
    return ~np.all(ts.point_mask(), axis=1)


def _nan_to_none(values) -> list:
    """Floats with non-finite values as None (strict JSON)."""
    return [None if not np.isfinite(v) else float(v) for v in np.asarray(values, dtype=float)]


def _n_params(sizes: Sequence[int]) -> int:
    """Number of weights and biases of an MLP with these layer widths."""
    return int(sum(a * b + b for a, b in zip(sizes[:-1], sizes[1:], strict=True)))


def _train_job(args):
    """Train one architecture (in a worker process or inline) and checkpoint it."""
    u, y, hidden, cfg, seed, progress, desc, ckpt, key = args
    model = train_mlp(u, y, hidden, cfg, seed=seed, progress=progress, desc=desc)
    if ckpt is not None:
        save_checkpoint(ckpt, model, key)
    return model


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

    @property
    def best(self) -> dict:
        """The selected row."""
        return self.rows[self.best_index]

    @property
    def score(self) -> float:
        """Held-out median relative L2 error of the selected model."""
        return float(self.best["holdout_median"])

    def as_dict(self) -> dict:
        """Everything as plain JSON (``sweep_report.json``)."""
        return {
            "selected": self.best, "rows": self.rows, "config": self.config.as_dict(),
            "data_hash": self.data_hash, "setup": self.train_set.setup,
            "diameter_um": self.train_set.diameter_um, "source": self.train_set.source,
            "n_curves_train": self.train_set.n_curves, "n_curves_holdout": self.holdout_set.n_curves,
            "n_points_train": self.train_set.n_valid_points, "n_points_holdout": self.holdout_set.n_valid_points,
            "truncation_train": self.train_set.truncation_summary(),
            "truncation_holdout": self.holdout_set.truncation_summary(),
            "holdout_curve_ids": self.holdout_set.curve_id.tolist(),
            "holdout_errors_selected": _nan_to_none(self.holdout_errors), "wall_s": self.wall_s,
            "metric": "median over held-out curves of ||y_hat - y||_2 / ||y||_2 (finite points; curves with < "
                      f"{MIN_SCORED_POINTS} finite points skipped)",
        }

    def markdown(self) -> str:
        """The report table (``sweep_report.md``)."""
        ts = self.train_set
        lines = [
            f"# Surrogate architecture sweep: {ts.setup}, {ts.diameter_um:g} um",
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
            "",
            "| hidden | params | holdout median | holdout p90 | best val MSE (std.) | epochs | stop | wall s |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for i, r in enumerate(self.rows):
            mark = " **(selected)**" if i == self.best_index else ""
            lines.append(f"| {r['width']}x{r['depth']}{mark} | {r['n_params']} | {r['holdout_median']:.4%} | "
                         f"{r['holdout_p90']:.4%} | {r['best_val_loss']:.3g} | {r['epochs']} | {r['stop_reason']} | "
                         f"{r['wall_s']:.1f} |")
        b = self.best
        lines += ["", f"Selected: {b['width']}x{b['depth']} with held-out median relative L2 "
                      f"{b['holdout_median']:.4%}."]
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
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        ts = self.holdout_set
        errs = self.holdout_errors
        scored = np.isfinite(errs)
        i = int(np.nanargmin(np.where(scored, np.abs(errs - np.median(errs[scored])), np.nan)))
        xv = ts.x[i][ts.point_mask()[i]]
        xs = np.linspace(xv.min(), xv.max(), 200)
        u = np.column_stack([np.repeat(ts.params[i:i + 1], xs.size, axis=0), xs])
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
        ax1.plot(ts.x[i], ts.y[i], "o", label="held-out data")
        ax1.plot(xs, self.best_model.predict(u), "-", label="surrogate")
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
        fig.suptitle(f"{ts.setup} {ts.diameter_um:g} um, selected {b['width']}x{b['depth']}")
        fig.tight_layout()
        path = Path(path)
        fig.savefig(path, dpi=110)
        plt.close(fig)
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


def run_sweep(ts: TrainingSet, config: SweepConfig | None = None, progress: bool = True,
              checkpoints: str | Path | None = None) -> SweepResult:
    """Train every architecture of ``config`` on a grouped split of ``ts`` and pick the best (module docstring).

    Parameters
    ----------
    ts : TrainingSet
        Filtered curves (:func:`bubblecal.surrogates.training.filter_curves`; failure-truncated prefixes with NaN
        tails are accepted: training and scores use the finite points), DPD units.
    config : SweepConfig, optional
        Settings (default ``SweepConfig()``).
    progress : bool
        Show progress bars and reuse messages.
    checkpoints : str or Path, optional
        Folder where each architecture is saved as soon as it is trained; a rerun reuses every saved
        architecture whose data, split, seed and recipe match (the device and thread count may differ), so an
        interrupted sweep resumes where it stopped.

    Returns
    -------
    SweepResult
        Rows per architecture and the selected model.

    Raises
    ------
    DatasetError
        For fewer than ``config.min_curves`` curves, untrainable data, or no scorable held-out curve.
    """
    config = config or SweepConfig()
    ts.check_trainable(min_curves=config.min_curves)
    t0 = time.perf_counter()
    tr_idx, ho_idx = grouped_holdout(ts.n_curves, config.holdout_frac, config.seed)
    train_set, holdout_set = ts.subset(tr_idx), ts.subset(ho_idx)
    try:
        train_set.check_trainable(min_curves=1)
    except DatasetError as exc:
        raise DatasetError(f"{exc} (in the training part of the grouped split)") from exc
    u, y, _ = train_set.points()
    archs = config.architectures()
    data_hash = ts.data_hash()
    models: list[TrainedMLP | None] = [None] * len(archs)
    jobs = []
    for i, h in enumerate(archs):
        key = checkpoint_key(data_hash, h, config)
        ckpt = checkpoint_path(checkpoints, h) if checkpoints is not None else None
        if ckpt is not None:
            models[i] = load_checkpoint(ckpt, key)
        if models[i] is None:
            jobs.append((i, (u, y, h, config.train, config.seed, progress and config.jobs == 1, f"{len(h)}x{h[0]}",
                             ckpt, key)))
    if progress and checkpoints is not None and len(jobs) < len(archs):
        print(f"sweep: {len(archs) - len(jobs)} of {len(archs)} architectures reused from {checkpoints}")
    if config.jobs > 1 and len(jobs) > 1:
        from tqdm.auto import tqdm

        # the largest networks first, so that no long job starts last
        jobs.sort(key=lambda j: -_n_params([u.shape[1], *j[1][2], 1]))
        ctx = mp.get_context("spawn")
        with ProcessPoolExecutor(max_workers=config.jobs, mp_context=ctx) as pool:
            done = tqdm(pool.map(_train_job, [j[1] for j in jobs]), total=len(jobs), desc="sweep",
                        disable=not progress)
            for (i, _), m in zip(jobs, done, strict=True):
                models[i] = m
    else:
        for i, job in jobs:
            models[i] = _train_job(job)
    rows = []
    preds = []
    errs_all = []
    prefix_mask = _truncated(holdout_set)
    for h, m in zip(archs, models, strict=True):
        err, pred = curve_errors(m, holdout_set)
        preds.append(pred)
        errs_all.append(err)
        rows.append({"hidden": list(h), "width": h[0], "depth": len(h), "n_params": _n_params(m.layer_sizes),
                     **error_summary(err, prefix_mask),
                     "best_val_loss": m.best_val_loss, "epochs": m.epochs, "stop_reason": m.stop_reason,
                     "wall_s": m.wall_s, "device": m.config.device})
    best = min(range(len(rows)), key=lambda i: (rows[i]["holdout_median"], rows[i]["n_params"]))
    return SweepResult(rows=rows, best_index=best, best_model=models[best], train_set=train_set,
                       holdout_set=holdout_set, holdout_errors=errs_all[best], holdout_pred=preds[best],
                       config=config, data_hash=data_hash, wall_s=time.perf_counter() - t0, models=models)
