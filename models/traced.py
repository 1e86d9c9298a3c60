"""Model arguments that stay traced: an MLP surrogate as a pytree, and curves padded to one length.

A compiled TMCMC program is shared by every model of one structure whose arrays are traced arguments
(:mod:`bubblecal.inference.tmcmc`). :class:`TracedSurrogate` makes a loaded surrogate's weights such
arguments, so curves whose networks have the same layer sizes share one compiled likelihood;
:func:`pad_curve` with the ``mask`` of :func:`~bubblecal.models.mechanical_model` lets curves of
different lengths share it too.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from bubblecal.surrogates.features import network_inputs, response_scale
from bubblecal.surrogates.mlp import mlp_forward

__all__ = ["TracedSurrogate", "pad_curve"]


@jax.tree_util.register_pytree_node_class
class TracedSurrogate:
    """A loaded MLP surrogate (:class:`bubblecal.surrogates.bundle.Surrogate`) as a pytree of its arrays.

    Same call ``(params[..., 6], x[...]) -> y[...]`` (DPD units) and the same arithmetic as the
    surrogate, but the weights and normalisations are pytree leaves: given to a model as an argument
    they are traced data of a compiled TMCMC program (not constants compiled into it), so curves whose
    networks have the same layer sizes and setup share one compiled likelihood.

    Parameters
    ----------
    weights, biases : sequence of array_like
        Layer weights and biases of the network.
    in_mean, in_std, out_mean, out_std : array_like
        Input and output normalisations.
    setup : {'compression', 'indentation'}
        The surrogate's loading protocol (checked by :func:`resolve_setup`).
    param_names : tuple of str
        The surrogate's parameter inputs.
    inputs : {'raw', 'diameter'}
        The network's input kind (:mod:`bubblecal.surrogates.features`).
    diameter_um : float or array_like, optional
        The bound bubble diameter [um] of a network over the diameter: a traced leaf too, so bubbles of
        different sizes share one compiled likelihood.
    log_inputs : tuple of str
        Shell parameters the network takes as natural logarithms (metadata ``log_inputs``).
    """

    def __init__(self, weights, biases, in_mean, in_std, out_mean, out_std, setup: str, param_names: tuple,
                 inputs: str = "raw", diameter_um=None, log_inputs: tuple = ()):
        self.weights, self.biases = tuple(weights), tuple(biases)
        self.in_mean, self.in_std, self.out_mean, self.out_std = in_mean, in_std, out_mean, out_std
        self.setup = setup
        self.param_names = tuple(param_names)
        self.inputs = inputs
        self.diameter_um = diameter_um
        self.log_inputs = tuple(log_inputs)

    @classmethod
    def wrap(cls, surrogate):
        """The surrogate as a :class:`TracedSurrogate`.

        Parameters
        ----------
        surrogate : object
            A loaded MLP surrogate, a :class:`TracedSurrogate`, or any other callable.

        Returns
        -------
        TracedSurrogate or object
            The wrapped MLP surrogate; anything that is not an MLP surrogate unchanged.
        """
        fields = ("weights", "biases", "in_mean", "in_std", "out_mean", "out_std", "setup", "param_names")
        if isinstance(surrogate, cls) or not all(hasattr(surrogate, f) for f in fields):
            return surrogate
        inputs = getattr(surrogate, "inputs", "raw")
        diameter = jnp.asarray(surrogate.diameter_um) if inputs == "diameter" else None
        return cls(*(getattr(surrogate, f) for f in fields), inputs=inputs, diameter_um=diameter,
                   log_inputs=tuple(getattr(surrogate, "log_inputs", ())))

    def __call__(self, params, x):
        """Surrogate output y[...] at ``params[..., 6]`` and ``x[...]`` (DPD units)."""
        u = network_inputs(self.inputs, params, x, self.diameter_um, xp=jnp,  # as Surrogate.__call__
                           log_inputs=self.log_inputs)
        y = mlp_forward(self.weights, self.biases, self.in_mean, self.in_std, self.out_mean, self.out_std, u)
        y = y[..., 0]
        if self.inputs == "diameter":
            y = y * response_scale(self.inputs, self.setup, jnp.asarray(params), self.diameter_um, xp=jnp)
        return y

    def tree_flatten(self):
        """Pytree children (the arrays, and the bound diameter) and auxiliary data (setup, names, input kind,
        logged inputs)."""
        return (self.weights, self.biases, self.in_mean, self.in_std, self.out_mean, self.out_std,
                self.diameter_um), (self.setup, self.param_names, self.inputs, self.log_inputs)

    @classmethod
    def tree_unflatten(cls, aux, children):
        """Rebuild from :meth:`tree_flatten`'s output."""
        *arrays, diameter = children
        setup, names, inputs, log_inputs = aux
        return cls(*arrays, setup, names, inputs=inputs, diameter_um=diameter, log_inputs=log_inputs)


def pad_curve(x, y, length: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A curve padded to ``length`` points, with the mask for :func:`mechanical_model`.

    Padding repeats the last x (a point the surrogate evaluates normally) with y = 0, and the mask
    (True on the real points) removes those points from the likelihood and from max |y|.

    Parameters
    ----------
    x, y : array_like
        The curve (DPD units).
    length : int
        Padded length (>= the curve's).

    Returns
    -------
    x, y : numpy.ndarray
        Padded curve, ``length`` points each.
    mask : numpy.ndarray
        (length,) booleans, True on the real points.

    Raises
    ------
    ValueError
        If ``length`` is shorter than the curve.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    n = len(x)
    if length < n:
        raise ValueError(f"cannot pad a curve of {n} points to {length}")
    pad = length - n
    return (np.concatenate([x, np.full(pad, x[-1])]), np.concatenate([y, np.zeros(pad)]),
            np.arange(length) < n)
