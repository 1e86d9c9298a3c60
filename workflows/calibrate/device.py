"""The JAX device of a run: check that it exists, and place the sampling on it."""

from __future__ import annotations

import contextlib

from bubblecal.workflows.calibrate.config import CalibrationError

__all__ = ["check_device", "on_device"]


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
