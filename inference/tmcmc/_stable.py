"""Stable digests of what builds a compiled program: equal across processes exactly when the inputs are equal.

The in-process program cache (``_programs``) keys programs by objects: a model function, fixed arguments
(by value or by identity), array shapes, bijections. A key for programs kept on disk must survive the process,
so every part is written out by value here, strictly: a function by its module, qualified name, code, closure
cells, defaults and attributes; an array by its dtype, shape and bytes; a dataclass, named tuple or pytree node
by its type and fields. An object of any other kind raises :class:`Unkeyable` and its program is simply not
kept on disk: a key that leaves out part of a value could hand back a program built from another value.

Functions and types are accepted only from the modules named in :data:`TRUSTED_MODULES` (bubblecal, whose
source is part of the store's key, and the libraries whose versions are): a user's own model changes without
anything here noticing a new version, so its programs are compiled as usual.
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import hashlib
import types
from typing import Any

import jax
import numpy as np

from bubblecal.inference.tmcmc._keys import _Identity

__all__ = ["TRUSTED_MODULES", "Unkeyable", "stable_digest"]

#: Top-level modules whose functions and types may appear in a stored program's key.
TRUSTED_MODULES = ("bubblecal", "numpyro", "jax", "jaxlib", "numpy", "builtins", "functools", "operator", "math")

_SCALARS = (type(None), bool, int, float, complex, str, bytes)


class Unkeyable(TypeError):
    """An object that has no stable digest (its program is compiled, not read from disk)."""


def stable_digest(obj: Any) -> str:
    """SHA-256 hex digest of ``obj`` written out by value.

    Parameters
    ----------
    obj : object
        Scalars, strings, arrays, tuples (named tuples with their type), lists, dicts, sets, dataclasses, enums,
        types, functions and ``functools.partial`` objects of :data:`TRUSTED_MODULES`, pytree definitions and
        registered pytree nodes, nested in any way.

    Returns
    -------
    str
        64 hexadecimal characters.

    Raises
    ------
    Unkeyable
        For an object of another kind (a tracer, an open file, a class instance that is no dataclass or pytree
        node, a function of an untrusted module), or a reference cycle.
    """
    h = hashlib.sha256()
    _encode(obj, h, ())
    return h.hexdigest()


def _put(h, tag: str, text: str | bytes = b"") -> None:
    """Write one tagged, length-prefixed field (so that no two sequences of fields run together)."""
    data = text.encode() if isinstance(text, str) else bytes(text)
    h.update(f"{tag}:{len(data)}:".encode())
    h.update(data)


def _qualified(obj) -> str:
    """``module.qualname`` of a function or type from a trusted module."""
    module = getattr(obj, "__module__", None) or ""
    if module.split(".")[0] not in TRUSTED_MODULES:
        raise Unkeyable(f"{obj!r} comes from module {module!r}, whose code is no part of the key")
    return f"{module}.{getattr(obj, '__qualname__', getattr(obj, '__name__', ''))}"


def _encode(obj, h, path: tuple) -> None:
    """Write ``obj`` into the hash ``h``; ``path`` holds the ids of the containers being written (cycles)."""
    if id(obj) in path:
        raise Unkeyable("a reference cycle")
    path = path + (id(obj),)
    if isinstance(obj, jax.core.Tracer):
        raise Unkeyable("a traced value")
    kind = type(obj)
    if kind in _SCALARS:
        _put(h, kind.__name__, repr(obj))
    elif isinstance(obj, enum.Enum):
        _put(h, "enum", _qualified(kind) + "." + obj.name)
    elif isinstance(obj, type):
        _put(h, "type", _qualified(obj))
    elif isinstance(obj, np.dtype):
        _put(h, "dtype", str(obj))
    elif isinstance(obj, (np.ndarray, np.generic, jax.Array)):
        value = np.asarray(obj)
        _put(h, "array", f"{value.dtype.str}{value.shape}")
        _put(h, "bytes", np.ascontiguousarray(value).tobytes())
    elif isinstance(obj, jax.Device):
        _put(h, "device", f"{obj.platform}:{obj.device_kind}:{obj.id}")
    elif isinstance(obj, jax.ShapeDtypeStruct):
        _put(h, "aval", f"{obj.shape}{obj.dtype}{bool(getattr(obj, 'weak_type', False))}")
    elif isinstance(obj, jax.tree_util.PyTreeDef):
        _treedef(obj, h, path)
    elif isinstance(obj, functools.partial):
        _put(h, "partial")
        for part in (obj.func, obj.args, obj.keywords):
            _encode(part, h, path)
    elif isinstance(obj, types.MethodType):
        _put(h, "method")
        _encode(obj.__func__, h, path)
        _encode(obj.__self__, h, path)
    elif isinstance(obj, types.FunctionType):
        _function(obj, h, path)
    elif isinstance(obj, types.BuiltinFunctionType):
        _put(h, "builtin", _qualified(obj))
    elif isinstance(obj, tuple):
        _put(h, "tuple", "" if kind is tuple else _qualified(kind))
        _sequence(obj, h, path)
    elif isinstance(obj, list):
        _put(h, "list")
        _sequence(obj, h, path)
    elif isinstance(obj, dict):
        _put(h, "dict", "" if kind is dict else _qualified(kind))
        _unordered([(k, v) for k, v in obj.items()], h, path)
    elif isinstance(obj, (set, frozenset)):
        _put(h, "set")
        _unordered(list(obj), h, path)
    elif dataclasses.is_dataclass(obj):
        _put(h, "dataclass", _qualified(kind))
        for field in dataclasses.fields(obj):
            _put(h, "field", field.name)
            _encode(getattr(obj, field.name), h, path)
    elif isinstance(obj, _Identity):  # the in-process key of an unhashable value: the value itself
        _encode(obj.obj, h, path)
    else:
        _pytree_node(obj, h, path)


def _sequence(items, h, path) -> None:
    _put(h, "len", str(len(items)))
    for item in items:
        _encode(item, h, path)


def _unordered(items, h, path) -> None:
    """A set or a dict's items, in the order of their own digests (independent of insertion order)."""
    digests = []
    for item in items:
        sub = hashlib.sha256()
        _encode(item, sub, path)
        digests.append(sub.hexdigest())
    _put(h, "len", str(len(digests)))
    for d in sorted(digests):
        _put(h, "item", d)


