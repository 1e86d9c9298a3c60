"""Training-data I/O: the published layout (heads in ../shared/reference), filtering, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from bubblecal.surrogates.training import (
    DatasetError,
    filter_curves,
    make_synthetic,
    read_dataset,
    read_published,
    write_published,
)

HEADS = {
    "training_head_compression_2.1um.csv": ("compression", 2.1),
    "training_head_compression_2.9um.csv": ("compression", 2.9),
    "training_head_compression_3.0um.csv": ("compression", 3.0),
    "training_head_indentation_3.2um.csv": ("indentation", 3.19),
    "training_head_indentation_5.8um.csv": ("indentation", 5.76),
}
# curves removed per reason in each published head (16 rows each), with the default criteria
EXPECTED_COUNTS = {
    "training_head_compression_2.1um.csv": {"rupture_trailing_zero": 0, "rupture_drop": 0},
    "training_head_compression_2.9um.csv": {"rupture_trailing_zero": 1, "rupture_drop": 0},
    "training_head_compression_3.0um.csv": {"rupture_trailing_zero": 3, "rupture_drop": 0},
    "training_head_indentation_3.2um.csv": {"rupture_trailing_zero": 0, "rupture_drop": 0},
    "training_head_indentation_5.8um.csv": {"rupture_trailing_zero": 0, "rupture_drop": 0},
}


@pytest.mark.parametrize("name", sorted(HEADS))
def test_published_heads_read_filter_roundtrip(shared_reference, tmp_path, name):
    setup, diameter = HEADS[name]
    ts = read_published(shared_reference / name)
    assert ts.setup == setup
    assert ts.n_curves == 16 and ts.n_points == 15
    assert ts.diameter_um == pytest.approx(diameter, abs=0.01)
    # Yt_Pa = 1790.92 ka in every row
    np.testing.assert_allclose(ts.extra["yt_pa"], 1790.918918 * ts.params[:, 0], rtol=1e-6)
    if setup == "compression":
        np.testing.assert_allclose(ts.x[0], np.arange(15) * 0.12, atol=1e-12)
    else:
        d0 = 2 * np.median(ts.radius_dpd)
        assert ts.extra["initial_diameter_dpd"][0] == pytest.approx(d0)
        assert np.all(ts.x[:, 0] == 0) and np.all(np.diff(ts.x, axis=1) > 0)  # force grid 0..F_max
        assert np.all(np.abs(ts.y[:, 0]) < 0.1)  # displacement starts near 0
        assert np.all(ts.y[:, -1] > ts.y[:, 0])  # and grows with force
    kept, report = filter_curves(ts)
    for reason, count in EXPECTED_COUNTS[name].items():
        assert report.counts[reason] == count, (reason, report)
    assert report.counts["non_finite"] == 0
    assert kept.n_curves == 16 - sum(report.counts.values())
    # round trip through the writer
    out = write_published(ts, tmp_path / name)
    back = read_published(out)
    np.testing.assert_allclose(back.params, ts.params, rtol=0, atol=0)
    np.testing.assert_allclose(back.x, ts.x, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(back.y, ts.y, rtol=1e-12, atol=1e-12)


def test_full_published_2p1_present_or_skip(shared_reference):
    path = shared_reference / "training_compression_2.1um.csv"
    if not path.exists():
        pytest.skip("full published 2.1 um training set not present (validation only; see benchmarks)")
    ts, report = filter_curves(read_published(path))
    assert ts.n_curves > 1000 and report.n_in > ts.n_curves * 0.5


def test_rupture_and_nonfinite_filters(tmp_path):
    ts = make_synthetic(30, "compression", noise=0.0, seed=3)
    ts.y[0, -3:] = [0.0, 0.4, 0.0]  # trailing zeros (rupture)
    ts.y[1, 9:] = ts.y[1, 8] * 0.7  # force drop of 30 % and a plateau
    ts.y[2, 4] = np.nan
    ts.params[3, 2] = np.inf
    kept, report = filter_curves(ts)
    assert report.counts == {"status": 0, "non_finite": 2, "rupture_trailing_zero": 1, "rupture_drop": 1}
    assert kept.n_curves == 26
    assert set(report.dropped["non_finite"]) == {ts.curve_id[2], ts.curve_id[3]}
    assert "26 kept" in str(report)
    # a tolerant drop criterion keeps curve 1
    _, rep2 = filter_curves(ts, max_rel_drop=0.5)
    assert rep2.counts["rupture_drop"] == 0


def test_nan_rows_in_file_are_counted(tmp_path):
    ts = make_synthetic(5, "compression", noise=0.0, seed=1)
    path = write_published(ts, tmp_path / "a.csv")
    lines = path.read_text().splitlines()
    cells = lines[2].split(",")
    cells[20] = "nan"
    lines[2] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    kept, report = filter_curves(read_published(path))
    assert report.counts["non_finite"] == 1 and kept.n_curves == 4


def test_wrong_column_count_names_file_and_line(tmp_path):
    ts = make_synthetic(4, "compression", noise=0.0, seed=1)
    path = write_published(ts, tmp_path / "bad.csv")
    lines = path.read_text().splitlines()
    lines[3] = lines[3] + ",1.0"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(DatasetError, match=r"bad\.csv: line 4: 39 columns, expected 38"):
        read_published(path)


def test_whitespace_dat_without_header(tmp_path):
    ts = make_synthetic(4, "indentation", radius_dpd=6.38, noise=0.0, seed=1)
    csv = write_published(ts, tmp_path / "x.csv")
    rows = [line.replace(",", " ") for line in csv.read_text().splitlines()[1:]]
    dat = tmp_path / "samples_all.dat"
    dat.write_text("\n".join(rows) + "\n")
    back = read_published(dat)  # setup inferred from the published file name
    assert back.setup == "indentation"
    np.testing.assert_allclose(back.y, ts.y, atol=1e-12)
    with pytest.raises(DatasetError, match="cannot tell compression from indentation"):
        read_published(dat.rename(tmp_path / "data.dat"))


def test_zero_variance_parameter_named(shared_reference):
    # the CI smoke fixture has 2 loading points (12 columns) and ka == 0 in every row
    with pytest.raises(DatasetError, match="expected 38"):
        read_published(shared_reference / "ci_smoke_compression_retraining.csv")
    ts = read_published(shared_reference / "ci_smoke_compression_retraining.csv", n_points="auto",
                        setup="compression")
    assert ts.n_points == 2
    with pytest.raises(DatasetError, match=r"ci_smoke_compression_retraining\.csv: parameter 'ka' has zero variance"):
        ts.check_trainable()


def test_too_few_curves_for_sweep():
    from bubblecal.surrogates.training import SweepConfig, run_sweep

    ts = make_synthetic(12, "compression", noise=0.0, seed=1)
    with pytest.raises(DatasetError, match="12 curve.*at least 20"):
        run_sweep(ts, SweepConfig(widths=(8,), depths=(1,)))


def test_read_dataset_dispatches_to_store(tmp_path):
    from bubblecal.data import CampaignStore, make_record

    store = CampaignStore.create(tmp_path / "camp", fsync=False)
    ts = make_synthetic(3, "compression", noise=0.0, seed=2)
    for i in range(3):
        store.append(make_record(sample_id=f"s{i}", setup="compression",
                                 params=dict(zip(("ka", "kb", "b1", "b2", "a3", "a4"), ts.params[i], strict=True)),
                                 radius_dpd=4.2, x=ts.x[i], y=ts.y[i], status="ok" if i else "failed",
                                 seed=i, tier="explicit"))
    back = read_dataset(tmp_path / "camp")
    assert back.n_curves == 3 and list(back.status) == ["failed", "ok", "ok"]
    kept, report = filter_curves(back)
    assert report.counts["status"] == 1 and kept.n_curves == 2
    assert report.status_counts == {"failed": 1} and "failed" in str(report)
    np.testing.assert_array_equal(kept.y, ts.y[1:])
