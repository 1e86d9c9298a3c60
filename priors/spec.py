"""Typed prior/hyperprior specifications: what a validated priors TOML file holds.

Built by :func:`bubblecal.priors.load_priors`. Units: DPD (``ka`` 2-D modulus, ``kb`` energy, ``d0`` length;
the Lim coefficients and noise amplitudes are dimensionless), see :mod:`bubblecal.data.units`; the priors and
the hierarchy are described in docs/inference.md section 4.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bubblecal.data import PARAMETER_UNITS

__all__ = ["Bounds", "ParameterPrior", "NoisePrior", "PriorSpec"]


@dataclass(frozen=True)
class Bounds:
    """A closed interval [lo, hi] in the units of its parameter.

    Parameters
    ----------
    lo, hi : float
        The ends of the interval, lo < hi.
    """

    lo: float
    hi: float

    @property
    def width(self) -> float:
        """hi - lo."""
        return self.hi - self.lo

    def contains(self, value) -> np.ndarray:
        """Elementwise lo <= value <= hi.

        Parameters
        ----------
        value : float or array_like
            Values in the units of the parameter.

        Returns
        -------
        numpy.ndarray of bool
            True where lo <= value <= hi (a NumPy boolean for a scalar ``value``).
        """
        value = np.asarray(value)
        return (value >= self.lo) & (value <= self.hi)

    def as_tuple(self) -> tuple[float, float]:
        """The bounds as a pair.

        Returns
        -------
        tuple of float
            (lo, hi).
        """
        return (self.lo, self.hi)


@dataclass(frozen=True)
class ParameterPrior:
    """Uniform prior of one model parameter; pooled parameters carry the hyperprior bounds of m and tau.

    Parameters
    ----------
    name : str
        One of :data:`~bubblecal.data.MODEL_PARAMETERS`.
    prior : Bounds
        Uniform prior of one bubble's value (units: :attr:`unit`).
    hyper_m : Bounds or None
        Uniform hyperprior of the population mean m (inside ``prior``); None if not pooled.
    hyper_tau : Bounds or None
        Uniform hyperprior of the population spread tau (>= 0); None if not pooled.
    """

    name: str
    prior: Bounds
    hyper_m: Bounds | None = None
    hyper_tau: Bounds | None = None

    @property
    def pooled(self) -> bool:
        """True if the parameter is drawn from the population distribution in the hierarchy."""
        return self.hyper_m is not None

    @property
    def unit(self) -> str:
        """Unit of the parameter (DPD), from :data:`~bubblecal.data.PARAMETER_UNITS`."""
        return PARAMETER_UNITS[self.name]


@dataclass(frozen=True)
class NoisePrior:
    """Uniform prior of a relative noise amplitude (dimensionless); never pooled.

    Parameters
    ----------
    name : str
        One of :data:`~bubblecal.data.NOISE_PARAMETERS`.
    prior : Bounds
        Uniform prior bounds [-].
    """

    name: str
    prior: Bounds


@dataclass(frozen=True)
class PriorSpec:
    """A validated workflow specification: free and fixed parameters, noise amplitudes, hyperpriors.

    Parameters
    ----------
    name : str
        The file's stem, e.g. ``"definity_reduced_acoustic"``.
    path : str
        The TOML file.
    agent : str
        'definity' or 'sonovue'.
    setup : str
        'compression' or 'indentation'.
    shell : str
        'full' or 'reduced' (b1 = b2 = a3 = a4 = 0).
    acoustic : bool
        True if resonance-frequency data enter the likelihood.
    parameters : dict of str to ParameterPrior
        The free parameters, in :data:`~bubblecal.data.MODEL_PARAMETERS` order.
    fixed : dict of str to float
        The parameters held constant, and their values (DPD units).
    noise : dict of str to NoisePrior
        The noise amplitudes, in file order.
    description : str
        Free text of the ``[workflow]`` section.
    """

    name: str
    path: str
    agent: str
    setup: str
    shell: str
    acoustic: bool
    parameters: dict[str, ParameterPrior]
    fixed: dict[str, float]
    noise: dict[str, NoisePrior]
    description: str = ""

    @property
    def free_names(self) -> tuple[str, ...]:
        """Free parameters in canonical order."""
        return tuple(self.parameters)

    @property
    def pooled_names(self) -> tuple[str, ...]:
        """Free parameters pooled in the population model."""
        return tuple(n for n, p in self.parameters.items() if p.pooled)

    @property
    def noise_names(self) -> tuple[str, ...]:
        """Noise amplitudes in file order."""
        return tuple(self.noise)

    @property
    def mechanical_noise_name(self) -> str:
        """'sigma' (spectroscopy-only workflows) or 'sigma_mech' (acoustic workflows)."""
        return "sigma_mech" if self.acoustic else "sigma"

    def bounds(self, name: str) -> Bounds:
        """Prior bounds of a free parameter or a noise amplitude.

        Parameters
        ----------
        name : str
            A free parameter or noise amplitude name.

        Returns
        -------
        Bounds
            In the units of the parameter.

        Raises
        ------
        KeyError
            If ``name`` is neither (the message lists the free, noise and fixed names).
        """
        if name in self.parameters:
            return self.parameters[name].prior
        if name in self.noise:
            return self.noise[name].prior
        raise KeyError(f"{name!r} is not a free parameter of {self.name} (free: {', '.join(self.free_names)}; "
                       f"noise: {', '.join(self.noise_names)}; fixed: {', '.join(self.fixed)})")

    def prior_box(self, names: tuple[str, ...] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The prior box of some parameters.

        Parameters
        ----------
        names : tuple of str, optional
            Free parameters or noise amplitudes (default: the free parameters, :attr:`free_names`).

        Returns
        -------
        lo, hi : numpy.ndarray
            Lower and upper prior bounds, in the order of ``names``.

        Raises
        ------
        KeyError
            If a name is neither a free parameter nor a noise amplitude.
        """
        names = self.free_names if names is None else names
        b = [self.bounds(n) for n in names]
        return np.array([x.lo for x in b]), np.array([x.hi for x in b])
