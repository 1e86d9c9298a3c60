"""Whether a folder can hold files a run writes for later runs (caches): one probe for every layer."""

from __future__ import annotations

import tempfile
from pathlib import Path

__all__ = ["folder_problem"]


def folder_problem(folder: Path) -> str | None:
    """Why ``folder`` cannot be written (None when it can): created if missing, then probed with a file.

    Parameters
    ----------
    folder : pathlib.Path
        The folder.

    Returns
    -------
    str or None
        E.g. ``'it is a file, not a folder'`` or ``'it cannot be written (Permission denied)'``.
    """
    if folder.exists() and not folder.is_dir():
        return "it is a file, not a folder"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".probe-"):
            pass
    except OSError as exc:
        return f"it cannot be written ({exc.strerror or exc})"
    return None
