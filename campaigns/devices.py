"""Whether the device a campaign names exists, checked before any task starts.

A campaign file that says ``device = "cuda"`` on a machine without a CUDA device would otherwise write one
'failed' record per sample; :func:`check_device` stops it first, naming the device and what this machine has.
"""

from __future__ import annotations

from bubblecal._extras import require
from bubblecal.campaigns.errors import CampaignError

__all__ = ["cuda_device_count", "check_device"]


def cuda_device_count() -> int:
    """CUDA devices Warp sees on this machine (0 without Warp, a driver or a GPU).

    Returns
    -------
    int
        The count.
    """
    try:
        wp = require("warp", "sim")
    except ImportError:
        return 0
    wp.config.quiet = True
    wp.init()
    return int(wp.get_cuda_device_count())


def check_device(device: str, n_cuda: int | None = None, where: str = "this machine") -> None:
    """Raise unless ``device`` exists: 'cpu' always, 'cuda' with one CUDA device, 'cuda:N' with N + 1.

    Parameters
    ----------
    device : str
        'cpu', 'cuda' or 'cuda:N'.
    n_cuda : int, optional
        CUDA devices available (default: :func:`cuda_device_count` here).
    where : str
        The machine named in the message (e.g. a Dask worker's address).

    Raises
    ------
    CampaignError
        The device is not there; the message says what is and how to choose another device.
    """
    if not device.startswith("cuda"):
        return
    n = cuda_device_count() if n_cuda is None else int(n_cuda)
    index = int(device.split(":", 1)[1]) if ":" in device else 0
    if index >= n:
        have = "no CUDA device" if n == 0 else f"{n} CUDA device(s) (cuda:0 - cuda:{n - 1})"
        raise CampaignError(f"device {device!r}: {where} has {have}; nothing was simulated (run on a GPU machine, or "
                            "pass --device cpu / set [campaign].device)")
