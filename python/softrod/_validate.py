"""The one validated boundary: every input from outside (design files and mappings, call
arguments, CLI options, dataset and schedule files) is converted and checked here, before any
work or allocation (docs/errors.md).

- Numbers are real, finite floats or ints of sane size: bools, complex numbers, masked
  arrays, mappings and text where a number belongs are errors, never coerced; numpy scalars
  are accepted wherever Python numbers are.
- Quantities with units are read by a restricted grammar, ``number [unit]``, where the unit
  is a product or quotient of unit symbols, each with an optional SI prefix and an integer
  exponent (``"110 mm"``, ``"1.2e-3 N*m^2"``, ``"1070 kg/m^3"``, ``"0.5 1/m"``). Only single
  unit symbols reach pint's registry (to look up their size and dimension); no text is ever
  evaluated as an expression, so ``"10**10**10 mm"`` is an instant error. The unit must have
  the field's dimension: ``"30 deg"`` is not a length and ``"5 %"`` is not a mass.
- Sizes are bounded by the limits of :mod:`softrod._limits` (channels, sections, chambers,
  steps, threads, rows, text), checked before anything is allocated.

Errors are :class:`~softrod.errors.DesignError` (design documents) or
:class:`~softrod.errors.InputError` (everything else), with ``field`` (the path of the
offending entry), ``value`` and ``rule``.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping
from functools import lru_cache

import numpy as np

from ._limits import (  # noqa: F401 - the limits are part of this module's interface
    LIMITS,
    MAX_ABS_INT,
    MAX_CHAMBERS,
    MAX_CHANNELS,
    MAX_DEPTH,
    MAX_DESIGN_STEPS,
    MAX_DYNAMIC_STEPS,
    MAX_ITERATIONS,
    MAX_LOADS,
    MAX_NAME_LENGTH,
    MAX_OBSTACLES,
    MAX_QUANTITY_LENGTH,
    MAX_RESTARTS,
    MAX_ROWS,
    MAX_SAVED_SAMPLES,
    MAX_SECTION_STEPS,
    MAX_SECTIONS,
    MAX_SHAPE_POINTS,
    MAX_TABLE_POINTS,
    MAX_TENDONS,
    MAX_TEXT_LENGTH,
    MAX_THREADS,
    VACUUM_PA,
)
from .errors import DesignError, InputError, design_error

# --- quantity kinds -------------------------------------------------------------------------------

# SI unit of each kind; its dimension is the kind's dimension.
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
    "contact_stiffness": "N/m^2",
    "stiffness_bending": "N*m^2",
    "curvature": "1/m",
    "time": "s",
    "pressure_rate": "Pa/s",
    "inertia": "kg*m^2",
    "inertia_per_length": "kg*m",
    "damping_force": "N*s",
    "damping_moment": "N*m^2*s",
    "damping_linear": "N*s/m",
    "damping_rotational": "N*m*s",
    "velocity": "m/s",
    "energy": "J",
}

# A unit the error messages suggest for each kind (what people usually write).
EXAMPLE_UNIT = {
    **SI_UNIT,
    "length": "mm",
    "pressure": "kPa",
    "mass": "g",
    "angle": "deg",
    "moment": "N*mm",
    "area": "mm^2",
    "time": "ms",
    "stiffness_bending": "N*mm^2",
    "velocity": "mm/s",
}

# Whole-symbol spellings pint would misread ("Nm" is pint's number-metre) or not know.
UNIT_ALIASES = {
    "Nm": "N*m",
    "Nmm": "N*mm",
    "Ncm": "N*cm",
    "mNm": "mN*m",
    "mNmm": "mN*mm",
    "kNm": "kN*m",
    "%": "percent",
    "°": "degree",
}

# --- numbers ------------------------------------------------------------------------------------


def fail(field: str, value: object, rule: str, cls: type[DesignError] = InputError) -> DesignError:
    """The error ``field = value: rule`` of class ``cls`` (not raised)."""
    return design_error(field, value, rule, cls)


def is_real(value: object) -> bool:
    """True for an int or float (Python or numpy scalar), not a bool."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, (bool, np.bool_)
    )


