"""Campaign records: one :mod:`bubblecal.data.store` record per replica of a finished (or failed) task.

The record format is :func:`bubblecal.data.make_record`'s; a campaign adds its provenance (campaign name,
design hash, task, device, diameter, and the worker's host, pid, compute time and per-replica info).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from bubblecal.campaigns.config import CampaignConfig
from bubblecal.campaigns.tasks import CampaignTask, TaskResult
from bubblecal.data import (
    RECORD_STATUSES,
    SHELL_PARAMETERS,
    jsonable,
    make_record,
    radius_dpd_from_diameter_um,
)

__all__ = ["task_records"]


def _replica_info(info: Mapping, r: int, n: int) -> dict:
    """Replica ``r``'s share of a task's info: a value that is a sequence of length ``n`` > 1 is split."""
    out = {}
    for k, v in info.items():
        if isinstance(v, (list, tuple, np.ndarray)) and len(v) == n and n > 1:
            out[k] = jsonable(v[r])
        else:
            out[k] = jsonable(v)
    return out


def task_records(config: CampaignConfig, task: CampaignTask, res: TaskResult | None, *, code_version: str,
                 design_hash: str, error: str | None = None, provenance: Mapping | None = None) -> list[dict]:
    """One store record per replica of a task.

    A replica's status is the task's, except: 'failed' for every replica when ``res`` is None (with
    ``error`` as message), 'invalid' when the result's shapes do not fit R replicas or an 'ok' curve holds
    non-finite values, 'failed' for a status outside :data:`bubblecal.data.names.RECORD_STATUSES`.

    Parameters
    ----------
    config : CampaignConfig
        The campaign.
    task : CampaignTask
        The task of R replicas.
    res : TaskResult or None
        Its result; None when the task raised.
    code_version : str
        :func:`bubblecal.data.names.code_version` of the writing process.
    design_hash : str
        ``config.design_hash()``.
    error : str, optional
        The exception text of a task that raised (the 'failed' records' message).
    provenance : Mapping, optional
        Provenance keys that override the defaults (a streamed curve: its task's index and size, ``streamed``).

    Returns
    -------
    list of dict
        R records (:func:`bubblecal.data.make_record`) in replica order; x, y in the task's units
        (DPD length / DPD force / DPD time; DPD force / DPD length), ``radius_dpd`` in DPD length.
    """
    R = task.n_replicas
    recs = []
    if res is not None:
        x = np.asarray(res.x, dtype=np.float64)
        y = np.asarray(res.y, dtype=np.float64)
        x2 = np.broadcast_to(x, y.shape) if x.ndim == 1 and y.ndim == 2 and x.shape[0] == y.shape[-1] else x
        shapes_ok = y.ndim == 2 and y.shape[0] == R and x2.shape == y.shape and len(res.status) == R
    for r in range(R):
        prov = {"campaign": config.name, "design_hash": design_hash, "task": task.index, "replicas_in_task": R,
                "device": task.device, "diameter_um": task.replica_diameter(r)}
        message = None
        if res is None:
            status, xs, ys, message = "failed", [], [], error
        else:
            prov.update(host=res.host, pid=res.pid, task_compute_s=round(res.compute_seconds, 6),
                        info=_replica_info(res.info, r, R))
            if not shapes_ok:
                status, xs, ys = "invalid", [], []
                message = f"task returned x {x.shape}, y {y.shape}, {len(res.status)} statuses for {R} replicas"
            else:
                xs, ys = x2[r].tolist(), y[r].tolist()
                status = str(res.status[r])
                if res.messages is not None and res.messages[r]:
                    message = str(res.messages[r])
                if status not in RECORD_STATUSES:
                    message, status = f"unknown status {status!r} from the simulation", "failed"
                elif status == "ok" and not (np.all(np.isfinite(x2[r])) and np.all(np.isfinite(y[r]))):
                    status, message = "invalid", "simulation reported ok but the curve holds non-finite values"
        if provenance:
            prov.update(provenance)
        recs.append(make_record(
            sample_id=task.sample_ids[r], setup=config.protocol,
            params={k: float(task.params[k][r]) for k in SHELL_PARAMETERS},
            radius_dpd=radius_dpd_from_diameter_um(task.replica_diameter(r)), x=xs, y=ys,
            status=status, seed=task.seeds[r], tier=task.tier, curve_id=f"{config.name}/{task.sample_ids[r]}",
            provenance=prov, message=message, code_version=code_version))
    return recs
