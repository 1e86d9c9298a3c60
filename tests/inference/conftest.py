"""Fixtures of the statistical-validity tests: the closed-form shell laws as JAX surrogates."""

from __future__ import annotations

import math

import jax.numpy as jnp
import pytest


class ClosedFormSurrogate:
    """The closed-form laws of :mod:`bubblecal.surrogates.training.synthetic` in JAX, with the surrogate contract
    ``(params[..., 6], x[...]) -> y[...]`` (DPD units; ``radius_dpd`` of the bubble). Checked against
    the NumPy original in ``test_coverage.py``."""

    def __init__(self, setup: str, radius_dpd: float):
        self.setup = setup
        self.radius = float(radius_dpd)

    def __call__(self, params, x):
        p = jnp.asarray(params)
        x = jnp.asarray(x)
        ka, kb, b1, b2, a3, a4 = (p[..., j] for j in range(6))
        R = self.radius
        kr = 8.0 * jnp.sqrt(jnp.abs(ka * kb) / math.sqrt(3.0)) / R
        if self.setup == "compression":
            e = x / (2.0 * R)
            return (kr * x * (1 + 0.5 * b1 * e + b2 * e**2) + math.pi * ka * R * e**2 * (1 + a3 * e + a4 * e**2)
                    + 0.01 * kr * R)
        q = x / (ka * R)
        return (x / kr) * (1 + 0.25 * b1 * q + b2 * q**2) / (1 + (2 + 0.5 * a3 + 0.25 * a4) * q)


@pytest.fixture
def closed_form():
    """The class :class:`ClosedFormSurrogate`: ``closed_form(setup, radius_dpd)``."""
    return ClosedFormSurrogate