def real(
    value: object,
    field: str,
    cls: type[DesignError] = InputError,
    *,
    minimum: float | None = None,
    maximum: float | None = None,
    exclusive: bool = False,
    what: str = "a number",
) -> float:
    """A finite real number (int or float, Python or numpy) within the bounds, as a float.

    ``exclusive`` makes ``minimum`` strict (``> minimum``)."""
    if not is_real(value):
        raise fail(field, value, f"must be {what}, not {_type_name(value)}", cls)
    x = _as_float(value, field, cls)
    if minimum is not None and (x <= minimum if exclusive else x < minimum):
        raise fail(field, value, f"must be {'>' if exclusive else '>='} {minimum:g}", cls)
    if maximum is not None and x > maximum:
        raise fail(field, value, f"must be <= {maximum:g}", cls)
    return x


def _as_float(value: object, field: str, cls: type[DesignError]) -> float:
    if isinstance(value, (int, np.integer)) and abs(int(value)) > MAX_ABS_INT:
        raise fail(field, value, "is too large (integers beyond 2^53 are refused)", cls)
    try:
        x = float(value)
    except (OverflowError, ValueError, TypeError):
        raise fail(field, value, "is not a finite number", cls) from None
    if not math.isfinite(x):
        raise fail(field, value, "must be a finite number", cls)
    return x


def integer(
    value: object,
    field: str,
    cls: type[DesignError] = InputError,
    *,
    minimum: int | None = None,
    maximum: int | None = None,
    hint: str = "",
) -> int:
    """An integer (Python or numpy int, not a bool, not a float such as 1.5 or 2.0) within
    [minimum, maximum]."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        rule = "must be an integer" + (f" >= {minimum}" if minimum is not None else "")
        raise fail(field, value, f"{rule}, not {_type_name(value)}", cls)
    n = int(value)
    if minimum is not None and n < minimum:
        raise fail(field, value, f"must be an integer >= {minimum}", cls)
    if maximum is not None and n > maximum:
        raise fail(field, value, f"must be <= {maximum}{hint}", cls)
    return n


def threads(value: object, field: str = "threads", cls: type[DesignError] = InputError) -> int:
    """Worker threads: 0 (all cores) ... MAX_THREADS."""
    return integer(
        value,
        field,
        cls,
        minimum=0,
        maximum=MAX_THREADS,
        hint=f" (the limit of softrod; 0 = all {os.cpu_count()} cores of this machine)",
    )


def boolean(value: object, field: str, cls: type[DesignError] = InputError) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise fail(field, value, f"must be true or false, not {_type_name(value)}", cls)
    return bool(value)


def text(
    value: object,
    field: str,
    cls: type[DesignError] = InputError,
    *,
    max_length: int = MAX_NAME_LENGTH,
    non_empty: bool = False,
) -> str:
    """A string of at most ``max_length`` characters (non-blank if ``non_empty``)."""
    if not isinstance(value, str):
        raise fail(field, value, f"must be a string, not {_type_name(value)}", cls)
    if len(value) > max_length:
        raise fail(field, value, f"is too long: at most {max_length} characters", cls)
    if non_empty and not value.strip():
        raise fail(field, value, "must be a non-empty string", cls)
    return value


def figure_title(value: object) -> str | None:
    """A figure's ``title``: None (the default title) or text."""
    if value is not None and not isinstance(value, str):
        raise fail("title", value, f"must be text or None, not {_type_name(value)}", InputError)
    return value


def choice(value: object, options, field: str, cls: type[DesignError] = InputError) -> str:
    """One of ``options`` (strings); anything else, including unhashable values, is an error."""
    if not isinstance(value, str) or value not in options:
        raise fail(field, value, f"must be one of {', '.join(map(repr, options))}", cls)
    return value


def _type_name(value: object) -> str:
    if isinstance(value, np.ma.MaskedArray):
        return "a masked array"
    if isinstance(value, (bool, np.bool_)):
        return "a boolean"
    if isinstance(value, (complex, np.complexfloating)):
        return "a complex number"
    if isinstance(value, str):
        return "text"
    if isinstance(value, Mapping):
        return "a mapping"
    if value is None:
        return "None"
    return f"a {type(value).__name__}"


# --- arrays -------------------------------------------------------------------------------------


