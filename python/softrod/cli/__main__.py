"""``python -m softrod.cli``."""

from . import main

main()
