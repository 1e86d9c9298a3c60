"""Acoustic model: relative-noise log density in MHz by hand."""

import math

import jax
import numpy as np
import pytest
from numpyro.infer import Predictive
from numpyro.infer.util import log_density

from bubblecal.data import acoustic_datasets
from bubblecal.models import SD_FLOOR_REL, acoustic_model, acoustic_prediction
from bubblecal.priors import load_priors


def test_log_density_matches_hand_formula(fres):
    spec = load_priors("definity_reduced_acoustic")
    ds = acoustic_datasets("definity")[0]
    assert ds.n_points == 14
    values = {"ka": 1.4e4, "sigma_ac": 0.1}
    got, tr = log_density(acoustic_model, (ds.diameter_um, ds.frequency_MHz, fres, spec), {}, values)
    fhat = np.array([float(fres(values["ka"], d)) for d in ds.diameter_um])
    sd = np.sqrt((0.1 * fhat) ** 2 + (SD_FLOOR_REL * ds.frequency_MHz.max()) ** 2)
    want = (-math.log(spec.bounds("ka").width) - math.log(spec.bounds("sigma_ac").width)
            + np.sum(-0.5 * ((ds.frequency_MHz - fhat) / sd) ** 2 - np.log(sd) - 0.5 * math.log(2 * math.pi)))
    assert float(got) == pytest.approx(want, rel=1e-5)
    assert tr["f"]["is_observed"] and tr["f"]["value"].shape == (14,)


def test_accepts_object_with_fres_method_and_predicts(fres):
    spec = load_priors("sonovue_reduced_acoustic")

    class Acoustic:
        def f_res(self, ka, diameter_um):
            return fres(ka, diameter_um)

    ds = acoustic_datasets("sonovue")
    assert len(ds) == 3 and all(d.n_points == 1 for d in ds)
    draws = Predictive(acoustic_model, num_samples=16)(jax.random.PRNGKey(0), ds[0].diameter_um, None, Acoustic(),
                                                          spec, f_scale=5.0)
    assert draws["f"].shape == (16, 1)
    fhat, sd = acoustic_prediction(draws["ka"], draws["sigma_ac"], Acoustic(), ds[0].diameter_um, f_scale=5.0)
    assert fhat.shape == sd.shape == (16, 1) and np.all(np.asarray(sd) > 0)


def test_non_acoustic_priors_rejected(fres):
    with pytest.raises(ValueError, match="sigma_ac"):
        log_density(acoustic_model, (np.array([3.0]), np.array([4.0]), fres, load_priors("definity_full")), {},
                    {"ka": 1e4, "sigma_ac": 0.1})
