"""An agent's figures drawn at once, one per process, where cores are spare.

Matplotlib renders under the interpreter lock, so threads would draw the figures one after the other; processes
(spawned, started while the agent samples, each importing matplotlib and the figure modules) draw them side by
side. What crosses to a process is a host-only copy of the summarised run (:func:`figure_snapshot`): draws,
bands and priors, no sampler, surrogate, bundle or device array (the acoustic figure's f_res band is evaluated
before, :func:`bubblecal.workflows.figures.acoustic_band`).
"""

from __future__ import annotations

import dataclasses
import pickle
from collections.abc import Sequence
from pathlib import Path

__all__ = ["FigureProcesses", "figure_processes", "figure_snapshot", "FIGURE_MODULES", "FIGURE_PROCESS_MIN_CPUS",
           "MAX_FIGURE_PROCESSES"]

#: Cores from which an agent draws its figures in processes.
FIGURE_PROCESS_MIN_CPUS = 8
#: Most figure processes per agent: one per figure (``population.png`` starts before the summaries, the other five
#: after them), so that the figures take about the time of the costliest one.
MAX_FIGURE_PROCESSES = 6
#: Submission order, costliest first (the population grid and the fit pages take two to three times the others).
_COSTLIEST_FIRST = ("population_figure", "fit_figure", "forest_figure", "ka_kb_figure", "acoustic_figure",
                    "diameter_figure")
#: What drawing imports: each figure process imports it when it starts (:meth:`FigureProcesses.start`).
FIGURE_MODULES = ("pandas", "matplotlib.figure", "matplotlib.backends.backend_agg", "bubblecal.workflows.figures")


def figure_processes(cpus: int | None = None) -> int:
    """Figure processes for a machine of ``cpus`` cores (0: draw in the agent's own process).

    Parameters
    ----------
    cpus : int or None
        Cores (None: those this process may run on).

    Returns
    -------
    int
        0 below :data:`FIGURE_PROCESS_MIN_CPUS` cores, else min(:data:`MAX_FIGURE_PROCESSES`, cpus // 3).
    """
    if cpus is None:
        from bubblecal.workflows.calibrate.device import usable_cores

        cpus = usable_cores()
    return 0 if cpus < FIGURE_PROCESS_MIN_CPUS else min(MAX_FIGURE_PROCESSES, cpus // 3)


def figure_snapshot(result, plan) -> bytes:
    """The pickled (result, plan) a figure needs: no sampler, surrogate, bundle or pointwise log likelihood, device
    arrays as NumPy arrays.

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
    if staged is not None:  # the samplers hold models and programs: a figure reads the draws only
        bare = lambda r: dataclasses.replace(r, sampler=None)  # noqa: E731
        staged = dataclasses.replace(staged, phase1=[bare(r) for r in staged.phase1], phase2=bare(staged.phase2),
                                     phase3=[bare(r) for r in staged.phase3])
    # the networks and the acoustic law import JAX: the figures read draws and bands, never a surrogate
    ap = dataclasses.replace(result.plan, surrogates=[None] * len(result.plan.surrogates), f_res=None)
    slim = dataclasses.replace(plan, bundle=None, agents=[]) if dataclasses.is_dataclass(plan) else plan
    buffer = io.BytesIO()
    _HostPickler(buffer, protocol=pickle.HIGHEST_PROTOCOL).dump(
        (dataclasses.replace(result, plan=ap, staged=staged, pointwise={}), slim))
    return buffer.getvalue()


class _HostPickler(pickle.Pickler):
    """Pickles every JAX array as a NumPy array (a figure process never imports JAX)."""

    def reducer_override(self, obj):
        if type(obj).__module__.startswith(("jax", "jaxlib")) and hasattr(obj, "__array__"):
            import numpy as np

            return np.asarray, (np.asarray(obj),)
        return NotImplemented


def _draw(payload: bytes, name: str, path: Path, kwargs) -> list[Path]:
    """Draw one figure from a :func:`figure_snapshot` (module level: a figure process unpickles it)."""
    from bubblecal.workflows.figures import draw_figure

    result, plan = pickle.loads(payload)
    return draw_figure(name, result, plan, path, **kwargs)


class FigureProcesses:
    """Figure processes of one agent: started ahead, then each figure of a run drawn in its own.

    Parameters
    ----------
    processes : int or None
        Processes; None: :func:`figure_processes` of this machine (0: :meth:`draw` draws in this process).
    """

    def __init__(self, processes: int | None = None):
        self.processes = figure_processes() if processes is None else int(processes)
        self._pool = None
        self._closer = None
        self._futures: dict[str, object] = {}

    def start(self) -> None:
        """Spawn the processes now, each importing :data:`FIGURE_MODULES` (a no-op without processes or once
        started)."""
        if self._pool is not None or self.processes == 0:
            return
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        from bubblecal.workflows.calibrate.agent_worker import preload

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
        self.start()
        payload = figure_snapshot(result, plan)
        rank = {name: k for k, name in enumerate(_COSTLIEST_FIRST)}
        for name, path, kwargs in sorted(figures, key=lambda f: rank.get(f[0], -1)):
            self._futures[name] = self._pool.submit(_draw, payload, name, Path(path), kwargs)

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
        from bubblecal.workflows.figures import draw_figure

        if self.processes == 0:
            return [p for name, path, kwargs in figures for p in draw_figure(name, result, plan, path, **kwargs)]
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
        """Let the processes end once their figures are drawn (their interpreters' exit overlaps the caller's work)."""
        if self._pool is not None and self._closer is None:
            from bubblecal.workflows.calibrate.agent_worker import shutdown_soon

            self._closer = shutdown_soon(self._pool)

    def close(self) -> None:
        """Stop the processes (waits for any figure still drawing)."""
        if self._pool is not None:
            self.close_soon()
            self._closer.join()
            self._pool = self._closer = None
        self._futures.clear()
