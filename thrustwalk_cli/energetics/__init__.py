"""Energy and cost of transport (SPEC 15)."""
