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


def _assert_same_tempering(a, b, atol: float = 1e-4) -> bool:
    """Assert that two TMCMC runs (replica by replica) are the same tempering to float32 round-off.

    Two programs that compute the same densities with differently fused arithmetic (a batched and a single run)
    differ by ~1e-6 in log L, which can flip one accept/reject decision among the thousands of a run; from that
    stage on (the proposal scale adapts to the acceptance) the runs are different, equally valid draws. So: every
    stage table row up to and including the first stage whose acceptance differs agrees within ``atol`` (β, Δ, ESS,
    log Z, scale: the first stage depends on the prior draws alone), and without such a flip the whole run and
    the final particles agree within ``atol``.  Returns whether every replica ran without a flip.
    """
    import numpy as np

    assert a.num_replicas == b.num_replicas
    strict = True
    for r in range(a.num_replicas):
        ta, tb = a.replica_stage_info(r), b.replica_stage_info(r)
        n = min(len(ta), len(tb))
        flipped = np.flatnonzero(np.abs(ta["acceptance"].to_numpy()[1:n] - tb["acceptance"].to_numpy()[1:n]) > 1e-6)
        upto = n if flipped.size == 0 else int(flipped[0]) + 2  # rows 0 .. the first flipped stage
        for column in ("beta", "delta", "ess", "log_evidence", "scale"):
            np.testing.assert_allclose(ta[column].to_numpy()[:upto], tb[column].to_numpy()[:upto], atol=atol,
                                       rtol=1e-5, err_msg=f"replica {r}, column {column}")
        if flipped.size == 0:
            assert len(ta) == len(tb)
            np.testing.assert_allclose(np.asarray(a._results[r]["state"].position),
                                       np.asarray(b._results[r]["state"].position), atol=atol)
        strict = strict and flipped.size == 0
    return strict


@pytest.fixture
def same_tempering():
    """The check :func:`_assert_same_tempering` ``(run_a, run_b, atol=1e-4) -> bool`` (True: no flip)."""
    return _assert_same_tempering
