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


def _phase1_sets(n_curves, n_acoustic, draws=50, seed=0):
    rng = np.random.default_rng(seed)
    curves = [{"ka": rng.uniform(1.2e4, 1.8e4, draws), "kb": rng.uniform(300, 700, draws)} for _ in range(n_curves)]
    acoustic = [{"ka": rng.uniform(1.0e4, 2.0e4, draws + 10)} for _ in range(n_acoustic)]
    return curves + acoustic


def test_grouped_weights_and_likelihood_equal_the_per_dataset_sums():
    """Stacking datasets of one shape changes nothing: weights, terms and log L(psi) as one dataset at a time."""
    import jax.numpy as jnp
    from jax.scipy.special import logsumexp

    from bubblecal.models import grouped_log_weights, importance_log_weights, staged_log_likelihood

    bounds = {"ka": (5e3, 3e4), "kb": (100.0, 1000.0)}
    sets = _phase1_sets(4, 3)
    m = {"ka": jnp.array([1.5e4, 1.6e4]), "kb": jnp.array([500.0, 450.0])}  # a batch of two psi
    tau = {"ka": jnp.array([2e3, 3e3]), "kb": jnp.array([100.0, 150.0])}
    groups = grouped_log_weights(m, tau, sets, bounds)
    assert [g[0] for g in groups] == [[0, 1, 2, 3], [4, 5, 6]]  # curves (ka, kb) and acoustic sets (ka only)
    want_total = 0.0
    for members, lw in groups:
        assert lw.shape == (2, len(members), len(sets[members[0]]["ka"]))
        for j, i in enumerate(members):
            one = importance_log_weights(m, tau, sets[i], bounds)
            np.testing.assert_allclose(np.asarray(lw[:, j]), np.asarray(one), rtol=1e-6)
    for s in sets:
        lw = importance_log_weights(m, tau, s, bounds)
        want_total = want_total + logsumexp(lw, axis=-1) - np.log(lw.shape[-1])
    np.testing.assert_allclose(np.asarray(staged_log_likelihood(m, tau, sets, bounds)), np.asarray(want_total),
                               rtol=1e-6)


def test_phase2_program_does_not_grow_with_the_datasets():
    """Phase 2 of 60 datasets traces to about the operations of 6: one computation per shape, not per dataset."""
    import jax

    from bubblecal.models import phase2_model
    from bubblecal.priors import load_priors

    spec = load_priors("definity_reduced_acoustic")
    pooled = set(spec.pooled_names)

    def equations(n):
        sets = [{k: v for k, v in s.items() if k in pooled} for s in _phase1_sets(n, n)]
        values = {f"{p}_{k}": 1.0 for k in spec.pooled_names for p in ("m", "tau")}

        def log_density(v):
            from numpyro.infer.util import log_density as ld

            return ld(phase2_model, (sets, spec), {}, v)[0]

        return len(jax.make_jaxpr(log_density)(values).jaxpr.eqns)

    small, large = equations(3), equations(30)
    # a stack operand, a slice and an add per dataset: one dataset's own densities would be dozens of operations
    assert (large - small) / (2 * 27) < 8


def test_all_datasets_log_likelihoods_equal_one_at_a_time():
    """Each column equals dataset i's term computed alone from its importance weights (no stacking)."""
    from scipy.special import logsumexp

    from bubblecal.models import dataset_log_likelihood, dataset_log_likelihoods, importance_log_weights

    bounds = {"ka": (5e3, 3e4), "kb": (100.0, 1000.0)}
    sets = _phase1_sets(3, 2)
    rng = np.random.default_rng(3)
    m = {"ka": rng.uniform(1.3e4, 1.7e4, 37), "kb": rng.uniform(400, 600, 37)}
    tau = {"ka": rng.uniform(1e3, 3e3, 37), "kb": rng.uniform(50, 200, 37)}
    got = dataset_log_likelihoods(m, tau, sets, bounds, chunk=16)  # 37 draws: a padded last chunk
    assert got.shape == (37, 5)
    for i, s in enumerate(sets):
        names = [k for k in m if k in s]
        lw = np.asarray(importance_log_weights({k: m[k] for k in names}, {k: tau[k] for k in names},
                                               {k: s[k] for k in names}, bounds, names=names), dtype=float)
        want = logsumexp(lw, axis=-1) - np.log(len(s[names[0]]))
        np.testing.assert_allclose(got[:, i], want, rtol=2e-6, atol=1e-5)
        np.testing.assert_array_equal(dataset_log_likelihood(m, tau, s, bounds, chunk=16), got[:, i])


def test_a_dataset_without_pooled_parameters_is_named():
    from bubblecal.models import dataset_log_likelihoods, grouped_log_weights

    bounds = {"ka": (5e3, 3e4)}
    sets = [{"ka": np.full(5, 1.5e4)}, {"kb": np.full(5, 500.0)}]
    m, tau = {"ka": np.full(3, 1.5e4)}, {"ka": np.full(3, 2e3)}
    with pytest.raises(ValueError, match="dataset 1 has none of the pooled parameters ka"):
        grouped_log_weights(m, tau, sets, bounds)
    with pytest.raises(ValueError, match="dataset 1 has none of the pooled parameters ka"):
        dataset_log_likelihoods(m, tau, sets, bounds)
