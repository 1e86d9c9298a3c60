"""Reference curves and the validating CSV reader (every bad input names file, row and column)."""

import numpy as np
import pytest

from bubblecal.data import (
    DEFAULT_UNITS,
    DataError,
    acoustic_datasets,
    acoustic_observations,
    load_acoustic_table,
    load_curve,
    load_reference,
    reference_curves,
)
from bubblecal.data.curves import resolve_reference_name

EXPECTED_POINTS = {  # retained / source, SI Table S3
    "definity_compression_2.1um": (24, 27), "definity_compression_2.9um": (14, 17),
    "definity_compression_3.0um": (22, 25), "sonovue_indentation_3.2um": (29, 32),
    "sonovue_indentation_3.4um": (20, 46), "sonovue_indentation_5.8um": (19, 22),
}


def test_reference_curves_counts_and_units():
    curves = reference_curves()
    assert [c.name for c in curves] == list(EXPECTED_POINTS)
    for c in curves:
        retained, source = EXPECTED_POINTS[c.name]
        assert c.n_points == retained
        assert c.source_curve.x.size == source
        assert int(c.source_curve.retained.sum()) == retained
        # the DPD curve is the retained part of the physical source, converted
        np.testing.assert_allclose(c.x_physical, c.source_curve.x[c.source_curve.retained], rtol=1e-9)
        np.testing.assert_allclose(c.y_physical, c.source_curve.y[c.source_curve.retained], rtol=1e-9)
        assert np.all(np.diff(c.x) > 0)


def test_load_reference_api():
    c = load_reference("definity", 2.1)
    assert (c.agent, c.kind, c.diameter_um, c.radius_dpd) == ("definity", "compression", 2.1, 4.2)
    assert c.x_quantity == "displacement" and c.axis_label("x", "physical") == "displacement [nm]"
    np.testing.assert_allclose(c.displacement_nm, c.x * 250.0)
    np.testing.assert_allclose(c.force_nN, c.y / DEFAULT_UNITS.nN_to_dpd(1.0))
    s = load_reference("SonoVue", 5.8)
    assert s.kind == "indentation" and s.radius_dpd == pytest.approx(11.52)
    assert s.x_quantity == "force" and np.array_equal(s.force_dpd, s.x)
    with pytest.raises(DataError, match="available: 2.1, 2.9, 3"):
        load_reference("definity", 4.0)
    with pytest.raises(DataError, match="unknown agent 'optison'"):
        load_reference("optison", 3.0)
    assert resolve_reference_name("sonovue-3.4") == "sonovue_indentation_3.4um"


def test_acoustic_observations():
    rows = acoustic_observations()
    assert len(rows) == 17
    assert len(acoustic_observations("definity")) == 14
    (definity,) = acoustic_datasets("definity")
    assert definity.n_points == 14 and definity.diameter_um.min() == pytest.approx(4.68)
    sonovue = acoustic_datasets("sonovue")
    assert [d.n_points for d in sonovue] == [1, 1, 1]
    assert [float(d.diameter_um[0]) for d in sonovue] == [2.6, 3.2, 4.0]


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
    "inf": ("displacement_dpd,force_dpd\n0.1,1\ninf,2\n0.3,3\n", r"row 2 \(line 3\), column 'displacement_dpd'.*not finite"),
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


def test_bad_acoustic_table(tmp_path):
    path = _write(tmp_path, "agent,source,source_figure,diameter_um,resonance_frequency_MHz\n"
                            "SonoVue,x,y,2.6,abc\nOptison,x,y,3,1\n", "ac.csv")
    with pytest.raises(DataError) as info:
        load_acoustic_table(path)
    text = str(info.value)
    assert "row 1, column 'resonance_frequency_MHz'" in text and "row 2, column 'agent'" in text
