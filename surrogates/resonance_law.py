"""A resonance law continuous in the diameter: f_res(k_a, D)^2 as a sum of powers of D times 1, k_a, k_a^2.

    f_res(k_a, D)^2 = sum_i k_a^i sum_{p in P_i} c_{i,p} D^p,    i = 0, 1, 2

with f_res in **physical MHz**, k_a in **DPD 2-D modulus units** and D in **um**. At a fixed diameter the law is
the quadratic a0 + a1 k_a + a2 k_a^2 of the per-diameter surrogates (:mod:`bubblecal.surrogates.resonance`),
with a_i(D) = sum_p c_{i,p} D^p, so every consumer of per-diameter coefficients works at any diameter inside the
law's range. A :class:`LawForm` names the powers P_i; :data:`LAW_FORMS` holds the candidates compared in
docs/decisions.md, each motivated by f ~ sqrt(stiffness / mass) / size: a shell whose own inertia (mass ~ D^2)
carries the breathing mode gives f^2 ~ (stiffness ~ k_a) / D^2, the gas adds ~ p D^2 / D^3 = 1/D, bending
(energy scale-free, stiffness ~ k_b / D^2) adds ~ D^-4, and liquid inertia (added mass ~ D^3) gives the classical
D^-2 (gas) and k_a D^-3 (shell) terms. Fitting and hold-out errors: :mod:`bubblecal.surrogates.law_fit`.

Each simulated diameter keeps its fitted k_a range; between two simulated diameters the valid k_a range is the
intersection of theirs (valid where both neighbouring sweeps were fitted).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

__all__ = ["LawForm", "LAW_FORMS", "DEFAULT_LAW_FORM", "ResonanceLaw", "LawFormatError"]

#: Exact-node tolerance of a diameter [um]: closer to a simulated diameter than this uses that sweep's k_a range.
NODE_ATOL_UM = 1e-9


class LawFormatError(ValueError):
    """A serialised resonance law is malformed (the message names the field)."""


@dataclass(frozen=True)
class LawForm:
    """Powers of the diameter multiplying k_a^0, k_a^1 and k_a^2 in f_res^2.

    Parameters
    ----------
    name : str
        Short name (the ``form`` field of a law file).
    powers : tuple of tuple of int
        ``(P_0, P_1, P_2)``: powers of D [um] in the coefficient of k_a^0, k_a^1, k_a^2 (an empty tuple: no term).
    description : str
        The physics each term stands for.
    """

    name: str
    powers: tuple[tuple[int, ...], tuple[int, ...], tuple[int, ...]]
    description: str = ""

    @property
    def n_coefficients(self) -> int:
        """Number of coefficients c_{i,p}."""
        return sum(len(p) for p in self.powers)

    def terms(self) -> list[tuple[int, int]]:
        """(k_a power i, D power p) of each coefficient, in storage order."""
        return [(i, p) for i, ps in enumerate(self.powers) for p in ps]

    def design(self, diameter_um, ka) -> np.ndarray:
        """(n, n_coefficients) design matrix of f_res^2 (columns k_a^i D^p).

        Parameters
        ----------
        diameter_um : array_like
            (n,) diameters [um].
        ka : array_like
            (n,) stretching moduli [DPD 2-D modulus].

        Returns
        -------
        numpy.ndarray
            Columns in the order of :meth:`terms`.
        """
        d = np.asarray(diameter_um, dtype=float)
        ka = np.asarray(ka, dtype=float)
        return np.stack([ka**i * d**p for i, p in self.terms()], axis=-1)

    def expression(self) -> str:
        """The law as text, e.g. ``f^2 = c0 D^-2 + c1 D^-1 + (c2 D^-2) ka + (c3 D^-2) ka^2``."""
        parts, j = [], 0
        for i, ps in enumerate(self.powers):
            if not ps:
                continue
            inner = " + ".join(f"c{j + k} D^{p}" for k, p in enumerate(ps))
            j += len(ps)
            parts.append(inner if i == 0 else f"({inner}) " + ("ka" if i == 1 else "ka^2"))
        return "f_res^2 = " + " + ".join(parts) + "; f_res [MHz], D [um], ka [DPD]"


#: Candidate forms (docs/decisions.md compares them by leaving diameters out).
LAW_FORMS: dict[str, LawForm] = {f.name: f for f in (
    LawForm("scale-free", ((-2,), (-2,), (-2,)),
            "shell inertia only: f D a function of ka alone"),
    LawForm("gas", ((-2, -1), (-2,), (-2,)),
            "shell inertia + the gas stiffness (p D^2 over a shell mass D^2, per D^2 of size: D^-1)"),
    LawForm("gas-coupled", ((-2, -1), (-2, -1), (-2,)),
            "gas + a size-dependent shell stiffness (curvature of the discrete shell: ka D^-1)"),
    LawForm("gas-bending", ((-4, -2, -1), (-2,), (-2,)),
            "gas + bending (k_b / D^2 stiffness over a D^2 mass: D^-4)"),
    LawForm("gas-coupled-bending", ((-4, -2, -1), (-2, -1), (-2,)),
            "gas-coupled + bending"),
    LawForm("liquid-inertia", ((-2, -3), (-3,), (-4,)),
            "classical scaling (water added mass ~ D^3): gas D^-2, surface tension D^-3, shell ka D^-3"),
)}
#: The form of the shipped law files (docs/decisions.md, "Acoustic law over the diameter").
DEFAULT_LAW_FORM = "gas-coupled"


@dataclass
class ResonanceLaw:
    """A fitted diameter-continuous law f_res(k_a, D) with its validity box and hold-out errors.

    Parameters
    ----------
    form : str
        Name of the form (a key of :data:`LAW_FORMS`, or any name when ``powers`` is given explicitly).
    powers : tuple of tuple of int
        Powers of D in the k_a^0, k_a^1, k_a^2 coefficients (:class:`LawForm`).
    coefficients : tuple of float
        c_{i,p} in the order of :meth:`LawForm.terms` [MHz^2 um^-p (DPD 2-D modulus)^-i].
    diameters_um : tuple of float
        The simulated diameters [um], increasing (at least 2).
    ka_min, ka_max : tuple of float
        Fitted k_a range of each simulated diameter [DPD 2-D modulus].
    n_points : int
        Rows fitted.
    holdout : dict
        Hold-out relative errors of f_res: ``per_diameter`` (list of {diameter_um, median, max, n}), ``median``,
        ``max`` (over every left-out row) and ``bands`` (list of {band_um, median, max, n}).
    meta : dict
        Provenance.
    """

    form: str
    powers: tuple
    coefficients: tuple
    diameters_um: tuple
    ka_min: tuple
    ka_max: tuple
    n_points: int = 0
    holdout: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)

    @property
    def law_form(self) -> LawForm:
        """The :class:`LawForm` of this law."""
        known = LAW_FORMS.get(self.form)
        if known is not None and known.powers == tuple(tuple(p) for p in self.powers):
            return known
        return LawForm(self.form, tuple(tuple(int(v) for v in p) for p in self.powers))

    @property
    def diameter_range(self) -> tuple[float, float]:
        """(smallest, largest) simulated diameter [um]: the law's range."""
        return float(self.diameters_um[0]), float(self.diameters_um[-1])

    @property
    def ka_range(self) -> tuple[float, float]:
        """Envelope (min ka_min, max ka_max) of the fitted k_a ranges [DPD 2-D modulus]."""
        return float(min(self.ka_min)), float(max(self.ka_max))

    def quadratic(self, diameter_um, xp=np):
        """(..., 3) coefficients (a0, a1, a2) of f_res^2 = a0 + a1 ka + a2 ka^2 at the given diameter(s).

        No range check here (:class:`~bubblecal.surrogates.acoustic_law.AcousticLawSurrogate` checks).

        Parameters
        ----------
        diameter_um : float or array_like
            Diameter(s) [um] (traced arrays allowed with ``xp=jax.numpy``).
        xp : module
            ``numpy`` or ``jax.numpy``.

        Returns
        -------
        array
            [MHz^2, MHz^2 per DPD 2-D modulus, MHz^2 per (DPD 2-D modulus)^2].
        """
        d = xp.asarray(diameter_um, dtype=float)
        out, j = [], 0
        for ps in self.powers:
            a = xp.zeros_like(d)
            for p in ps:
                a = a + float(self.coefficients[j]) * d ** int(p)
                j += 1
            out.append(a)
        return xp.stack(out, axis=-1)

    def f_res_squared(self, ka, diameter_um):
        """f_res^2 [MHz^2] at ka [DPD 2-D modulus] and diameter(s) [um] (JAX; no range check).

        Parameters
        ----------
        ka : array_like
            Stretching modulus [DPD 2-D modulus].
        diameter_um : array_like
            Diameter(s) [um]; broadcasts against ``ka``.

        Returns
        -------
        jax.Array
            f_res^2 [MHz^2].
        """
        import jax.numpy as jnp  # here, not at import: the CLI's choices read LAW_FORMS without loading JAX

        c = self.quadratic(diameter_um, xp=jnp)
        ka = jnp.asarray(ka)
        return c[..., 0] + c[..., 1] * ka + c[..., 2] * ka * ka

    def ka_bounds(self, diameter_um, xp=np):
        """(..., 2) valid k_a range at the given diameter(s): a node's own, else the intersection of the two
        simulated diameters around it (diameters outside the range get the nearest interval's).

        Parameters
        ----------
        diameter_um : float or array_like
            Diameter(s) [um].
        xp : module
            ``numpy`` or ``jax.numpy`` (traced diameters).

        Returns
        -------
        array
            [DPD 2-D modulus].
        """
        nodes = xp.asarray(self.diameters_um, dtype=float)
        lo_n, hi_n = xp.asarray(self.ka_min, dtype=float), xp.asarray(self.ka_max, dtype=float)
        d = xp.asarray(diameter_um, dtype=float)
        j = xp.clip(xp.searchsorted(nodes, d, side="right") - 1, 0, nodes.shape[0] - 2)
        at_left = xp.abs(d - nodes[j]) <= NODE_ATOL_UM
        at_right = xp.abs(d - nodes[j + 1]) <= NODE_ATOL_UM
        lo = xp.where(at_left, lo_n[j], xp.where(at_right, lo_n[j + 1], xp.maximum(lo_n[j], lo_n[j + 1])))
        hi = xp.where(at_left, hi_n[j], xp.where(at_right, hi_n[j + 1], xp.minimum(hi_n[j], hi_n[j + 1])))
        return xp.stack([lo, hi], axis=-1)

    def to_dict(self) -> dict:
        """JSON-ready dict (the ``law`` field of an acoustic surrogate file, format version 2)."""
        return {"form": self.form, "expression": self.law_form.expression(),
                "powers": [list(map(int, p)) for p in self.powers],
                "coefficients": [float(c) for c in self.coefficients],
                "diameter_range_um": list(self.diameter_range), "ka_range": list(self.ka_range),
                "diameters": [{"diameter_um": float(d), "ka_min": float(lo), "ka_max": float(hi)}
                              for d, lo, hi in zip(self.diameters_um, self.ka_min, self.ka_max, strict=True)],
                "n_points": int(self.n_points), "holdout": self.holdout, "meta": self.meta}

    @classmethod
    def from_dict(cls, d: Mapping) -> ResonanceLaw:
        """Rebuild and validate a law from :meth:`to_dict`'s output.

        Parameters
        ----------
        d : Mapping
            The ``law`` field of a file.

        Returns
        -------
        ResonanceLaw
            The law.

        Raises
        ------
        LawFormatError
            Naming the field: missing, non-finite coefficient, wrong count, bad powers, a diameter range that is
            not increasing, or a k_a range with ka_min >= ka_max.
        """
        if not isinstance(d, Mapping):
            raise LawFormatError("field 'law' must be an object")
        for k in ("form", "powers", "coefficients", "diameter_range_um", "diameters"):
            if k not in d:
                raise LawFormatError(f"field 'law.{k}' is missing")
        powers = d["powers"]
        if (not isinstance(powers, list) or len(powers) != 3
                or not all(isinstance(p, list) and all(isinstance(v, int) for v in p) for p in powers)):
            raise LawFormatError(f"field 'law.powers' must be three lists of integers, got {powers!r}")
        coef = d["coefficients"]
        n = sum(len(p) for p in powers)
        if not isinstance(coef, list) or len(coef) != n or n == 0:
            raise LawFormatError(f"field 'law.coefficients' must hold {n} numbers (one per power), got {coef!r}")
        for i, c in enumerate(coef):
            if not isinstance(c, (int, float)) or not math.isfinite(c):
                raise LawFormatError(f"field 'law.coefficients[{i}]' must be a finite number, got {c!r}")
        rng = d["diameter_range_um"]
        if (not isinstance(rng, list) or len(rng) != 2 or not all(isinstance(v, (int, float)) for v in rng)
                or not (math.isfinite(rng[0]) and math.isfinite(rng[1]) and 0 < rng[0] < rng[1])):
            raise LawFormatError(f"field 'law.diameter_range_um' must be [min, max] with 0 < min < max, got {rng!r}")
        rows = d["diameters"]
        if not isinstance(rows, list) or len(rows) < 2:
            raise LawFormatError("field 'law.diameters' must list at least 2 simulated diameters")
        dia, lo, hi = [], [], []
        for i, r in enumerate(rows):
            for k in ("diameter_um", "ka_min", "ka_max"):
                v = r.get(k) if isinstance(r, Mapping) else None
                if not isinstance(v, (int, float)) or not math.isfinite(v):
                    raise LawFormatError(f"field 'law.diameters[{i}].{k}' must be a finite number, got {v!r}")
            if not r["ka_min"] < r["ka_max"]:
                raise LawFormatError(f"field 'law.diameters[{i}]': ka_min {r['ka_min']} must be < ka_max "
                                     f"{r['ka_max']}")
            dia.append(float(r["diameter_um"]))
            lo.append(float(r["ka_min"]))
            hi.append(float(r["ka_max"]))
        if any(b <= a for a, b in zip(dia, dia[1:], strict=False)):
            raise LawFormatError(f"field 'law.diameters': diameters must increase, got {dia}")
        if not (math.isclose(dia[0], rng[0]) and math.isclose(dia[-1], rng[1])):
            raise LawFormatError(f"field 'law.diameter_range_um' {rng} must equal the first and last simulated "
                                 f"diameters [{dia[0]}, {dia[-1]}]")
        return cls(form=str(d["form"]), powers=tuple(tuple(p) for p in powers),
                   coefficients=tuple(float(c) for c in coef), diameters_um=tuple(dia), ka_min=tuple(lo),
                   ka_max=tuple(hi), n_points=int(d.get("n_points", 0)), holdout=dict(d.get("holdout", {})),
                   meta=dict(d.get("meta", {})))
