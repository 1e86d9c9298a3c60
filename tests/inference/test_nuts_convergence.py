"""When a NUTS run counts as converged, and the sentence that names what it misses."""

import pytest

from bubblecal.inference.nuts import NUTSResult


def _result(r_hat, n_eff, divergences):
    return NUTSResult(samples={}, samples_by_chain={}, summary={}, max_r_hat=r_hat, min_n_eff=n_eff,
                      num_divergences=divergences, mcmc=None)


def test_a_converged_run_has_no_note():
    res = _result(1.005, 812.0, 0)
    assert res.converged and res.convergence_note() is None


@pytest.mark.parametrize(("r_hat", "n_eff", "div", "shown"), [
    (1.2, 812.0, 0, "max r_hat 1.2"),
    (1.005, 120.0, 0, "min bulk ESS 120"),
    (1.005, 812.0, 3, "3 divergences"),
])
def test_each_criterion_makes_a_run_unconverged_and_the_note_shows_it(r_hat, n_eff, div, shown):
    res = _result(r_hat, n_eff, div)
    note = res.convergence_note()
    assert not res.converged
    assert note.startswith("NUTS did not converge") and shown in note and "not reliable" in note
