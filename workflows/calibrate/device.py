"""The machine of a run: the JAX device (check that it exists, place the sampling on it) and the host's cores."""

from __future__ import annotations

import contextlib
import os

from bubblecal.workflows.calibrate.config import CalibrationError

__all__ = ["check_device", "on_device", "usable_cores", "helper_processes", "HELPER_PROCESSES",
           "HELPER_PROCESS_MIN_CPUS"]

#: Cores from which an agent runs helper processes beside it (below, they would only compete with XLA for the cores).
HELPER_PROCESS_MIN_CPUS = 8
#: Helper processes of one agent: role -> (cores per process, most processes). Phase-file writers: a quarter of the
#: cores, at most 4; figure processes: a third, at most one per figure.
HELPER_PROCESSES = {"writer": (4, 4), "figure": (3, 6)}


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


def helper_processes(role: str, cpus: int | None = None) -> int:
    """Helper processes of one agent (phase-file writers, figure processes) for a machine of ``cpus`` cores.

    Parameters
    ----------
    role : str
        A key of :data:`HELPER_PROCESSES`: 'writer' or 'figure'.
    cpus : int or None
        Cores (None: those this process may run on).

    Returns
    -------
    int
        0 below :data:`HELPER_PROCESS_MIN_CPUS` cores, else min(most, cpus // cores per process) of the role.

    Raises
    ------
    KeyError
        An unknown role.
    """
    share, most = HELPER_PROCESSES[role]
    cpus = usable_cores() if cpus is None else int(cpus)
    return 0 if cpus < HELPER_PROCESS_MIN_CPUS else min(most, cpus // share)


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
