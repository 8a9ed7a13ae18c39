"""``python -m softrod``: the ``softrod`` command line."""

from .cli import main

main(prog_name="softrod")
