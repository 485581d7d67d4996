"""SPEC 7: full-order closed-loop hybrid simulation with thruster dynamics, and the reduced
cascade of SPEC 3."""