def real_array(
    value: object,
    field: str,
    cls: type[DesignError] = InputError,
    *,
    ndim: int | None = None,
    max_size: int = MAX_ROWS * MAX_CHANNELS,
    unit_kind: str | None = None,
    what: str = "numbers",
) -> np.ndarray:
    """A new float array of finite values from a sequence or an array.

    Refused: mappings, text, masked arrays (the hidden values would be used), bools, complex
    numbers, dates, objects that are not numbers. ``unit_kind``: a quantity kind whose unit
    strings are accepted element by element (``["30 kPa", 0]``); bare numbers are SI.
    Infinite and NaN values name the first offending index."""
    if isinstance(value, (str, bytes, Mapping)) or isinstance(value, (set, frozenset)):
        raise fail(field, value, f"must be an array of {what}, not {_type_name(value)}", cls)
    if isinstance(value, np.ma.MaskedArray):
        raise fail(
            field,
            "masked array",
            f"must be a plain array of {what}: a masked array's hidden values would be used "
            "(fill or drop the masked entries first, e.g. a.filled(...) or a.compressed())",
            cls,
        )
    if hasattr(value, "magnitude") and hasattr(value, "units"):
        raise fail(
            field,
            _type_name(value),
            f"must be plain {what} (SI); convert a pint quantity with .to(...).magnitude",
            cls,
        )
    try:
        arr = np.asarray(value)
    except (ValueError, TypeError, OverflowError) as exc:
        raise fail(field, value, f"must be a regular array of {what} ({exc})", cls) from None
    if arr.size > max_size:
        raise fail(field, f"array of {arr.size} values", f"is too large: at most {max_size}", cls)
    kind = arr.dtype.kind
    if kind in "iuf" and not isinstance(value, np.ndarray) and arr.size:
        # numpy turns [True, 0] into integers: look at what was given.
        given = np.array(value, dtype=object).ravel()
        if any(isinstance(x, (bool, np.bool_)) for x in given):
            kind = "b"
    if kind == "b":
        raise fail(field, value, f"must be {what}, not booleans", cls)
    if kind == "c":
        raise fail(field, value, f"must be real {what}, not complex", cls)
    if kind in "iu":
        if arr.size and int(np.abs(arr).max()) > MAX_ABS_INT:
            raise fail(field, value, f"holds integers beyond 2^53 = {MAX_ABS_INT}", cls)
        out = arr.astype(float)
    elif kind == "f":
        out = arr.astype(float)  # a copy, also of float16/32/longdouble input
    elif kind in "OUS":
        if unit_kind is None and kind != "O":
            raise fail(field, value, f"must be {what}, not text", cls)
        flat = arr.ravel()
        out = np.empty(flat.shape, dtype=float)
        for i, x in enumerate(flat):
            where = field + "".join(f"[{int(k)}]" for k in np.unravel_index(i, arr.shape))
            if unit_kind is not None and isinstance(x, str):
                out[i] = quantity(x, unit_kind, where, cls)
            else:
                out[i] = real(x, where, cls, what="a number")
        out = out.reshape(arr.shape)
    else:
        raise fail(field, value, f"must be {what}, not {arr.dtype}", cls)
    if ndim is not None and out.ndim != ndim:
        raise fail(field, f"shape {out.shape}", f"must be a {ndim}-d array of {what}", cls)
    bad = np.flatnonzero(~np.isfinite(out.ravel()))
    if bad.size:
        idx = np.unravel_index(bad[0], out.shape) if out.ndim else ()
        where = field + "".join(f"[{int(i)}]" for i in idx)
        raise fail(where, out[idx].item() if out.ndim else out.item(), "must be finite", cls)
    return out


# --- the unit grammar -----------------------------------------------------------------------------

_NUMBER = re.compile(
    r"\s*(?P<num>[+-]?(?:(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?|inf(?:inity)?|nan))",
    re.IGNORECASE,
)
# A unit symbol: letters (pint's names and prefixes; µ/μ for micro), or % or °.
_SYMBOL = re.compile(r"(?P<sym>[A-Za-zµμΩ_]+|%|°)(?:\s*(?:\^|\*\*)\s*(?P<exp>[+-]?\d{1,2}))?")
_MAX_FACTORS = 8
_GRAMMAR = (
    "a quantity reads 'number unit', e.g. '110 mm', '0.6 bar', '1.2e-3 N*m^2', '1070 kg/m^3' "
    "(unit symbols joined by * or /, integer exponents with ^)"
)


class _UnitSyntaxError(ValueError):
    pass


@lru_cache(maxsize=1)
def registry():
    """pint's unit registry, built on first use (importing pint takes a moment)."""
    import pint

    return pint.UnitRegistry()


