"""The program store: stable keys by value, executables read back by another process, and every way it must miss."""

from __future__ import annotations

import dataclasses
import functools
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from bubblecal.inference.tmcmc import executables
from bubblecal.inference.tmcmc._stable import Unkeyable, stable_digest
from bubblecal.inference.tmcmc.executables import STORE_SUFFIX, Program


def _trusted(fn):
    """``fn`` as if bubblecal defined it (the store trusts only code whose version or source is in its key)."""
    fn.__module__ = "bubblecal._test_functions"
    return fn


def _make_scaled(factor):
    def scaled(x):
        return x * factor

    return _trusted(scaled)


class _Pair(NamedTuple):
    a: int
    b: int


class _OtherPair(NamedTuple):
    a: int
    b: int


@dataclasses.dataclass(frozen=True)
class _Settings:
    width: int
    bounds: tuple


_Pair.__module__ = _OtherPair.__module__ = _Settings.__module__ = "bubblecal._test_functions"


def test_equal_values_give_equal_digests_and_every_difference_changes_it():
    x = np.arange(6, dtype=np.float32)
    y = x.copy()
    y[3] = np.nextafter(y[3], np.float32(10))  # one bit of one element
    assert stable_digest({"a": x, "b": (1, "s")}) == stable_digest({"b": (1, "s"), "a": x.copy()})  # key order
    assert stable_digest(x) != stable_digest(y)
    assert stable_digest(x) != stable_digest(x.astype(np.float64))
    assert stable_digest(x) != stable_digest(x.reshape(2, 3))
    assert stable_digest(1) != stable_digest(1.0) != stable_digest(True)
    assert stable_digest(_Pair(1, 2)) != stable_digest(_OtherPair(1, 2)) != stable_digest((1, 2))
    assert stable_digest(_Settings(3, (0.0, 1.0))) != stable_digest(_Settings(3, (0.0, 1.5)))
    assert stable_digest(jax.ShapeDtypeStruct((3,), jnp.float32)) != stable_digest(
        jax.ShapeDtypeStruct((3,), jnp.float32, weak_type=True))


def test_functions_are_keyed_by_code_closure_defaults_and_partial_arguments():
    assert stable_digest(_make_scaled(2.0)) == stable_digest(_make_scaled(2.0))
    assert stable_digest(_make_scaled(2.0)) != stable_digest(_make_scaled(3.0))  # the closure cell
    assert stable_digest(functools.partial(_make_scaled(2.0), 1)) != stable_digest(
        functools.partial(_make_scaled(2.0), 2))

    def power(x, p=2):
        return x**p

    def power3(x, p=3):
        return x**p

    first = _trusted(power)
    other_default = _trusted(power3)
    other_default.__qualname__ = first.__qualname__
    assert stable_digest(first) != stable_digest(other_default)
    lambdas = [_trusted(lambda v: v + 1), _trusted(lambda v: v - 1)]  # one qualified name, two bodies
    assert stable_digest(lambdas[0]) != stable_digest(lambdas[1])


def test_pytree_definitions_are_keyed_by_node_types_and_auxiliary_data():
    import numpyro.distributions as dist
    from numpyro.distributions.transforms import biject_to

    a, b = (biject_to(dist.constraints.interval(0.0, hi)) for hi in (2.0, 3.0))
    assert stable_digest(a) == stable_digest(biject_to(dist.constraints.interval(0.0, 2.0)))
    assert stable_digest(a) != stable_digest(b)
    assert stable_digest(jax.tree_util.tree_structure({"a": 1})) != stable_digest(
        jax.tree_util.tree_structure({"b": 1}))
    assert stable_digest(jax.tree_util.tree_structure(None)) != stable_digest(jax.tree_util.tree_structure(1))


def test_values_without_an_exact_key_are_refused():
    def local(x):
        return x

    with pytest.raises(Unkeyable, match="module"):
        stable_digest(local)  # this test module's code is no part of the store's key
    with pytest.raises(Unkeyable, match="object"):
        stable_digest({"a": object()})
    cycle: list = []
    cycle.append(cycle)
    with pytest.raises(Unkeyable, match="cycle"):
        stable_digest(cycle)
    with pytest.raises(Unkeyable, match="traced"):
        jax.eval_shape(lambda v: stable_digest(v) and v, jnp.ones(2))


def test_the_environment_digest_follows_xla_flags_and_jax_configuration(monkeypatch):
    base = executables.environment_digest()
    monkeypatch.setenv("XLA_FLAGS", os.environ.get("XLA_FLAGS", "") + " --xla_cpu_enable_fast_math=false")
    assert executables.environment_digest() != base
    monkeypatch.undo()
    assert executables.environment_digest() == base
    with jax.default_matmul_precision("highest"):
        assert executables.environment_digest() != base


def test_a_program_runs_its_kept_executable_and_falls_back_to_jit_for_other_calls(tmp_path, monkeypatch):
    monkeypatch.setitem(executables._state, "folder", tmp_path)
    program = Program(_make_scaled(2.0), identity=_make_scaled(2.0))
    x = jnp.arange(3.0)
    assert not program.ready(x)
    program.keep((x,), program.lower(x).compile())
    assert program.ready(x) and len(list(tmp_path.glob(f"*{STORE_SUFFIX}"))) == 1
    np.testing.assert_array_equal(program(x), 2 * x)
    np.testing.assert_array_equal(program(jnp.arange(4.0)), 2 * jnp.arange(4.0))  # another shape: jit
    assert jax.jit(lambda v: program(v) + 1)(x).shape == (3,)  # traced: jit
    fresh = Program(_make_scaled(2.0), identity=_make_scaled(2.0))  # another process's view: read from disk
    assert fresh.ready(x) and fresh.executables() == 1
    np.testing.assert_array_equal(fresh(x), 2 * x)
    assert not Program(_make_scaled(3.0), identity=_make_scaled(3.0)).ready(x)  # another closure: a miss


