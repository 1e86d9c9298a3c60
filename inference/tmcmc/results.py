"""Results of a TMCMC run: evidence, status, stage tables, samples and exports.

:class:`TMCMCResults` is the result half of :class:`~bubblecal.inference.tmcmc.TMCMC` (which inherits
it): everything read after ``TMCMC.run`` — the log evidence of each replica and its standard error,
the per-stage table, the constrained samples, a printed summary and an ArviZ export.
"""

from __future__ import annotations

import math

import numpy as np

from bubblecal.inference.tmcmc._programs import _model_programs
from bubblecal.inference.tmcmc.evaluator import _default_platform
from bubblecal.inference.tmcmc.state import StageInfo, TMCMCState

__all__ = ["TMCMCResults", "STAGE_COLUMNS", "POINTWISE_CPU_CHUNK"]

#: Particles per call of the pointwise log likelihood of an export on a CPU (intermediates stay in cache).
POINTWISE_CPU_CHUNK = 1024

#: Columns of the per-stage table (:attr:`TMCMCResults.stage_info`).
STAGE_COLUMNS = (
    "stage",
    "beta",
    "delta",
    "cov",
    "ess",
    "log_z_increment",
    "log_evidence",
    "acceptance",
    "unique_fraction",
    "scale",
    "max_log_likelihood",
    "num_nonfinite",
    "num_evaluations",
    "seconds",
)


