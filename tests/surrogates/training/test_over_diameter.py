"""One mechanical network over the diameter: inputs (logged moduli), training with leave-diameters-out, file versions
2 and 3, binding.

Known-answer synthetic curves (closed-form shell law, no noise) at four sizes; tiny networks and few epochs (the
assertions are about the plumbing: which curves train, what the file holds, what a bound surrogate computes).
"""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from bubblecal.models.traced import TracedSurrogate
from bubblecal.surrogates import (
    OutOfDomainError,
    SurrogateFormatError,
    load,
    load_bundle,
    network_inputs,
    radius_of_diameter,
    response_scale,
    write_bundle,
    x_per_size,
)
from bubblecal.surrogates.training import (
    DatasetError,
    SweepConfig,
    TrainConfig,
    TrainingSet,
    checkpoint_key,
    diameter_bands,
    export_sweep,
    make_synthetic,
    run_sweep,
)

DIAMETERS = (2.0, 3.0, 4.0, 5.0)


def several_sizes(setup: str, n: int = 24) -> TrainingSet:
    """Synthetic curves at four sizes; compression displacements scale with the size (fractions 0-0.2 of D)."""
    parts = []
    for k, d in enumerate(DIAMETERS):
        r = radius_of_diameter(d)
        x = np.linspace(0.0, 0.4 * r, 8) if setup == "compression" else None
        parts.append(make_synthetic(n, setup, radius_dpd=r, noise=0.0, seed=k, x=x))
    return TrainingSet(setup=setup, params=np.concatenate([p.params for p in parts]),
                       radius_dpd=np.concatenate([p.radius_dpd for p in parts]),
                       x=np.concatenate([p.x for p in parts]), y=np.concatenate([p.y for p in parts]),
                       curve_id=[f"{d:g}:{i}" for d in DIAMETERS for i in range(n)], source="synthetic sizes")


def midpoint_sizes(n: int = 4) -> TrainingSet:
    """Compression curves of the same law at the midpoints of :func:`several_sizes`' loading intervals."""
    parts = []
    for k, d in enumerate(DIAMETERS):
        r = radius_of_diameter(d)
        x = np.linspace(0.0, 0.4 * r, 8)
        parts.append(make_synthetic(n, "compression", radius_dpd=r, noise=0.0, seed=50 + k, x=0.5 * (x[:-1] + x[1:])))
    return TrainingSet(setup="compression", params=np.concatenate([p.params for p in parts]),
                       radius_dpd=np.concatenate([p.radius_dpd for p in parts]),
                       x=np.concatenate([p.x for p in parts]), y=np.concatenate([p.y for p in parts]),
                       curve_id=[f"mid{i}" for i in range(n * len(DIAMETERS))], source="midpoints")


CFG = dict(widths=(16,), depths=(2,), min_curves=2, seed=0,
           train=TrainConfig(max_epochs=25, batch_size=128, lr=3e-3, threads=1))


def test_inputs_and_scales():
    p = np.array([[5000.0, 300.0, 1.0, 2.0, 0.1, 0.2]] * 2)
    u = network_inputs("diameter", p, np.array([0.1, 0.2]), 3.0)
    assert u.shape == (2, 8) and np.all(u[:, 7] == 3.0) and np.all(u[:, 6] == [0.1, 0.2])
    assert network_inputs("raw", p, 0.5).shape == (2, 7)
    r = radius_of_diameter(3.0)
    assert r == pytest.approx(6.0)  # 0.25 um DPD length
    np.testing.assert_allclose(response_scale("diameter", "compression", p, 3.0), 5000.0 * r)
    np.testing.assert_allclose(response_scale("diameter", "indentation", p, 3.0), r)
    assert response_scale("raw", "compression", p) == 1.0
    assert x_per_size("compression", 1.2, 3.0) == pytest.approx(0.1)
    with pytest.raises(ValueError, match="needs diameter_um"):
        network_inputs("diameter", p, 0.1)
    # logged moduli: log k_a and log k_b in their columns, the rest as given, in NumPy and in JAX alike
    logged = network_inputs("diameter", p, np.array([0.1, 0.2]), 3.0, log_inputs=("kb", "ka"))
    np.testing.assert_allclose(logged[:, :2], np.log(p[:, :2]))
    np.testing.assert_array_equal(logged[:, 2:], u[:, 2:])
    np.testing.assert_allclose(np.asarray(network_inputs("diameter", jnp.asarray(p), jnp.asarray([0.1, 0.2]), 3.0,
                                                         xp=jnp, log_inputs=("ka", "kb"))), logged, rtol=1e-6)
    np.testing.assert_allclose(network_inputs("raw", p, 0.5, log_inputs=("kb",))[:, 1], np.log(300.0))
    with pytest.raises(ValueError, match=r"log_inputs may hold \['ka', 'kb'\], got \['b1'\]"):
        network_inputs("raw", p, 0.5, log_inputs=("b1",))


