"""bubblecal.campaigns: training-data campaigns, a seeded design over a parameter box run into a resumable store.

A campaign turns a :class:`CampaignConfig` (usually read from a TOML campaign file by
:func:`load_campaign_file`) into one record per design point in an append-only
:class:`bubblecal.data.store.CampaignStore`::

    from bubblecal.campaigns import CampaignConfig, load_campaign_file, run_campaign

    cfg = CampaignConfig(name="def21", protocol="compression", diameter_um=2.1, ranges={...},
                         n_samples=6000, seed=1, tier="quasistatic", replicas_per_task=64,
                         device="cuda", store="def21.store")
    summary = run_campaign(cfg)                 # LocalCluster(processes=True, threads_per_worker=1)
    summary = run_campaign(cfg, scheduler_address="tcp://10.0.0.5:8786")   # any Dask scheduler
    summary = run_campaign(load_campaign_file("definity_compression_2.1um").config)   # a shipped file

Modules: :mod:`~bubblecal.campaigns.config` (the config and its validation), :mod:`~bubblecal.campaigns.files`
(campaign TOML files, the shipped ones in ``shipped/``), :mod:`~bubblecal.campaigns.ranges` (the [ranges]
table), :mod:`~bubblecal.campaigns.design` (design points, ids, seeds), :mod:`~bubblecal.campaigns.tasks`
(tasks, pending samples, task functions), :mod:`~bubblecal.campaigns.records` (store records),
:mod:`~bubblecal.campaigns.runner` (the Dask / in-process loop), :mod:`~bubblecal.campaigns.status`
(store status).  Importing the package imports neither Warp nor Dask.

Design
------
* ``design='lhs'``: :func:`lhs_design` draws ``n_samples`` points with
  ``scipy.stats.qmc.LatinHypercube(d, seed=config.seed)`` over the free parameters (``lo < hi``) and
  scales them to the ranges; a parameter with ``lo == hi`` is held fixed.  The design is a pure function
  of the config, so a restarted campaign regenerates exactly the same points.
* ``design='grid'`` (ringdown sweeps): ``ka`` takes ``ka_values`` (or ``n_samples`` values evenly spaced
  over ``ranges['ka']``), every other parameter is fixed (``lo == hi``), mu = ka/3 (the shell model's
  rule); several diameters may be listed and the design is diameters x ka values.
* A design over a diameter range (``diameter_range_um`` with ``diameter_step_um``; 'lhs' only): the
  hypercube's last dimension is the diameter, mapped evenly onto the levels lo, lo + step, ..., hi (one mesh
  per level; on one mesh level the quasi-static tier runs the levels in one refill pool); compression grids
  are then fractions of the diameter (``loading_fractions``), indentation forces absolute
  (:mod:`~bubblecal.campaigns.diameters`).

Sample ``i`` has the id ``f"{name}-{i:06d}"`` and the seed :func:`sample_seed` ``(config.seed, i)``.

Execution
---------
``pending`` = design minus the samples whose latest store record is final (every status except
``config.retry_statuses``, default 'failed' and 'timeout': a sample that ruptured, went unstable or
produced a non-finite curve ('invalid') is not re-run).  Pending samples are chunked into tasks of
``replicas_per_task`` replicas of one diameter (of neighbouring diameter levels when
:attr:`CampaignConfig.pools_levels`) -- one :class:`~bubblecal.sim.tiers.CurveRequest` (one batched GPU
launch) per task -- and submitted to Dask.  Results are collected with ``as_completed`` and
appended by the CLIENT process only (single writer; every task's records go out in one atomic,
fsync'ed append), so a killed worker (Dask reschedules its task) or an interrupted client (the next run
skips what is stored) loses and duplicates nothing.  The per-task compute time is measured inside the
task, so Dask's overhead is ``1 - sum(task compute) / (wall x workers)`` (:class:`CampaignSummary`).

Before any task, a campaign on 'cuda' checks that the device exists (on this machine, or on every Dask
worker: :func:`check_device`); a call whose samples all fail is reported as such
(:attr:`CampaignSummary.all_failed`; the CLI exits 1).

A scheduler address is checked before anything runs (:func:`check_scheduler_address`), and a remote one
that does not answer within ``connect_timeout_s`` stops the call with the address named
(:func:`connect_scheduler`).

``scheduler_address='inline'`` runs the same loop in-process without Dask (debugging, or a machine
without dask installed), and there the quasi-static indentation tier (async schedule) streams: each curve's
record is appended as soon as the curve is finished (provenance ``streamed``), so a large task (one long
refill pool per campaign, whose slowest curves are paid once) loses only its unfinished curves when killed.
One process per GPU: processes sharing a GPU without MPS time-slice it, and a pool's latency-bound slowest
curves then crawl (measurements in benchmarks/RESULTS.md).  Several GPUs on one host: ``run_campaign(cfg,
gpus=N)`` (``bubblecal sim campaign CFG --gpus N``) starts one worker process per GPU, each pinned by
``CUDA_VISIBLE_DEVICES`` (:func:`gpu_cluster`), after counting the GPUs without touching CUDA here
(:func:`check_gpus`); a plain LocalCluster puts every 'cuda' worker on GPU 0.  A run with fewer tasks than
workers splits its tasks so every worker has one of the same cost (:func:`make_tasks`).

Clusters: SLURM through dask-jobqueue (the ``[cluster]`` extra), one GPU job per worker, in
:mod:`bubblecal.campaigns.slurm` (``python -m bubblecal.campaigns.slurm --jobs 8``; then ``--scheduler
tcp://...``); a ``dask cuda worker`` cluster of one's own works the same way.  docs/distributed.md.

Units: parameter ranges in DPD units (ka DPD 2-D modulus, kb DPD energy, b1..a4 dimensionless);
diameters in um; loading grids in DPD length (compression) or DPD force (indentation); ringdown
time in DPD time and radius in DPD length (:mod:`bubblecal.data.units`).  Campaign file and store record
formats: ``docs/data-formats.md``.
"""

