"""A loaded mechanical MLP surrogate: ``(params[..., 6], x[...]) -> y[...]`` in pure JAX, with its training box.

Inputs and outputs are DPD units (:mod:`bubblecal.surrogates.axes`): compression x = imposed displacement
[DPD length], y = force [DPD force]; indentation x = applied force [DPD force], y = depth [DPD length].
Surrogates are read from their ``.npz`` file by :func:`bubblecal.surrogates.load`
(:mod:`bubblecal.surrogates.surrogate_file`). Nothing here imports torch or onnx.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from bubblecal.surrogates.mlp import mlp_forward, surrogate_inputs

__all__ = ["Surrogate", "OutOfDomainError", "SurrogateDomainWarning"]


class OutOfDomainError(ValueError):
    """Evaluation requested outside the box of parameters / loading coordinates seen in training."""


class SurrogateDomainWarning(UserWarning):
    """Evaluation outside the training box (see :meth:`Surrogate.check_domain`)."""


class Surrogate:
    """A loaded MLP surrogate: callable ``(params[..., 6], x[...]) -> y[...]``, pure JAX.

    ``params`` holds ``(ka, kb, b1, b2, a3, a4)`` [DPD units] in the last axis; its leading shape broadcasts
    against ``x``'s shape (e.g. ``params[:, None, :]`` with ``x[None, :]`` gives a (n_sets, n_points) grid).
    The call is jit/vmap/grad-ready (weights are constants of the trace).

    Evaluation outside the training box is never silent: use :meth:`in_training_box` (a mask, jit-friendly),
    :meth:`check_domain` (warns or raises, host side) or :meth:`evaluate` (checks, then evaluates). The plain
    call does not check, so that it can run under ``jit``.

    Parameters
    ----------
    weights, biases : sequence of array_like
        Layer weights (fan_in, fan_out) and biases (fan_out,), input side first (:mod:`bubblecal.surrogates.mlp`).
    in_mean, in_std : array_like, shape (7,)
        Standardisation of the raw inputs (ka, kb, b1, b2, a3, a4, x).
    out_mean, out_std : array_like, shape (1,)
        Standardisation of the raw output.
    metadata : Mapping
        The file's metadata (keys: :mod:`bubblecal.surrogates.surrogate_file`).
    path : str or Path, optional
        The file it was loaded from (named in messages).
    """

    def __init__(self, weights, biases, in_mean, in_std, out_mean, out_std, metadata: Mapping,
                 path: str | Path | None = None):
        self.weights = tuple(jnp.asarray(w) for w in weights)
        self.biases = tuple(jnp.asarray(b) for b in biases)
        self.in_mean = jnp.asarray(in_mean, dtype=jnp.float32)
        self.in_std = jnp.asarray(in_std, dtype=jnp.float32)
        self.out_mean = jnp.asarray(out_mean, dtype=jnp.float32)
        self.out_std = jnp.asarray(out_std, dtype=jnp.float32)
        self.metadata = dict(metadata)
        self.path = None if path is None else Path(path)
        md = self.metadata
        self.setup: str = md["setup"]
        self.diameter_um: float = float(md["diameter_um"])
        self.nominal_diameter_um: float = float(md.get("nominal_diameter_um", self.diameter_um))
        self.radius_dpd: float = float(md["radius_dpd"])
        self.param_names: tuple[str, ...] = tuple(md["param_names"])
        self.input_names: tuple[str, ...] = tuple(md["input_names"])
        self.param_ranges: dict[str, tuple[float, float]] = {
            k: (float(v[0]), float(v[1])) for k, v in md["param_ranges"].items()}
        self.x_range: tuple[float, float] = (float(md["x_range"][0]), float(md["x_range"][1]))
        self.holdout_score: float = float(md["holdout_score"])
        self.data_hash: str = str(md["data_hash"])
        self.architecture: dict = dict(md["architecture"])
        self._lo = np.array([self.param_ranges[k][0] for k in self.param_names])
        self._hi = np.array([self.param_ranges[k][1] for k in self.param_names])

    def __call__(self, params, x):
        """Surrogate response at (params, x).

        Parameters
        ----------
        params : array_like, shape (..., 6)
            Shell parameters (ka, kb, b1, b2, a3, a4) [DPD units].
        x : array_like
            Loading coordinate [DPD length (compression) or DPD force (indentation)], broadcast against
            ``params[..., 0]``.

        Returns
        -------
        jax.Array
            Response of the broadcast shape [DPD force (compression) or DPD length (indentation)].
        """
        u = surrogate_inputs(params, x, self.param_names)
        y = mlp_forward(self.weights, self.biases, self.in_mean, self.in_std, self.out_mean,
                        self.out_std, u)
        return y[..., 0]

    def in_training_box(self, params, x, rtol: float = 1e-6):
        """Boolean mask of the points inside the training box (jit-friendly).

        A point is inside when every parameter lies in ``param_ranges`` and x in ``x_range``, each widened by
        ``rtol`` times the range width (round-off allowance).

        Parameters
        ----------
        params : array_like, shape (..., 6)
            Shell parameters [DPD units].
        x : array_like
            Loading coordinate [DPD length or DPD force].
        rtol : float
            Widening of each range, relative to its width.

        Returns
        -------
        jax.Array of bool
            Shape of the broadcast output.
        """
        params = jnp.asarray(params)
        x = jnp.asarray(x)
        width = self._hi - self._lo
        lo = jnp.asarray(self._lo - rtol * width)
        hi = jnp.asarray(self._hi + rtol * width)
        p_ok = jnp.all((params >= lo) & (params <= hi), axis=-1)
        xw = self.x_range[1] - self.x_range[0]
        x_ok = (x >= self.x_range[0] - rtol * xw) & (x <= self.x_range[1] + rtol * xw)
        shape = jnp.broadcast_shapes(p_ok.shape, x_ok.shape)
        return jnp.broadcast_to(p_ok, shape) & jnp.broadcast_to(x_ok, shape)

    def check_domain(self, params, x, action: str = "warn", rtol: float = 1e-6) -> np.ndarray:
        """Check the training box on the host; warn (``action='warn'``) or raise (``'raise'``).

        The message names every offending input with the number of points outside and the extremes requested
        versus the training range.

        Parameters
        ----------
        params : array_like, shape (..., 6)
            Shell parameters [DPD units].
        x : array_like
            Loading coordinate [DPD length or DPD force].
        action : {'warn', 'raise'}
            Emit a :class:`SurrogateDomainWarning` or raise.
        rtol : float
            Widening of each range, relative to its width.

        Returns
        -------
        numpy.ndarray of bool
            The mask of inside points.

        Raises
        ------
        OutOfDomainError
            With ``action='raise'`` when a point is outside.
        ValueError
            For an unknown ``action``.
        """
        if action not in ("warn", "raise"):
            raise ValueError(f"action must be 'warn' or 'raise', got {action!r}")
        mask = np.asarray(self.in_training_box(params, x, rtol=rtol))
        if mask.all():
            return mask
        p = np.asarray(params, dtype=float).reshape(-1, len(self.param_names))
        xv = np.asarray(x, dtype=float).ravel()
        parts = []
        for j, name in enumerate(self.param_names):
            lo, hi = self.param_ranges[name]
            w = (hi - lo) * rtol
            bad = (p[:, j] < lo - w) | (p[:, j] > hi + w)
            if bad.any():
                parts.append(f"{name}: {int(bad.sum())} of {len(bad)} parameter sets outside "
                             f"[{lo:.6g}, {hi:.6g}] (requested {p[:, j].min():.6g}..{p[:, j].max():.6g})")
        lo, hi = self.x_range
        w = (hi - lo) * rtol
        bad = (xv < lo - w) | (xv > hi + w)
        if bad.any():
            xname = self.input_names[-1]
            parts.append(f"{xname}: {int(bad.sum())} of {len(bad)} points outside [{lo:.6g}, {hi:.6g}] "
                         f"(requested {xv.min():.6g}..{xv.max():.6g})")
        where = f" ({self.path})" if self.path else ""
        msg = (f"{self.setup} {self.diameter_um:g} um surrogate{where}: {int((~mask).sum())} of "
               f"{mask.size} evaluations outside the training box; " + "; ".join(parts))
        if action == "raise":
            raise OutOfDomainError(msg)
        warnings.warn(msg, SurrogateDomainWarning, stacklevel=2)
        return mask

    def evaluate(self, params, x, action: str = "warn"):
        """Check the domain (:meth:`check_domain`), then evaluate.

        Parameters
        ----------
        params, x
            As :meth:`__call__`.
        action : {'warn', 'raise'}
            As :meth:`check_domain`.

        Returns
        -------
        y : jax.Array
            The response (:meth:`__call__`).
        inside : numpy.ndarray of bool
            The mask of inside points.

        Raises
        ------
        OutOfDomainError
            With ``action='raise'`` when a point is outside.
        """
        mask = self.check_domain(params, x, action=action)
        return self(params, x), mask

    def __repr__(self) -> str:
        return (f"Surrogate({self.setup}, {self.diameter_um:g} um, hidden={self.architecture.get('hidden')}, "
                f"holdout={self.holdout_score:.4g}, data_hash={self.data_hash[:12]})")
