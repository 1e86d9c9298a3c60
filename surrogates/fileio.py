"""File helpers shared by the surrogate formats: versioned JSON files, atomic binary writes, UTC timestamps.

Every surrogate file carries a ``format`` name and an integer ``format_version``; a reader accepts exactly the
version it was written for (docs/data-formats.md). Used by :mod:`bubblecal.surrogates.surrogate_file`,
:mod:`bubblecal.surrogates.bundle` and :mod:`bubblecal.surrogates.acoustic`; not part of the curated API.
"""

from __future__ import annotations

import datetime as _dt
import json
from pathlib import Path

from bubblecal.data import atomic_write

__all__ = ["utc_now", "atomic_write_bytes", "read_versioned_json"]


def utc_now() -> str:
    """The current UTC time as ``YYYY-MM-DDTHH:MM:SSZ`` (the ``created_utc`` of surrogate files)."""
    return _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def atomic_write_bytes(path: Path, writer) -> None:
    """Write ``path`` atomically (:func:`bubblecal.data.files.atomic_write`) through a binary handle.

    Parameters
    ----------
    path : Path
        Destination file.
    writer : callable
        ``writer(fh)`` writes the content to the open binary file handle ``fh``.
    """

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            writer(fh)

    atomic_write(path, write)


def read_versioned_json(path: Path, fmt: str, version: int | tuple[int, ...], error: type[Exception],
                        what: str) -> dict:
    """Read a JSON file whose ``format`` must equal ``fmt`` and ``format_version`` be (one of) ``version``.

    Parameters
    ----------
    path : Path
        The file.
    fmt : str
        Expected ``format``.
    version : int or tuple of int
        Expected ``format_version`` (a tuple: the versions this reader accepts).
    error : type of Exception
        Raised (with a message naming the file and the field) for invalid JSON or a wrong format/version.
    what : str
        What the file is, for the not-found message (e.g. ``"bundle manifest"``).

    Returns
    -------
    dict
        The parsed file.

    Raises
    ------
    FileNotFoundError
        When ``path`` is not a file.
    error
        For invalid JSON, non-UTF-8 text, JSON other than an object, or a format/version mismatch.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{what} not found: {path}")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise error(f"{path}: not valid JSON ({exc})") from exc
    except UnicodeDecodeError as exc:
        raise error(f"{path}: not UTF-8 text (byte {exc.start}), so not a {what}") from exc
    if not isinstance(data, dict):
        raise error(f"{path}: holds a JSON {type(data).__name__}, a {what} is a JSON object")
    if data.get("format") != fmt:
        raise error(f"{path}: field 'format' is {data.get('format')!r}, expected {fmt!r}")
    versions = version if isinstance(version, tuple) else (version,)
    if data.get("format_version") not in versions:
        raise error(f"{path}: field 'format_version' is {data.get('format_version')!r}, this code reads "
                    f"version {' or '.join(map(str, versions))}")
    return data
