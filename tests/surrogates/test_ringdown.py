"""Ringdown fit: a known damped sine recovered to 0.1 %, mass-scale correction, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bubblecal.data import DEFAULT_UNITS
from bubblecal.surrogates import damped_sine, fit_ringdown


@pytest.mark.parametrize("noise", [0.0, 2e-3])
def test_ringdown_recovers_known_damped_sine(noise):
    lam, w = 0.035, 1.7
    t = np.linspace(3.0, 60.0, 1200)  # ~15 cycles, does not start at t = 0
    R = damped_sine(t, 6.0, -2e-4, 0.06, 0.02, lam, w)
    R = R + noise * 0.06 * np.random.default_rng(1).standard_normal(t.size)
    fit = fit_ringdown(t, R)
    f_res = math.sqrt(w**2 - lam**2) / (2 * math.pi)
    f_0 = math.sqrt(w**2 + lam**2) / (2 * math.pi)
    assert fit.success
    assert fit.f_res == pytest.approx(f_res, rel=1e-3)
    assert fit.f_0 == pytest.approx(f_0, rel=1e-3)
    assert fit.f_d == pytest.approx(w / (2 * math.pi), rel=1e-3)
    assert fit.lam == pytest.approx(lam, rel=2e-2)
    assert fit.A == pytest.approx(0.06, rel=1e-2) and fit.B == pytest.approx(0.02, abs=1e-3)
    assert fit.r2 > 0.99 and fit.n_cycles == pytest.approx(w * 57 / (2 * math.pi), rel=1e-2)
    assert fit.f_res_stderr < 1e-3 * fit.f_res
    # mass-scale correction: physical f = f_dpd sqrt(M) / u_t
    phys = fit.physical_MHz(mass_factor=160.0)
    assert phys["f_res"] == pytest.approx(fit.f_res * math.sqrt(160.0) / DEFAULT_UNITS.time_s / 1e6, rel=1e-12)


def test_ringdown_frequency_scales_with_mass():
    # f ~ M^-1/2: traces of two mass factors give the same physical frequency
    t = np.linspace(0, 400, 1600)
    fits = {}
    for M in (80.0, 160.0):
        w = 0.5 * math.sqrt(160.0 / M)
        fits[M] = fit_ringdown(t, damped_sine(t, 6.0, 0.0, 0.05, 0.0, 0.01 * w, w)).physical_MHz(M)["f_res"]
    assert fits[80.0] == pytest.approx(fits[160.0], rel=1e-6)


def test_ringdown_rejects_bad_input():
    with pytest.raises(ValueError, match="too short"):
        fit_ringdown(np.arange(5.0), np.ones(5))
    fit = fit_ringdown(np.linspace(0, 10, 200), np.random.default_rng(0).standard_normal(200))
    assert not fit.success and "quality check" in fit.message
