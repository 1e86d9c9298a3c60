"""The persistent JAX compilation cache of the command line: compiled programs kept on disk between runs.

Switched on by the commands that sample (``bubblecal calibrate``, ``bubblecal evidence``; ``--no-cache`` turns it
off), never at ``import bubblecal``: a library user's JAX configuration stays theirs. The folder is
``platformdirs.user_cache_dir("bubblecal")/jax`` (``$XDG_CACHE_HOME/bubblecal/jax`` or ``~/.cache/bubblecal/jax``
without platformdirs), or the folder named by the environment variable :data:`CACHE_ENV`.

Entries are keyed by a hash of the program, the jaxlib version, the backend and the compile options, so a
folder shared by two runs, two checkouts or two JAX versions only ever returns a program compiled from the
same inputs. JAX writes an entry as one compressed file (no lock, not atomic); an entry that cannot be read
(torn by a concurrent or killed write, garbage bytes, another format) fails its checksum or its
deserialisation and JAX compiles the program again. Such failures reach the user as one warning line naming
the folder (:func:`enable_compilation_cache`), and entries that do not decompress are then deleted so that
the next run writes them afresh (entries younger than a minute are spared: another run may be writing them).
The subfolder ``programs`` holds the TMCMC program store (:mod:`bubblecal.inference.tmcmc.executables`):
executables keyed by what built them and by bubblecal's source, read back without tracing or lowering.
A folder that cannot be used at all (a file, not writable) gives one warning line and the run goes on
without the cache. Nothing the cache does touches the run's own outputs.

On a GPU the commands also let XLA pick matmul kernels by heuristics rather than by timing them
(:func:`skip_gpu_autotuning`), which takes most of the time out of compiling there.
"""

from __future__ import annotations

import os
import time
import warnings
from collections.abc import Callable
from pathlib import Path

from bubblecal._folders import folder_problem

__all__ = ["CACHE_ENV", "GPU_AUTOTUNE_FLAG", "PROGRAMS_ENV", "PROGRAMS_SUBFOLDER", "default_cache_dir",
           "enable_compilation_cache", "skip_gpu_autotuning"]

#: Environment variable naming the compilation cache folder (instead of the user's cache folder).
CACHE_ENV = "BUBBLECAL_CACHE_DIR"
#: Subfolder of the cache folder holding the TMCMC program store (executables keyed without tracing).
PROGRAMS_SUBFOLDER = "programs"
#: Environment variable that keeps the program store off ("off" or "0") while the compilation cache stays on.
PROGRAMS_ENV = "BUBBLECAL_PROGRAM_STORE"
#: The ``XLA_FLAGS`` entry with which XLA picks GPU matmul kernels by cuBLAS's heuristics instead of timing them.
GPU_AUTOTUNE_FLAG = "--xla_gpu_autotune_level=0"

# the messages JAX warns with when an entry cannot be read or written (jax._src.compiler)
_JAX_CACHE_WARNINGS = ("Error reading persistent compilation cache entry",
                       "Error writing persistent compilation cache entry")
_state: dict = {"folder": None, "say": None, "warned": set(), "previous": None}


def default_cache_dir() -> Path:
    """The compilation cache folder: :data:`CACHE_ENV` if set, else the user's cache folder + ``bubblecal/jax``.

    Returns
    -------
    pathlib.Path
        Not created here.
    """
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV]).expanduser()
    try:
        from platformdirs import user_cache_dir
    except ImportError:  # platformdirs comes with ArviZ; without it the XDG convention
        base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
        return base / "bubblecal" / "jax"
    return Path(user_cache_dir("bubblecal")) / "jax"


def skip_gpu_autotuning() -> bool:
    """Let XLA pick GPU matmul kernels by heuristics, not by timing candidates while it compiles.

    Appends :data:`GPU_AUTOTUNE_FLAG` to the environment's ``XLA_FLAGS`` unless they already set an autotune
    level (the user's choice stays). Timing candidate kernels is most of a GPU compilation of the calibration's
    programs, and the heuristic kernels evaluate the surrogates as fast (``benchmarks/RESULTS.md``, "The main
    job"); the choice then no longer depends on timings, so two runs compile the same kernels. Takes effect only
    when called before JAX starts its GPU backend: the commands call it first, never ``import bubblecal``.

    Returns
    -------
    bool
        True when the flag was added.
    """
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_gpu_autotune_level" in flags:
        return False
    os.environ["XLA_FLAGS"] = f"{flags} {GPU_AUTOTUNE_FLAG}".strip()
    return True


