"""The summaries' and figures' JAX evaluations on host data as one compiled program each: the same numbers as the
eager calls (to float32 round-off), for the acoustic surrogates fitted per diameter and the laws over the diameter."""

import jax
import numpy as np
import pytest

from bubblecal.models import sample_population_predictive
from bubblecal.models.acoustic import acoustic_prediction
from bubblecal.workflows.calibrate import CalibrationConfig, make_plan
from bubblecal.workflows.host_programs import (
    acoustic_prediction_program,
    frequency_program,
    population_predictive_draws,
)


@pytest.mark.parametrize("surrogates", ["per-diameter", "over-diameter"])
def test_acoustic_programs_equal_the_eager_calls(tmp_path, surrogates):
    f_res = make_plan(CalibrationConfig(out=tmp_path, agents=("definity",), surrogates=surrogates)).agents[0].f_res
    ka = np.linspace(5_000.0, 20_000.0, 7)
    diameters = np.array(list(f_res.diameters))[:4]
    got = frequency_program(f_res)(ka[:, None], diameters[None, :])
    want = np.asarray(f_res.f_res(ka[:, None], diameters[None, :]))
    assert got.shape == (7, 4)
    np.testing.assert_allclose(got, want, rtol=1e-6)
    # another set of diameters is another program, not the first one's answer
    other = frequency_program(f_res)(ka[:, None], diameters[None, 1:3])
    np.testing.assert_allclose(other, want[:, 1:3], rtol=1e-6)
    sigma = np.full(7, 0.05)
    mu, sd = acoustic_prediction_program(f_res)(ka, sigma, diameters, 5.0)
    mu_e, sd_e = acoustic_prediction(ka, sigma, f_res, diameters, f_scale=5.0)
    assert mu.dtype == np.float64 and mu.shape == (7, 4)
    np.testing.assert_allclose(mu, np.asarray(mu_e), rtol=1e-6)
    np.testing.assert_allclose(sd, np.asarray(sd_e), rtol=1e-6)


def test_population_draws_equal_the_eager_sampler():
    rng = np.random.default_rng(0)
    m = {"ka": rng.uniform(8e3, 12e3, 50), "kb": rng.uniform(1e3, 3e4, 50)}
    tau = {"ka": rng.uniform(500.0, 2e3, 50), "kb": rng.uniform(1e3, 5e3, 50)}
    bounds = {"ka": (1e3, 4e4), "kb": (1.0, 6e4)}
    key = jax.random.PRNGKey(3)
    got = population_predictive_draws(key, m, tau, bounds, 400)
    want = sample_population_predictive(key, m, tau, bounds, 400)
    for k in m:
        assert isinstance(got[k], np.ndarray) and got[k].shape == (400,)
        np.testing.assert_allclose(got[k], np.asarray(want[k]), rtol=2e-5)
        assert bounds[k][0] <= got[k].min() and got[k].max() <= bounds[k][1]
