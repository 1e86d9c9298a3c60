"""The shipped reference curves: counts, units and the load_reference / resolve_reference_name API."""

import numpy as np
import pytest

from bubblecal.data import DEFAULT_UNITS, DataError, load_reference, reference_curves, resolve_reference_name

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
