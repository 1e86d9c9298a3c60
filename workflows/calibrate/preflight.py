"""The likelihood preflight of a calibration: every dataset's log likelihood at a few prior draws, before sampling.

A dataset whose likelihood is non-finite over the prior box stops TMCMC at its first stage ("all prior draws
non-finite") after the surrogates were compiled; evaluating it at :data:`PREFLIGHT_DRAWS` draws of a fixed
seed names the dataset (curve or acoustic table, and its file) before any phase runs. The draws are made and
evaluated by phase 1's own compiled programs (:meth:`bubblecal.inference.TMCMC.prior_log_likelihood`: a batch
of the phase's population, of which the first :data:`PREFLIGHT_DRAWS` are judged), so the check compiles
nothing that phase 1 would not compile anyway. Before a staged TMCMC run, every phase-1 program of every agent (and of
its exports, for NetCDF phase files) is compiled here, several at a time
(:func:`bubblecal.inference.tmcmc.compile_ahead`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bubblecal.workflows.calibrate.config import CalibrationError

__all__ = ["PREFLIGHT_DRAWS", "PREFLIGHT_SEED", "preflight"]

#: Prior draws per dataset at which the log likelihood must be finite.
PREFLIGHT_DRAWS = 4
#: Seed of the preflight draws (fixed: a failing preflight fails the same way on rerun).
PREFLIGHT_SEED = 20_270


def preflight(plan, n_draws: int = PREFLIGHT_DRAWS, seed: int = PREFLIGHT_SEED) -> None:
    """Check that every dataset's log likelihood is finite at ``n_draws`` prior draws.

    Parameters
    ----------
    plan : bubblecal.workflows.calibrate.Plan
        The validated run (its agents' curves, acoustic datasets, surrogates and priors).
    n_draws : int
        Prior draws per dataset.
    seed : int
        Seed of the draws.

    Raises
    ------
    CalibrationError
        Naming the agent, the dataset and its file, and the values of the log likelihood, when one draw of a
        dataset gives a non-finite log likelihood (nothing has been sampled or written).
    """
    import jax

    from bubblecal.inference.tmcmc import TMCMC, RunSpec, compile_ahead
    from bubblecal.workflows.calibrate.config import phase_tmcmc_options
    from bubblecal.workflows.calibrate.device import on_device
    from bubblecal.workflows.calibrate.run import _dataset_objects, _pad_curves

    options = phase_tmcmc_options(plan.config)[0]
    options["num_particles"] = max(options["num_particles"], n_draws)
    key = jax.random.PRNGKey(seed)
    with on_device(plan.config.device):
        # the datasets as phase 1 sees them (same padding), each with its sampler: their programs are phase 1's
        runs = {ap.agent: [(d, RunSpec(TMCMC(d.model, **options), key, d.args, d.kwargs))
                           for d in _dataset_objects(ap, _pad_curves(plan.config))] for ap in plan.agents}
        if plan.config.sampler == "tmcmc":  # every agent's phase-1 programs, several at once (NetCDF: with exports)
            compile_ahead([spec for pairs in runs.values() for _, spec in pairs], exports=plan.config.netcdf)
        for ap in plan.agents:
            table = plan.config.data_dir and Path(plan.config.data_dir) / "acoustic_observations_published.csv"
            table = table if table and table.is_file() else "the shipped acoustic table"
            files = [c.path or c.source for c in ap.curves] + [table] * len(ap.acoustic)
            for (dataset, spec), where in zip(runs[ap.agent], files, strict=True):
                ll = spec.sampler.prior_log_likelihood(key, *dataset.args, **dataset.kwargs)[:n_draws]
                if not np.all(np.isfinite(ll)):
                    shown = ", ".join(f"{v:.4g}" for v in ll)
                    raise CalibrationError(
                        f"{ap.agent} dataset {dataset.name} ({where}): the log likelihood is not finite at "
                        f"{int(np.sum(~np.isfinite(ll)))} of {n_draws} prior draws ({shown}); its data cannot be "
                        "explained by any shell under these priors (check its values and units: "
                        "`bubblecal data check`)")