def test_an_executable_that_fails_to_dispatch_is_dropped_and_jit_answers(tmp_path, monkeypatch):
    monkeypatch.setitem(executables._state, "folder", tmp_path)
    program = Program(_make_scaled(2.0), identity=_make_scaled(2.0))
    x = jnp.arange(3.0)
    program.keep((x,), program.lower(x).compile())

    def broken(*args):
        raise jax.errors.JaxRuntimeError("INTERNAL: Error dispatching computation: Function fusion.1 not found")

    key = program.call_key((x,))
    program._entries[key] = (broken, program._entries[key][1])
    np.testing.assert_array_equal(program(x), 2 * x)
    assert key not in program._entries and not list(tmp_path.glob(f"*{STORE_SUFFIX}"))


def test_a_damaged_entry_is_a_miss(tmp_path, monkeypatch):
    monkeypatch.setitem(executables._state, "folder", tmp_path)
    program = Program(_make_scaled(2.0), identity=_make_scaled(2.0))
    x = jnp.arange(3.0)
    program.keep((x,), program.lower(x).compile())
    (entry,) = tmp_path.glob(f"*{STORE_SUFFIX}")
    blob = entry.read_bytes()
    for damaged in (blob[: len(blob) // 2], blob[:-1] + bytes([blob[-1] ^ 1]), b"garbage"):
        entry.write_bytes(damaged)
        assert not Program(_make_scaled(2.0), identity=_make_scaled(2.0)).ready(x)


_RUN = textwrap.dedent("""
    import hashlib, json, sys
    import jax, numpy as np
    from bubblecal.inference import TMCMC, RunSpec, compile_ahead
    from bubblecal.inference.tmcmc import enable_program_store, store_counts
    from bubblecal.models import FrequencyTable, acoustic_model
    from bubblecal.priors import load_priors

    if sys.argv[1] != "off":
        enable_program_store(sys.argv[1])
    if len(sys.argv) > 2:  # JAX's persistent compilation cache, for every program however quick
        jax.config.update("jax_compilation_cache_dir", sys.argv[2])
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
        jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)
    d = np.linspace(1.5, 4.0, 9)
    table = FrequencyTable(d, np.tile([1.0, 1e-3, 0.0], (9, 1)))
    freq = np.sqrt(1.0 + 1e-3 * 12000.0) * (1 + 0.05 * np.sin(np.arange(9)))
    args = (d, freq, table, load_priors("definity_reduced_acoustic"))
    key = jax.random.PRNGKey(3)
    sampler = TMCMC(acoustic_model, num_particles=300)
    compile_ahead([RunSpec(sampler, key, args)])
    samples = sampler.run(key, *args).get_samples()
    print(json.dumps({"counts": store_counts(), "ka": hashlib.sha256(np.asarray(samples["ka"]).tobytes()).hexdigest()}))
""")


def _run(script: Path, folder, *more) -> dict:
    proc = subprocess.run([sys.executable, str(script), str(folder), *map(str, more)], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_another_process_reads_the_programs_back_and_draws_the_same(tmp_path):
    """Cross-process, with JAX's compilation cache on as in the commands: a first run stores what XLA compiled; a
    run that finds every program in JAX's cache stores none (such an XLA:CPU executable serialises without its
    machine code); a third process reads every program back, compiles none and draws bit-identical samples (the
    stage's Cholesky included: LAPACK kernels of a program that process never lowered)."""
    script = tmp_path / "run.py"
    script.write_text(_RUN)
    cache, store = tmp_path / "jax", tmp_path / "store"
    first = _run(script, store, cache)
    assert first["counts"]["saved"] == first["counts"]["compiled"] > 0 and first["counts"]["unkeyed"] == 0
    second = _run(script, tmp_path / "other", cache)
    assert second["counts"]["compiled"] == first["counts"]["compiled"] and second["counts"]["saved"] == 0
    assert not list((tmp_path / "other").glob(f"*{STORE_SUFFIX}"))
    third = _run(script, store, cache)
    assert third["counts"]["loaded"] == first["counts"]["saved"] and third["counts"]["compiled"] == 0
    assert third["ka"] == second["ka"] == first["ka"]


def test_entries_of_other_environments_are_pruned_after_a_day_unused(tmp_path, monkeypatch):
    monkeypatch.setitem(executables._state, "folder", tmp_path)
    monkeypatch.setitem(executables._state, "pruned", None)
    prefix = executables.environment_digest()[:16]
    old = os.path.getmtime(tmp_path) - 2 * executables.PRUNE_AFTER_S
    names = {"ours_old": f"{prefix}-a{STORE_SUFFIX}", "theirs_old": f"{'0' * 16}-b{STORE_SUFFIX}",
             "theirs_new": f"{'0' * 16}-c{STORE_SUFFIX}", "temp_old": ".tmp-x"}
    for label, name in names.items():
        (tmp_path / name).write_bytes(b"x")
        if label.endswith("old"):
            os.utime(tmp_path / name, (old, old))
    program = Program(_make_scaled(2.0), identity=_make_scaled(2.0))
    assert not program.ready(jnp.arange(3.0))  # the first use of the store in a process prunes it
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([names["ours_old"], names["theirs_new"]])
