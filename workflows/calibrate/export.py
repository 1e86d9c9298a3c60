"""What the phase files of a calibration hold beyond the draws: dimension names, units, data, pointwise log
likelihood (the ArviZ groups; layout in ``docs/data-formats.md``, section "Calibration outputs").

:func:`phase_exports` gives every phase its :class:`~bubblecal.inference.idata.ExportInfo`: a curve's phases
name the points of the curve (``points``), an acoustic dataset's the bubbles (``bubbles``), phase 2 the datasets
(``datasets``) and the joint run the curves (``curves``) and acoustic datasets (``acoustic``). Phase 2's
likelihood is a factor, so its pointwise log likelihood (one column per dataset: log L_i(ψ), whose negative
gives the leave-one-out importance weights of phase 3) comes from :func:`phase2_log_likelihood`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from bubblecal.data import PARAMETER_UNITS
from bubblecal.inference.idata import ExportInfo

__all__ = ["phase_exports", "phase2_log_likelihood", "phase2_pareto_k", "joint_export", "PHASE2_LOGLIK"]

#: Name of phase 2's pointwise log-likelihood variable (one column per dataset).
PHASE2_LOGLIK = "population_likelihood"
#: Units of the observed and constant variables per curve kind: (loading coordinate x, observation y).
_CURVE_UNITS = {"compression": ("DPD length", "DPD force"), "indentation": ("DPD force", "DPD length")}


def _parameter_units() -> dict[str, str]:
    """Units of every posterior site of the models (parameters, derived sites, hyperparameters)."""
    units = dict(PARAMETER_UNITS)
    units |= {"E_MPa": "MPa", "kappa_kBT": "k_BT", "E_MPa_ac": "MPa", "ka_ac": PARAMETER_UNITS["ka"]}
    for k, u in PARAMETER_UNITS.items():
        units[f"m_{k}"] = units[f"tau_{k}"] = u
        units[f"{k}_u"] = "1"
    units["ka_ac_u"] = "1"
    return units


def _curve_info(curve, mask) -> ExportInfo:
    """Export of one loading curve's phase (observed site 'y' over 'points')."""
    x_unit, y_unit = _CURVE_UNITS[curve.kind]
    n = len(curve.x)
    return ExportInfo(
        dims={"y": ("points",), "loading": ("points",)}, coords={"points": np.arange(n)},
        units={**_parameter_units(), "y": y_unit, "loading": x_unit, "diameter_um": "um"},
        constant_data={"loading": np.asarray(curve.x, dtype=float), "diameter_um": float(curve.diameter_um)},
        keep={"y": np.asarray(mask, dtype=bool)} if mask is not None else {},
        attrs={"dataset": curve.name, "kind": curve.kind})


def _acoustic_info(ds) -> ExportInfo:
    """Export of one acoustic dataset's phase (observed site 'f' over 'bubbles')."""
    diam = np.atleast_1d(np.asarray(ds.diameter_um, dtype=float))
    return ExportInfo(dims={"f": ("bubbles",), "diameter_um": ("bubbles",)}, coords={"bubbles": np.arange(diam.size)},
                      units={**_parameter_units(), "f": "MHz", "diameter_um": "um"},
                      constant_data={"diameter_um": diam}, attrs={"dataset": ds.name, "kind": "acoustic"})


def phase_exports(ap, datasets: Sequence) -> dict[str, ExportInfo]:
    """The export of every phase of one agent.

    Parameters
    ----------
    ap : bubblecal.workflows.calibrate.AgentPlan
        The agent's curves and acoustic datasets.
    datasets : sequence of bubblecal.inference.hierarchical.Dataset
        The phase-1 datasets (curves first, padded curves with a ``mask`` keyword).

    Returns
    -------
    dict of str to ExportInfo
        ``phase1_<dataset>``, ``phase3_<dataset>`` and ``phase2``.
    """
    out = {}
    n_curves = len(ap.curves)
    for i, d in enumerate(datasets):
        info = (_curve_info(ap.curves[i], d.kwargs.get("mask")) if i < n_curves
                else _acoustic_info(ap.acoustic[i - n_curves]))
        out[f"phase1_{d.name}"] = out[f"phase3_{d.name}"] = info
    names = [d.name for d in datasets]
    out["phase2"] = ExportInfo(dims={PHASE2_LOGLIK: ("datasets",)}, coords={"datasets": np.asarray(names)},
                               units={**_parameter_units(), **{f"is_ess_{n}": "draws" for n in names}},
                               attrs={"datasets": ",".join(names)})
    return out


