"""Shared test fixtures: the location of ``../shared/reference`` (skipped cleanly when absent)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]


def shared_reference_dir() -> Path | None:
    """Return ``../shared/reference`` beside the checkout (or $BUBBLECAL_SHARED/reference), or None."""
    env = os.environ.get("BUBBLECAL_SHARED")
    candidates = [Path(env) / "reference"] if env else []
    candidates.append(REPO_ROOT.parent / "shared" / "reference")
    for path in candidates:
        if path.is_dir():
            return path
    return None


def _load_script(relpath: str):
    """Import a repository script that is not part of the package (e.g. ``benchmarks/compare_calibrations.py``) as a
    module named after its file; its own folder goes on ``sys.path`` for its sibling imports."""
    import importlib.util
    import sys

    path = REPO_ROOT / relpath
    sys.path.insert(0, str(path.parent))
    spec = importlib.util.spec_from_file_location(path.stem, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[path.stem] = mod
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="session")
def load_script():
    """``load_script("benchmarks/...py")``: a repository script outside the package, imported as a module
    (the tests run with --import-mode=importlib, so they cannot import this file)."""
    return _load_script


@pytest.fixture
def shared_reference() -> Path:
    """Path of the shared reference data; the test is skipped when it is not present."""
    path = shared_reference_dir()
    if path is None:
        pytest.skip("../shared/reference not present")
    return path


@pytest.fixture(scope="session")
def tiny_compression_surrogate(tmp_path_factory) -> Path:
    """A small compression surrogate (2.1 um) trained on synthetic data through the CLI (~10 s, once per run)."""
    from typer.testing import CliRunner

    from bubblecal.workflows.cli import app

    folder = tmp_path_factory.mktemp("tiny_surrogate")
    runner = CliRunner()
    data = folder / "synthetic.csv"
    result = runner.invoke(app, ["surrogates", "synthetic", str(data), "--n-curves", "120", "--seed", "3"])
    assert result.exit_code == 0, result.output
    result = runner.invoke(app, ["surrogates", "train", str(data), "--setup", "compression", "--diameter", "2.1",
                                 "--out", str(folder / "out"), "--width", "16", "--depth", "2", "--max-epochs", "80"])
    assert result.exit_code == 0, result.output
    return folder / "out" / "compression_2.1um.npz"


@pytest.fixture(scope="session")
def synthetic_bundle(tmp_path_factory) -> Path:
    """A complete SYNTHETIC bundle (6 mechanical + 2 acoustic surrogates, closed-form laws, quick
    settings; ~10 s, built once per run): bubblecal.surrogates.write_synthetic_bundle."""
    from bubblecal.surrogates import write_synthetic_bundle

    return write_synthetic_bundle(tmp_path_factory.mktemp("synthetic_bundle"), seed=0, quick=True)


@pytest.fixture(autouse=True, scope="session")
def _private_compilation_cache(tmp_path_factory):
    """Commands run in-process (``calibrate``, ``evidence``) switch the persistent compilation cache on: in
    the tests it is a folder of the session, never the user's. The program store stays off in the session (a
    program stored by one test would not follow another test's monkeypatch); its own tests switch it on."""
    from bubblecal.workflows.compile_cache import CACHE_ENV, PROGRAMS_ENV

    saved = {k: os.environ.get(k) for k in (CACHE_ENV, PROGRAMS_ENV)}
    os.environ[CACHE_ENV] = str(tmp_path_factory.mktemp("jax_cache"))
    os.environ[PROGRAMS_ENV] = "off"
    yield
    for key, value in saved.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value
