"""Agents calibrated at once (`calibrate --jobs`): the process count, the grouping, the worker protocol (ready,
errors, deaths, outcomes) and a two-agent run whose files equal the one-after-the-other run's."""

from __future__ import annotations

import os
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from bubblecal.workflows.calibrate import (
    MAX_AUTO_JOBS,
    AgentHeader,
    AgentOutcome,
    AgentProcesses,
    CalibrationConfig,
    CalibrationError,
    agent_groups,
    agent_jobs,
    gpu_memory_shared,
)
from bubblecal.workflows.cli import app


@pytest.mark.parametrize(("jobs", "agents", "cores", "want"), [
    (None, 2, 2, 2), (None, 2, 1, 1), (None, 9, 64, MAX_AUTO_JOBS), (None, 3, 2, 2),
    (1, 2, 16, 1), (3, 2, 16, 2), (5, 9, 1, 5)])
def test_agent_jobs(jobs, agents, cores, want):
    """Automatic: one per agent up to the cores and MAX_AUTO_JOBS; requested: never more than the agents."""
    assert agent_jobs(jobs, agents, cores=cores) == want


@pytest.mark.parametrize("jobs", [0, -2])
def test_agent_jobs_below_one_is_an_error(jobs):
    with pytest.raises(CalibrationError, match=rf"--jobs {jobs}: give at least 1"):
        agent_jobs(jobs, 2)


def test_agent_groups_balance_costs_and_put_the_costliest_first():
    costs = {"a": 4, "b": 6, "c": 3, "d": 3}
    assert agent_groups(costs, 1) == [("a", "b", "c", "d")]
    groups = agent_groups(costs, 2)
    assert groups == [("b", "d"), ("a", "c")]  # longest first: b, a, then c and d to the lighter group
    loads = [sum(costs[a] for a in g) for g in groups]
    assert loads == sorted(loads, reverse=True)
    assert sorted(a for g in groups for a in g) == sorted(costs)
    assert agent_groups({"x": 1.0, "y": 1.0}, 5) == [("x",), ("y",)]  # never an empty group


def test_gpu_memory_shared_only_for_several_gpu_processes_and_never_over_the_user(monkeypatch):
    for name in ("XLA_PYTHON_CLIENT_PREALLOCATE", "XLA_PYTHON_CLIENT_MEM_FRACTION"):
        monkeypatch.delenv(name, raising=False)
    gpu_memory_shared("cpu", 2)
    gpu_memory_shared("gpu", 1)
    assert "XLA_PYTHON_CLIENT_PREALLOCATE" not in os.environ
    gpu_memory_shared("gpu", 2)
    assert os.environ["XLA_PYTHON_CLIENT_PREALLOCATE"] == "false"
    monkeypatch.delenv("XLA_PYTHON_CLIENT_PREALLOCATE")
    monkeypatch.setenv("XLA_PYTHON_CLIENT_MEM_FRACTION", "0.3")
    gpu_memory_shared("gpu", 2)
    assert "XLA_PYTHON_CLIENT_PREALLOCATE" not in os.environ


class _Process:
    """A stand-in worker process: alive until told otherwise."""

    def __init__(self, alive=True, exitcode=None):
        self.alive, self.exitcode = alive, exitcode

    def is_alive(self):
        return self.alive

    def join(self, timeout=None):
        return None

    def terminate(self):
        self.alive = False


def _workers(groups, processes):
    workers = AgentProcesses(CalibrationConfig(), groups, cache=False)
    workers.processes = processes
    return workers


def _outcome(agent):
    return AgentOutcome(AgentHeader(agent, "reduced", None, Path("x")), pd.DataFrame(), None,
                        {"sampling_total": 1.0}, [])


