"""`bubblecal sim verify`: quick fluid checks pass on CPU; table + JSON line; exit status."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("warp")

from bubblecal.sim.validation import CheckResult, fluid_checks  # noqa: E402


@pytest.mark.parametrize("check", fluid_checks.ALL_FLUID_CHECKS, ids=lambda f: f.__name__)
def test_quick_fluid_checks_pass(check):
    res = check(quick=True, device="cpu")
    assert isinstance(res, CheckResult)
    assert res.passed, res.as_dict()


def test_block_mean_sem():
    import numpy as np

    x = np.random.default_rng(0).normal(2.0, 1.0, 4000)
    m, se = fluid_checks.block_mean_sem(x)
    assert abs(m - 2.0) < 0.1 and 0.005 < se < 0.05


def _invoke(args):
    from typer.testing import CliRunner

    from bubblecal.workflows.cli import app

    return CliRunner().invoke(app, args)


def test_cli_sim_verify_prints_table_and_json_last():
    # the fluid run is cached within the process, so this reuses the parametrized test's simulation
    res = _invoke(["sim", "verify", "--quick", "--device", "cpu", "--only", "check_eos_a25"])
    assert res.exit_code == 0, res.output
    lines = [ln for ln in res.output.strip().splitlines() if ln.strip()]
    payload = json.loads(lines[-1])
    assert payload["passed"] is True and payload["n_checks"] == 1
    assert payload["checks"][0]["name"] == "EOS pressure a=25"
    assert "tolerance" in res.output


def test_cli_sim_verify_fails_with_nonzero_exit(monkeypatch):
    from bubblecal.sim.validation import verify

    def bad(quick=True, device="cpu"):
        return CheckResult("always fails", "1", 2, "0", False)

    def boom(quick=True, device="cpu"):
        raise RuntimeError("kaput")

    monkeypatch.setattr(verify, "all_checks", lambda: [bad, boom])
    res = _invoke(["sim", "verify", "--quick"])
    assert res.exit_code == 1
    payload = json.loads(res.output.strip().splitlines()[-1])
    assert payload["n_failed"] == 2 and "kaput" in payload["checks"][1]["details"]["error"]


def test_cli_rejects_unknown_device():
    res = _invoke(["sim", "verify", "--quick", "--device", "tpu"])
    assert res.exit_code != 0