def _remove_damaged(folder: Path, min_age_s: float = 60.0) -> int:
    """Delete the entries of ``folder`` that do not decompress (torn or garbage), so that JAX writes them again.

    Entries younger than ``min_age_s`` are left alone: another run may be writing them right now.
    """
    try:  # the compression JAX wrote with (zstandard where installed, else zlib)
        from jax._src.compilation_cache import decompress_executable
    except ImportError:  # another JAX layout: leave the entries; JAX recompiles around them
        return 0
    removed = 0
    now = time.time()
    for entry in folder.glob("*-cache"):
        try:
            if now - entry.stat().st_mtime < min_age_s:
                continue
            decompress_executable(entry.read_bytes())
        except OSError:
            continue
        except Exception:  # noqa: BLE001 - any decompression error marks the entry as damaged
            try:
                entry.unlink()
                removed += 1
            except OSError:
                pass
    return removed


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """``warnings.showwarning`` that turns JAX's cache-entry warnings into one line naming the folder."""
    text = str(message)
    if _state["folder"] is not None and text.startswith(_JAX_CACHE_WARNINGS):
        kind = "read" if "reading" in text else "written"
        if kind not in _state["warned"]:  # once per kind and process: a damaged folder fails every entry
            _state["warned"].add(kind)
            detail = text.split(": ", 1)[-1]
            removed = _remove_damaged(_state["folder"]) if kind == "read" else 0
            note = f"; removed {removed} damaged entries" if removed else ""
            _state["say"](f"compilation cache {_state['folder']}: an entry could not be {kind} ({detail}){note}; "
                          "compiling instead (delete the folder or pass --no-cache to silence this)")
        return
    _state["previous"](message, category, filename, lineno, file, line)


def enable_compilation_cache(folder: Path | None = None, *, say: Callable[[str], None] | None = None
                             ) -> Path | None:
    """Keep compiled JAX programs in ``folder`` for later runs (every program, however small or quick).

    Also keeps the TMCMC runs' executables in its subfolder :data:`PROGRAMS_SUBFOLDER`
    (:func:`~bubblecal.inference.tmcmc.enable_program_store`), which later runs read without tracing them, unless
    :data:`PROGRAMS_ENV` is ``off``: keyed by value and by bubblecal's source, they would not follow code patched
    at run time (a test's monkeypatch, a notebook's edited module global).

    Parameters
    ----------
    folder : pathlib.Path or None
        The cache folder (created if missing); None: :func:`default_cache_dir`.
    say : callable or None
        Receives the one-line warnings (an unusable folder; an entry that could not be read or written).
        Default: :func:`warnings.warn` with a :class:`RuntimeWarning`.

    Returns
    -------
    pathlib.Path or None
        The folder in use; None when it cannot be used (the run compiles as without a cache).
    """
    import jax

    folder = Path(folder) if folder is not None else default_cache_dir()
    say = say or (lambda m: warnings.warn(m, RuntimeWarning, stacklevel=3))
    why = folder_problem(folder)
    if why is not None:
        say(f"compilation cache {folder}: {why}; running without it (pass --no-cache to silence this)")
        return None
    from bubblecal.inference.tmcmc import enable_program_store

    jax.config.update("jax_compilation_cache_dir", str(folder))
    # our programs compile in well under JAX's default thresholds on a GPU, yet there are hundreds of them
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)
    if os.environ.get(PROGRAMS_ENV, "").strip().lower() in ("0", "off", "no", "false"):
        pass  # the compilation cache alone
    elif enable_program_store(folder / PROGRAMS_SUBFOLDER) is None:
        say(f"compilation cache {folder / PROGRAMS_SUBFOLDER}: it cannot be written; TMCMC programs are lowered "
            "on every run (pass --no-cache to silence this)")
    _state.update(folder=folder, say=say)
    if warnings.showwarning is not _show_warning:
        _state["previous"] = warnings.showwarning
        warnings.showwarning = _show_warning
    return folder
