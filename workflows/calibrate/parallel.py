"""Agents calibrated at once: each group of agents in its own spawned process, one group in the calling one.

An agent's staged run is a chain of small programs (one thread traces and lowers them, since NumPyro's handler
stack is process-global) with waits on the device in between; two agents in two processes fill each other's
waits and lower their programs side by side (docs/decisions.md, "Agents in parallel processes").  The results are
those of a serial run: each agent draws from its own seed and reads only its own inputs.

Protocol: the command prestarts the workers before it imports JAX (:meth:`AgentProcesses.prestart`: interpreter,
imports, device), validates the whole plan (``make_plan(config, check_likelihoods=False)``), hands each worker its
agents (:meth:`AgentProcesses.start`; prestarted workers not needed end), runs the preflight of its own group, then
:meth:`AgentProcesses.wait_ready` collects every worker's preflight (no agent samples before every dataset of every
agent passed it) and :meth:`AgentProcesses.go` lets them run.  Workers
(:mod:`~bubblecal.workflows.calibrate.agent_worker`) report progress, TMCMC stages and a picklable
:class:`~bubblecal.workflows.calibrate.AgentOutcome` per agent through one queue, drained by
:meth:`AgentProcesses.listen`.
"""

from __future__ import annotations

import multiprocessing
import os
import queue as queue_module
import threading
from collections.abc import Callable, Mapping, Sequence

from bubblecal.workflows.calibrate.agent_worker import AgentOutcome, _worker
from bubblecal.workflows.calibrate.config import CalibrationConfig, CalibrationError
from bubblecal.workflows.calibrate.device import usable_cores
from bubblecal.workflows.calibrate.imports import preload

__all__ = ["AgentProcesses", "MAX_AUTO_JOBS", "agent_groups", "agent_jobs", "gpu_memory_shared"]

#: Most agent processes that ``jobs=None`` (automatic) starts.
MAX_AUTO_JOBS = 4

#: Seconds between checks that the workers are alive while their queue is quiet.
_POLL_S = 0.5


def agent_jobs(jobs: int | None, n_agents: int, cores: int | None = None) -> int:
    """Processes to calibrate ``n_agents`` agents with.

    Parameters
    ----------
    jobs : int or None
        Requested processes (>= 1); None: one per agent, at most the usable cores and :data:`MAX_AUTO_JOBS`.
    n_agents : int
        Agents of the run.
    cores : int or None
        Usable cores (default: :func:`~bubblecal.workflows.calibrate.usable_cores`).

    Returns
    -------
    int
        Between 1 and ``n_agents`` (more processes than agents would have nothing to run).

    Raises
    ------
    CalibrationError
        ``jobs`` < 1.
    """
    if jobs is not None and int(jobs) < 1:
        raise CalibrationError(f"--jobs {jobs}: give at least 1 (agents calibrated at once)")
    if jobs is None:
        cores = usable_cores() if cores is None else int(cores)
        jobs = min(cores, MAX_AUTO_JOBS)
    return max(1, min(int(jobs), int(n_agents)))


def agent_groups(costs: Mapping[str, float], jobs: int) -> list[tuple[str, ...]]:
    """Split agents into ``jobs`` groups of similar cost, the costliest group first (longest job first).

    Parameters
    ----------
    costs : mapping of str to float
        Agent -> its relative cost (e.g. its number of datasets), in run order.
    jobs : int
        Groups (>= 1).

    Returns
    -------
    list of tuple of str
        Non-empty groups, each in run order; the first has the largest total cost (the calling process runs it,
        since it starts first).
    """
    order = list(costs)
    groups: list[list[str]] = [[] for _ in range(max(1, min(int(jobs), len(order))))]
    load = [0.0] * len(groups)
    for name in sorted(order, key=lambda a: (-float(costs[a]), order.index(a))):
        k = min(range(len(groups)), key=lambda i: (load[i], i))
        groups[k].append(name)
        load[k] += float(costs[name])
    ranked = sorted(range(len(groups)), key=lambda i: (-load[i], i))
    return [tuple(sorted(groups[i], key=order.index)) for i in ranked if groups[i]]


