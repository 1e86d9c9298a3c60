"""Data as traced arguments: TracedSurrogate, pad_curve + mask, FrequencyTable give the densities of the
plain objects, so a compiled TMCMC program shared by several curves computes what each curve's own would."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from bubblecal.inference.tmcmc._flat_model import FlatModel
from bubblecal.models import FrequencyTable, TracedSurrogate, acoustic_model, mechanical_model, pad_curve
from bubblecal.priors import load_priors
from bubblecal.surrogates import default_bundle_path, load_bundle


@pytest.fixture(scope="module")
def bundle():
    return load_bundle(default_bundle_path(must_exist=True))


@pytest.fixture(scope="module")
def spec_sonovue():
    return load_priors("sonovue_reduced")


def _densities(model, args, kwargs, x):
    flat = FlatModel(model, args, kwargs)
    return np.asarray(jax.vmap(flat.log_terms)(x)), flat


def test_traced_surrogate_matches_the_loaded_surrogate(bundle):
    sur = bundle.get("indentation", 5.8)
    traced = TracedSurrogate.wrap(sur)
    assert TracedSurrogate.wrap(traced) is traced  # idempotent
    assert TracedSurrogate.wrap(len) is len  # anything else passes unchanged
    rng = np.random.default_rng(0)
    params = np.c_[rng.uniform(5000, 20000, 7), rng.uniform(100, 1000, 7), np.zeros((7, 4))]
    x = np.linspace(500.0, 6000.0, 7)
    np.testing.assert_allclose(np.asarray(traced(params, x)), np.asarray(sur(params, x)), rtol=1e-6)
    # a pytree: the weights are its leaves, setup and input names ride along
    leaves, treedef = jax.tree_util.tree_flatten(traced)
    assert len(leaves) == len(sur.weights) + len(sur.biases) + 4
    assert jax.tree_util.tree_unflatten(treedef, leaves).setup == "indentation"
    with pytest.raises(ValueError, match="last axis of length 6"):
        traced(np.ones(5), x)


def test_padded_masked_curve_has_the_density_of_the_curve(bundle, spec_sonovue):
    sur = TracedSurrogate.wrap(bundle.get("indentation", 3.2))
    x = np.linspace(500.0, 5000.0, 9)
    y = np.asarray(sur(jnp.array([12000.0, 400.0, 0, 0, 0, 0]), x)) + 0.01
    xp, yp, mask = pad_curve(x, y, 14)
    assert xp.shape == yp.shape == mask.shape == (14,) and mask.sum() == 9 and np.all(xp[9:] == x[-1])
    with pytest.raises(ValueError, match="cannot pad a curve of 9 points to 5"):
        pad_curve(x, y, 5)
    flat = FlatModel(mechanical_model, (x, y, sur, spec_sonovue))
    pts = jax.random.normal(jax.random.PRNGKey(3), (16, flat.dim))
    plain, _ = _densities(mechanical_model, (x, y, sur, spec_sonovue), {}, pts)
    padded, flat_p = _densities(mechanical_model, (xp, yp, sur, spec_sonovue), {"mask": mask}, pts)
    np.testing.assert_allclose(padded, plain, rtol=1e-5, atol=1e-3)
    assert len(flat_p.data) > 3  # curve, mask and the network's arrays are traced arguments


def test_frequency_table_matches_the_acoustic_surrogate(bundle):
    f_res = bundle.acoustic["sonovue"]
    d = np.array(f_res.diameters)
    table = FrequencyTable.at(f_res, d)
    ka = jnp.linspace(4000.0, 30000.0, 5)[:, None]
    np.testing.assert_allclose(np.asarray(table(ka, d)), np.asarray(f_res(ka, d)), rtol=1e-6)
    spec = load_priors("sonovue_reduced_acoustic")
    freq = np.asarray(f_res(12000.0, d)) * 1.02
    pts = jax.random.normal(jax.random.PRNGKey(1), (8, 2))
    a, _ = _densities(acoustic_model, (d, freq, f_res, spec), {}, pts)
    b, flat = _densities(acoustic_model, (d, freq, table, spec), {}, pts)
    np.testing.assert_allclose(b, a, rtol=1e-6, atol=1e-4)
    assert len(flat.data) == 4  # diameters, frequencies and both table arrays are traced


def test_equal_structures_share_a_signature_and_differ_in_data(bundle, spec_sonovue):
    sur = TracedSurrogate.wrap(bundle.get("indentation", 3.2))
    x = np.linspace(500.0, 5000.0, 9)
    flat_a = FlatModel(mechanical_model, (x, np.ones(9), sur, spec_sonovue))
    flat_b = FlatModel(mechanical_model, (x * 1.1, 2 * np.ones(9), sur, spec_sonovue))
    flat_c = FlatModel(mechanical_model, (x[:8], np.ones(8), sur, spec_sonovue))
    assert flat_a.signature == flat_b.signature  # one compiled program serves both
    assert flat_a.signature != flat_c.signature  # another curve length: another program
    # the template's densities with b's data are b's densities
    pts = jax.random.normal(jax.random.PRNGKey(0), (4, flat_a.dim))
    via_a = jax.vmap(lambda p: flat_a.log_terms(p, flat_b.data))(pts)
    own_b = jax.vmap(flat_b.log_terms)(pts)
    np.testing.assert_allclose(np.asarray(via_a), np.asarray(own_b), rtol=1e-6)
