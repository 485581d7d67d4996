"""``python -m thrustwalk_cli``."""

from .cli import main

main()
