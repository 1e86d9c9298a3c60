"""Architecture sweep (grouped holdout, report) and the `bubblecal surrogates train` command."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from bubblecal.surrogates.training import (
    SweepConfig,
    TrainConfig,
    grouped_holdout,
    make_synthetic,
    run_sweep,
    write_published,
)

pytest.importorskip("torch")
TINY = TrainConfig(max_epochs=6, patience=2, max_reductions=1, batch_size=128)


def test_grouped_holdout_is_seeded_and_disjoint():
    tr, ho = grouped_holdout(50, 0.1, seed=3)
    assert len(ho) == 5 and len(tr) == 45 and not set(tr) & set(ho)
    tr2, ho2 = grouped_holdout(50, 0.1, seed=3)
    assert np.array_equal(ho, ho2)
    assert not np.array_equal(ho, grouped_holdout(50, 0.1, seed=4)[1])


def test_sweep_selects_lowest_and_writes_report(tmp_path):
    ts = make_synthetic(24, "indentation", radius_dpd=6.38, noise=0.01, seed=1)
    res = run_sweep(ts, SweepConfig(widths=(4, 16), depths=(1, 2), train=TINY), progress=False)
    assert len(res.rows) == 4
    scores = [r["holdout_median"] for r in res.rows]
    assert res.score == min(scores) == res.best["holdout_median"]
    # holdout curves are whole curves that training never saw
    assert not set(res.holdout_set.curve_id) & set(res.train_set.curve_id)
    assert res.holdout_set.n_curves + res.train_set.n_curves == 24
    # score = median of per-curve relative L2 on the held-out curves
    err = np.linalg.norm(res.holdout_pred - res.holdout_set.y, axis=1) / np.linalg.norm(res.holdout_set.y, axis=1)
    assert res.score == pytest.approx(np.median(err))
    paths = res.write_report(tmp_path)
    report = json.loads(paths["json"].read_text())
    assert report["selected"]["holdout_median"] == pytest.approx(res.score)
    assert len(report["holdout_curve_ids"]) == res.holdout_set.n_curves
    assert "(selected)" in paths["markdown"].read_text()
    assert paths["plot"].stat().st_size > 1000


def test_cli_train_sweep_exports_validated_surrogate(tmp_path):
    from bubblecal.surrogates import load
    from bubblecal.workflows.cli_surrogates import app

    ts = make_synthetic(25, "compression", noise=0.01, seed=7)
    ts.y[0, -2:] = 0.0  # one ruptured curve, filtered and reported
    data = write_published(ts, tmp_path / "F_Delta.csv")
    out = tmp_path / "out"
    r = CliRunner().invoke(app, ["train", str(data), "--setup", "compression", "--diameter", "2.1", "--sweep",
                                 "--widths", "4,8", "--depths", "1", "--max-epochs", "4", "--patience", "2",
                                 "--out", str(out), "--quiet"])
    assert r.exit_code == 0, r.output
    assert "rupture_trailing_zero" in r.output and "24 kept" in r.output
    summary = json.loads((out / "train_summary.json").read_text())
    assert summary["parity"]["jax_vs_torch_max_rel_diff"] < 1e-5
    assert summary["parity"]["onnx_vs_jax_max_rel_diff"] < 1e-5
    sur = load(out / "compression_2.1um.npz")
    assert sur.holdout_score == pytest.approx(summary["holdout_score"])
    for name in ("sweep_report.md", "sweep_report.json", "heldout_curve.png", "filter_report.json",
                 "compression_2.1um.onnx"):
        assert (out / name).exists(), name


def test_cli_errors_are_clear(tmp_path):
    from bubblecal.workflows.cli_surrogates import app

    ts = make_synthetic(10, "compression", noise=0.01, seed=7)
    data = write_published(ts, tmp_path / "small.csv")
    runner = CliRunner()
    r = runner.invoke(app, ["train", str(data), "--setup", "compression", "--diameter", "2.1", "--sweep",
                            "--out", str(tmp_path / "o")])
    assert r.exit_code == 1 and "small.csv: 10 curve(s)" in r.output and "at least 20" in r.output
    r = runner.invoke(app, ["train", str(data), "--setup", "compression", "--diameter", "3.0",
                            "--out", str(tmp_path / "o")])
    assert r.exit_code == 1 and "radius_dpd" in r.output
    r = runner.invoke(app, ["train", str(data), "--setup", "compression", "--diameter", "2.1",
                            "--curve-weights", "relative", "--out", str(tmp_path / "o")])
    text = " ".join(r.output.replace("│", " ").split())  # the error panel wraps its lines
    assert r.exit_code == 2 and "--curve-weights must be one of ('none', 'capped'), got 'relative'" in text


def test_cli_published_indentation_head_nominal_diameter(shared_reference, tmp_path):
    """The published 3.2 um SonoVue head (radius 6.38, i.e. 3.19 um) through reader, filter, train, export."""
    from bubblecal.surrogates import load
    from bubblecal.workflows.cli_surrogates import app

    out = tmp_path / "o"
    r = CliRunner().invoke(app, ["train", str(shared_reference / "training_head_indentation_3.2um.csv"),
                                 "--setup", "indentation", "--diameter", "3.2", "--width", "4", "--depth", "1",
                                 "--max-epochs", "2", "--no-onnx", "--out", str(out), "--quiet"])
    assert r.exit_code == 0, r.output
    sur = load(out / "indentation_3.2um.npz")
    assert sur.diameter_um == pytest.approx(3.19) and sur.nominal_diameter_um == 3.2
    assert sur.input_names[-1] == "force" and sur.x_range == pytest.approx((0.0, 6000.0))


def test_surrogates_group_registered():
    from bubblecal.workflows import cli

    assert ("surrogates", "bubblecal.workflows.cli_surrogates") in cli.COMMAND_GROUPS


def test_sweep_checkpoints_resume_and_reject_other_recipes(tmp_path):
    from bubblecal.surrogates.training import checkpoint_path

    ts = make_synthetic(24, "compression", noise=0.01, seed=2)
    cfg = SweepConfig(widths=(4, 8), depths=(1,), train=TINY, min_curves=2)
    first = run_sweep(ts, cfg, progress=False, checkpoints=tmp_path)
    files = sorted(p.name for p in tmp_path.glob("arch_*.npz"))
    assert files == ["arch_4x1.npz", "arch_8x1.npz"] and not list(tmp_path.glob("*.part"))
    # an interrupted sweep: one architecture lost; the rerun trains only that one
    checkpoint_path(tmp_path, (8,)).unlink()
    again = run_sweep(ts, cfg, progress=False, checkpoints=tmp_path)
    for a, b in zip(first.models, again.models, strict=True):
        assert all(np.array_equal(x, y) for x, y in zip(a.weights, b.weights, strict=True))
    assert again.models[0].wall_s == first.models[0].wall_s  # reused, not retrained
    assert again.score == first.score
    # another recipe (more epochs) must not reuse them; another device or thread count may
    other = SweepConfig(widths=(4, 8), depths=(1,), train=TrainConfig(max_epochs=7, patience=2, max_reductions=1,
                                                                      batch_size=128), min_curves=2)
    third = run_sweep(ts, other, progress=False, checkpoints=tmp_path)
    assert third.models[0].wall_s != first.models[0].wall_s
    from bubblecal.surrogates.training import checkpoint_key
    k_cpu = checkpoint_key("h", (4,), cfg)
    k_gpu = checkpoint_key("h", (4,), SweepConfig(widths=(4, 8), depths=(1,), min_curves=2,
                                                  train=TrainConfig(max_epochs=6, patience=2, max_reductions=1,
                                                                    batch_size=128, device="cuda", threads=2)))
    assert k_cpu == k_gpu


@pytest.mark.gpu
def test_cuda_graph_training_matches_eager_cuda_and_cpu():
    # same initial weights and batch order on every path; graphs replay the eager step exactly
    import torch

    from bubblecal.surrogates.training import train_mlp

    if not torch.cuda.is_available():
        pytest.skip("no CUDA device")
    rng = np.random.default_rng(0)
    u = rng.uniform(size=(3000, 7))
    y = np.tanh(u @ rng.normal(size=7)) + 0.1 * u[:, 0] ** 2
    base = dict(max_epochs=40, patience=3, max_reductions=1, batch_size=256)  # 2,700 train points: a remainder batch
    cpu = train_mlp(u, y, (32, 32), TrainConfig(**base), progress=False)
    eager = train_mlp(u, y, (32, 32), TrainConfig(**base, device="cuda", cuda_graphs=False), progress=False)
    graph = train_mlp(u, y, (32, 32), TrainConfig(**base, device="cuda"), progress=False)
    assert graph.epochs == eager.epochs
    np.testing.assert_allclose(graph.history["val_loss"], eager.history["val_loss"], rtol=1e-4)
    np.testing.assert_allclose(graph.history["lr"], eager.history["lr"])
    # CPU and GPU differ by rounding only: the same loss curve to a few per cent
    n = min(len(cpu.history["val_loss"]), len(graph.history["val_loss"]), 20)
    np.testing.assert_allclose(graph.history["val_loss"][:n], cpu.history["val_loss"][:n], rtol=0.05)