class AgentProcesses:
    """Worker processes, one per group of agents, started from a validated configuration.

    Parameters
    ----------
    config : CalibrationConfig or None
        The run's configuration (each worker plans its own agents from it); None: given to :meth:`start`.
    groups : sequence of tuple of str
        One group of agents per worker (or given to :meth:`start`).
    cache : bool
        Switch the persistent compilation cache on in the workers (as in the caller).
    device : str or None
        'gpu': each worker starts its GPU while it waits for its agents (:meth:`prestart`).

    Notes
    -----
    Workers are spawned, never forked (JAX is not fork-safe), and inherit the environment: the caller sets
    ``XLA_FLAGS`` and the GPU memory settings before :meth:`prestart` or :meth:`start`.
    """

    def __init__(self, config: CalibrationConfig | None = None, groups: Sequence[tuple[str, ...]] = (), *,
                 cache: bool = True, device: str | None = None):
        self._ctx = multiprocessing.get_context("spawn")
        self.config = config
        self.groups = [tuple(g) for g in groups]
        self.cache = bool(cache)
        self.device = device
        self.queue = self._ctx.Queue()
        self._go = self._ctx.Event()
        self.processes: list = []
        self._inboxes: list = []
        self._spare: list = []
        self._exited: set[int] = set()
        self.outcomes: dict[str, AgentOutcome] = {}
        self.failures: dict[str, str] = {}

    def prestart(self, n: int) -> None:
        """Spawn ``n`` workers before the run is planned: their interpreter start, imports and device start-up
        overlap the caller's planning; :meth:`start` then hands them their agents (and ends those not needed).

        Parameters
        ----------
        n : int
            Workers to spawn now (>= 0).
        """
        for _ in range(int(n)):
            self._spawn()

    def _spawn(self) -> None:
        """Spawn one worker, waiting for its agents."""
        inbox = self._ctx.Queue()
        k = len(self.processes)
        p = self._ctx.Process(target=_worker, args=(k, self.cache, self.device, self.queue, self._go, inbox),
                              name=f"bubblecal-agents-{k}", daemon=False)
        p.start()
        self.processes.append(p)
        self._inboxes.append(inbox)

    def start(self, config: CalibrationConfig | None = None, groups: Sequence[tuple[str, ...]] | None = None) -> None:
        """Give each worker its group (spawning those not prestarted); they plan and run their preflight at once,
        then wait for :meth:`go`. Prestarted workers beyond the groups are ended.

        Parameters
        ----------
        config : CalibrationConfig or None
            The run's configuration (default: the constructor's).
        groups : sequence of tuple of str or None
            One group of agents per worker (default: the constructor's).
        """
        if config is not None:
            self.config = config
        if groups is not None:
            self.groups = [tuple(g) for g in groups]
        while len(self.processes) < len(self.groups):
            self._spawn()
        self.dismiss(len(self.groups))
        for inbox, group in zip(self._inboxes, self.groups, strict=True):
            inbox.put((self.config, group))

    def dismiss(self, keep: int = 0) -> None:
        """End the workers from index ``keep`` on that have no agents yet (they exit at once; :meth:`stop` joins
        them).

        Parameters
        ----------
        keep : int
            Workers kept.
        """
        for inbox in self._inboxes[keep:]:
            inbox.put(None)
        # the inboxes stay referenced: a spawned process opens its queue's semaphores by name when it starts
        self._spare += list(zip(self.processes[keep:], self._inboxes[keep:], strict=True))
        del self.processes[keep:], self._inboxes[keep:]

    def _get(self):
        """The next message, or None when the queue was quiet for a poll interval."""
        try:
            return self.queue.get(timeout=_POLL_S)
        except queue_module.Empty:
            return None

    def _dead(self) -> list[int]:
        """Workers that ended without saying so (killed, out of memory)."""
        return [k for k, p in enumerate(self.processes) if k not in self._exited and not p.is_alive()]

    def wait_ready(self, on_warning: Callable[[str], None] | None = None) -> None:
        """Block until every worker passed its plan and preflight.

        Parameters
        ----------
        on_warning : callable or None
            Receives the workers' warning lines (e.g. about the compilation cache).

        Raises
        ------
        CalibrationError
            A worker's plan or preflight failed (its message), or a worker ended before it was ready; the
            workers are stopped.
        """
        ready: set[int] = set()
        while len(ready) < len(self.processes):
            msg = self._get()
            if msg is None:
                dead = [k for k in self._dead() if k not in ready]
                if dead:
                    self.stop()
                    k = dead[0]
                    raise CalibrationError(f"the process of {', '.join(self.groups[k])} ended before its preflight "
                                           f"(exit code {self.processes[k].exitcode})")
                continue
            kind, who, payload = msg
            if kind == "ready":
                ready.add(who)
            elif kind == "error":
                self.stop()
                raise CalibrationError(payload)
            elif kind == "warning" and on_warning is not None:
                on_warning(payload)

    def go(self) -> None:
        """Let the workers sample."""
        self._go.set()

    def listen(self, on_progress: Callable[[str, str], None], on_stage: Callable[[str, int, Mapping], None],
               on_warning: Callable[[str], None] | None = None,
               on_done: Callable[[str, AgentOutcome], None] | None = None) -> threading.Thread:
        """Drain the workers' messages on a thread until every worker has ended.

        Parameters
        ----------
        on_progress : callable
            ``on_progress(agent, message)``.
        on_stage : callable
            ``on_stage(agent, replica, row)`` per TMCMC stage.
        on_warning : callable or None
            Receives warning lines.
        on_done : callable or None
            ``on_done(agent, outcome)`` as each agent finishes.

        Returns
        -------
        threading.Thread
            Join it; then :attr:`outcomes` holds each finished agent and :attr:`failures` each failed one (a
            worker that died names all of its agents not yet finished).
        """
        def drain() -> None:
            preload(("pandas",))  # an outcome unpickles DataFrames: not beside another thread's import of pandas
            while len(self._exited) < len(self.processes):
                msg = self._get()
                if msg is None:
                    for k in self._dead():
                        self._exited.add(k)
                        for agent in self.groups[k]:
                            if agent not in self.outcomes and agent not in self.failures:
                                self.failures[agent] = (f"its process ended (exit code {self.processes[k].exitcode})"
                                                        " before the agent finished")
                    continue
                kind, who, payload = msg
                if kind == "progress":
                    on_progress(who, payload)
                elif kind == "stage":
                    on_stage(who, *payload)
                elif kind == "done":
                    self.outcomes[who] = payload
                    if on_done is not None:
                        on_done(who, payload)
                elif kind == "failed":
                    self.failures[who] = payload
                elif kind == "exit":
                    self._exited.add(who)
                elif kind == "warning" and on_warning is not None:
                    on_warning(payload)
            for p in self.processes:
                p.join()

        thread = threading.Thread(target=drain, name="bubblecal-agent-listener", daemon=True)
        thread.start()
        return thread

    def stop(self) -> None:
        """Terminate every worker still running (finished phases stay on disk and are reused on rerun)."""
        every = [*self.processes, *(p for p, _ in self._spare)]
        for p in every:
            if p.is_alive():
                p.terminate()
        for p in every:
            p.join(timeout=10)


def gpu_memory_shared(device: str, jobs: int) -> None:
    """Let ``jobs`` processes share one GPU: JAX then allocates on demand instead of 75 % of the memory each.

    Sets ``XLA_PYTHON_CLIENT_PREALLOCATE=false`` in the environment unless the user set it or
    ``XLA_PYTHON_CLIENT_MEM_FRACTION``; call it before JAX starts its GPU backend.

    Parameters
    ----------
    device : str
        'gpu' or 'cpu' (nothing to do).
    jobs : int
        Processes that will share the GPU.
    """
    if device != "gpu" or jobs < 2:
        return
    if "XLA_PYTHON_CLIENT_PREALLOCATE" in os.environ or "XLA_PYTHON_CLIENT_MEM_FRACTION" in os.environ:
        return
    os.environ["XLA_PYTHON_CLIENT_PREALLOCATE"] = "false"
