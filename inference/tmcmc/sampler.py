"""TMCMC for NumPyro models: adaptive tempering, log evidence, Korali parity, pluggable moves.

Write a NumPyro model once; the same model runs under ``numpyro.infer.MCMC(NUTS(model))`` and here::

    tm = TMCMC(model, num_particles=10_000, num_replicas=4)
    tm.run(jax.random.PRNGKey(0), x, y=y)
    tm.get_samples(), tm.log_evidence, tm.log_evidence_se, tm.stage_info, tm.status

The algorithm (``docs/inference.md`` section 5) lives in the pure core
(:mod:`bubblecal.inference.tmcmc.core`); this module turns a model into the flat ``log_prior_fn`` /
``log_likelihood_fn`` the core needs (:class:`~bubblecal.inference.tmcmc._flat_model.FlatModel`), drives
the stages with compiled programs cached per model structure (:mod:`bubblecal.inference.tmcmc._programs`)
and collects the diagnostics (:class:`~bubblecal.inference.tmcmc.results.TMCMCResults`).

Presets
-------
``robust`` (default): unconstrained space, systematic resampling, ``num_mcmc_steps`` (default 10)
random-walk MH steps per stage from N(x, s² Σ_w) with s adapted toward acceptance 0.3 (starting at
s² = ``cov_scale``), or any ``move`` (e.g. :func:`~bubblecal.inference.tmcmc.moves.hmc_move`).

``korali``: Korali's TMCMC with its defaults — constrained space (proposals outside the box are
rejected), CoV target on the incremental weights, multinomial resampling, proposal covariance
``cov_scale`` (0.04) × weighted particle covariance, and chain lengths from the selection counts with
Korali's default maximum chain length 1: each of the N resampled copies makes one MH step. Like
Korali, the run ends with one generation (resample + move) at β = 1.

Failure behaviour: non-finite log L gets weight 0; if every prior draw has a non-finite log L (or log
prior) :class:`ValueError` names the model; the stage cap and the minimum Δ end the run with ``status``
'max_stages' / 'stalled' and a :class:`RuntimeWarning`, keeping the partial results.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

from bubblecal.inference.tmcmc._flat_model import FlatModel
from bubblecal.inference.tmcmc._programs import (
    _fused_programs,
    _model_programs,
    _on_device,
    _split_stage,
    _splittable,
    _stage_programs,
    flat_model,
    offset_evidence,
    start_positions,
    start_program,
)
from bubblecal.inference.tmcmc.evaluator import resolve_chunk_size
from bubblecal.inference.tmcmc.moves import Move, RandomWalk
from bubblecal.inference.tmcmc.progress import StageReporter, stage_reporter
from bubblecal.inference.tmcmc.results import TMCMCResults
from bubblecal.inference.tmcmc.state import (
    STATUS_MAX_STAGES,
    STATUS_NAMES,
    STATUS_RUNNING,
    TMCMCConfig,
    _check_int,
    _check_positive,
)

__all__ = ["TMCMC", "PRESETS"]

#: The presets of :class:`TMCMC`.
PRESETS = ("robust", "korali")


class TMCMC(TMCMCResults):
    """Transitional MCMC of a NumPyro model (see the module docstring).

    Parameters
    ----------
    model : callable
        NumPyro model function (continuous latent sites, any supports).
    num_particles : int
        N (published: 50,000).
    target_cov : float
        Target coefficient of variation of the incremental weights (published: 0.8 single level,
        0.6 hierarchical phases; ESS/N ≈ 1/(1 + c²)).
    cov_scale : float
        s² in Σ = s² Σ_w (Korali 0.04; the robust preset's starting value).
    num_mcmc_steps : int or None
        MH steps per stage for the robust random walk (default 10); the korali preset runs exactly one.
    preset : {'robust', 'korali'}
        See the module docstring.
    move : Move or None
        A move object (:class:`~bubblecal.inference.tmcmc.moves.RandomWalk` or a
        :class:`~bubblecal.inference.tmcmc.moves.KernelMove`, e.g. ``hmc_move()``); replaces the
        preset's random walk (robust preset only).
    num_replicas : int
        Independent runs; ``log_evidence`` is their mean, ``log_evidence_se`` its standard error;
        samples and stage table are those of the first replica.
    max_stages : int
        Stage cap (status 'max_stages' when hit).
    chunk_size : int, 'auto' or None
        Evaluate the densities this many particles at a time (memory, and on a CPU speed); None: all at once;
        'auto' (default): at most :data:`~bubblecal.inference.tmcmc.evaluator.CPU_CHUNK_SIZE` particles on a CPU
        (one that divides N where one exists), all at once on a GPU, decided by the default device when the run
        starts (:func:`~bubblecal.inference.tmcmc.evaluator.resolve_chunk_size`). The draws do not depend on it
        beyond floating-point round-off.
    space : {'unconstrained', 'constrained'} or None
        Sampling space; None: 'unconstrained' (robust) or 'constrained' (korali).
    min_delta : float
        A stage with Δ below this (and β < 1) ends the run with status 'stalled'.
    compiled : bool
        Run all stages in one ``lax.while_loop`` (no host round-trip per stage; the 'seconds' column
        then holds the run's mean per stage).
    progress : bool or callable
        Report each stage (stage, β, ESS, acceptance, log Z so far): False (default) nothing, True a rich
        line, or a reporter ``report(replica, row)`` called with each stage-table row
        (:mod:`bubblecal.inference.tmcmc.progress`). The draws do not depend on it.
    tempered : sequence of str or None
        Observed or factor sites to temper; the model's other observed sites join the prior in the base
        density, whose draws :meth:`run` then needs (``init_samples``). None (default): every observed and
        factor site is tempered and the run starts from exact prior draws. The results' ``log_prior`` and
        ``log_likelihood`` are the model's own split either way; the stage table's ``max_log_likelihood``
        is over the tempered sites.

    Raises
    ------
    ValueError
        For a model that is not callable and for any invalid setting (the message names it).
    """

    def __init__(
        self,
        model: Callable,
        num_particles: int = 50_000,
        target_cov: float = 0.8,
        cov_scale: float = 0.04,
        num_mcmc_steps: int | None = None,
        preset: str = "robust",
        move: Move | None = None,
        num_replicas: int = 1,
        max_stages: int = 200,
        chunk_size: int | str | None = "auto",
        space: str | None = None,
        min_delta: float = 1e-9,
        compiled: bool = False,
        progress: bool | StageReporter = False,
        tempered: tuple[str, ...] | list[str] | None = None,
    ):
        if not callable(model):
            raise ValueError(f"model must be a callable NumPyro model, got {model!r}")
        if preset not in PRESETS:
            raise ValueError(f"preset must be one of {PRESETS}, got {preset!r}")
        self.model = model
        self.num_particles = _check_int("num_particles", num_particles, 2)
        self.target_cov = _check_positive("target_cov", target_cov)
        self.cov_scale = _check_positive("cov_scale", cov_scale)
        self.num_replicas = _check_int("num_replicas", num_replicas, 1)
        self.max_stages = _check_int("max_stages", max_stages, 1)
        if chunk_size is not None and chunk_size != "auto":
            chunk_size = _check_int("chunk_size", chunk_size, 1)
        self.chunk_size = chunk_size
        if not (isinstance(min_delta, (int, float)) and 0 <= min_delta < 1):
            raise ValueError(f"min_delta must be a number in [0, 1), got {min_delta!r}")
        self.min_delta = float(min_delta)
        if space is None:
            space = "constrained" if preset == "korali" else "unconstrained"
        if space not in ("unconstrained", "constrained"):
            raise ValueError(f"space must be 'unconstrained' or 'constrained', got {space!r}")
        self.space = space
        self.preset = preset
        self.compiled = bool(compiled)
        if not (isinstance(progress, bool) or callable(progress)):
            raise ValueError(f"progress must be True, False or a callable report(replica, row), got {progress!r}")
        self.progress = progress
        if tempered is not None and (isinstance(tempered, str) or not tempered):
            raise ValueError(f"tempered must be a non-empty sequence of site names, got {tempered!r}")
        self.tempered = None if tempered is None else tuple(tempered)
        if preset == "korali":
            if num_mcmc_steps not in (None, 1):
                raise ValueError(
                    "preset='korali' runs one MH step per resampled particle (Korali's default chain "
                    f"length); got num_mcmc_steps={num_mcmc_steps!r}; use preset='robust' for more"
                )
            if move is not None:
                raise ValueError("preset='korali' uses Korali's random walk; pass move= with preset='robust'")
            self.move = RandomWalk(num_steps=1, init_scale2=self.cov_scale, adapt=False, name="korali-rw")
            self.resampling = "multinomial"
        else:
            if move is not None:
                if num_mcmc_steps is not None:
                    raise ValueError("give num_mcmc_steps to the move itself when passing move=")
                if not (callable(move) and hasattr(move, "init_params")):
                    raise ValueError(
                        f"move must be a RandomWalk or KernelMove-like object (init_params + __call__), got {move!r}"
                    )
                self.move = move
            else:
                steps = 10 if num_mcmc_steps is None else _check_int("num_mcmc_steps", num_mcmc_steps, 1)
                self.move = RandomWalk(num_steps=steps, init_scale2=self.cov_scale, adapt=True)
            self.resampling = "systematic"
        self._flat: FlatModel | None = None
        self._data: tuple = ()  # the model's arrays on the device (FlatModel.data)
        self._model_args: tuple = ((), {})
        self._results: list[dict] = []
        self._samples_cache: dict | None = None

    @property
    def config(self) -> TMCMCConfig:
        """The core's settings, with ``chunk_size`` resolved for the current default device."""
        return TMCMCConfig(target_cov=self.target_cov, resampling=self.resampling, min_delta=self.min_delta,
                           chunk_size=resolve_chunk_size(self.chunk_size, self.num_particles))

    def prior_log_likelihood(self, rng_key, *args, **kwargs) -> np.ndarray:
        """Log likelihood of ``num_particles`` exact prior draws, with the compiled programs of :meth:`run`.

        The draws and their evaluation are the programs a run's first stage uses (same model structure, same
        number of particles), so checking a model before sampling compiles nothing that the run would not.

        Parameters
        ----------
        rng_key : jax.Array
            PRNG key of the draws.
        *args, **kwargs
            Arguments of the model (as in :meth:`run`).

        Returns
        -------
        numpy.ndarray
            Shape (num_particles,): the log likelihood of each draw (NaN or ±inf where it is not finite).

        Raises
        ------
        ValueError
            If the model has a discrete or no latent site.
        """
        flat = flat_model(self.model, args, kwargs, space=self.space, rng_key=rng_key)
        data = _on_device(flat.data)
        model = _model_programs(flat, self.config.chunk_size)
        position = model.draws(rng_key, data, self.num_particles)
        return np.asarray(model.evaluate(position, data)[1])

    def run(self, rng_key, *args, init_samples=None, init_log_evidence: float = 0.0, **kwargs) -> TMCMC:
        """Run ``num_replicas`` independent TMCMC runs of ``model(*args, **kwargs)``.

        Parameters
        ----------
        rng_key : jax.Array
            PRNG key (split into one key per replica).
        *args, **kwargs
            Arguments of the model; its numeric arrays become traced data of the compiled programs.
        init_samples : mapping of str to array_like or None
            Equal-weight draws of the base density, ``num_particles`` per latent site (constrained values; other
            keys are ignored), as the population at β = 0 of every replica; required with ``tempered`` (e.g. the
            posterior of the model without its tempered sites), and without it they must be exact prior draws.
            None: exact prior draws.
        init_log_evidence : float
            Log normalising constant of the base density (0 for the prior; with ``tempered`` the log evidence of
            the model without its tempered sites), added to every log evidence of the run.

        Returns
        -------
        TMCMC
            ``self``, with the results (:class:`~bubblecal.inference.tmcmc.results.TMCMCResults`).

        Raises
        ------
        ValueError
            If the model has a discrete or no latent site, every initial particle has a non-finite log
            likelihood or log prior, ``tempered`` names no observed or factor site, or ``init_samples`` is
            missing (with ``tempered``) or lacks a latent site or holds another number of draws.
        """
        if self.tempered is not None and init_samples is None:
            raise ValueError(f"TMCMC with tempered={list(self.tempered)} needs init_samples: draws of the model "
                             "without those sites (e.g. its posterior), from which the tempering starts")
        flat = flat_model(self.model, args, kwargs, space=self.space, rng_key=rng_key, tempered=self.tempered)
        self._flat = flat
        self._model_args = (args, dict(kwargs))  # for the pointwise log likelihood of the export
        self._samples_cache = None
        n, move, cfg = self.num_particles, self.move, self.config
        # the model's arrays go to the device once, then every program call takes them as arguments
        data = self._data = _on_device(flat.data)
        model = _model_programs(flat, cfg.chunk_size)

        init_log_evidence = float(init_log_evidence)
        if not math.isfinite(init_log_evidence):
            raise ValueError(f"init_log_evidence must be finite, got {init_log_evidence!r}")
        start = None if init_samples is None else start_positions(model, flat, init_samples, n)
        if not self.compiled and _splittable(move):
            # host-driven stages: the model-free pieces are compiled once per process and shared by
            # every model; only the prior draws and the evaluator belong to this model's structure
            stages = _stage_programs(move, cfg)

            def evaluate(position):
                return model.evaluate(position, data)

            def init_fn(key):
                position = model.draws(key, data, n) if start is None else start
                return stages.initial_state(position, *evaluate(position))

            def step_fn(key, st):
                return _split_stage(stages, evaluate, move, cfg, key, st)

            run_fn = None
        else:
            fused = _fused_programs(flat, move, cfg, self.max_stages)

            def init_fn(key):
                if start is not None:
                    return start_program(move)(start, *model.evaluate(start, data))
                return fused.init(key, data, n)

            def run_fn(key, st):
                return fused.run(key, st, data)

            def step_fn(key, st):
                return fused.step(key, st, data)

        if init_log_evidence:
            init_fn = offset_evidence(init_fn, init_log_evidence)
        self._results = []
        report, close_report = stage_reporter(self.progress, f"TMCMC {flat.label}", self.num_replicas)
        try:
            self._run_replicas(rng_key, flat, n, init_fn, step_fn, run_fn, report)
        finally:
            close_report()
        if self.tempered is not None:  # the results keep the model's own prior / likelihood split
            for res in self._results:
                st = res["state"]
                lp, ll = model.untemper(st.position, st.log_prior, st.log_likelihood, data)
                res["state"] = st._replace(log_prior=lp, log_likelihood=ll)
        return self

    def _run_replicas(self, rng_key, flat, n, init_fn, step_fn, run_fn, report):
        """Run the replicas (host-driven stages, or ``run_fn`` when compiled), reporting each stage row."""
        for r, key in enumerate(jax.random.split(rng_key, self.num_replicas)):
            k_draw, k_run = jax.random.split(key)
            t0 = time.perf_counter()
            state = init_fn(k_draw)
            finite = np.asarray(jnp.isfinite(state.log_likelihood) & jnp.isfinite(state.log_prior))
            t_init = time.perf_counter() - t0
            if not finite.any():
                raise ValueError(
                    f"TMCMC: all {n} initial particles (prior draws or init_samples) of model {flat.label!r} have "
                    "a non-finite log likelihood or log prior (every particle is -inf): check the observed data, "
                    "the likelihood's support and any numpyro.factor terms"
                )
            rows = [self._initial_row(state, t_init)]
            report(r, rows[0])
            if self.compiled:
                t0 = time.perf_counter()
                state, infos, status = run_fn(k_run, state)
                infos = jax.device_get(infos)
                status = int(status)
                seconds = time.perf_counter() - t0
                k = int(state.stage)
                for i in range(k):
                    rows.append(
                        self._row(i + 1, jax.tree_util.tree_map(lambda a, i=i: a[i], infos), seconds / k)
                    )
                    report(r, rows[-1])
            else:
                status = STATUS_RUNNING
                key_loop = k_run
                while True:
                    key_loop, sub = jax.random.split(key_loop)
                    t0 = time.perf_counter()
                    state, info = step_fn(sub, state)
                    info = jax.device_get(info)
                    rows.append(self._row(len(rows), info, time.perf_counter() - t0))
                    report(r, rows[-1])
                    status = int(info.status)
                    if status != STATUS_RUNNING:
                        break
                    if len(rows) - 1 >= self.max_stages:
                        status = STATUS_MAX_STAGES
                        break
            status_name = STATUS_NAMES[status]
            if status_name != "converged":
                last = rows[-1]
                warnings.warn(
                    f"TMCMC of model {flat.label!r} (replica {r}) stopped with status {status_name!r} at "
                    f"beta={last['beta']:.6g} after {len(rows) - 1} stages "
                    f"(max_stages={self.max_stages}, last delta={last['delta']:.3g}, min_delta={self.min_delta:g}); "
                    "partial results are kept (log evidence covers only beta reached)",
                    RuntimeWarning,
                    stacklevel=3,
                )
            self._results.append(
                {
                    "state": state,
                    "stages": rows,
                    "status": status_name,
                    "log_evidence": float(state.log_evidence),
                    "seconds": float(sum(row["seconds"] for row in rows)),
                }
            )
