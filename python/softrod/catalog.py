"""Designs by name: the bundled design files and the presets, and ``load_design``, which
accepts a name, a path, a mapping or a Design. It sits above ``design`` (files) and
``presets`` (published models built from bundled files), so neither imports the other's
users."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from .design import Design, designs_dir, read_design
from .errors import design_error
from .io import exists as _exists
from .presets import PRESETS


def bundled_designs() -> list[str]:
    """Names of the bundled designs (usable in ``load_design``)."""
    return sorted(p.stem for p in designs_dir().glob("*.toml"))


def load_design(design: str | Path | Mapping[str, Any] | Design) -> Design:
    """Load and validate a design.

    ``design`` is a path to a TOML file, the name of a bundled design (see
    :func:`bundled_designs`), the name of a preset (see :func:`softrod.list_presets`), a
    mapping with the same structure as the file, or a Design.
    Raises :class:`DesignError` naming the field, the value and the rule.
    """
    if isinstance(design, (str, Path)):
        if isinstance(design, str) and (len(design) > 4096 or "\0" in design or not design):
            raise design_error(
                "design", design, "must be a design file path, a bundled design or a preset name"
            )
        path = Path(design)
        try:
            exists = _exists(path)
        except (OSError, ValueError):  # a name too long for the file system, for one
            exists = False
        if not exists:
            bundled = designs_dir() / f"{design}.toml"
            if path.suffix == "" and _exists(bundled):
                return read_design(bundled)
            if str(design) in PRESETS:
                return PRESETS[str(design)].load()
            raise design_error(
                "design",
                str(design),
                f"no such file, bundled design or preset (bundled designs: "
                f"{', '.join(bundled_designs())}; presets: {', '.join(PRESETS)})",
            )
    return read_design(design)
