"""The implicit-solvent MD tier: shell + ideal-gas pressure-volume law + back pressure + Langevin vertices."""

from __future__ import annotations

import dataclasses
import time

from bubblecal.sim.tiers.base import CurveBatch, CurveRequest, register_tier
from bubblecal.sim.tiers.md_base import _MDTierBase

__all__ = ["ImplicitTier"]


def _vertex_mass(mesh, protocol: str, mass_factor: float = 1.0) -> float:
    """Shell vertex mass (DPD mass): published shell density, x5 for indentation."""
    from bubblecal.sim.engine.particles import RHO_SHELL_KG_M3

    rho = RHO_SHELL_KG_M3 * (5.0 if protocol == "indentation" else 1.0)
    return mesh.vertex_mass(rho, mass_factor=mass_factor)


@dataclasses.dataclass
class ImplicitTier(_MDTierBase):
    """Implicit-solvent MD tier: :class:`bubblecal.sim.engine.implicit.ImplicitShellSystem` under the MD loading
    protocols (:mod:`bubblecal.sim.protocols.md_loading`).  All R replicas of a request run in the same launches
    (one mesh).

    Parameters
    ----------
    subdivisions : int, optional
        Icosphere level; overrides the request's when given.
    ramp_steps, hold_steps, sample_every, equilibration_steps : int
        Protocol step counts (published defaults; :class:`bubblecal.sim.protocols.ProtocolSteps`).
    scale : float
        Multiplies every step count (tests and smoke runs).
    dt : float
        Time step (DPD time).
    kbt : float
        Thermal energy of the vertex thermostat (DPD energy; 0 = athermal).
    contact : bubblecal.sim.protocols.PlateContact
        The compression plates' law.
    dtype : str
        'float32' or 'float64'.
    rupture_strain : float
        Max triangle area strain above which a replica is 'ruptured'.
    max_seconds : float, optional
        Wall-time budget (s); replicas still running when it is spent become 'timeout'.
    verbose : bool
        Print a progress line per point.
    indentation_convention : str
        A key of :data:`bubblecal.sim.tiers.INDENTATION_CONVENTIONS`.
    p0 : float
        Gas pressure at the reference volume (DPD pressure); the gas follows p0 V0 / V.
    p_back : float
        Back pressure (DPD pressure).
    p_water : float, optional
        Ambient pressure (DPD pressure); None = balanced at the reference.
    gamma : float, optional
        Vertex Langevin friction (DPD mass / DPD time); None = the published vertex-water estimate
        (:func:`bubblecal.sim.engine.default_vertex_friction`).
    mass_factor : float
        Multiplies the shell vertex mass.

    Raises
    ------
    ValueError
        If ``indentation_convention`` is unknown (at construction).
    """

    p0: float = 3.0
    p_back: float = 91.0
    p_water: float | None = None
    gamma: float | None = None
    mass_factor: float = 1.0
    name: str = "implicit"

    def run(self, request: CurveRequest, device: str = "cpu") -> CurveBatch:
        """Simulate ``request`` on the Warp ``device``.

        Parameters
        ----------
        request : CurveRequest
            The curves (units: :class:`CurveRequest`).
        device : str
            Warp device.

        Returns
        -------
        CurveBatch
            Observables, statuses and ``info`` (settings, per-point statuses, health verdicts, plate forces or
            axial diameters, the system's settings and memory).
        """
        from bubblecal.sim.engine import (
            HealthThresholds,
            ImplicitShellSystem,
            default_vertex_friction,
        )
        from bubblecal.sim.protocols.md_loading import run_md_protocol
        from bubblecal.sim.protocols.md_loading.adapters import ImplicitAdapter

        t0 = time.perf_counter()
        mesh = self._mesh(request)
        gamma = default_vertex_friction(mesh, request.protocol) if self.gamma is None else self.gamma
        system = ImplicitShellSystem(mesh, request.shell_params(self.indentation_convention), p0=self.p0,
                                     p_back=self.p_back, p_water=self.p_water, kbt=self.kbt, gamma=gamma,
                                     vertex_mass=_vertex_mass(mesh, request.protocol, self.mass_factor), dt=self.dt,
                                     device=device, dtype=self.dtype, seed=list(request.seeds), pin_com=True)
        adapter = ImplicitAdapter(system, HealthThresholds(rupture_strain=self.rupture_strain))
        out = run_md_protocol(adapter, mesh, request.protocol, request.grid_array(), self.protocol_steps(),
                              self.contact, pole_patch=self._convention().pole_patch(),
                              max_seconds=self.max_seconds, progress=self._progress())
        info = {"system": system.settings(), "memory_bytes": system.memory_bytes()}
        info["system"].pop("n_vertices", None)
        return self._batch(request, mesh, out, info, t0)


register_tier("implicit", ImplicitTier)
