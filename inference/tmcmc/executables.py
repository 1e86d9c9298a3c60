"""Compiled TMCMC programs kept on disk between processes, so that a later run neither traces, lowers nor compiles them.

JAX's persistent compilation cache is keyed by the lowered program: a run that reads every program from it
still traces and lowers each one first. The *program store* keeps the executables themselves
(``jax.experimental.serialize_executable``) under a key computed without tracing: the digest
(:func:`~bubblecal.inference.tmcmc._stable.stable_digest`) of what built the program (its role, the model
function and every fixed value and bijection of the model's signature, the move and its settings), the pytree
structure and shapes of the call's arguments, and of the environment (:func:`environment_digest`: bubblecal's
source files, the versions of Python, JAX, jaxlib, NumPyro and NumPy, JAX's configuration, ``XLA_FLAGS``, the
platform and device kind). A value the key cannot write out exactly (a user's own model function, an object of
unknown kind) leaves its program out of the store; it is then compiled as without one.

Entries are written whole (a temporary file, then an atomic rename) and carry a checksum; an entry that
cannot be read, checked or loaded counts as absent and is written again. An entry's name begins with its
environment's digest: entries of another environment (an edited source, an upgrade) that no process used for
:data:`PRUNE_AFTER_S` are deleted, so the folder holds about one version's programs. Two runs sharing the folder at once
write identical bytes under one name. Off unless :func:`enable_program_store` is called: the commands that
sample switch it on beside the compilation cache (``--no-cache`` switches both off), ``import bubblecal``
never does.
"""

from __future__ import annotations

import hashlib
import os
import platform
import sys
import threading
from collections.abc import Callable, Sequence
from importlib import metadata
from pathlib import Path
from typing import Any

import jax

from bubblecal._folders import folder_problem
from bubblecal.inference.tmcmc._stable import Unkeyable, stable_digest
from bubblecal.inference.tmcmc._store_files import PRUNE_AFTER_S, STORE_SUFFIX, prune, read_entry, write_entry

__all__ = ["Program", "enable_program_store", "disable_program_store", "program_store_folder", "store_counts",
           "environment_digest", "compile_fresh", "STORE_SUFFIX", "PRUNE_AFTER_S", "CACHE_HIT_EVENT"]

_PREFIX = 16  # hexadecimal characters of the environment digest that begin an entry's name
# JAX configuration names that cannot change a program (logging, caches, timeouts)
_CONFIG_IGNORED = ("log", "cache", "timeout", "explain")
_state: dict = {"folder": None, "counts": {"loaded": 0, "saved": 0, "compiled": 0, "unkeyed": 0},
                "source": None, "environment": (None, None), "pruned": None, "listening": False}
_lock = threading.Lock()


def enable_program_store(folder: str | os.PathLike) -> Path | None:
    """Keep the compiled programs of TMCMC runs in ``folder`` and read them back in later processes.

    Parameters
    ----------
    folder : path-like
        Created if missing.

    Returns
    -------
    pathlib.Path or None
        The folder in use; None when it cannot be created or written (programs are then compiled as usual).
    """
    folder = Path(folder)
    if folder_problem(folder) is not None:
        return None
    _state["folder"] = folder
    return folder


def disable_program_store() -> None:
    """Stop reading and writing stored programs (those already loaded in this process stay in use)."""
    _state["folder"] = None


def program_store_folder() -> Path | None:
    """The folder of the program store, None when it is off."""
    return _state["folder"]


def store_counts() -> dict[str, int]:
    """Programs of this process so far: ``loaded`` from the store, ``saved`` to it, ``compiled`` ahead in all,
    ``unkeyed`` (built from values without a stable key, so compiled and not stored)."""
    return dict(_state["counts"])


