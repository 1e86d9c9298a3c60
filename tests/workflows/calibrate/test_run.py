"""`bubblecal calibrate` runs: a tiny staged run with an injected crash in phase 2, reuse of finished phases,
outputs (NetCDF, manifest, summary, figures, report), the joint NUTS run and GPU curve padding."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from bubblecal.workflows.calibrate import CalibrationConfig, make_plan, run_calibration
from bubblecal.workflows.cli import app

runner = CliRunner()


def _cli(*args):
    return runner.invoke(app, ["calibrate", *map(str, args)])


# -------------------------------------------------------------------------------------------------
# a tiny staged run: crash in phase 2, rerun reuses phase 1, outputs
# -------------------------------------------------------------------------------------------------
CURVES = {"one": ("definity_compression_2.1um",), "all": ()}


@pytest.mark.parametrize("which", ["one", pytest.param("all", marks=pytest.mark.slow)])
def test_staged_run_crash_resume_and_outputs(tmp_path, synthetic_bundle, which):
    """Default suite: one curve (phases 1, 2, 3 once each); slow: all three Definity curves."""
    out = tmp_path / "cal"
    config = CalibrationConfig(agents=("definity",), workflow="reduced", bundle=synthetic_bundle, population=120,
                               out=out, phase2_samples=120, predictive_samples=200, num_mcmc_steps=3,
                               curves=CURVES[which])
    plan = make_plan(config)
    assert plan.synthetic_bundle

    def crash(name):
        if name == "phase2":
            raise RuntimeError("injected crash in phase 2")

    with pytest.raises(RuntimeError, match="injected"):
        run_calibration(plan, inject=crash)
    run_dir = out / "definity" / "reduced"
    phase1 = sorted(p.name for p in run_dir.glob("phase1_*.nc"))
    diameters = ("2.1",) if which == "one" else ("2.1", "2.9", "3.0")
    assert phase1 == [f"phase1_definity_compression_{d}um.nc" for d in diameters]
    assert not list(run_dir.glob("phase2*")) and not list(run_dir.glob(".*tmp"))
    stamps = {p: p.stat().st_mtime_ns for p in run_dir.glob("phase1_*.nc")}

    results = run_calibration(make_plan(config))
    (res,) = results
    assert sorted(res.reused) == sorted(p.removesuffix(".nc") for p in phase1)
    assert all(p.stat().st_mtime_ns == t for p, t in stamps.items())  # phase-1 files untouched
    manifest = json.loads((run_dir / "manifest.json").read_text())
    assert set(manifest["phases"]) == {*(p.removesuffix(".nc") for p in phase1), "phase2",
                                       *(p.replace("phase1", "phase3").removesuffix(".nc") for p in phase1)}
    assert all(len(v["config_hash"]) == 16 for v in manifest["phases"].values())
    # summary: per curve mean / 90 % / MAP of ka, kb, d0, sigma in DPD and physical units + coverage, CRPS
    df = pd.read_csv(run_dir / "summary.csv")
    curve = df[df["dataset"] == "definity_compression_2.1um"].set_index("parameter")
    assert set(curve.index) == {"ka", "kb", "d0", "sigma"}
    ka = curve.loc["ka"]
    assert ka["q05"] <= ka["mean"] <= ka["q95"] and 3.4e3 <= ka["map"] <= 3.5e4
    assert ka["mean_phys"] == pytest.approx(ka["mean"] * 1790.92e-6, rel=1e-3)  # E [MPa]
    assert curve.loc["d0", "physical_unit"] == "nm" and curve.loc["kb", "physical_unit"] == "k_BT"
    assert 0 <= ka["coverage_90"] <= 1 and ka["crps"] > 0 and ka["crps_unit"] == "nN"
    assert "population (new bubble)" in set(df["dataset"]) and "hyperparameters" in set(df["dataset"])
    ess = pd.read_csv(run_dir / "ess.csv")
    assert len(ess) == len(diameters) and (ess["ess_median"] >= 1).all()
    report = (run_dir / "report.md").read_text()
    assert "SYNTHETIC" in report and "ess.csv" in report and "figures/fit.png" in report
    assert "published Korali phase 3: population prior over p(ψ | all data); tempered from each dataset's phase-1 " \
           "draws" in report
    # the default asks for the networks over the diameter; the synthetic bundle has none, so its file served
    assert "- surrogates: the networks over the diameter (fast)" in report
    assert "  - definity_compression_2.1um: per-diameter file compression_2.1um.npz" in report
    for name in ("fit", "ka_kb", "population"):
        assert (run_dir / "figures" / f"{name}.png").stat().st_size > 10_000
    # NetCDF phase files open with ArviZ and carry the evidence and the config hash
    import arviz as az

    idata = az.from_netcdf(str(run_dir / "phase2.nc"))
    assert np.isfinite(float(idata.posterior.attrs["log_evidence"]))
    assert idata.posterior.attrs["config_hash"] == manifest["phases"]["phase2"]["config_hash"]
    _check_arviz_groups(run_dir, diameters)
    assert np.isfinite(ess["pareto_k"]).all() and "Pareto k" in report

    # the CLI with the same settings reuses every phase and prints the summary table
    args = ["--agent", "definity", "--workflow", "reduced", "--bundle", synthetic_bundle, "--population", 120,
            "--phase2-samples", 120, "--mcmc-steps", 3, "--out", out, "--no-figures"]
    for c in CURVES[which]:
        args += ["--curve", c]
    r = _cli(*args)
    assert r.exit_code == 0, r.output
    assert "reused phases: phase1_definity_compression_2.1um" in r.output and "compression_2.1um" in r.output
    assert "E [MPa]" in r.output and "coverage" in r.output
    assert "surrogates: definity: definity_compression_2.1um: per-diameter file compression_2.1um.npz" in r.output

    # a changed setting invalidates exactly the dependent phases: a new phase-2 sample size keeps phase 1
    cfg2 = CalibrationConfig(**{**config.__dict__, "phase2_samples": 100, "figures": False})
    from bubblecal.workflows.calibrate import PhaseStore, bundle_hashes, phase_hashes

    plan2 = make_plan(cfg2)
    h_old = {k: v["config_hash"] for k, v in manifest["phases"].items()}
    h_new = phase_hashes(plan2.agents[0], cfg2, bundle_hashes(plan2.bundle))
    assert all(h_new[k] == h_old[k] for k in h_old if k.startswith("phase1"))
    assert h_new["phase2"] != h_old["phase2"] and all(h_new[k] != h_old[k] for k in h_old if k.startswith("phase3"))
    assert PhaseStore(run_dir).manifest["phases"].keys() == manifest["phases"].keys()

    # --phase3 exact: phases 1 and 2 are reused, phase 3 reruns with leave-one-out ψ weights
    r = _cli(*args, "--phase3", "exact")
    assert r.exit_code == 0, r.output
    assert "leave-one-out importance ESS" in r.output, r.output
    exact = json.loads((run_dir / "manifest.json").read_text())["phases"]
    assert all(exact[k]["config_hash"] == h_old[k] for k in h_old if not k.startswith("phase3"))
    assert all(exact[k]["config_hash"] != h_old[k] for k in h_old if k.startswith("phase3"))

    # phase 3 started from phase 1's draws (the default): its stage 0 holds phase 1's log evidence; with
    # --phase3-start prior (Korali's path from the uniform prior) it starts at 0, and phase 3 alone reruns
    def first_log_z(phase):
        import arviz as az

        return float(az.from_netcdf(run_dir / f"{phase}.nc").sample_stats["stage_log_evidence"].values.ravel()[0])

    for k in (k for k in exact if k.startswith("phase3")):
        assert first_log_z(k) == pytest.approx(exact[k.replace("phase3", "phase1")]["log_evidence"], abs=1e-4)
    r = _cli(*args, "--phase3-start", "prior")
    assert r.exit_code == 0, r.output
    korali = json.loads((run_dir / "manifest.json").read_text())["phases"]
    assert all(korali[k]["config_hash"] == h_old[k] for k in h_old if not k.startswith("phase3"))
    assert all(korali[k]["config_hash"] not in (h_old[k], exact[k]["config_hash"]) for k in h_old
               if k.startswith("phase3"))
    assert all(first_log_z(k) == 0.0 for k in korali if k.startswith("phase3"))


def _check_arviz_groups(run_dir, diameters):
    """Every phase file: the ArviZ groups, named dims, units, versions; az.loo runs on it."""
    import arviz as az

    for path in sorted(run_dir.glob("phase*.nc")):
        idata = az.from_netcdf(str(path))
        assert {"posterior", "sample_stats", "log_likelihood"} <= set(idata.groups()), path.name
        for group in idata.groups():
            ds = getattr(idata, group)
            assert not any("_dim_" in d for d in ds.dims), (path.name, group, dict(ds.sizes))
            assert ds.attrs["bubblecal_idata_format"] == 2 and "numpyro_version" in ds.attrs
        loo = az.loo(idata)
        assert np.isfinite(loo["elpd_loo"]) and np.isfinite(loo["pareto_k"]).all(), path.name
        if path.name.startswith(("phase1_", "phase3_")):
            assert {"observed_data", "constant_data"} <= set(idata.groups())
            assert idata.log_likelihood["y"].dims == ("chain", "draw", "points")
            assert idata.observed_data["y"].attrs["units"] == "DPD force"
            assert idata.constant_data["loading"].attrs["units"] == "DPD length"
            assert idata.constant_data["diameter_um"].attrs["units"] == "um"
            assert idata.posterior["ka"].attrs["units"].startswith("DPD 2-D modulus")
        if path.name.startswith("phase1_"):  # phase 3's tempered total also holds the population-prior factor
            # the pointwise log likelihood is the sampler's: it sums to the stored total of every draw
            np.testing.assert_allclose(idata.log_likelihood["y"].sum("points"), idata.sample_stats["loglik"],
                                       rtol=1e-4, atol=1e-2)
    p2 = az.from_netcdf(str(run_dir / "phase2.nc"))
    assert p2.log_likelihood["population_likelihood"].dims == ("chain", "draw", "datasets")
    assert p2.log_likelihood.sizes["datasets"] == len(diameters)


@pytest.mark.slow
def test_netcdf_export_leaves_the_draws_of_the_npz_run(tmp_path, synthetic_bundle):
    """Same seed: the NetCDF run (ArviZ export) and the .npz run (no export) hold the same draws, log Z and
    summaries (the referee of behaviour-preserving changes, benchmarks/compare_calibrations.py, on both)."""
    from bubblecal.workflows.calibrate import read_phase

    kw = dict(agents=("definity",), workflow="reduced", bundle=synthetic_bundle, population=120, phase2_samples=120,
              predictive_samples=200, num_mcmc_steps=3, curves=CURVES["one"], figures=False)
    run_calibration(make_plan(CalibrationConfig(out=tmp_path / "nc", **kw)))
    run_calibration(make_plan(CalibrationConfig(out=tmp_path / "npz", netcdf=False, **kw)))
    a, b = tmp_path / "nc" / "definity" / "reduced", tmp_path / "npz" / "definity" / "reduced"
    for path in sorted(a.glob("phase*.nc")):
        (ra, la), (rb, lb) = read_phase(path), read_phase(b / f"{path.stem}.npz")
        assert ra.log_evidence == rb.log_evidence and set(ra.samples) == set(rb.samples)
        assert all(np.array_equal(ra.samples[k], rb.samples[k]) for k in ra.samples) and np.array_equal(la, lb)
    sa, sb = pd.read_csv(a / "summary.csv"), pd.read_csv(b / "summary.csv")
    pd.testing.assert_frame_equal(sa, sb)


@pytest.mark.slow
def test_joint_nuts_run(tmp_path, synthetic_bundle):
    """--sampler nuts: the joint model, the same summaries (one curve, short chains)."""
    config = CalibrationConfig(agents=("definity",), workflow="reduced", sampler="nuts", bundle=synthetic_bundle,
                               out=tmp_path, nuts_samples=100, nuts_warmup=100, nuts_chains=1,
                               predictive_samples=100, curves=("definity_compression_2.9um",))
    said = []
    (res,) = run_calibration(make_plan(config), progress=said.append)
    df = pd.read_csv(tmp_path / "definity" / "reduced" / "summary.csv")
    assert {"ka", "kb", "d0", "sigma"} <= set(df[df["dataset"] == "definity_compression_2.9um"]["parameter"])
    assert (tmp_path / "definity" / "reduced" / "joint_nuts.nc").is_file() and res.joint.diagnostics
    # 100 draws of one chain cannot reach a bulk ESS of 400: the run and the report say the chains did not converge
    assert res.joint.convergence_note is not None and "NUTS did not converge" in res.joint.convergence_note
    assert any("NUTS did not converge" in m and "--sampler tmcmc" in m for m in said)
    assert "did not converge" in (tmp_path / "definity" / "reduced" / "report.md").read_text()
    import arviz as az

    idata = az.from_netcdf(str(tmp_path / "definity" / "reduced" / "joint_nuts.nc"))
    assert idata.posterior.sizes["chain"] == 1 and idata.posterior["ka"].dims == ("chain", "draw", "curves")
    assert idata.sample_stats["diverging"].dims == ("chain", "draw") and "lp" in idata.sample_stats
    assert np.isfinite(az.loo(idata)["elpd_loo"])
    (again,) = run_calibration(make_plan(config))  # reused: the chains read back concatenated
    assert all(np.array_equal(again.joint.samples[k], res.joint.samples[k]) for k in res.joint.samples)


def test_gpu_padding_groups_curves_by_network_shape_and_keeps_each_density(tmp_path):
    """--device gpu pads the curves of one network shape to one length (shared compiled programs); every
    padded dataset has the log density of its unpadded curve."""
    import jax
    import numpy as np

    from bubblecal.inference.tmcmc._flat_model import FlatModel
    from bubblecal.workflows.calibrate.run import _dataset_objects

    plan = make_plan(CalibrationConfig(agents=("sonovue",), population=200, out=tmp_path / "o"),
                     check_likelihoods=False)
    (ap,) = plan.agents
    plain, padded = _dataset_objects(ap, pad=False), _dataset_objects(ap, pad=True)
    n = len(ap.curves)
    groups = {}
    for d, curve in zip(padded[:n], ap.curves, strict=True):
        x, _, sur, _ = d.args
        mask = d.kwargs["mask"]
        assert mask.sum() == len(curve.x) and np.all(mask[: len(curve.x)])
        groups.setdefault(tuple(np.shape(w) for w in sur.weights), set()).add(len(x))
    assert all(len(lengths) == 1 for lengths in groups.values())  # one length per network shape
    for a, b in zip(plain[:n], padded[:n], strict=True):
        fa, fb = FlatModel(a.model, a.args, a.kwargs), FlatModel(b.model, b.args, b.kwargs)
        pts = jax.random.normal(jax.random.PRNGKey(0), (6, fa.dim))
        np.testing.assert_allclose(np.asarray(jax.vmap(fb.log_terms)(pts)), np.asarray(jax.vmap(fa.log_terms)(pts)),
                                   rtol=1e-5, atol=1e-3)
    # curves of one shape share a signature: one compiled program
    sigs = [FlatModel(d.model, d.args, d.kwargs).signature for d in padded[:n]]
    assert len(set(sigs)) == len(groups)
