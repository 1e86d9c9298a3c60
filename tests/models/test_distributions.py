"""The shared constructors: uniform priors from Bounds, the relative-noise observation distribution."""

import jax.numpy as jnp
import numpy as np
import numpyro.distributions as dist

from bubblecal.models import SD_FLOOR_REL, noise_sd, relative_normal, sd_floor_for, uniform_prior
from bubblecal.priors import load_priors


def test_uniform_prior_spans_the_bounds_with_python_floats():
    spec = load_priors("definity_reduced")
    for p in spec.parameters.values():
        for b in (p.prior, p.hyper_m, p.hyper_tau):
            if b is None:
                continue
            d = uniform_prior(b)
            assert isinstance(d, dist.Uniform)
            assert float(d.low) == b.lo and float(d.high) == b.hi
            assert type(d.low) is float and type(d.high) is float  # Python floats, as the models always passed


def test_relative_normal_is_normal_with_the_floored_sd():
    yhat = jnp.array([0.0, 1.0, 2.5])
    floor = sd_floor_for(2.5)
    d = relative_normal(yhat, 0.05, floor)
    np.testing.assert_array_equal(d.loc, yhat)
    np.testing.assert_array_equal(d.scale, noise_sd(yhat, 0.05, floor))
    np.testing.assert_allclose(float(d.scale[0]), 2.5 * SD_FLOOR_REL, rtol=1e-6)  # a clamped prediction keeps the floor
