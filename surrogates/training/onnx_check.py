"""ONNX parity check: onnxruntime output of an exported model versus the JAX surrogate (and torch).

Relative error is measured on the scale of the output: ``max |a - b| / max |b|`` over the
evaluation points (an elementwise ratio is meaningless where the response passes through 0,
e.g. indentation depth at zero force).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bubblecal._extras import require
from bubblecal.surrogates.features import network_inputs, response_scale

__all__ = ["onnx_predict", "scaled_max_rel_diff", "onnx_parity"]


def scaled_max_rel_diff(a, b) -> float:
    """Largest difference on the scale of the output: ``max |a - b| / max |b|``.

    Parameters
    ----------
    a, b : array_like
        Compared values (same units); ``b`` is the reference.

    Returns
    -------
    float
        The scaled difference.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), np.finfo(float).tiny))


def onnx_predict(onnx_path: str | Path, u) -> np.ndarray:
    """Evaluate an exported model with onnxruntime (CPU).

    Parameters
    ----------
    onnx_path : str or Path
        Model from :func:`bubblecal.surrogates.training.export_onnx`.
    u : array_like, shape (n, 7) or (n, 8)
        Raw inputs (ka, kb, b1, b2, a3, a4, x[, diameter_um]) [DPD units; um]; the graph gets them with the
        surrogate's ``log_inputs`` columns logged, as it was exported.

    Returns
    -------
    numpy.ndarray, shape (n,)
        Raw network outputs (float32) [DPD force or DPD length; over its size scale for a network over the
        diameter].
    """
    ort = require("onnxruntime", "train")

    sess = ort.InferenceSession(str(onnx_path), providers=["CPUExecutionProvider"])
    name = sess.get_inputs()[0].name
    return sess.run(None, {name: np.asarray(u, dtype=np.float32)})[0][:, 0]


def onnx_parity(onnx_path: str | Path, surrogate, u) -> dict:
    """Compare onnxruntime with a loaded :class:`~bubblecal.surrogates.Surrogate` on ``u``.

    Parameters
    ----------
    onnx_path : str or Path
        Exported model.
    surrogate : Surrogate
        The same model loaded from its ``.npz``.
    u : array_like, shape (n, 7) or (n, 8)
        Raw inputs (ka, kb, b1, b2, a3, a4, x[, diameter_um]) [DPD units; um]; the graph gets them with the
        surrogate's ``log_inputs`` columns logged, as it was exported.

    Returns
    -------
    dict
        ``{"n": number of points, "max_rel_diff": scaled_max_rel_diff(onnx, surrogate)}``; for a network over
        the diameter both sides are the network's target (the response over its size scale: the ONNX graph is
        the bare network).
    """
    u = np.asarray(u, dtype=float)
    over = getattr(surrogate, "over_diameter", False)
    u_net = network_inputs("diameter" if over else "raw", u[:, :6], u[:, 6], u[:, 7] if over else None,
                           log_inputs=getattr(surrogate, "log_inputs", ()))
    y_onnx = onnx_predict(onnx_path, u_net)
    if over:
        d = u[:, 7]
        scale = response_scale("diameter", surrogate.setup, u[:, :6], d)
        y_jax = np.asarray(surrogate(u[:, :6], u[:, 6], d)) / scale
    else:
        y_jax = np.asarray(surrogate(u[:, :6], u[:, 6]))
    return {"n": int(u.shape[0]), "max_rel_diff": scaled_max_rel_diff(y_onnx, y_jax)}
