"""bubblecal.surrogates.training: data, training and export of the mechanical MLP surrogates.

Numpy-only parts, imported with the package: the training set (:mod:`~bubblecal.surrogates.training.dataset`),
reading and writing data (:mod:`~bubblecal.surrogates.training.data_io`), filtering
(:mod:`~bubblecal.surrogates.training.filtering`), known-answer data (:mod:`~bubblecal.surrogates.training.synthetic`),
the grouped holdout (:mod:`~bubblecal.surrogates.training.holdout`), the per-curve loss weights
(:mod:`~bubblecal.surrogates.training.weights`) and the ONNX parity check
(:mod:`~bubblecal.surrogates.training.onnx_check`, onnxruntime imported on use).

The torch parts - :mod:`~bubblecal.surrogates.training.train`, :mod:`~bubblecal.surrogates.training.sweep`,
:mod:`~bubblecal.surrogates.training.sweep_result`, :mod:`~bubblecal.surrogates.training.checkpoints`,
:mod:`~bubblecal.surrogates.training.export` - are imported
on first access to one of their names, so that reading and filtering data never imports torch::

    from bubblecal.surrogates.training import filter_curves, read_dataset   # no torch
    from bubblecal.surrogates.training import SweepConfig, run_sweep        # imports torch here

Calibration code never imports this package; it loads the exported ``.npz`` with :func:`bubblecal.surrogates.load`.
"""

from bubblecal._lazy import lazy_exports
from bubblecal.surrogates.training.data_io import (
    N_META,
    PUBLISHED_META_COLUMNS,
    PUBLISHED_POINTS,
    read_dataset,
    read_published,
    read_store_dataset,
    write_published,
)
from bubblecal.surrogates.training.dataset import (
    DatasetError,
    TrainingSet,
    concat_training_sets,
    diameter_um_from_radius,
    leading_finite,
)
from bubblecal.surrogates.training.filtering import PREFIX_STATUSES, FilterReport, filter_curves
from bubblecal.surrogates.training.holdout import (
    FAST_MEDIAN_FACTOR,
    FAST_P90_FACTOR,
    MIN_SCORED_POINTS,
    curve_errors,
    diameter_bands,
    error_summary,
    fast_choice,
    grouped_holdout,
    selection_score,
)
from bubblecal.surrogates.training.onnx_check import onnx_parity, onnx_predict, scaled_max_rel_diff
from bubblecal.surrogates.training.synthetic import (
    DEFAULT_RANGES,
    DEFAULT_X,
    compression_force,
    indentation_displacement,
    make_synthetic,
    noise_floor,
    relative_l2,
    truth,
)
from bubblecal.surrogates.training.weights import CURVE_WEIGHTS, curve_weights

#: Torch-side names, imported on first access: module -> the names it exports.
_TORCH_SIDE: dict[str, tuple[str, ...]] = {
    "train": ("TrainConfig", "TrainedMLP", "NormalisedMLP", "train_mlp", "numpy_forward"),
    "sweep": ("SweepConfig", "run_sweep", "MIN_SWEEP_CURVES"),
    "sweep_result": ("SweepResult",),
    "checkpoints": ("checkpoint_key", "checkpoint_path", "save_checkpoint", "load_checkpoint"),
    "export": ("surrogate_metadata", "export_npz", "export_sweep", "export_onnx", "HOLDOUT_METRIC"),
}
_LAZY = {name: f"{__name__}.{module}" for module, names in _TORCH_SIDE.items() for name in names}

__all__ = [
    # training set, data I/O, filtering
    "TrainingSet", "DatasetError", "concat_training_sets", "leading_finite", "diameter_um_from_radius",
    "read_dataset", "read_published",
    "write_published", "read_store_dataset", "N_META", "PUBLISHED_POINTS", "PUBLISHED_META_COLUMNS",
    "FilterReport", "filter_curves", "PREFIX_STATUSES",
    # known-answer data
    "make_synthetic", "truth", "compression_force", "indentation_displacement", "noise_floor", "relative_l2",
    "DEFAULT_RANGES", "DEFAULT_X",
    # grouped holdout, ONNX parity
    "grouped_holdout", "diameter_bands", "curve_errors", "error_summary", "selection_score", "fast_choice",
    "FAST_MEDIAN_FACTOR", "FAST_P90_FACTOR", "MIN_SCORED_POINTS",
    "onnx_predict", "onnx_parity", "scaled_max_rel_diff",
    # per-curve loss weights
    "curve_weights", "CURVE_WEIGHTS",
    # torch side (lazy)
    *_LAZY,
]

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())
