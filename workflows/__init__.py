"""bubblecal.workflows."""