def test_listen_collects_outcomes_failures_and_names_the_agents_of_a_dead_worker():
    """Progress and stages go to the callbacks; a worker that ended without 'exit' fails its unfinished agents."""
    workers = _workers([("a", "b"), ("c", "d")], [_Process(), _Process(alive=False, exitcode=-9)])
    seen = []
    for msg in [("progress", "a", "phase1 a: done"), ("stage", "a", (0, {"beta": 0.5})),
                ("done", "a", _outcome("a")), ("failed", "b", "phase 2 failed"), ("exit", 0, None),
                ("done", "c", _outcome("c"))]:
        workers.queue.put(msg)
    thread = workers.listen(lambda a, m: seen.append(("progress", a, m)),
                            lambda a, r, row: seen.append(("stage", a, r, row["beta"])),
                            on_done=lambda a, o: seen.append(("done", a)))
    thread.join(timeout=60)
    assert not thread.is_alive()
    assert seen == [("progress", "a", "phase1 a: done"), ("stage", "a", 0, 0.5), ("done", "a"), ("done", "c")]
    assert set(workers.outcomes) == {"a", "c"}
    assert workers.failures["b"] == "phase 2 failed"
    assert workers.failures["d"].startswith("its process ended (exit code -9)")
    assert "c" not in workers.failures


def test_wait_ready_raises_the_workers_error_and_stops_the_others():
    workers = _workers([("a",), ("b",)], [_Process(), _Process()])
    workers.queue.put(("ready", 0, None))
    workers.queue.put(("warning", 1, "cache folder not writable"))
    workers.queue.put(("error", 1, "sonovue dataset x: the log likelihood is not finite"))
    warned = []
    with pytest.raises(CalibrationError, match="not finite"):
        workers.wait_ready(on_warning=warned.append)
    assert warned == ["cache folder not writable"]
    assert not any(p.is_alive() for p in workers.processes)


def test_wait_ready_names_a_worker_that_died_before_its_preflight():
    workers = _workers([("a",), ("b",)], [_Process(), _Process(alive=False, exitcode=1)])
    workers.queue.put(("ready", 0, None))
    with pytest.raises(CalibrationError, match=r"the process of b ended before its preflight \(exit code 1\)"):
        workers.wait_ready()


def test_a_real_worker_reports_its_planning_error(synthetic_bundle, tmp_path):
    """A spawned worker asked for an agent the run does not plan says so instead of hanging."""
    config = CalibrationConfig(agents=("definity",), workflow="reduced", bundle=synthetic_bundle, population=120,
                               out=tmp_path / "cal", phase2_samples=120, curves=("definity_compression_2.1um",))
    workers = AgentProcesses(config, [("sonovue",)], cache=False)
    workers.start()
    try:
        with pytest.raises(CalibrationError, match="plans no agent sonovue"):
            workers.wait_ready()
    finally:
        workers.stop()
    assert all(p.exitcode is not None for p in workers.processes)


def test_prestarted_workers_take_their_agents_in_order_and_the_spare_ones_end(synthetic_bundle, tmp_path):
    """Workers spawned before the plan: the first gets the group (and reports its planning error), the spare one
    ends by itself once it has started."""
    config = CalibrationConfig(agents=("definity",), workflow="reduced", bundle=synthetic_bundle, population=120,
                               out=tmp_path / "cal", phase2_samples=120, curves=("definity_compression_2.1um",))
    workers = AgentProcesses(cache=False)
    workers.prestart(2)
    workers.start(config, [("sonovue",)])
    try:
        assert len(workers.processes) == 1
        spare = workers._spare[0][0]
        spare.join(timeout=120)
        assert spare.exitcode == 0
        with pytest.raises(CalibrationError, match="plans no agent sonovue"):
            workers.wait_ready()
    finally:
        workers.stop()


