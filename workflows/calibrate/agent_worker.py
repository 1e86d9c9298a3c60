"""The body of an agent worker process and what crosses back from it (:mod:`bubblecal.workflows.calibrate.parallel`).

A worker starts before the run is planned: it switches the compilation cache on and imports what planning and
sampling need (:data:`RUN_MODULES`), then takes its agents from its inbox while the GPU starts on a thread, plans
them, runs their preflight, reports ready, waits for the go and runs them one by one. Everything it returns is host data
(:class:`AgentOutcome`), and it ends without the interpreter's teardown once its messages are queued.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from bubblecal.workflows.calibrate.config import CalibrationConfig, CalibrationError
from bubblecal.workflows.calibrate.imports import library, preload, preload_soon

__all__ = ["AgentHeader", "AgentOutcome", "LATE_MODULES", "RUN_MODULES", "late_modules", "outcome_of",
           "shutdown_soon"]


@dataclass(frozen=True)
class AgentHeader:
    """What the summary table of an agent names: agent (label), workflow, priors and output folder."""

    agent: str
    workflow: str
    spec: object
    out_dir: Path


@dataclass
class AgentOutcome:
    """One agent's finished run as a worker process returns it (host data only, picklable).

    Parameters
    ----------
    plan : AgentHeader
        Agent, workflow, priors (:class:`bubblecal.priors.PriorSpec`) and output folder.
    summary : pandas.DataFrame or None
        ``summary.csv``.
    ess : pandas.DataFrame or None
        ``ess.csv``.
    seconds : dict of str to float
        Wall seconds per phase, of the sampling and of the summaries.
    reused : list of str
        Phases read back from disk.
    figures : list of Path
    report : Path or None
    """

    plan: AgentHeader
    summary: object
    ess: object | None
    seconds: dict[str, float]
    reused: list[str]
    figures: list[Path] = field(default_factory=list)
    report: Path | None = None


def outcome_of(result) -> AgentOutcome:
    """The :class:`AgentOutcome` of an :class:`~bubblecal.workflows.calibrate.AgentResult`.

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult

    Returns
    -------
    AgentOutcome
    """
    ap = result.plan
    return AgentOutcome(AgentHeader(ap.agent, ap.workflow, ap.spec, Path(ap.out_dir)), result.summary, result.ess,
                        dict(result.seconds), list(result.reused), list(result.figures), result.report)


def _stage_row(row: Mapping) -> dict:
    """A TMCMC stage row as plain floats and ints (it crosses a process boundary)."""
    out = {}
    for k, v in dict(row).items():
        with contextlib.suppress(TypeError, ValueError):
            out[k] = v if isinstance(v, int | str) else float(v)
    return out


#: Modules a worker needs to plan, check and sample its agents: imported while it waits for them.
RUN_MODULES = ("bubblecal.workflows.calibrate.plan", "bubblecal.workflows.calibrate.preflight",
               "bubblecal.workflows.calibrate.run")


def shutdown_soon(pool) -> threading.Thread:
    """Shut a pool down on a daemon thread: its queued tasks still run, then its processes (or threads) end while
    the caller goes on; join the thread to wait for their end.

    Parameters
    ----------
    pool : concurrent.futures.Executor

    Returns
    -------
    threading.Thread
        The started thread.
    """
    thread = threading.Thread(target=pool.shutdown, kwargs={"wait": True}, name="bubblecal-pool-shutdown",
                              daemon=True)
    thread.start()
    return thread


#: Libraries an agent's summaries and figures import (none imports bubblecal): imported while the processes wait
#: for each other's preflight (:func:`preload_soon`, :func:`late_modules`).
LATE_MODULES = ("pandas", "matplotlib.figure", "matplotlib.backends.backend_agg")


def late_modules(device: str) -> tuple[str, ...]:
    """The :data:`LATE_MODULES` an agent's process imports itself: pandas, and matplotlib unless the figures are
    drawn in figure processes (:func:`~bubblecal.workflows.calibrate.figure_processes.drawing_processes`).

    Parameters
    ----------
    device : str
        The run's device, 'cpu' or 'gpu'.

    Returns
    -------
    tuple of str
    """
    from bubblecal.workflows.calibrate.figure_processes import drawing_processes

    return LATE_MODULES[:1] if drawing_processes(device) else LATE_MODULES


def _worker(index: int, cache: bool, device: str | None, queue, go, inbox) -> None:
    """A worker process: start (cache, imports, device), wait for its agents in ``inbox`` (None: not needed, exit),
    then plan and preflight them, report ready, wait for ``go`` and run them one by one."""
    try:
        if cache:
            from bubblecal.workflows.compile_cache import enable_compilation_cache

            enable_compilation_cache(say=lambda m: queue.put(("warning", index, m)))
        preload(RUN_MODULES)
        if device == "gpu":  # the device starts (CUDA context) while the agents arrive and are planned
            threading.Thread(target=_start_gpu, name="bubblecal-gpu-start", daemon=True).start()
        assignment = inbox.get()
        if assignment is None:
            return
        _work(*assignment, index, queue, go)
    except KeyboardInterrupt:  # Ctrl-C reaches the whole process group: the caller reports it, once
        return
    # every file is closed: once the messages are out, end without the teardown the caller would wait for
    queue.close()
    queue.join_thread()
    from bubblecal.workflows.console import end_process

    end_process(0)


def _start_gpu() -> None:
    """Start JAX's GPU backend (a failure is left to the preflight, which reports it), JAX imported in the import
    turn (:mod:`~bubblecal.workflows.calibrate.imports`): the worker plans its agents meanwhile."""
    with contextlib.suppress(Exception):
        library("jax").devices("gpu")


def _work(config: CalibrationConfig, agents: tuple[str, ...], index: int, queue, go) -> None:
    """The planning and the runs of :func:`_worker`."""
    try:
        preload(("jax",))  # complete before planning imports it, if the GPU start's thread is importing it
        from bubblecal.workflows.calibrate.plan import make_plan

        plan = make_plan(config, agents=agents)
    except CalibrationError as exc:
        queue.put(("error", index, str(exc)))
        return
    except Exception as exc:  # noqa: BLE001 - reported by the parent, which owns the console
        queue.put(("error", index, f"{type(exc).__name__}: {exc}"))
        return
    queue.put(("ready", index, None))
    preload_soon(late_modules(config.device))
    go.wait()
    from bubblecal.workflows.calibrate.run import run_agent_with_report

    for ap in plan.agents:
        try:
            result = run_agent_with_report(
                plan, ap, progress=lambda m, a=ap.agent: queue.put(("progress", a, m)),
                stages=lambda r, row, a=ap.agent: queue.put(("stage", a, (r, _stage_row(row)))))
            queue.put(("done", ap.agent, outcome_of(result)))
        except Exception as exc:  # noqa: BLE001 - one agent's failure is reported, the next agent still runs
            text = str(exc) if isinstance(exc, RuntimeError) else f"{type(exc).__name__}: {exc}"
            queue.put(("failed", ap.agent, text))
    queue.put(("exit", index, None))