@lru_cache(maxsize=4096)
def _symbol(sym: str) -> tuple[float, tuple, bool]:
    """(size in coherent SI base units, dimension, is an angle unit) of one unit symbol,
    looked up by name in pint's registry (never parsed as an expression)."""
    ureg = registry()
    try:
        name = ureg.get_name(sym)
    except Exception:  # pint's UndefinedUnitError, and anything else a lookup may raise
        raise _UnitSyntaxError(f"unknown unit {sym!r}") from None
    if not name:
        raise _UnitSyntaxError(f"unknown unit {sym!r}")
    factor, base = ureg.get_base_units(name)
    dims = ureg.get_dimensionality(name)
    # Offset units (degC) have a temperature dimension, which no softrod quantity has.
    is_angle = dict(base._units) == {"radian": 1}
    return float(factor), tuple(sorted(dims.items())), is_angle


@lru_cache(maxsize=4096)
def parse_unit(unit: str) -> tuple[float, tuple, bool]:
    """(SI factor, dimension, is an angle) of a unit expression such as ``N*m^2``,
    ``kg/m^3`` or ``1/m``; raises ``ValueError`` with the reason for anything else."""
    text = unit.strip()
    if not text:
        return 1.0, (), False
    if len(text) > MAX_QUANTITY_LENGTH:
        raise _UnitSyntaxError(f"a unit of at most {MAX_QUANTITY_LENGTH} characters")
    text = UNIT_ALIASES.get(text, text)
    pos, sign = 0, 1
    factor, dims, angle, n = 1.0, {}, [], 0
    if re.match(r"1\s*/", text):  # "1/m": a quotient with nothing above the line
        pos, sign = re.match(r"1\s*/\s*", text).end(), -1
    while True:
        m = _SYMBOL.match(text, pos)
        if m is None:
            raise _UnitSyntaxError(f"expected a unit symbol at {text[pos:]!r}")
        n += 1
        if n > _MAX_FACTORS:
            raise _UnitSyntaxError(f"at most {_MAX_FACTORS} unit symbols")
        sym = m["sym"]
        exp = sign * (int(m["exp"]) if m["exp"] else 1)
        if abs(exp) > 4:
            raise _UnitSyntaxError(f"exponent {exp} out of range (-4 ... 4)")
        for part in UNIT_ALIASES[sym].split("*") if sym in UNIT_ALIASES else [sym]:
            f, d, is_angle = _symbol(part)
            factor *= f**exp
            for k, v in d:
                dims[k] = dims.get(k, 0) + v * exp
            angle.append(is_angle and exp == 1)
        pos = m.end()
        rest = re.match(r"\s*([*/·])\s*|\s+(?=\S)", text[pos:])
        if pos == len(text):
            break
        if rest is None:
            raise _UnitSyntaxError(f"unexpected {text[pos:]!r}")
        sign = -1 if rest.group(1) == "/" else 1
        pos += rest.end()
    dims_t = tuple(sorted((k, v) for k, v in dims.items() if v != 0))
    return factor, dims_t, len(angle) == 1 and angle[0]


@lru_cache(maxsize=64)
def _kind_dims(kind: str) -> tuple:
    return parse_unit(SI_UNIT[kind])[1]


def split_quantity(text: str) -> tuple[float, str]:
    """(number, unit text) of ``"number unit"``; ValueError if the text is not of that form."""
    m = _NUMBER.match(text)
    if m is None:
        raise _UnitSyntaxError("it does not start with a number")
    return float(m["num"]), text[m.end() :].strip()


def quantity(
    value: object,
    kind: str,
    field: str,
    cls: type[DesignError] = InputError,
    *,
    bare: str = "si",
) -> float:
    """An SI float of quantity kind ``kind`` from a number or a string with units.

    ``bare`` says what a bare number (or a string without a unit) means: ``"si"`` (it is SI,
    as in the Python API's arrays), ``"error"`` (refused unless it is zero: design files
    without ``units = "SI"`` and CLI options), or a message suffix for the error."""
    if isinstance(value, str):
        if len(value) > MAX_QUANTITY_LENGTH:
            rule = f"is too long for a quantity ({MAX_QUANTITY_LENGTH} characters at most)"
            raise fail(field, value, rule, cls)
        try:
            number, unit = split_quantity(value)
            factor, dims, is_angle = parse_unit(unit)
        except _UnitSyntaxError as exc:
            rule = f"cannot read as {_article(kind)} {kind}: {exc}; {_GRAMMAR}"
            raise fail(field, value, rule, cls) from None
        if not math.isfinite(number):
            raise fail(field, value, "must be a finite number", cls)
        if not unit:
            return _bare(number, value, kind, field, cls, bare)
        want = _kind_dims(kind)
        if kind == "angle":
            if not is_angle:
                rule = "must be an angle with an angle unit (e.g. '30 deg' or '0.5 rad'), got "
                raise fail(field, value, rule + _dim_text(dims, unit), cls)
        elif dims != want:
            raise fail(
                field,
                value,
                f"wrong unit: must be {_article(kind)} {kind} (like '{EXAMPLE_UNIT[kind]}'), "
                f"got {_dim_text(dims, unit)}",
                cls,
            )
        x = number * factor
        if not math.isfinite(x):
            raise fail(field, value, "is out of range (not finite in SI)", cls)
        return x
    if not is_real(value):
        raise fail(
            field,
            value,
            f"must be {_article(kind)} {kind} such as '1 {EXAMPLE_UNIT[kind]}', "
            f"not {_type_name(value)}",
            cls,
        )
    return _bare(_as_float(value, field, cls), value, kind, field, cls, bare)


