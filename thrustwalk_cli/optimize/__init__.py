"""SPEC 6 and 15: thrust schedules by convex optimisation: ``qp`` (the QP solver),
``min_effort`` (minimum-effort schedules as an exact convex QP) and ``min_energy`` (the least
thruster input energy: sequential convex programming, interior point)."""
