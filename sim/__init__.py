"""bubblecal.sim."""
