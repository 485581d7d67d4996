"""Everything a thruster is and does, below the zero dynamics: thrust schedules (SPEC 4) and
the linear thruster dynamics (SPEC 7, 11, 13); numpy only."""
