"""The persistent compilation cache of the command line: folder choice, unusable folders, damaged and foreign
entries, two processes sharing one folder, and `calibrate --no-cache` / a broken cache folder end to end."""

from __future__ import annotations

import os
import subprocess
import sys
import time
import zlib
from pathlib import Path

import pytest

from bubblecal.workflows.compile_cache import CACHE_ENV, default_cache_dir, enable_compilation_cache

# a process that switches the cache on and runs two small programs (their values are printed)
PROGRAM = """
import sys
from pathlib import Path
import jax, jax.numpy as jnp
from bubblecal.workflows.compile_cache import enable_compilation_cache
print("FOLDER", enable_compilation_cache(Path(sys.argv[1]), say=lambda m: print("SAY", m)))
f = jax.jit(lambda x: jnp.sin(x) * 2.0 + x.sum())
g = jax.jit(lambda x: jnp.cumsum(x) ** 2)
print("RESULT", float(f(jnp.arange(5.0)).sum()), float(g(jnp.arange(5.0)).sum()))
"""


def _expected() -> tuple[float, float]:
    import numpy as np

    x = np.arange(5.0)
    return float(np.sum(np.sin(x) * 2.0 + x.sum())), float(np.sum(np.cumsum(x) ** 2))


def _result_ok(out: str) -> bool:
    (line,) = [line for line in out.splitlines() if line.startswith("RESULT")]
    return all(abs(float(v) - e) <= 1e-5 * abs(e) for v, e in zip(line.split()[1:], _expected(), strict=True))


def _run(folder: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "JAX_LOG_COMPILES": "1", "JAX_PLATFORMS": "cpu"}
    return subprocess.Popen([sys.executable, "-c", PROGRAM, str(folder)], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _finish(proc) -> tuple[str, str]:
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err[-2000:]
    return out, err


def _hits(err: str) -> int:
    return err.count("Persistent compilation cache hit")


def _entries(folder: Path) -> list[Path]:
    return sorted(folder.glob("*-cache"))


def _age(paths, seconds=120):
    t = time.time() - seconds
    for p in paths:
        os.utime(p, (t, t))


def test_the_folder_is_the_users_cache_folder_or_the_environment_variable(tmp_path, monkeypatch):
    monkeypatch.delenv(CACHE_ENV, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert default_cache_dir() == tmp_path / "xdg" / "bubblecal" / "jax"
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "mine"))
    assert default_cache_dir() == tmp_path / "mine"


@pytest.mark.parametrize("case", ["file", "parent is a file"])
def test_an_unusable_folder_gives_one_line_naming_it_and_no_cache(tmp_path, case):
    import jax

    before = jax.config.jax_compilation_cache_dir
    (tmp_path / "f").write_text("not a folder")
    folder = tmp_path / "f" if case == "file" else tmp_path / "f" / "jax"
    said = []
    assert enable_compilation_cache(folder, say=said.append) is None
    assert len(said) == 1 and "\n" not in said[0] and str(folder) in said[0] and "running without it" in said[0]
    assert ("is a file" if case == "file" else "cannot be written") in said[0]
    assert jax.config.jax_compilation_cache_dir == before  # JAX's configuration untouched


def test_an_unwritable_folder_is_named(tmp_path, monkeypatch):
    import tempfile

    def refuse(*a, **k):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(tempfile, "NamedTemporaryFile", refuse)
    said = []
    assert enable_compilation_cache(tmp_path / "c", say=said.append) is None
    assert "cannot be written (Permission denied)" in said[0] and str(tmp_path / "c") in said[0]


def test_warm_run_reads_every_program_back_and_damaged_entries_are_recompiled(tmp_path):
    folder = tmp_path / "cache"
    out, err = _finish(_run(folder))
    assert _result_ok(out) and _hits(err) == 0 and f"FOLDER {folder}" in out
    entries = _entries(folder)
    assert len(entries) >= 2
    out, err = _finish(_run(folder))
    assert _result_ok(out) and _hits(err) == len(entries) and "SAY" not in out
    # garbage bytes in every entry: one warning line naming the folder, the same values, the entries replaced
    for p in entries:
        p.write_bytes(os.urandom(700))
    _age(entries)
    out, err = _finish(_run(folder))
    said = [line for line in out.splitlines() if line.startswith("SAY")]
    assert _result_ok(out) and len(said) == 1 and str(folder) in said[0] and "could not be read" in said[0]
    assert f"removed {len(entries)} damaged entries" in said[0]
    out, err = _finish(_run(folder))
    assert _result_ok(out) and _hits(err) == len(entries) and "SAY" not in out