def test_two_agents_at_once_write_what_one_after_the_other_writes(synthetic_bundle, tmp_path):
    """`--jobs 2` (Definity in a worker) and `--jobs 1`: every phase file and summary.csv equal, both summaries
    printed with the agents' names on their phase lines."""
    import numpy as np

    from bubblecal.workflows.calibrate import read_phase

    def run(jobs):
        out = tmp_path / f"jobs{jobs}"
        r = CliRunner().invoke(app, ["calibrate", "--bundle", str(synthetic_bundle), "--workflow", "reduced",
                                     "--curve", "definity_compression_2.1um", "--curve", "sonovue_indentation_3.2um",
                                     "--population", "120", "--phase2-samples", "120", "--mcmc-steps", "2",
                                     "--no-figures", "--jobs", str(jobs), "--out", str(out)])
        assert r.exit_code == 0, r.output
        return out, r.output

    serial, text1 = run(1)
    parallel, text2 = run(2)
    for agent in ("definity", "sonovue"):
        assert f"{agent}: wrote" in text1 and f"{agent}: wrote" in text2
        assert f"{agent}: phase1_" in text2  # agents at once: phase lines carry the agent
        a, b = serial / agent / "reduced", parallel / agent / "reduced"
        names = sorted(p.name for p in a.glob("phase*.nc"))
        assert names and names == sorted(p.name for p in b.glob("phase*.nc"))
        for name in names:
            (x, lx), (y, ly) = read_phase(a / name), read_phase(b / name)
            np.testing.assert_array_equal(lx, ly, err_msg=name)
            for k in x.samples:
                np.testing.assert_array_equal(np.asarray(x.samples[k]), np.asarray(y.samples[k]), err_msg=name)
        pd.testing.assert_frame_equal(pd.read_csv(a / "summary.csv"), pd.read_csv(b / "summary.csv"))


def test_the_command_ends_cleanly_with_a_worker(synthetic_bundle, tmp_path):
    """`python -m bubblecal.workflows.cli calibrate` with two agents (one in a worker): exit status 0, both agents
    written, and no leaked-semaphore report from multiprocessing although the process skips its teardown."""
    import subprocess
    import sys

    out = tmp_path / "cal"
    proc = subprocess.run([sys.executable, "-m", "bubblecal.workflows.cli", "calibrate", "--bundle",
                           str(synthetic_bundle), "--workflow", "reduced", "--curve", "definity_compression_2.1um",
                           "--curve", "sonovue_indentation_3.2um", "--population", "120", "--phase2-samples", "120",
                           "--mcmc-steps", "2", "--no-figures", "--jobs", "2", "--out", str(out)],
                          capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "definity: wrote" in proc.stdout and "sonovue: wrote" in proc.stdout
    assert "leaked" not in proc.stderr, proc.stderr[-2000:]


def test_a_failed_agent_does_not_stop_the_other_and_is_named(synthetic_bundle, tmp_path, monkeypatch):
    """Agents at once: Definity (equal cost, first in run order: this process's group) fails, SonoVue (a worker)
    still finishes; exit status 1 names Definity and its folder."""
    import bubblecal.workflows.calibrate as calibrate

    real = calibrate.run_agent_with_report

    def run_agent_with_report(plan, ap, **kwargs):
        if ap.agent == "definity":
            raise RuntimeError("injected failure in phase 1")
        return real(plan, ap, **kwargs)

    monkeypatch.setattr(calibrate, "run_agent_with_report", run_agent_with_report)
    out = tmp_path / "cal"
    r = CliRunner().invoke(app, ["calibrate", "--bundle", str(synthetic_bundle), "--workflow", "reduced",
                                 "--curve", "definity_compression_2.1um", "--curve", "sonovue_indentation_3.2um",
                                 "--population", "120", "--phase2-samples", "120", "--mcmc-steps", "2",
                                 "--no-figures", "--jobs", "2", "--out", str(out)])
    assert r.exit_code == 1, (r.output, repr(r.exception))
    assert "definity: injected failure in phase 1 (finished phases are kept in" in " ".join(r.output.split())
    assert "sonovue: wrote" in r.output
    assert (out / "sonovue" / "reduced" / "summary.csv").is_file()
    assert not (out / "definity" / "reduced" / "summary.csv").exists()
