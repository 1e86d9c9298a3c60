"""Training, plain-weight export, JAX evaluation (parity with torch and ONNX), domain checks, bundles."""

from __future__ import annotations

import json
import subprocess
import sys
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from bubblecal.surrogates import (
    OutOfDomainError,
    SurrogateDomainWarning,
    SurrogateFormatError,
    load,
    load_bundle,
    write_bundle,
)
from bubblecal.surrogates.training import SweepConfig, TrainConfig, make_synthetic, run_sweep, train_mlp

torch = pytest.importorskip("torch")

TINY = TrainConfig(max_epochs=12, patience=3, max_reductions=1, batch_size=128)


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    from bubblecal.surrogates.training import export_sweep

    ts = make_synthetic(30, "compression", noise=0.01, seed=5)
    res = run_sweep(ts, SweepConfig(widths=(16,), depths=(2,), min_curves=2, train=TINY), progress=False)
    path = export_sweep(res, tmp_path_factory.mktemp("sur") / "compression_2.1um.npz")
    return res, path


def test_metadata_and_attributes(trained):
    res, path = trained
    sur = load(path)
    assert sur.setup == "compression" and sur.diameter_um == pytest.approx(2.1) and sur.radius_dpd == 4.2
    assert sur.param_names == ("ka", "kb", "b1", "b2", "a3", "a4")
    assert sur.param_ranges["ka"] == pytest.approx(tuple(res.train_set.param_ranges()["ka"]))
    assert sur.x_range == pytest.approx((0.0, 1.68))
    assert sur.holdout_score == pytest.approx(res.score)
    assert sur.data_hash == res.data_hash and len(sur.data_hash) == 64
    assert sur.architecture["hidden"] == [16, 16]
    assert sur.metadata["output_units"] == "DPD force"


def test_jax_matches_torch_1e5(trained):
    res, path = trained
    sur = load(path)
    u, _, _ = res.holdout_set.points()
    with torch.no_grad():
        y_t64 = res.best_model.torch_module(torch.float64)(torch.as_tensor(u)).numpy()[:, 0]
        y_t32 = res.best_model.torch_module(torch.float32)(torch.as_tensor(u, dtype=torch.float32)).numpy()[:, 0]
    y_jax = np.asarray(sur(u[:, :6], u[:, 6]))
    scale = np.max(np.abs(y_t64))
    assert np.max(np.abs(y_jax - y_t64)) / scale < 1e-5
    assert np.max(np.abs(y_jax - y_t32)) / scale < 1e-5
    big = np.abs(y_t64) > 0.05 * scale  # pointwise too, away from zero crossings
    np.testing.assert_allclose(y_jax[big], y_t64[big], rtol=1e-5)


def test_onnx_parity_1e5(trained, tmp_path):
    from bubblecal.surrogates.training import export_onnx, onnx_parity

    res, path = trained
    onnx_path = export_onnx(res.best_model, tmp_path / "m.onnx")
    u, _, _ = res.holdout_set.points()
    out = onnx_parity(onnx_path, load(path), u)
    assert out["n"] == u.shape[0] and out["max_rel_diff"] < 1e-5


def test_jit_vmap_grad_and_broadcasting(trained):
    _, path = trained
    sur = load(path)
    rng = np.random.default_rng(0)
    lo = np.array([sur.param_ranges[k][0] for k in sur.param_names])
    hi = np.array([sur.param_ranges[k][1] for k in sur.param_names])
    params = jnp.asarray(lo + rng.random((5, 6)) * (hi - lo))
    x = jnp.linspace(0.1, 1.6, 7)
    grid = sur(params[:, None, :], x[None, :])
    assert grid.shape == (5, 7)
    np.testing.assert_allclose(jax.jit(sur)(params[:, None, :], x), grid, rtol=1e-6)
    np.testing.assert_allclose(jax.vmap(lambda p: sur(p, x))(params), grid, rtol=1e-6)
    assert sur(params[0], x).shape == (7,) and sur(params[0], 0.5).shape == ()
    g = jax.grad(lambda p: jnp.sum(sur(p, x)))(params[0])
    assert g.shape == (6,) and bool(jnp.all(jnp.isfinite(g)))
    with pytest.raises(ValueError, match="last axis of length 6"):
        sur(params[:, :5], x)


def test_domain_mask_warn_raise(trained):
    _, path = trained
    sur = load(path)
    inside = np.array([np.mean(sur.param_ranges[k]) for k in sur.param_names])
    outside = inside.copy()
    outside[1] = sur.param_ranges["kb"][1] * 2
    params = np.stack([inside, outside])
    x = np.array([0.5, 0.5])
    mask = np.asarray(sur.in_training_box(params, x))
    assert mask.tolist() == [True, False]
    assert np.asarray(jax.jit(sur.in_training_box)(params, x)).tolist() == [True, False]
    with pytest.warns(SurrogateDomainWarning, match="kb: 1 of 2 parameter sets outside"):
        sur.check_domain(params, x)
    with pytest.raises(OutOfDomainError, match="displacement: 1 of 1 points outside"):
        sur.check_domain(inside, 5.0, action="raise")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        y, m = sur.evaluate(inside, 0.5)  # inside: no warning
    assert bool(m) and np.isfinite(float(y))


