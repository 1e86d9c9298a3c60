"""Unit conversions pinned to the published numbers (physics.md section 1)."""

import math

import numpy as np
import pandas as pd
import pytest

from bubblecal.data import DEFAULT_UNITS, UnitSystem


def test_pinned_numbers():
    u = DEFAULT_UNITS
    assert u.nN_to_dpd(1.0) == pytest.approx(446.698, abs=5e-4)
    assert u.dpd_to_nm(1.0) == pytest.approx(250.0, rel=1e-12)
    assert abs(u.young_to_ka(10e6) - 5584.0) <= 1.0
    assert u.yt_per_ka == pytest.approx(1790.92, abs=5e-3)
    assert u.time_s == pytest.approx(8.852e-6, rel=2e-4)
    assert 1.0 / u.time_s / 1e6 == pytest.approx(0.11296, rel=1e-4)
    assert u.energy_J == pytest.approx(4.1415e-21, rel=1e-12)
    assert u.mass_kg == pytest.approx(5.193e-18, rel=2e-4)
    assert u.force_N == pytest.approx(1.657e-14, rel=2e-4)
    assert u.modulus2d_N_per_m == pytest.approx(6.626e-8, rel=2e-4)
    assert u.pressure_Pa == pytest.approx(0.265, rel=1e-3)
    assert float(u.radius_dpd(2.1)) == pytest.approx(4.2)


def test_published_time_unit_with_rho_1000():
    # the published PCA table used rho = 1000 kg/m^3: tau = 8.86564957825223e-06 s
    assert UnitSystem(rho_water=1000.0).time_s == pytest.approx(8.86564957825223e-06, rel=1e-9)


@pytest.mark.parametrize("pair", [
    ("length_to_dpd", "length_to_physical", 3e-7), ("nm_to_dpd", "dpd_to_nm", 123.0),
    ("force_to_dpd", "force_to_physical", 2e-9), ("nN_to_dpd", "dpd_to_nN", 1.7),
    ("stiffness_to_dpd", "stiffness_to_physical", 0.05), ("modulus2d_to_dpd", "modulus2d_to_physical", 0.1),
    ("pressure_to_dpd", "pressure_to_physical", 101325.0), ("time_to_dpd", "time_to_physical", 1e-6),
    ("young_to_ka", "ka_to_young", 2e7), ("young_to_kb", "kb_to_young", 2e7), ("ka_to_yt", "yt_to_ka", 12345.0),
    ("bending_kBT_to_kb", "kb_to_bending_kBT", 50.0),
])
def test_round_trips(pair):
    forward, backward, value = pair
    u = DEFAULT_UNITS
    assert float(getattr(u, backward)(getattr(u, forward)(value))) == pytest.approx(value, rel=1e-12)


def test_frequency_mass_scale():
    u = DEFAULT_UNITS
    # f_phys = f_dpd sqrt(M)/u_t: a 160x heavier shell rings sqrt(160) slower
    f = u.frequency_to_physical(0.01, mass_factor=160.0)
    assert f == pytest.approx(0.01 * math.sqrt(160.0) / u.time_s)
    assert u.frequency_to_dpd(f, mass_factor=160.0) == pytest.approx(0.01)
    assert u.angular_to_physical_Hz(2 * math.pi * 0.01) == pytest.approx(0.01 / u.time_s)
    with pytest.raises(ValueError, match="mass_factor"):
        u.frequency_to_physical(1.0, mass_factor=0.0)


def test_moduli_relations():
    u = DEFAULT_UNITS
    E = 1e7
    assert float(u.young_to_mu(E)) == pytest.approx(float(u.young_to_ka(E)) / 3.0)
    # Yt is Young's modulus at nu = 1/2
    assert float(u.ka_to_yt(u.young_to_ka(E))) == pytest.approx(E)
    # k_b scales as E h^3: check against the formula of physics.md
    kb = fscale_kb = 0.0074 * (2 / math.sqrt(3)) * E * (5e-9) ** 3 / (12 * (1 - 0.25)) / u.energy_J
    assert float(u.young_to_kb(E)) == pytest.approx(fscale_kb)
    assert float(u.kb_to_bending_kBT(kb)) == pytest.approx(E * (5e-9) ** 3 / (12 * 0.75) / u.energy_J)


def test_invalid_unit_system():
    with pytest.raises(ValueError, match="fscale"):
        UnitSystem(fscale=-1.0)
    with pytest.raises(ValueError, match="poisson"):
        UnitSystem(poisson=0.7)


def test_frozen():
    with pytest.raises(AttributeError):
        DEFAULT_UNITS.fscale = 1.0  # type: ignore[misc]


def _pairs(shared_reference):
    for dpd in sorted(shared_reference.glob("*_dpd.csv")):
        source = shared_reference / dpd.name.replace("_dpd.csv", "_source_physical.csv")
        if source.exists():
            yield dpd, source


def test_every_shared_dpd_row_is_a_converted_source_row(shared_reference):
    u = DEFAULT_UNITS
    pairs = list(_pairs(shared_reference))
    assert len(pairs) == 6
    for dpd_path, src_path in pairs:
        dpd = pd.read_csv(dpd_path)
        src = pd.read_csv(src_path)
        kept = src[src["retained_in_inference"] == 1]
        assert len(kept) == len(dpd), dpd_path.name
        converted = {"displacement_dpd": u.nm_to_dpd(kept["displacement_nm"].to_numpy()),
                     "force_dpd": u.nN_to_dpd(kept["force_nN"].to_numpy())}
        for column, values in converted.items():
            np.testing.assert_allclose(dpd[column].to_numpy(), values, rtol=1e-9, err_msg=f"{dpd_path.name}:{column}")


def test_training_heads_yt_column(shared_reference):
    for path in shared_reference.glob("training_head_*.csv"):
        table = pd.read_csv(path)
        np.testing.assert_allclose(table["Yt_Pa"], DEFAULT_UNITS.ka_to_yt(table["ka_dpd"]), rtol=1e-9)
