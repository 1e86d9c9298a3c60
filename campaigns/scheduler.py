"""Which Dask scheduler a campaign uses: the allowed ``--scheduler`` / ``[dask].scheduler_address`` values and a
connection that gives up after a short timeout with the address named (never a hang or a raw traceback)."""

from __future__ import annotations

import re

from bubblecal._extras import require
from bubblecal.campaigns.errors import CampaignConfigError, CampaignError

__all__ = ["SCHEDULER_CHOICES", "CONNECT_TIMEOUT_S", "check_scheduler_address", "connect_scheduler"]

#: What a scheduler address may be (the message of a bad one lists this).
SCHEDULER_CHOICES = "'' or 'local' (a LocalCluster here), 'inline' (no Dask) or tcp://HOST:PORT (tls:// too)"
#: Seconds a connection to a remote scheduler may take before the campaign stops with the address named.
CONNECT_TIMEOUT_S = 10.0
_REMOTE = re.compile(r"^(tcp|tls)://[^\s:/]+:\d{1,5}$")


def check_scheduler_address(address: str | None) -> str | None:
    """A valid scheduler address, normalised: None for a LocalCluster, 'inline', or a remote address.

    Parameters
    ----------
    address : str or None
        None, '', 'local', 'inline' or 'tcp://HOST:PORT' / 'tls://HOST:PORT' (PORT 1-65535).

    Returns
    -------
    str or None
        None (LocalCluster), 'inline' or the remote address.

    Raises
    ------
    CampaignConfigError
        Field ``scheduler_address``: anything else, with the allowed values.
    """
    if address in (None, "", "local"):
        return None
    if address == "inline":
        return address
    if not isinstance(address, str) or not _REMOTE.match(address) or not 0 < int(address.rsplit(":", 1)[1]) < 65536:
        raise CampaignConfigError("scheduler_address", f"{address!r} is not a scheduler address; allowed: "
                                                       f"{SCHEDULER_CHOICES}")
    return address


def connect_scheduler(address: str, timeout_s: float = CONNECT_TIMEOUT_S):
    """A Dask client of the scheduler at ``address``, or a named error after ``timeout_s`` seconds.

    Parameters
    ----------
    address : str
        'tcp://HOST:PORT' (checked by :func:`check_scheduler_address`).
    timeout_s : float
        Seconds to wait for the scheduler [s].

    Returns
    -------
    distributed.Client

    Raises
    ------
    CampaignError
        The scheduler cannot be reached within ``timeout_s`` (nothing was submitted; the store is unchanged).
    """
    Client = require("distributed", "sim").Client

    try:
        return Client(address, timeout=f"{timeout_s}s")
    except (OSError, TimeoutError) as exc:
        raise CampaignError(f"cannot reach the Dask scheduler at {address} within {timeout_s:g} s ({exc}); is it "
                            "running, and is the address (host and port) right? Nothing was run") from None
