"""An agent's figures drawn side by side in processes where cores are spare.

Matplotlib renders under the interpreter lock, so threads would draw the figures one after the other; processes
(spawned, started while the agent samples, each importing matplotlib and the figure modules) draw them side by
side. What crosses to a process is a host-only copy of the summarised run (:func:`figure_snapshot`, written once to a
temporary file that each process reads): the phase-2 and phase-3 draws, bands and priors, no sampler, surrogate,
bundle or device array (the acoustic figure's f_res band is evaluated before,
:func:`bubblecal.workflows.figures.acoustic_band`).
"""

from __future__ import annotations

import dataclasses
import functools
import pickle
from collections.abc import Sequence
from pathlib import Path

__all__ = ["FigureProcesses", "drawing_processes", "figure_snapshot", "FIGURE_MODULES"]

#: Submission order, costliest first (the population grid and the fit pages take two to three times the others).
_COSTLIEST_FIRST = ("population_figure", "fit_figure", "forest_figure", "ka_kb_figure", "acoustic_figure",
                    "diameter_figure")
#: What drawing imports: each figure process imports it when it starts (:meth:`FigureProcesses.start`).
FIGURE_MODULES = ("pandas", "matplotlib.figure", "matplotlib.backends.backend_agg", "bubblecal.workflows.figures")


def figure_snapshot(result, plan) -> bytes:
    """The pickled (result, plan) the figures need: phases 2 and 3 without their samplers, no surrogate, bundle or
    log likelihood, device arrays as NumPy arrays.

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
        A summarised run.
    plan : bubblecal.workflows.calibrate.Plan

    Returns
    -------
    bytes
        A pickle that loads without JAX.
    """
    import io

    staged = result.staged
    if staged is not None:  # the samplers hold models and programs; the figures read phases 2 and 3 only
        bare = lambda r: dataclasses.replace(r, sampler=None)  # noqa: E731
        staged = dataclasses.replace(staged, phase1=[], phase2=bare(staged.phase2),
                                     phase3=[bare(r) for r in staged.phase3])
    # the networks and the acoustic law import JAX: the figures read draws and bands, never a surrogate
    ap = dataclasses.replace(result.plan, surrogates=[None] * len(result.plan.surrogates), f_res=None)
    slim = dataclasses.replace(plan, bundle=None, agents=[]) if dataclasses.is_dataclass(plan) else plan
    buffer = io.BytesIO()
    _HostPickler(buffer, protocol=pickle.HIGHEST_PROTOCOL).dump(
        (dataclasses.replace(result, plan=ap, staged=staged, loglik={}, pointwise={}), slim))
    return buffer.getvalue()


class _HostPickler(pickle.Pickler):
    """Pickles every JAX array as a NumPy array (a figure process never imports JAX)."""

    def reducer_override(self, obj):
        if type(obj).__module__.startswith(("jax", "jaxlib")) and hasattr(obj, "__array__"):
            import numpy as np

            return np.asarray, (np.asarray(obj),)
        return NotImplemented


@functools.lru_cache(maxsize=2)
def _snapshot(path: str) -> tuple:
    """The (result, plan) of a snapshot file, read once per process."""
    return pickle.loads(Path(path).read_bytes())


def _draw(snapshot: str, name: str, path: Path, kwargs) -> list[Path]:
    """Draw one figure from a :func:`figure_snapshot` file (module level: a figure process unpickles it)."""
    from bubblecal.workflows.figures import draw_figure

    result, plan = _snapshot(snapshot)
    return draw_figure(name, result, plan, path, **kwargs)


def drawing_processes(device: str, cpus: int | None = None) -> int:
    """Figure processes of an agent of a run on ``device`` (0: it draws its figures itself).

    Parameters
    ----------
    device : str
        The run's device, 'cpu' or 'gpu'.
    cpus : int or None
        Cores (None: those this process may run on).

    Returns
    -------
    int
        ``helper_processes('figure', cpus)`` on a GPU run (:func:`~bubblecal.workflows.calibrate.device.
        helper_processes`); 0 on CPU devices, where the phases keep every core busy and the processes' imports
        would compete with them.
    """
    if device != "gpu":
        return 0
    from bubblecal.workflows.calibrate.device import helper_processes

    return helper_processes("figure", cpus)


