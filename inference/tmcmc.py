"""TMCMC for NumPyro models: adaptive tempering, log evidence, Korali parity, pluggable moves.

Write a NumPyro model once; the same model runs under ``numpyro.infer.MCMC(NUTS(model))`` and here::

    tm = TMCMC(model, num_particles=10_000, num_replicas=4)
    tm.run(jax.random.PRNGKey(0), x, y=y)
    tm.get_samples(), tm.log_evidence, tm.log_evidence_se, tm.stage_info, tm.status

The algorithm (``../shared/docs/inference.md`` §5) lives in the pure core
:mod:`bubblecal.inference.tmcmc_core` (re-exported here: :class:`TMCMCState`, :func:`init`,
:func:`step`, :func:`run`, :func:`tmcmc`, :class:`RandomWalk`); this module turns a model into the flat
``log_prior_fn`` / ``log_likelihood_fn`` the core needs, drives the stages and collects diagnostics.

Presets
-------
``robust`` (default): unconstrained space, systematic resampling, ``num_mcmc_steps`` (default 10)
random-walk MH steps per stage from N(x, s² Σ_w) with s adapted toward acceptance 0.3 (starting at
s² = ``cov_scale``), or any ``move`` (e.g. :func:`bubblecal.inference.moves.hmc_move`).

``korali``: Korali's TMCMC with its defaults — constrained space (proposals outside the box are
rejected), CoV target on the incremental weights, multinomial resampling, proposal covariance
``cov_scale`` (0.04) × weighted particle covariance, and chain lengths from the selection counts with
Korali's default maximum chain length 1: each of the N resampled copies makes one MH step.  Like
Korali, the run ends with one generation (resample + move) at β = 1.

Failure behaviour: non-finite log L gets weight 0; if every prior draw has a non-finite log L (or log
prior) :class:`ValueError` names the model; the stage cap and the minimum Δ end the run with ``status``
'max_stages' / 'stalled' and a :class:`RuntimeWarning`, keeping the partial results.
"""

from __future__ import annotations

import collections
import functools
import math
import time
import warnings
from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from bubblecal.inference import tmcmc_core as core
from bubblecal.inference._numpyro_utils import FlatModel, _static_key
from bubblecal.inference.tmcmc_core import (  # noqa: F401  (re-exported: the pure core is part of this module's API)
    STATUS_NAMES,
    RandomWalk,
    StageInfo,
    TMCMCConfig,
    TMCMCState,
    init,
    run,
    step,
    tmcmc,
)

PRESETS = ("robust", "korali")

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


def _check_int(name, value, minimum):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value}")
    return int(value)


