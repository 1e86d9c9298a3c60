"""Several training sets trained on together: concat_training_sets and `surrogates train A B`."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from bubblecal.surrogates import radius_of_diameter
from bubblecal.surrogates.training import DatasetError, concat_training_sets, make_synthetic, write_published
from bubblecal.workflows.cli import app


def _part(seed: int, d: float, setup: str = "compression", points: int = 8, n: int = 10):
    r = radius_of_diameter(d)
    x = np.linspace(0.0, 0.4 * r, points) if setup == "compression" else None
    ts = make_synthetic(n, setup, radius_dpd=r, noise=0.0, seed=seed, x=x)
    ts.curve_id = np.array([f"s{seed}:{i}" for i in range(n)])
    return ts


def test_concat_keeps_every_curve_in_order():
    a, b = _part(0, 2.0), _part(1, 4.0)
    both = concat_training_sets([a, b])
    assert both.n_curves == 20 and both.source == f"{a.source} + {b.source}"
    np.testing.assert_array_equal(both.params, np.concatenate([a.params, b.params]))
    np.testing.assert_array_equal(both.y[10:], b.y)
    np.testing.assert_array_equal(both.radius_dpd[:10], a.radius_dpd)
    assert list(both.curve_id[:2]) == ["s0:0", "s0:1"] and concat_training_sets([a]) is a


def test_concat_names_what_does_not_fit():
    a = _part(0, 2.0)
    with pytest.raises(DatasetError, match="no training set"):
        concat_training_sets([])
    with pytest.raises(DatasetError, match="holds indentation data"):
        concat_training_sets([a, _part(1, 2.0, setup="indentation")])
    with pytest.raises(DatasetError, match="6 load points per curve"):
        concat_training_sets([a, _part(1, 2.0, points=6)])
    with pytest.raises(DatasetError, match="curve id 's0:0' occurs 2 times"):
        concat_training_sets([a, _part(0, 3.0)])


def test_cli_trains_on_two_files_as_on_their_union(tmp_path):
    """Two files give the data hash of one file holding both halves (the same curves in the same order)."""
    a, b = _part(0, 2.0), _part(1, 4.0)
    fa, fb, fab = tmp_path / "a.csv", tmp_path / "b.csv", tmp_path / "ab.csv"
    write_published(a, fa)
    write_published(b, fb)
    write_published(concat_training_sets([a, b]), fab)
    args = ["--setup", "compression", "--over-diameter", "--no-sweep", "--width", "8", "--depth", "1",
            "--max-epochs", "2", "--no-onnx", "--quiet", "--n-points", "8"]
    hashes = []
    for files, out in (([fa, fb], "two"), ([fab], "one")):
        run = CliRunner().invoke(app, ["surrogates", "train", *map(str, files), *args, "--out", str(tmp_path / out)])
        assert run.exit_code == 0, run.output
        hashes.append(json.loads((tmp_path / out / "train_summary.json").read_text())["data_hash"])
    assert hashes[0] == hashes[1]
    bad = CliRunner().invoke(app, ["surrogates", "train", str(fa), str(fa), *args, "--out", str(tmp_path / "x")])
    assert bad.exit_code == 1 and "occurs 2 times" in bad.output
