"""What a mechanical network sees and predicts: per-diameter ("raw") or one network over the sizes ("diameter").

Two input kinds, recorded in a surrogate file's metadata as ``inputs`` (docs/data-formats.md):

* ``raw`` (one network per diameter): inputs ``(ka, kb, b1, b2, a3, a4, x)``, target the response ``y``;
* ``diameter`` (one network over 1.5-8 um): inputs ``(ka, kb, b1, b2, a3, a4, x, diameter_um)``, target the
  response over its size scale, ``y / s`` with ``s = radius_dpd`` for an indentation depth and
  ``s = ka radius_dpd`` for a compression force (a shell of 2-D modulus ka and radius R resists with a force of
  order ka R), so that the network fits an order-one response at every size (docs/decisions.md, "One network
  over the sizes").

Either kind may enter the moduli as natural logarithms (metadata ``log_inputs``, e.g. ``["ka", "kb"]``): the
designs draw k_a and k_b over two to three decades, and standardised linear inputs squeeze the soft shells of lipid
bubbles into a sliver of the input range (docs/decisions.md, "One network over the sizes").

The loading coordinate ``x`` stays in DPD units. The domain of a diameter network is its shell-parameter box,
its diameter range and the loading range per size: for compression the displacement as a fraction of the
diameter ``x / (2 radius_dpd)`` (the designs scale the plate travel with the size), for indentation the force
itself (one force grid at every size). Every function works on NumPy and JAX arrays (``xp``).
"""

from __future__ import annotations

import numpy as np

from bubblecal.data import DEFAULT_UNITS, LOADING_PROTOCOLS, SHELL_PARAMETERS

__all__ = ["INPUT_KINDS", "LOG_INPUT_CHOICES", "DEFAULT_LOG_INPUTS", "RESPONSE_SCALES", "UM_PER_RADIUS_DPD",
           "radius_of_diameter", "check_log_inputs", "network_inputs", "response_scale", "x_per_size"]

#: Network input kinds (module docstring).
INPUT_KINDS: tuple[str, ...] = ("raw", "diameter")
#: Shell parameters a network may take as natural logarithms (positive in every box).
LOG_INPUT_CHOICES: tuple[str, ...] = ("ka", "kb")
#: Logged inputs of a new network, per input kind (the per-diameter networks keep the published linear inputs).
DEFAULT_LOG_INPUTS: dict[str, tuple[str, ...]] = {"raw": (), "diameter": ("ka", "kb")}
#: Name of the response scale of a diameter network, per loading protocol (metadata ``response_scale``).
RESPONSE_SCALES: dict[str, str] = {"compression": "ka * radius_dpd", "indentation": "radius_dpd"}
#: Bubble diameter [um] per DPD radius (2 x the DPD length in um).
UM_PER_RADIUS_DPD: float = 2.0 * DEFAULT_UNITS.length_m * 1e6


def radius_of_diameter(diameter_um):
    """Bubble radius [DPD length] of a diameter [um] (array-friendly, JAX-traceable).

    Parameters
    ----------
    diameter_um : float or array_like
        Bubble diameter [um].

    Returns
    -------
    float or array
        Radius [DPD length].
    """
    return diameter_um / UM_PER_RADIUS_DPD


def _check(kind: str, setup: str) -> None:
    if kind not in INPUT_KINDS:
        raise ValueError(f"inputs must be one of {INPUT_KINDS}, got {kind!r}")
    if setup not in LOADING_PROTOCOLS:
        raise ValueError(f"setup must be one of {LOADING_PROTOCOLS}, got {setup!r}")


def check_log_inputs(log_inputs) -> tuple[str, ...]:
    """The logged inputs as a tuple in parameter order, checked.

    Parameters
    ----------
    log_inputs : iterable of str
        Names from :data:`LOG_INPUT_CHOICES`.

    Returns
    -------
    tuple of str
        The names, each once, in the order of :data:`LOG_INPUT_CHOICES`.

    Raises
    ------
    ValueError
        For a name outside :data:`LOG_INPUT_CHOICES`.
    """
    names = set(log_inputs)
    bad = sorted(names - set(LOG_INPUT_CHOICES))
    if bad:
        raise ValueError(f"log_inputs may hold {list(LOG_INPUT_CHOICES)}, got {bad}")
    return tuple(k for k in LOG_INPUT_CHOICES if k in names)


