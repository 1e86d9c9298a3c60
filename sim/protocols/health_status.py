"""Health verdicts of the MD engines mapped to replica statuses, shared by the MD loading and ringdown protocols.

The verdict names are those of :class:`bubblecal.sim.engine.health.Status` (explicit tier) and of
:meth:`bubblecal.sim.engine.implicit.ImplicitShellSystem.check_health` (implicit tier).
"""

from __future__ import annotations

__all__ = ["STATUS_MAP"]

#: Health verdict name -> one of :data:`bubblecal.data.names.STATUSES` (an unknown verdict counts as 'failed').
STATUS_MAP = {"OK": "ok", "NAN": "failed", "ESCAPE": "unstable", "INVERSION": "unstable", "RUPTURE": "ruptured",
              "LEAK": "failed"}
