"""Failure-truncated prefixes: filter_curves(keep_failed_prefix=True) and NaN tails downstream."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bubblecal.surrogates.training import DatasetError, filter_curves, leading_finite, make_synthetic

M = 15  # loading points of the synthetic indentation curves (force 0..6000 DPD)
N = 30


def _store_like_set():
    """30 synthetic indentation curves (3.19 um) with store statuses and NaN tails like the DPD campaigns.

    curve  status     response                                    with keep_failed_prefix (min 5)
    0      ruptured   finite 0..12, NaN 13..14                   kept: points 0..11 (12)
    1      failed     finite 0..7, NaN 8..14                     kept: points 0..6 (7)
    2      ruptured   NaN at 5 and 12..14 (interior NaN)         prefix_invalid
    3      failed     finite 0..4, NaN 5..14                     prefix_too_short (4 points left)
    4      unstable   finite 0..9, NaN 10..14                    status (unstable is never kept)
    5      ruptured   fully finite (failure point unknown)       prefix_invalid
    6      invalid    finite 0..9, NaN 10..14                    status
    7      failed     +inf at 10, NaN 11..14                     prefix_invalid
    8      ruptured   drop of 70 % at 6..8, NaN 10..14           rupture_drop (checked on the prefix)
    9      ruptured   last finite point 9 collapses to 0, NaN    kept: points 0..8 (9); the collapse is dropped
    10-29  ok         finite                                     kept
    """
    ts = make_synthetic(N, "indentation", radius_dpd=6.38, noise=0.0, seed=11)
    assert ts.n_points == M
    status = np.full(N, "ok", dtype=object)
    status[[0, 2, 5, 8, 9]] = "ruptured"
    status[[1, 3, 7]] = "failed"
    status[4] = "unstable"
    status[6] = "invalid"
    ts.status = status.astype(str)
    ts.y[0, 13:] = np.nan
    ts.y[1, 8:] = np.nan
    ts.y[2, 5] = np.nan
    ts.y[2, 12:] = np.nan
    ts.y[3, 5:] = np.nan
    ts.y[4, 10:] = np.nan
    ts.y[6, 10:] = np.nan
    ts.y[7, 10] = np.inf
    ts.y[7, 11:] = np.nan
    ts.y[8, 6:9] = 0.3 * ts.y[8, 5]
    ts.y[8, 10:] = np.nan
    ts.y[9, 9] = 0.0
    ts.y[9, 10:] = np.nan
    return ts


def test_leading_finite():
    y = np.array([[0, 1, 2, np.nan, np.nan], [0, 1, 2, 3, 4], [0, np.nan, 2, np.nan, np.nan],
                  [0, 1, np.inf, np.nan, np.nan], [np.nan] * 5], dtype=float)
    k, tail = leading_finite(y)
    assert k.tolist() == [3, 5, 1, 2, 0]
    assert tail.tolist() == [True, True, False, False, True]


def test_default_is_backward_compatible():
    ts = _store_like_set()
    kept, report = filter_curves(ts)
    assert kept.n_curves == 20 and np.all(kept.status == "ok") and np.all(np.isfinite(kept.y))
    assert report.counts == {"status": 10, "non_finite": 0, "rupture_trailing_zero": 0, "rupture_drop": 0}
    assert report.status_counts == {"failed": 3, "invalid": 1, "ruptured": 5, "unstable": 1}
    assert report.prefix == {} and report.n_prefix_curves == 0 and report.n_points_kept == 20 * M
    assert "prefix" not in str(report)


def test_keep_failed_prefix_counts_and_points():
    ts = _store_like_set()
    y0 = ts.y.copy()
    kept, report = filter_curves(ts, keep_failed_prefix=True)
    assert report.counts == {"status": 2, "non_finite": 0, "prefix_invalid": 3, "prefix_too_short": 1,
                             "rupture_trailing_zero": 0, "rupture_drop": 1}
    assert report.status_counts == {"invalid": 1, "unstable": 1}
    assert set(report.dropped["prefix_invalid"]) == {ts.curve_id[i] for i in (2, 5, 7)}
    assert report.dropped["prefix_too_short"] == [ts.curve_id[3]]
    assert report.dropped["rupture_drop"] == [ts.curve_id[8]]
    assert report.prefix == {
        "ruptured": {"kept": 2, "points": 12 + 9, "invalid": 2, "too_short": 0, "quality": 1},
        "failed": {"kept": 1, "points": 7, "invalid": 1, "too_short": 1, "quality": 0},
    }
    assert report.n_prefix_curves == 3 and report.n_prefix_points == 28
    assert kept.n_curves == report.n_kept == 23
    assert report.n_points_kept == kept.n_valid_points == 20 * M + 28
    # the input is not modified; kept curves keep the (n, 15) layout, NaN in the dropped tail, x on its grid
    np.testing.assert_array_equal(ts.y, y0)
    assert kept.y.shape == (23, M) and np.all(np.isfinite(kept.x))
    ids = list(kept.curve_id)
    for i, n_keep in ((0, 12), (1, 7), (9, 9)):
        row = kept.y[ids.index(ts.curve_id[i])]
        np.testing.assert_array_equal(row[:n_keep], y0[i, :n_keep])
        assert np.all(np.isnan(row[n_keep:]))
    assert "unstable" not in set(kept.status) and "invalid" not in set(kept.status)
    text = str(report)
    assert "failure-truncated prefixes kept: 3 curves, 28 points" in text
    assert "ruptured   kept     2 curves     21 points" in text
    d = report.as_dict()
    assert d["n_prefix_curves"] == 3 and d["n_prefix_points"] == 28 and d["settings"]["keep_failed_prefix"] is True
    json.dumps(d)


def test_min_prefix_points():
    ts = _store_like_set()
    _, r4 = filter_curves(ts, keep_failed_prefix=True, min_prefix_points=4)
    assert r4.prefix["failed"] == {"kept": 2, "points": 11, "invalid": 1, "too_short": 0, "quality": 0}
    assert r4.counts["prefix_too_short"] == 0
    _, r10 = filter_curves(ts, keep_failed_prefix=True, min_prefix_points=10)
    # curves 8 and 9 keep 9 points: too short (checked before the rupture checks)
    assert r10.prefix["ruptured"] == {"kept": 1, "points": 12, "invalid": 2, "too_short": 2, "quality": 0}
    assert r10.prefix["failed"]["kept"] == 0 and r10.prefix["failed"]["too_short"] == 2
    _, r13 = filter_curves(ts, keep_failed_prefix=True, min_prefix_points=13)
    assert r13.n_prefix_curves == 0 and r13.n_kept == 20
    with pytest.raises(ValueError, match="min_prefix_points"):
        filter_curves(ts, keep_failed_prefix=True, min_prefix_points=1)


def test_points_exclude_nan_and_check_trainable():
    ts = _store_like_set()
    kept, _ = filter_curves(ts, keep_failed_prefix=True)
    u, y, idx = kept.points()
    assert u.shape == (20 * M + 28, 7) and y.shape == idx.shape == (20 * M + 28,)
    assert np.all(np.isfinite(u)) and np.all(np.isfinite(y))
    i0 = list(kept.curve_id).index(ts.curve_id[0])
    np.testing.assert_array_equal(u[idx == i0, 6], ts.x[0, :12])
    assert kept.x_range() == (0.0, 6000.0)
    summary = kept.truncation_summary()
    assert summary == {"n_curves": 23, "n_points": 328, "n_prefix_curves": 3, "n_prefix_points": 28,
                       "prefix_by_status": {"failed": {"curves": 1, "points": 7},
                                            "ruptured": {"curves": 2, "points": 21}}}
    kept.check_trainable(min_curves=20)  # trailing NaN accepted

    bad = kept.subset(np.arange(kept.n_curves))
    bad.y = bad.y.copy()
    bad.y[i0, 3] = np.nan  # interior NaN
    bad.source = "camp.jsonl.gz"
    with pytest.raises(DatasetError, match=r"camp\.jsonl\.gz: field 'y' \(displacement\) of curve .*interior NaN"):
        bad.check_trainable()
    bad.y[i0, 3] = np.inf
    with pytest.raises(DatasetError, match="field 'y'.*infinity"):
        bad.check_trainable()
    bad.y[i0, 3] = kept.y[i0, 3]
    bad.x = bad.x.copy()
    bad.x[i0, 2] = np.nan
    with pytest.raises(DatasetError, match=r"camp\.jsonl\.gz: field 'x' \(force\)"):
        bad.check_trainable()
    bad.x[i0, 2] = kept.x[i0, 2]
    bad.x[i0, 13] = np.nan  # x may be NaN where the response is NaN
    bad.check_trainable()
    bad.params = bad.params.copy()
    bad.params[0, 1] = np.nan
    with pytest.raises(DatasetError, match=r"camp\.jsonl\.gz: field 'params'"):
        bad.check_trainable()


def test_curve_errors_mask_and_skip():
    from bubblecal.surrogates.training import TrainConfig, TrainedMLP, curve_errors, error_summary

    ts = _store_like_set()
    kept, _ = filter_curves(ts, keep_failed_prefix=True)
    hold = kept.subset(np.arange(5))
    hold.y = hold.y.copy()
    hold.y[1, 1:] = np.nan  # one finite point only: skipped
    # a known model: y_hat = constant 0.5 (zero weights, out_mean 0.5)
    model = TrainedMLP(hidden=(2,), weights=[np.zeros((7, 2)), np.zeros((2, 1))], biases=[np.zeros(2), np.zeros(1)],
                       in_mean=np.zeros(7), in_std=np.ones(7), out_mean=np.array([0.5]), out_std=np.ones(1),
                       config=TrainConfig(), seed=0, epochs=0, stop_reason="", best_val_loss=0.0, wall_s=0.0)
    err, pred = curve_errors(model, hold)
    assert pred.shape == (5, M) and np.allclose(pred, 0.5)
    assert np.isnan(err[1]) and np.sum(np.isfinite(err)) == 4
    i0 = list(hold.curve_id).index(ts.curve_id[0])
    y = ts.y[0, :12]
    assert err[i0] == pytest.approx(np.linalg.norm(0.5 - y) / np.linalg.norm(y))
    s = error_summary(err, prefix_mask=~np.all(hold.point_mask(), axis=1))
    assert s["holdout_n_scored"] == 4 and s["holdout_n_skipped"] == 1
    assert s["holdout_median"] == pytest.approx(np.median(err[np.isfinite(err)]))
    assert s["holdout_n_prefix"] == 2  # curves 0 and 1 of the kept set are prefixes; the skipped one not scored
    with pytest.raises(DatasetError, match="no held-out curve"):
        error_summary(np.array([np.nan, np.nan]))


def test_train_export_end_to_end_with_prefixes(tmp_path):
    pytest.importorskip("torch")
    from bubblecal.surrogates import load
    from bubblecal.surrogates.training import SweepConfig, TrainConfig, export_sweep, run_sweep

    ts = _store_like_set()
    kept, report = filter_curves(ts, keep_failed_prefix=True)
    tiny = TrainConfig(max_epochs=5, patience=2, max_reductions=1, batch_size=64)
    res = run_sweep(kept, SweepConfig(widths=(8,), depths=(2,), holdout_frac=0.5, seed=1, train=tiny), progress=False)
    row = res.best
    n_trunc_hold = int(np.sum(~np.all(res.holdout_set.point_mask(), axis=1)))
    n_trunc_train = int(np.sum(~np.all(res.train_set.point_mask(), axis=1)))
    assert n_trunc_hold + n_trunc_train == 3
    assert row["holdout_n_scored"] == res.holdout_set.n_curves and row["holdout_n_skipped"] == 0
    assert row["holdout_n_prefix"] == n_trunc_hold
    assert np.all(np.isfinite(res.holdout_errors))
    assert all(np.isfinite(row[k]) for k in ("holdout_median", "holdout_p90", "holdout_max"))
    assert np.isfinite(res.best_model.in_mean).all() and np.isfinite(res.best_model.out_std).all()
    paths = res.write_report(tmp_path / "rep")
    js = json.loads(paths["json"].read_text())
    assert js["n_points_train"] + js["n_points_holdout"] == 328
    assert js["truncation_train"]["n_prefix_curves"] == n_trunc_train
    npz = export_sweep(res, tmp_path / "indentation_3.2um.npz", nominal_diameter_um=3.2, filter_report=report)
    md = load(npz).metadata
    assert md["n_prefix_curves_train"] == n_trunc_train
    assert md["n_points_train"] == res.train_set.n_valid_points
    assert md["filter"]["n_prefix_curves"] == 3 and md["filter"]["n_prefix_points"] == 28
    assert md["x_range"] == [0.0, 6000.0]


def _write_store(tmp_path, ts):
    from bubblecal.data import CampaignStore, make_record

    store = CampaignStore.create(tmp_path / "camp", fsync=False)
    for i in range(ts.n_curves):
        store.append(make_record(sample_id=f"s{i}", setup=ts.setup,
                                 params=dict(zip(("ka", "kb", "b1", "b2", "a3", "a4"), ts.params[i], strict=True)),
                                 radius_dpd=float(ts.radius_dpd[i]), x=ts.x[i], y=ts.y[i], status=str(ts.status[i]),
                                 seed=i, tier="quasistatic"))
    return tmp_path / "camp"


def test_store_roundtrip_and_cli_default_keeps_prefixes(tmp_path):
    pytest.importorskip("torch")
    from typer.testing import CliRunner

    from bubblecal.surrogates import load
    from bubblecal.surrogates.training import read_dataset
    from bubblecal.workflows.cli_surrogates import app

    ts = _store_like_set()
    ts.status[7] = "failed"
    path = _write_store(tmp_path, ts)
    back = read_dataset(path)
    _, report = filter_curves(back, keep_failed_prefix=True)
    assert report.n_prefix_curves == 3 and report.n_prefix_points == 28

    args = ["train", str(path), "--setup", "indentation", "--diameter", "3.2", "--width", "4", "--depth", "1",
            "--max-epochs", "2", "--no-onnx", "--quiet"]
    runner = CliRunner()
    r = runner.invoke(app, [*args, "--out", str(tmp_path / "on")])
    assert r.exit_code == 0, r.output
    assert "23 kept (328 points)" in r.output and "failure-truncated prefixes kept: 3 curves, 28 points" in r.output
    md = load(tmp_path / "on" / "indentation_3.2um.npz").metadata
    assert md["filter"]["n_prefix_curves"] == 3 and md["filter"]["settings"]["keep_failed_prefix"] is True
    r = runner.invoke(app, [*args, "--no-failed-prefix", "--out", str(tmp_path / "off")])
    assert r.exit_code == 0, r.output
    assert "20 kept (300 points)" in r.output and "prefixes kept" not in r.output
    md = load(tmp_path / "off" / "indentation_3.2um.npz").metadata
    assert md["n_prefix_curves_train"] == 0 and md["filter"]["n_prefix_curves"] == 0
    r = runner.invoke(app, [*args, "--min-prefix-points", "4", "--out", str(tmp_path / "m4")])
    assert r.exit_code == 0, r.output
    assert "24 kept (332 points)" in r.output
