"""Architecture sweep with a grouped parameter-set holdout (and whole diameter bands). Imports torch.

Whole curves (parameter sets) are held out: a seeded random ``holdout_frac`` of the curves never enters
training or the pointwise validation split. Each architecture (width x depth hidden layers, tanh) is trained
on the remaining curves with :func:`bubblecal.surrogates.training.train_mlp` and scored on the held-out
curves (:mod:`bubblecal.surrogates.training.holdout`) by

    score = median over held-out curves of ||y_hat - y||_2 / ||y||_2   (per curve, over its finite points)

Curves may be failure-truncated prefixes (NaN tails, :func:`bubblecal.surrogates.training.filter_curves` with
``keep_failed_prefix``): training uses the finite points only, each held-out curve is scored on its finite
points, and a held-out curve with too few finite points is skipped (counted in the
rows as ``holdout_n_skipped``). The rows also give the median over the held-out prefix curves alone.

A network over the diameter (``SweepConfig.inputs = 'diameter'``) is also scored on whole diameter bands
never trained on (``ldo_bands``, leave-diameters-out), and the selection uses the worse of its two medians.
Curves simulated at loading points between the training grid's (``offgrid``: the designs load every curve on
one grid, a measured curve has its own points) are scored the same way and join the selection: a network that
fits the grid's points but wiggles between them loses there (docs/decisions.md, "Networks chosen between the
loading points").  The architecture with the lowest score is selected (ties: fewer parameters).  Reports:
``sweep_report.md`` (table), ``sweep_report.json`` (everything, incl. per-curve errors of the selection) and
``heldout_curve.png`` (the held-out curve whose error is nearest the median).  Trained architectures can be
checkpointed (:mod:`bubblecal.surrogates.training.checkpoints`) so that an interrupted sweep resumes.
"""

from __future__ import annotations

import multiprocessing as mp
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

from bubblecal.surrogates.features import DEFAULT_LOG_INPUTS, INPUT_KINDS, check_log_inputs
from bubblecal.surrogates.training.checkpoints import (
    checkpoint_key,
    checkpoint_path,
    load_checkpoint,
    save_checkpoint,
)
from bubblecal.surrogates.training.dataset import DatasetError, TrainingSet
from bubblecal.surrogates.training.holdout import (
    curve_errors,
    diameter_bands,
    error_summary,
    grouped_holdout,
    selection_score,
)
from bubblecal.surrogates.training.sweep_result import SweepResult, _truncated
from bubblecal.surrogates.training.train import TrainConfig, TrainedMLP, train_mlp

