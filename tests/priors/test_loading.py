"""Shipped prior TOML files: they load, their values match SI Table S4, names resolve."""

import csv

import pytest

from bubblecal.priors import PriorError, available_priors, load_priors, prior_path

TABLE_TO_FILE = {
    ("Definity", "spectroscopy_only_full"): ["definity_full"],
    ("SonoVue", "spectroscopy_only_full"): ["sonovue_full"],
    ("Definity", "compression_plus_acoustic_reduced"): ["definity_reduced_acoustic"],
    ("SonoVue", "indentation_plus_acoustic_reduced"): ["sonovue_reduced_acoustic"],
}


def test_shipped_files_load():
    names = available_priors()
    assert names == sorted(["definity_full", "sonovue_full", "definity_reduced", "sonovue_reduced",
                            "definity_reduced_acoustic", "sonovue_reduced_acoustic"])
    for name in names:
        spec = load_priors(name)
        assert spec.agent in name
        if "reduced" in name:
            assert spec.free_names == ("ka", "kb", "d0")
            assert spec.fixed == {"b1": 0.0, "b2": 0.0, "a3": 0.0, "a4": 0.0}
        else:
            assert spec.free_names == ("ka", "kb", "b1", "b2", "a3", "a4", "d0")
        assert spec.noise_names == (("sigma_mech", "sigma_ac") if spec.acoustic else ("sigma",))


def test_shipped_values_match_table_s4(shared_reference):
    with open(shared_reference / "priors_hyperpriors_tableS4.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 26
    for row in rows:
        names = TABLE_TO_FILE[(row["agent"], row["workflow"])]
        param = row["parameter"].replace("d0_dpd", "d0")
        for name in names:
            spec = load_priors(name)
            bounds = spec.bounds(param)
            assert bounds.as_tuple() == (float(row["prior_lo"]), float(row["prior_hi"])), (name, param)
            if row["hyper_m_lo"]:
                p = spec.parameters[param]
                assert p.hyper_m.as_tuple() == (float(row["hyper_m_lo"]), float(row["hyper_m_hi"]))
                assert p.hyper_tau.as_tuple() == (float(row["hyper_tau_lo"]), float(row["hyper_tau_hi"]))
    # reduced spectroscopy-only workflows reuse the full ranges for ka, kb, d0, sigma
    for agent in ("definity", "sonovue"):
        full, reduced = load_priors(f"{agent}_full"), load_priors(f"{agent}_reduced")
        for name in ("ka", "kb", "d0", "sigma"):
            assert full.bounds(name) == reduced.bounds(name)


def test_unknown_name():
    with pytest.raises(PriorError, match="shipped: definity_full"):
        prior_path("definity_huge")
