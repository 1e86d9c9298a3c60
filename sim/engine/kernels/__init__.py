"""bubblecal.sim.engine.kernels: the engine's Warp kernels, one module per family, built per scalar type.

``common`` (the per-dtype kernel decorator, periodic minimum image), ``pairs`` (DPD pair forces),
``integrate`` (kick-drift), ``bounce`` (bounce-back on moving triangles), ``shell`` (the membrane forces and
:class:`~bubblecal.sim.engine.kernels.shell.ShellForceField`), ``implicit`` (the implicit-solvent system),
``fire`` (the device FIRE minimiser) and ``qs_loading`` (quasi-static loads and observables).  Each family's
builder (``pair_kernels(dtype)``, ...) is cached, so a family compiles once per ``wp.float32`` / ``wp.float64``;
nothing compiles at import.
"""
