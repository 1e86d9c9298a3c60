"""Transitional MCMC (Ching & Chen 2007, and the Korali variant) for NumPyro models and flat densities.

User code imports the front end from the layer, ``from bubblecal.inference import TMCMC``; this
subpackage holds the whole algorithm (``docs/inference.md`` section 5):

- :mod:`~bubblecal.inference.tmcmc.sampler`: :class:`TMCMC`, the NumPyro front end (presets, replicas);
- :mod:`~bubblecal.inference.tmcmc.kernel`: :class:`TMCMCKernel`, TMCMC as a ``numpyro.infer.MCMC`` kernel;
- :mod:`~bubblecal.inference.tmcmc.batched`: :func:`run_batched`, the runs of K datasets of one model structure
  in one compiled program (vmap over datasets), :func:`batch_groups`, :class:`BatchStructureError`;
- :mod:`~bubblecal.inference.tmcmc.results`: :class:`TMCMCResults`, what a run reports;
- :mod:`~bubblecal.inference.tmcmc.core`: the pure, jittable core on flat particle arrays, BlackJAX-style
  (:func:`init`, :func:`step`, :func:`run`, :func:`tmcmc`);
- :mod:`~bubblecal.inference.tmcmc.state`: :class:`TMCMCState`, :class:`StageInfo`, :class:`TMCMCConfig`;
- :mod:`~bubblecal.inference.tmcmc.tempering`: exponent, weights, resampling and covariance of a stage;
- :mod:`~bubblecal.inference.tmcmc.moves`: the :class:`Move` interface, :class:`RandomWalk`,
  :class:`KernelMove`, :func:`hmc_move`, :func:`nuts_move`;
- :mod:`~bubblecal.inference.tmcmc.progress`: the per-stage reporter (``TMCMC(..., progress=True)`` or a
  callable ``report(replica, row)``), :class:`StageDisplay` and :func:`stage_text`;
- :mod:`~bubblecal.inference.tmcmc.ahead`: :func:`compile_ahead`, the programs of runs (:class:`RunSpec`)
  compiled before they run, several at a time (:func:`compile_lowered` for any lowered programs);
- :mod:`~bubblecal.inference.tmcmc.executables`: the program store, compiled programs kept on disk and read
  back by later processes without tracing (:func:`enable_program_store`, :func:`store_counts`);
- :mod:`~bubblecal.inference.tmcmc.evaluator`: :class:`Evaluator`, the densities over a population, and
  :func:`resolve_chunk_size` / :data:`CPU_CHUNK_SIZE` (how many particles at a time);
- private: ``_flat_model`` (a NumPyro model as flat prior / likelihood functions) and ``_programs``
  (compiled programs cached per process; :func:`clear_program_cache`).
"""

from bubblecal.inference.tmcmc._programs import clear_program_cache
from bubblecal.inference.tmcmc.ahead import (
    MAX_COMPILE_WORKERS,
    RunSpec,
    compile_ahead,
    compile_lowered,
    compile_workers,
)
from bubblecal.inference.tmcmc.batched import BatchStructureError, batch_groups, run_batched, structure_key
from bubblecal.inference.tmcmc.core import TMCMCAlgorithm, init, run, step, tmcmc
from bubblecal.inference.tmcmc.evaluator import CPU_CHUNK_SIZE, Evaluator, resolve_chunk_size
from bubblecal.inference.tmcmc.executables import (
    disable_program_store,
    enable_program_store,
    program_store_folder,
    store_counts,
)
from bubblecal.inference.tmcmc.kernel import TMCMCKernel, TMCMCKernelState
from bubblecal.inference.tmcmc.moves import KernelMove, Move, MoveResult, RandomWalk, hmc_move, nuts_move
from bubblecal.inference.tmcmc.progress import StageDisplay, StageReporter, stage_text
from bubblecal.inference.tmcmc.results import POINTWISE_CPU_CHUNK, STAGE_COLUMNS, TMCMCResults
from bubblecal.inference.tmcmc.sampler import PRESETS, TMCMC
from bubblecal.inference.tmcmc.state import STATUS_NAMES, StageInfo, TMCMCConfig, TMCMCState

__all__ = [
    "TMCMC", "TMCMCKernel", "TMCMCKernelState", "PRESETS", "TMCMCResults", "STAGE_COLUMNS", "clear_program_cache",
    "TMCMCState", "StageInfo", "run_batched", "batch_groups", "structure_key", "BatchStructureError",
    "TMCMCConfig", "STATUS_NAMES", "TMCMCAlgorithm", "init", "step", "run", "tmcmc", "Move", "MoveResult",
    "RandomWalk", "KernelMove", "hmc_move", "nuts_move", "Evaluator", "CPU_CHUNK_SIZE",
    "resolve_chunk_size", "POINTWISE_CPU_CHUNK", "StageDisplay", "StageReporter", "stage_text", "RunSpec",
    "compile_ahead", "compile_lowered", "compile_workers", "MAX_COMPILE_WORKERS", "enable_program_store",
    "disable_program_store", "program_store_folder", "store_counts",
]
