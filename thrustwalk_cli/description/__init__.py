"""Immutable inputs: robots and gaits as plain data (SPEC 1-2); numpy only."""
