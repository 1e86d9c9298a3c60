"""Campaigns on Dask: each curve a worker finishes goes to the client at once, and the client writes it.

A task function that takes ``on_curve`` (:func:`~bubblecal.campaigns.simulate_task` with a streaming tier) hands
each finished curve to :func:`_execute_streaming` on the worker, which sends it to the client as a Dask event
(``Worker.log_event`` on a topic of this run; ``Client.subscribe_topic`` on the client).  The client's event
loop only queues what arrives; the calling thread is the one that writes the store, streamed curves and finished
tasks alike, so the store keeps a single writer.  Events are best effort (a curve sent just before its worker
dies may never arrive); the task's final result stays the authority: it writes every sample of the task not
already written in this run, so a task Dask re-runs after its worker died writes nothing twice and loses nothing
(docs/decisions.md, "Streaming Dask records through worker events").
"""

from __future__ import annotations

import hashlib
import os
import pickle
import queue
import socket
import time
from collections.abc import Callable

from bubblecal._extras import require
from bubblecal.campaigns.progress import _Progress
from bubblecal.campaigns.tasks import CampaignTask, TaskResult, _execute_task, _takes_on_curve

#: Seconds the client waits for a streamed curve or a finished task before it waits again (a bounded wait keeps
#: Ctrl-C prompt).
_POLL_S = 0.5


def _execute_streaming(simulate: Callable, task: CampaignTask, topic: str | None) -> TaskResult:
    """Run a task on a Dask worker, sending each finished curve to the client as an event on ``topic``.

    Parameters
    ----------
    simulate : callable
        The task function; curves stream only when it takes ``on_curve``.
    task : CampaignTask
        The task.
    topic : str or None
        The run's event topic; None runs the task without streaming.

    Returns
    -------
    TaskResult
        The task's full result (every replica, streamed or not), as :func:`~bubblecal.campaigns.tasks.
        _execute_task` returns it.
    """
    if topic is None or not _takes_on_curve(simulate):
        return _execute_task(simulate, task)
    worker = require("distributed", "sim").get_worker()
    t_task = time.perf_counter()
    host, pid = socket.gethostname(), os.getpid()

    def on_curve(r, y_row, status, info):
        """Send replica ``r``'s finished curve to the client (pickled: events carry msgpack-able data only)."""
        payload = (task.index, int(r), y_row, str(status), dict(info or {}), time.perf_counter() - t_task, host, pid)
        try:
            data = pickle.dumps(payload, protocol=pickle.HIGHEST_PROTOCOL)
        except (pickle.PicklingError, TypeError, AttributeError):
            return  # best effort: the task's result still carries this curve
        worker.log_event(topic, data)

    return _execute_task(simulate, task, on_curve)


def _run_dask(client, tasks: list[CampaignTask], simulate: Callable, writer, bar: _Progress, name: str) -> None:
    """Submit every task to ``client``; write each streamed curve and each finished task as it arrives.

    Parameters
    ----------
    client : distributed.Client
        The client (not closed here).
    tasks : list of CampaignTask
        The tasks of this run.
    simulate : callable
        The task function (picklable).
    writer : bubblecal.campaigns.runner._RecordWriter
        The run's store writer: ``curve_done`` for a streamed curve, ``task_done`` for a finished task.
    bar : _Progress
        Advanced per sample written.
    name : str
        Campaign name (in the task keys and the event topic).

    Raises
    ------
    CampaignError
        From ``writer.task_done`` (the campaign stopped on task errors); every task not yet finished is
        cancelled first, as on any other exception (an interrupt included).
    """
    token = hashlib.sha256(f"{time.time_ns()}-{os.getpid()}".encode()).hexdigest()[:8]
    streams = _takes_on_curve(simulate)
    topic = f"bubblecal-{name}-{token}" if streams else None
    by_index = {task.index: task for task in tasks}
    inbox: queue.Queue = queue.Queue()  # filled by the client's event loop and future callbacks; drained here
    if topic is not None:
        client.subscribe_topic(topic, lambda event: inbox.put(("curve", event[1])))
    futures = {}
    try:
        for task in tasks:
            fut = client.submit(_execute_streaming, simulate, task, topic, key=f"{name}-t{task.index:05d}-{token}",
                                pure=False)
            futures[fut.key] = (fut, task)
            fut.add_done_callback(lambda f: inbox.put(("task", f.key)))
        remaining = set(futures)
        while remaining:
            try:
                kind, item = inbox.get(timeout=_POLL_S)
            except queue.Empty:
                continue
            if kind == "curve":
                index, r, y_row, status, info, seconds, host, pid = pickle.loads(item)
                if index in by_index:
                    n = writer.curve_done(by_index[index], r, y_row, status, info, seconds=seconds, host=host,
                                          pid=pid)
                    bar.update(n, writer.counts)
                continue
            if item not in remaining:
                continue
            remaining.discard(item)
            fut, task = futures[item]
            try:
                res, err = fut.result(), None
            except Exception as exc:  # recorded or re-raised by task_done()
                res, err = None, exc
            bar.update(writer.task_done(task, res, err), writer.counts)
            fut.release()
    except BaseException:
        client.cancel([f for f, _ in futures.values()])
        raise
    finally:
        if topic is not None and client.status == "running":  # a closed client has nothing left to unsubscribe
            client.unsubscribe_topic(topic)