__all__ = ["SweepConfig", "run_sweep", "MIN_SWEEP_CURVES"]

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
    inputs : {'raw', 'diameter'}
        Network inputs (:mod:`bubblecal.surrogates.features`): one network per diameter, or one over the sizes.
    ldo_bands : tuple of (float, float)
        Diameter bands [um] held out whole (leave-diameters-out; ``inputs='diameter'`` only): their curves never
        enter training and score every architecture beside the grouped holdout.
    log_inputs : tuple of str or None
        Shell parameters entered as natural logarithms (:data:`~bubblecal.surrogates.LOG_INPUT_CHOICES`); None
        (default): :data:`~bubblecal.surrogates.DEFAULT_LOG_INPUTS` of ``inputs`` (k_a and k_b over the diameter,
        none per diameter, as the published networks).

    Raises
    ------
    ValueError
        For an unknown ``inputs``, bands without ``inputs='diameter'``, a band with lo > hi, or an unknown name
        in ``log_inputs``.
    """

    widths: tuple[int, ...] = (32, 64, 128, 256)
    depths: tuple[int, ...] = (2, 3, 4)
    holdout_frac: float = 0.1
    seed: int = 0
    min_curves: int = MIN_SWEEP_CURVES
    jobs: int = 1
    train: TrainConfig = field(default_factory=TrainConfig)
    inputs: str = "raw"
    ldo_bands: tuple[tuple[float, float], ...] = ()
    log_inputs: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        if self.inputs not in INPUT_KINDS:
            raise ValueError(f"SweepConfig.inputs must be one of {INPUT_KINDS}, got {self.inputs!r}")
        logged = DEFAULT_LOG_INPUTS[self.inputs] if self.log_inputs is None else self.log_inputs
        try:
            object.__setattr__(self, "log_inputs", check_log_inputs(logged))
        except ValueError as exc:
            raise ValueError(f"SweepConfig.{exc}") from None
        bands = tuple((float(lo), float(hi)) for lo, hi in self.ldo_bands)
        if bands and self.inputs != "diameter":
            raise ValueError("SweepConfig.ldo_bands needs inputs='diameter' (a network over the sizes)")
        diameter_bands([], bands)  # checks each band
        object.__setattr__(self, "ldo_bands", bands)

    def architectures(self) -> list[tuple[int, ...]]:
        """Hidden-layer widths of every architecture, depth-major (e.g. ``(32, 32)``, ``(64, 64)``, ...)."""
        return [(int(w),) * int(d) for d in self.depths for w in self.widths]

    def as_dict(self) -> dict:
        """The settings as a plain dict (training settings included)."""
        d = asdict(self)
        d["train"] = self.train.as_dict()
        return d


def _n_params(sizes: Sequence[int]) -> int:
    """Number of weights and biases of an MLP with these layer widths."""
    return int(sum(a * b + b for a, b in zip(sizes[:-1], sizes[1:], strict=True)))


def _train_job(args):
    """Train one architecture (in a worker process or inline) and checkpoint it."""
    u, y, curve, hidden, cfg, seed, progress, desc, ckpt, key = args
    model = train_mlp(u, y, hidden, cfg, seed=seed, progress=progress, desc=desc, curve=curve)
    if ckpt is not None:
        save_checkpoint(ckpt, model, key)
    return model


def run_sweep(ts: TrainingSet, config: SweepConfig | None = None, progress: bool = True,
              checkpoints: str | Path | None = None, offgrid: TrainingSet | None = None) -> SweepResult:
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
    offgrid : TrainingSet, optional
        Curves of the same protocol at loading points other than the training grid's (DPD units), scored like
        the held-out curves; the selection then takes the worst of the held-out, leave-diameters-out and
        off-grid medians.  Never trained on, and not part of the checkpoint key (selection only).

    Returns
    -------
    SweepResult
        Rows per architecture and the selected model.

    Raises
    ------
    DatasetError
        For fewer than ``config.min_curves`` curves, untrainable data, no scorable held-out curve, or ``offgrid``
        curves of another protocol or none at all.
    """
    config = config or SweepConfig()
    if offgrid is not None and offgrid.setup != ts.setup:
        raise DatasetError(f"{offgrid.source}: off-grid curves are {offgrid.setup}, the training data {ts.setup}")
    if offgrid is not None and offgrid.n_curves == 0:
        raise DatasetError(f"{offgrid.source}: no off-grid curve to score (none kept by the filter)")
    several = config.inputs == "diameter"
    ts.check_trainable(min_curves=config.min_curves, several_sizes=several)
    t0 = time.perf_counter()
    rest, ldo_set = ts, None
    if config.ldo_bands:
        band = diameter_bands(ts.diameters_um, config.ldo_bands)
        if not band.any() or band.all():
            raise DatasetError(f"{ts.source}: the held-out diameter bands {list(config.ldo_bands)} hold "
                               f"{int(band.sum())} of {ts.n_curves} curves; they must hold some but not all")
        rest, ldo_set = ts.subset(~band), ts.subset(band)
    tr_idx, ho_idx = grouped_holdout(rest.n_curves, config.holdout_frac, config.seed)
    train_set, holdout_set = rest.subset(tr_idx), rest.subset(ho_idx)
    try:
        train_set.check_trainable(min_curves=1, several_sizes=several)
    except DatasetError as exc:
        raise DatasetError(f"{exc} (in the training part of the grouped split)") from exc
    u, y, curve, _ = train_set.network_points(config.inputs, config.log_inputs)
    if config.train.curve_weights == "none":
        curve = None  # not sent to every worker process when the loss does not use it
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
            jobs.append((i, (u, y, curve, h, config.train, config.seed, progress and config.jobs == 1,
                             f"{len(h)}x{h[0]}", ckpt, key)))
    if progress and checkpoints is not None and len(jobs) < len(archs):
        print(f"sweep: {len(archs) - len(jobs)} of {len(archs)} architectures reused from {checkpoints}")
    if config.jobs > 1 and len(jobs) > 1:
        from bubblecal._progress import ProgressLine

        # the largest networks first, so that no long job starts last
        jobs.sort(key=lambda j: -_n_params([u.shape[1], *j[1][2], 1]))
        ctx = mp.get_context("spawn")
        with ProcessPoolExecutor(max_workers=config.jobs, mp_context=ctx) as pool, \
                ProgressLine("sweep", total=len(jobs), enabled=progress) as bar:
            for (i, _), m in zip(jobs, pool.map(_train_job, [j[1] for j in jobs]), strict=True):
                models[i] = m
                bar.update(advance=1)
    else:
        for i, job in jobs:
            models[i] = _train_job(job)
    rows = []
    preds = []
    errs_all = []
    prefix_mask = _truncated(holdout_set)
    ldo_errs = []
    for h, m in zip(archs, models, strict=True):
        err, pred = curve_errors(m, holdout_set, config.inputs, config.log_inputs)
        preds.append(pred)
        errs_all.append(err)
        row = {"hidden": list(h), "width": h[0], "depth": len(h), "n_params": _n_params(m.layer_sizes),
               **error_summary(err, prefix_mask),
               "best_val_loss": m.best_val_loss, "epochs": m.epochs, "stop_reason": m.stop_reason,
               "wall_s": m.wall_s, "device": m.config.device}
        if ldo_set is not None:
            ldo_err, _ = curve_errors(m, ldo_set, config.inputs, config.log_inputs)
            ldo_errs.append(ldo_err)
            row.update({"ldo_" + k.removeprefix("holdout_"): v for k, v in error_summary(ldo_err).items()})
        if offgrid is not None:
            og_err, _ = curve_errors(m, offgrid, config.inputs, config.log_inputs)
            row.update({"offgrid_" + k.removeprefix("holdout_"): v for k, v in error_summary(og_err).items()})
        rows.append(row)
    # the worst holdout decides: a network must generalise across parameter sets, sizes and loading points
    best = min(range(len(rows)), key=lambda i: (selection_score(rows[i]), rows[i]["n_params"]))
    return SweepResult(rows=rows, best_index=best, best_model=models[best], train_set=train_set,
                       holdout_set=holdout_set, holdout_errors=errs_all[best], holdout_pred=preds[best],
                       config=config, data_hash=data_hash, wall_s=time.perf_counter() - t0, models=models,
                       ldo_set=ldo_set, ldo_errors=ldo_errs[best] if ldo_errs else None, offgrid_set=offgrid)
