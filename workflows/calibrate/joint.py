"""The joint hierarchical model of one agent by NUTS (``--sampler nuts``), its phase file and diagnostics.

The staged TMCMC path is :mod:`bubblecal.workflows.calibrate.run`; this module is its NUTS alternative: one
non-centred joint run over every dataset of the agent, reused from ``joint_nuts`` when its hash matches, written
with its chains (``docs/data-formats.md``), and named on the progress callback when it does not converge.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from bubblecal.workflows.calibrate.config import CalibrationConfig
from bubblecal.workflows.calibrate.device import on_device
from bubblecal.workflows.calibrate.phase_files import write_phase
from bubblecal.workflows.calibrate.plan import AgentPlan
from bubblecal.workflows.calibrate.store import PhaseStore, config_hash

__all__ = ["JointResult", "run_joint", "joint_inference_data"]


@dataclass
class JointResult:
    """Draws, total log likelihood per draw, seconds and NUTS diagnostics of the joint run; ``convergence_note``
    names what a run that did not converge misses (:meth:`bubblecal.inference.nuts.NUTSResult.convergence_note`),
    None for a converged or reused run."""

    samples: dict
    loglik: np.ndarray
    seconds: float
    diagnostics: dict
    reused: bool
    convergence_note: str | None = None


def run_joint(ap: AgentPlan, config: CalibrationConfig, key, store: PhaseStore, say) -> JointResult:
    """Joint hierarchical model with NUTS (non-centred); reuses ``joint_nuts`` when its hash matches."""
    from numpyro.infer import init_to_value, log_likelihood

    from bubblecal.inference.nuts import run_nuts
    from bubblecal.inference.phase_results import PhaseResult
    from bubblecal.models import hierarchical_model, nuts_init_values
    from bubblecal.workflows.calibrate.export import joint_export

    name = "joint_nuts"
    store.expected[name] = config_hash({"phases": store.expected, "nuts": [config.nuts_warmup, config.nuts_samples,
                                                                            config.nuts_chains], "seed": config.seed})
    cached = store.load(name)
    if cached is not None:
        say(f"{name}: reused")
        return JointResult(cached.samples, store.loglik.get(name), cached.seconds, {}, True)
    say(f"{name}: running NUTS ({config.nuts_chains} chains x {config.nuts_samples} draws)")
    t0 = time.perf_counter()
    kwargs = {"acoustic": ap.acoustic, "f_res": ap.f_res, "noncentred": True}
    init = nuts_init_values(ap.spec, n_curves=len(ap.curves))
    with on_device(config.device):
        res = run_nuts(hierarchical_model, ap.curves, ap.surrogates, ap.spec, rng_key=key,
                       num_warmup=config.nuts_warmup, num_samples=config.nuts_samples, num_chains=config.nuts_chains,
                       target_accept_prob=0.9, init_strategy=init_to_value(values=init), **kwargs)
        ll = log_likelihood(hierarchical_model, res.samples, ap.curves, ap.surrogates, ap.spec, **kwargs)
    total_ll = sum(np.asarray(v).reshape(np.asarray(v).shape[0], -1).sum(axis=1) for v in ll.values())
    seconds = time.perf_counter() - t0
    samples = {k: np.asarray(v) for k, v in res.samples.items()}
    result = PhaseResult(name=name, samples=samples, log_evidence=math.nan, log_evidence_se=math.nan,
                         status="converged" if res.converged else "not converged", seconds=seconds)
    store.loglik[name] = total_ll
    diag = {"max_r_hat": res.max_r_hat, "min_n_eff": res.min_n_eff, "num_divergences": res.num_divergences}
    note = res.convergence_note()
    if note is not None:
        say(f"warning: {name}: {note}; run longer chains (--nuts-samples, also the warm-up; --nuts-chains) or use "
            "--sampler tmcmc")
    idata = joint_inference_data(res, ap, kwargs, total_ll, joint_export(ap), diag) if config.netcdf else None
    write_phase(store.path(name), result, total_ll, {"config_hash": store.expected[name], "phase": name,
                                                      "phase_result_chains": "all", **diag}, idata=idata)
    store.manifest["phases"][name] = {"file": store.path(name).name, "config_hash": store.expected[name],
                                      "status": result.status, "seconds": seconds, "max_r_hat": res.max_r_hat,
                                      "min_n_eff": res.min_n_eff, "num_divergences": res.num_divergences}
    store.write_manifest()
    return JointResult(samples, total_ll, seconds, diag, False, note)


def joint_inference_data(res, ap: AgentPlan, kwargs, total_ll, export, diag):
    """The joint run's chains as InferenceData: every observation of every dataset in one variable 'y'."""
    from bubblecal.inference.idata import build_inference_data, pointwise_log_likelihood
    from bubblecal.models import hierarchical_model

    info, sites = export
    pw = pointwise_log_likelihood(hierarchical_model, res.samples_by_chain, (ap.curves, ap.surrogates, ap.spec),
                                  kwargs, batch_ndims=2)
    observed = [np.asarray(c.y, dtype=float) for c in ap.curves]
    observed += [np.asarray(d.frequency_MHz, dtype=float) for d in ap.acoustic] if ap.spec.acoustic else []
    chains = res.diverging.shape[0]
    stats = {"lp": -np.asarray(res.potential_energy), "diverging": np.asarray(res.diverging, dtype=bool),
             "loglik": np.asarray(total_ll).reshape(chains, -1)}
    return build_inference_data(res.samples_by_chain, sample_stats=stats,
                                log_likelihood={"y": np.concatenate([pw[s] for s in sites], axis=-1)},
                                observed_data={"y": np.concatenate(observed)}, info=info,
                                attrs={"inference_library": "numpyro.infer.NUTS", **diag})
