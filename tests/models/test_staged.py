"""Leave-one-out ψ weights of the exact phase 3 (bubblecal.models.staged) against a direct computation."""

import numpy as np
import pytest
from scipy.stats import truncnorm

from bubblecal.models import leave_one_out_log_weights

BOUNDS = {"ka": (1.0e3, 3.0e4), "d0": (0.0, 0.5)}


def direct(m, tau, theta):
    """-log mean_k p(θ^k | ψ_s) / p0(θ^k) per ψ_s, normalised (float64 loops, scipy truncnorm)."""
    out = []
    for s in range(len(m["ka"])):
        ratio = np.ones(len(theta["ka"]))
        for k, (lo, hi) in BOUNDS.items():
            a, b = (lo - m[k][s]) / tau[k][s], (hi - m[k][s]) / tau[k][s]
            ratio *= truncnorm.pdf(theta[k], a, b, loc=m[k][s], scale=tau[k][s]) * (hi - lo)
        out.append(-np.log(ratio.mean()))
    out = np.asarray(out)
    return out - np.log(np.exp(out - out.max()).sum()) - out.max()


def test_matches_direct_computation_and_is_normalised():
    rng = np.random.default_rng(1)
    theta = {"ka": rng.uniform(5e3, 2e4, 300), "d0": rng.uniform(0.05, 0.3, 300), "sigma": rng.uniform(0, 1, 300)}
    m = {"ka": rng.uniform(4e3, 2.5e4, 50), "d0": rng.uniform(0.0, 0.4, 50)}
    tau = {"ka": rng.uniform(1e3, 8e3, 50), "d0": rng.uniform(0.02, 0.2, 50)}
    lw = leave_one_out_log_weights(m, tau, theta, BOUNDS, chunk=16)  # chunks of 16 over 50 draws
    assert lw.shape == (50,)
    np.testing.assert_allclose(lw, direct(m, tau, theta), rtol=0, atol=2e-4)  # float32 JAX vs float64
    assert np.exp(lw).sum() == pytest.approx(1.0, abs=1e-9)
    # the ψ that explains the dataset best (largest L_i) gets the smallest weight
    assert np.argmin(lw) == np.argmax(-direct(m, tau, theta))


def test_no_pooled_parameter_is_an_error():
    with pytest.raises(ValueError, match="none of the pooled parameters"):
        leave_one_out_log_weights({"kb": np.ones(3)}, {"kb": np.ones(3)}, {"ka": np.ones(4)}, BOUNDS)
