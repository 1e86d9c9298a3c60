"""Pure log densities of the observation model: the relative noise and its floor."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from bubblecal.models import SD_FLOOR_REL, noise_sd, relative_normal_loglik, sd_floor_for


def test_noise_floor_keeps_density_finite():
    y = jnp.array([1.0, 2.0, 3.0])
    yhat = jnp.zeros(3)  # a clamped prediction
    floor = sd_floor_for(3.0)
    assert float(floor) == pytest.approx(3.0 * SD_FLOOR_REL)
    ll = relative_normal_loglik(y, yhat, 0.05, floor)
    assert np.isfinite(float(ll))
    g = jax.grad(lambda s: relative_normal_loglik(y, yhat, s, floor))(0.05)
    assert np.isfinite(float(g))
    # away from zero the floor is negligible
    np.testing.assert_allclose(float(noise_sd(2.0, 0.05, floor)), 0.1, rtol=1e-5)
