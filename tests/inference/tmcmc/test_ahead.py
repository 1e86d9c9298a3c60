"""Compiling TMCMC runs ahead (``compile_ahead``): the runs then compile nothing, and draw what they drew without it."""

from __future__ import annotations

import logging

import jax
import numpy as np
import numpyro
import numpyro.distributions as dist
import pytest

from bubblecal.inference.tmcmc import MAX_COMPILE_WORKERS, TMCMC, RunSpec, compile_ahead, compile_workers, hmc_move
from bubblecal.inference.tmcmc import _programs as tm

# the programs of a run (prior draws, evaluator, stage pieces, exports); eager one-operation programs
# (key splits, isfinite) are not run programs
RUN_PROGRAMS = ("evaluate", "sites", "pointwise", "untemper", "begin", "propose", "accept", "end", "<lambda>")


def line_model(x, y=None):
    a = numpyro.sample("a", dist.Normal(0.0, 3.0))
    b = numpyro.sample("b", dist.Uniform(-5.0, 5.0))
    numpyro.deterministic("slope_sq", b * b)
    numpyro.sample("y", dist.Normal(a + b * x, 0.3), obs=y)


def tempered_model(x, y=None):
    line_model(x, y)
    numpyro.factor("pop", dist.Normal(0.0, 2.0).log_prob(numpyro.sample("c", dist.Normal(0.0, 1.0))))


def _data(n=9):
    x = np.linspace(-1.0, 1.0, n)
    return x, (0.5 + 1.5 * x + 0.3 * np.random.default_rng(0).normal(size=n)).astype(np.float32)


class _Compiles(logging.Handler):
    """Names of the programs XLA compiled while attached."""

    def __init__(self):
        super().__init__(logging.DEBUG)
        self.names: list[str] = []

    def emit(self, record):
        msg = record.getMessage()
        if msg.startswith("Finished XLA compilation of jit("):
            self.names.append(msg.split("jit(", 1)[1].split(")", 1)[0])


@pytest.fixture()
def compiles():
    handler = _Compiles()
    logger = logging.getLogger("jax")
    logger.addHandler(handler)
    with jax.log_compiles(True):
        yield handler
    logger.removeHandler(handler)


def _run(sampler, x, y, **kwargs):
    sampler.run(jax.random.PRNGKey(3), x, y=y, **kwargs)
    parts = sampler.inference_parts()
    return sampler.get_samples(), sampler.log_evidence, parts["log_likelihood"]


def test_a_run_compiled_ahead_compiles_nothing_and_draws_the_same(compiles):
    x, y = _data()
    tm.clear_program_cache()
    plain = _run(TMCMC(line_model, num_particles=600), x, y)
    tm.clear_program_cache()
    sampler = TMCMC(line_model, num_particles=600)
    n = compile_ahead([RunSpec(sampler, jax.random.PRNGKey(0), (x,), {"y": y})], workers=2)
    assert n >= 8  # draws, evaluate, initial state, the four stage pieces, sites, pointwise
    compiles.names.clear()
    ahead = _run(sampler, x, y)
    assert not [p for p in compiles.names if p in RUN_PROGRAMS], compiles.names
    for k in plain[0]:
        np.testing.assert_array_equal(ahead[0][k], plain[0][k])
    assert ahead[1] == plain[1]
    np.testing.assert_array_equal(ahead[2]["y"], plain[2]["y"])


def test_a_tempered_run_from_given_draws_compiled_ahead_compiles_nothing(compiles):
    x, y = _data()
    tm.clear_program_cache()
    rng = np.random.default_rng(1)
    init = {"a": rng.normal(0.5, 0.1, 500).astype(np.float32), "b": rng.uniform(1.0, 2.0, 500).astype(np.float32),
            "c": rng.normal(0.0, 1.0, 500).astype(np.float32)}
    sampler = TMCMC(tempered_model, num_particles=500, tempered=("pop",))
    compile_ahead([RunSpec(sampler, jax.random.PRNGKey(0), (x,), {"y": y}, init)])
    compiles.names.clear()
    sampler.run(jax.random.PRNGKey(3), x, y=y, init_samples=init, init_log_evidence=-2.0)
    sampler.get_samples()
    sampler.inference_parts()
    assert not [p for p in compiles.names if p in RUN_PROGRAMS], compiles.names


def test_runs_of_one_structure_are_compiled_once_and_other_runs_are_left_to_compile_as_they_run():
    x, y = _data()
    tm.clear_program_cache()
    specs = [RunSpec(TMCMC(line_model, num_particles=400), jax.random.PRNGKey(k), (x,), {"y": y + k})
             for k in range(3)]
    lowered = compile_ahead(specs, workers=1)  # one structure: its programs lowered once for the three runs
    assert lowered > 0 and compile_ahead(specs, workers=1) == 0  # held now
    tm.clear_program_cache()
    assert compile_ahead(specs[:1], workers=1) == lowered
    assert compile_ahead([RunSpec(TMCMC(line_model, num_particles=400, compiled=True), jax.random.PRNGKey(0),
                                  (x,), {"y": y})]) == 0
    assert compile_ahead([RunSpec(TMCMC(line_model, num_particles=400, move=hmc_move()), jax.random.PRNGKey(0),
                                  (x,), {"y": y})]) == 0
    assert 1 <= compile_workers() <= MAX_COMPILE_WORKERS


def test_a_model_that_cannot_run_fails_ahead_as_it_would_in_run():
    def discrete():
        numpyro.sample("k", dist.Poisson(2.0))

    with pytest.raises(ValueError, match="discrete"):
        compile_ahead([RunSpec(TMCMC(discrete, num_particles=200), jax.random.PRNGKey(0))])