def test_training_set_points_over_the_diameter():
    ts = several_sizes("indentation", n=5)
    u, t, curve, scale = ts.network_points("diameter")
    np.testing.assert_allclose(np.unique(u[:, 7]), DIAMETERS)
    np.testing.assert_allclose(t * scale, ts.y.reshape(-1)[ts.point_mask().reshape(-1)])
    with pytest.raises(DatasetError, match="several radii"):
        ts.check_trainable()
    ts.check_trainable(several_sizes=True)
    with pytest.raises(DatasetError, match="one radius"):
        ts.subset(np.arange(5)).check_trainable(several_sizes=True)


def test_sweep_config_checks_bands():
    with pytest.raises(ValueError, match="needs inputs='diameter'"):
        SweepConfig(ldo_bands=((2.0, 3.0),))
    with pytest.raises(ValueError, match="lo <= hi"):
        SweepConfig(inputs="diameter", ldo_bands=((3.0, 2.0),))
    with pytest.raises(ValueError, match="inputs must be one of"):
        SweepConfig(inputs="log")
    raw = SweepConfig(**CFG)
    wide = SweepConfig(**CFG, inputs="diameter", ldo_bands=((3.0, 3.0),))
    assert raw.log_inputs == () and wide.log_inputs == ("ka", "kb")  # the defaults per input kind
    assert "inputs" not in checkpoint_key("h", (16, 16), raw)  # per-diameter checkpoints keep their key
    assert "log_inputs" not in checkpoint_key("h", (16, 16), raw)
    assert checkpoint_key("h", (16, 16), wide)["ldo_bands"] == [[3.0, 3.0]]
    assert checkpoint_key("h", (16, 16), wide)["log_inputs"] == ["ka", "kb"]
    linear = SweepConfig(**CFG, inputs="diameter", ldo_bands=((3.0, 3.0),), log_inputs=())
    assert "log_inputs" not in checkpoint_key("h", (16, 16), linear)  # linear inputs never reuse logged weights
    assert SweepConfig(**CFG, log_inputs=("kb", "ka", "kb")).log_inputs == ("ka", "kb")
    with pytest.raises(ValueError, match=r"SweepConfig\.log_inputs may hold"):
        SweepConfig(**CFG, log_inputs=("mu",))
    np.testing.assert_array_equal(diameter_bands([2.0, 3.0, 3.05, 4.0], ((2.9, 3.1),)), [False, True, True, False])


@pytest.fixture(scope="module", params=["compression", "indentation"])
def swept(request, tmp_path_factory):
    ts = several_sizes(request.param)
    res = run_sweep(ts, SweepConfig(**CFG, inputs="diameter", ldo_bands=((3.0, 3.0),)), progress=False)
    path = export_sweep(res, tmp_path_factory.mktemp("wide") / f"{request.param}.npz")
    return ts, res, path


def test_bands_never_train_and_are_scored(swept):
    ts, res, _ = swept
    assert np.all(res.ldo_set.diameters_um == pytest.approx(3.0))
    assert res.ldo_set.n_curves == 24
    assert not np.any(np.isclose(res.train_set.diameters_um, 3.0))
    assert not np.any(np.isclose(res.holdout_set.diameters_um, 3.0))
    row = res.best
    assert row["ldo_n_scored"] == 24 and np.isfinite(row["ldo_median"])
    assert "LDO median" in res.markdown() and "one network over the diameter" in res.markdown()


