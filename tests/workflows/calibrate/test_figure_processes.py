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
    """What crosses to a figure process unpickles in an interpreter that never imports JAX or NumPyro: device
    arrays become NumPy arrays, the samplers (here a stand-in holding a device array) and phase 1 are left out."""
    import dataclasses

    import jax.numpy as jnp

    from bubblecal.workflows.calibrate.figure_processes import figure_snapshot

    result, plan = fake_result(tmp_path / "run", 2)
    staged = result.staged
    staged.phase3[0] = dataclasses.replace(staged.phase3[0], sampler=jnp.zeros(3))
    result.population_predictive = {k: jnp.asarray(v) for k, v in result.population_predictive.items()}
    path = tmp_path / "snapshot.pkl"
    path.write_bytes(figure_snapshot(result, plan))
    code = (f"import pickle, sys; r, p = pickle.loads(open({str(path)!r}, 'rb').read()); "
            "assert r.staged.phase1 == [] and all(x.sampler is None for x in r.staged.phase3); "
            "assert all(type(v).__module__ == 'numpy' for v in r.population_predictive.values()); "
            "print(sorted(m for m in ('jax', 'jaxlib', 'numpyro') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


@pytest.mark.parametrize(("device", "drawers", "modules"), [
    ("gpu", 0, ("pandas", "matplotlib.figure", "matplotlib.backends.backend_agg")), ("gpu", 4, ("pandas",)),
    ("cpu", 4, ("pandas", "matplotlib.figure", "matplotlib.backends.backend_agg"))])
def test_an_agent_process_imports_matplotlib_only_where_it_draws(monkeypatch, device, drawers, modules):
    """Where figure processes draw (GPU runs with spare cores), the agent's own process needs pandas alone."""
    from bubblecal.workflows.calibrate import device as device_module
    from bubblecal.workflows.calibrate import late_modules

    monkeypatch.setattr(device_module, "helper_processes", lambda role, cpus=None: drawers)
    assert late_modules(device) == modules


@pytest.mark.parametrize(("device", "cpus", "processes"), [("gpu", 16, 5), ("gpu", 4, 0), ("cpu", 16, 0)])
def test_figure_processes_only_on_gpu_runs_with_spare_cores(device, cpus, processes):
    from bubblecal.workflows.calibrate import drawing_processes

    assert drawing_processes(device, cpus) == processes


def test_a_run_draws_the_same_figures_in_figure_processes(tmp_path, synthetic_bundle, monkeypatch):
    """A staged run whose figures go to two figure processes (the GPU path, forced here): the same PNG files as a
    run that draws them itself, the acoustic band included, and no process left behind. The second run reads the
    first one's phases back (a reused phase holds the draws of the run that wrote it)."""
    import multiprocessing
    import shutil

    from bubblecal.workflows.calibrate import CalibrationConfig, FigureProcesses, make_plan, run_calibration
    from bubblecal.workflows.calibrate import run as run_module

    kw = dict(agents=("definity",), workflow="reduced-acoustic", bundle=synthetic_bundle, population=120,
              phase2_samples=120, predictive_samples=200, num_mcmc_steps=3, curves=("definity_compression_2.1um",))
    (here,) = run_calibration(make_plan(CalibrationConfig(out=tmp_path / "here", **kw)))
    shutil.copytree(tmp_path / "here", tmp_path / "there", ignore=shutil.ignore_patterns("figures", "*.csv", "*.md"))
    monkeypatch.setattr(run_module, "_figure_drawers", lambda config: FigureProcesses(2))
    (there,) = run_calibration(make_plan(CalibrationConfig(out=tmp_path / "there", **kw)))
    assert there.reused and not (set(here.reused) & set(there.reused))
    assert [p.name for p in there.figures] == [p.name for p in here.figures]
    assert "acoustic.png" in [p.name for p in here.figures]
    assert all(a.read_bytes() == b.read_bytes() for a, b in zip(here.figures, there.figures, strict=True))
    assert multiprocessing.active_children() == []
