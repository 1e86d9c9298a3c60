"""bubblecal.inference: samplers and what is computed from samples; knows no physics.

Every function takes a NumPyro model (built by :mod:`bubblecal.models`) or plain arrays::

    from bubblecal.inference import TMCMC, run_nuts, compare_posteriors

- :class:`TMCMC` — transitional MCMC with log evidence (``docs/inference.md`` section 5), its moves
  (:class:`RandomWalk`, :class:`KernelMove`, :func:`hmc_move`, :func:`nuts_move`) and
  :func:`clear_program_cache`, :func:`compile_ahead` and :func:`enable_program_store` (compiled programs read
  back from disk by later processes); :class:`TMCMCKernel`, the same algorithm as a ``numpyro.infer.MCMC``
  kernel (``MCMC(TMCMCKernel(model), ...)`` in place of ``MCMC(NUTS(model), ...)``); :func:`run_batched`, the
  runs of many datasets of one model structure in one compiled program; the pure core is in
  :mod:`bubblecal.inference.tmcmc`;
- :func:`run_nuts` — the NUTS cross-check; :func:`compare_posteriors` — agreement of two samplers;
- :func:`run_staged` and the staged (Korali-style) hierarchy (section 4);
- posterior-predictive metrics (section 7): :func:`predictive_band`, :func:`coverage`,
  :func:`predictive_crps`, :func:`map_index`, ...;
- :class:`ExportInfo`, :func:`build_inference_data`, :func:`pointwise_log_likelihood` — ArviZ-complete exports
  (named dims, units, pointwise log likelihood); :func:`write_netcdf` — such an export as ArviZ's NetCDF file,
  in one open of the file; :func:`pareto_k` — PSIS Pareto k̂ (ArviZ's, in NumPy alone);
- :func:`sobol_along` — Sobol sensitivity along a loading coordinate (section 8; SALib is imported
  only when it runs).
"""

from bubblecal._lazy import by_module, lazy_exports

#: Exported name -> defining module, imported on first access: importing the layer (the CLI's option defaults,
#: a configuration) loads neither JAX nor SciPy; every name keeps its one path ``from bubblecal.inference import X``.
_LAZY = by_module({
    "bubblecal.inference.compare": ("Comparison", "compare_posteriors", "compare_staged_joint"),
    "bubblecal.inference.crps": ("CRPSResult", "crps_ensemble", "gaussian_crps", "predictive_crps"),
    "bubblecal.inference.hierarchical": ("Dataset", "run_phase", "run_staged"),
    "bubblecal.inference.phase_results": ("ESS_PREFIX", "PhaseResult", "StagedResult", "ess_table"),
    "bubblecal.inference.idata": ("ExportInfo", "build_inference_data", "pointwise_log_likelihood"),
    "bubblecal.inference.netcdf": ("write_netcdf",),
    "bubblecal.inference.nuts": ("NUTSResult", "run_nuts"),
    "bubblecal.inference.predictive": ("PredictiveBand", "coverage", "map_estimate", "map_index", "mixture_cdf",
        "mixture_quantile", "predictive_band"),
    "bubblecal.inference.psis": ("pareto_k",),
    "bubblecal.inference.sensitivity": ("SobolResult", "saltelli_design", "sobol_along", "sobol_indices"),
    "bubblecal.inference.tmcmc": ("TMCMC", "BatchStructureError", "KernelMove", "RandomWalk", "RunSpec",
        "TMCMCKernel", "clear_program_cache", "compile_ahead", "enable_program_store", "hmc_move", "nuts_move",
        "run_batched"),
})

__all__ = [
    # TMCMC
    "TMCMC", "TMCMCKernel", "RandomWalk", "KernelMove", "hmc_move", "nuts_move", "clear_program_cache",
    "run_batched", "BatchStructureError", "compile_ahead", "RunSpec", "enable_program_store",
    # NUTS and sampler comparison
    "run_nuts", "NUTSResult", "compare_posteriors", "Comparison",
    # staged hierarchy
    "Dataset", "PhaseResult", "StagedResult", "run_phase", "run_staged", "ess_table", "compare_staged_joint",
    "ESS_PREFIX",
    # ArviZ export and PSIS
    "ExportInfo", "build_inference_data", "pointwise_log_likelihood", "pareto_k", "write_netcdf",
    # posterior-predictive metrics
    "PredictiveBand", "CRPSResult", "mixture_cdf", "mixture_quantile", "predictive_band", "coverage",
    "gaussian_crps", "crps_ensemble", "predictive_crps", "map_index", "map_estimate",
    # sensitivity
    "SobolResult", "saltelli_design", "sobol_indices", "sobol_along",
]

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())
