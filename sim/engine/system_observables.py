"""Measurements of a :class:`~bubblecal.sim.engine.system.ParticleSystem` (host side, float64).

:class:`ParticleObservables` is the part of :class:`ParticleSystem` that reads the device state back: counts,
virial pressure, kinetic temperature, momentum, positions, shell areas and volumes, status and memory.  Every
method synchronises with the device.  Units: DPD (length r_c = 250 nm, energy k_BT, water bead mass 1).
"""

from __future__ import annotations

import numpy as np

from bubblecal._extras import require
from bubblecal.sim.engine.particles import GAS, N_TYPES, VERTEX, WALL, WATER

wp = require("warp", "sim")

__all__ = ["ParticleObservables"]


class ParticleObservables:
    """Measurement methods of :class:`~bubblecal.sim.engine.system.ParticleSystem` (a mixin of it)."""

    def solvent_counts(self) -> np.ndarray:
        """Number of solvent particles of each type per replica.

        Returns
        -------
        numpy.ndarray
            [R, N_TYPES] int64 (columns WATER, GAS, VERTEX, WALL).
        """
        rep, typ = self.rep.numpy(), self.typ.numpy()
        out = np.zeros((self.R, N_TYPES), dtype=np.int64)
        np.add.at(out, (rep, typ), 1)
        return out

    def virial_pressure(self) -> tuple[np.ndarray, np.ndarray]:
        """Pressure and kinetic temperature of the solvent: P = (sum m v^2 + sum r.F^C) / (3V).

        Only valid for replicas without a shell; rebuilds the neighbour lists if they are stale.

        Returns
        -------
        pressure, temperature : numpy.ndarray
            [R] each (DPD pressure k_BT / r_c^3, and k_BT units over the mobile solvent).
        """
        if self._need_rebuild:
            self.rebuild()
        vir = wp.zeros(self.R, dtype=wp.float64, device=self.device)
        kin = wp.zeros(self.R, dtype=wp.float64, device=self.device)
        wp.launch(self.kp["solvent_virial"], dim=self.N,
                  inputs=[self.x, self.v, self.typ, self.rep, self.nbr, self.ncount, self.box, self.tab_a,
                          self.mass, vir, kin], device=self.device)
        vol = self.boxes.prod(axis=1)
        nmob = self.solvent_counts()[:, [WATER, GAS]].sum(axis=1)
        k = kin.numpy()
        return (k + vir.numpy()) / (3.0 * vol), k / (3.0 * np.maximum(nmob, 1))

    def kinetic_temperature(self) -> np.ndarray:
        """<m v^2> / 3 per replica over the mobile solvent particles.

        Returns
        -------
        numpy.ndarray
            [R] (k_BT units).
        """
        v = self.v.numpy().astype(np.float64)
        m = self.mass_np[self.rep.numpy(), self.typ.numpy()]
        mob = self.typ.numpy() != WALL
        e = np.zeros(self.R)
        c = np.zeros(self.R)
        rep = self.rep.numpy()
        np.add.at(e, rep[mob], (m[mob, None] * v[mob] ** 2).sum(axis=1))
        np.add.at(c, rep[mob], 1)
        return e / (3.0 * np.maximum(c, 1))

    def total_momentum(self) -> np.ndarray:
        """Total momentum (solvent + mobile shell vertices) per replica.

        Returns
        -------
        numpy.ndarray
            [R, 3] float64 (DPD mass x DPD velocity).
        """
        p = np.zeros((self.R, 3))
        v = self.v.numpy().astype(np.float64)
        rep, typ = self.rep.numpy(), self.typ.numpy()
        m = self.mass_np[rep, typ] * (typ != WALL)
        np.add.at(p, rep, m[:, None] * v)
        if self.Nv:
            vv = self.vv.numpy().astype(np.float64)
            vr = self.vrep.numpy()
            mv = self.mass_np[vr, VERTEX] * (self.inv_mass_np[vr, VERTEX] > 0)
            np.add.at(p, vr, mv[:, None] * vv)
        return p

    def solvent_numpy(self) -> dict[str, np.ndarray]:
        """Solvent arrays in persistent-id order.

        Returns
        -------
        dict of numpy.ndarray
            ``x`` and ``v`` [N, 3] float64 (DPD length, velocity), ``type`` and ``replica`` [N].
        """
        order = np.argsort(self.pid.numpy())
        return {"x": self.x.numpy().astype(np.float64)[order], "v": self.v.numpy().astype(np.float64)[order],
                "type": self.typ.numpy()[order], "replica": self.rep.numpy()[order]}

    def vertices_numpy(self, r: int) -> np.ndarray:
        """Shell vertex positions of one replica (unwrapped).

        Parameters
        ----------
        r : int
            Replica index.

        Returns
        -------
        numpy.ndarray
            [N_v, 3] float64 (DPD length).
        """
        o, n = int(self.vertex_offset[r]), int(self.vertex_count[r])
        return self.xv.numpy().astype(np.float64)[o:o + n]

    def shell_area_volume(self) -> tuple[np.ndarray, np.ndarray]:
        """Shell area and enclosed volume per replica.

        Returns
        -------
        area, volume : numpy.ndarray
            [R] each (DPD length^2, length^3); NaN for replicas without a shell.
        """
        a = np.full(self.R, np.nan)
        vol = np.full(self.R, np.nan)
        if self.Nv:
            aa, vv = self.shell_field.areas_volumes(self.xv)
            a[self.shell_replicas] = aa
            vol[self.shell_replicas] = vv
        return a, vol

    def status_numpy(self) -> np.ndarray:
        """Per-replica :class:`~bubblecal.sim.engine.health.Status` codes.

        Returns
        -------
        numpy.ndarray
            [R] int32 (a copy).
        """
        return self.status.numpy().copy()

    def memory_bytes(self) -> int:
        """Bytes of the device arrays held by the system and its shell field (neighbour lists included).

        Returns
        -------
        int
        """
        total = 0
        for val in vars(self).values():
            if isinstance(val, wp.array):
                total += val.capacity
        if self.shell_field is not None:
            for val in vars(self.shell_field).values():
                if isinstance(val, wp.array):
                    total += val.capacity
        return int(total)

