"""The one table dialect softrod reads and writes (docs/datasets.md).

Column names are ``<base>_<unit>``: ``p0_kPa`` ... (gauge pressure of each channel, channels
numbered from 0), ``t0_N`` ... (tension of each tendon channel, optional), ``tip_x_mm`` ...
(tip position, world frame), ``tip_qw`` ... (tip orientation as a unit quaternion, scalar
first), ``base_fx_N`` ..., ``base_mx_Nmm`` ... (the wrench the rod exerts on its mount),
``tip_reaction_fx_N`` ..., ``tip_reaction_mx_Nmm`` ... (the wrench a held tip's constraint
applies to the tip: measured, or a held tip's sweep), ``time_s``, ``experiment``,
``mounting``. A table softrod writes may carry
further *result columns* after these (``converged``, ``iterations``, ``cmd0_kPa``,
``sigma_ext``, ...); their names are declared, with a description, in the ``columns`` entry of
the table's metadata block, so :func:`softrod.load_dataset` reads them back while an undeclared
unknown column (a typo) stays an error.

This module holds what every writer shares: the units of each quantity kind, the quaternion
conversions and :func:`schema_frame`, which lays out the columns. It imports no softrod module
above :mod:`softrod.units` and :mod:`softrod.errors`, so results (``BatchSolution``,
``Trajectory``) and datasets use it alike.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ._limits import MAX_CHANNELS
from .errors import InputError, design_error

__all__ = [
    "DEFAULT_UNITS",
    "DISPLAY_UNITS",
    "TABLE_SI",
    "UNIT_ALIASES",
    "Extra",
    "matrix_to_quat",
    "quat_to_matrix",
    "schema_frame",
    "table_units",
    "unit_factor",
    "unit_suffix",
]

# ASCII spellings of moment units, mapped before pint reads a unit: pint reads "Nm" as
# number-metre and does not know "Nmm". Keys are exact (case-sensitive) unit strings.
UNIT_ALIASES = {
    "Nm": "N*m",
    "Nmm": "N*mm",
    "Ncm": "N*cm",
    "mNm": "mN*m",
    "mNmm": "mN*mm",
    "kNm": "kN*m",
}
_SUFFIX_OF = {v: k for k, v in UNIT_ALIASES.items()}

# The SI unit of each kind a table column can have.
TABLE_SI = {
    "pressure": "Pa",
    "length": "m",
    "force": "N",
    "moment": "N*m",
    "time": "s",
    "velocity": "m/s",
    "energy": "J",
}

# Units tables are written in unless told otherwise (one per kind), as column suffixes.
DEFAULT_UNITS = {
    "pressure": "kPa",
    "length": "mm",
    "force": "N",
    "moment": "Nmm",
    "time": "s",
    "velocity": "mm/s",
    "energy": "J",
}

# The one unit in which each kind of quantity is *shown* to people: command-line tables,
# summaries, reprs, reports and figures (SI stays the unit of every array and of JSON).
# Keys are the SI unit of a value, values (shown unit, factor from SI).
DISPLAY_UNITS = {
    "Pa": ("kPa", 1e-3),
    "m": ("mm", 1e3),
    "N": ("N", 1.0),
    "N*m": ("N mm", 1e3),
    "s": ("s", 1.0),
    "rad": ("deg", 180.0 / np.pi),
    "1": ("", 1.0),
}


def display(value: float, si_unit: str) -> tuple[float, str]:
    """(value in its display unit, that unit) for an SI ``value`` in ``si_unit``."""
    unit, factor = DISPLAY_UNITS.get(si_unit, (si_unit, 1.0))
    return value * factor, unit


def _fail(field: str, value: object, rule: str) -> InputError:
    return design_error(field, value, rule, InputError)


def unit_suffix(unit: str) -> str:
    """The column-name spelling of a unit (``N*mm`` -> ``Nmm``)."""
    return _SUFFIX_OF.get(unit.strip(), unit.strip())


# SI factors of the units tables are written in by default and in SI, as pint gives them:
# writing a table needs no unit registry (building pint's takes a good part of a second).
_KNOWN_FACTORS = {
    ("pressure", "kPa"): 1e3,
    ("pressure", "Pa"): 1.0,
    ("length", "mm"): 1e-3,
    ("length", "m"): 1.0,
    ("force", "N"): 1.0,
    ("moment", "Nmm"): 1e-3,
    ("moment", "N*mm"): 1e-3,
    ("moment", "Nm"): 1.0,
    ("moment", "N*m"): 1.0,
    ("time", "s"): 1.0,
    ("velocity", "mm/s"): 1e-3,
    ("velocity", "m/s"): 1.0,
    ("energy", "J"): 1.0,
}


def unit_factor(unit: str, kind: str, column: str) -> float:
    """SI factor of ``unit`` (a unit string, aliases allowed) checked against ``kind``, read
    by the restricted unit grammar of :mod:`softrod._validate` (never evaluated as an
    expression: a column ``p0_10**10**10`` is refused at once)."""
    if not isinstance(unit, str):
        raise _fail(column, unit, "must be a unit string such as 'kPa'")
    known = _KNOWN_FACTORS.get((kind, unit.strip()))
    if known is not None:
        return known
    from ._validate import unit_factor as checked

    return checked(unit, kind, column)


def table_units(units: Mapping[str, str] | None) -> tuple[dict[str, str], dict[str, float]]:
    """(column suffix per kind, SI factor per kind): :data:`DEFAULT_UNITS` with ``units``
    (kind -> unit, any subset) applied. ``units="SI"`` picks the SI unit of every kind."""
    if isinstance(units, str) and units == "SI":
        units = TABLE_SI
    chosen = dict(DEFAULT_UNITS)
    if units is not None and not isinstance(units, Mapping):
        raise _fail(
            "units", units, "must map a kind ('pressure', 'length', ...) to a unit, or 'SI'"
        )
    for kind, unit in dict(units or {}).items():
        if kind not in DEFAULT_UNITS:
            raise _fail(f"units.{kind}", unit, f"unknown kind (known: {', '.join(DEFAULT_UNITS)})")
        if not isinstance(unit, str):
            raise _fail(f"units.{kind}", unit, "must be a unit string such as 'kPa'")
        chosen[kind] = unit_suffix(unit)
    return chosen, {k: unit_factor(u, k, f"units.{k}") for k, u in chosen.items()}


# --- rotations -------------------------------------------------------------------------------


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(m, 4) unit quaternions (w, x, y, z) -> (m, 3, 3) rotation matrices."""
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=1,
    )


