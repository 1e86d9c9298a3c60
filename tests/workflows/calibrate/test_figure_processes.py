"""Figures drawn in figure processes: the same files as drawn in the agent's process, from a snapshot without JAX."""

from __future__ import annotations

import subprocess
import sys

import pytest

from tests.workflows.test_figures_many import fake_result


def test_processes_draw_the_same_files_as_the_agent_process(tmp_path):
    """Every figure of a fake summarised run, byte for byte, in the same order, the figures of the phases alone
    submitted first."""
    from bubblecal.workflows.calibrate.figure_processes import FigureProcesses
    from bubblecal.workflows.figures import PHASE_FIGURES, agent_figures, figure_jobs

    here, plan = fake_result(tmp_path / "here", 5)
    there, _ = fake_result(tmp_path / "there", 5)
    drawers = FigureProcesses(2)
    try:
        drawers.start()
        drawers.submit(there, plan, figure_jobs(there, PHASE_FIGURES))
        got = agent_figures(there, plan, processes=drawers)
    finally:
        drawers.close()
    want = agent_figures(here, plan)
    assert [p.name for p in got] == [p.name for p in want] == ["fit.png", "forest.png", "diameter.png", "ka_kb.png",
                                                               "population.png"]
    assert all(a.read_bytes() == b.read_bytes() for a, b in zip(got, want, strict=True))


def test_a_failing_figure_is_raised_after_the_others_finished(tmp_path):
    """The error of one figure reaches the caller; the other figures are written."""
    from bubblecal.workflows.calibrate.figure_processes import FigureProcesses

    result, plan = fake_result(tmp_path / "run", 2)
    folder = tmp_path / "run" / "figures"
    folder.mkdir(parents=True)
    drawers = FigureProcesses(2)
    try:
        with pytest.raises(KeyError):
            drawers.draw(result, plan, [("forest_figure", folder / "forest.png", {}),
                                        ("no_such_figure", folder / "x.png", {})])
    finally:
        drawers.close()
    assert (folder / "forest.png").is_file()


def test_the_snapshot_loads_without_jax(tmp_path):
    """What crosses to a figure process unpickles in an interpreter that never imports JAX or NumPyro."""
    from bubblecal.workflows.calibrate.figure_processes import figure_snapshot

    result, plan = fake_result(tmp_path / "run", 2)
    path = tmp_path / "snapshot.pkl"
    path.write_bytes(figure_snapshot(result, plan))
    code = (f"import pickle, sys; r, p = pickle.loads(open({str(path)!r}, 'rb').read()); "
            "assert r.staged.phase1[0].sampler is None; "
            "print(sorted(m for m in ('jax', 'numpyro') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


@pytest.mark.parametrize(("cpus", "processes"), [(2, 0), (7, 0), (8, 2), (16, 5), (64, 6)])
def test_processes_follow_the_cores(cpus, processes):
    """None below 8 cores, a third of them above, at most one per figure."""
    from bubblecal.workflows.calibrate.figure_processes import figure_processes

    assert figure_processes(cpus) == processes


@pytest.mark.parametrize(("drawers", "modules"), [(0, ("pandas", "matplotlib.figure",
                                                       "matplotlib.backends.backend_agg")), (4, ("pandas",))])
def test_an_agent_process_imports_matplotlib_only_where_it_draws(monkeypatch, drawers, modules):
    """Where figure processes draw, the agent's own process needs pandas alone of the late libraries."""
    import importlib

    from bubblecal.workflows.calibrate import late_modules

    module = importlib.import_module("bubblecal.workflows.calibrate.figure_processes")

    monkeypatch.setattr(module, "figure_processes", lambda cpus=None: drawers)
    assert late_modules() == modules
