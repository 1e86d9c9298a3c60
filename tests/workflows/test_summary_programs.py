"""Summaries: a curve's predictions at the data, on the grid and at the MAP come from one compiled program, equal
(to float tolerance) to evaluating them one by one, and a second curve of the same network compiles nothing."""

from __future__ import annotations

import logging

import jax
import numpy as np

from bubblecal.models import mechanical_prediction
from bubblecal.priors import load_priors
from bubblecal.surrogates import default_bundle_path, load_bundle
from bubblecal.workflows.summary import _curve_predictions, _prediction_arguments


class _Compiles(logging.Handler):
    def __init__(self):
        super().__init__(logging.WARNING)
        self.names = []

    def emit(self, record):
        if record.getMessage().startswith("Finished XLA compilation of "):
            self.names.append(record.getMessage().split()[4])


def _draws(spec, n, seed):
    rng = np.random.default_rng(seed)
    out = {k: rng.uniform(*p.prior.as_tuple(), size=n).astype(np.float32) for k, p in spec.parameters.items()}
    out[spec.mechanical_noise_name] = rng.uniform(0.03, 0.08, size=n).astype(np.float32)
    return out


def _predictions(predict, thin, samples, imap, surrogate, spec, x, grid, y_scale):
    arguments = _prediction_arguments(thin, samples, imap, surrogate, spec, x, grid, y_scale)
    return _curve_predictions(predict, arguments, spec, len(x), len(grid), imap)


def test_one_program_per_network_and_the_values_of_separate_calls():
    spec = load_priors("definity_reduced_acoustic")
    bundle = load_bundle(default_bundle_path(must_exist=True))
    sur_a, sur_b = bundle.get("compression", 2.1), bundle.get("compression", 2.9)  # one network shape
    predict = jax.jit(lambda v, s, x, ys: mechanical_prediction(v, s, spec, x, y_scale=ys))
    samples = _draws(spec, 300, 0)
    thin = {k: v[:200] for k, v in samples.items()}
    x, grid, y_scale = np.linspace(0.05, 1.2, 24), np.linspace(0.0, 1.3, 80), 900.0
    mu, sd, gmu, gsd, map_curve = _predictions(predict, thin, samples, 7, sur_a, spec, x, grid, y_scale)
    ref_mu, ref_sd = mechanical_prediction(thin, sur_a, spec, x, y_scale=y_scale)
    ref_gmu, ref_gsd = mechanical_prediction(thin, sur_a, spec, grid, y_scale=y_scale)
    ref_map = mechanical_prediction({k: v[7:8] for k, v in samples.items()}, sur_a, spec, grid, y_scale=y_scale)[0][0]
    for got, ref in ((mu, ref_mu), (sd, ref_sd), (gmu, ref_gmu), (gsd, ref_gsd), (map_curve, ref_map)):
        np.testing.assert_allclose(got, np.asarray(ref, dtype=float), rtol=2e-5, atol=1e-6 * np.max(np.abs(ref)))
    assert mu.shape == (200, 24) and gmu.shape == (200, 80) and map_curve.shape == (80,)
    assert _predictions(predict, thin, samples, None, sur_a, spec, x, grid, y_scale)[4] is None
    handler = _Compiles()
    logger = logging.getLogger("jax")
    logger.addHandler(handler)
    try:
        with jax.log_compiles(True):  # another curve of the same network, another length: the same program
            _predictions(predict, thin, samples, 3, sur_b, spec, x[:14], grid, y_scale * 1.1)
    finally:
        logger.removeHandler(handler)
    assert handler.names == [], handler.names
