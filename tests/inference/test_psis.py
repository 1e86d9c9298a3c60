"""Pareto k̂ (`bubblecal.inference.pareto_k`): ArviZ's `psislw` diagnostic to the last bit, and the shape of
known Pareto tails."""

from __future__ import annotations

import numpy as np
import pytest

from bubblecal.inference import pareto_k


@pytest.mark.parametrize("alpha", [1.0, 2.0, 4.0])
def test_pareto_k_of_pareto_tailed_weights(alpha):
    """Importance ratios with a Pareto(α) tail have k = 1/α (PSIS's estimate, 4,000 draws, ± 0.15)."""
    w = np.random.default_rng(3).pareto(alpha, size=4000) + 1.0
    assert float(pareto_k(np.log(w))) == pytest.approx(1.0 / alpha, abs=0.15)


def test_pareto_k_per_column():
    """(S, n) weights: one k per column, each that of its own column's tail."""
    rng = np.random.default_rng(4)
    lw = np.log(np.stack([rng.pareto(a, size=4000) + 1.0 for a in (1.0, 4.0)], axis=-1))
    k = pareto_k(lw)
    assert k.shape == (2,) and k[0] == pytest.approx(1.0, abs=0.15) and k[1] == pytest.approx(0.25, abs=0.15)



@pytest.mark.parametrize("draws", [50, 2000, 50_000])
def test_pareto_k_equals_arviz_psislw(draws):
    """Weights of every kind (heavy and light tails, -inf entries, a tail too short to fit): the same k̂ as
    ``arviz.psislw``, bit for bit where both are finite."""
    az = pytest.importorskip("arviz")
    rng = np.random.default_rng(draws)
    lw = np.stack([np.log(rng.pareto(a, size=draws) + 1.0) for a in (0.6, 1.5, 5.0)]
                  + [rng.normal(size=draws), np.where(rng.random(draws) < 0.5, -np.inf, rng.normal(size=draws))],
                  axis=-1)
    lw[:3, 2] = 30.0  # three outliers
    _, want = az.psislw(lw.T.copy(), reff=1.0)
    got = pareto_k(lw)
    np.testing.assert_array_equal(got, np.asarray(want))
    assert float(pareto_k(lw[:, 0])) == float(np.asarray(want)[0])


def test_pareto_k_of_a_tail_of_four_draws_is_infinite():
    """Five draws: the tail (one fifth) holds too few draws to fit, as in ArviZ."""
    assert np.isinf(pareto_k(np.log(np.arange(1.0, 6.0))))
