"""Physical plausibility bounds: a force of 1e300, an all-zero force curve and a 1e300 resonance frequency are
refused with file, row, column, value and the allowed range; a UTF-8 BOM is read, a semicolon header named."""

from __future__ import annotations

import pytest

from bubblecal.data import PLAUSIBLE_RANGES, DataError, load_acoustic_table, load_curve, reference_curves

ACOUSTIC_HEADER = "agent,source,source_figure,diameter_um,resonance_frequency_MHz\n"


def test_a_force_of_1e300_names_row_column_value_and_range(tmp_path):
    path = tmp_path / "big.csv"
    path.write_text("displacement_dpd,force_dpd\n0.1,1\n0.2,1e300\n0.3,5\n")
    with pytest.raises(DataError) as err:
        load_curve(path, "compression")
    msg = str(err.value)
    assert "big.csv" in msg and "row 2 (line 3), column 'force_dpd'" in msg and "1e+300 DPD force" in msg
    assert "plausible range [0, 10000] nN" in msg


def test_a_physical_displacement_beyond_the_range(tmp_path):
    path = tmp_path / "far.csv"
    path.write_text("force_nN,displacement_nm\n0.1,10\n0.2,2e6\n0.3,30\n")
    with pytest.raises(DataError, match=r"row 2 \(line 3\), column 'displacement_nm': displacement 2e\+06 nm.*"
                                        r"\[0, 100000\] nm"):
        load_curve(path, "indentation", "physical")


def test_an_all_zero_force_curve_carries_no_signal(tmp_path):
    path = tmp_path / "zero.csv"
    path.write_text("displacement_dpd,force_dpd\n0.1,0\n0.2,0\n0.3,0\n")
    with pytest.raises(DataError, match=r"zero\.csv.*\n.*every force is below 0.001 nN.*no signal"):
        load_curve(path, "compression")


def test_a_resonance_of_1e300_mhz(tmp_path):
    path = tmp_path / "acoustic.csv"
    path.write_text(ACOUSTIC_HEADER + "definity,x,Fig 1,2.5,2.0\ndefinity,x,Fig 1,3.0,1e300\n")
    with pytest.raises(DataError) as err:
        load_acoustic_table(path)
    msg = str(err.value)
    assert "acoustic.csv" in msg and "row 2, column 'resonance_frequency_MHz'" in msg and "1e+300 MHz" in msg
    assert "[0.01, 200] MHz" in msg


def test_every_shipped_value_is_plausible():
    """The bounds accept every shipped curve and observation (they would otherwise refuse the reference data)."""
    from bubblecal.data import acoustic_observations

    force, disp = PLAUSIBLE_RANGES["force"], PLAUSIBLE_RANGES["displacement"]
    for c in reference_curves():
        assert force.lo <= c.force_nN.min() and c.force_nN.max() <= force.hi
        assert disp.lo <= c.displacement_nm.min() and c.displacement_nm.max() <= disp.hi
    assert len(acoustic_observations()) == 17


def test_a_byte_order_mark_is_read_and_a_semicolon_header_is_named(tmp_path):
    bom = tmp_path / "bom.csv"
    bom.write_bytes("\ufeffdisplacement_dpd,force_dpd\n0.1,1\n0.2,2\n0.3,5\n".encode())
    assert load_curve(bom, "compression").n_points == 3
    semi = tmp_path / "semi.csv"
    semi.write_text("displacement_dpd;force_dpd\n0.1;1\n0.2;2\n0.3;5\n")
    with pytest.raises(DataError, match="semicolon-separated"):
        load_curve(semi, "compression")
    acoustic = tmp_path / "ac.csv"
    acoustic.write_bytes(("\ufeff" + ACOUSTIC_HEADER + "definity,x,Fig 1,2.5,2.0\n").encode())
    assert load_acoustic_table(acoustic)[0].frequency_MHz == 2.0
    acoustic.write_text(ACOUSTIC_HEADER.replace(",", ";") + "definity;x;Fig 1;2.5;2.0\n")
    with pytest.raises(DataError, match="semicolon-separated"):
        load_acoustic_table(acoustic)


def test_a_folder_or_non_utf8_file_is_a_data_error(tmp_path):
    with pytest.raises(DataError, match="is a folder"):
        load_curve(tmp_path, "compression")
    raw = tmp_path / "latin1.csv"
    raw.write_bytes(b"displacement_dpd,force_dpd\n0.1,1\xe9\n")
    with pytest.raises(DataError, match="not UTF-8"):
        load_acoustic_table(raw)
