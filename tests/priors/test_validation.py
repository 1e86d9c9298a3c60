"""Prior TOML validation: a valid user file loads; every bad edit is reported with file and key."""

import pytest

from bubblecal.priors import PriorError, check_priors, load_priors

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
