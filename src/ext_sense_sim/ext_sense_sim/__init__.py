"""Scene simulator: sensor signals and device byte streams from declared physical effects."""
