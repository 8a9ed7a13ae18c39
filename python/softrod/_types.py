"""Type aliases of the public API's annotations (imported under TYPE_CHECKING only, so
nothing here is loaded at run time: the CLI's start-up stays free of numpy).

- ``DesignLike``: a :class:`~softrod.Design`, the name of a bundled design or preset, a path
  to a TOML file, or a mapping with the file's structure;
- ``ArrayLike``: numpy's (nested sequences, arrays), values in SI unless the name says;
- ``Quantity``: a number in SI units, or a string with its unit (``"30 kPa"``);
- ``PathLike``: a ``str`` or ``os.PathLike`` path;
- ``Progress``: ``None`` (a bar in interactive sessions), ``True``, ``False`` or a callable;
- ``Units``: display units of a table (``None``: the defaults; ``"SI"``; or a mapping from a
  kind such as ``"pressure"`` to a unit).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from numpy.typing import ArrayLike as ArrayLike  # re-exported for the annotations

    from .design import Design

    DesignLike = Design | str | os.PathLike[str] | Mapping[str, Any]
    PathLike = str | os.PathLike[str]
    Quantity = float | str
    Progress = bool | None | Callable[..., Any]
    Units = str | Mapping[str, str] | None