def _source_digest() -> str:
    """Digest of bubblecal's Python source: the package's own modules and every subpackage folder's."""
    if _state["source"] is None:
        import bubblecal

        root = Path(bubblecal.__file__).resolve().parent
        files = sorted(root.glob("*.py"))
        for sub in sorted(p for p in root.iterdir() if (p / "__init__.py").is_file()):
            files += sorted(f for f in sub.rglob("*.py") if "__pycache__" not in f.parts)
        h = hashlib.sha256()
        for f in files:
            h.update(f.relative_to(root).as_posix().encode() + b"\0")
            h.update(hashlib.sha256(f.read_bytes()).digest())
        _state["source"] = h.hexdigest()
    return _state["source"]


def _version(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "absent"


def environment_digest() -> str:
    """Digest of everything outside a program's own inputs that can change what it computes.

    bubblecal's source files, the Python, JAX, jaxlib, NumPyro and NumPy versions, JAX's configuration values
    (but those of logging, caches and timeouts), ``XLA_FLAGS``, and the default backend's platform, device
    kind and device count.

    Returns
    -------
    str
        64 hexadecimal characters.
    """
    config = tuple(sorted((k, v) for k, v in jax.config.values.items() if not any(w in k for w in _CONFIG_IGNORED)))
    snapshot = (config, os.environ.get("XLA_FLAGS", ""))
    if _state["environment"][0] != snapshot:
        devices = jax.devices()
        digest = stable_digest((
            _source_digest(), sys.version, platform.machine(),
            tuple(_version(d) for d in ("jax", "jaxlib", "numpyro", "numpy")), snapshot,
            devices[0].platform, devices[0].device_kind, len(devices),
        ))
        _state["environment"] = (snapshot, digest)
    return _state["environment"][1]


def _aval(leaf) -> tuple | None:
    """(shape, dtype, weak type) of an argument leaf as jit sees it; None for a traced value."""
    if isinstance(leaf, jax.ShapeDtypeStruct):
        return tuple(leaf.shape), str(leaf.dtype), bool(getattr(leaf, "weak_type", False))
    if isinstance(leaf, jax.core.Tracer):
        return None
    aval = jax.typeof(leaf)
    return tuple(aval.shape), str(aval.dtype), bool(getattr(aval, "weak_type", False))


class Program:
    """A jitted function that also runs executables compiled ahead or read from the program store.

    Called like the jitted function. For arguments whose structure and shapes it holds an executable for
    (:meth:`keep`, or one found in the store), it runs that executable; for any others (traced values
    included) it calls ``jax.jit(fn)``, which traces and compiles as usual.

    Parameters
    ----------
    fn : callable
        The function to jit.
    identity : hashable or None
        What built ``fn``, by value (e.g. ``("model", "evaluate", signature, chunk_size)``): the stored key's
        part for the program itself. None: never stored.
    static_argnums : sequence of int
        Positional arguments that are static (as for ``jax.jit``); they are part of the call's key.
    """

    def __init__(self, fn: Callable, identity: Any = None, static_argnums: Sequence[int] = ()):
        self.static_argnums = tuple(static_argnums)
        self.jitted = jax.jit(fn, static_argnums=self.static_argnums)
        self.identity = identity
        self._identity_digest: str | None = None
        self._entries: dict = {}  # call key -> (executable, output shapes)

    def __call__(self, *args):
        if self._entries:
            key = self.call_key(args)
            entry = self._entries.get(key) if key is not None else None
            if entry is not None:
                try:
                    return entry[0](*self._dynamic(args))
                except jax.errors.JaxRuntimeError as exc:
                    # an executable whose code did not survive serialisation fails before it runs: drop it
                    if "not found" not in str(exc):
                        raise
                    self._forget(key)
        return self.jitted(*args)

    def _forget(self, key: tuple) -> None:
        """Drop the executable of ``key`` and its stored entry (calls then go through jit)."""
        self._entries.pop(key, None)
        name = self._stored_name(key)
        if name is not None:
            try:
                os.unlink(name)
            except OSError:
                pass

    def lower(self, *args):
        """``jax.jit(fn).lower(*args)``."""
        return self.jitted.lower(*args)

    def executables(self) -> int:
        """Executables this program holds: those kept or read from the store, and those jit compiled."""
        return len(self._entries) + self.jitted._cache_size()

    def _dynamic(self, args) -> tuple:
        return tuple(a for i, a in enumerate(args) if i not in self.static_argnums)

    def call_key(self, args: tuple) -> tuple | None:
        """The call's argument structure, shapes and static values (hashable); None when an argument is traced."""
        leaves, treedef = jax.tree_util.tree_flatten(self._dynamic(args))
        avals = tuple(_aval(v) for v in leaves)
        if any(a is None for a in avals):
            return None
        return treedef, avals, tuple(args[i] for i in self.static_argnums)

    def _stored_name(self, key: tuple) -> str | None:
        """The file name of the call ``key`` in the store; None when the store is off or the program unkeyable."""
        folder = _state["folder"]
        if folder is None or self.identity is None:
            return None
        try:
            if self._identity_digest is None:
                self._identity_digest = stable_digest(self.identity)
            environment = environment_digest()
            digest = stable_digest((environment, self._identity_digest, key))
        except Unkeyable:
            self.identity = None
            with _lock:
                _state["counts"]["unkeyed"] += 1
            return None
        prefix = environment[:_PREFIX]
        if _state["pruned"] != (folder, prefix):
            _state["pruned"] = (folder, prefix)
            prune(folder, prefix)
        return str(folder / f"{prefix}-{digest}{STORE_SUFFIX}")

    def _entry(self, key: tuple | None):
        """(executable, output shapes) of the call ``key``: held already, or read now from the store; else None."""
        if key is None:
            return None
        entry = self._entries.get(key)
        if entry is None:
            name = self._stored_name(key)
            entry = read_entry(name) if name is not None else None
            if entry is not None:
                self._entries[key] = entry
                with _lock:
                    _state["counts"]["loaded"] += 1
        return entry

    def ready(self, *args) -> bool:
        """Whether an executable for ``args`` is at hand: held already, or read now from the store."""
        return self._entry(self.call_key(args)) is not None

    def shapes(self, *args):
        """The output's ``jax.ShapeDtypeStruct`` pytree for ``args`` (from the executable held, else traced)."""
        entry = self._entry(self.call_key(args))
        if entry is not None:
            return entry[1]
        if self.static_argnums:
            static = {i: args[i] for i in self.static_argnums}

            def call(*dynamic):
                it = iter(dynamic)
                return self.jitted(*[static[i] if i in static else next(it) for i in range(len(args))])

            return jax.eval_shape(call, *self._dynamic(args))
        return jax.eval_shape(self.jitted, *args)

    def keep(self, args: tuple, compiled, store: bool = True) -> None:
        """Hold ``compiled`` (``self.lower(*args).compile()``) for calls like ``args``; with ``store``, also write
        it to the store (pass False for an executable read from JAX's cache: :func:`compile_fresh`)."""
        key = self.call_key(args)
        if key is None:
            return
        entry = (compiled, self.shapes(*args))
        self._entries[key] = entry
        with _lock:
            _state["counts"]["compiled"] += 1
        name = self._stored_name(key) if store else None
        if name is not None and write_entry(name, compiled, entry[1]):
            with _lock:
                _state["counts"]["saved"] += 1


#: JAX's monitoring event of an executable read from its persistent compilation cache.
CACHE_HIT_EVENT = "/jax/compilation_cache/cache_hits"
_thread = threading.local()


def _on_event(event: str, **_kwargs) -> None:
    if event == CACHE_HIT_EVENT:
        _thread.hit = True


def compile_fresh(lowered) -> tuple[Any, bool]:
    """Compile ``lowered``; also say whether XLA compiled it here, rather than JAX reading it from its cache.

    An XLA:CPU executable read from JAX's persistent compilation cache serialises without its machine code (it
    would fail to run where it is loaded), so only executables compiled here go to the store.

    Parameters
    ----------
    lowered : jax.stages.Lowered
        A lowered program.

    Returns
    -------
    tuple
        ``(executable, fresh)``.
    """
    if not _state["listening"]:
        with _lock:
            if not _state["listening"]:
                jax.monitoring.register_event_listener(_on_event)
                _state["listening"] = True
    _thread.hit = False
    executable = lowered.compile()
    return executable, not _thread.hit
