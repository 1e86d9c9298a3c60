"""The tier interface: request validation and the published conventions it applies."""

import numpy as np
import pytest

from bubblecal.sim.tiers import KB_KERNEL_SCALE, CurveRequest

PARAMS = {"ka": [5584.0, 8000.0], "kb": [389.23, 600.0], "b1": [0.0, 1.0], "b2": [0.0, 2.0], "a3": [-2.0, 0.5],
          "a4": [8.0, 1.0]}


@pytest.mark.parametrize("protocol", ["compression", "indentation"])
def test_shell_params_carry_the_protocol_kb_convention(protocol):
    req = CurveRequest(protocol, 3.0, (0.0, 0.5), PARAMS, (1, 2))
    sp = req.shell_params()
    assert [p.ka for p in sp] == PARAMS["ka"] and [p.a4 for p in sp] == PARAMS["a4"]
    np.testing.assert_allclose([p.kb for p in sp], np.array(PARAMS["kb"]) * KB_KERNEL_SCALE[protocol], rtol=1e-15)
    assert all(p.mu is None or p.mu == pytest.approx(p.ka / 3) for p in sp)
    assert KB_KERNEL_SCALE == {"compression": 1.0, "indentation": pytest.approx(2.0 / 3.0)}


def test_bad_request_names_the_field():
    with pytest.raises(ValueError, match="CurveRequest.seeds must have one seed per replica"):
        CurveRequest("compression", 3.0, (0.0, 0.5), PARAMS, (1,))
    with pytest.raises(ValueError, match=r"CurveRequest.params is missing \['a4'\]"):
        CurveRequest("compression", 3.0, (0.0, 0.5), {k: v for k, v in PARAMS.items() if k != "a4"}, (1, 2))
    with pytest.raises(ValueError, match="CurveRequest.grid must be"):
        CurveRequest("compression", 3.0, (0.5, 0.1), PARAMS, (1, 2))
    with pytest.raises(ValueError, match="CurveRequest.protocol must be one of"):
        CurveRequest("shear", 3.0, (0.0, 0.5), PARAMS, (1, 2))


def test_indentation_conventions_map_kb_and_name_the_allowed_values():
    from bubblecal.sim.tiers import (
        DEFAULT_INDENTATION_CONVENTION,
        INDENTATION_CONVENTIONS,
        indentation_convention,
    )

    assert DEFAULT_INDENTATION_CONVENTION == "bubblecal-v1"  # campaign files without the setting keep their design
    assert indentation_convention("bubblecal-v1").kb_scale == pytest.approx(KB_KERNEL_SCALE["indentation"])
    assert indentation_convention("mirheo").kb_scale == 1.0
    # the published patch: the pole vertex and its first ring on the subdivision-4 icosphere (2,562 vertices),
    # the same cap (two rings) at subdivision 5; bubblecal-v1: 1 % of the vertices
    from bubblecal.sim.engine import icosphere, pole_patches

    for sub, n_mirheo, n_v1 in ((4, 7, 25), (5, 19, 102)):
        v = icosphere(11.5, sub).vertices
        assert len(pole_patches(v, **indentation_convention("mirheo").pole_patch())[0]) == n_mirheo
        assert len(pole_patches(v, **indentation_convention("bubblecal-v1").pole_patch())[1]) == n_v1
    ind = CurveRequest("indentation", 3.2, (0.0, 500.0), PARAMS, (1, 2))
    np.testing.assert_allclose([p.kb for p in ind.shell_params("mirheo")], PARAMS["kb"], rtol=1e-15)
    comp = CurveRequest("compression", 3.0, (0.0, 0.5), PARAMS, (1, 2))
    assert [p.kb for p in comp.shell_params("mirheo")] == [p.kb for p in comp.shell_params()]  # compression: no change
    with pytest.raises(ValueError, match=r"indentation_convention must be one of \['bubblecal-v1', 'mirheo'\]"):
        ind.shell_params("Mirheo")
    assert set(INDENTATION_CONVENTIONS) == {"bubblecal-v1", "mirheo"}


def test_tiers_reject_an_unknown_indentation_convention_at_construction():
    pytest.importorskip("warp")
    from bubblecal.sim.tiers import get_tier

    for tier in ("quasistatic", "explicit", "implicit"):
        with pytest.raises(ValueError, match="indentation_convention must be one of"):
            get_tier(tier, indentation_convention="v2")


def _published_rows(ref, rows):
    from bubblecal.surrogates.training import filter_curves, read_published

    ts, _ = filter_curves(read_published(ref / "training_head_indentation_3.2um.csv", setup="indentation"))
    return ts.subset(np.asarray(rows))


@pytest.mark.slow  # two published rows at subdivision 4 in both conventions: ~2 min on 2 cores
def test_mirheo_convention_reproduces_the_published_indentation_curves(shared_reference):
    """Quasi-static d(F) / published d(F) on two 3.2 um training rows of very different ka / kb (16 and 0.8):
    with the ``mirheo`` convention both are 0.97-0.98 (measured; asserted in [0.95, 1.0]) and within 2 % of each
    other; the ``bubblecal-v1`` patch (25 vertices) gives 0.95 and 1.10, a ka / kb-dependent error (RESULTS.md)."""
    pytest.importorskip("warp")
    from bubblecal.data import SHELL_PARAMETERS
    from bubblecal.sim.tiers import get_tier

    ts = _published_rows(shared_reference, [0, 2])
    params = {k: ts.params[:, j] for j, k in enumerate(SHELL_PARAMETERS)}
    req = CurveRequest("indentation", 3.2, tuple(ts.x[0]), params, (0, 1), subdivisions=4)
    pts = slice(4, 15)
    ratio = {}
    for conv in ("mirheo", "bubblecal-v1"):
        batch = get_tier("quasistatic", indentation_convention=conv).run(req)
        assert batch.status == ["ok", "ok"] and batch.info["indentation_convention"] == conv
        ratio[conv] = np.median(batch.observable[:, pts] / ts.y[:, pts], axis=1)
    assert np.all((ratio["mirheo"] > 0.95) & (ratio["mirheo"] < 1.0)), ratio
    assert abs(ratio["mirheo"][0] - ratio["mirheo"][1]) < 0.02, ratio
    assert abs(ratio["bubblecal-v1"][0] - ratio["bubblecal-v1"][1]) > 0.1, ratio
