"""The calibration report: notes on hyperparameters piled at a hyperprior bound."""

from __future__ import annotations


def test_hyperprior_bound_notes_flag_only_pressed_bounds():
    """m_ka piled at its lower hyperprior bound is reported; a tau well inside its range is not."""
    import pandas as pd

    from bubblecal.priors import load_priors
    from bubblecal.workflows.report import hyperprior_bound_notes

    spec = load_priors("definity_reduced_acoustic")
    lo, hi = spec.parameters["ka"].hyper_m.as_tuple()
    tlo, thi = spec.parameters["ka"].hyper_tau.as_tuple()
    hyp = pd.DataFrame([
        {"parameter": "m_ka", "q05": lo + 0.001 * (hi - lo), "q95": lo + 0.3 * (hi - lo)},
        {"parameter": "tau_ka", "q05": tlo + 0.2 * (thi - tlo), "q95": tlo + 0.7 * (thi - tlo)},
    ])
    notes = hyperprior_bound_notes(hyp, spec)
    assert len(notes) == 1 and notes[0].startswith("m_ka") and "lower" in notes[0]
