"""Checkpoints of an architecture sweep: one file per trained architecture, reused when the key matches.

A checkpoint is a plain ``.npz`` (no pickles) with the weights, the standardisation and a JSON ``meta`` holding
the training summary and the *key*: what a saved architecture must match to be reused (the data hash, the
architecture, the split seed and fraction, and the training recipe; where and how fast it trained - device,
threads, CUDA graphs - is not part of the key). Files are written atomically so that a killed sweep leaves no
half-written checkpoint. Imports torch (through :mod:`bubblecal.surrogates.training.train`).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from bubblecal.surrogates.training.train import TrainConfig, TrainedMLP

if TYPE_CHECKING:
    from bubblecal.surrogates.training.sweep import SweepConfig

__all__ = ["checkpoint_key", "checkpoint_path", "save_checkpoint", "load_checkpoint"]

#: TrainConfig fields that change where and how fast a model trains, not the recipe (not part of a checkpoint key)
_EXECUTION_FIELDS = ("threads", "device", "cuda_graphs")


def checkpoint_key(data_hash: str, hidden: Sequence[int], config: SweepConfig) -> dict:
    """What a saved architecture must match to be reused: data, split, architecture, seed and recipe.

    Parameters
    ----------
    data_hash : str
        :meth:`~bubblecal.surrogates.training.TrainingSet.data_hash` of the (filtered) data.
    hidden : sequence of int
        Hidden-layer widths.
    config : SweepConfig
        The sweep settings (seed, holdout fraction, training recipe).

    Returns
    -------
    dict
        The key (plain JSON).
    """
    recipe = {k: v for k, v in config.train.as_dict().items() if k not in _EXECUTION_FIELDS}
    key = {"data_hash": data_hash, "hidden": [int(h) for h in hidden], "seed": int(config.seed),
           "holdout_frac": float(config.holdout_frac), "recipe": recipe}
    if config.inputs != "raw":  # per-diameter keys stay as they were, so their saved sweeps are reused
        key.update(inputs=config.inputs, ldo_bands=[list(b) for b in config.ldo_bands])
    if config.log_inputs:
        key["log_inputs"] = list(config.log_inputs)
    return key


def checkpoint_path(folder: str | Path, hidden: Sequence[int]) -> Path:
    """File of one trained architecture in a sweep checkpoint folder.

    Parameters
    ----------
    folder : str or Path
        Checkpoint folder.
    hidden : sequence of int
        Hidden-layer widths (one width repeated, as in a sweep).

    Returns
    -------
    Path
        ``folder/arch_<width>x<depth>.npz``.
    """
    return Path(folder) / f"arch_{hidden[0]}x{len(hidden)}.npz"


def save_checkpoint(path: str | Path, model: TrainedMLP, key: dict) -> Path:
    """Write a trained model and its key atomically.

    Parameters
    ----------
    path : str or Path
        Checkpoint file (parent folders are created).
    model : TrainedMLP
        The trained architecture.
    key : dict
        :func:`checkpoint_key` of the model.

    Returns
    -------
    Path
        ``path``.
    """
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
    """The saved model at ``path`` if it exists and was trained under ``key``, else None.

    Parameters
    ----------
    path : str or Path
        Checkpoint file.
    key : dict
        :func:`checkpoint_key` the model must have been trained under.

    Returns
    -------
    TrainedMLP or None
        The model, or None when the file is missing or its key differs.
    """
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
    return TrainedMLP(hidden=tuple(meta["hidden"]), weights=weights, biases=biases,
                      config=TrainConfig(**meta["config"]), seed=int(meta["seed"]), epochs=int(meta["epochs"]),
                      stop_reason=meta["stop_reason"], best_val_loss=float(meta["best_val_loss"]),
                      wall_s=float(meta["wall_s"]), history=meta["history"], **stats)
