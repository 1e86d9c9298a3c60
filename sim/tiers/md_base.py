"""What the two MD tiers share: protocol step counts, mesh choice, progress lines and the batch they return."""

from __future__ import annotations

import dataclasses
import time

from bubblecal.sim.protocols.md_loading import ProtocolSteps
from bubblecal.sim.protocols.plates import PlateContact
from bubblecal.sim.tiers.base import CurveBatch, CurveRequest
from bubblecal.sim.tiers.conventions import (
    DEFAULT_INDENTATION_CONVENTION,
    DISPLACEMENT_CONVENTION,
    indentation_convention,
)

__all__: list[str] = []


@dataclasses.dataclass
class _MDTierBase:
    """Settings common to :class:`~bubblecal.sim.tiers.ExplicitTier` and :class:`~bubblecal.sim.tiers.ImplicitTier`
    (documented there)."""

    subdivisions: int | None = None
    ramp_steps: int = 40_000
    hold_steps: int = 20_000
    sample_every: int = 400
    equilibration_steps: int = 20_000
    scale: float = 1.0
    dt: float = 1e-4
    kbt: float = 1.0
    contact: PlateContact = PlateContact()
    dtype: str = "float32"
    rupture_strain: float = 1.0
    max_seconds: float | None = None
    verbose: bool = False
    indentation_convention: str = DEFAULT_INDENTATION_CONVENTION

    def __post_init__(self) -> None:
        indentation_convention(self.indentation_convention)  # a bad name fails before any set-up

    def _convention(self):
        """The tier's :class:`~bubblecal.sim.tiers.IndentationConvention`."""
        return indentation_convention(self.indentation_convention)

    def protocol_steps(self) -> ProtocolSteps:
        """The step counts this tier runs.

        Returns
        -------
        ProtocolSteps
            The published counts (or the tier's settings) multiplied by ``scale``.
        """
        return ProtocolSteps(ramp_steps=self.ramp_steps, hold_steps=self.hold_steps, sample_every=self.sample_every,
                             equilibration_steps=self.equilibration_steps).scaled(self.scale)

    def _mesh(self, request: CurveRequest):
        """The reference mesh of ``request`` (the tier's ``subdivisions`` override the request's)."""
        from bubblecal.sim.engine.mesh import mesh_for_diameter

        if request.several_sizes or request.grids is not None:
            raise ValueError(f"{self.name} tier: one bubble size and one grid per request (CurveRequest.diameters_um "
                             "/ grids are for the quasi-static tier)")
        sub = self.subdivisions if self.subdivisions is not None else request.subdivisions
        return mesh_for_diameter(request.diameter_um, sub)

    def _progress(self):
        """A progress printer when ``verbose``, else None."""
        if not self.verbose:
            return None

        def cb(j, P, sec):
            eta = sec / j * (P - j)
            print(f"  [{self.name}] point {j}/{P}  {sec:.1f} s  ETA {eta:.1f} s", flush=True)

        return cb

    def _batch(self, request, mesh, out, info, t0) -> CurveBatch:
        """The :class:`CurveBatch` of a finished :func:`~bubblecal.sim.protocols.run_md_protocol` run."""
        steps = self.protocol_steps()
        info.update({"tier": self.name, "mesh_subdivisions": mesh.subdivisions, "n_vertices": mesh.n_vertices,
                     "displacement_convention": DISPLACEMENT_CONVENTION if request.protocol == "compression" else None,
                     "protocol_steps": dataclasses.asdict(steps), "dt": self.dt, "md_steps": out["steps"],
                     "indentation_convention": self.indentation_convention if request.protocol == "indentation"
                     else None,
                     "point_status": out["point_status"], "health": out["health"],
                     "contact": {**dataclasses.asdict(self.contact), "cutoff": self.contact.cutoff}})
        for key in ("force_top", "force_bottom", "force_sem", "axial_diameter", "axial_sem",
                    "axial_diameter_equilibrated", "initial_diameter_reference"):
            if key in out:
                info[key] = out[key]
        return CurveBatch(tier=self.name, request=request, observable=out["observable"], status=out["status"],
                          info=info, seconds=time.perf_counter() - t0)
