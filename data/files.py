"""File helpers: atomic writes and plain-JSON conversion of NumPy-laden results.

An atomic write leaves a reader the old file or the new one, never half of one.
"""

from __future__ import annotations

import math
import os
import tempfile
import threading
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

__all__ = ["atomic_write", "current_umask", "jsonable"]


def atomic_write(path: str | Path, writer: Callable[[Path], None]) -> Path:
    """Write ``path`` atomically through a temporary file in the same folder.

    ``writer`` fills the temporary file, which is then fsync'ed and renamed over ``path``. The file gets the
    permissions of an ordinary new file, 0o666 minus the process umask (not the 0o600 of a temporary file).

    Parameters
    ----------
    path : str or pathlib.Path
        The file to write; missing parent folders are created.
    writer : callable
        ``writer(tmp)`` writes the whole content to the temporary file ``tmp`` (a :class:`pathlib.Path`).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    BaseException
        Whatever ``writer`` raises; the temporary file is removed and ``path`` is left untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    try:
        writer(Path(tmp))
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~current_umask())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


_UMASK_LOCK = threading.Lock()


def current_umask() -> int:
    """The process umask (read by setting it and setting it back, under a lock).

    Returns
    -------
    int
        E.g. ``0o022``: the permission bits a newly created file does not get.
    """
    with _UMASK_LOCK:
        mask = os.umask(0o022)
        os.umask(mask)
    return mask


def jsonable(obj, *, nonfinite_as_none: bool = False):
    """``obj`` converted to plain JSON types.

    Parameters
    ----------
    obj : object
        Mappings, lists/tuples, NumPy arrays and scalars, Python scalars, None, nested freely.
    nonfinite_as_none : bool
        Turn NaN/inf floats into None (strict JSON); otherwise they stay floats.

    Returns
    -------
    object
        Mappings become dicts with ``str`` keys, sequences and arrays lists, NumPy/Python booleans, integers and
        floats ``bool``, ``int`` and ``float``; None and strings are kept and any other object becomes ``str(obj)``.
    """
    if isinstance(obj, Mapping):
        return {str(k): jsonable(v, nonfinite_as_none=nonfinite_as_none) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v, nonfinite_as_none=nonfinite_as_none) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist(), nonfinite_as_none=nonfinite_as_none)
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return None if nonfinite_as_none and not math.isfinite(v) else v
    if obj is None or isinstance(obj, str):
        return obj
    return str(obj)
