"""Per-dataset predictive statistics of the summaries, computed on worker threads.

A dataset's statistics (the 90 % predictive band at the data and on the figures' grid, the model-curve
quantiles and the CRPS; ``docs/inference.md`` section 7) are NumPy work over (S, P) arrays whose inner loops
release the GIL, so :class:`StatisticsPool` runs the datasets of an agent on the host's cores while the
caller's thread evaluates the next dataset's predictions.  The CRPS draws are made on the caller's thread in
dataset order (:meth:`StatisticsPool.submit`), so the scores are the same whatever the number of threads.
"""

from __future__ import annotations

from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

__all__ = ["MAX_STATISTICS_THREADS", "DatasetStatistics", "StatisticsPool", "dataset_statistics",
           "statistics_threads"]

#: Most worker threads of a :class:`StatisticsPool` (the work per dataset is a few hundred ms; more threads
#: than this only add memory for the arrays in flight).
MAX_STATISTICS_THREADS = 8


def statistics_threads(cpus: int | None = None) -> int:
    """Worker threads for the summaries' statistics: one per core, at most :data:`MAX_STATISTICS_THREADS`.

    Parameters
    ----------
    cpus : int, optional
        Cores to plan for (default: those this process may run on,
        :func:`~bubblecal.workflows.calibrate.device.usable_cores`).

    Returns
    -------
    int
        At least 1.
    """
    if cpus is None:
        from bubblecal.workflows.calibrate.device import usable_cores

        cpus = usable_cores()
    return max(1, min(MAX_STATISTICS_THREADS, int(cpus or 1)))


@dataclass(frozen=True)
class DatasetStatistics:
    """Predictive statistics of one dataset.

    Parameters
    ----------
    band : bubblecal.inference.PredictiveBand
        Median and 90 % band of the predictive mixture at the data points (units of y).
    crps : bubblecal.inference.CRPSResult
        CRPS of the predictive at the observations (units of y).
    grid_band : bubblecal.inference.PredictiveBand or None
        The same band on the figures' grid (None for a dataset without a grid).
    grid_model : numpy.ndarray or None
        (3, G) 5 %, 50 % and 95 % quantiles of the model curve (no observation noise) on the grid.
    """

    band: object
    crps: object
    grid_band: object | None = None
    grid_model: np.ndarray | None = None


def dataset_statistics(mu, sd, y, normals, gmu=None, gsd=None) -> DatasetStatistics:
    """Band, CRPS and (with a grid) the grid's band and model quantiles of one dataset.

    Parameters
    ----------
    mu, sd : numpy.ndarray
        (S, P) predictive means and noise standard deviations at the data points (units of y).
    y : numpy.ndarray
        (P,) observations.
    normals : numpy.ndarray
        (R, S, P) standard normal draws of the CRPS' R replicates.
    gmu, gsd : numpy.ndarray, optional
        (S, G) the same on the grid.

    Returns
    -------
    DatasetStatistics

    Raises
    ------
    ValueError
        For badly shaped or non-finite inputs (from :func:`bubblecal.inference.predictive_band` and
        :func:`bubblecal.inference.predictive_crps`).
    """
    from bubblecal.inference import predictive_band, predictive_crps

    band = predictive_band(mu, sd, 0.9)
    crps = predictive_crps(mu, sd, y, normals=normals)
    if gmu is None:
        return DatasetStatistics(band=band, crps=crps)
    return DatasetStatistics(band=band, crps=crps, grid_band=predictive_band(gmu, gsd, 0.9),
                             grid_model=np.quantile(gmu, [0.05, 0.5, 0.95], axis=0))


class StatisticsPool:
    """Worker threads computing :func:`dataset_statistics`, with a bounded number of datasets in flight.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the CRPS draws, consumed on the caller's thread in submission order.
    replicates : int
        CRPS replicates per dataset (>= 1).
    threads : int, optional
        Worker threads (default :func:`statistics_threads`); 1 computes on one worker, in order.

    Notes
    -----
    At most ``2 * threads`` datasets are in flight: :meth:`submit` waits for the oldest before it takes
    another, so the arrays held at once stay bounded whatever the number of datasets.  Use as a context
    manager; :meth:`results` returns every dataset's statistics in submission order.
    """

    def __init__(self, rng: np.random.Generator, replicates: int, threads: int | None = None):
        if replicates < 1:
            raise ValueError(f"replicates must be >= 1, got {replicates}")
        self._rng = rng
        self._replicates = int(replicates)
        self._threads = statistics_threads() if threads is None else max(1, int(threads))
        self._pool = ThreadPoolExecutor(self._threads, thread_name_prefix="bubblecal-summary")
        self._inflight: deque[tuple[str, Future]] = deque()
        self._done: dict[str, DatasetStatistics] = {}

    def __enter__(self) -> StatisticsPool:
        return self

    def __exit__(self, *exc) -> None:
        self._pool.shutdown(wait=True, cancel_futures=exc[0] is not None)

    def submit(self, name: str, mu, sd, y, gmu=None, gsd=None) -> None:
        """Queue the statistics of dataset ``name`` (arguments as :func:`dataset_statistics`, less ``normals``).

        Raises
        ------
        ValueError
            If ``name`` was submitted before.
        Exception
            Whatever an earlier dataset's statistics raised, when this call waits for it.
        """
        if name in self._done or any(n == name for n, _ in self._inflight):
            raise ValueError(f"dataset {name!r} submitted twice")
        mu = np.asarray(mu, dtype=float)
        normals = self._rng.standard_normal((self._replicates, *mu.shape))
        while len(self._inflight) >= 2 * self._threads:
            self._collect_oldest()
        self._inflight.append((name, self._pool.submit(dataset_statistics, mu, sd, y, normals, gmu, gsd)))

    def _collect_oldest(self) -> None:
        name, fut = self._inflight.popleft()
        self._done[name] = fut.result()

    def results(self) -> dict[str, DatasetStatistics]:
        """Every submitted dataset's statistics, in submission order (waits for the unfinished ones).

        Raises
        ------
        Exception
            The first error a dataset's statistics raised.
        """
        while self._inflight:
            self._collect_oldest()
        return dict(self._done)
