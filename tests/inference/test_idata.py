"""ArviZ export of TMCMC and NUTS runs: one chain per replica, named dims, units, versions, the pointwise log
likelihood against the analytic normal density, PSIS-LOO, and Pareto k of known-tail weights."""

from __future__ import annotations

import jax
import numpy as np
import numpyro
import numpyro.distributions as dist
import pytest
from scipy import stats

from bubblecal.inference import TMCMC, ExportInfo, pointwise_log_likelihood

Y = np.linspace(-1.0, 1.5, 12)


def normal_mean(y):
    mu = numpyro.sample("mu", dist.Uniform(-5.0, 5.0))
    numpyro.deterministic("mu2", 2.0 * mu)
    numpyro.factor("extra", 0.0)  # a factor is not an observation: no pointwise log likelihood
    numpyro.sample("y", dist.Normal(mu, 1.0), obs=y)


def test_tmcmc_export_has_every_replica_named_dims_units_and_the_analytic_pointwise_loglik(tmp_path):
    import arviz as az

    tm = TMCMC(normal_mean, num_particles=200, num_replicas=3, num_mcmc_steps=2)
    tm.run(jax.random.PRNGKey(1), Y)
    info = ExportInfo(dims={"y": ("points",), "x": ("points",)}, coords={"points": np.arange(Y.size)},
                      units={"mu": "m", "y": "m"}, constant_data={"x": np.arange(Y.size) * 1.0},
                      attrs={"dataset": "toy"})
    idata = tm.to_inference_data(info)
    path = tmp_path / "run.nc"
    idata.to_netcdf(str(path))
    back = az.from_netcdf(str(path))
    assert {"posterior", "sample_stats", "log_likelihood", "observed_data", "constant_data"} <= set(back.groups())
    assert back.posterior.sizes["chain"] == 3 and back.posterior.sizes["draw"] == 200
    for r in range(3):  # each chain is that replica's particles
        np.testing.assert_array_equal(back.posterior["mu"].values[r], tm.get_samples(r)["mu"])
    assert list(back.log_likelihood) == ["y"] and back.log_likelihood["y"].dims == ("chain", "draw", "points")
    mu = back.posterior["mu"].values
    expected = stats.norm.logpdf(Y[None, None, :], mu[..., None], 1.0)
    np.testing.assert_allclose(back.log_likelihood["y"].values, expected, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(back.log_likelihood["y"].values.sum(-1), back.sample_stats["loglik"].values,
                               rtol=1e-4, atol=1e-3)
    np.testing.assert_allclose(back.sample_stats["lp"].values,
                               back.sample_stats["loglik"].values + back.sample_stats["log_prior"].values, rtol=1e-6)
    np.testing.assert_array_equal(back.observed_data["y"].values, Y)
    assert back.posterior["mu"].attrs["units"] == "m" and back.observed_data["y"].attrs["units"] == "m"
    assert back.sample_stats["stage_beta"].dims == ("chain", "stage")
    assert np.nanmax(back.sample_stats["stage_beta"].values, axis=1) == pytest.approx([1.0] * 3)
    for group in back.groups():
        ds = getattr(back, group)
        assert ds.attrs["bubblecal_idata_format"] == 2 and ds.attrs["numpyro_version"] == numpyro.__version__
        assert not any("_dim_" in d for d in ds.dims), (group, ds.dims)
    assert float(back.posterior.attrs["log_evidence"]) == pytest.approx(tm.log_evidence)
    loo = az.loo(back)
    assert np.isfinite(loo["elpd_loo"]) and loo["n_data_points"] == Y.size


def test_pointwise_log_likelihood_drops_padding_and_checks_shapes():
    def padded(y, mask):
        mu = numpyro.sample("mu", dist.Normal(0.0, 1.0))
        numpyro.sample("y", dist.Normal(mu, 1.0).mask(mask), obs=y)

    y = np.array([0.1, 0.2, 0.3, 0.0])
    mask = np.array([True, True, True, False])
    draws = {"mu": np.linspace(-1, 1, 7)}
    ll = pointwise_log_likelihood(padded, draws, (y, mask), keep={"y": mask}, chunk_size=3)
    assert ll["y"].shape == (7, 3) and ll["y"].dtype == np.float32
    np.testing.assert_allclose(ll["y"], stats.norm.logpdf(y[None, :3], draws["mu"][:, None]), rtol=1e-5)
    with pytest.raises(ValueError, match="disagree"):
        pointwise_log_likelihood(padded, {"mu": np.zeros(3), "z": np.zeros(4)}, (y, mask))


def test_observed_sites_as_data_and_computed_in_the_model_equal_the_eager_trace():
    import jax.numpy as jnp
    from numpyro.handlers import substitute, trace

    from bubblecal.inference.idata import observed_sites

    y = np.array([0.5, 1.5, 2.5], dtype=np.float32)

    def model(y, scale):
        mu = numpyro.sample("mu", dist.Normal(0.0, 1.0))
        numpyro.sample("as_data", dist.Normal(mu, 1.0), obs=y)
        numpyro.sample("computed", dist.Normal(mu, 1.0), obs=jnp.asarray(y, dtype=float) * scale)
        numpyro.factor("not_an_observation", -mu**2)

    draws = {"mu": np.zeros((2, 4))}
    got = observed_sites(model, draws, (y, 3.0), batch_ndims=2)
    eager = trace(substitute(model, {"mu": 0.0})).get_trace(y, 3.0)
    assert sorted(got) == ["as_data", "computed"]
    for name in got:
        assert isinstance(got[name], np.ndarray)
        np.testing.assert_array_equal(got[name], np.asarray(eager[name]["value"]))


def test_export_evaluates_the_pointwise_loglik_in_cpu_chunks_or_all_at_once_on_an_accelerator(monkeypatch):
    from bubblecal.inference import idata as idata_module
    from bubblecal.inference.tmcmc import results as results_module

    tm = TMCMC(normal_mean, num_particles=1500, num_replicas=2, num_mcmc_steps=1)
    tm.run(jax.random.PRNGKey(3), Y)
    sizes = []
    real = idata_module.pointwise_log_likelihood

    def spy(*args, **kwargs):
        sizes.append(kwargs["chunk_size"])
        return real(*args, **kwargs)

    monkeypatch.setattr(idata_module, "pointwise_log_likelihood", spy)
    on_cpu = tm.inference_parts()["log_likelihood"]["y"]
    monkeypatch.setattr(results_module, "_default_platform", lambda: "gpu")
    at_once = tm.inference_parts()["log_likelihood"]["y"]
    assert sizes == [results_module.POINTWISE_CPU_CHUNK, 3000]
    np.testing.assert_allclose(at_once, on_cpu, rtol=1e-6, atol=1e-6)
    assert on_cpu.shape == (2, 1500, Y.size)
