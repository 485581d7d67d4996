"""SPEC 2-4: virtual constraints, hybrid zero dynamics, limit cycles and center-manifold
shaping (thrust schedules live in ``thrust/``)."""
