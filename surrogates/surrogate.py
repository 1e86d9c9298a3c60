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

import jax
import jax.numpy as jnp
import numpy as np

from bubblecal.surrogates.features import network_inputs, radius_of_diameter, response_scale, x_per_size
from bubblecal.surrogates.mlp import mlp_forward

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

    A network over the diameter (metadata ``inputs = 'diameter'``, :mod:`bubblecal.surrogates.features`) takes
    the bubble diameter as well: pass ``diameter_um`` to the call, or bind one with :meth:`at_diameter`, which
    returns a surrogate that behaves like a per-diameter one (what :meth:`Bundle.get
    <bubblecal.surrogates.Bundle.get>` hands to the models). Its training box adds the diameter range and, for
    compression, the displacement as a fraction of the diameter.

    Parameters
    ----------
    weights, biases : sequence of array_like
        Layer weights (fan_in, fan_out) and biases (fan_out,), input side first (:mod:`bubblecal.surrogates.mlp`).
    in_mean, in_std : array_like, shape (7,) or (8,)
        Standardisation of the raw inputs (ka, kb, b1, b2, a3, a4, x[, diameter_um]).
    out_mean, out_std : array_like, shape (1,)
        Standardisation of the raw output.
    metadata : Mapping
        The file's metadata (keys: :mod:`bubblecal.surrogates.surrogate_file`).
    path : str or Path, optional
        The file it was loaded from (named in messages).
    diameter_um : float, optional
        The bound diameter [um] of a network over the diameter (:meth:`at_diameter`).
    """

    def __init__(self, weights, biases, in_mean, in_std, out_mean, out_std, metadata: Mapping,
                 path: str | Path | None = None, diameter_um: float | None = None):
        # jax.device_put gives the dtypes jnp.asarray gives, without compiling a copy program per array shape
        self.weights = tuple(jax.device_put(np.asarray(w)) for w in weights)
        self.biases = tuple(jax.device_put(np.asarray(b)) for b in biases)
        self.in_mean = jax.device_put(np.asarray(in_mean, dtype=np.float32))
        self.in_std = jax.device_put(np.asarray(in_std, dtype=np.float32))
        self.out_mean = jax.device_put(np.asarray(out_mean, dtype=np.float32))
        self.out_std = jax.device_put(np.asarray(out_std, dtype=np.float32))
        self.metadata = dict(metadata)
        self.path = None if path is None else Path(path)
        md = self.metadata
        self.setup: str = md["setup"]
        self.inputs: str = md.get("inputs", "raw")
        self.log_inputs: tuple[str, ...] = tuple(md.get("log_inputs", ()))
        if self.inputs == "diameter":
            self.diameter_range_um = (float(md["diameter_range_um"][0]), float(md["diameter_range_um"][1]))
            self.loading_range_per_size = (float(md["loading_range_per_size"][0]),
                                           float(md["loading_range_per_size"][1]))
            self.diameter_um = float("nan") if diameter_um is None else float(diameter_um)
            self.radius_dpd = float(radius_of_diameter(self.diameter_um))
        else:
            self.diameter_um = float(md["diameter_um"])
            self.radius_dpd = float(md["radius_dpd"])
        self.nominal_diameter_um: float = float(md.get("nominal_diameter_um", self.diameter_um))
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

    @property
    def over_diameter(self) -> bool:
        """True for one network over the sizes (inputs include the diameter)."""
        return self.inputs == "diameter"

    def _diameter(self, diameter_um):
        """The diameter of a call: the argument, else the bound one (a network over the diameter only)."""
        if not self.over_diameter:
            if diameter_um is not None:
                raise ValueError(f"the {self.setup} {self.diameter_um:g} um surrogate is trained at one diameter; "
                                 "it takes no diameter_um")
            return None
        if diameter_um is None:
            if not np.isfinite(self.diameter_um):
                raise ValueError(f"the {self.setup} surrogate over {self.diameter_range_um[0]:g}-"
                                 f"{self.diameter_range_um[1]:g} um needs diameter_um (or bind one: at_diameter)")
            return self.diameter_um
        return diameter_um

    def at_diameter(self, diameter_um: float, rtol: float = 1e-6) -> Surrogate:
        """This network over the diameter bound to one diameter: a per-diameter surrogate for the models.

        Parameters
        ----------
        diameter_um : float
            Bubble diameter [um], inside :attr:`diameter_range_um`.
        rtol : float
            Widening of the range, relative to its width.

        Returns
        -------
        Surrogate
            The same weights; calls, box checks and messages at ``diameter_um``.

        Raises
        ------
        ValueError
            For a per-diameter surrogate.
        OutOfDomainError
            When the diameter lies outside the trained range.
        """
        if not self.over_diameter:
            raise ValueError(f"the {self.setup} {self.diameter_um:g} um surrogate is trained at one diameter")
        lo, hi = self.diameter_range_um
        w = rtol * (hi - lo)
        d = float(diameter_um)
        if not (lo - w <= d <= hi + w):
            where = f" ({self.path})" if self.path else ""
            raise OutOfDomainError(f"{self.setup} surrogate{where}: diameter {d:g} um outside its trained range "
                                   f"[{lo:g}, {hi:g}] um")
        return Surrogate(self.weights, self.biases, self.in_mean, self.in_std, self.out_mean, self.out_std,
                         self.metadata, path=self.path, diameter_um=d)

    def __call__(self, params, x, diameter_um=None):
        """Surrogate response at (params, x) [and the diameter].

        Parameters
        ----------
        params : array_like, shape (..., 6)
            Shell parameters (ka, kb, b1, b2, a3, a4) [DPD units].
        x : array_like
            Loading coordinate [DPD length (compression) or DPD force (indentation)], broadcast against
            ``params[..., 0]``.
        diameter_um : float or array_like, optional
            Bubble diameter [um], broadcast like ``x`` (a network over the diameter; default: the bound one).

        Returns
        -------
        jax.Array
            Response of the broadcast shape [DPD force (compression) or DPD length (indentation)].

        Raises
        ------
        ValueError
            For a diameter given to a per-diameter surrogate, or none to an unbound network over the diameter.
        """
        d = self._diameter(diameter_um)
        u = network_inputs(self.inputs, params, x, d, xp=jnp, log_inputs=self.log_inputs)
        y = mlp_forward(self.weights, self.biases, self.in_mean, self.in_std, self.out_mean,
                        self.out_std, u)[..., 0]
        if self.over_diameter:
            y = y * response_scale(self.inputs, self.setup, jnp.asarray(params), d, xp=jnp)
        return y

    def loading_range(self, diameter_um=None) -> tuple[float, float]:
        """The loading coordinate's training range at a diameter, in the coordinate's own units.

        Parameters
        ----------
        diameter_um : float, optional
            Bubble diameter [um] (a network over the diameter; default: the bound one).  A per-diameter
            surrogate takes none.

        Returns
        -------
        (float, float)
            ``x_range`` of a per-diameter surrogate; for a network over the diameter ``loading_range_per_size``
            back in DPD length (compression: times the diameter in DPD length) or DPD force (indentation).

        Raises
        ------
        ValueError
            A diameter given to a per-diameter surrogate, or none to an unbound network over the diameter.
        """
        d = self._diameter(diameter_um)
        if not self.over_diameter:
            return tuple(float(v) for v in self.x_range)
        unit = float(x_per_size(self.setup, 1.0, d))  # the per-size coordinate of x = 1
        return tuple(float(v) / unit for v in self.loading_range_per_size)

    def _loading_box(self, x, diameter_um, xp=jnp):
        """(coordinate, range) of the loading check: x and ``x_range``, or the per-size coordinate and range."""
        if not self.over_diameter:
            return x, self.x_range
        return x_per_size(self.setup, x, diameter_um, xp=xp), self.loading_range_per_size

    def in_training_box(self, params, x, rtol: float = 1e-6, diameter_um=None):
        """Boolean mask of the points inside the training box (jit-friendly).

        A point is inside when every parameter lies in ``param_ranges`` and x in ``x_range`` (a network over the
        diameter: the diameter in ``diameter_range_um`` and the loading per size in ``loading_range_per_size``),
        each widened by ``rtol`` times the range width (round-off allowance).

        Parameters
        ----------
        params : array_like, shape (..., 6)
            Shell parameters [DPD units].
        x : array_like
            Loading coordinate [DPD length or DPD force].
        rtol : float
            Widening of each range, relative to its width.
        diameter_um : float or array_like, optional
            Bubble diameter [um] (a network over the diameter; default: the bound one).

        Returns
        -------
        jax.Array of bool
            Shape of the broadcast output.
        """
        return self._in_box(params, x, rtol, self._diameter(diameter_um), jnp)

    def _in_box(self, params, x, rtol: float, d, xp):
        """:meth:`in_training_box` with the array module ``xp`` (numpy on the host: no JAX program per shape)."""
        params = xp.asarray(params)
        x = xp.asarray(x)
        width = self._hi - self._lo
        lo = xp.asarray(self._lo - rtol * width)
        hi = xp.asarray(self._hi + rtol * width)
        p_ok = xp.all((params >= lo) & (params <= hi), axis=-1)
        xc, (xlo, xhi) = self._loading_box(x, d, xp)
        xw = xhi - xlo
        x_ok = (xc >= xlo - rtol * xw) & (xc <= xhi + rtol * xw)
        if self.over_diameter:
            dlo, dhi = self.diameter_range_um
            dw = rtol * (dhi - dlo)
            dd = xp.asarray(d)
            x_ok = x_ok & (dd >= dlo - dw) & (dd <= dhi + dw)
        shape = np.broadcast_shapes(p_ok.shape, x_ok.shape)
        return xp.broadcast_to(p_ok, shape) & xp.broadcast_to(x_ok, shape)

    def check_domain(self, params, x, action: str = "warn", rtol: float = 1e-6, diameter_um=None) -> np.ndarray:
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
        diameter_um : float or array_like, optional
            Bubble diameter [um] (a network over the diameter; default: the bound one).

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
        d = self._diameter(diameter_um)
        mask = np.asarray(self._in_box(params, x, rtol, d, np))
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
        xc, (lo, hi) = self._loading_box(xv, d)
        xc = np.asarray(xc, dtype=float).ravel()
        w = (hi - lo) * rtol
        bad = (xc < lo - w) | (xc > hi + w)
        if bad.any():
            xname = self.input_names[6] + (" / diameter" if self.over_diameter and self.setup == "compression"
                                           else "")
            parts.append(f"{xname}: {int(bad.sum())} of {len(bad)} points outside [{lo:.6g}, {hi:.6g}] "
                         f"(requested {xc.min():.6g}..{xc.max():.6g})")
        if self.over_diameter:
            dv = np.asarray(d, dtype=float).ravel()
            dlo, dhi = self.diameter_range_um
            dw = rtol * (dhi - dlo)
            bad = (dv < dlo - dw) | (dv > dhi + dw)
            if bad.any():
                parts.append(f"diameter_um: {dv[bad].min():g}..{dv[bad].max():g} outside [{dlo:g}, {dhi:g}] um")
        where = f" ({self.path})" if self.path else ""
        msg = (f"{self.setup} {self._size_label()} surrogate{where}: {int((~mask).sum())} of "
               f"{mask.size} evaluations outside the training box; " + "; ".join(parts))
        if action == "raise":
            raise OutOfDomainError(msg)
        warnings.warn(msg, SurrogateDomainWarning, stacklevel=2)
        return mask

    def _size_label(self) -> str:
        """'3.2 um', or '1.5-8 um' (at 3.7 um) for a network over the diameter."""
        if not self.over_diameter:
            return f"{self.diameter_um:g} um"
        lo, hi = self.diameter_range_um
        at = f" at {self.diameter_um:g} um" if np.isfinite(self.diameter_um) else ""
        return f"{lo:g}-{hi:g} um{at}"

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
        logged = f", log_inputs={','.join(self.log_inputs)}" if self.log_inputs else ""
        return (f"Surrogate({self.setup}, {self._size_label()}, hidden={self.architecture.get('hidden')}{logged}, "
                f"holdout={self.holdout_score:.4g}, data_hash={self.data_hash[:12]})")
