"""Gait design by constrained optimisation, with an independent re-check (SPEC 2, 3, 5)."""
