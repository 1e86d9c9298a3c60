"""The machine of a run: the JAX device (check that it exists, place the sampling on it) and the host's cores."""

from __future__ import annotations

import contextlib
import os

from bubblecal.workflows.calibrate.config import CalibrationError

__all__ = ["check_device", "on_device", "usable_cores"]


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity where the platform has one, else the machine's).

    Returns
    -------
    int
        At least 1.
    """
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return os.cpu_count() or 1


def check_device(device: str) -> None:
    """Check that JAX sees the requested device.

    Parameters
    ----------
    device : str
        'cpu' or 'gpu'.

    Raises
    ------
    CalibrationError
        ``device`` is 'gpu' and JAX sees no GPU.
    """
    import jax

    if device == "gpu":
        try:
            jax.devices("gpu")
        except RuntimeError:
            raise CalibrationError("--device gpu: JAX sees no GPU on this machine (jax.devices() = "
                                   f"{[d.platform for d in jax.devices()]}); use --device cpu") from None


@contextlib.contextmanager
def on_device(device: str):
    """Context manager: JAX arrays and programs default to the first device of the platform.

    Parameters
    ----------
    device : str
        'gpu' selects the first GPU; anything else the first CPU.
    """
    import jax

    platform = "gpu" if device == "gpu" else "cpu"
    with jax.default_device(jax.devices(platform)[0]):
        yield
