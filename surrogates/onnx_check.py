"""ONNX parity check: onnxruntime output of an exported model versus the JAX surrogate (and torch).

Relative error is measured on the scale of the output: ``max |a - b| / max |b|`` over the
evaluation points (an elementwise ratio is meaningless where the response passes through 0,
e.g. indentation depth at zero force).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["onnx_predict", "scaled_max_rel_diff", "onnx_parity"]


def scaled_max_rel_diff(a, b) -> float:
    """``max |a - b| / max |b|``."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), np.finfo(float).tiny))


def onnx_predict(onnx_path: str | Path, u) -> np.ndarray:
    """Evaluate an exported model on raw inputs ``u`` (n, 7) with onnxruntime (CPU); returns (n,)."""
    import onnxruntime as ort

    sess = ort.InferenceSession(str(onnx_path), providers=["CPUExecutionProvider"])
    name = sess.get_inputs()[0].name
    return sess.run(None, {name: np.asarray(u, dtype=np.float32)})[0][:, 0]


def onnx_parity(onnx_path: str | Path, surrogate, u) -> dict:
    """Compare onnxruntime with a loaded :class:`~bubblecal.surrogates.bundle.Surrogate` on ``u``.

    Returns ``{"n": ..., "max_rel_diff": ...}``.
    """
    u = np.asarray(u, dtype=float)
    y_onnx = onnx_predict(onnx_path, u)
    y_jax = np.asarray(surrogate(u[:, :6], u[:, 6]))
    return {"n": int(u.shape[0]), "max_rel_diff": scaled_max_rel_diff(y_onnx, y_jax)}
