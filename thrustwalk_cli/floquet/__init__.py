"""SPEC 13: Floquet analysis of the full-order closed loop with its thruster states."""
