"""Cache keys of the compiled TMCMC programs: hashable stand-ins for a model's fixed arguments and arrays."""

from __future__ import annotations

import enum

import jax
import numpy as np


class _DataSlot(enum.Enum):
    """Marks the place of a traced array among a model's fixed arguments (a value with a stable key)."""

    DATA = "data"


#: The one marker of a traced array's place.
DATA = _DataSlot.DATA


class _Identity:
    """Hashable stand-in of an unhashable fixed argument: equal only to the same object (kept alive)."""

    __slots__ = ("obj",)

    def __init__(self, obj):
        self.obj = obj

    def __eq__(self, other):
        return isinstance(other, _Identity) and other.obj is self.obj

    def __hash__(self):
        return id(self.obj)


def _static_key(value):
    """Cache key of a fixed argument: the value itself when hashable, else its identity."""
    try:
        hash(value)
    except TypeError:
        return _Identity(value)
    return (type(value), value)  # the type keeps 1 / 1.0 / True apart


def _fingerprint(tree):
    """Hashable value of a pytree of concrete arrays (e.g. a bijection with its bounds)."""
    leaves, treedef = jax.tree_util.tree_flatten(tree)
    return treedef, tuple((np.shape(v), str(np.asarray(v).dtype), np.asarray(v).tobytes()) for v in leaves)


def _aval_key(value):
    """(shape, dtype as jit sees it, weak type) of a data leaf."""
    dtype = jax.dtypes.canonicalize_dtype(np.dtype(value.dtype))
    return tuple(np.shape(value)), str(dtype), bool(getattr(value, "weak_type", False))
