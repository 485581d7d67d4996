"""Robustness analyses (SPEC 12): impulsive pushes, basins of attraction of the reduced step
map and of the full-order closed loop, push trials and parameter uncertainty."""
