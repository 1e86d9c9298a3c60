"""The acoustic surrogate of a diameter-continuous resonance law (JSON format version 2).

:class:`AcousticLawSurrogate` answers every question of :class:`~bubblecal.surrogates.AcousticSurrogate`
(``coefficients``, ``f_res_squared``, ``f_res``, ``ka_ranges``, ``in_range``, ``check_range``) at any diameter
inside the law's range, from one :class:`~bubblecal.surrogates.resonance_law.ResonanceLaw`; a diameter outside it
raises :class:`~bubblecal.surrogates.AcousticRangeError` naming the diameter and the range. Evaluation is JAX:
``f_res`` is jit- and grad-ready in both k_a and the diameter (a traced diameter skips the host-side range check;
:meth:`AcousticLawSurrogate.in_range` masks it). File layout: docs/data-formats.md, "Acoustic surrogate files".
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from bubblecal.surrogates.acoustic import ACOUSTIC_FORMAT, AcousticFormatError, AcousticRangeError, AcousticSurrogate
from bubblecal.surrogates.resonance_law import LawFormatError, ResonanceLaw

__all__ = ["AcousticLawSurrogate", "ACOUSTIC_LAW_FORMAT_VERSION"]

#: ``format_version`` of an acoustic surrogate file that stores a law.
ACOUSTIC_LAW_FORMAT_VERSION = 2


class AcousticLawSurrogate(AcousticSurrogate):
    """An acoustic surrogate continuous in the diameter: f_res(k_a, D) from a :class:`ResonanceLaw`.

    Parameters
    ----------
    law : ResonanceLaw
        The fitted law.
    name : str
        Agent or label (e.g. ``'definity'``).
    meta : Mapping, optional
        Provenance stored in the file.
    path : str or Path, optional
        The file it was loaded from.
    """

    def __init__(self, law: ResonanceLaw, name: str = "", meta: Mapping | None = None,
                 path: str | Path | None = None):
        super().__init__([], name=name, meta=meta, path=path)
        self.law = law

    @property
    def diameters(self) -> list[float]:
        """The simulated diameters behind the law [um], sorted."""
        return [float(d) for d in self.law.diameters_um]

    @property
    def diameter_range(self) -> tuple[float, float]:
        """(min, max) diameter [um] where the law is valid."""
        return self.law.diameter_range

    def _check_diameter(self, diameter_um) -> None:
        """AcousticRangeError naming the diameter(s) outside the law's range; traced diameters pass."""
        if isinstance(diameter_um, jax.core.Tracer):
            return
        d = np.asarray(diameter_um, dtype=float)
        lo, hi = self.law.diameter_range
        bad = d[~((d >= lo - 1e-9) & (d <= hi + 1e-9))]
        if bad.size:
            raise AcousticRangeError(f"acoustic law {self.name!r}: diameter(s) "
                                     f"{', '.join(f'{v:g}' for v in np.unique(bad))} um outside the law's range "
                                     f"[{lo:g}, {hi:g}] um")

    def coefficients(self, diameter_um) -> np.ndarray:
        """(..., 3) array of (a0, a1, a2) of f_res^2 at the requested diameter(s).

        Parameters
        ----------
        diameter_um : float or array_like
            Diameter(s) [um] inside the law's range.

        Returns
        -------
        numpy.ndarray
            Coefficients [MHz^2, MHz^2 per DPD 2-D modulus, MHz^2 per (DPD 2-D modulus)^2].

        Raises
        ------
        AcousticRangeError
            For a diameter outside the law's range.
        """
        self._check_diameter(diameter_um)
        return self.law.quadratic(np.asarray(diameter_um, dtype=float))

    def ka_ranges(self, diameter_um) -> np.ndarray:
        """(..., 2) array of the valid (ka_min, ka_max) at the requested diameter(s).

        Parameters
        ----------
        diameter_um : float or array_like
            Diameter(s) [um] inside the law's range.

        Returns
        -------
        numpy.ndarray
            k_a ranges [DPD 2-D modulus] (between simulated diameters: the intersection of the neighbours').

        Raises
        ------
        AcousticRangeError
            For a diameter outside the law's range.
        """
        self._check_diameter(diameter_um)
        return self.law.ka_bounds(np.asarray(diameter_um, dtype=float))

    def f_res_squared(self, ka, diameter_um):
        """The squared resonance frequency of the law (JAX; jit/grad-ready in ka and the diameter).

        Parameters
        ----------
        ka : array_like
            Stretching modulus [DPD 2-D modulus]; broadcasts against the diameters.
        diameter_um : float or array_like
            Diameter(s) [um] inside the law's range (may be traced).

        Returns
        -------
        jax.Array
            f_res^2 [MHz^2].

        Raises
        ------
        AcousticRangeError
            For a concrete diameter outside the law's range.
        """
        self._check_diameter(diameter_um)
        return self.law.f_res_squared(ka, diameter_um)

    def in_range(self, ka, diameter_um, rtol: float = 1e-9):
        """Mask of (ka, diameter) inside the law's box (and a positive f_res^2); JAX, traced diameters allowed.

        Parameters
        ----------
        ka : array_like
            Stretching modulus [DPD 2-D modulus].
        diameter_um : float or array_like
            Diameter(s) [um].
        rtol : float
            Widening of the k_a range, relative to its width.

        Returns
        -------
        jax.Array of bool
            True where both are valid.
        """
        d = jnp.asarray(diameter_um, dtype=float)
        ka = jnp.asarray(ka)
        lo_d, hi_d = self.law.diameter_range
        r = self.law.ka_bounds(d, xp=jnp)
        w = (r[..., 1] - r[..., 0]) * rtol
        return ((d >= lo_d - 1e-9) & (d <= hi_d + 1e-9) & (ka >= r[..., 0] - w) & (ka <= r[..., 1] + w)
                & (self.law.f_res_squared(ka, d) > 0))

    def check_range(self, ka, diameter_um, action: str = "warn") -> np.ndarray:
        """Host-side check: a diameter outside the law's range raises; k_a outside warns or raises.

        Parameters
        ----------
        ka : array_like
            Stretching modulus [DPD 2-D modulus].
        diameter_um : float or array_like
            Diameter(s) [um].
        action : {'warn', 'raise'}
            For k_a outside the valid range: emit an AcousticRangeWarning or raise.

        Returns
        -------
        numpy.ndarray of bool
            The mask of valid points.

        Raises
        ------
        AcousticRangeError
            For a diameter outside the law's range (always), or k_a outside with ``action='raise'``.
        ValueError
            For an unknown ``action``.
        """
        self._check_diameter(diameter_um)
        return super().check_range(ka, diameter_um, action=action)

    def to_dict(self) -> dict:
        """JSON-ready dict: format, version 2, model, units, name, meta and the ``law``."""
        return {"format": ACOUSTIC_FORMAT, "format_version": ACOUSTIC_LAW_FORMAT_VERSION,
                "model": self.law.law_form.expression(), "frequency_units": "MHz", "ka_units": "DPD",
                "diameter_units": "um", "name": self.name, "meta": self.meta, "law": self.law.to_dict()}

    @classmethod
    def from_file_dict(cls, d: Mapping, path: str | Path) -> AcousticLawSurrogate:
        """Build from a parsed version-2 file (format and version already checked).

        Parameters
        ----------
        d : Mapping
            The parsed JSON.
        path : str or Path
            The file (named in errors).

        Returns
        -------
        AcousticLawSurrogate
            The surrogate.

        Raises
        ------
        AcousticFormatError
            Naming the file and the field: other frequency or diameter units, or a malformed ``law``.
        """
        for k, unit in (("frequency_units", "MHz"), ("diameter_units", "um")):
            if d.get(k) != unit:
                raise AcousticFormatError(f"{path}: field '{k}' must be {unit!r}, got {d.get(k)!r}")
        if "law" not in d:
            raise AcousticFormatError(f"{path}: field 'law' is missing (format version 2 stores a law)")
        try:
            law = ResonanceLaw.from_dict(d["law"])
        except LawFormatError as exc:
            raise AcousticFormatError(f"{path}: {exc}") from None
        return cls(law, name=d.get("name", ""), meta=d.get("meta", {}), path=path)
