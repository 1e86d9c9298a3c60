"""Acoustic resonance observations: the shipped table, its grouping into datasets, the validating reader."""

import pytest

from bubblecal.data import DataError, acoustic_datasets, acoustic_observations, load_acoustic_table


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


def test_bad_acoustic_table(tmp_path):
    path = _write(tmp_path, "agent,source,source_figure,diameter_um,resonance_frequency_MHz\n"
                            "SonoVue,x,y,2.6,abc\nOptison,x,y,3,1\n", "ac.csv")
    with pytest.raises(DataError) as info:
        load_acoustic_table(path)
    text = str(info.value)
    assert "row 1, column 'resonance_frequency_MHz'" in text and "row 2, column 'agent'" in text
