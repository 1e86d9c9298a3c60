"""Phase files written off the sampling thread: one writer thread, or writer processes where cores are spare.

A NetCDF phase file costs a few hundredths of a second to a few tenths (ArviZ builds the groups as xarray datasets,
:func:`~bubblecal.inference.write_netcdf` compresses and writes them), and h5py runs every HDF5 call of a process
behind one lock: one writer thread keeps up on a laptop, but on a GPU host, where a phase samples in a fraction of a
second, 200 files queue behind it. There the files go to writer processes (spawned: JAX must not be forked), each
with its own HDF5 library. The model-dependent part of an export
(:func:`~bubblecal.workflows.calibrate.phase_inference_parts`) stays on the caller's thread; what crosses to a writer
is host arrays and metadata.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from bubblecal.workflows.calibrate.agent_worker import shutdown_soon
from bubblecal.workflows.calibrate.device import helper_processes
from bubblecal.workflows.calibrate.imports import import_turn, preload

__all__ = ["PhaseWriter"]

#: What a NetCDF write imports: each writer process imports it when it starts (:meth:`PhaseWriter.start`).
WRITE_MODULES = ("arviz", "h5py", "bubblecal.inference.idata", "bubblecal.inference.netcdf",
                 "bubblecal.workflows.calibrate.phase_files")


def _write(path: Path, result, loglik, attrs: Mapping, info, pointwise, parts) -> Path:
    """:func:`~bubblecal.workflows.calibrate.write_phase` (module level: a writer process unpickles it), in the
    import turn: the writer thread's first write imports ArviZ (pandas, xarray, matplotlib), later ones lazily more."""
    with import_turn():
        from bubblecal.workflows.calibrate.phase_files import write_phase

        return write_phase(path, result, loglik, attrs, info=info, pointwise=pointwise, parts=parts)


def _warm_up() -> None:
    """Import what a write needs, then write one small phase file into a temporary folder: the first write of a
    process pays for lazy imports and library set-up, which a writer started ahead pays while the phases sample."""
    import sys
    import tempfile

    # ArviZ imports Numba, where it is installed, to compile statistics that a writer never computes
    if "numba" not in sys.modules:
        sys.modules["numba"] = None
    preload(WRITE_MODULES)
    from bubblecal.inference.idata import ExportInfo
    from bubblecal.inference.phase_results import PhaseResult

    draws = np.zeros((1, 4))
    info = ExportInfo(dims={"y": ("point",)}, units={"x": "DPD"},
                      constant_data={"loading": np.zeros(3), "diameter_um": np.float64(1.0)})
    parts = {"posterior": {"x": draws}, "sample_stats": {"lp": draws}, "log_likelihood": {"y": np.zeros((1, 4, 3))},
             "observed_data": {"y": np.zeros(3)}, "info": info}
    with tempfile.TemporaryDirectory(prefix="bubblecal-writer-") as folder:
        _write(Path(folder) / "warm_up.nc", PhaseResult("warm_up", {"x": draws[0]}, 0.0, 0.0, "converged", 0.0),
               None, {}, None, None, parts)


def _host(obj):
    """``obj`` with every device array replaced by a NumPy array (mappings, sequences and ExportInfo walked)."""
    if isinstance(obj, np.ndarray | np.generic | str | bytes | int | float | bool) or obj is None:
        return obj
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return dataclasses.replace(obj, **{f.name: _host(getattr(obj, f.name)) for f in dataclasses.fields(obj)})
    if isinstance(obj, Mapping):
        return {k: _host(v) for k, v in obj.items()}
    if isinstance(obj, tuple | list):
        return type(obj)(_host(v) for v in obj)
    if hasattr(obj, "__array__"):
        return np.asarray(obj)
    return obj


