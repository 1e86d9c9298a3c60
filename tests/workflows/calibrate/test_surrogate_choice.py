"""`calibrate --surrogates`: the published study on the networks over the diameter and the acoustic laws by default
(--paper too), on the per-diameter files when asked; the run's choice recorded and reused by whatever rebuilds its
surrogates.

Plans only (``check_likelihoods=False``): nothing is sampled."""

from __future__ import annotations

import copy
import dataclasses
import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from bubblecal.surrogates import AcousticLawSurrogate
from bubblecal.workflows.calibrate import (
    SURROGATE_CHOICES,
    CalibrationConfig,
    CalibrationError,
    bundle_hashes,
    make_plan,
    phase_hashes,
    run_config,
    run_plan,
    served_lines,
)
from bubblecal.workflows.cli import app

PUBLISHED_DIAMETERS = {"definity": [2.1, 2.9, 3.0], "sonovue": [3.2, 3.4, 5.8]}


def _plan(tmp_path, **kwargs):
    return make_plan(CalibrationConfig(out=tmp_path / "out", **kwargs), check_likelihoods=False)


def _files(ap) -> list[str]:
    return [s.path.name for s in ap.surrogates]


def test_default_serves_every_published_curve_from_the_fast_networks_and_the_laws(tmp_path):
    plan = _plan(tmp_path)
    assert plan.config.resolved_surrogates == "over-diameter"
    for ap in plan.agents:
        kind = ap.curves[0].kind
        assert _files(ap) == [f"{kind}_1.5-8um_fast.npz"] * 3, ap.agent
        assert all(s.over_diameter for s in ap.surrogates)
        # each network bound to its curve's diameter
        assert [s.diameter_um for s in ap.surrogates] == pytest.approx(PUBLISHED_DIAMETERS[ap.agent], abs=0.01)
        assert isinstance(ap.f_res, AcousticLawSurrogate)
        lines = served_lines(ap, plan.bundle)
        assert lines[0].endswith(f"network over the diameter {kind}_1.5-8um_fast.npz (fast)")
        assert lines[-1].startswith(ap.acoustic[0].name) and "acoustic law over 1.5-" in lines[-1]


def test_paper_runs_on_the_networks_over_the_diameter_unless_asked_for_the_per_diameter_files(tmp_path):
    """--paper sets the sampler; the surrogates stay the default's, and --surrogates per-diameter is the paper's
    exact set-up: the per-diameter files and quadratics."""
    assert _plan(tmp_path / "a", paper=True).config.resolved_surrogates == "over-diameter"
    assert all(s.over_diameter for ap in _plan(tmp_path / "a", paper=True).agents for s in ap.surrogates)
    plan = _plan(tmp_path, paper=True, surrogates="per-diameter")
    assert plan.config.resolved_surrogates == "per-diameter"
    definity, sonovue = plan.agents
    assert _files(definity) == ["compression_2.1um.npz", "compression_2.9um.npz", "compression_3um.npz"]
    assert _files(sonovue) == ["indentation_3.2um.npz", "indentation_3.4um.npz", "indentation_5.8um.npz"]
    assert not any(s.over_diameter for ap in plan.agents for s in ap.surrogates)
    assert not any(isinstance(ap.f_res, AcousticLawSurrogate) for ap in plan.agents)
    first = served_lines(definity, plan.bundle)[0]
    assert first == "definity_compression_2.1um: per-diameter file compression_2.1um.npz"


@pytest.mark.parametrize("kwargs, over", [({"surrogates": "per-diameter"}, False),
                                          ({"surrogates": "per-diameter", "paper": True}, False),
                                          ({"surrogates": "over-diameter", "paper": True}, True)])
def test_explicit_choice_overrides_the_default_both_ways(tmp_path, kwargs, over):
    plan = _plan(tmp_path, agents=("sonovue",), **kwargs)
    (ap,) = plan.agents
    assert all(s.over_diameter == over for s in ap.surrogates)
    assert isinstance(ap.f_res, AcousticLawSurrogate) == over


