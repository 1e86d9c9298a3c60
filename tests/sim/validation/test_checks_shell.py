"""The shell verification checks (docs/physics.md section 6, checks 3-5) in quick mode on the CPU."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("warp")

from bubblecal.sim.validation import ALL_SHELL_CHECKS, CheckResult, measure_kantor_kappa  # noqa: E402


@pytest.mark.parametrize("check", ALL_SHELL_CHECKS, ids=lambda c: c.__name__)
def test_shell_check_quick_cpu(check):
    res = check(quick=True, device="cpu")
    assert isinstance(res, CheckResult)
    json.dumps(res.as_dict(), default=str)  # serialisable for the verify JSON line
    assert res.passed, res.as_dict()


def test_kantor_kappa_is_sqrt3_over_2():
    # continuum limit of stress-free Kantor on an icosphere: kappa = sqrt(3)/2 kb (0.845 at s4, l = 6)
    assert 0.82 < measure_kantor_kappa(4, ell=6) < 0.87


@pytest.mark.slow
@pytest.mark.parametrize("check", ALL_SHELL_CHECKS, ids=lambda c: c.__name__)
def test_shell_check_full_cpu(check):
    res = check(quick=False, device="cpu")
    assert res.passed, res.as_dict()
