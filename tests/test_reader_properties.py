"""Property-based tests of every reader a user feeds (hypothesis, derandomized, few examples).

Generated malformed inputs — damaged copies of valid files (truncated, bytes flipped, lines dropped or
duplicated, values replaced by huge, non-finite, negative or non-numeric ones) — must end in the project's own
error type with a message naming the file, or be accepted with only finite, plausible values: never another
exception.
"""

from __future__ import annotations

import json
import math
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bubblecal.data import (
    PLAUSIBLE_RANGES,
    DataError,
    TidyDataError,
    load_acoustic_table,
    load_curve,
    published_tidy_paths,
    read_bubble_curves,
    read_resonance,
)

ROOT = Path(__file__).resolve().parents[1]
CURVE = ROOT / "data" / "reference" / "definity_compression_2.1um_dpd.csv"
PHYSICAL = ROOT / "data" / "reference" / "sonovue_indentation_3.2um_source_physical.csv"
ACOUSTIC = ROOT / "data" / "reference" / "acoustic_observations_published.csv"
TIDY_CURVES, TIDY_RESONANCE = published_tidy_paths()
PRIORS = ROOT / "priors" / "definity_reduced_acoustic.toml"
CAMPAIGN = ROOT / "tests" / "campaigns" / "tiny_campaign.toml"
BUNDLE = ROOT / "surrogates" / "bundle"
NPZ = sorted(BUNDLE.glob("*.npz"))[0]

PROFILE = settings(derandomize=True, max_examples=60, deadline=None, database=None,
                   suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

#: Tokens a damaged or hand-edited file holds in place of a value.
BAD_TOKENS = ["1e300", "-1e300", "nan", "inf", "-inf", "-3", "0", "", "abc", "1,5", "1;5", "\"", "0x10", "1e-320",
              "[", "]", "=", "{", "true", "\ufeff", "\x00", "é"]


@st.composite
def damaged_text(draw, original: str):
    """``original`` with one to three edits: a token replaced, a line dropped/duplicated, a cut, a BOM, ';'."""
    text = original
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["token", "token", "drop", "dup", "cut", "bom", "semicolon", "tab"]))
        lines = text.splitlines(keepends=True)
        if kind == "token":
            pieces = text.replace("\n", ",\n").split(",")
            i = draw(st.integers(0, len(pieces) - 1))
            pieces[i] = draw(st.sampled_from(BAD_TOKENS)) + ("\n" if pieces[i].endswith("\n") else "")
            text = ",".join(pieces).replace(",\n", "\n")
        elif kind in ("drop", "dup") and lines:
            i = draw(st.integers(0, len(lines) - 1))
            lines[i:i + 1] = [] if kind == "drop" else [lines[i], lines[i]]
            text = "".join(lines)
        elif kind == "cut":
            text = text[: draw(st.integers(0, len(text)))]
        elif kind == "bom":
            text = "\ufeff" + text
        else:
            text = text.replace(",", ";" if kind == "semicolon" else "\t")
    return text


@st.composite
def damaged_bytes(draw, original: bytes):
    """``original`` truncated, with bytes flipped, or with garbage appended."""
    data = bytearray(original)
    kind = draw(st.sampled_from(["cut", "flip", "flip", "append"]))
    if kind == "cut":
        return bytes(data[: draw(st.integers(0, len(data) - 1))])
    if kind == "append":
        return bytes(data) + draw(st.binary(min_size=1, max_size=64))
    for _ in range(draw(st.integers(1, 8))):
        i = draw(st.integers(0, len(data) - 1))
        data[i] ^= draw(st.integers(1, 255))
    return bytes(data)


_SCRATCH: dict[str, Path] = {}


@pytest.fixture(autouse=True, scope="module")
def _scratch_root():
    """One scratch folder for the module's generated files, removed afterwards (hypothesis examples cannot
    take the function-scoped ``tmp_path``)."""
    root = Path(tempfile.mkdtemp(prefix="bubblecal-prop-"))
    _SCRATCH["root"] = root
    yield root
    shutil.rmtree(root, ignore_errors=True)


def _write(content, name: str) -> Path:
    folder = Path(tempfile.mkdtemp(dir=_SCRATCH["root"]))
    path = folder / name
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")
    return path


def _plausible(values, quantity: str) -> bool:
    rng = PLAUSIBLE_RANGES[quantity]
    v = np.asarray(values, dtype=float)
    return bool(np.all(np.isfinite(v)) and np.all(v >= rng.lo) and np.all(v <= rng.hi))


