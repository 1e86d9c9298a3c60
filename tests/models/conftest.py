"""Closed-form JAX stand-ins for the surrogates (the models accept any callable with their signature)."""

from __future__ import annotations

import math

import jax.numpy as jnp
import pytest

PARAMS = ("ka", "kb", "b1", "b2", "a3", "a4")


class StandInSurrogate:
    """Reissner-flavoured closed-form law with the surrogate contract: (params[..., 6], x[...]) -> y[...].

    compression: F(x) = k_R x (1 + b1 e/2 + b2 e^2) + pi ka R e^2 (1 + a3 e + a4 e^2), e = x / (2R);
    indentation: delta(F) = (F / k_R) (1 + b1 q/4 + b2 q^2) / (1 + (2 + a3/2 + a4/4) q), q = F / (ka R);
    k_R = 8 sqrt(ka kb / sqrt 3) / R (DPD units, R = DPD radius).
    """

    def __init__(self, setup: str, diameter_um: float, offset: float = 0.0):
        self.setup = setup
        self.diameter_um = diameter_um
        self.radius = diameter_um * 2.0  # DPD radius (1 DPD length = 0.25 um)
        self.offset = offset  # shifts the output (lets tests make the clamp bite)
        self.param_ranges = {"ka": (1e2, 1e6), "kb": (10.0, 1e5), "b1": (0, 3), "b2": (0, 10), "a3": (-2.5, 3),
                             "a4": (0, 4)}
        self.x_range = (0.0, 2.0) if setup == "compression" else (0.0, 8000.0)

    def __call__(self, params, x):
        p = jnp.asarray(params)
        x = jnp.asarray(x)
        ka, kb, b1, b2, a3, a4 = (p[..., j] for j in range(6))
        R = self.radius
        kr = 8.0 * jnp.sqrt(ka * kb / math.sqrt(3.0)) / R
        if self.setup == "compression":
            e = x / (2.0 * R)
            y = kr * x * (1 + 0.5 * b1 * e + b2 * e**2) + math.pi * ka * R * e**2 * (1 + a3 * e + a4 * e**2)
        else:
            q = x / (ka * R)
            y = (x / kr) * (1 + 0.25 * b1 * q + b2 * q**2) / (1 + (2 + 0.5 * a3 + 0.25 * a4) * q)
        return y + self.offset


def stand_in_fres(ka, diameter_um):
    """Acoustic stand-in: f [MHz] = sqrt(a0 + a1 ka + a2 ka^2) / D with fixed coefficients."""
    return jnp.sqrt(4.0 + 2.0e-3 * ka + 1.0e-8 * ka**2) * 3.0 / diameter_um


@pytest.fixture
def compression_surrogate():
    return StandInSurrogate("compression", 2.1)


@pytest.fixture
def indentation_surrogate():
    return StandInSurrogate("indentation", 3.2)


@pytest.fixture
def make_surrogate():
    """The stand-in surrogate class: make_surrogate(setup, diameter_um, offset=0.0)."""
    return StandInSurrogate


@pytest.fixture
def fres():
    return stand_in_fres
