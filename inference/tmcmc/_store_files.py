"""The files of the program store: entries written whole with a checksum, read back, pruned (private).

An entry is ``_FORMAT``, the SHA-256 of the body, and the body: the pickled serialised executable
(``jax.experimental.serialize_executable``), its input and output pytree definitions and its output shapes.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import tempfile
import time
from pathlib import Path

import jax

__all__ = ["STORE_SUFFIX", "PRUNE_AFTER_S", "prune", "read_entry", "write_entry"]

#: File suffix of a stored program.
STORE_SUFFIX = ".jaxprog"
#: Entries of another environment unused for this long [s] are deleted when a process first uses the store.
PRUNE_AFTER_S = 86400.0
_FORMAT = b"bubblecal-program-1\n"
_state = {"prepared": False}


def _prepare_runtime() -> None:
    """The Python-side set-up that executables read back may need and that JAX does only while lowering.

    XLA:CPU's LAPACK kernels (Cholesky, triangular solves) find their routines once JAX has initialised them, which
    it does when it lowers a LAPACK call; a program read from the store is never lowered, and would crash.
    """
    if _state["prepared"]:
        return
    try:
        from jax._src.lax.linalg import initialize_lapack
    except ImportError:  # another JAX layout: lowering a Cholesky initialises the same
        import jax.numpy as jnp

        jax.jit(jnp.linalg.cholesky).lower(jax.ShapeDtypeStruct((2, 2), "float32"))
    else:
        initialize_lapack()
    _state["prepared"] = True


def prune(folder: Path, prefix: str, max_idle_s: float = PRUNE_AFTER_S) -> int:
    """Delete the entries of other environments (another source, JAX, device) unused for ``max_idle_s``, and stale
    temporary files: the store keeps about one version's programs, not one set per edit or upgrade."""
    removed = 0
    now = time.time()
    for path in list(folder.glob(f"*{STORE_SUFFIX}")) + list(folder.glob(".tmp-*")):
        try:
            if path.name.startswith(prefix + "-") or now - path.stat().st_mtime < max_idle_s:
                continue
            path.unlink()
            removed += 1
        except OSError:
            continue
    return removed


def read_entry(name: str):
    """(executable, output shapes) of a stored entry; None when absent, damaged or not loadable here."""
    from jax.experimental import serialize_executable

    _prepare_runtime()
    try:
        blob = Path(name).read_bytes()
        os.utime(name)  # its last use: entries of other environments are pruned after a day unused
    except OSError:
        return None
    head = len(_FORMAT) + 32
    if not blob.startswith(_FORMAT) or hashlib.sha256(blob[head:]).digest() != blob[len(_FORMAT):head]:
        return None
    try:
        payload, in_tree, out_tree, shapes = pickle.loads(blob[head:])
        return serialize_executable.deserialize_and_load(payload, in_tree, out_tree), shapes
    except Exception:  # noqa: BLE001 - any failure to load is a miss: the program is compiled instead
        return None


def write_entry(name: str, compiled, shapes) -> bool:
    """Write one entry whole (temporary file, then rename); False when it could not be written."""
    from jax.experimental import serialize_executable

    try:
        payload, in_tree, out_tree = serialize_executable.serialize(compiled)
        body = pickle.dumps((payload, in_tree, out_tree, shapes), protocol=pickle.HIGHEST_PROTOCOL)
    except Exception:  # noqa: BLE001 - an executable the backend cannot serialise is simply not stored
        return False
    path = Path(name)
    try:
        with tempfile.NamedTemporaryFile(dir=path.parent, prefix=".tmp-", delete=False) as fh:
            fh.write(_FORMAT + hashlib.sha256(body).digest() + body)
        os.replace(fh.name, path)
    except OSError:
        try:
            os.unlink(fh.name)
        except (OSError, NameError):
            pass
        return False
    return True
