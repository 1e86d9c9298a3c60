"""Prior TOML files: shipped values match SI Table S4; every bad edit is reported with file and key."""

import csv

import pytest

from bubblecal.priors import PriorError, available_priors, check_priors, load_priors, prior_path

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


VALID = """
[workflow]
agent = "definity"
setup = "compression"
shell = "reduced"
acoustic = false

[parameters.ka]
prior = [5.58e3, 2.79e4]
hyper_m = [5.58e3, 2.79e4]
hyper_tau = [0.0, 2.79e4]

[parameters.kb]
prior = [100.0, 1000.0]

[parameters.d0]
prior = [0.0, 0.5]

[fixed]
b1 = 0.0
b2 = 0.0
a3 = 0.0
a4 = 0.0

[noise.sigma]
prior = [0.0, 1.0]
"""


def _write(tmp_path, text):
    path = tmp_path / "edited.toml"
    path.write_text(text)
    return path


def test_valid_user_file(tmp_path):
    spec = load_priors(_write(tmp_path, VALID))
    assert spec.pooled_names == ("ka",)
    assert check_priors(_write(tmp_path, VALID)) == []


BAD_EDITS = {
    "lo >= hi": (("prior = [100.0, 1000.0]", "prior = [1000.0, 100.0]"),
                 r"parameters\.kb\.prior: lo \(1000\) must be smaller than hi \(100\)"),
    "negative tau": (("hyper_tau = [0.0, 2.79e4]", "hyper_tau = [-5.0, 2.79e4]"),
                     r"parameters\.ka\.hyper_tau: spread range \[-5, 27900\] must be >= 0"),
    "hyper mean outside prior": (("hyper_m = [5.58e3, 2.79e4]", "hyper_m = [1e3, 2.79e4]"),
                                 r"parameters\.ka\.hyper_m: range \[1000, 27900\] lies outside the prior range"),
    "unknown parameter": (("[parameters.d0]", "[parameters.k_a]\nprior = [1.0, 2.0]\n\n[parameters.d0]"),
                          r"parameters\.k_a: unknown parameter \(allowed: ka, kb, b1, b2, a3, a4, d0\)"),
    "missing parameter": (("[parameters.d0]\nprior = [0.0, 0.5]", ""), r"parameters\.d0: missing"),
    "wrong type": (("prior = [0.0, 0.5]", 'prior = ["zero", 0.5]'),
                   r"parameters\.d0\.prior: lo and hi must be numbers"),
    "not a pair": (("prior = [0.0, 0.5]", "prior = 0.5"), r"parameters\.d0\.prior: must be a list \[lo, hi\]"),
    "bad agent": (('agent = "definity"', 'agent = "optison"'), r"workflow\.agent: 'optison' is not one of"),
    "reduced with free b1": (("b1 = 0.0\n", ""), r"parameters\.b1: missing"),
    "nonzero fixed in reduced": (("b1 = 0.0", "b1 = 0.3"), r"fixed\.b1: a reduced shell fixes b1 = 0, got 0\.3"),
    "missing noise": (("[noise.sigma]\nprior = [0.0, 1.0]", ""), r"noise\.sigma: missing"),
    "unknown section": (("[fixed]", "[hyper]\nx = 1\n\n[fixed]"), r"hyper: unknown section"),
    "negative modulus": (("prior = [100.0, 1000.0]", "prior = [-100.0, 1000.0]"),
                         r"parameters\.kb\.prior: lower bound -100 must be > 0"),
    "only hyper_m": (("hyper_tau = [0.0, 2.79e4]\n", ""), r"parameters\.ka: give both hyper_m and hyper_tau"),
    "bad toml": (("[fixed]", "[fixed"), r"not valid TOML"),
}


@pytest.mark.parametrize("case", list(BAD_EDITS))
def test_bad_prior_files(tmp_path, case):
    (old, new), pattern = BAD_EDITS[case]
    assert old in VALID
    path = _write(tmp_path, VALID.replace(old, new, 1))
    with pytest.raises(PriorError, match=pattern) as info:
        load_priors(path)
    assert str(path) in str(info.value)


def test_all_problems_listed_at_once(tmp_path):
    text = VALID.replace("prior = [100.0, 1000.0]", "prior = [1000.0, 100.0]").replace(
        'agent = "definity"', 'agent = "x"').replace("[noise.sigma]\nprior = [0.0, 1.0]", "")
    problems = check_priors(_write(tmp_path, text))
    assert len(problems) == 3
    assert any("workflow.agent" in p for p in problems) and any("noise.sigma" in p for p in problems)


def test_unknown_name():
    with pytest.raises(PriorError, match="shipped: definity_full"):
        prior_path("definity_huge")
