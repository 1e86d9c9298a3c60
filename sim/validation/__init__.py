"""bubblecal.sim.validation: physics checks, reference energies and ``bubblecal sim verify``."""