def _check_positive(name, value):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive number, got {value!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return v


# ---------------------------------------------------------------------------------------------
# Compiled programs, cached per process
#
# A phase of a staged hierarchy is a new TMCMC run of a new model; if every run built its own jitted
# closures, every run would trace and compile everything again.  Programs are therefore built once
# per key and kept here: the model-free stage pieces per (move, resampling), the model's own
# programs per FlatModel.signature (its arrays are traced arguments, so datasets of one structure
# share them), and jit keeps one executable per argument shape (N, d, data shapes) under each.
# ---------------------------------------------------------------------------------------------

_PROGRAM_CACHE_SIZE = 64
_program_cache: collections.OrderedDict = collections.OrderedDict()


def _cached_programs(key, build: Callable):
    """``build()`` once per ``key`` (least recently used entries beyond the cache size are dropped)."""
    if key in _program_cache:
        _program_cache.move_to_end(key)
        return _program_cache[key]
    value = _program_cache[key] = build()
    while len(_program_cache) > _PROGRAM_CACHE_SIZE:
        _program_cache.popitem(last=False)
    return value


def clear_program_cache() -> None:
    """Forget every cached compiled TMCMC program (the next runs trace and compile again)."""
    _program_cache.clear()


class _StagePrograms(NamedTuple):
    """Jitted model-free pieces of a random-walk stage (see :func:`_split_stage`)."""

    initial_state: Callable  # (position, log_prior, log_likelihood) -> TMCMCState
    begin: Callable  # (key, state, target CoV) -> (StagePlan, chol, log s, move carry)
    propose: Callable  # (key, x, chol, log s) -> (key, acceptance key, proposal)
    accept: Callable  # (acceptance key, carry, proposal, lp, ll, beta) -> carry
    end: Callable  # (state, plan, carry, log s at the start, min Δ) -> (state, StageInfo)


class _ModelPrograms(NamedTuple):
    """Jitted programs of one model structure; the model's arrays (``FlatModel.data``) are arguments."""

    draws: Callable  # (key, data, num) -> (num, d) exact prior draws in the flat space
    evaluate: Callable  # (position, data) -> (log prior, log L) of (N, d) particles
    sites: Callable  # (position, data) -> {site: (N, ...) constrained values and deterministic sites}


class _FusedPrograms(NamedTuple):
    """Jitted init / stage / whole run with the move fused in (moves that need the model inside)."""

    init: Callable  # (key, data, num) -> TMCMCState
    step: Callable  # (key, state, data) -> (state, StageInfo)
    run: Callable  # (key, state, data) -> (state, infos, status)


def _splittable(move) -> bool:
    """True for moves whose stage can run as model-free pieces around the evaluator (the random walk)."""
    return isinstance(move, RandomWalk)


def _stage_programs(move: RandomWalk, config: TMCMCConfig) -> _StagePrograms:
    """The stage pieces of ``move`` with ``config``'s resampling, shared by every model, dataset and CoV
    target: the numeric settings (target CoV, minimum Δ) are traced arguments of each call."""

    def build():
        def settings(target_cov, min_delta):
            return TMCMCConfig(target_cov=target_cov, resampling=config.resampling, min_delta=min_delta)

        def begin(key, state, target_cov):
            plan = core.prepare_stage(key, state, settings(target_cov, 0.0))
            chol, log_s = move.start(plan.weighted_cov, state.move_params)
            carry = (plan.position, plan.log_prior, plan.log_likelihood, log_s, jnp.zeros((), plan.position.dtype))
            return plan, chol, log_s, carry

        def end(state, plan, carry, log_s0, min_delta):
            return core.finish_stage(state, plan, move.result(carry, log_s0), settings(1.0, min_delta))

        return _StagePrograms(
            initial_state=jax.jit(lambda position, lp, ll: core.initial_state(position, lp, ll, move)),
            begin=jax.jit(begin),
            propose=jax.jit(move.propose),
            accept=jax.jit(move.accept),
            end=jax.jit(end),
        )

    # the type is part of the key: NamedTuples of equal fields compare equal across classes
    return _cached_programs(("stage", type(move), move, config.resampling), build)


def _densities(flat: FlatModel, data) -> tuple[Callable, Callable]:
    """(log prior, log likelihood) of one flat vector of ``flat``'s structure with ``data`` as its arrays."""
    return functools.partial(flat.log_prior, data=data), functools.partial(flat.log_likelihood, data=data)


def _model_programs(flat: FlatModel, chunk_size: int | None) -> _ModelPrograms:
    """Prior draws, evaluator and sites of ``flat``'s structure; ``flat`` (the first model seen with
    this signature) serves as the template, every later model of equal signature passes its own data."""

    def build():
        def evaluate(position, data):
            return core.make_evaluator(*_densities(flat, data), chunk_size)(position)

        def sites(position, data):
            return core.chunked_vmap(functools.partial(flat.sites, data=data), chunk_size)(position)

        return _ModelPrograms(
            draws=jax.jit(lambda key, data, num: flat.prior_draws(key, num, data), static_argnums=2),
            evaluate=jax.jit(evaluate),
            sites=jax.jit(sites),
        )

    return _cached_programs(("model", flat.signature, chunk_size), build)


def _fused_programs(flat: FlatModel, move: Any, config: TMCMCConfig, max_stages: int) -> _FusedPrograms:
    """Init, stage and whole run with ``move`` fused in, for ``flat``'s structure (data as arguments)."""

    def build():
        return _FusedPrograms(
            init=jax.jit(
                lambda key, data, num: core.init(
                    flat.prior_draws(key, num, data), *_densities(flat, data), move, config.chunk_size
                ),
                static_argnums=2,
            ),
            step=jax.jit(lambda key, state, data: core.step(key, state, *_densities(flat, data), move, config)),
            run=jax.jit(
                lambda key, state, data: core.run(key, state, *_densities(flat, data), move, config, max_stages)
            ),
        )

    key = ("fused", flat.signature, type(move), _static_key(move), config, max_stages)
    return _cached_programs(key, build)


def _split_stage(stages: _StagePrograms, evaluate: Callable, move: RandomWalk, config: TMCMCConfig, key, state):
    """One stage as host-driven pieces: the arithmetic and random numbers of :func:`core.step` with a
    :class:`RandomWalk`, but only ``evaluate`` (jitted, ``(N, d) -> (log prior, log L)``) is specific to
    the model.  Returns ``(state, info)``.  (Not bitwise equal to the fused step: XLA fuses the
    proposal into the fused step's likelihood, which moves log L by float round-off, ~1e-6 relative.)"""
    # Python floats reach jit as traced weakly typed scalars (the dtype of the particles), not constants
    plan, chol, log_s0, carry = stages.begin(key, state, float(config.target_cov))
    key = plan.key_move
    for _ in range(move.num_steps):
        key, k_acc, prop = stages.propose(key, carry[0], chol, carry[3])
        lp_p, ll_p = evaluate(prop)
        carry = stages.accept(k_acc, carry, prop, lp_p, ll_p, plan.beta)
    return stages.end(state, plan, carry, log_s0, float(config.min_delta))


class TMCMC:
    """Transitional MCMC of a NumPyro model (see the module docstring).

    :param model: NumPyro model function (continuous latent sites, any supports).
    :param num_particles: N (published: 50,000).
    :param target_cov: target coefficient of variation of the incremental weights (0.8 single
        level, 0.6 hierarchical phases; ESS/N ≈ 1/(1 + c²)).
    :param cov_scale: s² in Σ = s² Σ_w (Korali 0.04; the robust preset's starting value).
    :param num_mcmc_steps: MH steps per stage for the robust random walk (default 10); the korali preset
        runs exactly one.
    :param preset: 'robust' or 'korali'.
    :param move: a move object (``RandomWalk`` or a :class:`~bubblecal.inference.moves.KernelMove`,
        e.g. ``hmc_move()``); replaces the preset's random walk (robust preset only).
    :param num_replicas: independent runs; ``log_evidence`` is their mean, ``log_evidence_se`` its
        standard error; samples and stage table are those of the first replica.
    :param max_stages: stage cap (status 'max_stages' when hit).
    :param chunk_size: evaluate the likelihood this many particles at a time (memory).
    :param space: 'unconstrained' (robust default) or 'constrained' (korali default).
    :param min_delta: a stage with Δ below this (and β < 1) ends the run with status 'stalled'.
    :param compiled: run all stages in one ``lax.while_loop`` (no host round-trip per stage; the
        'seconds' column then holds the run's mean per stage).
    """

    def __init__(
        self,
        model: Callable,
        num_particles: int = 50_000,
        target_cov: float = 0.8,
        cov_scale: float = 0.04,
        num_mcmc_steps: int | None = None,
        preset: str = "robust",
        move: Any | None = None,
        num_replicas: int = 1,
        max_stages: int = 200,
        chunk_size: int | None = None,
        space: str | None = None,
        min_delta: float = 1e-9,
        compiled: bool = False,
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
        if chunk_size is not None:
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
        self.config = TMCMCConfig(
            target_cov=self.target_cov,
            resampling=self.resampling,
            min_delta=self.min_delta,
            chunk_size=self.chunk_size,
        )
        self._flat: FlatModel | None = None
        self._data: tuple = ()  # the model's arrays on the device (FlatModel.data)
        self._results: list[dict] = []
        self._samples_cache: dict | None = None

    # ------------------------------------------------------------------------------------------

    def run(self, rng_key, *args, **kwargs) -> TMCMC:
        """Run ``num_replicas`` independent TMCMC runs of ``model(*args, **kwargs)``; returns self."""
        flat = FlatModel(self.model, args, kwargs, space=self.space, rng_key=rng_key)
        self._flat = flat
        self._samples_cache = None
        n, move, cfg = self.num_particles, self.move, self.config
        # the model's arrays go to the device once, then every program call takes them as arguments
        data = self._data = tuple(jnp.asarray(v) for v in flat.data)
        model = _model_programs(flat, cfg.chunk_size)

        if not self.compiled and _splittable(move):
            # host-driven stages: the model-free pieces are compiled once per process and shared by
            # every model; only the prior draws and the evaluator belong to this model's structure
            stages = _stage_programs(move, cfg)

            def evaluate(position):
                return model.evaluate(position, data)

            def init_fn(key):
                position = model.draws(key, data, n)
                return stages.initial_state(position, *evaluate(position))

            def step_fn(key, st):
                return _split_stage(stages, evaluate, move, cfg, key, st)
        else:
            fused = _fused_programs(flat, move, cfg, self.max_stages)

            def init_fn(key):
                return fused.init(key, data, n)

            def run_fn(key, st):
                return fused.run(key, st, data)

            def step_fn(key, st):
                return fused.step(key, st, data)

        self._results = []
        for r, key in enumerate(jax.random.split(rng_key, self.num_replicas)):
            k_draw, k_run = jax.random.split(key)
            t0 = time.perf_counter()
            state = init_fn(k_draw)
            finite = np.asarray(jnp.isfinite(state.log_likelihood) & jnp.isfinite(state.log_prior))
            t_init = time.perf_counter() - t0
            if not finite.any():
                raise ValueError(
                    f"TMCMC: all {n} prior draws of model {flat.label!r} have a non-finite log likelihood "
                    "or log prior (every particle is -inf): check the observed data, the likelihood's "
                    "support and any numpyro.factor terms"
                )
            rows = [self._initial_row(state, t_init)]
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
            else:
                status = core.STATUS_RUNNING
                key_loop = k_run
                while True:
                    key_loop, sub = jax.random.split(key_loop)
                    t0 = time.perf_counter()
                    state, info = step_fn(sub, state)
                    info = jax.device_get(info)
                    rows.append(self._row(len(rows), info, time.perf_counter() - t0))
                    status = int(info.status)
                    if status != core.STATUS_RUNNING:
                        break
                    if len(rows) - 1 >= self.max_stages:
                        status = core.STATUS_MAX_STAGES
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
                    stacklevel=2,
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
        return self

    @staticmethod
    def _initial_row(state, seconds):
        ll = np.asarray(state.log_likelihood)
        fin = np.isfinite(ll)
        return {
            "stage": 0,
            "beta": 0.0,
            "delta": 0.0,
            "cov": float("nan"),
            "ess": float(len(ll)),
            "log_z_increment": 0.0,
            "log_evidence": 0.0,
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
        row = {"stage": stage}
        for f in StageInfo._fields:
            if f == "status":
                continue
            v = np.asarray(getattr(info, f))
            row[f] = int(v) if f in ("num_nonfinite", "num_evaluations") else float(v)
        row["seconds"] = seconds
        return row

    # ------------------------------------------------------------------------------------------

    def _need_run(self):
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

        Columns: stage, beta, delta, cov (achieved), ess, log_z_increment, log_evidence (running
        total), acceptance, unique_fraction, scale, max_log_likelihood, num_nonfinite,
        num_evaluations, seconds.  The first replica's row 0 and stage 1 (``compiled=False``; every
        row with ``compiled=True``) include the compilation time.
        """
        return self.replica_stage_info(0)

    def replica_stage_info(self, replica: int):
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
        """Constrained latent values and deterministic sites, leading dimension = num_particles."""
        self._need_run()
        if replica == 0 and self._samples_cache is not None:
            return self._samples_cache
        pos = self._results[replica]["state"].position
        out = _model_programs(self._flat, self.chunk_size).sites(pos, self._data)
        out = {k: np.asarray(v) for k, v in out.items()}
        if replica == 0:
            self._samples_cache = out
        return out

    def print_summary(self, prob: float = 0.9) -> None:
        """Posterior summary of the first replica, the evidence and the stage table."""
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

    def to_inference_data(self):
        """ArviZ InferenceData: posterior (1 chain × N draws), sample_stats ('loglik': total log
        likelihood, 'log_prior': in the sampling space), a 'tmcmc_stages' group with the stage table, and the evidence/status in attrs."""
        import arviz as az
        import xarray as xr

        samples = self.get_samples()
        st = self.state
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
        }
        idata = az.from_dict(
            posterior={k: v[None] for k, v in samples.items()},
            sample_stats={
                "loglik": np.asarray(st.log_likelihood)[None],
                "log_prior": np.asarray(st.log_prior)[None],
            },
        )
        idata.posterior.attrs.update(attrs)
        idata.sample_stats.attrs.update(attrs)
        table = self.stage_info
        ds = xr.Dataset(
            {c: ("stage", table[c].to_numpy()) for c in table.columns if c != "stage"},
            coords={"stage": table["stage"].to_numpy()},
            attrs=attrs,
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            idata.add_groups({"tmcmc_stages": ds})
        return idata