def test_networks_accurate_picks_the_accurate_networks(tmp_path):
    plan = _plan(tmp_path, networks="accurate")
    assert [_files(ap) for ap in plan.agents] == [["compression_1.5-8um.npz"] * 3, ["indentation_1.5-8um.npz"] * 3]
    assert served_lines(plan.agents[0], plan.bundle)[0].endswith("compression_1.5-8um.npz (accurate)")


def test_phase_hashes_differ_between_the_two_choices(tmp_path):
    """A phase computed on the per-diameter files is never reused by an over-diameter run (or the fast network's
    by an accurate run): every phase hash differs."""
    hashes = {}
    for key, kwargs in (("per", {"surrogates": "per-diameter"}), ("over", {}), ("accurate", {"networks": "accurate"})):
        plan = _plan(tmp_path, **kwargs)
        hashes[key] = {ap.agent: phase_hashes(ap, plan.config, bundle_hashes(plan.bundle)) for ap in plan.agents}
    for agent in ("definity", "sonovue"):
        per, over, acc = (hashes[k][agent] for k in ("per", "over", "accurate"))
        assert per.keys() == over.keys() == acc.keys()
        assert all(per[k] != over[k] for k in per), agent
        # the acoustic law serves both roles: only its phase 1 is shared (phases 2 and 3 see the curves' phase 1)
        shared = {k for k in over if over[k] == acc[k]}
        assert shared == {k for k in over if k.startswith(f"phase1_{agent}_acoustic")}, agent


def test_phase_hashes_tell_logged_moduli_apart(tmp_path):
    """Two networks of one training set and one architecture, one with logged moduli: no phase of one is reused by
    the other (a network taking linear moduli keeps the hashes it had)."""
    plan = _plan(tmp_path, agents=("sonovue",))
    (ap,) = plan.agents
    assert all(s.log_inputs == ("ka", "kb") for s in ap.surrogates)  # the shipped networks over the diameter
    logged = phase_hashes(ap, plan.config, bundle_hashes(plan.bundle))
    linear = dataclasses.replace(ap, surrogates=[copy.copy(s) for s in ap.surrogates])
    for s in linear.surrogates:
        s.log_inputs = ()
    other = phase_hashes(linear, plan.config, bundle_hashes(plan.bundle))
    assert all(logged[k] != other[k] for k in logged if not k.startswith("phase1_sonovue_acoustic"))


def test_the_manifest_records_the_choice_and_old_manifests_read_per_diameter(tmp_path):
    config = CalibrationConfig(agents=("definity",), out=tmp_path, networks="accurate")
    d = json.loads(json.dumps(config.as_dict()))
    assert (d["surrogates"], d["networks"]) == ("over-diameter", "accurate")
    back = CalibrationConfig.from_dict(d)
    assert back == dataclasses.replace(config, surrogates="over-diameter")
    assert CalibrationConfig.from_dict(CalibrationConfig(paper=True).as_dict()).resolved_surrogates == "over-diameter"
    paper_run = CalibrationConfig(paper=True, surrogates="per-diameter").as_dict()
    assert CalibrationConfig.from_dict(paper_run).resolved_surrogates == "per-diameter"
    old = {k: v for k, v in d.items() if k not in ("surrogates", "networks")}
    assert CalibrationConfig.from_dict(old).surrogate_lookup() == {"prefer": "per-diameter", "network": "accurate"}
    # a measured-bubbles run always ran on the networks over the diameter
    data_run = {**old, "data": str(tmp_path / "c.csv")}
    assert CalibrationConfig.from_dict(data_run).resolved_surrogates == "over-diameter"


def _write_manifest(folder: Path, config: CalibrationConfig, drop=()) -> Path:
    folder.mkdir(parents=True)
    d = {k: v for k, v in config.as_dict().items() if k not in drop}
    (folder / "manifest.json").write_text(json.dumps({"run": {"config": d, "agent": "definity"}, "phases": {}}))
    return folder