from bubblecal.campaigns.cluster import GPU_WORKER_DEVICE, gpu_cluster, open_client
from bubblecal.campaigns.config import (
    DESIGN_FIELDS,
    DESIGNS,
    EXECUTION_ONLY_TIER_SETTINGS,
    OPTIONAL_DESIGN_FIELDS,
    CampaignConfig,
)
from bubblecal.campaigns.design import design_points, grid_design, lhs_design, sample_ids, sample_seed
from bubblecal.campaigns.devices import check_device, check_gpus, cuda_device_count, visible_gpus
from bubblecal.campaigns.diameters import (
    DIAMETER_DESIGN_RANGE_UM,
    MAX_COMPRESSION_FRACTION,
    diameter_levels,
    fraction_grid,
    published_grid,
)
from bubblecal.campaigns.errors import CampaignConfigError, CampaignError, CampaignFileError
from bubblecal.campaigns.files import (
    CampaignFile,
    available_campaigns,
    campaign_path,
    load_campaign_config,
    load_campaign_file,
    parse_tier_settings,
)
from bubblecal.campaigns.records import task_records
from bubblecal.campaigns.runner import CampaignSummary, run_campaign
from bubblecal.campaigns.scheduler import (
    CONNECT_TIMEOUT_S,
    SCHEDULER_CHOICES,
    check_scheduler_address,
    connect_scheduler,
)
from bubblecal.campaigns.status import DesignProgress, StoreStatus, design_progress, store_status
from bubblecal.campaigns.tasks import (
    CampaignTask,
    TaskResult,
    make_tasks,
    pending_indices,
    simulate_task,
    synthetic_simulate,
)

__all__ = [
    # configuration and errors
    "DESIGNS", "DESIGN_FIELDS", "OPTIONAL_DESIGN_FIELDS", "EXECUTION_ONLY_TIER_SETTINGS", "CampaignConfig",
    # diameters and loading grids
    "DIAMETER_DESIGN_RANGE_UM", "MAX_COMPRESSION_FRACTION", "diameter_levels", "fraction_grid", "published_grid",
    # devices and clusters (one worker per GPU; SLURM: bubblecal.campaigns.slurm)
    "check_device", "cuda_device_count", "visible_gpus", "check_gpus", "GPU_WORKER_DEVICE", "gpu_cluster",
    "open_client",
    "CampaignError", "CampaignConfigError", "CampaignFileError",
    # campaign files
    "CampaignFile", "available_campaigns", "campaign_path", "load_campaign_file", "load_campaign_config",
    "parse_tier_settings",
    # design
    "sample_ids", "sample_seed", "lhs_design", "grid_design", "design_points",
    # tasks and records
    "CampaignTask", "TaskResult", "make_tasks", "pending_indices", "simulate_task", "synthetic_simulate",
    "task_records",
    # running and status
    "CampaignSummary", "run_campaign", "SCHEDULER_CHOICES", "CONNECT_TIMEOUT_S", "check_scheduler_address",
    "connect_scheduler", "StoreStatus", "store_status", "DesignProgress", "design_progress",
]
