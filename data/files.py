"""File helpers: atomic writes (a reader sees the old file or the new one, never half of one) and plain-JSON
conversion of NumPy-laden results."""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

__all__ = ["atomic_write", "jsonable"]


def atomic_write(path: str | Path, writer: Callable[[Path], None]) -> Path:
    """Write ``path`` by calling ``writer(tmp)`` on a temporary file in the same folder, fsync it and
    rename it over ``path``; if ``writer`` raises, the temporary file is removed and ``path`` is untouched."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    try:
        writer(Path(tmp))
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def jsonable(obj, *, nonfinite_as_none: bool = False):
    """``obj`` with mappings, sequences and NumPy arrays/scalars turned into plain JSON types (keys as str,
    unknown objects as ``str``); NaN/inf become None when ``nonfinite_as_none`` (strict JSON)."""
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
