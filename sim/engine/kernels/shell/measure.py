"""Measurements of a :class:`~bubblecal.sim.engine.kernels.shell.field.ShellForceField` (a mixin of it).

Total areas and volumes, health indicators, energies per replica and term, and the NumPy convenience interface
(reference positions, energies and forces of host positions) used by CPU checks and minimiser callbacks.  Every
method synchronises with the device; results are float64, DPD units (length r_c = 250 nm, energy k_BT).
"""

# (no "from __future__ import annotations": Warp must see the closure types of the kernel signatures)

import numpy as np

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.shell.launch import launch_forces
from bubblecal.sim.engine.kernels.shell.layout import (
    E_AREA,
    E_PB,
    E_VOL,
    ENERGY_TERMS,
    P_A0TOT,
    P_KATOT,
    P_KVTOT,
    P_PB,
    P_V0,
)

wp = require("warp", "sim")

__all__ = ["ShellFieldMeasurements"]


class ShellFieldMeasurements:
    """Measurement methods of :class:`~bubblecal.sim.engine.kernels.shell.field.ShellForceField`."""

    def areas_volumes(self, x: wp.array) -> tuple[np.ndarray, np.ndarray]:
        """Total area and enclosed volume of every replica's shell (synchronises).

        Parameters
        ----------
        x : wp.array of vec3
            Particle positions (DPD length).

        Returns
        -------
        area, volume : numpy.ndarray
            [R] float64 each (DPD length^2, length^3).
        """
        self._check_array(x, "x")
        self._avr.zero_()
        wp.launch(self._k["area_volume_kernel"], dim=self.n_triangles,
                  inputs=[x, self._tri, self._tri_rep, self._goff, self._avr], device=self.device)
        avr = self._avr.numpy().astype(np.float64)
        return avr[:, 0].copy(), avr[:, 1].copy()

    def health(self, x: wp.array) -> dict[str, np.ndarray]:
        """Per-replica shell health indicators (synchronises); thresholds are the caller's choice.

        Parameters
        ----------
        x : wp.array of vec3
            Particle positions (DPD length); test them for NaN first (non-finite positions give NaN or
            meaningless values).

        Returns
        -------
        dict of numpy.ndarray
            [R] each: ``max_area_strain`` max_t |A_t/A0_t - 1| (rupture / over-stretch), ``min_area_ratio``
            min_t A_t/A0_t (collapse; areas are unsigned, so also watch the next one), ``max_dihedral_change``
            max_e |theta_e - theta0_e| in radians (a triangle folded over its neighbour gives values near pi).
        """
        self._check_array(x, "x")
        init = np.zeros((self.n_replicas, 3))
        init[:, 1] = np.inf if self.dtype is wp.float64 else np.finfo(np.float32).max
        self._health.assign(init)
        wp.launch(self._k["health_tris"], dim=self.n_triangles,
                  inputs=[x, self._tri, self._ref, self._tri_rep, self._health], device=self.device)
        wp.launch(self._k["health_edges"], dim=self.n_edges,
                  inputs=[x, self._dih, self._theta0, self._edge_rep, self._health], device=self.device)
        h = self._health.numpy().astype(np.float64)
        return {"max_area_strain": h[:, 0].copy(), "min_area_ratio": h[:, 1].copy(),
                "max_dihedral_change": h[:, 2].copy()}

    def energies(self, x: wp.array) -> np.ndarray:
        """Energy per replica and term (synchronises).

        The constraint and back-pressure columns are evaluated in float64 on the host from the device areas and
        volumes: ka_tot (A-A0)^2/(2A0), kv_tot (V-V0)^2/(2V0), -p_back (V-V0).

        Parameters
        ----------
        x : wp.array of vec3
            Particle positions (DPD length).

        Returns
        -------
        numpy.ndarray
            [R, 6] float64 energies (k_BT), columns :data:`ENERGY_TERMS`.
        """
        self._check_array(x, "x")
        if self._scratch_f is None or self._scratch_f.shape[0] != x.shape[0]:
            self._scratch_f = wp.zeros_like(x)
        self._energy.zero_()
        launch_forces(self, x, self._scratch_f, None, self._energy, 1)
        return self._finish_energies(x)

    def _finish_energies(self, x: wp.array) -> np.ndarray:
        """Device energy table plus the host-evaluated constraint and back-pressure columns."""
        e = self._energy.numpy().astype(np.float64)
        a, vol = self.areas_volumes(x)
        t = self.param_table
        a0, v0 = t[:, P_A0TOT], t[:, P_V0]  # the references the force kernels read
        e[:, E_AREA] = t[:, P_KATOT] * (a - a0) ** 2 / (2 * a0)
        e[:, E_VOL] = t[:, P_KVTOT] * (vol - v0) ** 2 / (2 * v0)
        e[:, E_PB] = -t[:, P_PB] * (vol - v0)
        return e

    def reference_positions(self, n_rows: int | None = None) -> np.ndarray:
        """Every replica's reference vertices at its rows of a particle array.

        Parameters
        ----------
        n_rows : int, optional
            Rows of the array (default ``n_rows_min``).

        Returns
        -------
        numpy.ndarray
            [n_rows, 3] float64 (DPD length); other rows are 0.
        """
        n = self.n_rows_min if n_rows is None else n_rows
        x = np.zeros((n, 3))
        for m, o in zip(self.meshes, self.offsets, strict=True):
            x[o:o + m.n_vertices] = m.vertices
        return x

    def energy_forces_numpy(self, x: np.ndarray, with_energy: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Energies and forces for NumPy positions (copies to and from the device).

        Parameters
        ----------
        x : numpy.ndarray
            [N, 3] positions (DPD length), N >= ``n_rows_min``.
        with_energy : bool, optional
            Also evaluate the energies (otherwise the energy array is zeros).

        Returns
        -------
        energies, forces : numpy.ndarray
            [R, 6] energies (k_BT, columns :data:`ENERGY_TERMS`) and [N, 3] forces (DPD force), float64.
        """
        x = np.ascontiguousarray(x, dtype=np.float64)
        if self._np_x is None or self._np_x.shape[0] != x.shape[0]:
            self._np_x = wp.zeros(x.shape[0], dtype=self.vec3, device=self.device)
            self._np_f = wp.zeros(x.shape[0], dtype=self.vec3, device=self.device)
        self._np_x.assign(x.astype(np.float32 if self.dtype is wp.float32 else np.float64))
        self._np_f.zero_()
        self._energy.zero_()
        launch_forces(self, self._np_x, self._np_f, None, self._energy if with_energy else self._dummy_energy,
                             int(with_energy))
        f = self._np_f.numpy().astype(np.float64)
        if not with_energy:
            return np.zeros((self.n_replicas, len(ENERGY_TERMS))), f
        return self._finish_energies(self._np_x), f
