"""The tidy input format: a good file round-trips, every bad-input class is named, units are sniffed, and the
published study read in this format equals the shipped reference curves and acoustic table."""

from __future__ import annotations

import numpy as np
import pytest

from bubblecal.data import (
    DEFAULT_UNITS,
    REFERENCE_CURVES,
    DataError,
    TidyDataError,
    acoustic_observations,
    check_consistency,
    load_reference,
    published_tidy_paths,
    read_bubble_curves,
    read_resonance,
    tidy_kind,
    write_published_tidy,
)

HEADER = "bubble,agent,protocol,diameter_um,displacement_nm,force_nN,retained\n"


def _rows(bubble="b1", agent="lab", protocol="compression", d=3.0, disp=(10, 20, 30, 40), force=(0.1, 0.2, 0.4, 0.8),
          retained=(1, 1, 1, 1)) -> str:
    return "".join(f"{bubble},{agent},{protocol},{d},{x},{f},{r}\n"
                   for x, f, r in zip(disp, force, retained, strict=True))


def _write(tmp_path, text: str, name="curves.csv"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _problems(path, reader=read_bubble_curves) -> list[str]:
    with pytest.raises(TidyDataError) as info:
        reader(path)
    assert str(path) in str(info.value)
    return info.value.problems


def test_good_file_round_trip(tmp_path):
    text = HEADER + _rows() + _rows("b2", "lab", "compression", 2.5, retained=(0, 1, 1, 1)) + \
        "c1,other,indentation,4.0,5,0.1,1\nc1,other,indentation,4.0,9,0.3,1\nc1,other,indentation,4.0,12,0.6,1\n"
    curves = read_bubble_curves(_write(tmp_path, text))
    assert [b.bubble for b in curves] == ["b1", "b2", "c1"]
    assert curves.agents == ("lab", "other")
    assert curves.counts() == {"lab": {"bubbles": 2, "points": 8, "retained": 7},
                               "other": {"bubbles": 1, "points": 3, "retained": 3}}
    assert list(curves.by_agent_protocol()) == [("lab", "compression"), ("other", "indentation")]
    b1, b2, c1 = curves.bubbles
    np.testing.assert_allclose(b1.x, DEFAULT_UNITS.nm_to_dpd([10, 20, 30, 40]))
    np.testing.assert_allclose(b1.y, DEFAULT_UNITS.nN_to_dpd([0.1, 0.2, 0.4, 0.8]))
    # indentation: x = force, y = displacement
    np.testing.assert_allclose(c1.x, DEFAULT_UNITS.nN_to_dpd([0.1, 0.3, 0.6]))
    np.testing.assert_allclose(c1.y, DEFAULT_UNITS.nm_to_dpd([5, 9, 12]))
    assert b2.retained.tolist() == [False, True, True, True] and b2.lines == (6, 7, 8, 9)
    curve = b2.loading_curve()
    assert curve.n_points == 3 and curve.source_curve.x.size == 4 and curve.kind == "compression"
    np.testing.assert_allclose(curve.source_curve.x, [10, 20, 30, 40])
    with pytest.raises(ValueError):
        b1.x[0] = 1.0
    assert tidy_kind(tmp_path / "curves.csv") == "curves"


def test_retained_column_is_optional(tmp_path):
    text = "bubble,agent,protocol,diameter_um,displacement_nm,force_nN\n" + "".join(
        f"b,a,compression,3,{x},{f}\n" for x, f in ((1, 0.1), (2, 0.2), (3, 0.3)))
    assert read_bubble_curves(_write(tmp_path, text)).bubbles[0].n_retained == 3


def test_every_problem_is_listed_at_once(tmp_path):
    text = (HEADER
            + _rows("ok1")
            + "p1,lab,squeeze,3,10,0.1,1\n"             # unknown protocol
            + "p2,lab,compression,abc,10,0.1,1\n"       # non-numeric
            + "p3,lab,compression,3,10,0.1,yes\n"       # retained not 0/1
            + _rows("few", retained=(1, 1, 0, 0))       # fewer than 3 retained
            + _rows("mono", disp=(10, 30, 20, 40))      # not monotone
            + _rows("huge", force=(0.1, 0.2, 0.4, 2e4))  # one force out of range
            + _rows("dd", d=3.0)[:-1] + "\n" + "dd,lab,compression,3.5,50,1.0,1\n"  # diameters disagree
            + "mix,lab,compression,3,10,0.1,1\nmix,labb,compression,3,20,0.2,1\nmix,lab,compression,3,30,0.3,1\n"
            + _rows("dup", agent="A") + _rows("dup", agent="B", disp=(50, 60, 70, 80))
            + "short,lab,compression,3\n")
    problems = _problems(_write(tmp_path, text))
    joined = "\n".join(problems)
    expected = ["unknown protocol 'squeeze'", "'abc' is not a number", "'yes' must be 0 or 1",
                "bubble 'few' (rows", "only 2 retained points; a bubble needs at least 3",
                "the curve is not monotone", "plausible range [0, 10000] nN",
                "bubble 'dd': its rows disagree on diameter_um", "bubble 'mix': its rows disagree on agent",
                "bubble 'dup': the id is used in 2 agents", "4 cells, expected 7"]
    for text_ in expected:
        assert text_ in joined, text_
    # row and line of a problem: p1 is data row 5, file line 6
    assert any(p.startswith("row 5 (line 6), column 'protocol'") for p in problems)
    assert "ok1" not in joined


@pytest.mark.parametrize(("column", "values", "message"), [
    ("force", (1e-10, 2e-10, 4e-10, 8e-10), "forces 1e-10 to 8e-10 look like newtons (N): give nN"),
    ("force", (2e4, 3e4, 5e4, 9e4), "look like pN: give nN"),
    ("disp", (0.01, 0.02, 0.03, 0.04), "displacements 0.01 to 0.04 look like um: give nm"),
    ("disp", (1e-8, 2e-8, 3e-8, 4e-8), "look like metres (m): give nm"),
    ("diameter", 3000.0, "diameter 3e+03 to 3e+03 look like nm: give um"),
    ("diameter", 3e-6, "look like metres (m): give um"),
])
def test_unit_sniffing_names_the_probable_unit(tmp_path, column, values, message):
    kwargs = {"force": {"force": values}, "disp": {"disp": values}, "diameter": {"d": values}}[column]
    problems = _problems(_write(tmp_path, HEADER + _rows(**kwargs)))
    assert any(message in p for p in problems), problems
    # the sniffed column is not also reported as implausible
    assert not any("carries no signal" in p or "outside the plausible range" in p for p in problems), problems


def test_header_problems_with_near_miss_hint(tmp_path):
    path = _write(tmp_path, "bubble,agent,protocol,diameter_um,displacement_nm,force_nn,colour\n"
                            "b,a,compression,3,1,1,x\n")
    joined = "\n".join(_problems(path))
    assert "unknown column 'force_nn' (did you mean 'force_nN'?)" in joined
    assert "unknown column 'colour'" in joined and "missing column 'force_nN'" in joined


def test_separator_and_empty_file_hints(tmp_path):
    semi = _write(tmp_path, HEADER.replace(",", ";") + "b;a;compression;3;1;1;1\n", "semi.csv")
    assert "semicolon-separated" in _problems(semi)[0]
    assert "file is empty" in _problems(_write(tmp_path, "\n\n", "empty.csv"))[0]
    with pytest.raises(DataError, match="file not found"):
        read_bubble_curves(tmp_path / "missing.csv")


def test_resonance_file_and_consistency(tmp_path):
    curves = read_bubble_curves(_write(tmp_path, HEADER + _rows()))
    good = read_resonance(_write(tmp_path, "agent,diameter_um,frequency_MHz\nlab,3.0,2.5\nlab,4,1.5\n", "r.csv"))
    assert good.agents == ("lab",) and good.source == ("", "")
    np.testing.assert_allclose(good.frequency_dpd, DEFAULT_UNITS.frequency_to_dpd(np.array([2.5, 1.5]) * 1e6))
    check_consistency(curves, good)
    orphan = read_resonance(_write(tmp_path, "agent,diameter_um,frequency_MHz,source\nlab,3,2,x\nghost,3,2,y\n",
                                   "o.csv"))
    with pytest.raises(TidyDataError, match=r"row 2 \(line 3\), column 'agent': 'ghost' has no curves"):
        check_consistency(curves, orphan)
    bad = _write(tmp_path, "agent,diameter_um,frequency_MHz\nlab,3000,2.5\nlab,3,2500000\nlab,3,abc\n", "b.csv")
    joined = "\n".join(_problems(bad, read_resonance))
    assert "3000 looks like nm" in joined and "looks like Hz" in joined and "'abc' is not a number" in joined
    assert tidy_kind(tmp_path / "r.csv") == "resonance"


def test_published_files_equal_the_reference():
    curves_path, resonance_path = published_tidy_paths()
    curves = read_bubble_curves(curves_path)
    assert len(curves) == len(REFERENCE_CURVES)
    for name, (agent, _kind, nominal, measured, _) in REFERENCE_CURVES.items():
        bubble = next(b for b in curves if b.bubble == f"{agent}-{nominal:g}um")
        ref = load_reference(agent, nominal)
        assert bubble.agent == agent and bubble.diameter_um == measured, name
        got = bubble.loading_curve()
        np.testing.assert_allclose(got.x, ref.x, rtol=1e-12, err_msg=name)
        np.testing.assert_allclose(got.y, ref.y, rtol=1e-12, err_msg=name)
        np.testing.assert_array_equal(bubble.retained, ref.source_curve.retained)
    resonance = read_resonance(resonance_path)
    obs = acoustic_observations()
    assert resonance.agent == tuple(o.agent for o in obs)
    np.testing.assert_array_equal(resonance.diameter_um, [o.diameter_um for o in obs])
    np.testing.assert_array_equal(resonance.frequency_MHz, [o.frequency_MHz for o in obs])
    check_consistency(curves, resonance)


def test_published_files_are_what_the_writer_writes(tmp_path):
    written = write_published_tidy(tmp_path)
    for new, shipped in zip(written, published_tidy_paths(), strict=True):
        assert new.read_text() == shipped.read_text(), shipped.name