class PhaseWriter:
    """Writes phase files in the background and reports each finished one, in submission order.

    Parameters
    ----------
    processes : int or None
        Writer processes; 0: one writer thread; None: ``helper_processes('writer')`` of this machine
        (:func:`~bubblecal.workflows.calibrate.device.helper_processes`).

    Notes
    -----
    ``on_done`` callbacks run on the caller's thread, from :meth:`submit` (for the writes finished by then) and
    :meth:`close`, never on a writer: the caller's bookkeeping (the run's manifest) needs no lock.
    """

    def __init__(self, processes: int | None = None):
        self.processes = helper_processes("writer") if processes is None else int(processes)
        self._pool = None
        self._closer = None
        self._pending: list[tuple] = []
        self._errors: list[BaseException] = []
        self._warm: list = []

    def _executor(self):
        """The thread or process pool, started on first use."""
        if self._pool is None:
            from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor

            if self.processes > 0:
                import multiprocessing

                self._pool = ProcessPoolExecutor(self.processes, mp_context=multiprocessing.get_context("spawn"))
            else:
                self._pool = ThreadPoolExecutor(1, thread_name_prefix="bubblecal-phase-writer")
        return self._pool

    def start(self) -> None:
        """Start the writers now, each importing what a write needs and writing a small file of its own, so that the
        first phase file does not wait for a process start, its imports and a first write's set-up (a no-op for the
        writer thread and for writers already started)."""
        if self._pool is not None or self.processes == 0:
            return
        pool = self._executor()
        # one warm-up task per process: the pool spawns a process for each task that finds none idle
        self._warm = [pool.submit(_warm_up) for _ in range(self.processes)]

    def submit(self, on_done: Callable[[], None], path: Path, result, loglik, attrs: Mapping, *, info=None,
               pointwise=None, parts: Mapping | None = None) -> None:
        """Queue one :func:`~bubblecal.workflows.calibrate.write_phase`; ``on_done()`` once the file is complete.

        Parameters
        ----------
        on_done : callable
            Called without arguments after the write succeeded (not after a failed one).
        path, result, loglik, attrs, info, pointwise, parts
            As :func:`~bubblecal.workflows.calibrate.write_phase`; ``parts`` computed on the sampling thread.

        Raises
        ------
        RuntimeError
            After :meth:`close_soon`.
        """
        from bubblecal.inference.phase_results import PhaseResult

        if self._closer is not None:
            raise RuntimeError(f"{path}: the phase writer was told that no more files come (close_soon)")
        if self.processes > 0:  # what crosses to a process: host arrays and plain metadata, no sampler
            result = PhaseResult(result.name, _host(dict(result.samples)), result.log_evidence,
                                 result.log_evidence_se, result.status, result.seconds)
            loglik, info, pointwise, parts = _host(loglik), _host(info), _host(pointwise), _host(parts)
        future = self._executor().submit(_write, Path(path), result, loglik, dict(attrs), info, pointwise, parts)
        self._pending.append((future, on_done))
        self._harvest(wait=False)

    def _harvest(self, wait: bool) -> None:
        """Report the finished writes in order (all of them with ``wait``), keeping their errors."""
        while self._pending:
            future, on_done = self._pending[0]
            if not wait and not future.done():
                return
            self._pending.pop(0)
            try:
                future.result()
            except Exception as exc:  # noqa: PERF203 - one failed file must not hide the others
                self._errors.append(exc)
            else:
                on_done()

    def close_soon(self) -> None:
        """No more files will come (a later :meth:`submit` raises RuntimeError): the writers finish the queued ones
        and end meanwhile (their interpreters' exit overlaps the caller's work); :meth:`close` still reports the
        writes and waits for the writers' end."""
        if self._pool is not None and self._closer is None:
            self._closer = shutdown_soon(self._pool)

    def close(self) -> None:
        """Wait for every write, report them, stop the writers.

        Raises
        ------
        Exception
            The first error a write raised (every other write finished and was reported first).
        """
        try:
            self._harvest(wait=True)
        finally:
            if self._pool is not None:
                self.close_soon()
                self._closer.join()
                self._pool = self._closer = None
        if self._errors:
            errors, self._errors = self._errors, []
            raise errors[0]