class FigureProcesses:
    """Figure processes of one agent: started ahead, then the figures of a run drawn side by side.

    Parameters
    ----------
    processes : int or None
        Processes; None: ``helper_processes('figure')`` of this machine
        (:func:`~bubblecal.workflows.calibrate.device.helper_processes`; 0: :meth:`draw` draws in this process).
    """

    def __init__(self, processes: int | None = None):
        from bubblecal.workflows.calibrate.device import helper_processes

        self.processes = helper_processes("figure") if processes is None else int(processes)
        self._pool = None
        self._closer = None
        self._futures: dict[str, object] = {}
        self._folder: Path | None = None

    def start(self) -> None:
        """Spawn the processes now, each importing :data:`FIGURE_MODULES` (a no-op without processes or once
        started)."""
        if self._pool is not None or self.processes == 0:
            return
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        from bubblecal.workflows.calibrate.imports import preload

        self._pool = ProcessPoolExecutor(self.processes, mp_context=multiprocessing.get_context("spawn"))
        # one warm-up task per process: the pool spawns a process for each task that finds none idle
        for _ in range(self.processes):
            self._pool.submit(preload, FIGURE_MODULES)

    def submit(self, result, plan, figures: Sequence[tuple[str, Path, dict]]) -> None:
        """Start drawing ``figures`` now, the costliest first (e.g. :data:`~bubblecal.workflows.figures.PHASE_FIGURES`
        before the summaries exist); :meth:`draw` collects them. A no-op without processes.

        Parameters
        ----------
        result : bubblecal.workflows.calibrate.AgentResult
        plan : bubblecal.workflows.calibrate.Plan
        figures : sequence of (str, Path, dict)
            Name of :data:`bubblecal.workflows.figures.FIGURES`, PNG path, keyword arguments of
            :func:`~bubblecal.workflows.figures.draw_figure`.
        """
        if self.processes == 0 or not figures:
            return
        import tempfile

        self.start()
        if self._folder is None:
            self._folder = Path(tempfile.mkdtemp(prefix="bubblecal-figures-"))
        snapshot = self._folder / f"snapshot{len(list(self._folder.iterdir()))}.pkl"
        snapshot.write_bytes(figure_snapshot(result, plan))  # once: every process reads the one file
        rank = {name: k for k, name in enumerate(_COSTLIEST_FIRST)}
        for name, path, kwargs in sorted(figures, key=lambda f: rank.get(f[0], -1)):
            self._futures[name] = self._pool.submit(_draw, str(snapshot), name, Path(path), kwargs)

    def draw(self, result, plan, figures: Sequence[tuple[str, Path, dict]]) -> list[Path]:
        """Draw ``figures`` of a summarised run (those :meth:`submit` started are collected), then let the processes
        end.

        Parameters
        ----------
        result : bubblecal.workflows.calibrate.AgentResult
        plan : bubblecal.workflows.calibrate.Plan
        figures : sequence of (str, Path, dict)
            As :meth:`submit`.

        Returns
        -------
        list of Path
            The written files in the order of ``figures``.

        Raises
        ------
        Exception
            The first error a figure raised (after every figure finished).
        """
        if self.processes == 0:
            from bubblecal.workflows.figures import draw_jobs

            return draw_jobs(result, plan, figures)
        self.submit(result, plan, [f for f in figures if f[0] not in self._futures])
        out: list[Path] = []
        error = None
        for name, _path, _kwargs in figures:
            try:
                out += self._futures.pop(name).result()
            except Exception as exc:  # noqa: BLE001, PERF203 - every figure finishes before the first error is raised
                error = error or exc
        self.close_soon()
        if error is not None:
            raise error
        return out

    def close_soon(self) -> None:
        """Let the processes end once their figures are drawn (their interpreters' exit overlaps the caller's work);
        no figure can be submitted after it."""
        if self._pool is not None and self._closer is None:
            from bubblecal.workflows.calibrate.agent_worker import shutdown_soon

            self._closer = shutdown_soon(self._pool)

    def close(self) -> None:
        """Stop the processes (waits for any figure still drawing) and remove the snapshot files."""
        import shutil

        if self._pool is not None:
            self.close_soon()
            self._closer.join()
            self._pool = self._closer = None
        self._futures.clear()
        if self._folder is not None:
            shutil.rmtree(self._folder, ignore_errors=True)
            self._folder = None