def test_file_version_3_round_trip(swept):
    ts, res, path = swept
    sur = load(path)
    md = sur.metadata
    assert sur.over_diameter and md["inputs"] == "diameter" and md["input_names"][-1] == "diameter_um"
    assert sur.log_inputs == ("ka", "kb") and md["log_inputs"] == ["ka", "kb"] and "log_inputs=ka,kb" in repr(sur)
    assert "ka, kb as natural logarithms" in res.markdown()
    assert sur.diameter_range_um == pytest.approx((2.0, 5.0))
    assert md["ldo_score"] == pytest.approx(res.best["ldo_median"]) and md["ldo_bands_um"] == [[3.0, 3.0]]
    with np.load(path) as npz:
        assert int(npz["format_version"]) == 3
    # the exported JAX function is the trained network times the size scale
    h = res.holdout_set
    for i in range(3):
        y = np.asarray(sur(h.params[i], h.x[i], h.diameters_um[i]))
        np.testing.assert_allclose(y, res.predict(h, i, h.x[i]), rtol=2e-5, atol=1e-6 * np.abs(y).max())
        bound = sur.at_diameter(h.diameters_um[i])
        np.testing.assert_array_equal(np.asarray(bound(h.params[i], h.x[i])), y)
        assert bound.radius_dpd == pytest.approx(radius_of_diameter(h.diameters_um[i]))


def test_linear_moduli_keep_file_version_2(tmp_path):
    ts = several_sizes("indentation", n=8)
    res = run_sweep(ts, SweepConfig(**CFG, inputs="diameter", ldo_bands=((3.0, 3.0),), log_inputs=()),
                    progress=False)
    sur = load(export_sweep(res, tmp_path / "linear.npz"))
    assert sur.log_inputs == () and "log_inputs" not in sur.metadata
    with np.load(tmp_path / "linear.npz") as npz:
        assert int(npz["format_version"]) == 2
        np.testing.assert_allclose(npz["in_mean"][:2], ts.params[:, :2].mean(axis=0), rtol=0.2)  # linear moduli
    h = res.holdout_set
    y = np.asarray(sur(h.params[0], h.x[0], h.diameters_um[0]))
    np.testing.assert_allclose(y, res.predict(h, 0, h.x[0]), rtol=2e-5, atol=1e-6 * np.abs(y).max())


def test_bound_surrogate_domain(swept):
    ts, _, path = swept
    sur = load(path)
    with pytest.raises(ValueError, match="needs diameter_um"):
        sur(ts.params[0], ts.x[0])
    with pytest.raises(OutOfDomainError, match=r"diameter 6\.5 um outside its trained range \[2, 5\]"):
        sur.at_diameter(6.5)
    bound = sur.at_diameter(3.7)  # between trained sizes: inside the box
    p, x = ts.params[0], ts.x[0] * 3.7 / ts.diameters_um[0] if ts.setup == "compression" else ts.x[0]
    assert bound.check_domain(p, x, action="raise").all()
    with pytest.raises(OutOfDomainError, match="diameter_um: 6.5"):
        sur.check_domain(p, x, diameter_um=6.5, action="raise")
    if ts.setup == "compression":  # the loading range is per size: a 2 um curve's travel at 5 um is inside
        with pytest.raises(OutOfDomainError, match="displacement / diameter"):
            bound.check_domain(p, 2 * x, action="raise")


def test_loading_range_at_a_diameter(swept):
    """The per-size training range back in the curve's own units: the largest trained x at each size."""
    ts, _, path = swept
    sur = load(path)
    for d in (2.0, 5.0):
        lo, hi = sur.loading_range(d)
        xmax = np.nanmax(ts.x[np.isclose(ts.diameters_um, d)])
        assert hi == pytest.approx(xmax, rel=1e-9) and lo == pytest.approx(0.0, abs=1e-12)
        assert sur.at_diameter(d).loading_range() == (lo, hi)
    if ts.setup == "compression":  # displacements scale with the size, forces do not
        assert sur.loading_range(5.0)[1] == pytest.approx(2.5 * sur.loading_range(2.0)[1])
    else:
        assert sur.loading_range(5.0) == sur.loading_range(2.0)
    with pytest.raises(ValueError, match="needs diameter_um"):
        sur.loading_range()


