"""bubblecal.inference."""