def matrix_to_quat(r: np.ndarray) -> np.ndarray:
    """(m, 3, 3) rotation matrices -> (m, 4) unit quaternions (w, x, y, z) with w >= 0.

    Shepperd's method: divide by the largest of |w|, |x|, |y|, |z| so no branch loses digits.
    Rows with a non-finite matrix (a failed solve) give NaN.
    """
    r = np.asarray(r, dtype=float).reshape(-1, 3, 3)
    good = np.isfinite(r).all(axis=(1, 2))
    q = np.full((len(r), 4), np.nan)
    if good.any():
        q[good] = _matrix_to_quat(r[good])
    return q


def _matrix_to_quat(r: np.ndarray) -> np.ndarray:
    tr = np.trace(r, axis1=1, axis2=2)
    diag = np.stack([r[:, 0, 0], r[:, 1, 1], r[:, 2, 2]], axis=1)
    four_sq = np.column_stack([1 + tr, 1 + 2 * diag - tr[:, None]])  # 4w^2, 4x^2, 4y^2, 4z^2
    pick = np.argmax(four_sq, axis=1)
    big = 0.5 * np.sqrt(np.maximum(four_sq[np.arange(len(r)), pick], 0.0))
    d = 4.0 * np.where(big > 0, big, 1.0)
    a21, a12, a02, a20, a10, a01 = (
        r[:, 2, 1],
        r[:, 1, 2],
        r[:, 0, 2],
        r[:, 2, 0],
        r[:, 1, 0],
        r[:, 0, 1],
    )
    cases = [
        (big, (a21 - a12) / d, (a02 - a20) / d, (a10 - a01) / d),
        ((a21 - a12) / d, big, (a01 + a10) / d, (a02 + a20) / d),
        ((a02 - a20) / d, (a01 + a10) / d, big, (a12 + a21) / d),
        ((a10 - a01) / d, (a02 + a20) / d, (a12 + a21) / d, big),
    ]
    q = np.zeros((len(r), 4))
    for k, comps in enumerate(cases):
        sel = pick == k
        q[sel] = np.column_stack([c[sel] for c in comps])
    q[q[:, 0] < 0] *= -1.0
    return q / np.linalg.norm(q, axis=1, keepdims=True)


