"""SPEC 6: minimum-effort thrust schedules as an exact convex QP."""
