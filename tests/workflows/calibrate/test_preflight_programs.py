"""The likelihood preflight runs on phase 1's own compiled programs: after it, phase 1 compiles no model program."""

from __future__ import annotations

import logging

import jax
import numpy as np

from bubblecal.inference.hierarchical import run_phase
from bubblecal.inference.tmcmc import TMCMC
from bubblecal.inference.tmcmc._programs import clear_program_cache
from bubblecal.workflows.calibrate import CalibrationConfig, make_plan, on_device, phase_tmcmc_options
from bubblecal.workflows.calibrate.run import _dataset_objects, _pad_curves


def _config(bundle, out):
    return CalibrationConfig(agents=("definity",), workflow="reduced", bundle=bundle, population=120, out=out,
                             phase2_samples=120, predictive_samples=100, num_mcmc_steps=2,
                             curves=("definity_compression_2.1um",), figures=False, summaries=False)


class _Compiles(logging.Handler):
    """Names of the programs built in this process: compiled, or read back from the session's persistent cache
    (an earlier test of the same structure leaves its programs there)."""

    def __init__(self):
        super().__init__(logging.DEBUG)
        self.names = []

    def emit(self, record):
        msg = record.getMessage()
        if msg.startswith("Finished XLA compilation of "):
            self.names.append(msg.split()[4])
        elif msg.startswith("Persistent compilation cache hit for '"):
            self.names.append(msg.split("'")[1])


def test_phase1_after_the_preflight_compiles_no_model_program(tmp_path, synthetic_bundle):
    clear_program_cache()
    config = _config(synthetic_bundle, tmp_path / "o")
    plan = make_plan(config)  # runs the preflight
    (dataset,) = _dataset_objects(plan.agents[0], _pad_curves(config))
    handler = _Compiles()
    logger = logging.getLogger("jax")
    logger.addHandler(handler)
    try:
        with jax.log_compiles(True), on_device(config.device):  # as run_agent runs the phases
            run_phase("phase1", dataset.model, dataset.args, dataset.kwargs, jax.random.PRNGKey(0),
                      phase_tmcmc_options(config)[0])
            probe = np.float32(np.random.default_rng().random())  # a program no test built before

            def capture_probe(x):
                return x * probe + 1

            jax.jit(capture_probe)(np.float32(2.0)).block_until_ready()
    finally:
        logger.removeHandler(handler)
    assert any("capture_probe" in n for n in handler.names), f"the log capture does not work: {handler.names}"
    # the evaluator was compiled by the preflight (the prior draws too); only the stage pieces and sites remain
    assert "jit(evaluate)" not in handler.names, handler.names


def test_prior_log_likelihood_is_the_models_log_likelihood_at_prior_draws(synthetic_bundle, tmp_path):
    from bubblecal.inference.tmcmc._flat_model import FlatModel

    config = _config(synthetic_bundle, tmp_path / "o")
    plan = make_plan(config)
    (dataset,) = _dataset_objects(plan.agents[0], _pad_curves(config))
    options = phase_tmcmc_options(config)[0]
    key = jax.random.PRNGKey(3)
    ll = TMCMC(dataset.model, **options).prior_log_likelihood(key, *dataset.args, **dataset.kwargs)
    assert ll.shape == (options["num_particles"],) and np.all(np.isfinite(ll))
    # the same draws through the model's plain (uncompiled) trace
    flat = FlatModel(dataset.model, dataset.args, dataset.kwargs)
    position = flat.prior_draws(key, options["num_particles"])
    reference = np.array([float(flat.log_likelihood(p)) for p in position[:8]])
    np.testing.assert_allclose(ll[:8], reference, rtol=1e-5)
