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
    assert sum(s == "ok" for _, s in stored.values()) == 32_972