def network_inputs(kind: str, params, x, diameter_um=None, xp=np, log_inputs=()):
    """Network inputs: the shell parameters and ``x`` (and the diameter), broadcast, in the last axis.

    Parameters
    ----------
    kind : {'raw', 'diameter'}
        Input kind.
    params : array_like, shape (..., 6)
        Shell parameters (ka, kb, b1, b2, a3, a4) [DPD units].
    x : array_like
        Loading coordinate [DPD length (compression) or DPD force (indentation)]; broadcasts against
        ``params[..., 0]``.
    diameter_um : float or array_like, optional
        Bubble diameter [um] (``kind='diameter'`` only); broadcasts like ``x``.
    xp : module
        ``numpy`` or ``jax.numpy``.
    log_inputs : iterable of str
        Shell parameters entered as their natural logarithm (:data:`LOG_INPUT_CHOICES`; default none).

    Returns
    -------
    array, shape (broadcast shape, 7 or 8)
        The inputs ``u``.

    Raises
    ------
    ValueError
        For an unknown kind, a last axis of ``params`` that is not 6 long, a missing diameter, or an unknown
        name in ``log_inputs``.
    """
    if kind not in INPUT_KINDS:
        raise ValueError(f"inputs must be one of {INPUT_KINDS}, got {kind!r}")
    params = xp.asarray(params)
    x = xp.asarray(x)
    if params.ndim == 0 or params.shape[-1] != len(SHELL_PARAMETERS):
        raise ValueError(f"params must have a last axis of length {len(SHELL_PARAMETERS)} "
                         f"({', '.join(SHELL_PARAMETERS)}), got shape {params.shape}")
    cols = [x]
    if kind == "diameter":
        if diameter_um is None:
            raise ValueError("a diameter network needs diameter_um [um]")
        cols.append(xp.asarray(diameter_um))
    shape = params.shape[:-1]
    for c in cols:
        shape = np.broadcast_shapes(shape, c.shape)
    logged = check_log_inputs(log_inputs)
    if logged:  # before the broadcast: one log per parameter set, not per point
        params = xp.concatenate([xp.log(params[..., i:i + 1]) if name in logged else params[..., i:i + 1]
                                 for i, name in enumerate(SHELL_PARAMETERS)], axis=-1)
    p = xp.broadcast_to(params, shape + (params.shape[-1],))
    extra = [xp.broadcast_to(c, shape)[..., None].astype(p.dtype) for c in cols]
    return xp.concatenate([p, *extra], axis=-1)


def response_scale(kind: str, setup: str, params, diameter_um=None, xp=np):
    """The factor that turns a network's target into the response: ``y = target * scale``.

    Parameters
    ----------
    kind : {'raw', 'diameter'}
        Input kind (``raw``: 1).
    setup : {'compression', 'indentation'}
        Loading protocol.
    params : array_like, shape (..., 6)
        Shell parameters [DPD units] (ka is ``params[..., 0]``).
    diameter_um : float or array_like, optional
        Bubble diameter [um] (``kind='diameter'``).
    xp : module
        ``numpy`` or ``jax.numpy``.

    Returns
    -------
    array or float
        ``radius_dpd`` (indentation, DPD length) or ``ka radius_dpd`` (compression, DPD force), shaped like
        ``params[..., 0]`` broadcast with the diameter; 1.0 for ``raw``.

    Raises
    ------
    ValueError
        For an unknown kind or setup, or a missing diameter.
    """
    _check(kind, setup)
    if kind == "raw":
        return 1.0
    if diameter_um is None:
        raise ValueError("a diameter network needs diameter_um [um]")
    r = radius_of_diameter(xp.asarray(diameter_um))
    return r * xp.asarray(params)[..., 0] if setup == "compression" else r + 0.0 * xp.asarray(params)[..., 0]


def x_per_size(setup: str, x, diameter_um, xp=np):
    """The loading coordinate of the per-size domain: ``x / (2 radius_dpd)`` (compression) or ``x``.

    Parameters
    ----------
    setup : {'compression', 'indentation'}
        Loading protocol.
    x : array_like
        Loading coordinate [DPD length or DPD force].
    diameter_um : float or array_like
        Bubble diameter [um].
    xp : module
        ``numpy`` or ``jax.numpy``.

    Returns
    -------
    array
        Displacement over the diameter (compression, dimensionless) or the force (indentation, DPD force).
    """
    x = xp.asarray(x)
    if setup == "compression":
        return x / (2.0 * radius_of_diameter(xp.asarray(diameter_um)))
    return x
