"""Where a campaign stands: status counts of a store, and what of a config's design is done or pending."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from bubblecal.campaigns.config import CampaignConfig
from bubblecal.campaigns.tasks import make_tasks, pending_indices
from bubblecal.data import RETRY_STATUSES, CampaignStore

__all__ = ["StoreStatus", "store_status", "DesignProgress", "design_progress"]


@dataclass
class StoreStatus:
    """Counts of a campaign store: latest status per sample, design size (from the header), pending.

    Parameters
    ----------
    path : str
        The store (directory or .jsonl).
    name : str or None
        Campaign name from the store header (None: no header).
    n_design : int or None
        Design points from the header (None: no header).
    counts : dict of str to int
        Latest status per sample -> number of samples.
    n_records : int
        Readable record lines.
    n_lines_skipped : int
        Unreadable lines skipped.
    retry_statuses : tuple of str
        Statuses counted as pending.
    config : dict
        The campaign config kept in the header (empty without one).
    pending : int, optional
        Pending samples by a config's :func:`~bubblecal.campaigns.pending_indices`, when given.
    """

    path: str
    name: str | None
    n_design: int | None
    counts: dict[str, int]
    n_records: int
    n_lines_skipped: int
    retry_statuses: tuple[str, ...]
    config: dict
    pending: int | None = None

    @property
    def n_samples_stored(self) -> int:
        """Samples with at least one record."""
        return sum(self.counts.values())

    @property
    def n_final(self) -> int:
        """Samples whose latest status is not a retry status."""
        return sum(v for k, v in self.counts.items() if k not in self.retry_statuses)

    @property
    def n_pending(self) -> int | None:
        """``pending`` when given, else design size minus final samples (None without a header)."""
        if self.pending is not None:
            return self.pending
        return None if self.n_design is None else self.n_design - self.n_final

    def as_dict(self) -> dict:
        """The status as JSON-able dict (without ``config`` and ``retry_statuses``)."""
        return {"path": self.path, "name": self.name, "n_design": self.n_design, "counts": dict(self.counts),
                "n_records": self.n_records, "n_lines_skipped": self.n_lines_skipped, "n_final": self.n_final,
                "n_pending": self.n_pending}


def store_status(path: str | Path, retry_statuses: Sequence[str] | None = None) -> StoreStatus:
    """Read a campaign store and count statuses; pending needs the campaign header.

    Parameters
    ----------
    path : str or Path
        Store directory or bare ``.jsonl`` file.
    retry_statuses : Sequence[str], optional
        Statuses counted as pending (default: those of the config the store was created with; pass the
        current config's when it retries more, e.g. 'unstable').

    Returns
    -------
    StoreStatus
        Counts by latest status per sample.

    Raises
    ------
    bubblecal.data.store.StoreError
        The store cannot be read.
    """
    store = CampaignStore(path)
    n_records = sum(1 for _ in store.iter_records())
    skipped = len(store.problems)
    meta = store.header().get("meta", {}) if store.header_path is not None else {}
    cfg = meta.get("campaign", {}) or {}
    n_design = None
    if isinstance(cfg.get("n_samples"), int):
        d = cfg.get("diameter_um")
        n_diameters = len(d) if isinstance(d, list) else 1
        n_design = cfg["n_samples"] * (n_diameters if cfg.get("design") == "grid" else 1)
    retry = tuple(cfg.get("retry_statuses", RETRY_STATUSES)) if retry_statuses is None else tuple(retry_statuses)
    return StoreStatus(path=str(path), name=cfg.get("name"), n_design=n_design, counts=store.counts(),
                       n_records=n_records, n_lines_skipped=skipped, retry_statuses=retry, config=cfg)


@dataclass(frozen=True)
class DesignProgress:
    """What of a config's design its store holds (a dry run's view).

    Parameters
    ----------
    state : str
        'new' (no store yet), 'exists' (a store of this design, or a bare .jsonl), 'other_design' (a run
        would refuse the store).
    n_done, n_pending : int or None
        Design points final / pending (None for 'other_design').
    n_pending_tasks : int or None
        Tasks a run would submit for the pending points (chunks of ``replicas_per_task`` per diameter).
    """

    state: str
    n_done: int | None = None
    n_pending: int | None = None
    n_pending_tasks: int | None = None


def design_progress(config: CampaignConfig) -> DesignProgress:
    """Compare a config's design with its store without writing anything.

    Parameters
    ----------
    config : CampaignConfig
        The campaign (its ``store`` is read when it exists).

    Returns
    -------
    DesignProgress
        The store's state and the done / pending counts.

    Raises
    ------
    bubblecal.data.store.StoreError
        The store exists but cannot be read.
    """
    st = CampaignStore(config.store_path)
    bare = st.header_path is None and st.records_path.exists()  # a bare .jsonl store (no header)
    if bare or (st.header_path is not None and st.header_path.exists()):
        meta = st.header().get("meta", {})
        if meta.get("design_hash") not in (None, config.design_hash()):
            return DesignProgress("other_design")
        pending, state = pending_indices(config, st), "exists"
    else:
        pending, state = list(range(config.n_design)), "new"
    n_tasks = len(make_tasks(config, pending)) if pending else 0
    return DesignProgress(state, config.n_design - len(pending), len(pending), n_tasks)
