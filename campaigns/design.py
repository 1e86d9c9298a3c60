"""Campaign designs: the design points of a :class:`~bubblecal.campaigns.CampaignConfig`, their ids and seeds.

Every function here is a pure function of the config, so a restarted campaign regenerates exactly the same
points, ids and seeds.
"""

from __future__ import annotations

import numpy as np

from bubblecal.campaigns.config import CampaignConfig
from bubblecal.campaigns.diameters import level_of_unit
from bubblecal.data import SHELL_PARAMETERS

__all__ = ["sample_ids", "sample_seed", "lhs_design", "grid_design", "design_points"]


def sample_ids(config: CampaignConfig) -> list[str]:
    """Design point ids ``f"{name}-{i:06d}"``.

    Parameters
    ----------
    config : CampaignConfig
        The campaign.

    Returns
    -------
    list of str
        One id per design point, i = 0 .. ``config.n_design`` - 1.
    """
    return [f"{config.name}-{i:06d}" for i in range(config.n_design)]


def sample_seed(seed: int, index: int) -> int:
    """Seed of one design point, derived from (campaign seed, index) via ``numpy.random.SeedSequence``.

    Parameters
    ----------
    seed : int
        The campaign seed (``CampaignConfig.seed``).
    index : int
        Design point index.

    Returns
    -------
    int
        A non-negative 31-bit seed.
    """
    return int(np.random.SeedSequence([int(seed), int(index)]).generate_state(1, dtype=np.uint32)[0] >> 1)


def lhs_design(config: CampaignConfig) -> dict[str, np.ndarray]:
    """Latin hypercube over the free parameters (and the diameter of a design over a diameter range).

    ``scipy.stats.qmc.LatinHypercube(d, seed=config.seed)`` with d = number of free parameters (lo < hi),
    scaled to ``config.ranges``; fixed parameters (lo == hi) are constant.  With ``config.diameter_range_um``
    the hypercube has one more (last) dimension, mapped onto the diameter levels
    (:func:`bubblecal.campaigns.diameters.level_of_unit`: n / n_levels points per level).

    Parameters
    ----------
    config : CampaignConfig
        The campaign (``design='lhs'``).

    Returns
    -------
    dict of str to numpy.ndarray
        ``{ka, kb, b1, b2, a3, a4: array[n_samples]}`` in DPD units (ka DPD 2-D modulus, kb DPD energy,
        b1..a4 dimensionless), plus ``'diameter_um'`` [um] for a design over a diameter range.
    """
    from scipy.stats import qmc

    free = config.free_names
    n = config.n_samples
    out = {k: np.full(n, config.ranges[k][0]) for k in SHELL_PARAMETERS}
    over_diameter = config.diameter_range_um is not None
    if free or over_diameter:
        unit = qmc.LatinHypercube(len(free) + int(over_diameter), seed=config.seed).random(n)
        if over_diameter:
            levels = np.asarray(config.diameters, dtype=np.float64)
            out["diameter_um"] = levels[level_of_unit(unit[:, -1], len(levels))]
            unit = unit[:, :-1]
    if free:
        lo = np.array([config.ranges[k][0] for k in free])
        hi = np.array([config.ranges[k][1] for k in free])
        scaled = qmc.scale(unit, lo, hi)
        for j, k in enumerate(free):
            out[k] = scaled[:, j].astype(np.float64)
    return out


def grid_design(config: CampaignConfig) -> dict[str, np.ndarray]:
    """ka grid x diameters, every other parameter fixed (ringdown sweeps).

    ka takes ``config.ka_values``, or ``n_samples`` values evenly spaced over ``ranges['ka']``; the rows are
    diameter-major (all ka values of the first diameter, then the next).

    Parameters
    ----------
    config : CampaignConfig
        The campaign (``design='grid'``).

    Returns
    -------
    dict of str to numpy.ndarray
        ``{ka..a4: array[n_design]}`` in DPD units and ``'diameter_um': array[n_design]`` [um].
    """
    if config.ka_values is not None:
        ka = np.asarray(config.ka_values, dtype=np.float64)
    else:
        lo, hi = config.ranges["ka"]
        ka = np.linspace(lo, hi, config.n_samples) if config.n_samples > 1 else np.array([lo])
    nd = len(config.diameters)
    out = {k: np.full(ka.size * nd, config.ranges[k][0]) for k in SHELL_PARAMETERS}
    out["ka"] = np.tile(ka, nd)
    out["diameter_um"] = np.repeat(np.asarray(config.diameters, dtype=np.float64), ka.size)
    return out


def design_points(config: CampaignConfig) -> dict[str, np.ndarray]:
    """The full design of a campaign: parameters, diameter and seed of every design point.

    Parameters
    ----------
    config : CampaignConfig
        The campaign.

    Returns
    -------
    dict of str to numpy.ndarray
        ``{ka..a4}`` (DPD units), ``'diameter_um'`` [um] and ``'seed'`` (int64, :func:`sample_seed`):
        arrays [n_design].
    """
    if config.design == "grid":
        out = grid_design(config)
    else:
        out = lhs_design(config)
        out.setdefault("diameter_um", np.full(config.n_samples, config.diameters[0]))
    out["seed"] = np.array([sample_seed(config.seed, i) for i in range(config.n_design)], dtype=np.int64)
    return out
