"""bubblecal.data."""
