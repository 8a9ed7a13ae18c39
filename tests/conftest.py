"""Shared pytest setup."""

import os

# Tests never open windows: pick matplotlib's non-interactive backend before anything
# imports pyplot (the library itself never selects a backend).
os.environ.setdefault("MPLBACKEND", "Agg")
