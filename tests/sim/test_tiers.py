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


def test_quasistatic_tier_self_avoidance_inert_and_dtype_checked():
    pytest.importorskip("warp")
    from bubblecal.sim.tiers import get_tier

    req = CurveRequest("compression", 1.5, (0.0, 0.12, 0.24, 0.36), PARAMS, (1, 2), subdivisions=2)
    off = get_tier("quasistatic").run(req)
    on = get_tier("quasistatic", self_avoid=True).run(req)
    assert off.info["self_avoid"] is False and on.info["self_avoid"] is True
    assert off.status == on.status == ["ok", "ok"]
    # the repulsion never engages in athermal plate loading: the same curves to round-off
    np.testing.assert_allclose(off.observable, on.observable, rtol=1e-10, atol=1e-9)
    with pytest.raises(ValueError, match="dtype must be 'float64' or 'float32'"):
        get_tier("quasistatic", dtype="float16")
    with pytest.raises(ValueError, match="schedule must be"):
        get_tier("quasistatic", schedule="eager")


def test_quasistatic_tier_slot_refill_same_curves():
    pytest.importorskip("warp")
    from bubblecal.sim.tiers import get_tier

    req = CurveRequest("compression", 1.5, (0.0, 0.12, 0.24), PARAMS, (1, 2), subdivisions=2)
    whole = get_tier("quasistatic").run(req)
    one_slot = get_tier("quasistatic", max_replicas=1).run(req)
    assert one_slot.info["settings"]["max_replicas"] == 1
    assert one_slot.status == whole.status
    np.testing.assert_array_equal(one_slot.observable, whole.observable)
    for bad in (0, 2.0, True):
        with pytest.raises(ValueError, match="max_replicas must be an integer"):
            get_tier("quasistatic", max_replicas=bad)
    with pytest.raises(ValueError, match="needs schedule"):
        get_tier("quasistatic", max_replicas=4, schedule="lockstep")
