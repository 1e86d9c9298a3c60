"""One ``calibrate`` run per output folder: a lock file holding the writer's PID and host.

A second run into the same folder stops with the PID of the first; a lock left by a killed run (its PID is no
longer alive on this host) is taken over, and the caller is told so.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import time
from collections.abc import Callable, Iterator
from pathlib import Path

from bubblecal.workflows.calibrate.config import CalibrationError

__all__ = ["LOCK_NAME", "run_lock"]

#: The lock file of a run, in the output root (``--out``).
LOCK_NAME = ".bubblecal-calibrate.lock"


def _pid_alive(pid: int) -> bool:
    """Whether process ``pid`` exists on this host (signal 0 probes without sending anything)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by another user
        return True
    return True


def _holder(path: Path) -> dict | None:
    """The lock's content, or None when it is unreadable (a half-written lock of a killed run)."""
    try:
        info = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return info if isinstance(info, dict) and isinstance(info.get("pid"), int) else None


@contextlib.contextmanager
def run_lock(out: Path, say: Callable[[str], None] | None = None) -> Iterator[Path]:
    """Hold the output folder's lock for the duration of a ``with`` block.

    Parameters
    ----------
    out : Path
        The output root (created if missing).
    say : callable or None
        Told when a stale lock of a run that no longer exists is taken over.

    Yields
    ------
    Path
        The lock file; removed on exit.

    Raises
    ------
    CalibrationError
        Another run on this host (its PID alive) or on another host holds the lock: the message names the
        folder, the PID, the host and the lock file.
    """
    say = say or (lambda _m: None)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / LOCK_NAME
    me = {"pid": os.getpid(), "host": socket.gethostname(), "started": time.strftime("%Y-%m-%d %H:%M:%S")}
    for _attempt in range(3):
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666)
        except FileExistsError:
            holder = _holder(path)
            if holder is not None and holder.get("host") != me["host"]:
                raise CalibrationError(f"--out {out}: a calibrate run on host {holder.get('host')} (PID "
                                       f"{holder['pid']}, started {holder.get('started', '?')}) holds {path}; wait "
                                       "for it, give another --out, or delete the lock if that run is gone") from None
            if holder is not None and holder["pid"] != me["pid"] and _pid_alive(holder["pid"]):
                raise CalibrationError(f"--out {out}: another calibrate run (PID {holder['pid']}, started "
                                       f"{holder.get('started', '?')}) is writing into this folder ({path}); wait "
                                       "for it to finish or give another --out") from None
            what = "an unreadable lock" if holder is None else f"the lock of PID {holder['pid']} (no longer running)"
            say(f"{out}: took over {what} left by a run that was killed ({path})")
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
            continue
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(me, fh)
        break
    else:
        raise CalibrationError(f"--out {out}: could not take the lock {path} (another run keeps creating it)")
    try:
        yield path
    finally:
        if (_holder(path) or {}).get("pid") == me["pid"]:
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
