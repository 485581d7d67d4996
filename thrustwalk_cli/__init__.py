"""thrustwalk: thruster-assisted bipedal walking with hybrid zero dynamics."""

__version__ = "0.1.0"
