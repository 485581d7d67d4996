"""SPEC 5: ground forces on the periodic orbit and at impact; feasibility verdicts."""