def test_run_plan_rebuilds_the_runs_own_surrogates(tmp_path):
    """A run on the networks over the diameter rebuilds them, a manifest without the field the per-diameter
    files it ran on, whatever today's default is."""
    root = tmp_path / "cal"
    new = _write_manifest(root / "definity" / "reduced-acoustic", CalibrationConfig(agents=("definity",), out=root))
    assert all(s.over_diameter for s in run_plan(new).surrogates)
    assert run_config(new)[0].surrogates == "over-diameter"
    root2 = tmp_path / "old"
    old = _write_manifest(root2 / "definity" / "reduced-acoustic", CalibrationConfig(agents=("definity",), out=root2),
                          drop=("surrogates",))
    ap = run_plan(old)
    assert _files(ap) == ["compression_2.1um.npz", "compression_2.9um.npz", "compression_3um.npz"]
    assert not isinstance(ap.f_res, AcousticLawSurrogate)


class _RecordingBundle:
    """Answers ``get`` with a sentinel error after recording its keyword arguments."""

    def __init__(self):
        self.calls = []

    def get(self, setup, diameter_um, **kwargs):
        self.calls.append(kwargs)
        raise LookupError("recorded")


def test_confirm_and_evidence_ask_another_bundle_for_the_runs_kind(tmp_path, synthetic_bundle):
    from bubblecal.workflows.confirm import confirm_run
    from bubblecal.workflows.evidence import run_evidence

    root = tmp_path / "cal"
    config = CalibrationConfig(agents=("definity",), workflow="reduced", bundle=synthetic_bundle, out=root,
                               paper=True, surrogates="per-diameter", curves=("definity_compression_2.1um",))
    folder = _write_manifest(root / "definity" / "reduced", config)
    fake = _RecordingBundle()
    with pytest.raises(LookupError, match="recorded"):
        confirm_run(folder, tier="quasistatic", bundle=fake)
    assert fake.calls == [{"prefer": "per-diameter", "network": "fast"}]
    fake = _RecordingBundle()
    with pytest.raises(LookupError, match="recorded"):
        run_evidence(["definity"], fake, curves=("definity_compression_2.1um",))
    assert fake.calls == [{"prefer": "over-diameter", "network": "fast"}]
    fake = _RecordingBundle()
    with pytest.raises(LookupError, match="recorded"):
        run_evidence(["definity"], fake, surrogates="per-diameter", networks="accurate")
    assert fake.calls == [{"prefer": "per-diameter", "network": "accurate"}]


def test_a_bundle_without_networks_over_the_diameter_still_plans(tmp_path, synthetic_bundle):
    """The synthetic bundle has only per-diameter files and quadratics: the default falls back to them."""
    plan = make_plan(CalibrationConfig(bundle=synthetic_bundle, population=200, out=tmp_path / "o"),
                     check_likelihoods=False)
    assert plan.config.resolved_surrogates == "over-diameter"
    for ap in plan.agents:
        assert not any(s.over_diameter for s in ap.surrogates) and len(ap.surrogates) == 3
        assert ap.f_res is not None and not isinstance(ap.f_res, AcousticLawSurrogate)


def test_bad_choices_are_named(tmp_path, synthetic_bundle):
    with pytest.raises(CalibrationError, match="--surrogates must be one of over-diameter, per-diameter"):
        make_plan(CalibrationConfig(bundle=synthetic_bundle, surrogates="both", out=tmp_path / "o"))
    curves = tmp_path / "c.csv"
    curves.write_text("bubble,agent,protocol,diameter_um,displacement_nm,force_nN\nb1,lab,compression,2.5,10,0.2\n")
    with pytest.raises(CalibrationError, match="--surrogates per-diameter: .* with --data CURVES.csv"):
        make_plan(CalibrationConfig(data=curves, surrogates="per-diameter", out=tmp_path / "o"))
    r = CliRunner().invoke(app, ["calibrate", "--surrogates", "both", "--bundle", str(synthetic_bundle)])
    assert r.exit_code == 2 and "'both' is not one of" in r.output
    assert SURROGATE_CHOICES == ("over-diameter", "per-diameter")
