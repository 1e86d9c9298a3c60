"""Measurements, status and health checks of an :class:`~bubblecal.sim.engine.implicit.ImplicitShellSystem`.

:class:`ImplicitObservables` is the part of the implicit system that reads its state back (positions,
velocities, volumes, areas, gas pressure, temperature, energies, status, memory, settings) and holds the
helpers between per-replica [R, Nv, 3] arrays and the packed rows;
:meth:`~ImplicitObservables.check_health` and :meth:`~ImplicitObservables.freeze` mark failed replicas with
:class:`~bubblecal.sim.engine.health.Status` codes (a marked replica is no longer integrated).  Every method
synchronises with the device; results are float64, DPD units (length r_c = 250 nm, energy k_BT).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from bubblecal._extras import require
from bubblecal.sim.engine.health import Status

wp = require("warp", "sim")

__all__ = ["HealthThresholds", "ImplicitObservables"]


@dataclasses.dataclass(frozen=True)
class HealthThresholds:
    """Limits of :meth:`ImplicitObservables.check_health` (dimensionless).

    Parameters
    ----------
    rupture_strain : float, optional
        Largest triangle |A/A0 - 1| (above: RUPTURE).
    min_area_ratio : float, optional
        Smallest A/A0 before a triangle counts as collapsed (INVERSION).
    max_dihedral_change : float, optional
        Largest |theta - theta0| in radians (a fold gives ~pi; INVERSION).
    max_radius_factor : float, optional
        Largest vertex distance from the centroid in units of the reference radius (ESCAPE).
    """

    rupture_strain: float = 1.0
    min_area_ratio: float = 0.02
    max_dihedral_change: float = 2.5
    max_radius_factor: float = 3.0


class ImplicitObservables:
    """Measurement methods of :class:`~bubblecal.sim.engine.implicit.ImplicitShellSystem` (a mixin of it)."""

    def _remove_means(self, v: np.ndarray) -> np.ndarray:
        """``v`` with every replica's mean row removed."""
        out = v.copy()
        for r in range(self.R):
            o, n = int(self.offsets[r]), int(self.n_vertices[r])
            out[o:o + n] -= out[o:o + n].mean(axis=0)
        return out

    def _to_packed(self, a, name: str) -> np.ndarray:
        """[R, Nv, 3] or [sum Nv, 3] input as packed float64 rows (ValueError otherwise)."""
        a = np.asarray(a, dtype=np.float64)
        if a.shape == (self.N, 3):
            return a
        if self.uniform and a.shape == (self.R, int(self.n_vertices[0]), 3):
            return a.reshape(-1, 3)
        raise ValueError(f"{name} must have shape [R, Nv, 3] or [sum Nv, 3], got {a.shape}")

    def _rows(self, r: int) -> slice:
        """Packed rows of replica ``r``."""
        o = int(self.offsets[r])
        return slice(o, o + int(self.n_vertices[r]))

    def _unpack(self, a: np.ndarray):
        """Packed rows as [R, Nv, ...] (uniform meshes) or a list of per-replica arrays."""
        if self.uniform:
            return a.reshape(self.R, int(self.n_vertices[0]), -1) if a.ndim == 2 else a.reshape(self.R, -1)
        return [a[self._rows(r)] for r in range(self.R)]

    def vertices(self):
        """Vertex positions (DPD length).

        Returns
        -------
        numpy.ndarray or list of numpy.ndarray
            [R, Nv, 3] float64, or a list of [Nv_r, 3] when the meshes differ.
        """
        return self._unpack(self.x.numpy().astype(np.float64))

    def velocities(self):
        """Vertex velocities (DPD velocity).

        Returns
        -------
        numpy.ndarray or list of numpy.ndarray
            [R, Nv, 3] float64, or a list of [Nv_r, 3] when the meshes differ.
        """
        return self._unpack(self.v.numpy().astype(np.float64))

    def volumes(self) -> np.ndarray:
        """Enclosed volume per replica.

        Returns
        -------
        numpy.ndarray
            [R] (DPD length^3).
        """
        self.vol.zero_()
        wp.launch(self._k["volume_kernel"], dim=self.n_tri, inputs=[self.x, self.tri, self.tri_rep, self.goff,
                                                                       self.vol], device=self.device)
        return self.vol.numpy().astype(np.float64)

    def areas(self) -> np.ndarray:
        """Total shell area per replica.

        Returns
        -------
        numpy.ndarray
            [R] (DPD length^2).
        """
        return self.field.areas_volumes(self.x)[0]

    def gas_pressure(self) -> np.ndarray:
        """Ideal-gas pressure N_g k_BT / V per replica.

        Returns
        -------
        numpy.ndarray
            [R] (DPD pressure).
        """
        return self.nkt / self.volumes()

    def centers(self) -> np.ndarray:
        """Vertex centroid per replica.

        Returns
        -------
        numpy.ndarray
            [R, 3] (DPD length).
        """
        x = self.x.numpy().astype(np.float64)
        return np.stack([x[self._rows(r)].mean(axis=0) for r in range(self.R)])

    def kinetic_temperature(self) -> np.ndarray:
        """sum m v^2 / n_dof per replica, n_dof = 3 N_v - (3 if pinned) - (anchored vertices).

        Returns
        -------
        numpy.ndarray
            [R] (k_BT units).
        """
        out = wp.zeros(self.R, dtype=wp.float64, device=self.device)
        wp.launch(self._k["kinetic_kernel"], dim=self.N, inputs=[self.v, self.vrep, self.tab, out], device=self.device)
        nanch = np.bincount(self.vrep_np, weights=self.anchor_np, minlength=self.R)
        dof = 3 * self.n_vertices - (3 if self.pin_com else 0) - nanch
        return out.numpy() / dof

    def energies(self) -> np.ndarray:
        """Shell energy per replica and term.

        Returns
        -------
        numpy.ndarray
            [R, 6] (k_BT), columns :data:`bubblecal.sim.engine.kernels.shell.ENERGY_TERMS`; the back-pressure column
            is 0 here (the pressures are the system's).
        """
        return self.field.energies(self.x)

    def status_names(self) -> list[str]:
        """Per-replica :class:`Status` names.

        Returns
        -------
        list of str
            ``'OK'``, ``'NAN'``, ``'RUPTURE'``, ...
        """
        return [Status(int(s)).name for s in self.status.numpy()]

    def freeze(self, replicas, code: int = int(Status.NAN)) -> None:
        """Mark replicas as failed (they stop moving); replicas already marked keep their code.

        Parameters
        ----------
        replicas : int or array_like of int
            Replica indices.
        code : int, optional
            A :class:`~bubblecal.sim.engine.health.Status` code (default NAN).
        """
        st = self.status.numpy().copy()
        for r in np.atleast_1d(replicas):
            if st[int(r)] == 0:
                st[int(r)] = int(code)
        self.status.assign(st)

    def check_health(self, thresholds: HealthThresholds | None = None) -> dict:
        """Check every live replica and freeze the failures (NAN, RUPTURE, INVERSION, ESCAPE, in that order).

        Parameters
        ----------
        thresholds : HealthThresholds, optional
            Limits (default :class:`HealthThresholds`).

        Returns
        -------
        dict
            ``status`` (per-replica :class:`Status` names) and the [R] indicators ``max_area_strain``,
            ``min_area_ratio``, ``max_dihedral_change`` (radians) and ``max_radius_ratio`` (largest vertex
            distance from the centroid over the reference radius; NaN for non-finite replicas).
        """
        th = thresholds or HealthThresholds()
        x = self.x.numpy().astype(np.float64)
        st = self.status.numpy().copy()
        finite = np.array([np.all(np.isfinite(x[self._rows(r)])) for r in range(self.R)])
        h = self.field.health(self.x)
        radius = np.full(self.R, np.nan)
        for r in range(self.R):
            if finite[r]:
                xr = x[self._rows(r)]
                radius[r] = np.max(np.linalg.norm(xr - xr.mean(axis=0), axis=1)) / self.radius0[r]
        for r in range(self.R):
            if st[r] != 0:
                continue
            if not finite[r] or not np.isfinite(h["max_area_strain"][r]):
                st[r] = Status.NAN
            elif h["max_area_strain"][r] > th.rupture_strain:
                st[r] = Status.RUPTURE
            elif h["min_area_ratio"][r] < th.min_area_ratio or h["max_dihedral_change"][r] > th.max_dihedral_change:
                st[r] = Status.INVERSION
            elif radius[r] > th.max_radius_factor:
                st[r] = Status.ESCAPE
        self.status.assign(st.astype(np.int32))
        return {"status": [Status(int(s)).name for s in st], "max_area_strain": h["max_area_strain"],
                "min_area_ratio": h["min_area_ratio"], "max_dihedral_change": h["max_dihedral_change"],
                "max_radius_ratio": radius}

    def memory_bytes(self) -> int:
        """Device bytes held by the system and its shell field.

        Returns
        -------
        int
        """
        total = 0
        for obj in (self, self.field):
            for val in vars(obj).values():
                if isinstance(val, wp.array):
                    total += val.capacity
        return int(total)

    def settings(self) -> dict:
        """The physical choices of this system (per replica where they vary), DPD units.

        Returns
        -------
        dict
            JSON-friendly: gas number, pressures, k_BT, friction, vertex mass, dt, pinning, thermostat, vertex counts.
        """
        return {"gas_number": self.gas_number.tolist(), "p_back": self.p_back.tolist(),
                "p_water": self.p_water.tolist(), "kbt": self.kbt.tolist(), "gamma": self.gamma.tolist(),
                "vertex_mass": self.vertex_mass.tolist(), "dt": self.dt, "pin_com": self.pin_com,
                "thermostat": "Langevin (BAOAB) on vertices", "n_vertices": self.n_vertices.tolist()}
