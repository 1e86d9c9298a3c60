"""Architecture sweep with a grouped parameter-set holdout. Imports torch (through train).

Whole curves (parameter sets) are held out: a seeded random ``holdout_frac`` of the curves never
enters training or the pointwise validation split. Each architecture (width x depth hidden
layers, tanh) is trained on the remaining curves with :func:`bubblecal.surrogates.train.train_mlp`
and scored on the held-out curves by

    score = median over held-out curves of ||y_hat - y||_2 / ||y||_2   (per curve, over its points)

The architecture with the lowest score is selected (ties: fewer parameters). Reports:
``sweep_report.md`` (table), ``sweep_report.json`` (everything, incl. per-curve errors of the
selection) and ``heldout_curve.png`` (the held-out curve whose error is nearest the median).
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

from bubblecal.surrogates.dataset import DatasetError, TrainingSet
from bubblecal.surrogates.train import TrainConfig, TrainedMLP, train_mlp

__all__ = ["SweepConfig", "SweepResult", "grouped_holdout", "run_sweep", "curve_errors", "MIN_SWEEP_CURVES"]

MIN_SWEEP_CURVES = 20


@dataclass(frozen=True)
class SweepConfig:
    """Sweep settings: the architecture grid, holdout and training settings."""

    widths: tuple[int, ...] = (32, 64, 128, 256)
    depths: tuple[int, ...] = (2, 3, 4)
    holdout_frac: float = 0.1
    seed: int = 0
    min_curves: int = MIN_SWEEP_CURVES
    jobs: int = 1  # architectures trained in parallel processes (1 torch thread each)
    train: TrainConfig = field(default_factory=TrainConfig)

    def architectures(self) -> list[tuple[int, ...]]:
        return [(int(w),) * int(d) for d in self.depths for w in self.widths]

    def as_dict(self) -> dict:
        d = asdict(self)
        d["train"] = self.train.as_dict()
        return d


def grouped_holdout(n_curves: int, frac: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Seeded split of curve indices into (train, holdout); at least one curve on each side."""
    if not 0.0 < frac < 1.0:
        raise ValueError(f"holdout_frac must be in (0, 1), got {frac}")
    if n_curves < 2:
        raise ValueError(f"need at least 2 curves for a grouped holdout, got {n_curves}")
    rng = np.random.default_rng(seed)
    perm = rng.permutation(n_curves)
    n_hold = min(n_curves - 1, max(1, int(round(frac * n_curves))))
    return np.sort(perm[n_hold:]), np.sort(perm[:n_hold])


def curve_errors(model: TrainedMLP, ts: TrainingSet) -> tuple[np.ndarray, np.ndarray]:
    """(per-curve relative L2 errors, predictions (n, m)) of ``model`` on the curves of ``ts``."""
    u, y, _ = ts.points()
    y_hat = model.predict(u).reshape(ts.y.shape)
    err = np.linalg.norm(y_hat - ts.y, axis=1) / np.linalg.norm(ts.y, axis=1)
    return err, y_hat


def _n_params(sizes: Sequence[int]) -> int:
    return int(sum(a * b + b for a, b in zip(sizes[:-1], sizes[1:], strict=True)))


def _train_job(args):
    u, y, hidden, cfg, seed, progress, desc = args
    return train_mlp(u, y, hidden, cfg, seed=seed, progress=progress, desc=desc)


