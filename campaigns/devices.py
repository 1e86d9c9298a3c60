"""Whether the device a campaign names exists, checked before any task starts.

A campaign file that says ``device = "cuda"`` on a machine without a CUDA device would otherwise write one
'failed' record per sample; :func:`check_device` stops it first, naming the device and what this machine has.
A campaign over several GPUs (one Dask worker per GPU) asks :func:`check_gpus` how many there are, counted
without initialising CUDA in the client (whose process then never holds a GPU context).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from collections.abc import Mapping

from bubblecal._extras import require
from bubblecal.campaigns.errors import CampaignError

__all__ = ["cuda_device_count", "check_device", "visible_gpus", "check_gpus"]


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


def _count_with_warp() -> int:
    """CUDA devices Warp sees, counted in a child process so this one never initialises CUDA (0 on any failure)."""
    code = "import warp as wp; wp.config.quiet = True; wp.init(); print(wp.get_cuda_device_count())"
    try:
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False)
        return int(out.stdout.strip().splitlines()[-1]) if out.returncode == 0 else 0
    except (OSError, ValueError, IndexError, subprocess.TimeoutExpired):
        return 0


def _gpus_and_source(env: Mapping[str, str]) -> tuple[list[str], str]:
    """:func:`visible_gpus` and where the list came from (for messages)."""
    given = env.get("CUDA_VISIBLE_DEVICES")
    if given is not None:
        out = []
        for entry in (e.strip() for e in given.split(",")):
            if not entry or entry.startswith("-"):  # CUDA ignores this entry and every one after it
                break
            out.append(entry)
        return out, f"CUDA_VISIBLE_DEVICES={given!r}"
    smi = shutil.which("nvidia-smi", path=env.get("PATH"))
    if smi:
        try:
            listing = subprocess.run([smi, "-L"], capture_output=True, text=True, timeout=60, check=False)
            if listing.returncode == 0:
                n = sum(1 for line in listing.stdout.splitlines() if line.startswith("GPU "))
                return [str(i) for i in range(n)], "nvidia-smi -L"
        except (OSError, subprocess.TimeoutExpired):
            pass
    return [str(i) for i in range(_count_with_warp())], "Warp"


def visible_gpus(env: Mapping[str, str] | None = None) -> list[str]:
    """The GPUs this machine offers a campaign, as ``CUDA_VISIBLE_DEVICES`` entries, without initialising CUDA here.

    ``CUDA_VISIBLE_DEVICES`` when it is set (its entries up to the first empty or negative one, as CUDA reads
    it; e.g. a batch system's allocation), else one entry per GPU line of ``nvidia-smi -L``, else a Warp count
    in a child process.

    Parameters
    ----------
    env : Mapping[str, str], optional
        The environment to read (default ``os.environ``; its PATH finds nvidia-smi).

    Returns
    -------
    list of str
        One entry per GPU ('0', '1', ... or the UUIDs a scheduler gave), in order; empty without a GPU.
    """
    return _gpus_and_source(os.environ if env is None else env)[0]


def check_gpus(n_gpus: int, env: Mapping[str, str] | None = None) -> list[str]:
    """The first ``n_gpus`` GPUs of :func:`visible_gpus`, or a named error when the machine has fewer.

    Parameters
    ----------
    n_gpus : int
        GPUs (one Dask worker each) the campaign asks for, >= 1.
    env : Mapping[str, str], optional
        The environment to read (default ``os.environ``).

    Returns
    -------
    list of str
        ``CUDA_VISIBLE_DEVICES`` values, one per worker.

    Raises
    ------
    CampaignError
        ``n_gpus`` is not an integer >= 1, or exceeds the GPUs of this machine; nothing has run then.
    """
    if isinstance(n_gpus, bool) or not isinstance(n_gpus, int) or n_gpus < 1:
        raise CampaignError(f"gpus must be an integer >= 1 (one Dask worker per GPU), got {n_gpus!r}")
    gpus, source = _gpus_and_source(os.environ if env is None else env)
    if n_gpus > len(gpus):
        have = "no GPU" if not gpus else f"{len(gpus)} GPU{'s' if len(gpus) > 1 else ''} ({', '.join(gpus)})"
        fix = f"ask for at most {len(gpus)}" if gpus else "run on a GPU machine"
        raise CampaignError(f"{n_gpus} GPU{'s' if n_gpus > 1 else ''} asked for, but this machine has {have} "
                            f"(counted by {source}); nothing was run and the store is unchanged ({fix})")
    return gpus[:n_gpus]