def test_a_foreign_entry_is_recompiled_with_one_warning(tmp_path):
    folder = tmp_path / "cache"
    _finish(_run(folder))
    for p in _entries(folder):  # well-formed compression around bytes that are no executable
        p.write_bytes(zlib.compress(b"\0\0\0\1" + os.urandom(2000)))
    out, err = _finish(_run(folder))
    said = [line for line in out.splitlines() if line.startswith("SAY")]
    assert _result_ok(out) and len(said) == 1 and "could not be read" in said[0] and str(folder) in said[0]


@pytest.mark.slow  # four processes
def test_two_processes_share_one_folder(tmp_path):
    folder = tmp_path / "cache"
    procs = [_run(folder) for _ in range(3)]  # started together: they compile and write the same entries
    for proc in procs:
        out, err = _finish(proc)
        assert _result_ok(out) and "SAY" not in out and "Error" not in err
    out, err = _finish(_run(folder))
    assert _result_ok(out) and _hits(err) == len(_entries(folder)) > 0 and "SAY" not in out


def test_calibrate_with_an_unusable_cache_warns_once_and_keeps_its_phases(tmp_path, monkeypatch, synthetic_bundle):
    from typer.testing import CliRunner

    from bubblecal.workflows.cli import app

    args = ["calibrate", "--agent", "definity", "--workflow", "reduced", "--curve", "definity_compression_2.1um",
            "--bundle", str(synthetic_bundle), "--population", "120", "--phase2-samples", "120", "--mcmc-steps", "2",
            "--no-figures", "--out", str(tmp_path / "out")]
    blocker = tmp_path / "cache-is-a-file"
    blocker.write_text("x")
    monkeypatch.setenv(CACHE_ENV, str(blocker))
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    text = " ".join(result.output.split())
    assert text.count(f"compilation cache {blocker}: it is a file, not a folder; running without it") == 1
    phases = sorted(p.name for p in (tmp_path / "out" / "definity" / "reduced").glob("phase*"))
    assert len(phases) == 3  # phase 1, 2 and 3 of the one curve
    absent = tmp_path / "never-created"
    monkeypatch.setenv(CACHE_ENV, str(absent))
    result = CliRunner().invoke(app, [*args, "--no-cache"])
    assert result.exit_code == 0, result.output
    assert not absent.exists() and "compilation cache" not in result.output
    assert sorted(p.name for p in (tmp_path / "out" / "definity" / "reduced").glob("phase*")) == phases


def test_gpu_autotuning_is_skipped_unless_the_user_set_a_level(monkeypatch):
    from bubblecal.workflows.compile_cache import GPU_AUTOTUNE_FLAG, skip_gpu_autotuning

    monkeypatch.delenv("XLA_FLAGS", raising=False)
    assert skip_gpu_autotuning() and os.environ["XLA_FLAGS"] == GPU_AUTOTUNE_FLAG
    assert not skip_gpu_autotuning() and os.environ["XLA_FLAGS"] == GPU_AUTOTUNE_FLAG  # added once
    monkeypatch.setenv("XLA_FLAGS", "--xla_dump_to=/tmp/d")
    assert skip_gpu_autotuning() and os.environ["XLA_FLAGS"] == f"--xla_dump_to=/tmp/d {GPU_AUTOTUNE_FLAG}"
    monkeypatch.setenv("XLA_FLAGS", "--xla_gpu_autotune_level=4")
    assert not skip_gpu_autotuning() and os.environ["XLA_FLAGS"] == "--xla_gpu_autotune_level=4"  # the user's


def test_the_commands_switch_the_program_store_on_beside_the_cache_unless_told_not_to(tmp_path, monkeypatch):
    import warnings

    import jax

    from bubblecal.inference.tmcmc import disable_program_store, program_store_folder
    from bubblecal.workflows import compile_cache
    from bubblecal.workflows.compile_cache import PROGRAMS_ENV, PROGRAMS_SUBFOLDER

    # this process's JAX configuration, warning hook and cache state stay as they were
    monkeypatch.setattr(jax.config, "update", lambda *a, **k: None)
    monkeypatch.setattr(warnings, "showwarning", warnings.showwarning)
    monkeypatch.setattr(compile_cache, "_state", dict(compile_cache._state))
    try:
        monkeypatch.setenv(PROGRAMS_ENV, "off")
        enable_compilation_cache(tmp_path / "a", say=lambda m: None)
        assert program_store_folder() is None
        monkeypatch.delenv(PROGRAMS_ENV)
        enable_compilation_cache(tmp_path / "b", say=lambda m: None)
        assert program_store_folder() == tmp_path / "b" / PROGRAMS_SUBFOLDER
        said = []
        (tmp_path / "c").mkdir()
        (tmp_path / "c" / PROGRAMS_SUBFOLDER).write_text("a file, not a folder")
        disable_program_store()
        assert enable_compilation_cache(tmp_path / "c", say=said.append) == tmp_path / "c"
        assert program_store_folder() is None and "cannot be written" in said[0]
    finally:
        disable_program_store()
