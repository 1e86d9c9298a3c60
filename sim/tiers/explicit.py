"""The explicit-solvent MD tier (the reference): shell + explicit water and gas, bounce-back."""

from __future__ import annotations

import dataclasses
import time

from bubblecal.sim.tiers.base import CurveBatch, CurveRequest, register_tier
from bubblecal.sim.tiers.md_base import _MDTierBase

__all__ = ["ExplicitTier"]


@dataclasses.dataclass
class ExplicitTier(_MDTierBase):
    """Explicit-solvent MD tier: R :func:`bubblecal.sim.engine.bubble_spec` replicas (published water, gas,
    bounce-back, per-replica shell parameters, back pressure) in one
    :class:`bubblecal.sim.engine.system.ParticleSystem`, under the MD loading protocols
    (:mod:`bubblecal.sim.protocols.md_loading`).

    Parameters
    ----------
    subdivisions, ramp_steps, hold_steps, sample_every, equilibration_steps, scale, dt, kbt, contact, dtype, \
rupture_strain, max_seconds, verbose, indentation_convention
        As in :class:`bubblecal.sim.tiers.ImplicitTier` (``kbt``: the DPD temperature).
    gas_density : float
        Gas number density inside (DPD length^-3).
    p_back : float
        Back pressure (DPD pressure).
    box : tuple of float, optional
        Periodic box (DPD length); None = (2R+5, 2R+5, 2R+10).
    a_vertex_water : float, optional
        Vertex-water repulsion (DPD); None = 400 compression, 40 indentation.
    water_gap : float
        Water-free gap around the shell at set-up (DPD length).
    mass_factor : float
        Multiplies the shell vertex mass (e.g. 5 keeps stiff shells at small diameters stable at ``dt``; an
        equilibrium observable does not depend on it, a ringdown does).
    fsi_friction_factor : float
        Multiplies the vertex-solvent dissipative coefficients; like ``mass_factor`` it changes how fast the shell
        relaxes, not the equilibrium it relaxes to.
    a_water : float
        Water-water repulsion (DPD force; the published 100 sets the water's pressure, about 94, that ``p_back``
        plus the gas balance).
    chunk : int
        Engine steps per CUDA graph.
    health_leaks : bool
        Count leaked particles at every health check.

    Raises
    ------
    ValueError
        If ``indentation_convention`` is unknown (at construction).
    """

    gas_density: float = 3.0
    p_back: float = 91.0
    box: tuple | None = None
    a_vertex_water: float | None = None
    water_gap: float = 0.5
    mass_factor: float = 1.0
    fsi_friction_factor: float = 1.0
    a_water: float = 100.0
    chunk: int = 20
    health_leaks: bool = True
    name: str = "explicit"

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
            axial diameters, particle counts, box, memory, the last health report).
        """
        from bubblecal.sim.engine import ParticleSystem, bubble_spec
        from bubblecal.sim.engine.health import HealthConfig, HealthMonitor
        from bubblecal.sim.protocols.md_loading import run_md_protocol
        from bubblecal.sim.protocols.md_loading.adapters import ExplicitAdapter

        t0 = time.perf_counter()
        mesh = self._mesh(request)
        specs = []
        for p, seed in zip(request.shell_params(self.indentation_convention), request.seeds, strict=True):
            sp = bubble_spec(request.diameter_um, mesh.subdivisions, box=self.box, seed=seed, ka=p.ka, kb=p.kb,
                             p_back=self.p_back, gas_density=self.gas_density, protocol=request.protocol,
                             mass_factor=self.mass_factor, a_vertex_water=self.a_vertex_water, kbt=self.kbt,
                             fsi_friction_factor=self.fsi_friction_factor, a_water=self.a_water, mu=p.mu, b1=p.b1,
                             b2=p.b2, a3=p.a3, a4=p.a4)
            sp.pin_com = True
            sp.water_gap = self.water_gap
            specs.append(sp)
        system = ParticleSystem(specs, dt=self.dt, device=device, dtype=self.dtype, chunk=self.chunk)
        monitor = HealthMonitor(HealthConfig(rupture_strain=self.rupture_strain, check_leaks=self.health_leaks))
        adapter = ExplicitAdapter(system, monitor)
        out = run_md_protocol(adapter, mesh, request.protocol, request.grid_array(), self.protocol_steps(),
                              self.contact, pole_patch=self._convention().pole_patch(),
                              max_seconds=self.max_seconds, progress=self._progress())
        counts = system.solvent_counts()
        info = {"n_particles": int(system.N + system.Nv), "solvent_counts": counts.tolist(),
                "box": list(map(float, specs[0].box)), "memory_bytes": system.memory_bytes(),
                "health_last": monitor.reports[-1].as_dict() if monitor.reports else None}
        return self._batch(request, mesh, out, info, t0)


register_tier("explicit", ExplicitTier)
