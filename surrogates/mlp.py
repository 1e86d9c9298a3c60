"""Pure-JAX forward pass of a standardised tanh MLP over plain weight arrays (no torch, no onnx).

The network maps the 7 standardised inputs ``(ka, kb, b1, b2, a3, a4, x)`` to one standardised
output; hidden layers use ``tanh``, the output layer is linear:

    z = (u - in_mean) / in_std
    h_0 = z;  h_{l+1} = tanh(h_l W_l + b_l)  (l < L-1);  out = h_{L-1} W_{L-1} + b_{L-1}
    y = out * out_std + out_mean

``W_l`` has shape (fan_in, fan_out) (the transpose of torch's ``Linear.weight``). Inputs are the shell
parameters [DPD units] and the loading coordinate [DPD length or DPD force]; the output is the response
[DPD force or DPD length] (:mod:`bubblecal.surrogates.axes`).
"""

from __future__ import annotations

from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["mlp_forward", "standardised_forward", "matmul_floor_forward", "flops_per_point",
           "xavier_uniform_weights"]


def standardised_forward(weights: Sequence, biases: Sequence, z, xp=jnp):
    """Forward pass on already standardised inputs (tanh hidden layers, linear output).

    Parameters
    ----------
    weights, biases : sequence of array_like
        Layer weights (fan_in, fan_out) and biases (fan_out,), input side first.
    z : array_like, shape (..., n_in)
        Standardised inputs.
    xp : module
        Array module: ``jax.numpy`` (default) or ``numpy`` (float64 reference on the host).

    Returns
    -------
    array, shape (..., n_out)
        Standardised outputs.
    """
    h = z
    last = len(weights) - 1
    for i, (w, b) in enumerate(zip(weights, biases, strict=True)):
        # full float32 products on GPUs too (their default TF32 matmuls err by ~1e-3 relative)
        h = (jnp.matmul(h, w, precision=jax.lax.Precision.HIGHEST) if xp is jnp else h @ w) + b
        if i < last:
            h = xp.tanh(h)
    return h


def mlp_forward(weights, biases, in_mean, in_std, out_mean, out_std, u, xp=jnp):
    """Full map from raw inputs to raw outputs: standardise, :func:`standardised_forward`, de-standardise.

    Parameters
    ----------
    weights, biases : sequence of array_like
        Layer weights (fan_in, fan_out) and biases (fan_out,), input side first.
    in_mean, in_std : array_like, shape (n_in,)
        Standardisation of the raw inputs.
    out_mean, out_std : array_like, shape (n_out,)
        Standardisation of the raw outputs.
    u : array_like, shape (..., n_in)
        Raw inputs (ka, kb, b1, b2, a3, a4, x) [DPD units].
    xp : module
        Array module (``jax.numpy`` or ``numpy``).

    Returns
    -------
    array, shape (..., n_out)
        Raw outputs [DPD force or DPD length].
    """
    z = (u - in_mean) / in_std
    return standardised_forward(weights, biases, z, xp=xp) * out_std + out_mean


def matmul_floor_forward(weights, biases, u):
    """The same chain of matrix products with no activation or normalisation (a throughput floor for benchmarks).

    Parameters
    ----------
    weights, biases : sequence of array_like
        Layer weights (fan_in, fan_out) and biases (fan_out,).
    u : array_like, shape (..., n_in)
        Inputs.

    Returns
    -------
    array, shape (..., n_out)
        ``u`` through the affine layers only.
    """
    h = u
    for w, b in zip(weights, biases, strict=True):
        h = h @ w + b
    return h


def flops_per_point(layer_sizes: Sequence[int]) -> int:
    """Floating-point operations of one forward pass (2·fan_in·fan_out per layer, multiply-add).

    Parameters
    ----------
    layer_sizes : sequence of int
        Widths from the input to the output layer.

    Returns
    -------
    int
        FLOPs per evaluated point.
    """
    return int(sum(2 * a * b for a, b in zip(layer_sizes[:-1], layer_sizes[1:], strict=True)))


def xavier_uniform_weights(layer_sizes: Sequence[int], seed: int = 0, dtype=np.float32):
    """Random Xavier-uniform weights and zero biases (numpy), e.g. for throughput benchmarks and initial weights.

    Parameters
    ----------
    layer_sizes : sequence of int
        Widths from the input to the output layer.
    seed : int
        Seed of ``numpy.random.default_rng``.
    dtype : numpy dtype
        Dtype of the arrays.

    Returns
    -------
    weights, biases : list of numpy.ndarray
        Weights (fan_in, fan_out) and zero biases (fan_out,).
    """
    rng = np.random.default_rng(seed)
    weights, biases = [], []
    for fan_in, fan_out in zip(layer_sizes[:-1], layer_sizes[1:], strict=True):
        bound = np.sqrt(6.0 / (fan_in + fan_out))
        weights.append(rng.uniform(-bound, bound, size=(fan_in, fan_out)).astype(dtype))
        biases.append(np.zeros(fan_out, dtype=dtype))
    return weights, biases
