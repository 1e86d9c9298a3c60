"""benchmarks/studies/minimiser_cg.py: the host CG on an analytic quadratic energy (the shell run is the study's)."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture(scope="module")
def mcg(load_script):
    return load_script("benchmarks/studies/minimiser_cg.py")


def test_cg_reaches_the_minimum_of_an_ill_conditioned_quadratic(mcg):
    rng = np.random.default_rng(3)
    k = np.exp(rng.uniform(0.0, np.log(1e3), (40, 3)))  # condition number up to 1,000
    target = rng.normal(size=(40, 3))
    x, iters, n_eval, fmax = mcg.cg_minimize(lambda x: -k * (x - target), np.zeros((40, 3)), ftol=1e-6)
    assert fmax <= 1e-6
    np.testing.assert_allclose(x, target, atol=1e-6 / k.min())
    # with its inexact line search the CG takes ~2x the 120 steps of an exact one (241 here); a steepest descent
    # would need ~kappa ln(1 / tolerance) ~ 10,000 at this conditioning
    assert iters <= 400 and n_eval <= 4 * iters


def test_cg_stops_at_once_when_the_start_is_converged(mcg):
    x, iters, n_eval, fmax = mcg.cg_minimize(lambda x: np.zeros_like(x), np.ones((5, 3)))
    assert iters == 0 and n_eval == 1 and fmax == 0.0