# -------------------------------------------------------------------------------------------------
# data: curve CSVs (DPD and physical) and acoustic tables
# -------------------------------------------------------------------------------------------------
@PROFILE
@given(damaged_text(CURVE.read_text()))
def test_curve_csv(text):
    path = _write(text, "curve.csv")
    try:
        curve = load_curve(path, "compression", "dpd")
    except DataError as exc:
        assert str(path) in str(exc)
        return
    assert _plausible(curve.force_nN, "force") and _plausible(curve.displacement_nm, "displacement")
    assert np.all(np.diff(curve.x) > 0)


@PROFILE
@given(damaged_text(PHYSICAL.read_text()))
def test_physical_curve_csv(text):
    path = _write(text, "physical.csv")
    try:
        curve = load_curve(path, "indentation", "physical")
    except DataError as exc:
        assert str(path) in str(exc)
        return
    assert _plausible(curve.source_curve.x, "force") and _plausible(curve.source_curve.y, "displacement")


@PROFILE
@given(damaged_text(ACOUSTIC.read_text()))
def test_acoustic_table(text):
    path = _write(text, "acoustic.csv")
    try:
        rows = load_acoustic_table(path)
    except DataError as exc:
        assert str(path) in str(exc)
        return
    assert _plausible([r.diameter_um for r in rows], "diameter")
    assert _plausible([r.frequency_MHz for r in rows], "resonance_frequency")


@PROFILE
@given(damaged_text(TIDY_CURVES.read_text()))
def test_tidy_curves(text):
    path = _write(text, "curves.csv")
    try:
        curves = read_bubble_curves(path)
    except TidyDataError as exc:
        assert str(path) in str(exc)
        return
    for b in curves:
        assert b.n_retained >= 3 and np.all(np.diff(b.x) > 0)
        assert _plausible(b.loading_curve().force_nN, "force") and _plausible([b.diameter_um], "diameter")


@PROFILE
@given(st.one_of(damaged_bytes(TIDY_CURVES.read_bytes()[:3000]), damaged_bytes(TIDY_RESONANCE.read_bytes())))
def test_tidy_bytes(data):
    path = _write(data, "tidy.csv")
    for reader in (read_bubble_curves, read_resonance):
        try:
            reader(path)
        except TidyDataError as exc:
            assert str(path) in str(exc)


@PROFILE
@given(damaged_text(TIDY_RESONANCE.read_text()))
def test_tidy_resonance(text):
    path = _write(text, "resonance.csv")
    try:
        res = read_resonance(path)
    except TidyDataError as exc:
        assert str(path) in str(exc)
        return
    assert _plausible(res.diameter_um, "diameter") and _plausible(res.frequency_MHz, "resonance_frequency")


# -------------------------------------------------------------------------------------------------
# priors and campaign TOML
# -------------------------------------------------------------------------------------------------
@PROFILE
@given(damaged_text(PRIORS.read_text()))
def test_priors_toml(text):
    from bubblecal.priors import PriorError, load_priors

    path = _write(text, "priors.toml")
    try:
        spec = load_priors(path)
    except PriorError as exc:
        assert str(path) in str(exc)
        return
    for p in spec.parameters.values():
        assert math.isfinite(p.prior.lo) and math.isfinite(p.prior.hi) and p.prior.lo < p.prior.hi


@PROFILE
@given(damaged_text(CAMPAIGN.read_text()))
def test_campaign_toml(text):
    from bubblecal.campaigns import CampaignFileError, load_campaign_file

    path = _write(text, "campaign.toml")
    try:
        cf = load_campaign_file(path, store=path.parent / "store")
    except CampaignFileError as exc:
        assert str(path) in str(exc)
        return
    assert cf.config.n_samples >= 1


@PROFILE
@given(st.binary(max_size=200))
def test_priors_and_campaign_toml_from_raw_bytes(data):
    from bubblecal.campaigns import CampaignFileError, load_campaign_file
    from bubblecal.priors import PriorError, load_priors

    path = _write(data, "raw.toml")
    with pytest.raises(PriorError, match=str(path)):
        load_priors(path)
    with pytest.raises(CampaignFileError, match=str(path)):
        load_campaign_file(path)