def _bare(x: float, value, kind: str, field: str, cls, bare: str) -> float:
    if bare == "si" or x == 0.0:
        return x
    suffix = "" if bare == "error" else f" {bare}"
    shown = value.strip() if isinstance(value, str) else f"{x:g}"
    units = dict.fromkeys((EXAMPLE_UNIT[kind], SI_UNIT[kind]))
    spelled = " or ".join(f'"{shown} {u}"' for u in units)
    raise fail(
        field,
        value,
        f"a bare number is ambiguous for {_article(kind)} {kind}: write it with its unit, e.g. "
        f"{spelled}{suffix}",
        cls,
    )


def _article(word: str) -> str:
    return "an" if word[0] in "aeiou" else "a"


def _dim_text(dims: tuple, unit: str) -> str:
    if not dims:
        return f"{unit!r}, which has no dimension"
    return f"{unit!r} of dimension " + " * ".join(f"{k}" if v == 1 else f"{k}^{v}" for k, v in dims)


def unit_factor(unit: str, kind: str, field: str, cls: type[DesignError] = InputError) -> float:
    """SI factor of a unit alone (a column-name unit such as ``kPa`` or ``Nmm``) of ``kind``."""
    if not isinstance(unit, str):
        raise fail(field, unit, "must be a unit string such as 'kPa'", cls)
    if not unit.strip():
        rule = f"empty unit: {_article(kind)} {kind} needs one, e.g. '{EXAMPLE_UNIT[kind]}'"
        raise fail(field, unit, rule, cls)
    try:
        factor, dims, is_angle = parse_unit(unit)
    except _UnitSyntaxError as exc:
        raise fail(field, unit, f"not a unit of {_article(kind)} {kind}: {exc}", cls) from None
    ok = is_angle if kind == "angle" else dims == _kind_dims(kind)
    if not ok:
        raise fail(
            field,
            unit,
            f"wrong unit: must be {_article(kind)} {kind} unit (like '{EXAMPLE_UNIT[kind]}'), "
            f"got {_dim_text(dims, unit)}",
            cls,
        )
    return factor


# --- structure -----------------------------------------------------------------------------------


_SCALARS = frozenset({int, float, str, bool, type(None)})


def check_depth(
    obj: object, field: str, cls: type[DesignError] = InputError, limit: int = MAX_DEPTH
) -> None:
    """Refuse tables and arrays nested deeper than ``limit`` (iteratively: a hostile document
    can never raise RecursionError here)."""
    stack = [(obj, 0)]
    while stack:
        item, depth = stack.pop()
        if depth > limit:
            rule = f"nests tables/arrays deeper than {limit} levels"
            raise fail(field, "deeply nested data", rule, cls)
        if isinstance(item, (list, tuple)):  # before Mapping: an abstract, slower check
            children = item
        elif isinstance(item, Mapping):
            children = item.values()
        else:
            continue
        for c in children:
            # Scalars first, by exact type: a document's thousands of numbers (an inline
            # mesh) skip the abstract Mapping check.
            if type(c) not in _SCALARS and isinstance(c, (list, tuple, Mapping)):
                stack.append((c, depth + 1))


def si_text(value: float, kind: str) -> str:
    """An SI value as a quantity string that reads back exactly (``"0.0123 m"``): how
    softrod writes computed values into design documents, which need units."""
    return f"{float(value)!r} {SI_UNIT[kind]}"