def test_bad_version_2_metadata_is_named(swept, tmp_path):
    _, _, path = swept
    with np.load(path) as npz:
        arrays = {k: npz[k] for k in npz.files}
    md = json.loads(str(arrays["metadata"]))
    md["diameter_range_um"] = [5.0, 2.0]
    np.savez(tmp_path / "bad.npz", **{**arrays, "metadata": np.array(json.dumps(md))})
    with pytest.raises(SurrogateFormatError, match=r"bad\.npz: metadata field 'diameter_range_um'"):
        load(tmp_path / "bad.npz")
    del md["response_scale"]
    np.savez(tmp_path / "bad2.npz", **{**arrays, "metadata": np.array(json.dumps(md))})
    with pytest.raises(SurrogateFormatError, match="lacks key.*response_scale"):
        load(tmp_path / "bad2.npz")


def test_bad_log_inputs_metadata_is_named(swept, tmp_path):
    _, _, path = swept
    with np.load(path) as npz:
        arrays = {k: npz[k] for k in npz.files}
    good = json.loads(str(arrays["metadata"]))

    def write(name, md, version=3):
        np.savez(tmp_path / name, **{**arrays, "metadata": np.array(json.dumps(md)),
                                     "format_version": np.array(version)})
        return tmp_path / name

    for value in (["kb", "ka"], ["b1"], "ka", ["ka", "ka"]):
        with pytest.raises(SurrogateFormatError, match=r"metadata field 'log_inputs' must list names"):
            load(write("order.npz", {**good, "log_inputs": value}))
    ranges = {**good["param_ranges"], "kb": [0.0, 70000.0]}
    with pytest.raises(SurrogateFormatError, match=r"'param_ranges' of the logged input 'kb' must start above 0"):
        load(write("zero.npz", {**good, "param_ranges": ranges}))
    # a version-2 reader would feed such a file linear moduli: the version must say that they are logged
    with pytest.raises(SurrogateFormatError, match=r"'format_version' 2 does not match .* 'log_inputs'"):
        load(write("v2.npz", good, version=2))
    with pytest.raises(SurrogateFormatError, match=r"'format_version' 3 does not match"):
        load(write("v3.npz", {k: v for k, v in good.items() if k != "log_inputs"}))


def test_bundle_binds_the_diameter_and_shares_one_trace(swept, tmp_path):
    ts, _, path = swept
    write_bundle(tmp_path / "b", [path])
    b = load_bundle(tmp_path / "b")
    assert ts.setup in b.over_diameter and not b.surrogates
    s37, s42 = b.get(ts.setup, 3.7), b.get(ts.setup, 4.2)
    assert s37.diameter_um == 3.7 and s42.diameter_um == 4.2
    with pytest.raises(KeyError, match="over the diameter"):
        b.get(ts.setup, 7.0)
    traces = []

    @jax.jit
    def f(sur, p, x):
        traces.append(1)
        return sur(p, x)

    p, x = jnp.asarray(ts.params[0]), jnp.asarray(ts.x[0])
    for s in (s37, s42):
        np.testing.assert_allclose(np.asarray(f(TracedSurrogate.wrap(s), p, x)), np.asarray(s(p, x)), rtol=1e-6)
    assert len(traces) == 1  # the diameter is traced data: bubbles of any size share one compiled program