def _code(code: types.CodeType, h, path) -> None:
    """A code object by its instructions, names and constants (nested code objects included)."""
    _put(h, "code", code.co_qualname if hasattr(code, "co_qualname") else code.co_name)
    _put(h, "bytecode", code.co_code)
    _put(h, "names", " ".join(code.co_names + code.co_varnames + code.co_freevars + code.co_cellvars))
    _put(h, "shape", f"{code.co_argcount},{code.co_posonlyargcount},{code.co_kwonlyargcount},{code.co_flags},"
                     f"{code.co_firstlineno}")
    _put(h, "consts", str(len(code.co_consts)))
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            _code(const, h, path)
        else:
            _encode(const, h, path)


def _function(fn: types.FunctionType, h, path) -> None:
    """A Python function: where it lives, its code, the values its closure cells hold, its defaults."""
    _put(h, "function", _qualified(fn))
    _code(fn.__code__, h, path)
    cells = fn.__closure__ or ()
    _put(h, "cells", str(len(cells)))
    for cell in cells:
        try:
            value = cell.cell_contents
        except ValueError:  # an empty cell (a name assigned after the function was made)
            _put(h, "empty-cell")
            continue
        _encode(value, h, path)
    _encode(fn.__defaults__, h, path)
    _encode(fn.__kwdefaults__, h, path)
    _encode({k: v for k, v in vars(fn).items() if k not in ("__doc__",)}, h, path)


def _treedef(treedef, h, path) -> None:
    """A pytree definition by its node types, their auxiliary data and its children, depth first."""
    if treedef.num_nodes == 1 and treedef.num_leaves == 1:
        _put(h, "leaf")
        return
    node_type, aux = treedef.node_data()
    _put(h, "node")
    _encode(node_type, h, path)
    _encode(aux, h, path)
    children = treedef.children()
    _put(h, "children", str(len(children)))
    for child in children:
        _treedef(child, h, path)


def _pytree_node(obj, h, path) -> None:
    """An instance of a registered pytree node type: its definition and its children (one level)."""
    try:
        children, treedef = jax.tree_util.tree_flatten(obj, is_leaf=lambda x: x is not obj)
    except Exception as exc:  # noqa: BLE001 - a node type whose flatten fails is as good as unknown
        raise Unkeyable(f"{type(obj).__qualname__} could not be flattened ({exc})") from exc
    if treedef.num_nodes == 1 and treedef.num_leaves == 1:
        raise Unkeyable(f"an instance of {type(obj).__module__}.{type(obj).__qualname__} (no dataclass, named "
                        "tuple or pytree node)")
    _put(h, "pytree")
    _treedef(treedef, h, path)
    _sequence(children, h, path)
