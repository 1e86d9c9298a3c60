"""The acoustic model on a diameter-continuous law: bubbles at diameters no sweep simulated."""

from __future__ import annotations

from pathlib import Path

import jax
import numpy as np
import pytest

from bubblecal.inference.tmcmc._flat_model import FlatModel
from bubblecal.models import FrequencyTable, acoustic_model, predict_frequency
from bubblecal.priors import load_priors
from bubblecal.surrogates import AcousticLawSurrogate, fit_law
from bubblecal.workflows.acoustic_sweep import law_rows, sweeps_from_rows_csv

ROWS = Path(__file__).resolve().parents[2] / "data" / "training" / "sonovue_ringdown_1.5-8um_rows.csv"


@pytest.fixture(scope="module")
def law_surrogate():
    return AcousticLawSurrogate(fit_law(*law_rows(sweeps_from_rows_csv(ROWS)), bands_um=()), name="sonovue")


def test_acoustic_model_at_diameters_never_simulated(law_surrogate):
    d = np.array([3.7, 5.3, 7.05])  # the sweeps ran every 0.5 um
    assert not set(d) & set(law_surrogate.diameters)
    table = FrequencyTable.at(law_surrogate, d)  # what bubblecal calibrate passes to the sampler
    ka = np.linspace(4000.0, 30000.0, 5)[:, None]
    np.testing.assert_allclose(np.asarray(table(ka, d)), np.asarray(law_surrogate.f_res(ka, d)), rtol=1e-6)
    np.testing.assert_allclose(np.asarray(predict_frequency(law_surrogate, 12000.0, d)),
                               np.asarray(law_surrogate.f_res(12000.0, d)), rtol=1e-7)
    spec = load_priors("sonovue_reduced_acoustic")
    freq = np.asarray(law_surrogate.f_res(12000.0, d)) * 1.02
    pts = jax.random.normal(jax.random.PRNGKey(1), (8, 2))
    a = np.asarray(jax.vmap(FlatModel(acoustic_model, (d, freq, law_surrogate, spec), {}).log_terms)(pts))
    b = np.asarray(jax.vmap(FlatModel(acoustic_model, (d, freq, table, spec), {}).log_terms)(pts))
    assert np.all(np.isfinite(a))
    np.testing.assert_allclose(b, a, rtol=1e-6, atol=1e-4)
    # the calibration plan asks for the fitted k_a range at each observed diameter
    lo, hi = law_surrogate.ka_ranges(3.7)
    assert lo == pytest.approx(617.0) and hi == pytest.approx(42000.0)
