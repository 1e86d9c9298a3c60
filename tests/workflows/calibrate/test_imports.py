"""The import turn: a library imported on a background thread is never seen half-initialised by another thread."""

from __future__ import annotations

import contextlib
import sys
import threading
import types

import pytest

#: A package whose body waits (after its first lines) until the test lets it go, then uses its submodule; the
#: submodule imports the package first. Two threads importing the package and the submodule at once wait on each
#: other's module locks, which CPython breaks by handing the package the submodule half-initialised.
_PACKAGE = {
    "__init__.py": "import turn_probe_signal as s\ns.started.set()\ns.go.wait(30)\nfrom turn_probe import sub\n"
                   "VALUE = 7 * sub.STEP\n",
    "sub.py": "import turn_probe\n\nSTEP = 2\n",
}


@pytest.fixture
def probe(tmp_path, monkeypatch):
    """The package ``turn_probe`` on the path, its signals, and no trace of it in ``sys.modules`` afterwards."""
    folder = tmp_path / "turn_probe"
    folder.mkdir()
    for name, text in _PACKAGE.items():
        (folder / name).write_text(text)
    monkeypatch.syspath_prepend(str(tmp_path))
    signal = types.SimpleNamespace(started=threading.Event(), go=threading.Event())
    monkeypatch.setitem(sys.modules, "turn_probe_signal", signal)
    yield signal
    signal.go.set()
    for name in ("turn_probe", "turn_probe.sub"):
        sys.modules.pop(name, None)


def _on_a_thread(import_module):
    """Start ``import_module()`` on a thread; returns (thread, outcome dict with 'module' or 'error')."""
    outcome: dict = {}

    def body():
        try:
            outcome["module"] = import_module()
        except Exception as exc:  # noqa: BLE001 - the outcome is inspected by the test
            outcome["error"] = exc

    thread = threading.Thread(target=body)
    thread.start()
    return thread, outcome


def test_a_thread_that_needs_a_package_being_preloaded_waits_for_it(probe):
    """preload_soon imports the package; another thread's library('turn_probe.sub') waits for the turn, then finds
    both complete."""
    from bubblecal.workflows.calibrate import library, preload_soon

    loader = preload_soon(["turn_probe"])
    assert probe.started.wait(30)
    thread, outcome = _on_a_thread(lambda: library("turn_probe.sub"))
    thread.join(0.3)
    assert thread.is_alive() and not outcome  # waiting for the turn, not importing beside the package
    probe.go.set()
    thread.join(30)
    loader.join(30)
    assert "error" not in outcome, outcome
    assert outcome["module"].STEP == 2
    assert sys.modules["turn_probe"].VALUE == 14


def test_without_the_turn_one_of_two_overlapping_imports_fails(probe):
    """The hazard the turn removes (CPython 3.11): the package imported on one thread while another imports its
    submodule; the two wait on each other's module locks, and CPython hands the package the submodule before its
    body ran (as matplotlib was handed half of itself)."""
    import importlib

    loader, package = _on_a_thread(lambda: importlib.import_module("turn_probe"))
    assert probe.started.wait(30)
    thread, submodule = _on_a_thread(lambda: importlib.import_module("turn_probe.sub"))
    thread.join(0.3)  # the submodule's thread now waits for the package's lock, holding its own
    probe.go.set()
    thread.join(30)
    loader.join(30)
    assert isinstance(package.get("error"), AttributeError), package
    assert "partially initialized module 'turn_probe.sub' has no attribute 'STEP'" in str(package["error"])


def test_a_complete_library_is_returned_without_the_turn():
    """library() of a complete module costs no lock: it returns while another thread holds the turn."""
    from bubblecal.workflows.calibrate import import_turn, library

    held, release = threading.Event(), threading.Event()

    def hold():
        with import_turn():
            held.set()
            release.wait(30)

    holder = threading.Thread(target=hold)
    holder.start()
    try:
        assert held.wait(30)
        thread, outcome = _on_a_thread(lambda: library("json"))
        thread.join(5)
        assert outcome.get("module") is sys.modules["json"]
    finally:
        release.set()
        holder.join(30)


def test_phase_files_are_written_and_read_in_the_turn(tmp_path, monkeypatch):
    """The writer thread's writes and every read of a phase file hold the turn (their first calls import ArviZ,
    xarray, h5netcdf and dask)."""
    import bubblecal.workflows.calibrate.phase_files as phase_files
    import bubblecal.workflows.calibrate.writer as writer
    from bubblecal.workflows.calibrate import import_turn

    held = []
    monkeypatch.setattr(phase_files, "write_phase", lambda *a, **k: held.append(("write", import_turn()._is_owned())))
    writer._write(tmp_path / "p.nc", None, None, {}, None, None, None)

    def opened(*args, **kwargs):
        held.append(("read", import_turn()._is_owned()))
        raise OSError("no such file")

    import xarray

    monkeypatch.setattr(xarray, "open_dataset", opened)
    for read in (phase_files.read_phase, phase_files.phase_format, phase_files.read_pointwise):
        with contextlib.suppress(phase_files.PhaseFileError):
            read(tmp_path / "missing.nc")
    assert held == [("write", True)] + [("read", True)] * 3


def test_a_workers_gpu_start_imports_jax_in_the_turn(monkeypatch):
    """The worker's GPU-start thread imports JAX through library() (in the turn), then asks for the GPU."""
    import bubblecal.workflows.calibrate.agent_worker as agent_worker

    calls = []

    class FakeJax:
        @staticmethod
        def devices(kind):
            calls.append(("devices", kind))

    monkeypatch.setattr(agent_worker, "library", lambda name: calls.append(("library", name)) or FakeJax)
    agent_worker._start_gpu()
    assert calls == [("library", "jax"), ("devices", "gpu")]