# -------------------------------------------------------------------------------------------------
# surrogates: the .npz file, the bundle manifest, the acoustic surrogate JSON
# -------------------------------------------------------------------------------------------------
@PROFILE
@given(damaged_bytes(NPZ.read_bytes()))
def test_surrogate_npz(data):
    from bubblecal.surrogates import SurrogateFormatError, load

    path = _write(data, "surrogate.npz")
    try:
        sur = load(path)
    except SurrogateFormatError as exc:
        assert str(path) in str(exc)
        return
    assert all(np.all(np.isfinite(w)) for w in sur.weights) and all(np.all(np.isfinite(b)) for b in sur.biases)


def _copy_bundle() -> Path:
    folder = Path(tempfile.mkdtemp(dir=_SCRATCH["root"])) / "bundle"
    shutil.copytree(BUNDLE, folder)
    return folder


@PROFILE
@given(damaged_text((BUNDLE / "manifest.json").read_text()))
def test_bundle_manifest(text):
    from bubblecal.surrogates import SurrogateFormatError, load_bundle
    from bubblecal.surrogates.acoustic import AcousticFormatError

    folder = _copy_bundle()
    (folder / "manifest.json").write_text(text, encoding="utf-8")
    try:
        load_bundle(folder)
    except (SurrogateFormatError, AcousticFormatError, FileNotFoundError) as exc:
        assert str(folder) in str(exc)


@PROFILE
@given(damaged_text((BUNDLE / "acoustic_definity.json").read_text()))
def test_acoustic_surrogate_json(text):
    from bubblecal.surrogates import AcousticFormatError, AcousticSurrogate

    path = _write(text, "acoustic.json")
    try:
        sur = AcousticSurrogate.load(path)
    except AcousticFormatError as exc:
        assert str(path) in str(exc)
        return
    for d in sur.diameters:
        assert np.all(np.isfinite(sur.coefficients(d)))


def test_the_undamaged_files_are_accepted():
    """The strategies start from valid files (else every property would hold vacuously)."""
    from bubblecal.campaigns import load_campaign_file
    from bubblecal.priors import load_priors
    from bubblecal.surrogates import AcousticSurrogate, load, load_bundle

    assert load_curve(CURVE, "compression").n_points > 3 and load_curve(PHYSICAL, "indentation", "physical")
    assert len(load_acoustic_table(ACOUSTIC)) == 17 and load_priors(PRIORS).acoustic
    assert load_campaign_file(CAMPAIGN).config.n_samples == 2 and load(NPZ).setup
    assert load_bundle(BUNDLE).acoustic and AcousticSurrogate.load(BUNDLE / "acoustic_definity.json").diameters
    assert json.loads((BUNDLE / "manifest.json").read_text())["surrogates"]


JSON_VALUES = [None, True, -1, 0, 1e300, "x", [], {}, [1], {"a": 1}, float("nan")]


def _paths(obj, prefix=()):
    yield prefix
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _paths(v, (*prefix, k))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _paths(v, (*prefix, i))


@st.composite
def damaged_json(draw, original: str):
    """``original`` (JSON) with one value, at any depth, replaced by a value of another type or a bad number."""
    obj = json.loads(original)
    paths = [p for p in _paths(obj) if p]
    path = draw(st.sampled_from(paths))
    node = obj
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = draw(st.sampled_from(JSON_VALUES))
    return json.dumps(obj)


@PROFILE
@given(damaged_json((BUNDLE / "acoustic_definity.json").read_text()))
def test_acoustic_surrogate_json_structure_through_a_bundle(text):
    from bubblecal.surrogates import SurrogateFormatError, load_bundle
    from bubblecal.surrogates.acoustic import AcousticFormatError

    folder = _copy_bundle()
    (folder / "acoustic_definity.json").write_text(text, encoding="utf-8")
    try:
        bundle = load_bundle(folder)
    except (SurrogateFormatError, AcousticFormatError) as exc:
        assert str(folder) in str(exc)
        return
    for d in bundle.acoustic["definity"].diameters:
        assert np.all(np.isfinite(bundle.acoustic["definity"].coefficients(d)))


@PROFILE
@given(damaged_json((BUNDLE / "acoustic_definity.json").read_text()))
def test_acoustic_surrogate_json_structure(text):
    test_acoustic_surrogate_json.hypothesis.inner_test(text)


@PROFILE
@given(damaged_json((BUNDLE / "manifest.json").read_text()))
def test_bundle_manifest_structure(text):
    test_bundle_manifest.hypothesis.inner_test(text)
