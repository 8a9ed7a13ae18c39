"""Units at the boundary: strings such as "110 mm" or "0.6 bar" become SI floats here.

Bare numbers are taken as SI. Everything inside softrod is SI (m, N, Pa, kg, s, rad).
"""

from __future__ import annotations

import math
from functools import lru_cache

import pint

from .errors import DesignError, design_error

# The dimension each quantity kind must have, as pint writes it.
DIMENSIONS = {
    "length": "[length]",
    "pressure": "[mass] / [length] / [time] ** 2",
    "mass": "[mass]",
    "density": "[mass] / [length] ** 3",
    "acceleration": "[length] / [time] ** 2",
    "angle": "",
    "force": "[length] * [mass] / [time] ** 2",
    "moment": "[length] ** 2 * [mass] / [time] ** 2",
    "area": "[length] ** 2",
    "force_per_length": "[mass] / [time] ** 2",
    "stiffness_bending": "[length] ** 3 * [mass] / [time] ** 2",
    "time": "[time]",
    "pressure_rate": "[mass] / [length] / [time] ** 3",
    "inertia": "[length] ** 2 * [mass]",
    "inertia_per_length": "[length] * [mass]",
    "damping_force": "[length] * [mass] / [time]",
    "damping_moment": "[length] ** 3 * [mass] / [time]",
    "damping_linear": "[mass] / [time]",
    "damping_rotational": "[length] ** 2 * [mass] / [time]",
}

SI_UNIT = {
    "length": "m",
    "pressure": "Pa",
    "mass": "kg",
    "density": "kg/m^3",
    "acceleration": "m/s^2",
    "angle": "rad",
    "force": "N",
    "moment": "N*m",
    "area": "m^2",
    "force_per_length": "N/m",
    "stiffness_bending": "N*m^2",
    "time": "s",
    "pressure_rate": "Pa/s",
    "inertia": "kg*m^2",
    "inertia_per_length": "kg*m",
    "damping_force": "N*s",
    "damping_moment": "N*m^2*s",
    "damping_linear": "N*s/m",
    "damping_rotational": "N*m*s",
}


@lru_cache(maxsize=1)
def registry() -> pint.UnitRegistry:
    return pint.UnitRegistry()


def to_si(value: object, kind: str, field: str, cls: type[DesignError] = DesignError) -> float:
    """Convert a number (SI) or a string with units to an SI float of the given kind."""
    if isinstance(value, bool) or value is None:
        raise design_error(field, value, f"must be a {kind} such as '1 {SI_UNIT[kind]}'", cls)
    if isinstance(value, (int, float)):
        x = float(value)
    elif isinstance(value, str):
        ureg = registry()
        try:
            q = ureg.Quantity(value.strip())
        except Exception as exc:  # pint raises several error types for bad strings
            raise design_error(field, value, f"cannot read as a {kind}: {exc}", cls) from None
        if not isinstance(q, pint.Quantity):
            x = float(q)
        else:
            # Compare dimensionality objects, not their strings: pint orders the base
            # dimensions of a string by its own rules (N prints "[mass] * [length] / ...").
            want = ureg.get_dimensionality(SI_UNIT[kind]) if kind != "angle" else None
            have = str(q.dimensionality)
            if kind == "angle":
                if not q.dimensionless:
                    raise design_error(
                        field, value, f"must be an angle (e.g. '30 deg'), got dimension {have}", cls
                    )
                x = float(q.to("radian").magnitude)
            else:
                if q.dimensionless:
                    x = float(q.magnitude)  # a bare number in a string: SI
                elif q.dimensionality != want:
                    raise design_error(
                        field,
                        value,
                        f"wrong unit: must be a {kind} (like '{SI_UNIT[kind]}'), "
                        f"got dimension {have}",
                        cls,
                    )
                else:
                    x = float(q.to(SI_UNIT[kind]).magnitude)
    else:
        raise design_error(field, value, f"must be a number or a string with units ({kind})", cls)
    if not math.isfinite(x):
        raise design_error(field, value, "must be a finite number", cls)
    return x


def vector_to_si(
    value: object,
    kind: str,
    field: str,
    cls: type[DesignError] = DesignError,
    length: int | None = 3,
):
    """A list of quantities: ``length`` of them (3 by default), or any number if None."""
    if not isinstance(value, (list, tuple)) or (length is not None and len(value) != length):
        count = "" if length is None else f"{length} "
        raise design_error(field, value, f"must be a list of {count}{kind} values", cls)
    return [to_si(v, kind, f"{field}[{i}]", cls) for i, v in enumerate(value)]


def number(value: object, field: str, cls: type[DesignError] = DesignError) -> float:
    """A dimensionless finite number."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise design_error(field, value, "must be a number", cls)
    x = float(value)
    if not math.isfinite(x):
        raise design_error(field, value, "must be a finite number", cls)
    return x
