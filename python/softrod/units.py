"""Units at the boundary: strings such as "110 mm" or "0.6 bar" become SI floats here.

Everything inside softrod is SI (m, N, Pa, kg, s, rad). Strings are read by the restricted
grammar of :mod:`softrod._validate` (``number [unit]``, never evaluated as an expression) and
must have the field's dimension. A bare number is SI in the Python API's per-call arguments
(``bare="si"``, the default here); design files and CLI options refuse non-zero bare numbers
for dimensional quantities (``bare="error"``).
"""

from __future__ import annotations

from ._validate import SI_UNIT, fail, quantity, real, registry
from .errors import DesignError

__all__ = ["SI_UNIT", "number", "registry", "to_si", "vector_to_si"]


def to_si(
    value: object,
    kind: str,
    field: str,
    cls: type[DesignError] = DesignError,
    *,
    bare: str = "si",
) -> float:
    """Convert a number or a string with units to an SI float of the given kind."""
    return quantity(value, kind, field, cls, bare=bare)


def vector_to_si(
    value: object,
    kind: str,
    field: str,
    cls: type[DesignError] = DesignError,
    length: int | None = 3,
    *,
    bare: str = "si",
    max_length: int | None = None,
):
    """A list of quantities: ``length`` of them (3 by default), or any number (at most
    ``max_length``) if None."""
    if not isinstance(value, (list, tuple)) or (length is not None and len(value) != length):
        count = "" if length is None else f"{length} "
        raise fail(field, value, f"must be a list of {count}{kind} values", cls)
    if max_length is not None and len(value) > max_length:
        raise fail(field, value, f"has too many values: at most {max_length}", cls)
    return [quantity(v, kind, f"{field}[{i}]", cls, bare=bare) for i, v in enumerate(value)]


def number(value: object, field: str, cls: type[DesignError] = DesignError) -> float:
    """A dimensionless finite number (int or float; not a bool, not text)."""
    return real(value, field, cls)
