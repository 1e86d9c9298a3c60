"""The SYNTHETIC development bundle: complete, loadable, boxes cover the priors, flagged loudly."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bubblecal.data import acoustic_observations, reference_curves
from bubblecal.priors import load_priors
from bubblecal.surrogates import (
    SYNTHETIC_NOTE,
    TRAINING_BOXES,
    is_synthetic_bundle,
    load_bundle,
    ringdown_frequency_MHz,
)

WORKFLOWS = ("full", "reduced", "reduced_acoustic")


@pytest.mark.parametrize("agent", ["definity", "sonovue"])
def test_training_boxes_contain_every_prior_box(agent):
    box = TRAINING_BOXES[agent]
    for wf in WORKFLOWS:
        spec = load_priors(f"{agent}_{wf}")
        for name, p in spec.parameters.items():
            if name == "d0":
                continue
            lo, hi = p.prior.as_tuple()
            assert box[name][0] <= lo and hi <= box[name][1], (agent, wf, name)


def test_bundle_complete_and_flagged(synthetic_bundle):
    bundle = load_bundle(synthetic_bundle)
    assert is_synthetic_bundle(bundle)
    assert SYNTHETIC_NOTE in bundle.manifest["notes"]
    for curve in reference_curves():
        sur = bundle.get(curve.kind, curve.diameter_um)
        assert sur.metadata["synthetic"] is True and "not DPD" in sur.metadata["notes"]
        assert sur.radius_dpd == pytest.approx(curve.radius_dpd)
        # the whole loading range of the data (x; compression x - d0 >= 0) is in the training box
        assert sur.x_range[0] <= 0.0 and sur.x_range[1] >= curve.x.max()
        box = TRAINING_BOXES[curve.agent]
        for name in ("ka", "kb"):
            assert sur.param_ranges[name][0] <= box[name][0] * (1 + 1e-9)
        # smooth, positive and increasing along the loading coordinate at a mid-box parameter set
        mid = np.array([np.sqrt(box["ka"][0] * box["ka"][1]), np.sqrt(box["kb"][0] * box["kb"][1]), 1.0, 2.0, 0.0, 1.0])
        y = np.asarray(sur(mid, np.linspace(0.05, 1.0, 20) * curve.x.max()))
        assert np.all(y > 0) and np.all(np.diff(y) > 0), (curve.name, y)
    for agent in ("definity", "sonovue"):
        ac = bundle.acoustic[agent]
        assert "not DPD" in ac.meta["notes"]
        for obs in acoustic_observations(agent):
            lo, hi = ac.ka_ranges(obs.diameter_um)
            ka = np.geomspace(lo, hi, 7)
            np.testing.assert_allclose(np.asarray(ac.f_res(ka, obs.diameter_um)),
                                       ringdown_frequency_MHz(ka, obs.diameter_um), rtol=1e-6)
    manifest = json.loads((synthetic_bundle / "manifest.json").read_text())
    assert len(manifest["surrogates"]) == 6 and len(manifest["acoustic"]) == 2


def test_ringdown_law_magnitudes():
    # Definity 5 um at E ~ 27 MPa: ~1.7 MHz, the measured order; f ~ sqrt(ka) / R
    f = ringdown_frequency_MHz(15000.0, 5.0)
    assert 1.3 < f < 2.2
    assert ringdown_frequency_MHz(60000.0, 10.0) == pytest.approx(2 * ringdown_frequency_MHz(15000.0, 10.0), rel=0.05)


def test_cli_command_registered():
    from typer.testing import CliRunner

    from bubblecal.workflows.cli import app

    r = CliRunner().invoke(app, ["surrogates", "synthetic-bundle", "--help"])
    assert r.exit_code == 0 and "SYNTHETIC" in r.output