# --- the frame ---------------------------------------------------------------------------------

_XYZ = ("x", "y", "z")
TIP = tuple(f"tip_{a}" for a in _XYZ)
QUAT = ("tip_qw", "tip_qx", "tip_qy", "tip_qz")
FORCE = tuple(f"base_f{a}" for a in _XYZ)
MOMENT = tuple(f"base_m{a}" for a in _XYZ)
REACTION_FORCE = tuple(f"tip_reaction_f{a}" for a in _XYZ)
REACTION_MOMENT = tuple(f"tip_reaction_m{a}" for a in _XYZ)


@dataclass(frozen=True)
class Extra:
    """A result column after the schema's: ``base`` name, quantity ``kind`` (None: no unit;
    the name gets ``_<unit>`` otherwise), values in SI and a description for the metadata."""

    base: str
    values: Any
    description: str
    kind: str | None = None


#: ``Dataset.marker_body`` of a marker on a system's platform.
PLATFORM_BODY = -1


def body_name(index: int) -> str:
    """The metadata's name of ``Dataset.marker_body`` value ``index``."""
    return "platform" if index == PLATFORM_BODY else f"rod{int(index)}"


def schema_frame(
    *,
    pressures,
    tip_position,
    tensions=None,
    tip_rotation=None,
    base_force=None,
    base_moment=None,
    time=None,
    experiment=None,
    mounting=None,
    markers=None,
    marker_s=None,
    marker_offset=None,
    marker_body=None,
    tip_reaction_force=None,
    tip_reaction_moment=None,
    extras: Sequence[Extra] = (),
    units: Mapping[str, str] | str | None = None,
    metadata: Mapping[str, Any] | None = None,
):
    """A pandas DataFrame in the dataset schema from SI arrays (m rows).

    Columns in order: experiment, mounting, time, p0..p<c-1>, t0..t<k-1> (tendon
    tensions, from ``tensions`` (m, k); none when None), tip_x/y/z (unless
    ``tip_position`` is None), tip_qw..qz (from ``tip_rotation``), base_fx..fz,
    base_mx..mz, tip_reaction_fx..fz and tip_reaction_mx..mz (from ``tip_reaction_force``
    and ``tip_reaction_moment`` (m, 3), NaN where not measured), marker0_x/y/z ... (from
    ``markers`` (m, K, 3), NaN where not seen), then ``extras``. Units go into the names
    (:data:`DEFAULT_UNITS` or ``units``). NaN rows (a failed solve) stay NaN. The metadata
    (``frame.attrs["softrod.metadata"]``) gets a ``columns`` entry that declares every
    extra column by its name, and with markers a ``markers`` entry with each marker's arc
    length ``marker_s`` (K,) and offset ``marker_offset`` (K, 3), SI (and, for a system's
    markers, the body ``marker_body`` (K,) each sits on).
    """
    import pandas as pd

    chosen, factor = table_units(units)
    cols: dict[str, Any] = {}
    if experiment is not None:
        cols["experiment"] = np.asarray(experiment)
    if mounting is not None:
        cols["mounting"] = np.asarray(mounting)
    if time is not None:
        cols[f"time_{chosen['time']}"] = np.asarray(time, dtype=float) / factor["time"]
    p = np.asarray(pressures, dtype=float)
    for k in range(p.shape[1]):
        cols[f"p{k}_{chosen['pressure']}"] = p[:, k] / factor["pressure"]
    if tensions is not None:
        t = np.asarray(tensions, dtype=float)
        for k in range(t.shape[1]):
            cols[f"t{k}_{chosen['force']}"] = t[:, k] / factor["force"]
    if tip_position is not None:
        tip = np.asarray(tip_position, dtype=float)
        for i, name in enumerate(TIP):
            cols[f"{name}_{chosen['length']}"] = tip[:, i] / factor["length"]
    if tip_rotation is not None:
        q = matrix_to_quat(tip_rotation)
        for i, name in enumerate(QUAT):
            cols[name] = q[:, i]
    for names, arr, kind in (
        (FORCE, base_force, "force"),
        (MOMENT, base_moment, "moment"),
        (REACTION_FORCE, tip_reaction_force, "force"),
        (REACTION_MOMENT, tip_reaction_moment, "moment"),
    ):
        if arr is not None:
            a = np.asarray(arr, dtype=float)
            for i, name in enumerate(names):
                cols[f"{name}_{chosen[kind]}"] = a[:, i] / factor[kind]
    sites = None
    if markers is not None:
        mk = np.asarray(markers, dtype=float)
        for k in range(mk.shape[1]):
            for i, a in enumerate(_XYZ):
                cols[f"marker{k}_{a}_{chosen['length']}"] = mk[:, k, i] / factor["length"]
        sites = {
            f"marker{k}": {
                "s": f"{float(s)!r} m",
                "offset": [f"{float(v)!r} m" for v in o],
            }
            for k, (s, o) in enumerate(zip(marker_s, marker_offset, strict=True))
        }
        if marker_body is not None:  # a system's markers: the body each sits on
            for k, b in enumerate(marker_body):
                site = sites[f"marker{k}"]
                site["body"] = body_name(b)
                if b == PLATFORM_BODY:
                    del site["s"]
    declared: dict[str, str] = {}
    for extra in extras:
        values = np.asarray(extra.values)
        if extra.kind is None:
            name = extra.base
        else:
            name = f"{extra.base}_{chosen[extra.kind]}"
            values = values.astype(float) / factor[extra.kind]
        if name in cols:
            raise _fail("extras", name, "names a column twice")
        cols[name] = values
        declared[name] = extra.description
    frame = pd.DataFrame(cols)
    meta = dict(metadata or {})
    if sites is not None:
        meta["markers"] = sites
    if declared:
        meta["columns"] = {**dict(meta.get("columns") or {}), **declared}
    frame.attrs["softrod.metadata"] = meta
    return frame