@dataclass
class SweepResult:
    """Outcome of :func:`run_sweep`."""

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
        return self.rows[self.best_index]

    @property
    def score(self) -> float:
        return float(self.best["holdout_median"])

    def as_dict(self) -> dict:
        return {
            "selected": self.best, "rows": self.rows, "config": self.config.as_dict(),
            "data_hash": self.data_hash, "setup": self.train_set.setup,
            "diameter_um": self.train_set.diameter_um, "source": self.train_set.source,
            "n_curves_train": self.train_set.n_curves, "n_curves_holdout": self.holdout_set.n_curves,
            "holdout_curve_ids": self.holdout_set.curve_id.tolist(),
            "holdout_errors_selected": self.holdout_errors.tolist(), "wall_s": self.wall_s,
            "metric": "median over held-out curves of ||y_hat - y||_2 / ||y||_2",
        }

    def markdown(self) -> str:
        ts = self.train_set
        lines = [
            f"# Surrogate architecture sweep: {ts.setup}, {ts.diameter_um:g} um",
            "",
            f"- data: `{ts.source}` (sha256 {self.data_hash[:16]}...), {ts.n_curves} training curves, "
            f"{self.holdout_set.n_curves} held-out curves (grouped holdout, seed {self.config.seed}, "
            f"fraction {self.config.holdout_frac})",
            "- score: median over held-out curves of ||y_hat - y||_2 / ||y||_2 (per curve)",
            f"- sweep wall time: {self.wall_s:.1f} s ({self.config.jobs} job(s), "
            f"{self.config.train.threads} torch thread(s) each)",
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
        lines += ["", f"Selected: {b['width']}x{b['depth']} with held-out median relative L2 {b['holdout_median']:.4%}.", ""]
        return "\n".join(lines)

    def plot(self, path: str | Path) -> Path:
        """Plot the held-out curve nearest the median error, plus the error histogram."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from bubblecal.surrogates.dataset import X_INFO, Y_INFO

        ts = self.holdout_set
        i = int(np.argmin(np.abs(self.holdout_errors - np.median(self.holdout_errors))))
        xs = np.linspace(ts.x[i].min(), ts.x[i].max(), 200)
        u = np.column_stack([np.repeat(ts.params[i:i + 1], xs.size, axis=0), xs])
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
        ax1.plot(ts.x[i], ts.y[i], "o", label="held-out data")
        ax1.plot(xs, self.best_model.predict(u), "-", label="surrogate")
        ax1.set_xlabel(f"{X_INFO[ts.setup][0]} [{X_INFO[ts.setup][1]}]")
        ax1.set_ylabel(f"{Y_INFO[ts.setup][0]} [{Y_INFO[ts.setup][1]}]")
        ax1.set_title(f"{ts.curve_id[i]}: rel. L2 {self.holdout_errors[i]:.3%}", fontsize=9)
        ax1.legend()
        ax2.hist(self.holdout_errors * 100, bins=min(30, max(5, ts.n_curves // 3)))
        ax2.axvline(np.median(self.holdout_errors) * 100, color="k", ls="--", label="median")
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
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        paths = {"markdown": out / "sweep_report.md", "json": out / "sweep_report.json",
                 "plot": out / "heldout_curve.png"}
        paths["markdown"].write_text(self.markdown())
        paths["json"].write_text(json.dumps(self.as_dict(), indent=2, default=float))
        self.plot(paths["plot"])
        return paths


def run_sweep(ts: TrainingSet, config: SweepConfig | None = None, progress: bool = True) -> SweepResult:
    """Train every architecture of ``config`` on a grouped split of ``ts`` and pick the best.

    ``ts`` must be filtered (:func:`bubblecal.surrogates.dataset.filter_curves`). Raises
    :class:`DatasetError` for fewer than ``config.min_curves`` curves or untrainable data.
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
    jobs = [(u, y, h, config.train, config.seed, progress and config.jobs == 1, f"{len(h)}x{h[0]}") for h in archs]
    if config.jobs > 1 and len(jobs) > 1:
        from tqdm.auto import tqdm

        ctx = mp.get_context("spawn")
        with ProcessPoolExecutor(max_workers=config.jobs, mp_context=ctx) as pool:
            models = list(tqdm(pool.map(_train_job, jobs), total=len(jobs), desc="sweep", disable=not progress))
    else:
        models = [_train_job(j) for j in jobs]
    rows = []
    preds = []
    errs_all = []
    for h, m in zip(archs, models, strict=True):
        err, pred = curve_errors(m, holdout_set)
        preds.append(pred)
        errs_all.append(err)
        rows.append({"hidden": list(h), "width": h[0], "depth": len(h), "n_params": _n_params(m.layer_sizes),
                     "holdout_median": float(np.median(err)), "holdout_mean": float(np.mean(err)),
                     "holdout_p90": float(np.quantile(err, 0.9)), "holdout_max": float(np.max(err)),
                     "best_val_loss": m.best_val_loss, "epochs": m.epochs, "stop_reason": m.stop_reason,
                     "wall_s": m.wall_s})
    best = min(range(len(rows)), key=lambda i: (rows[i]["holdout_median"], rows[i]["n_params"]))
    return SweepResult(rows=rows, best_index=best, best_model=models[best], train_set=train_set,
                       holdout_set=holdout_set, holdout_errors=errs_all[best], holdout_pred=preds[best],
                       config=config, data_hash=ts.data_hash(), wall_s=time.perf_counter() - t0, models=models)
