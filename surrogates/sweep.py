"""Architecture sweep with a grouped parameter-set holdout. Imports torch (through train).

Whole curves (parameter sets) are held out: a seeded random ``holdout_frac`` of the curves never
enters training or the pointwise validation split. Each architecture (width x depth hidden
layers, tanh) is trained on the remaining curves with :func:`bubblecal.surrogates.train.train_mlp`
and scored on the held-out curves by

    score = median over held-out curves of ||y_hat - y||_2 / ||y||_2   (per curve, over its finite points)

Curves may be failure-truncated prefixes (NaN tails, :func:`bubblecal.surrogates.dataset.filter_curves`
with ``keep_failed_prefix``): training uses the finite points only, each held-out curve is scored on
its finite points, and a held-out curve with fewer than 2 finite points is skipped (counted in the
rows as ``holdout_n_skipped``). The rows also give the median over the held-out prefix curves alone.

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

__all__ = ["SweepConfig", "SweepResult", "grouped_holdout", "run_sweep", "curve_errors", "error_summary",
           "checkpoint_key", "checkpoint_path", "save_checkpoint", "load_checkpoint", "MIN_SWEEP_CURVES",
           "MIN_SCORED_POINTS"]

MIN_SWEEP_CURVES = 20
#: a held-out curve needs this many finite points to be scored
MIN_SCORED_POINTS = 2


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
    """(per-curve relative L2 errors (n,), predictions (n, m)) of ``model`` on the curves of ``ts``.

    Each curve is scored on its finite points (``ts.point_mask()``): ||y_hat - y||_2 / ||y||_2. The
    error is NaN for a curve with fewer than :data:`MIN_SCORED_POINTS` finite points (skipped; see
    :func:`error_summary`). Predictions cover every point with a finite x (also a curve's NaN tail).
    """
    n, m = ts.x.shape
    xfin = np.isfinite(ts.x)
    u = np.concatenate([np.repeat(ts.params, m, axis=0), np.where(xfin, ts.x, 0.0).reshape(-1, 1)], axis=1)
    y_hat = np.where(xfin, model.predict(u).reshape(n, m), np.nan)
    valid = ts.point_mask()
    diff = np.where(valid, y_hat - ts.y, 0.0)
    ref = np.where(valid, ts.y, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        err = np.linalg.norm(diff, axis=1) / np.linalg.norm(ref, axis=1)
    err[valid.sum(axis=1) < MIN_SCORED_POINTS] = np.nan
    return err, y_hat


def error_summary(err: np.ndarray, prefix_mask: np.ndarray | None = None) -> dict:
    """Median / mean / p90 / max of the finite per-curve errors, with the numbers scored and skipped.

    ``prefix_mask`` (n,) marks failure-truncated curves: their median and count are added
    (``holdout_median_prefix`` is None when none was scored).
    """
    err = np.asarray(err, dtype=float)
    ok = np.isfinite(err)
    if not ok.any():
        raise DatasetError(f"no held-out curve has >= {MIN_SCORED_POINTS} finite points to score")
    e = err[ok]
    out = {"holdout_median": float(np.median(e)), "holdout_mean": float(np.mean(e)),
           "holdout_p90": float(np.quantile(e, 0.9)), "holdout_max": float(np.max(e)),
           "holdout_n_scored": int(ok.sum()), "holdout_n_skipped": int((~ok).sum())}
    if prefix_mask is not None:
        pm = np.asarray(prefix_mask, bool) & ok
        out["holdout_n_prefix"] = int(pm.sum())
        out["holdout_median_prefix"] = float(np.median(err[pm])) if pm.any() else None
    return out


def _truncated(ts: TrainingSet) -> np.ndarray:
    """(n,) True for curves with a non-finite point (failure-truncated prefixes)."""
    return ~np.all(ts.point_mask(), axis=1)


def _nan_to_none(values) -> list:
    return [None if not np.isfinite(v) else float(v) for v in np.asarray(values, dtype=float)]


def _n_params(sizes: Sequence[int]) -> int:
    return int(sum(a * b + b for a, b in zip(sizes[:-1], sizes[1:], strict=True)))


#: TrainConfig fields that change where and how fast a model trains, not the recipe (not part of a checkpoint key)
_EXECUTION_FIELDS = ("threads", "device", "cuda_graphs")


def checkpoint_key(data_hash: str, hidden: Sequence[int], config: SweepConfig) -> dict:
    """What a saved architecture must match to be reused: data, split, architecture, seed and recipe."""
    recipe = {k: v for k, v in config.train.as_dict().items() if k not in _EXECUTION_FIELDS}
    return {"data_hash": data_hash, "hidden": [int(h) for h in hidden], "seed": int(config.seed),
            "holdout_frac": float(config.holdout_frac), "recipe": recipe}


def checkpoint_path(folder: str | Path, hidden: Sequence[int]) -> Path:
    """File of one trained architecture in a sweep checkpoint folder."""
    return Path(folder) / f"arch_{hidden[0]}x{len(hidden)}.npz"


def save_checkpoint(path: str | Path, model: TrainedMLP, key: dict) -> Path:
    """Write a trained model and its key atomically (a killed sweep leaves no half-written file)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    meta = {"key": key, "hidden": list(model.hidden), "seed": model.seed, "epochs": model.epochs,
            "stop_reason": model.stop_reason, "best_val_loss": model.best_val_loss, "wall_s": model.wall_s,
            "config": model.config.as_dict(), "history": model.history}
    arrays = {f"W_{i}": w for i, w in enumerate(model.weights)}
    arrays.update({f"b_{i}": b for i, b in enumerate(model.biases)})
    tmp = path.with_name(path.name + ".part")
    with open(tmp, "wb") as fh:
        np.savez(fh, in_mean=model.in_mean, in_std=model.in_std, out_mean=model.out_mean, out_std=model.out_std,
                 meta=np.array(json.dumps(meta)), **arrays)
    tmp.replace(path)
    return path


def load_checkpoint(path: str | Path, key: dict) -> TrainedMLP | None:
    """The saved model at ``path`` if it exists and was trained under ``key``, else None."""
    path = Path(path)
    if not path.is_file():
        return None
    with np.load(path) as z:
        meta = json.loads(str(z["meta"]))
        if meta.get("key") != json.loads(json.dumps(key)):
            return None
        n = len(meta["hidden"]) + 1
        weights = [z[f"W_{i}"] for i in range(n)]
        biases = [z[f"b_{i}"] for i in range(n)]
        stats = {k: z[k] for k in ("in_mean", "in_std", "out_mean", "out_std")}
    return TrainedMLP(hidden=tuple(meta["hidden"]), weights=weights, biases=biases, config=TrainConfig(**meta["config"]),
                      seed=int(meta["seed"]), epochs=int(meta["epochs"]), stop_reason=meta["stop_reason"],
                      best_val_loss=float(meta["best_val_loss"]), wall_s=float(meta["wall_s"]),
                      history=meta["history"], **stats)


def _train_job(args):
    u, y, hidden, cfg, seed, progress, desc, ckpt, key = args
    model = train_mlp(u, y, hidden, cfg, seed=seed, progress=progress, desc=desc)
    if ckpt is not None:
        save_checkpoint(ckpt, model, key)
    return model


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
            "n_points_train": self.train_set.n_valid_points, "n_points_holdout": self.holdout_set.n_valid_points,
            "truncation_train": self.train_set.truncation_summary(),
            "truncation_holdout": self.holdout_set.truncation_summary(),
            "holdout_curve_ids": self.holdout_set.curve_id.tolist(),
            "holdout_errors_selected": _nan_to_none(self.holdout_errors), "wall_s": self.wall_s,
            "metric": "median over held-out curves of ||y_hat - y||_2 / ||y||_2 (finite points; curves with < "
                      f"{MIN_SCORED_POINTS} finite points skipped)",
        }

    def markdown(self) -> str:
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
            f"{sum(r['wall_s'] for r in self.rows):.0f} s on {', '.join(sorted({r.get('device', 'cpu') for r in self.rows}))}",
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
        lines += ["", f"Selected: {b['width']}x{b['depth']} with held-out median relative L2 {b['holdout_median']:.4%}."]
        if b.get("holdout_n_prefix"):
            lines.append(f"Held-out failure-truncated prefix curves: {b['holdout_n_prefix']}, median relative L2 "
                         f"{b['holdout_median_prefix']:.4%}.")
        lines.append("")
        return "\n".join(lines)

    def plot(self, path: str | Path) -> Path:
        """Plot the held-out curve nearest the median error, plus the error histogram."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from bubblecal.surrogates.dataset import X_INFO, Y_INFO

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
    """Train every architecture of ``config`` on a grouped split of ``ts`` and pick the best.

    ``checkpoints``: a folder where each architecture is saved as soon as it is trained; a rerun
    reuses every saved architecture whose data, split, seed and recipe match (the device and
    thread count may differ), so an interrupted sweep resumes where it stopped.

    ``ts`` must be filtered (:func:`bubblecal.surrogates.dataset.filter_curves`; failure-truncated
    prefixes with NaN tails are accepted: training and scores use the finite points). Raises
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
