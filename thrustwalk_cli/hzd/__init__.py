"""SPEC 2-4: virtual constraints, hybrid zero dynamics, limit cycles, thrust schedules and
center-manifold shaping."""