def _rewrite(src, dst, drop=(), **changes):
    with np.load(src) as npz:
        arrays = {k: npz[k] for k in npz.files if k not in drop}
    arrays.update(changes)
    np.savez(dst, **arrays)
    return dst


def test_bad_weight_files_name_file_and_field(trained, tmp_path):
    _, path = trained
    with pytest.raises(SurrogateFormatError, match=r"broken\.npz: missing field 'W_1'"):
        load(_rewrite(path, tmp_path / "broken.npz", drop=("W_1",)))
    with pytest.raises(SurrogateFormatError, match=r"v4\.npz: field .format_version. is 4, this code reads versions"):
        load(_rewrite(path, tmp_path / "v4.npz", format_version=np.array(4)))
    with pytest.raises(SurrogateFormatError, match=r"v2\.npz: field 'format_version' 2 does not match .*'raw'"):
        load(_rewrite(path, tmp_path / "v2.npz", format_version=np.array(2)))
    with pytest.raises(SurrogateFormatError, match="field 'format'"):
        load(_rewrite(path, tmp_path / "other.npz", format=np.array("something-else")))
    with np.load(path) as npz:
        md = json.loads(str(npz["metadata"]))
    del md["data_hash"]
    with pytest.raises(SurrogateFormatError, match="lacks key.*data_hash"):
        load(_rewrite(path, tmp_path / "nohash.npz", metadata=np.array(json.dumps(md))))
    with pytest.raises(SurrogateFormatError, match="'W_0'/'b_0' shapes"):
        load(_rewrite(path, tmp_path / "shape.npz", W_0=np.zeros((6, 16), np.float32)))


def test_training_is_seeded_and_reproducible():
    ts = make_synthetic(20, "indentation", radius_dpd=6.38, noise=0.01, seed=2)
    u, y, _ = ts.points()
    cfg = TrainConfig(max_epochs=4, batch_size=64)
    a = train_mlp(u, y, (8, 8), cfg, seed=3, progress=False)
    b = train_mlp(u, y, (8, 8), cfg, seed=3, progress=False)
    c = train_mlp(u, y, (8, 8), cfg, seed=4, progress=False)
    for wa, wb in zip(a.weights, b.weights, strict=True):
        np.testing.assert_array_equal(wa, wb)
    assert not np.array_equal(a.weights[0], c.weights[0])
    assert len(a.history["val_loss"]) == a.epochs == 4


def test_lr_schedule_stops_after_reductions():
    ts = make_synthetic(20, "compression", noise=0.05, seed=2)
    u, y, _ = ts.points()
    # patience 1 with an impossible improvement threshold: reduce twice, then stop at the next stall
    cfg = TrainConfig(max_epochs=50, patience=1, max_reductions=2, min_rel_improvement=0.99, batch_size=128)
    m = train_mlp(u, y, (4,), cfg, seed=0, progress=False)
    assert m.stop_reason.startswith("plateau after 2")
    assert m.history["lr"][-1] == pytest.approx(1e-5)
    assert m.epochs == 4


def test_bundle_roundtrip(trained, tmp_path):
    from bubblecal.surrogates import AcousticSurrogate

    _, path = trained
    ka = np.linspace(1e3, 2e4, 8)
    ac = AcousticSurrogate.fit({4.68: (ka, np.sqrt(0.5 + 2e-4 * ka))}, name="definity")
    ac_path = ac.save(tmp_path / "acoustic_definity.json")
    bdir = tmp_path / "bundle"
    write_bundle(bdir, [path], {"definity": ac_path}, notes="test")
    b = load_bundle(bdir)
    assert b.keys() == [("compression", pytest.approx(2.1))]
    sur = b.get("compression", 2.1)
    assert sur.data_hash == load(path).data_hash
    assert float(b.acoustic["definity"].f_res(1e4, 4.68)) == pytest.approx(np.sqrt(0.5 + 2.0), rel=1e-5)
    assert b.get("compression", 2.11) is sur  # nearest within 0.025 um
    with pytest.raises(KeyError, match="no compression surrogate at 2.2 um"):
        b.get("compression", 2.2)
    with pytest.raises(KeyError, match="no indentation surrogate at 3.2 um"):
        b.get("indentation", 3.2)
    manifest = json.loads((bdir / "manifest.json").read_text())
    manifest["surrogates"][0]["data_hash"] = "0" * 64
    (bdir / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(SurrogateFormatError, match="data_hash"):
        load_bundle(bdir)


def test_calibration_side_never_imports_torch_or_onnx(trained):
    _, path = trained
    code = ("import sys; from bubblecal.surrogates import load, load_bundle; s = load(sys.argv[1]); "
            "s([1e4, 500, 1, 1, 0, 1], 0.5).block_until_ready(); "
            "bad = [m for m in ('torch', 'onnx', 'onnxruntime') if m in sys.modules]; print(bad); "
            "sys.exit(1 if bad else 0)")
    out = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr
