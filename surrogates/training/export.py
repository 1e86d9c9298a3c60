"""Export trained models: the plain-weight surrogate ``.npz`` (:mod:`bubblecal.surrogates.surrogate_file`) and ONNX.

Imports torch (the training side); calibration reads the ``.npz`` with :func:`bubblecal.surrogates.load` and
never imports this module.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from bubblecal._extras import require
from bubblecal.data import PARAMETER_UNITS, SHELL_PARAMETERS
from bubblecal.surrogates.axes import X_INFO, Y_INFO
from bubblecal.surrogates.features import RESPONSE_SCALES, x_per_size
from bubblecal.surrogates.surrogate_file import save_surrogate
from bubblecal.surrogates.training.dataset import TrainingSet
from bubblecal.surrogates.training.train import TrainedMLP

__all__ = ["surrogate_metadata", "export_npz", "export_sweep", "export_onnx"]

#: The ``holdout_metric`` recorded with a sweep's ``holdout_score``.
HOLDOUT_METRIC = "median over held-out curves of ||y_hat - y||_2 / ||y||_2"


def surrogate_metadata(model: TrainedMLP, train_set: TrainingSet, holdout_score: float, data_hash: str,
                       extra_training: dict | None = None, nominal_diameter_um: float | None = None,
                       filter_report=None, inputs: str = "raw", log_inputs: tuple[str, ...] = ()) -> dict:
    """Metadata of a surrogate file (keys: :mod:`bubblecal.surrogates.surrogate_file`).

    ``diameter_um`` is the data's (2 x 0.25 um x median radius_dpd, e.g. 3.19 for the "3.2 um" SonoVue set);
    ``nominal_diameter_um`` the name the user gave (defaults to the same). Provenance of the training points:
    ``n_points_train`` (finite points), ``n_prefix_curves_train`` / ``n_prefix_points_train`` (failure-truncated
    prefix curves, NaN tails, and their points) and ``training_data``
    (:meth:`~bubblecal.surrogates.training.TrainingSet.truncation_summary`).

    Parameters
    ----------
    model : TrainedMLP
        The trained network.
    train_set : TrainingSet
        Its training curves (define the training box, DPD units).
    holdout_score : float
        Held-out median relative L2 error.
    data_hash : str
        Hash of the (filtered) data.
    extra_training : dict, optional
        Merged into the ``training`` entry (e.g. the sweep rows).
    nominal_diameter_um : float, optional
        Nominal bubble diameter [um].
    filter_report : FilterReport or dict, optional
        Recorded as ``filter`` (``as_dict``) when given.
    inputs : {'raw', 'diameter'}
        The network's input kind; ``diameter`` writes the keys of a network over the diameter (diameter range,
        loading range per size, response scale) instead of ``diameter_um`` / ``radius_dpd``.
    log_inputs : tuple of str
        Shell parameters the network takes as natural logarithms (written as ``log_inputs`` when not empty).

    Returns
    -------
    dict
        The metadata (``code_version`` and ``created_utc`` are added when the file is written).
    """
    setup = train_set.setup
    training = model.training_summary()
    training.update(extra_training or {})
    trunc = train_set.truncation_summary()
    md = {
        "setup": setup,
        "diameter_um": float(train_set.diameter_um),
        "nominal_diameter_um": float(train_set.diameter_um if nominal_diameter_um is None else nominal_diameter_um),
        "radius_dpd": float(np.median(train_set.radius_dpd)),
        "param_names": list(SHELL_PARAMETERS),
        "input_names": [*SHELL_PARAMETERS, X_INFO[setup][0]],
        "input_units": [PARAMETER_UNITS[k] for k in SHELL_PARAMETERS] + [X_INFO[setup][1]],
        "output_name": Y_INFO[setup][0],
        "output_units": Y_INFO[setup][1],
        "param_ranges": {k: list(v) for k, v in train_set.param_ranges().items()},
        "x_range": list(train_set.x_range()),
        "holdout_score": float(holdout_score),
        "holdout_metric": HOLDOUT_METRIC,
        "data_hash": data_hash,
        "architecture": {"hidden": list(model.hidden), "activation": "tanh", "output": "linear"},
        "training": training,
        "source": train_set.source,
        "n_curves_train": train_set.n_curves,
        "n_points_train": trunc["n_points"],
        "n_prefix_curves_train": trunc["n_prefix_curves"],
        "n_prefix_points_train": trunc["n_prefix_points"],
        "training_data": trunc,
    }
    if filter_report is not None:
        md["filter"] = filter_report.as_dict() if hasattr(filter_report, "as_dict") else dict(filter_report)
    if log_inputs:
        md["log_inputs"] = list(log_inputs)
    if inputs == "diameter":
        d = train_set.diameters_um
        valid = train_set.point_mask()
        per_size = x_per_size(setup, train_set.x, d[:, None])[valid]
        for key in ("diameter_um", "nominal_diameter_um", "radius_dpd"):
            md.pop(key)
        md.update(inputs="diameter", response_scale=RESPONSE_SCALES[setup],
                  input_names=[*md["input_names"], "diameter_um"], input_units=[*md["input_units"], "um"],
                  diameter_range_um=[float(d.min()), float(d.max())],
                  loading_range_per_size=[float(per_size.min()), float(per_size.max())])
    return md


def export_npz(model: TrainedMLP, path: str | Path, train_set: TrainingSet, holdout_score: float,
               data_hash: str, extra_training: dict | None = None, nominal_diameter_um: float | None = None,
               filter_report=None, inputs: str = "raw", extra_metadata: dict | None = None,
               log_inputs: tuple[str, ...] = ()) -> Path:
    """Write ``model`` as a surrogate ``.npz`` (training box = ``train_set``'s ranges).

    Parameters
    ----------
    model, train_set, holdout_score, data_hash, extra_training, nominal_diameter_um, filter_report, inputs, log_inputs
        As :func:`surrogate_metadata`.
    extra_metadata : dict, optional
        Further top-level metadata keys (e.g. ``ldo_score``).
    path : str or Path
        Output ``.npz`` (written atomically).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    SurrogateFormatError
        When the arrays or metadata are inconsistent (e.g. a zero standard deviation).
    """
    md = surrogate_metadata(model, train_set, holdout_score, data_hash, extra_training, nominal_diameter_um,
                            filter_report, inputs, log_inputs)
    md.update(extra_metadata or {})
    return save_surrogate(path, model.weights, model.biases, model.in_mean, model.in_std, model.out_mean,
                          model.out_std, md)


def export_sweep(result, path: str | Path, nominal_diameter_um: float | None = None, filter_report=None) -> Path:
    """Write the selected model of a sweep as a surrogate ``.npz``.

    Parameters
    ----------
    result : SweepResult
        The sweep (:func:`bubblecal.surrogates.training.run_sweep`).
    path : str or Path
        Output ``.npz``.
    nominal_diameter_um : float, optional
        Nominal bubble diameter [um].
    filter_report : FilterReport, optional
        The data's filter report, recorded in the metadata as provenance (``filter``).

    Returns
    -------
    Path
        ``path``.
    """
    b = result.best
    extra = {"holdout_seed": result.config.seed, "holdout_frac": result.config.holdout_frac,
             "n_curves_holdout": result.holdout_set.n_curves,
             "n_points_holdout": result.holdout_set.n_valid_points,
             "holdout": {k: b[k] for k in ("holdout_median", "holdout_p90", "holdout_n_scored", "holdout_n_skipped",
                                           "holdout_n_prefix", "holdout_median_prefix") if k in b},
             "sweep": [{k: r[k] for k in ("width", "depth", "n_params", "holdout_median", "holdout_p90", "ldo_median",
                                         "offgrid_median") if k in r} for r in result.rows]}
    top = {}
    if result.ldo_set is not None:
        extra["ldo"] = {k: b[k] for k in ("ldo_median", "ldo_p90", "ldo_max", "ldo_n_scored") if k in b}
        extra["n_curves_ldo"] = result.ldo_set.n_curves
        top = {"ldo_score": float(b["ldo_median"]), "ldo_bands_um": [list(x) for x in result.config.ldo_bands]}
    if result.offgrid_set is not None:
        extra["offgrid"] = {k: b[k] for k in ("offgrid_median", "offgrid_p90", "offgrid_max", "offgrid_n_scored")
                            if k in b}
        extra["offgrid"]["source"] = result.offgrid_set.source
        top["offgrid_score"] = float(b["offgrid_median"])
    return export_npz(result.best_model, path, result.train_set, result.score, result.data_hash, extra,
                      nominal_diameter_um, filter_report, inputs=result.inputs, extra_metadata=top,
                      log_inputs=result.config.log_inputs)


def export_onnx(model: TrainedMLP, path: str | Path) -> Path:
    """Export the full raw-input -> raw-output map (standardisation included) to ONNX.

    Parameters
    ----------
    model : TrainedMLP
        The trained network.
    path : str or Path
        Output ``.onnx`` (parent folders are created).

    Returns
    -------
    Path
        ``path``: input ``u`` float32 (n, 7 or 8) = the network inputs (ka, kb, b1, b2, a3, a4, x[, diameter_um])
        [DPD units; um], with the columns of the metadata's ``log_inputs`` as natural logarithms; output ``y``
        float32 (n, 1) = the network's target (the response, or over its size scale for a network over the
        diameter).
    """
    torch = require("torch", "train")
    require("onnx", "train")  # the exporter's own import, checked before anything is written

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    mod = model.torch_module(torch.float32)
    example = torch.zeros((2, model.layer_sizes[0]), dtype=torch.float32)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:  # TorchScript-based exporter: fast and sufficient for an MLP
            torch.onnx.export(mod, (example,), str(path), dynamo=False, input_names=["u"], output_names=["y"],
                              dynamic_axes={"u": {0: "n"}, "y": {0: "n"}}, opset_version=17)
        except (TypeError, RuntimeError, AttributeError):  # pragma: no cover - exporter variants
            torch.onnx.export(mod, (example,), str(path), input_names=["u"], output_names=["y"],
                              dynamic_shapes=({0: torch.export.Dim("n")},))
    return path
