"""benchmarks/campaign_sample_throughput.py: the settings parser, the stratified sample and the stored curves.

The simulation itself (a GPU campaign task) is not run here; its figures are in benchmarks/RESULTS.md.
"""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture(scope="module")
def cst(load_script):
    return load_script("benchmarks/campaign_sample_throughput.py")


def test_settings_parse_numbers_flags_and_names(cst):
    assert cst.parse_setting("-") == {}
    got = cst.parse_setting("dtype=float32,max_replicas=2000,ftol=0.1,stop_unstable=true")
    assert got == {"dtype": "float32", "max_replicas": 2000, "ftol": 0.1, "stop_unstable": True}
    assert isinstance(got["max_replicas"], int)
    with pytest.raises(SystemExit, match="KEY=VALUE"):
        cst.parse_setting("max_replicas")


def test_sample_takes_the_first_points_of_each_level_in_order(cst):
    design = {"diameter_um": np.array([2.0, 1.5, 2.0, 1.5, 1.5, 3.0, 2.0])}
    assert cst.sample_indices(design, 2) == [1, 3, 0, 2, 5]
    assert cst.sample_indices(design, 5, levels=[2.0]) == [0, 2, 6]
    assert cst.sample_indices(design, 1, levels=[1.5, 3.0]) == [1, 5]


def test_stored_curves_are_read_by_sample_id(cst):
    stored = cst.stored_curves("definity_compression_1.5-8um")
    assert len(stored) == 33_000
    y, status = stored["definity_compression_1.5-8um-000000"]
    assert y.shape == (15,) and status in {"ok", "unstable", "ruptured", "failed"}
    assert sum(s == "ok" for _, s in stored.values()) == 33_000  # the shipped store (data/training/README.md)


def test_comparison_rows_stats_and_worst(cst):
    y = np.array([1.0, 2.0, 2.0])
    curves = {"a": (y * 1.01, "ok"), "b": (y, "ok"), "c": (y, "ok"), "d": (y, "failed"), "e": (y, "ok")}
    ref = {"a": (y, "ok"), "b": (y * 1.1, "ok"), "c": (y, "unstable"), "d": (y, "failed")}
    rows = cst.compare(curves, ref)
    assert [r[0] for r in rows] == ["a", "b", "c", "d"]  # "e" has no reference record
    np.testing.assert_allclose(rows[0][1], 0.01)
    np.testing.assert_allclose(rows[1][1], 0.1 / 1.1)
    assert np.isnan(rows[2][1]) and np.isnan(rows[3][1])
    stats = cst.rel_stats(rows)
    np.testing.assert_allclose([stats["median"], stats["max"]], [(0.01 + 0.1 / 1.1) / 2, 0.1 / 1.1])
    # the farthest first, then the sample ok in one run only ("d" failed in both: not listed)
    assert [r[0] for r in cst.worst(rows, n=1)] == ["b", "c"]
    assert cst.rel_l2(curves, ref) == stats and cst.rel_stats([]) is None