def provenance(generator: str, design=None, *, synthetic: bool = True, **settings) -> dict:
    """The metadata block of a table softrod writes: what made it (``generator``), whether
    its tip columns come from the model (``synthetic``, True for sweeps, comparisons and
    trajectories; a table of measurements with results beside them says False), the softrod
    version, the design (name and file) and the settings given."""
    from . import __version__

    meta: dict[str, Any] = {
        "generator": generator,
        "synthetic": bool(synthetic),
        "softrod_version": __version__,
    }
    if design is not None:
        meta["design"] = design.name
        meta["design_source"] = None if design.source is None else str(design.source.name)
    meta.update(settings)
    return meta


def channel_index(base: str, column: str) -> int:
    """The channel index of a ``p<k>`` (pressure) or ``t<k>`` (tendon tension) base name,
    refused beyond MAX_CHANNELS before any table of channels is built."""
    digits = base[1:]
    if len(digits) > 3 or int(digits) >= MAX_CHANNELS:
        shown = digits if len(digits) <= 12 else digits[:12] + "..."
        kind = "pressure" if base[0] == "p" else "tension"
        raise design_error(
            column,
            column,
            f"channel {shown} is beyond softrod's limit of {MAX_CHANNELS} {kind} channels "
            f"({base[0]}0 ... {base[0]}{MAX_CHANNELS - 1})",
            InputError,
        )
    return int(digits)
