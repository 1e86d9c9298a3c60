"""Libraries imported in the background, one thread at a time (the process's import turn).

A calibration process imports large libraries off its main thread (:func:`preload_soon`; the phase writer's thread
imports ArviZ, which imports pandas, xarray and matplotlib) while the main thread goes on. CPython locks each module
while it runs, but two threads importing overlapping packages at once can wait on each other's module locks; CPython
breaks that deadlock by handing one thread the other's half-initialised module (``AttributeError: module
'matplotlib' has no attribute 'get_data_path'``). So every import that may overlap another thread's takes the
process's import turn: :func:`preload` and :func:`library` hold it, background imports run one after the other, and
a thread that needs a library another thread is importing waits until that import is complete.
"""

from __future__ import annotations

import contextlib
import importlib
import sys
import threading
from collections.abc import Sequence

__all__ = ["import_turn", "library", "preload", "preload_soon"]

_TURN = threading.RLock()


def import_turn() -> threading.RLock:
    """The process's import turn (reentrant lock): hold it around an import that another thread may be making.

    Returns
    -------
    threading.RLock
    """
    return _TURN


def _complete(name: str):
    """The module ``name`` when it is imported and no thread is still running its body; else None."""
    module = sys.modules.get(name)
    if module is None or getattr(getattr(module, "__spec__", None), "_initializing", False):
        return None
    return module


def library(name: str):
    """The module ``name``, imported in the import turn unless it is complete already.

    Parameters
    ----------
    name : str
        Module name, e.g. 'xarray'.

    Returns
    -------
    module

    Raises
    ------
    ImportError
        The module is not installed.
    """
    module = _complete(name)
    if module is not None:  # no lock: a library imported before costs a dictionary lookup
        return module
    with _TURN:
        return importlib.import_module(name)


def preload(modules: Sequence[str]) -> None:
    """Import ``modules`` now, in the import turn (one that is not installed is skipped: the code that needs it
    reports it).

    Parameters
    ----------
    modules : sequence of str
        Module names.
    """
    for name in modules:
        with contextlib.suppress(ImportError):
            library(name)


def preload_soon(modules: Sequence[str]) -> threading.Thread:
    """Import ``modules`` on a daemon thread (:func:`preload`): the imports go on while this thread waits (for
    other processes, for the device); a thread that needs one of them before it is complete waits for the turn
    (:func:`library`, :func:`preload`).

    Parameters
    ----------
    modules : sequence of str
        Module names.

    Returns
    -------
    threading.Thread
        The started thread.
    """
    thread = threading.Thread(target=preload, args=(tuple(modules),), name="bubblecal-preload", daemon=True)
    thread.start()
    return thread