def test_cli_trains_one_network_over_the_diameter(tmp_path):
    from typer.testing import CliRunner

    from bubblecal.surrogates.training import write_published
    from bubblecal.workflows.cli import app

    csv, off = tmp_path / "sizes.csv", tmp_path / "midpoints.csv"
    write_published(several_sizes("compression", n=10), csv)
    write_published(midpoint_sizes(), off)
    run = CliRunner().invoke(app, ["surrogates", "train", str(csv), "--setup", "compression", "--over-diameter",
                                   "--ldo-bands", "3.0-3.0", "--no-sweep", "--width", "8", "--depth", "1",
                                   "--max-epochs", "3", "--quiet", "--n-points", "8",
                                   "--offgrid", str(off), "--out", str(tmp_path / "out")])
    assert run.exit_code == 0, run.output
    sur = load(tmp_path / "out" / "compression_2-5um.npz")
    assert sur.over_diameter and sur.metadata["ldo_bands_um"] == [[3.0, 3.0]] and sur.log_inputs == ("ka", "kb")
    assert "onnx_vs_jax_max_rel_diff" in run.output  # the ONNX graph takes the logged moduli as exported
    assert sur.metadata["offgrid_score"] > 0 and "off the grid" in run.output
    # an off-grid file the filter keeps nothing of (another protocol's table read as compression), or none at all
    write_published(several_sizes("indentation", n=3), tmp_path / "ind.csv")
    for bad_file, message in ((tmp_path / "ind.csv", "ind.csv: no off-grid curve to score"),
                              (tmp_path / "missing.csv", "missing.csv")):
        bad = CliRunner().invoke(app, ["surrogates", "train", str(csv), "--setup", "compression", "--over-diameter",
                                       "--no-sweep", "--width", "8", "--depth", "1", "--max-epochs", "2",
                                       "--no-onnx", "--quiet", "--n-points", "8", "--offgrid", str(bad_file),
                                       "--out", str(tmp_path / "bad")])
        assert bad.exit_code == 1 and message in bad.output, bad.output
    bad = CliRunner().invoke(app, ["surrogates", "train", str(csv), "--setup", "compression", "--diameter", "2",
                                   "--over-diameter", "--out", str(tmp_path / "o2")])
    assert bad.exit_code == 2 and "not both" in bad.output
    bad = CliRunner().invoke(app, ["surrogates", "train", str(csv), "--setup", "compression", "--over-diameter",
                                   "--log-inputs", "ka,mu", "--out", str(tmp_path / "o3")])
    flat = " ".join(bad.output.replace("│", " ").split())  # the message as one line, out of its box
    assert bad.exit_code == 2 and "--log-inputs must be 'auto', 'none' or names from ['ka', 'kb']" in flat, flat


def test_off_grid_curves_take_part_in_the_selection(tmp_path):
    from bubblecal.surrogates.training import selection_score

    ts, off = several_sizes("compression"), midpoint_sizes()
    cfg = SweepConfig(**{**CFG, "widths": (4, 16), "depths": (1,)}, inputs="diameter", ldo_bands=((3.0, 3.0),))
    res = run_sweep(ts, cfg, progress=False, offgrid=off)
    assert all(r["offgrid_n_scored"] == 16 and np.isfinite(r["offgrid_median"]) for r in res.rows)
    assert res.best_index == min(range(2), key=lambda i: (selection_score(res.rows[i]), res.rows[i]["n_params"]))
    assert "off-grid median" in res.markdown() and "midpoints" in res.markdown()
    md = load(export_sweep(res, tmp_path / "c.npz")).metadata
    assert md["offgrid_score"] == pytest.approx(res.best["offgrid_median"])
    assert [r["offgrid_median"] for r in md["training"]["sweep"]] == [r["offgrid_median"] for r in res.rows]
    # the worst of the three medians decides
    assert selection_score({"holdout_median": 0.1, "ldo_median": 0.2, "offgrid_median": 0.5}) == 0.5
    assert selection_score({"holdout_median": 0.3}) == 0.3
    with pytest.raises(DatasetError, match="off-grid curves are indentation"):
        run_sweep(ts, cfg, progress=False, offgrid=several_sizes("indentation", n=2))
    with pytest.raises(DatasetError, match="midpoints: no off-grid curve to score"):
        run_sweep(ts, cfg, progress=False, offgrid=off.subset(np.zeros(off.n_curves, bool)))
    assert off.subset(np.zeros(off.n_curves, bool)).x.shape == (0, 7)  # an empty selection keeps its points