def phase2_log_likelihood(samples: Mapping[str, np.ndarray], thinned: Sequence[Mapping[str, np.ndarray]],
                          spec) -> np.ndarray:
    """Phase 2's pointwise log likelihood: log L_i(ψ_s) of every dataset i at every phase-2 draw s.

    Parameters
    ----------
    samples : mapping of str to array_like
        Phase-2 draws (sites ``m_<k>``, ``tau_<k>``; DPD units).
    thinned : sequence of mapping
        Each dataset's phase-1 draws as phase 2 used them (DPD units).
    spec : bubblecal.priors.PriorSpec
        The priors (ranges of the pooled parameters).

    Returns
    -------
    numpy.ndarray
        (S, n_datasets) float64, dimensionless.
    """
    from bubblecal.models import dataset_log_likelihoods, pooled_bounds

    bounds = pooled_bounds(spec)
    m = {k.removeprefix("m_"): np.asarray(v) for k, v in samples.items() if k.startswith("m_")}
    tau = {k.removeprefix("tau_"): np.asarray(v) for k, v in samples.items() if k.startswith("tau_")}
    return dataset_log_likelihoods(m, tau, thinned, bounds)


def phase2_pareto_k(loglik) -> np.ndarray:
    """Pareto k̂ of each dataset's leave-one-out importance weights 1 / L_i(ψ_s) over the phase-2 draws.

    Parameters
    ----------
    loglik : array_like
        (S, n_datasets) log L_i(ψ_s) (:func:`phase2_log_likelihood`).

    Returns
    -------
    numpy.ndarray
        (n_datasets,) k̂ (above 0.7 the leave-one-out estimate of that dataset is unreliable).
    """
    from bubblecal.inference import pareto_k

    lw = -np.asarray(loglik, dtype=np.float64)
    lw = np.where(np.isfinite(lw), lw, -np.inf)  # L_i(ψ_s) = 0 or undefined: that draw gets no weight
    return np.atleast_1d(pareto_k(lw))


def joint_export(ap) -> tuple[ExportInfo, list[str]]:
    """Export of the joint run: plates ``curves`` / ``acoustic``, every observation in one variable 'y'.

    Parameters
    ----------
    ap : bubblecal.workflows.calibrate.AgentPlan
        The agent's curves and acoustic datasets.

    Returns
    -------
    tuple
        (ExportInfo with dims, coords, units and constant data; the model's observed site names in order,
        whose observations are concatenated along ``points`` (constant data ``point_dataset``, ``point_unit``)).
    """
    from bubblecal.models.hierarchical import acoustic_site_name, curve_site_name

    sites = [curve_site_name(c, i) for i, c in enumerate(ap.curves)]
    sites += [acoustic_site_name(d, j) for j, d in enumerate(ap.acoustic)] if ap.spec.acoustic else []
    labels, units, loading = [], [], []
    for c in ap.curves:
        labels += [c.name] * len(c.x)
        units += [_CURVE_UNITS[c.kind][1]] * len(c.x)
        loading += list(np.asarray(c.x, dtype=float))
    for ds in ap.acoustic if ap.spec.acoustic else []:
        d = np.atleast_1d(np.asarray(ds.diameter_um, dtype=float))
        labels += [ds.name] * d.size
        units += ["MHz"] * d.size
        loading += list(d)
    per_curve = tuple(ap.spec.free_names) + (ap.spec.mechanical_noise_name, "E_MPa", "kappa_kBT")
    dims = {k: ("curves",) for k in per_curve} | {f"{k}_u": ("curves",) for k in ap.spec.free_names}
    dims |= {k: ("acoustic",) for k in ("ka_ac", "ka_ac_u", "sigma_ac", "E_MPa_ac")}
    dims |= {k: ("points",) for k in ("y", "loading", "point_dataset", "point_unit")}
    coords = {"curves": np.asarray([c.name for c in ap.curves]), "acoustic": np.asarray([d.name for d in ap.acoustic]),
              "points": np.arange(len(labels))}
    info = ExportInfo(dims=dims, coords=coords,
                      units={**_parameter_units(), "y": "per point: constant_data point_unit",
                             "loading": "per point: DPD length (compression), DPD force (indentation), um (acoustic)"},
                      constant_data={"loading": np.asarray(loading), "point_dataset": np.asarray(labels),
                                     "point_unit": np.asarray(units)},
                      attrs={"datasets": ",".join(ap.dataset_names)})
    return info, sites
