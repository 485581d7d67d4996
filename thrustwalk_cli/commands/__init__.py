"""One module per command; each exposes ``register(app)`` and a plain ``run_*`` function."""
