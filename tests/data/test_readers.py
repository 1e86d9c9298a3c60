"""The validating curve CSV reader (every bad input names file, row and column)."""

import numpy as np
import pytest

from bubblecal.data import DEFAULT_UNITS, DataError, load_curve


def _write(tmp_path, text, name="curve.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_user_curve_dpd_and_physical(tmp_path):
    path = _write(tmp_path, "displacement_dpd,force_dpd\n0.1,10\n0.2,20\n0.3,35\n")
    c = load_curve(path, "compression", "dpd")
    assert c.n_points == 3 and c.agent is None
    phys = _write(tmp_path, "force_nN,displacement_nm,retained_in_inference\n0.5,10,0\n1,20,1\n2,30,1\n3,45,1\n",
                  "p.csv")
    c = load_curve(phys, "indentation", "physical")
    assert c.n_points == 3
    np.testing.assert_allclose(c.x, DEFAULT_UNITS.nN_to_dpd([1, 2, 3]))
    np.testing.assert_allclose(c.y, [0.08, 0.12, 0.18])
    assert c.source_curve.x.size == 4


BAD_FILES = {
    "missing column": ("displacement_dpd,forc_dpd\n0.1,1\n0.2,2\n0.3,3\n", r"missing column 'force_dpd'"),
    "unknown column": ("displacement_dpd,force_dpd,extra\n0.1,1,0\n0.2,2,0\n0.3,3,0\n", r"unknown column 'extra'"),
    "non-numeric": ("displacement_dpd,force_dpd\n0.1,1\n0.2,abc\n0.3,3\n",
                    r"row 2 \(line 3\), column 'force_dpd': 'abc' is not a number"),
    "nan": ("displacement_dpd,force_dpd\n0.1,1\n0.2,nan\n0.3,3\n", r"row 2 \(line 3\), column 'force_dpd'.*not finite"),
    "inf": ("displacement_dpd,force_dpd\n0.1,1\ninf,2\n0.3,3\n",
            r"row 2 \(line 3\), column 'displacement_dpd'.*not finite"),
    "negative force": ("displacement_dpd,force_dpd\n0.1,1\n0.2,-2\n0.3,3\n",
                       r"row 2 \(line 3\), column 'force_dpd': negative value -2"),
    "negative displacement": ("displacement_dpd,force_dpd\n-0.1,1\n0.2,2\n0.3,3\n",
                              r"row 1 \(line 2\), column 'displacement_dpd': negative"),
    "not increasing": ("displacement_dpd,force_dpd\n0.1,1\n0.3,2\n0.2,3\n",
                       r"row 3 \(line 4\), column 'displacement_dpd'.*strictly increasing"),
    "too few points": ("displacement_dpd,force_dpd\n0.1,1\n0.2,2\n", r"only 2 data rows; a curve needs at least 3"),
    "ragged row": ("displacement_dpd,force_dpd\n0.1,1\n0.2\n0.3,3\n0.4,4\n", r"row 2 \(line 3\): 1 cells, expected 2"),
}


@pytest.mark.parametrize("case", list(BAD_FILES))
def test_bad_curve_files(tmp_path, case):
    text, pattern = BAD_FILES[case]
    path = _write(tmp_path, text, f"{case.replace(' ', '_')}.csv")
    with pytest.raises(DataError, match=pattern) as info:
        load_curve(path, "compression", "dpd")
    assert str(path) in str(info.value)


def test_all_problems_listed(tmp_path):
    path = _write(tmp_path, "displacement_dpd,force_dpd\n0.1,x\n-0.2,nan\n0.3,3\n")
    with pytest.raises(DataError) as info:
        load_curve(path, "compression", "dpd")
    assert len(info.value.problems) >= 3


def test_unknown_units_and_kind(tmp_path):
    path = _write(tmp_path, "displacement_dpd,force_dpd\n0.1,1\n0.2,2\n0.3,3\n")
    with pytest.raises(DataError, match="unknown units 'mm'; allowed: dpd, physical"):
        load_curve(path, "compression", "mm")
    with pytest.raises(DataError, match="unknown kind 'stretching'"):
        load_curve(path, "stretching", "dpd")
    with pytest.raises(DataError, match="file not found"):
        load_curve(tmp_path / "nope.csv", "compression", "dpd")


def test_bad_retained_flag(tmp_path):
    path = _write(tmp_path, "displacement_nm,force_nN,retained_in_inference\n1,1,1\n2,2,yes\n3,3,1\n4,4,1\n")
    with pytest.raises(DataError, match=r"row 2 \(line 3\), column 'retained_in_inference'"):
        load_curve(path, "compression", "physical")
