"""Results of the staged hierarchy: one phase's draws and evidence, the three phases together, and the phase-2
importance-sampling ESS table.

Plain containers of host arrays: importing this module loads no JAX, so a process that only reads results (a
figure process, a report) unpickles them without the sampler's libraries.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from bubblecal.inference.tmcmc import TMCMC

__all__ = ["PhaseResult", "StagedResult", "ess_table", "phase_draws", "ESS_PREFIX"]

#: Prefix of the phase-2 deterministic sites that hold the per-dataset IS effective sample size.
ESS_PREFIX = "is_ess_"


@dataclass
class PhaseResult:
    """Outcome of one TMCMC run of a phase.

    Parameters
    ----------
    name : str
        Phase name (``phase1_<dataset>``, ``phase2``, ``phase3_<dataset>``).
    samples : dict of str to numpy.ndarray
        Constrained samples, deterministic sites included.
    log_evidence, log_evidence_se : float
        Log evidence (mean over replicas) and its standard error.
    status : str
        TMCMC status.
    seconds : float
        Wall time of the run.
    sampler : TMCMC or None
        The sampler (None for a result loaded from disk).
    """

    name: str
    samples: dict[str, np.ndarray]
    log_evidence: float
    log_evidence_se: float
    status: str
    seconds: float
    sampler: TMCMC | None = None

    def to_inference_data(self):
        """The run as ArviZ InferenceData (stage table and evidence in the attrs).

        Returns
        -------
        arviz.InferenceData
        """
        if self.sampler is not None:
            return self.sampler.to_inference_data()
        import arviz as az

        idata = az.from_dict(posterior={k: v[None] for k, v in self.samples.items()})
        idata.posterior.attrs.update({"log_evidence": self.log_evidence, "log_evidence_se": self.log_evidence_se,
                                      "status": self.status, "phase": self.name})
        return idata


@dataclass
class StagedResult:
    """Phases 1, 2 and 3 of a staged hierarchy.

    Parameters
    ----------
    phase1 : list of PhaseResult
        One per dataset.
    phase2 : PhaseResult
        The hyperparameters ψ.
    phase3 : list of PhaseResult
        One per dataset.
    phase3_ess : dict of str to float
        Importance ESS of the phase-3 re-weighting per dataset (empty for the published phase 3).
    phase2_max_samples : int or None
        Phase-1 draws per dataset phase 2 used at most (None: all).
    """

    phase1: list[PhaseResult]
    phase2: PhaseResult
    phase3: list[PhaseResult]
    phase3_ess: dict[str, float] = field(default_factory=dict)
    phase2_max_samples: int | None = None

    @property
    def psi_samples(self) -> dict[str, np.ndarray]:
        """Posterior draws of the hyperparameters (sites m_*, tau_*)."""
        return {k: v for k, v in self.phase2.samples.items() if k.startswith(("m_", "tau_"))}

    def ess(self):
        """Per-dataset importance-sampling ESS summary (fractions of the draws phase 2 used).

        Returns
        -------
        pandas.DataFrame
            See :func:`ess_table`.
        """
        cap = self.phase2_max_samples or math.inf
        return ess_table(self.phase2.samples, {r.name: int(min(phase_draws(r), cap)) for r in self.phase1})


def phase_draws(result: PhaseResult) -> int:
    """Number of draws of a phase.

    Parameters
    ----------
    result : PhaseResult

    Returns
    -------
    int
    """
    return int(next(iter(result.samples.values())).shape[0])


def ess_table(phase2_samples: Mapping[str, np.ndarray], num_draws: Mapping[str, int] | None = None):
    """Per dataset: importance-sampling effective sample size over the phase-2 posterior.

    A collapse (ESS ≈ 1) means phase 1 did not cover what ψ proposes.

    Parameters
    ----------
    phase2_samples : mapping of str to array_like
        Phase-2 samples; the sites ``is_ess_<dataset>`` are read.
    num_draws : mapping of str to int or None
        Phase-1 draws per dataset (keys ``phase1_<dataset>`` or ``<dataset>``), for the fraction.

    Returns
    -------
    pandas.DataFrame
        Columns dataset, ess_min, ess_p05, ess_median, ess_median_fraction (NaN without ``num_draws``).
    """
    import pandas as pd

    rows = []
    for key, values in phase2_samples.items():
        if not key.startswith(ESS_PREFIX):
            continue
        name = key[len(ESS_PREFIX):]
        v = np.asarray(values, dtype=float)
        n = (num_draws or {}).get(f"phase1_{name}", (num_draws or {}).get(name))
        rows.append({"dataset": name, "ess_min": float(v.min()), "ess_p05": float(np.quantile(v, 0.05)),
                     "ess_median": float(np.median(v)),
                     "ess_median_fraction": float(np.median(v)) / n if n else math.nan})
    return pd.DataFrame(rows)
