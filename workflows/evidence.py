"""Model evidence of the full vs the reduced shell per loading curve, and the Bayes factors.

For each curve of an agent, TMCMC (``num_replicas`` independent runs, target CoV 0.8, s² 0.04) gives
ln Z under the spectroscopy-only priors ``<agent>_full`` and ``<agent>_reduced`` (same surrogate; the
reduced shell evaluates it at b1 = b2 = a3 = a4 = 0); ln Z is the replica mean and its error the standard
error of that mean. The Bayes factor ln B = ln Z_full − ln Z_reduced has error
sqrt(SE_full² + SE_reduced²). Verdict (Kass & Raftery 1995, on 2 ln B): < 2 "not worth more than a bare
mention", 2–6 "positive", 6–10 "strong", > 10 "very strong", in favour of the model with the larger
evidence; "inconclusive (Monte Carlo error)" when |ln B| < 2 × its error.

Beside ln Z, PSIS-LOO (Vehtari, Gelman & Gabry 2017, through ArviZ) of each model: the particles of every
replica are one chain, the pointwise log likelihood is one value per curve point; elpd_loo ± its SE,
p_loo, the number of points whose Pareto k̂ exceeds 0.7 (their leave-one-out estimate is unreliable), and
``az.compare`` of the two models (elpd difference ± its SE, the model ranked first).

Written to ``out/<agent>/evidence.csv`` (read by :func:`bubblecal.workflows.report.write_report`).
The single-curve TMCMC is the code path of ``bubblecal compare`` (:func:`bubblecal.models.mechanical_model`
under :class:`bubblecal.inference.tmcmc.TMCMC`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from bubblecal.workflows.calibrate import DEFAULT_POPULATION, CalibrationConfig

__all__ = ["kass_raftery", "loo_columns", "run_evidence", "EVIDENCE_COLUMNS", "DEFAULT_REPLICAS", "PARETO_K_LIMIT"]

#: Independent TMCMC runs per model and curve (at least 2 give ln Z an error bar).
DEFAULT_REPLICAS = 3
#: Columns of ``evidence.csv``.
EVIDENCE_COLUMNS = ("agent", "curve", "diameter_um", "log_z_full", "log_z_full_se", "log_z_reduced",
                    "log_z_reduced_se", "ln_bayes_factor", "ln_bayes_factor_se", "favours", "verdict", "num_particles",
                    "num_replicas", "seconds", "elpd_loo_full", "elpd_loo_full_se", "p_loo_full", "pareto_k_bad_full",
                    "elpd_loo_reduced", "elpd_loo_reduced_se", "p_loo_reduced", "pareto_k_bad_reduced",
                    "elpd_diff", "elpd_diff_se", "loo_favours", "surrogate")
#: Pareto k̂ above which a point's PSIS leave-one-out estimate is unreliable.
PARETO_K_LIMIT = 0.7
#: The defaults ``evidence`` shares with ``calibrate`` (its surrogates and network without ``--paper``).
_D = CalibrationConfig()


def kass_raftery(ln_b: float, se: float = 0.0) -> tuple[str, str]:
    """Kass–Raftery verdict of a Bayes factor.

    Parameters
    ----------
    ln_b : float
        ln B = ln Z_full − ln Z_reduced.
    se : float
        Its Monte Carlo standard error.

    Returns
    -------
    tuple of str
        (favoured model 'full' | 'reduced' | '' when undefined, strength).
    """
    if not math.isfinite(ln_b):
        return "", "undefined"
    favours = "full" if ln_b > 0 else "reduced"
    if math.isfinite(se) and abs(ln_b) < 2.0 * se:
        return favours, "inconclusive (Monte Carlo error)"
    two = 2.0 * abs(ln_b)
    if two < 2.0:
        strength = "not worth more than a bare mention"
    elif two < 6.0:
        strength = "positive"
    elif two < 10.0:
        strength = "strong"
    else:
        strength = "very strong"
    return favours, strength


def loo_columns(idatas) -> dict:
    """PSIS-LOO of the full and the reduced model of one curve, and their comparison.

    Parameters
    ----------
    idatas : mapping of str to arviz.InferenceData
        'full' and 'reduced' -> a run with a pointwise log likelihood over the curve's points.

    Returns
    -------
    dict
        ``elpd_loo_<model>``, ``elpd_loo_<model>_se``, ``p_loo_<model>``, ``pareto_k_bad_<model>`` (points
        with k̂ > :data:`PARETO_K_LIMIT`), ``elpd_diff`` and ``elpd_diff_se`` (first-ranked minus second,
        from ``az.compare``) and ``loo_favours`` (the first-ranked model).
    """
    import warnings

    import arviz as az

    row = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # ArviZ warns on k̂ > 0.7; the count goes into the table instead
        for model, idata in idatas.items():
            loo = az.loo(idata, pointwise=True)
            row[f"elpd_loo_{model}"] = float(loo["elpd_loo"])
            row[f"elpd_loo_{model}_se"] = float(loo["se"])
            row[f"p_loo_{model}"] = float(loo["p_loo"])
            row[f"pareto_k_bad_{model}"] = int(np.sum(np.asarray(loo["pareto_k"]) > PARETO_K_LIMIT))
        cmp = az.compare(dict(idatas), ic="loo")
    second = cmp.iloc[-1]
    row.update({"elpd_diff": float(second["elpd_diff"]), "elpd_diff_se": float(second["dse"]),
                "loo_favours": str(cmp.index[0])})
    return row


def run_evidence(agents, bundle, *, population: int = DEFAULT_POPULATION, replicas: int = DEFAULT_REPLICAS,
                 seed: int = 0, device: str = "cpu", out: Path | None = None, curves: tuple[str, ...] = (),
                 num_mcmc_steps: int = 10, progress: Callable[[str], None] | None = None,
                 stages: Callable[[int, Mapping], None] | None = None, surrogates: str | None = None,
                 networks: str = _D.networks):
    """ln Z of the full and the reduced shell for every curve of ``agents``, and the Bayes factors.

    Parameters
    ----------
    agents : sequence of str
        'definity' and/or 'sonovue'.
    bundle : bubblecal.surrogates.Bundle
        A loaded bundle holding a surrogate for every curve.
    population : int
        TMCMC particles per run.
    replicas : int
        Independent TMCMC runs per model and curve.
    seed : int
        Seed of the JAX keys.
    device : str
        'cpu' or 'gpu' (JAX device).
    out : Path or None
        Output root: writes ``out/<agent>/evidence.csv``.
    curves : tuple of str
        Restrict to these curve names (empty: all).
    num_mcmc_steps : int
        Random-walk Metropolis steps per TMCMC stage.
    progress : callable or None
        Receives one-line messages.
    stages : callable or None
        ``stages(replica, row)``: each TMCMC stage (the ``progress`` reporter of
        :class:`~bubblecal.inference.TMCMC`).
    surrogates : {'over-diameter', 'per-diameter'} or None
        Which surrogates serve the curves, as ``calibrate --surrogates`` (None: calibrate's default, the networks
        over the diameter); the per-diameter file answers where no network covers a curve.
    networks : {'fast', 'accurate'}
        Role of the network over the diameter.

    Returns
    -------
    pandas.DataFrame
        Columns :data:`EVIDENCE_COLUMNS` (PSIS-LOO columns from :func:`loo_columns`; ``surrogate`` names the
        surrogate of the curve, :func:`~bubblecal.workflows.calibrate.surrogate_label`). ln Z and elpd are
        dimensionless (natural log of a density of the curve's y
        in DPD units).

    Raises
    ------
    KeyError
        When the bundle has no surrogate for a curve.
    ValueError
        For an unknown ``surrogates`` or ``networks``.
    """
    import time

    import jax
    import pandas as pd

    from bubblecal.data import reference_curves
    from bubblecal.inference import TMCMC
    from bubblecal.models import mechanical_model
    from bubblecal.priors import load_priors
    from bubblecal.workflows.calibrate import PAPER_COV, PAPER_COV_SCALE, on_device, surrogate_label

    say = progress or (lambda _m: None)
    lookup = CalibrationConfig(surrogates=surrogates, networks=networks).surrogate_lookup()
    rows = []
    key = jax.random.PRNGKey(seed)
    for agent in agents:
        specs = {"full": load_priors(f"{agent}_full"), "reduced": load_priors(f"{agent}_reduced")}
        agent_rows = []
        for curve in reference_curves(agent):
            if curves and curve.name not in curves:
                continue
            sur = bundle.get(curve.kind, curve.diameter_um, **lookup)
            row = {"agent": agent, "curve": curve.name, "diameter_um": curve.diameter_um,
                   "surrogate": surrogate_label(sur, bundle)}
            t0 = time.perf_counter()
            idatas = {}
            for model_name, spec in specs.items():
                key, sub = jax.random.split(key)
                say(f"{curve.name}: {model_name} shell, N = {population} x {replicas} replicas")
                tm = TMCMC(mechanical_model, num_particles=population, num_replicas=replicas,
                           target_cov=PAPER_COV[0], cov_scale=PAPER_COV_SCALE, num_mcmc_steps=num_mcmc_steps,
                           progress=stages or False)
                with on_device(device):
                    tm.run(sub, np.asarray(curve.x), np.asarray(curve.y), sur, spec)
                row[f"log_z_{model_name}"] = tm.log_evidence
                row[f"log_z_{model_name}_se"] = tm.log_evidence_se
                with on_device(device):
                    idatas[model_name] = tm.to_inference_data()
            ln_b = row["log_z_full"] - row["log_z_reduced"]
            se = math.hypot(row["log_z_full_se"], row["log_z_reduced_se"])
            favours, verdict = kass_raftery(ln_b, se)
            row.update({"ln_bayes_factor": ln_b, "ln_bayes_factor_se": se, "favours": favours,
                        "verdict": f"{verdict} for the {favours} shell" if favours and "inconclusive" not in verdict
                        else verdict, "num_particles": population, "num_replicas": replicas,
                        "seconds": time.perf_counter() - t0})
            row.update(loo_columns(idatas))
            say(f"{curve.name}: ln B = {ln_b:.2f} ± {se:.2f} ({row['verdict']}); elpd_loo full "
                f"{row['elpd_loo_full']:.2f} ± {row['elpd_loo_full_se']:.2f}, reduced {row['elpd_loo_reduced']:.2f} ± "
                f"{row['elpd_loo_reduced_se']:.2f}; Pareto k > {PARETO_K_LIMIT}: {row['pareto_k_bad_full']} full, "
                f"{row['pareto_k_bad_reduced']} reduced")
            agent_rows.append(row)
        if out is not None:
            folder = Path(out) / agent
            folder.mkdir(parents=True, exist_ok=True)
            pd.DataFrame(agent_rows, columns=list(EVIDENCE_COLUMNS)).to_csv(folder / "evidence.csv", index=False)
        rows += agent_rows
    return pd.DataFrame(rows, columns=list(EVIDENCE_COLUMNS))
