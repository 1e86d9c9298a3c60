"""bubblecal.sim.experiments: loading protocols (compression, indentation) and their fidelity tiers."""
