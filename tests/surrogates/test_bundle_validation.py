"""A bundle's measured validation figures (validation.json) and how `surrogates info` shows them."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from bubblecal.surrogates import SurrogateFormatError, default_bundle_path, load_bundle, load_validation
from bubblecal.surrogates.bundle_validation import validation_lines
from bubblecal.workflows.cli import app

GOOD = {"format": "bubblecal-bundle-validation", "format_version": 1,
        "networks": {"net.npz": {"explicit_tier": {"gate": 0.03, "source": "bench x", "rows": [
            {"diameter_um": 1.8, "median": 0.0163, "n": 7}, {"diameter_um": 7.0, "median": 0.271}]},
            "published_rows": {"rows": [{"diameter_um": 2.1, "median": 0.0325, "per_diameter": 0.0327}]}}}}


def test_lines_of_one_network(tmp_path):
    (tmp_path / "validation.json").write_text(json.dumps(GOOD))
    figures = load_validation(tmp_path)
    explicit, published = validation_lines(figures, "net.npz")
    assert explicit.startswith("  training curves vs the explicit tier at new diameters: 1.8 um 1.63 % (7 sets), "
                               "7 um 27.10 %; gate 3 % (bench x)")
    assert "2.1 um 3.25 % [3.27 %]" in published and validation_lines(figures, "other.npz") == []
    assert load_validation(tmp_path / "nothing") == {}


@pytest.mark.parametrize(("change", "message"), [
    (lambda d: d.update(format_version=2), "format_version"),
    (lambda d: d.update(networks=[]), "field 'networks'"),
    (lambda d: d["networks"]["net.npz"].update(holdout={"rows": [{"diameter_um": 1, "median": 0.1}]}),
     r"networks\.net\.npz\.holdout: unknown kind; allowed: explicit_tier, published_rows"),
    (lambda d: d["networks"]["net.npz"]["explicit_tier"].update(rows=[]), "'rows' must be a non-empty list"),
    (lambda d: d["networks"]["net.npz"]["explicit_tier"]["rows"][1].update(median="27 %"),
     r"explicit_tier\.rows\[1\]: needs numbers 'diameter_um' and 'median'"),
])
def test_malformed_files_are_named(tmp_path, change, message):
    doc = json.loads(json.dumps(GOOD))
    change(doc)
    (tmp_path / "validation.json").write_text(json.dumps(doc))
    with pytest.raises(SurrogateFormatError, match=message):
        load_validation(tmp_path)
    (tmp_path / "validation.json").write_text("{not json")
    with pytest.raises(SurrogateFormatError, match="validation.json: not JSON"):
        load_validation(tmp_path)


def test_the_shipped_bundle_shows_its_figures():
    """Every network over the diameter of the default bundle has the explicit-tier figures, and info prints them."""
    path = default_bundle_path()
    figures = load_validation(path)
    bundle = load_bundle(path)
    for setup in ("compression", "indentation"):
        for role in bundle.networks(setup):
            sur = (bundle.fast if role == "fast" else bundle.over_diameter)[setup]
            assert "explicit_tier" in figures[sur.path.name]
    r = CliRunner().invoke(app, ["surrogates", "info", str(path)])
    assert r.exit_code == 0, r.output
    assert r.output.count("training curves vs the explicit tier at new diameters") == 4
    assert "against the published Mirheo rows" in r.output
