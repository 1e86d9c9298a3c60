"""Acoustic ringdown sweeps: simulate R(t) over a k_a grid, fit, convert to MHz, fit f_res²(k_a).

Pipeline (``docs/physics.md`` section 5)::

    result = ringdown_sweep("definity", 2.1)          # sweep.py: simulate + fit each R(t), MHz
    fits = fit_sweep(result)                          # fit.py: f_res² = a0 + a1 k_a + a2 k_a² per diameter
    write_sweep_outputs(result, "out", fits[2.1])     # output.py: CSV, JSON, traces, PNG

1. :func:`ringdown_sweep`: one diameter, ``n_ka`` k_a values (default 28, evenly spaced over the agent's
   acoustic prior range of k_a), μ = k_a / 3, k_b fixed (:data:`AGENT_KB`), b1 = b2 = a3 = a4 = 0. Each
   R(t) is fitted with :func:`bubblecal.surrogates.fit_ringdown` and converted to MHz; the check-7
   ratio (2π f_0)² / ω0² (``docs/physics.md`` section 6) is reported per row.
2. :func:`fit_sweep`: :func:`bubblecal.surrogates.acoustic.fit_quadratic` per diameter (f_res in MHz) with
   leave-one-out relative errors.
3. :func:`write_sweep_outputs`: CSV (one row per k_a), JSON (rows, fit, settings) and a PNG.

Ringdown campaign stores are refitted by :func:`sweeps_from_store` (stores.py), and
:func:`acoustic_surrogate_from_stores` turns them into the agent's acoustic surrogate (one quadratic per
diameter); :func:`acoustic_law_from_stores` (law.py) into one law continuous in the diameter.

Units: k_a DPD 2-D modulus, k_b DPD energy, ``f_*_dpd`` cycles per DPD time, ``f_*_MHz`` physical MHz.
"""

from bubblecal.workflows.acoustic_sweep.fit import (
    acoustic_surrogate_from_stores,
    fit_sweep,
    read_sweeps,
    write_rows_csv,
)
from bubblecal.workflows.acoustic_sweep.law import acoustic_law_from_stores, law_rows
from bubblecal.workflows.acoustic_sweep.output import write_sweep_outputs
from bubblecal.workflows.acoustic_sweep.stores import sweeps_from_rows_csv, sweeps_from_store
from bubblecal.workflows.acoustic_sweep.sweep import (
    ACOUSTIC_PRIOR,
    AGENT_KB,
    ROW_FIELDS,
    SweepResult,
    check_agent,
    default_ka_values,
    ringdown_sweep,
    sweep_row,
)

__all__ = ["AGENT_KB", "ACOUSTIC_PRIOR", "ROW_FIELDS", "check_agent", "SweepResult", "default_ka_values",
           "ringdown_sweep", "sweep_row", "fit_sweep", "write_sweep_outputs", "sweeps_from_store",
           "sweeps_from_rows_csv", "acoustic_surrogate_from_stores", "read_sweeps", "write_rows_csv",
           "acoustic_law_from_stores", "law_rows"]
