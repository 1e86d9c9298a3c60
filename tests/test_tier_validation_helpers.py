"""benchmarks/tier_validation.py: re-gating against stored explicit curves (``--explicit-curves``)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest


@pytest.fixture(scope="module")
def tv(load_script):
    return load_script("benchmarks/tier_validation.py")


def _csv(path, x, y):
    lines = ["row,point,x,published,explicit,quasistatic"]
    for i in range(x.shape[0]):
        for j in range(x.shape[1]):
            lines.append(f"{i + 1},{j + 1},{float(x[i, j])!r},nan,{float(y[i, j])!r},0.0")
    path.write_text("\n".join(lines) + "\n")


def test_explicit_curves_from_an_earlier_run(tv, tmp_path):
    x = np.tile(np.linspace(0.0, 6000.0, 4), (3, 1))
    y = np.arange(12.0).reshape(3, 4) / 7.0
    y[2, 3] = np.nan  # a curve the explicit tier lost stays NaN
    _csv(tmp_path / "c.csv", x, y)
    got = tv.explicit_from_csv(str(tmp_path / "c.csv"), SimpleNamespace(x=x))
    np.testing.assert_array_equal(got, y)
    with pytest.raises(SystemExit, match="3 rows x 4 points, this run has 2 x 4"):
        tv.explicit_from_csv(str(tmp_path / "c.csv"), SimpleNamespace(x=x[:2]))
    with pytest.raises(SystemExit, match="loading grids differ"):
        tv.explicit_from_csv(str(tmp_path / "c.csv"), SimpleNamespace(x=2.0 * x))
    (tmp_path / "d.csv").write_text("row,point,x,published\n1,1,0.0,0.0\n")
    with pytest.raises(SystemExit, match="no 'explicit' column"):
        tv.explicit_from_csv(str(tmp_path / "d.csv"), SimpleNamespace(x=x))


def test_lhs_slice_keeps_the_published_rows_and_the_chosen_lhs_rows(tv):
    from bubblecal.surrogates.training import TrainingSet

    ts = tv.lhs_only_rows("indentation", 3.2, 6, seed=3)  # 6 LHS rows of the shipped 3.2 um box
    both = tv.with_lhs_rows(ts.subset(np.arange(2)), "indentation", 3.2, 4, seed=3)  # 2 "published" + 4 LHS
    assert isinstance(both, TrainingSet) and both.n_curves == 6
    cut = tv.lhs_slice(both, 4, "1:3")
    assert cut.curve_id.tolist() == [both.curve_id[0], both.curve_id[1], "lhs2", "lhs3"]
    np.testing.assert_array_equal(cut.params, both.params[[0, 1, 3, 4]])  # same sets as the full run's rows
    for bad in ("3:1", "0:5", "a:b", "2"):
        with pytest.raises(SystemExit, match="--lhs-slice"):
            tv.lhs_slice(both, 4, bad)