class TMCMCResults:
    """Accessors of a finished TMCMC run (base of :class:`~bubblecal.inference.tmcmc.TMCMC`).

    Reads the attributes the sampler sets: ``_results`` (one dict per replica: 'state', 'stages',
    'status', 'log_evidence', 'seconds'), ``_flat`` and ``_data`` (the model and its arrays, for the
    samples), ``_samples_cache`` and the settings (``preset``, ``space``, ``num_particles``,
    ``num_replicas``, ``target_cov``, ``chunk_size``).

    Raises
    ------
    RuntimeError
        From every accessor, before ``run`` was called.
    """

    @staticmethod
    def _initial_row(state, seconds):
        """Row 0 of the stage table: the initial particles (prior draws, or the base density's draws)."""
        ll = np.asarray(state.log_likelihood)
        fin = np.isfinite(ll)
        return {
            "stage": 0,
            "beta": 0.0,
            "delta": 0.0,
            "cov": float("nan"),
            "ess": float(len(ll)),
            "log_z_increment": 0.0,
            "log_evidence": float(state.log_evidence),
            "acceptance": float("nan"),
            "unique_fraction": 1.0,
            "scale": float("nan"),
            "max_log_likelihood": float(ll[fin].max()) if fin.any() else -math.inf,
            "num_nonfinite": int((~fin).sum()),
            "num_evaluations": len(ll),
            "seconds": seconds,
        }

    @staticmethod
    def _row(stage, info, seconds):
        """Row of the stage table from one stage's :class:`StageInfo` (status left out)."""
        row = {"stage": stage}
        for f in StageInfo._fields:
            if f == "status":
                continue
            v = np.asarray(getattr(info, f))
            row[f] = int(v) if f in ("num_nonfinite", "num_evaluations") else float(v)
        row["seconds"] = seconds
        return row

    def _need_run(self):
        """Raise RuntimeError before the first run."""
        if not self._results:
            raise RuntimeError("call TMCMC.run(rng_key, *model_args) first")

    @property
    def status(self) -> str:
        """'converged' if every replica reached β = 1, else the first other status."""
        self._need_run()
        for res in self._results:
            if res["status"] != "converged":
                return res["status"]
        return "converged"

    @property
    def log_evidences(self) -> np.ndarray:
        """log Z of each replica."""
        self._need_run()
        return np.array([res["log_evidence"] for res in self._results])

    @property
    def log_evidence(self) -> float:
        """Mean log Z over the replicas."""
        return float(self.log_evidences.mean())

    @property
    def log_evidence_se(self) -> float:
        """Standard error of the mean log Z over replicas (NaN with one replica)."""
        z = self.log_evidences
        if len(z) < 2:
            return float("nan")
        return float(z.std(ddof=1) / math.sqrt(len(z)))

    @property
    def stage_info(self):
        """Per-stage table (pandas DataFrame) of the first replica; row 0 is the prior draws.

        Columns (:data:`STAGE_COLUMNS`): stage, beta, delta, cov (achieved), ess, log_z_increment,
        log_evidence (running total), acceptance, unique_fraction, scale, max_log_likelihood,
        num_nonfinite, num_evaluations, seconds. The first replica's row 0 and stage 1
        (``compiled=False``; every row with ``compiled=True``) include the compilation time.
        """
        return self.replica_stage_info(0)

    def replica_stage_info(self, replica: int):
        """Per-stage table of one replica (columns as :attr:`stage_info`).

        Parameters
        ----------
        replica : int
            Replica index, 0 .. num_replicas − 1.

        Returns
        -------
        pandas.DataFrame
        """
        import pandas as pd

        self._need_run()
        return pd.DataFrame(self._results[replica]["stages"], columns=list(STAGE_COLUMNS))

    @property
    def num_evaluations(self) -> int:
        """Likelihood evaluations of the first replica (prior draws included)."""
        self._need_run()
        return int(self._results[0]["state"].num_evaluations)

    @property
    def state(self) -> TMCMCState:
        """Final core state of the first replica (flat particles, log prior/likelihood)."""
        self._need_run()
        return self._results[0]["state"]

    def get_samples(self, replica: int = 0) -> dict:
        """Final particles as constrained latent values and deterministic sites.

        Parameters
        ----------
        replica : int
            Replica index (default the first).

        Returns
        -------
        dict
            Site name -> NumPy array with leading dimension ``num_particles``.
        """
        self._need_run()
        if replica == 0 and self._samples_cache is not None:
            return self._samples_cache
        pos = self._results[replica]["state"].position
        out = _model_programs(self._flat, self.config.chunk_size).sites(pos, self._data)
        out = {k: np.asarray(v) for k, v in out.items()}
        if replica == 0:
            self._samples_cache = out
        return out

    def print_summary(self, prob: float = 0.9) -> None:
        """Print the posterior summary of the first replica, the evidence and the stage table.

        Parameters
        ----------
        prob : float
            Probability mass of the credible intervals of NumPyro's summary.
        """
        from numpyro.diagnostics import print_summary

        samples = self.get_samples()
        print_summary({k: v for k, v in samples.items()}, prob=prob, group_by_chain=False)
        se = self.log_evidence_se
        se_txt = f" ± {se:.4f} (SE over {self.num_replicas} replicas)" if math.isfinite(se) else ""
        print(
            f"\nTMCMC [{self.preset}, {self.space}], N = {self.num_particles}: status {self.status}, "
            f"log Z = {self.log_evidence:.4f}{se_txt}, {len(self.stage_info) - 1} stages, "
            f"{self.num_evaluations} likelihood evaluations"
        )
        with np.printoptions(linewidth=200):
            print(self.stage_info.to_string(index=False, float_format=lambda v: f"{v:.4g}"))

    def to_inference_data(self, info=None, log_likelihood=True, chunk_size: int | None = None):
        """Every replica as one chain of an ArviZ InferenceData.

        Parameters
        ----------
        info : bubblecal.inference.idata.ExportInfo or None
            Dimension names, coordinates, units, constant data and attributes from the caller.
        log_likelihood : bool or mapping of str to array_like
            True: the pointwise log likelihood of the model's observed sites (and their observed values) at
            every particle of every replica; a mapping: those (chain, draw, ...) arrays instead (for models
            whose likelihood is a factor); False: no log_likelihood group.
        chunk_size : int or None
            Particles per vectorised evaluation of the pointwise log likelihood; None: :data:`POINTWISE_CPU_CHUNK`
            on a CPU, every particle in one call on an accelerator (a call per chunk costs a dispatch and a
            transfer, which at 50,000 particles and 1,024 per chunk dominated a phase file's export on a GPU).

        Returns
        -------
        arviz.InferenceData
            posterior (num_replicas chains x N draws); sample_stats 'lp' (log prior + log likelihood in the
            sampling space), 'loglik' (total log likelihood), 'log_prior' and the stage table
            ``stage_<column>`` (dims chain, stage; NaN past a replica's last stage; wall times in the attrs
            only); log_likelihood and observed_data; the evidence, status, settings and library versions
            in the attrs of every group.
        """
        from bubblecal.inference.idata import build_inference_data

        return build_inference_data(**self.inference_parts(info, log_likelihood, chunk_size))

    def inference_parts(self, info=None, log_likelihood=True, chunk_size: int | None = None) -> dict:
        """The arrays of :meth:`to_inference_data`, before ArviZ builds its groups.

        The part that traces the model and evaluates the pointwise log likelihood: call it on the thread that
        sampled (NumPyro's effect handlers are not thread-safe); building the InferenceData from its result
        is array work that may run elsewhere.

        Parameters
        ----------
        info, log_likelihood, chunk_size
            As :meth:`to_inference_data`.

        Returns
        -------
        dict
            Keyword arguments of :func:`~bubblecal.inference.idata.build_inference_data`.
        """
        from bubblecal.inference.idata import _likelihood_groups

        self._need_run()
        replicas = [self.get_samples(r) for r in range(self.num_replicas)]
        posterior = {k: np.stack([s[k] for s in replicas]) for k in replicas[0]}
        states = [res["state"] for res in self._results]
        ll = np.stack([np.asarray(st.log_likelihood) for st in states])
        lprior = np.stack([np.asarray(st.log_prior) for st in states])
        attrs = {
            "inference_library": "bubblecal.inference.tmcmc",
            "preset": self.preset,
            "space": self.space,
            "num_particles": self.num_particles,
            "num_replicas": self.num_replicas,
            "log_evidence": self.log_evidence,
            "log_evidence_se": self.log_evidence_se,
            "log_evidences": [float(v) for v in self.log_evidences],
            "status": self.status,
            "target_cov": self.target_cov,
            "num_evaluations": self.num_evaluations,
            "stage_seconds": [float(sum(row["seconds"] for row in res["stages"])) for res in self._results],
        }
        tables = [self.replica_stage_info(r) for r in range(self.num_replicas)]
        n_stages = max(len(t) for t in tables)
        stages = {}
        for c in STAGE_COLUMNS:
            if c in ("stage", "seconds"):
                continue
            values = np.full((self.num_replicas, n_stages), np.nan)
            for r, t in enumerate(tables):
                values[r, :len(t)] = t[c].to_numpy(dtype=float)
            stages[f"stage_{c}"] = (("chain", "stage"), values)
        if chunk_size is None:
            chunk_size = POINTWISE_CPU_CHUNK if _default_platform() == "cpu" else self.num_replicas * self.num_particles
        args, kwargs = self._model_args
        # the pointwise program of the model's structure, its arrays as arguments: compiled once for all datasets
        programs = _model_programs(self._flat, self.config.chunk_size)
        pointwise, observed = _likelihood_groups(self.model, posterior, args, kwargs, log_likelihood, info,
                                                 chunk_size, lambda chunk: programs.pointwise(chunk, self._data))
        return {"posterior": posterior, "sample_stats": {"lp": lprior + ll, "loglik": ll, "log_prior": lprior},
                "log_likelihood": pointwise, "observed_data": observed, "info": info, "extra_stats": stages,
                "attrs": attrs, "stats_coords": {"stage": np.arange(n_stages)}}
