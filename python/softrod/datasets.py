"""Measurement datasets: load, validate, write and synthesise (schema in docs/datasets.md).

A dataset is a table with one row per static equilibrium (or time sample). Columns (base
names; kind; required or not):

- ``p0``, ``p1``, ... ``p<c-1>`` (pressure, required): gauge pressure of each channel.
- ``t0``, ``t1``, ... ``t<k-1>`` (force, optional): tension of each tendon channel (>= 0);
  without them every tendon is slack, as ``tensions=None`` in a solve.
- ``tip_x``, ``tip_y``, ``tip_z`` (length, required): tip position in the world frame of the
  design, the frame of ``StaticSolution.tip_position``.
- ``tip_qw``, ``tip_qx``, ``tip_qy``, ``tip_qz`` (no unit, optional group): tip orientation
  [d1 d2 d3] (world) as a unit quaternion, scalar first.
- ``base_fx``, ``base_fy``, ``base_fz`` (force) and ``base_mx``, ``base_my``, ``base_mz``
  (moment), optional groups: the force the rod exerts on its mount and its moment about the
  base point, world frame (``StaticSolution.base_force`` / ``base_moment``).
- ``marker0_x``, ``marker0_y``, ``marker0_z``, ``marker1_x``, ... (length, optional groups):
  positions of motion-capture markers anywhere on the body, world frame. A marker not seen
  in a row leaves its three cells empty. Where each marker sits is given once, in the
  metadata block: ``{"markers": {"marker0": {"s": "55 mm", "offset": ["12 mm", "0 mm"]}}}``
  (reference arc length s from the base and an offset in the cross-section frame (d1, d2)
  or (d1, d2, d3)).
- ``tip_reaction_fx``, ``tip_reaction_fy``, ``tip_reaction_fz`` (force) and
  ``tip_reaction_mx``, ``tip_reaction_my``, ``tip_reaction_mz`` (moment), optional groups:
  the measured wrench a held tip's constraint applies to the tip, world frame (the blocked
  force; the names and convention of a held tip's sweep table, ``tip_reaction_fx_N`` ...).
  A component not measured in a row (a one-axis load cell) leaves its cell empty.
- ``experiment`` (integer or string id), ``mounting`` (string), ``time`` (time): optional.

A dataset needs the tip columns, markers, the reaction, or a combination.

Every column of a kind with a dimension carries its unit, either in its name
(``<base>_<unit>``: ``p0_kPa``, ``tip_x_mm``, ``base_mx_Nmm``, ``time_s``) or in a metadata
block (CSV: a leading comment line ``# units: {"p0": "kPa"}``; Parquet: the key-value
metadata entry ``softrod.units``), never in both. Units are parsed by pint after the ASCII
spellings of :data:`UNIT_ALIASES` are mapped (``Nm`` would be pint's number-metre). Inside,
everything is SI: Pa, m, N, N m, s.

Errors are :class:`~softrod.errors.InputError` naming the column, the value and the rule; rows
are located by their line in a CSV file (as a text editor counts them), by their 0-based row in
a Parquet file and by their index label in a DataFrame.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from . import _validate as V
from .catalog import load_design
from .design import PACKAGE_DIR
from .errors import InputError, design_error
from .io import TABLE_SUFFIXES, check_table_path, read_text_file, write_table
from .io import exists as _exists
from .io import is_file as _is_file
from .schema import (
    DEFAULT_UNITS,
    PLATFORM_BODY,
    UNIT_ALIASES,
    Extra,
    channel_index,
    schema_frame,
)
from .schema import matrix_to_quat as _matrix_to_quat  # noqa: F401  (re-exported)
from .schema import quat_to_matrix as _quat_to_matrix
from .schema import unit_factor as _unit_factor

if TYPE_CHECKING:
    from ._types import ArrayLike, DesignLike, PathLike

__all__ = [
    "DEFAULT_UNITS",
    "Dataset",
    "QUATERNION_TOLERANCE",
    "UNIT_ALIASES",
    "example_dataset_path",
    "example_datasets",
    "load_dataset",
    "write_dataset",
]

# |q| must be 1 within this. Motion-capture exports round quaternions to about 7 significant
# digits (|q| - 1 ~ 1e-7); a larger error means the columns are not a unit quaternion at all
# (scalar-last order, Euler angles, degrees), which must not be renormalised silently.
QUATERNION_TOLERANCE = 1e-6

# A stored rotation matrix must be orthonormal within this (same reasoning).
_ROTATION_TOLERANCE = 1e-6

_NAME = re.compile(
    r"^(?P<base>p(?:0|[1-9][0-9]*)|t(?:0|[1-9][0-9]*)|tip_[xyz]|tip_q[wxyz]|base_[fm][xyz]|experiment|mounting|time"
    r"|marker(?:0|[1-9][0-9]*)_[xyz]|tip_reaction_[fm][xyz])"
    r"(?:_(?P<unit>.*))?$"
)
_MARKER = re.compile(r"^marker(0|[1-9][0-9]*)_([xyz])$")
_TENSION = re.compile(r"^t(0|[1-9][0-9]*)$")
#: Most markers a dataset may have (a motion-capture rig tracks tens).
MAX_MARKERS = 256
_XYZ = ("x", "y", "z")
_TIP = tuple(f"tip_{a}" for a in _XYZ)
_QUAT = ("tip_qw", "tip_qx", "tip_qy", "tip_qz")
_FORCE = tuple(f"base_f{a}" for a in _XYZ)
_MOMENT = tuple(f"base_m{a}" for a in _XYZ)
_REACTION_FORCE = tuple(f"tip_reaction_f{a}" for a in _XYZ)
_REACTION_MOMENT = tuple(f"tip_reaction_m{a}" for a in _XYZ)
_LABELS = ("experiment", "mounting")
_KNOWN = (
    "p0, p1, ... (channels), t0, t1, ... (tendon tensions), tip_x/y/z, tip_qw/qx/qy/qz, "
    "base_fx/fy/fz, base_mx/my/mz, marker0_x/y/z, marker1_x/y/z, ..., "
    "tip_reaction_fx/fy/fz, tip_reaction_mx/my/mz, experiment, mounting, time"
)
_MAX_LISTED = 10  # rows named in one error message before "and N more"

_EXAMPLES_DIR = PACKAGE_DIR / "data" / "examples"


def _kind(base: str) -> str | None:
    """Quantity kind of a base column name (None: no unit allowed)."""
    if base[0] == "p":
        return "pressure"
    if _TENSION.match(base):
        return "force"
    if base in _TIP or _MARKER.match(base):
        return "length"
    if base in _FORCE or base in _REACTION_FORCE:
        return "force"
    if base in _MOMENT or base in _REACTION_MOMENT:
        return "moment"
    if base == "time":
        return "time"
    return None


def _base(name: str) -> str | None:
    """The schema's base name of a column name (``p0_kPa`` -> ``p0``), None if unknown."""
    m = _NAME.match(name)
    return None if m is None else m["base"]


def _fail(field: str, value: object, rule: str) -> InputError:
    return design_error(field, value, rule, InputError)


def _checked_metadata(metadata) -> dict:
    """A copy of a data container's metadata with ``synthetic`` (default False) checked."""
    if not isinstance(metadata, Mapping):
        raise _fail("metadata", metadata, "must be a dict")
    meta = dict(metadata)
    meta.setdefault("synthetic", False)
    if not isinstance(meta["synthetic"], bool):
        raise _fail("metadata.synthetic", meta["synthetic"], "must be true or false")
    return meta


def _json_block(body: str, key: str, where: str) -> dict:
    """A ``# units:``/``# metadata:`` JSON object, nesting bounded (no RecursionError)."""
    try:
        value = json.loads(body)
    except json.JSONDecodeError as exc:
        raise _fail(
            key,
            body.strip(),
            f"{where}: not valid JSON ({exc.msg}); write e.g. "
            '# units: {"p0": "kPa", "tip_x": "mm"}',
        ) from None
    except RecursionError:
        raise _fail(key, body.strip(), f"{where}: nested too deeply") from None
    if not isinstance(value, dict):
        raise _fail(key, value, f"{where}: must be a JSON object {{...}}")
    V.check_depth(value, key)
    return value


# --- the dataset -------------------------------------------------------------------------------


def _real_or_nan(raw, field: str, what: str) -> np.ndarray:
    """A float array of real numbers where NaN marks a value not measured (a marker not seen,
    a reaction component not measured); any other bad entry is refused as
    :func:`V.real_array` refuses it."""
    if type(raw) is np.ndarray and raw.dtype.kind == "f":  # (a masked array: refused below)
        unmeasured = np.isnan(raw)
        a = V.real_array(np.where(unmeasured, 0.0, raw), field, what=what)
        a[unmeasured] = np.nan
        return a
    return V.real_array(raw, field, what=what)


def _row_indices(rows: object, n: int) -> list[int]:
    """0-based row indices of a dataset of ``n`` rows (an iterable of integers), each named
    by its position when it is not one."""
    if isinstance(rows, (str, bytes, Mapping)) or not isinstance(rows, Iterable):
        raise _fail("rows", type(rows).__name__, "must be a list of 0-based row indices")
    return [
        V.integer(r, f"rows[{i}]", minimum=0, maximum=max(n - 1, 0)) for i, r in enumerate(rows)
    ]


def _readonly(a: np.ndarray | None) -> np.ndarray | None:
    if a is not None:
        a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False, repr=False)
class Dataset:
    """Measured (or synthetic) static equilibria, SI, one row per sample (m rows).

    pressures: (m, c) gauge pressures, Pa.     tip_position: (m, 3) tip position, m (world),
    or None when the dataset has markers instead.
    tensions: (m, k) tendon tensions, N (>= 0), or None: every tendon slack.
    tip_rotation: (m, 3, 3) [d1 d2 d3] of the tip (world) or None.
    base_force, base_moment: (m, 3) force (N) and moment about the base point (N m) that the
    rod exerts on its mount, world frame, or None (``StaticSolution.base_force`` convention).
    experiment: (m,) ids (int64 or str) or None.  mounting: (m,) str or None.
    time: (m,) s or None.  metadata: dict; ``metadata["synthetic"]`` is True for data made by
    :func:`synthesize_dataset` (with the design, noise and seed).  source: file read or None.
    first_line: for a CSV source, the file line of the first row (messages name rows by
    line, as a text editor counts them); None otherwise.
    extra: the result columns of a table softrod wrote (``converged``, ``iterations``,
    ``sigma_ext``, ...), by column name as written, (m,) each, described in
    ``metadata["columns"]``; empty for measurements.
    markers: (m, K, 3) measured marker positions, m (world), NaN where a marker was not
    seen, or None. marker_s: (K,) where each marker sits, reference arc length from the
    base (m); marker_offset: (K, 3) its offset in the cross-section frame (d1, d2, d3) at
    s, m ((K, 2) is read as (d1, d2)). marker_body: (K,) int, the body each marker sits
    on in a system of rods (:func:`softrod.calibrate_system`): -1 the platform (offset in
    the platform frame, s = 0), i >= 0 rod i (s and offset on that rod); None: the
    markers sit on one design's rod.
    tip_reaction_force, tip_reaction_moment: (m, 3) the measured wrench a held tip's
    constraint applies to the tip (N, N m; world frame, the blocked force), NaN where a
    component was not measured, or None.
    A dataset needs tip positions, markers, a reaction, or a combination.

    Arrays are read-only. Use :func:`load_dataset` to read a file, :meth:`to_frame` and
    :func:`write_dataset` to write one.
    """

    pressures: np.ndarray
    tip_position: np.ndarray | None = None
    tensions: np.ndarray | None = None
    tip_rotation: np.ndarray | None = None
    base_force: np.ndarray | None = None
    base_moment: np.ndarray | None = None
    experiment: np.ndarray | None = None
    mounting: np.ndarray | None = None
    time: np.ndarray | None = None
    metadata: dict = field(default_factory=lambda: {"synthetic": False})
    source: Path | None = None
    first_line: int | None = None
    extra: Mapping[str, np.ndarray] = field(default_factory=dict)
    markers: np.ndarray | None = None
    marker_s: np.ndarray | None = None
    marker_offset: np.ndarray | None = None
    tip_reaction_force: np.ndarray | None = None
    tip_reaction_moment: np.ndarray | None = None
    marker_body: np.ndarray | None = None

    def __post_init__(self):
        set_ = object.__setattr__
        p = V.real_array(self.pressures, "pressures", what="gauge pressures (Pa)")
        # Every row needs an input: pressures, or tensions for a design without chambers.
        least = 0 if self.tensions is not None else 1
        if p.ndim != 2 or p.shape[1] < least or p.shape[1] > V.MAX_CHANNELS:
            raise _fail(
                "pressures",
                f"shape {p.shape}",
                "must be an (m, channels) array in Pa (channels >= 1 unless tensions are given)",
            )
        m = p.shape[0]
        set_(self, "pressures", _readonly(p))
        if self.tensions is not None:
            t = V.real_array(self.tensions, "tensions", what="tendon tensions (N)")
            if t.ndim != 2 or t.shape[0] != m or not 1 <= t.shape[1] <= V.MAX_CHANNELS:
                raise _fail(
                    "tensions", f"shape {t.shape}", f"must be an (m, tendons) array in N (m = {m})"
                )
            bad = np.flatnonzero(~(np.isfinite(t) & (t >= 0)).all(axis=1))
            if bad.size:
                raise _fail(
                    "tensions",
                    "negative or non-finite",
                    f"tendon tensions must be finite and >= 0 N (rows {_runs(bad)})",
                )
            set_(self, "tensions", _readonly(t))
        shapes = {
            "tip_position": (m, 3),
            "tip_rotation": (m, 3, 3),
            "base_force": (m, 3),
            "base_moment": (m, 3),
            "time": (m,),
        }
        for name, shape in shapes.items():
            value = getattr(self, name)
            if value is None:
                if name == "tip_position" and self.markers is None and not self._reactions:
                    raise _fail(
                        name,
                        None,
                        "is required (an (m, 3) array in m) unless markers or a tip reaction "
                        "(tip_reaction_force, tip_reaction_moment) are given",
                    )
                continue
            a = V.real_array(value, name)
            if a.shape != shape:
                raise _fail(name, f"shape {a.shape}", f"must have shape {shape} (m = {m} rows)")
            set_(self, name, _readonly(a))
        for name in ("pressures", "tip_position", "tip_rotation", "base_force", "base_moment"):
            a = getattr(self, name)
            if a is not None and not np.isfinite(a).all():
                bad = np.flatnonzero(~np.isfinite(a.reshape(m, -1)).all(axis=1))
                raise _fail(name, "non-finite", f"must be finite (rows {_runs(bad)})")
        self._check_reactions(m)
        self._check_markers(m)
        if self.tip_rotation is not None and m:
            r = self.tip_rotation
            err = np.abs(np.einsum("kji,kjl->kil", r, r) - np.eye(3)).max(axis=(1, 2))
            det = np.linalg.det(r)
            bad = np.flatnonzero((err > _ROTATION_TOLERANCE) | (det < 0))
            if bad.size:
                raise _fail(
                    "tip_rotation",
                    f"rows {_runs(bad)}",
                    f"must be rotation matrices (orthonormal within {_ROTATION_TOLERANCE:g}, "
                    "det +1)",
                )
        for name in _LABELS:
            value = getattr(self, name)
            if value is not None:
                a = _labels(np.asarray(value), name, ints=name == "experiment")
                if a.shape != (m,):
                    raise _fail(name, f"shape {a.shape}", f"must have shape ({m},)")
                set_(self, name, _readonly(a))
        set_(self, "metadata", _checked_metadata(self.metadata))
        if self.source is not None:
            set_(self, "source", Path(self.source))
        if not isinstance(self.extra, Mapping):
            raise _fail("extra", type(self.extra).__name__, "must map column names to arrays")
        extra = {}
        for name, values in self.extra.items():
            if not isinstance(name, str) or _base(name) is not None:
                raise _fail(
                    "extra", name, "result columns need names outside the schema (a string)"
                )
            a = np.array(values)  # a copy; an object array of lists stays 1-D
            if a.shape != (m,):
                raise _fail(f"extra.{name}", f"shape {a.shape}", f"must have shape ({m},)")
            extra[name] = _readonly(a)
        set_(self, "extra", extra)

    def _check_markers(self, m: int) -> None:
        set_ = object.__setattr__
        if self.markers is None:
            for name in ("marker_s", "marker_offset", "marker_body"):
                if getattr(self, name) is not None:
                    raise _fail(name, "given", "needs markers (the measured marker positions)")
            return
        a = _real_or_nan(self.markers, "markers", "marker positions (m)")
        if a.ndim != 3 or a.shape[0] != m or a.shape[2] != 3 or not 1 <= a.shape[1] <= MAX_MARKERS:
            raise _fail(
                "markers",
                f"shape {a.shape}",
                f"must be an (m, K, 3) array in m with m = {m} rows and 1 <= K <= {MAX_MARKERS}",
            )
        k = a.shape[1]
        seen = np.isfinite(a)  # (_real_or_nan has refused inf: NaN is "not seen")
        partial = seen.any(axis=2) & ~seen.all(axis=2)
        if partial.any():
            row, mk = np.argwhere(partial)[0]
            raise _fail(
                f"markers[{row}, {mk}]",
                a[row, mk].tolist(),
                "a marker is seen (x, y, z all given) or not (all three NaN)",
            )
        if self.tip_position is None:
            empty = ~seen.all(axis=2).any(axis=1)
            for r in (self.tip_reaction_force, self.tip_reaction_moment):
                if r is not None:
                    empty &= ~np.isfinite(r).any(axis=1)
            if empty.any():
                raise _fail(
                    "markers",
                    f"no marker seen in rows {_runs(np.flatnonzero(empty))}",
                    "without tip columns every row needs at least one seen marker (or a "
                    "measured reaction component)",
                )
        if self.marker_s is None or self.marker_offset is None:
            missing = "marker_s" if self.marker_s is None else "marker_offset"
            raise _fail(
                missing,
                None,
                "say where each marker sits on the body: its arc length s from the base and "
                'its offset in the cross-section frame (the metadata block\'s "markers" entry '
                "in a file)",
            )
        s = V.real_array(self.marker_s, "marker_s", what="arc lengths (m)")
        if s.shape != (k,) or not np.isfinite(s).all() or (s < 0).any():
            raise _fail("marker_s", s.tolist(), f"must be {k} finite arc lengths >= 0 m")
        o = V.real_array(self.marker_offset, "marker_offset", what="offsets (m)")
        if o.ndim != 2 or o.shape[0] != k or o.shape[1] not in (2, 3) or not np.isfinite(o).all():
            raise _fail(
                "marker_offset",
                f"shape {o.shape}",
                f"must be a finite ({k}, 2) or ({k}, 3) array of offsets in m (d1, d2[, d3])",
            )
        if o.shape[1] == 2:
            o = np.column_stack([o, np.zeros(k)])
        if self.marker_body is not None:
            body = np.asarray(self.marker_body)
            if (
                body.shape != (k,)
                or not np.issubdtype(body.dtype, np.integer)
                or (body < PLATFORM_BODY).any()
            ):
                raise _fail(
                    "marker_body",
                    body.tolist(),
                    f"must be {k} integers: -1 for a marker on the platform, i >= 0 for one "
                    "on rod i",
                )
            on_platform = body == PLATFORM_BODY
            if (s[on_platform] != 0).any():
                j = int(np.flatnonzero(on_platform & (s != 0))[0])
                raise _fail(
                    f"marker_s[{j}]",
                    float(s[j]),
                    "a marker on the platform has no arc length: give 0 (its offset is in "
                    "the platform frame)",
                )
            set_(self, "marker_body", _readonly(body.astype(np.int64)))
        set_(self, "markers", _readonly(a))
        set_(self, "marker_s", _readonly(s))
        set_(self, "marker_offset", _readonly(np.ascontiguousarray(o)))

    @property
    def _reactions(self) -> bool:
        return self.tip_reaction_force is not None or self.tip_reaction_moment is not None

    def _check_reactions(self, m: int) -> None:
        """Each reaction (m, 3), finite numbers or NaN (a component not measured); without
        tip columns and markers every row needs a measured component."""
        for name, unit in (("tip_reaction_force", "N"), ("tip_reaction_moment", "N m")):
            if getattr(self, name) is None:
                continue
            a = _real_or_nan(getattr(self, name), name, f"reaction components ({unit})")
            if a.shape != (m, 3):
                raise _fail(
                    name,
                    f"shape {a.shape}",
                    f"must be an (m, 3) array in {unit} (m = {m} rows), NaN where a component "
                    "was not measured",
                )
            object.__setattr__(self, name, _readonly(a))
        if self._reactions and self.tip_position is None and self.markers is None:
            measured = np.zeros(m, dtype=bool)
            for r in (self.tip_reaction_force, self.tip_reaction_moment):
                if r is not None:
                    measured |= np.isfinite(r).any(axis=1)
            if not measured.all():
                force = self.tip_reaction_force is not None
                raise _fail(
                    "tip_reaction_force" if force else "tip_reaction_moment",
                    f"nothing measured in rows {_runs(np.flatnonzero(~measured))}",
                    "without tip columns and markers every row needs a measured reaction component",
                )

    def require_tip(self, what: str) -> np.ndarray:
        """The tip positions, or an InputError saying that ``what`` needs them."""
        if self.tip_position is None:
            raise _fail(
                "tip_position",
                None,
                f"{what} needs the tip position (tip_x, tip_y, tip_z); this dataset has "
                "none (markers or a tip reaction only)",
            )
        return self.tip_position

    @property
    def n_markers(self) -> int:
        return 0 if self.markers is None else self.markers.shape[1]

    def __len__(self) -> int:
        return self.pressures.shape[0]

    def rows_text(self, rows: Iterable[int]) -> str:
        """Rows (0-based indices) as a message names them: by file line for a CSV source
        ("d.csv lines 3-5, 9"), by 0-based row for a Parquet source, else by index."""
        rows = sorted(_row_indices(rows, len(self)))
        many = len(rows) > 1
        if self.source is not None and self.first_line is not None:
            noun = "lines" if many else "line"
            return f"{self.source.name} {noun} {_runs(r + self.first_line for r in rows)}"
        prefix = f"{self.source.name} " if self.source is not None else ""
        return f"{prefix}{'rows' if many else 'row'} {_runs(rows)} (0-based)"

    def __repr__(self) -> str:
        parts = [f"{len(self)} rows", f"{self.n_channels} channels"]
        if self.tensions is not None:
            parts.append(f"{self.n_tendons} tendon channels")
        if self.experiment is not None:
            parts.append(f"experiments {list(self.experiments)}")
        optional = [
            n
            for n in (
                "tip_rotation",
                "base_force",
                "base_moment",
                "time",
                "tip_reaction_force",
                "tip_reaction_moment",
            )
            if getattr(self, n) is not None
        ]
        if self.markers is not None:
            optional.append(f"{self.n_markers} markers")
        if self.tip_position is None:
            parts.append("no tip")
        if optional:
            parts.append("with " + ", ".join(optional))
        if self.extra:
            shown = list(self.extra)[:6]
            more = len(self.extra) - len(shown)
            parts.append(
                "result columns " + ", ".join(shown) + (f" and {more} more" if more > 0 else "")
            )
        if self.synthetic:
            made = self.metadata.get("design") or (
                f"system {self.metadata['system']}" if "system" in self.metadata else "?"
            )
            parts.append(f"SYNTHETIC from {made}")
        if self.source is not None:
            parts.append(f"source={str(self.source)!r}")
        return f"Dataset({'; '.join(parts)})"

    @property
    def n_channels(self) -> int:
        """Number of pressure channels (columns of ``pressures``)."""
        return self.pressures.shape[1]

    @property
    def n_tendons(self) -> int:
        """Number of tendon tension channels (columns of ``tensions``; 0 without)."""
        return 0 if self.tensions is None else self.tensions.shape[1]

    def require_slack(self, what: str) -> None:
        """Refuse a dataset with a tendon under tension in an entry point that solves with
        slack tendons only: never a silent answer for other inputs than the measured ones."""
        if self.tensions is not None and np.any(self.tensions != 0):
            raise _fail(
                "tensions",
                f"{self.n_tendons} tension channel(s)",
                f"{what} solves with slack tendons; the dataset records tendon tensions "
                "(t0, t1, ... columns), which it cannot use",
            )

    @property
    def synthetic(self) -> bool:
        """True for data generated by the model (not measurements)."""
        return bool(self.metadata.get("synthetic", False))

    @property
    def experiments(self) -> tuple:
        """The distinct experiment ids in order of first appearance (empty if none)."""
        if self.experiment is None:
            return ()
        _, first = np.unique(self.experiment, return_index=True)
        return tuple(self.experiment[i].item() for i in sorted(first))

    def subset(self, rows: ArrayLike) -> Dataset:
        """The rows chosen by a boolean mask of length m or by integer indices (in that order)."""
        a = np.asarray(rows)
        m = len(self)
        if a.dtype == bool:
            if a.shape != (m,):
                raise _fail(
                    "rows", f"mask of shape {a.shape}", f"a boolean mask needs shape ({m},)"
                )
            idx = np.flatnonzero(a)
        elif a.size == 0:
            idx = np.zeros(0, dtype=int)
        elif np.issubdtype(a.dtype, np.integer) and a.ndim == 1:
            if a.min() < -m or a.max() >= m:
                raise _fail("rows", f"indices {a.min()}..{a.max()}", f"must lie in [-{m}, {m})")
            idx = a
        else:
            raise _fail("rows", rows, "must be a boolean mask or a 1-d array of integer indices")

        def take(x):
            return None if x is None else x[idx]

        return Dataset(
            pressures=self.pressures[idx],
            tensions=take(self.tensions),
            tip_position=take(self.tip_position),
            tip_rotation=take(self.tip_rotation),
            base_force=take(self.base_force),
            base_moment=take(self.base_moment),
            experiment=take(self.experiment),
            mounting=take(self.mounting),
            time=take(self.time),
            metadata=dict(self.metadata),
            source=self.source,
            extra={name: values[idx] for name, values in self.extra.items()},
            markers=take(self.markers),
            marker_s=self.marker_s,
            marker_offset=self.marker_offset,
            tip_reaction_force=take(self.tip_reaction_force),
            tip_reaction_moment=take(self.tip_reaction_moment),
            marker_body=self.marker_body,
        )

    def split(self, by: str = "experiment", *, test: Any) -> tuple[Dataset, Dataset]:
        """(train, test): the rows whose ``by`` column ("experiment" or "mounting") holds one
        of the ``test`` ids go to test, the others to train. Unknown ids are an error."""
        if by not in _LABELS:
            raise _fail("by", by, f"must be one of {', '.join(_LABELS)}")
        labels = getattr(self, by)
        if labels is None:
            raise _fail("by", by, f"the dataset has no {by} column to split by")
        if isinstance(test, (str, int, np.integer)) and not isinstance(test, (bool, np.bool_)):
            ids = [test]
        elif isinstance(test, (list, tuple, set, frozenset, np.ndarray, range)):
            ids = list(np.asarray(test).ravel()) if isinstance(test, np.ndarray) else list(test)
        else:
            raise _fail("test", type(test).__name__, f"must be a {by} id or a list of them")
        if not ids:
            raise _fail("test", test, f"name at least one {by} id")
        known = self.experiments if by == "experiment" else tuple(dict.fromkeys(labels.tolist()))
        unknown = [t for t in ids if not any(_same_id(t, k) for k in known)]
        if unknown:
            raise _fail(
                "test",
                unknown,
                f"unknown {by} id(s); the dataset has {', '.join(repr(k) for k in known)}",
            )
        mask = np.zeros(len(self), dtype=bool)
        for t in ids:
            mask |= labels == t
        if mask.all():
            raise _fail("test", ids, f"takes every {by}: nothing would be left to train on")
        return self.subset(~mask), self.subset(mask)

    def to_frame(self, units: Mapping[str, str] | str | None = None) -> pd.DataFrame:
        """The dataset as a DataFrame of the schema, units in the column names.

        ``units`` maps a kind ("pressure", "length", "force", "moment", "time") to a unit;
        the others keep :data:`DEFAULT_UNITS` (kPa, mm, N, Nmm = N*mm, s); ``units="SI"``
        writes Pa, m, N, Nm and s. The orientation is written as a unit quaternion
        (w >= 0). The result columns of :attr:`extra` follow, as they were read.
        ``frame.attrs["softrod.metadata"]`` holds the metadata, so ``load_dataset(frame)``
        keeps the synthetic flag and the result columns.
        """
        described = dict(self.metadata.get("columns") or {})
        return schema_frame(
            pressures=self.pressures,
            tensions=self.tensions,
            tip_position=self.tip_position,
            tip_rotation=self.tip_rotation,
            base_force=self.base_force,
            base_moment=self.base_moment,
            time=self.time,
            experiment=self.experiment,
            mounting=self.mounting,
            markers=self.markers,
            marker_s=self.marker_s,
            marker_offset=self.marker_offset,
            marker_body=self.marker_body,
            tip_reaction_force=self.tip_reaction_force,
            tip_reaction_moment=self.tip_reaction_moment,
            extras=[Extra(n, v, str(described.get(n, ""))) for n, v in self.extra.items()],
            units=units,
            metadata=self.metadata,
        )


def _same_id(a, b) -> bool:
    """Equal ids of the same kind: 1 and np.int64(1) match, 1 and "1" (or True) do not."""
    if isinstance(a, (bool, np.bool_)) or isinstance(b, (bool, np.bool_)):
        return False
    if isinstance(a, (int, np.integer)) and isinstance(b, (int, np.integer)):
        return int(a) == int(b)
    return isinstance(a, str) and isinstance(b, str) and a == b


def _labels(a: np.ndarray, name: str, ints: bool) -> np.ndarray:
    """Experiment ids as int64 when all are integers, else str; mounting always str."""
    if ints and a.dtype.kind in "iuf":
        if a.dtype.kind == "f" and not (np.all(np.isfinite(a)) and np.all(a == np.round(a))):
            raise _fail(name, "non-integer numbers", "ids must be integers or strings")
        big = np.flatnonzero(np.abs(a.astype(float)) > V.MAX_ABS_INT)
        if big.size:
            raise _fail(name, a[big[0]].item(), _ID_RULE)
        return a.astype(np.int64)
    if a.dtype.kind == "b":
        raise _fail(name, "booleans", "must be integers or strings")
    values = [v.item() if isinstance(v, np.generic) else v for v in a.tolist()]
    if ints and all(isinstance(v, int) and not isinstance(v, bool) for v in values):
        return _integer_ids(values, name)
    if (
        ints
        and values
        and all(isinstance(v, str) and re.fullmatch(r"-?(0|[1-9][0-9]*)", v) for v in values)
    ):
        return _integer_ids([int(v) for v in values], name)
    return np.asarray([str(v).strip() for v in values], dtype=str)


# Integer ids beyond 2^53 are not exact as floats (the type a CSV reader may give them).
_ID_RULE = f"integer ids must lie within +-2^53 ({V.MAX_ABS_INT})"


def _integer_ids(values: list, name: str) -> np.ndarray:
    """Python integer ids as int64, each within +-2^53."""
    big = [v for v in values if abs(v) > V.MAX_ABS_INT]
    if big:
        raise _fail(name, big[0], _ID_RULE)
    return np.asarray(values, dtype=np.int64)


# --- locating rows in messages ----------------------------------------------------------------


def _runs(idx: Iterable[int], fmt: Callable[[int], int | str] = lambda i: i) -> str:
    """'3, 7-9, 12' (consecutive runs compressed), at most _MAX_LISTED items then 'and N more'."""
    idx = sorted(int(i) for i in idx)
    items: list[str] = []
    i = 0
    while i < len(idx):
        j = i
        while j + 1 < len(idx) and idx[j + 1] == idx[j] + 1:
            j += 1
        items.append(f"{fmt(idx[i])}" if j == i else f"{fmt(idx[i])}-{fmt(idx[j])}")
        i = j + 1
    more = len(items) - _MAX_LISTED
    text = ", ".join(items[:_MAX_LISTED])
    return text + (f" and {more} more" if more > 0 else "")


@dataclass(frozen=True)
class _Where:
    """How rows are named in messages: CSV lines, Parquet rows or DataFrame index labels."""

    noun: str  # "line", "row", "index"
    first: int = 0  # CSV: line number of the first data row
    labels: tuple | None = None  # DataFrame index labels

    def __call__(self, rows: Iterable[int]) -> str:
        rows = list(rows)
        noun = (
            self.noun
            if len(rows) == 1
            else {"index": "index labels"}.get(self.noun, self.noun + "s")
        )
        if self.labels is not None:
            shown = ", ".join(repr(self.labels[i]) for i in rows[:_MAX_LISTED])
            more = len(rows) - _MAX_LISTED
            return f"{noun} {shown}" + (f" and {more} more" if more > 0 else "")
        return f"{noun} {_runs(rows, lambda i: i + self.first)}"


@dataclass(frozen=True)
class _KeptRows:
    """Rows named as in the file after some rows were dropped (``kept``: the original index
    of each remaining row)."""

    where: _Where
    kept: np.ndarray

    @property
    def labels(self):
        return None

    def __call__(self, rows: Iterable[int]) -> str:
        return self.where([int(self.kept[i]) for i in rows])


# --- loading -------------------------------------------------------------------------------------


def _read_csv(path: Path) -> tuple[pd.DataFrame, dict, dict, _Where]:
    text = read_text_file(path)
    lines = text.splitlines()
    units: dict = {}
    meta: dict = {}
    n_pre = 0
    for n_pre, line in enumerate(lines):  # noqa: B007 - n_pre is the header's index after
        stripped = line.strip()
        if stripped and not stripped.startswith("#"):
            break
        entry = re.match(r"^#\s*(units|metadata)\s*:(.*)$", stripped)
        if entry:
            key, body = entry.group(1), entry.group(2)
            value = _json_block(body, key, f"line {n_pre + 1}")
            target = units if key == "units" else meta
            if target:
                raise _fail(key, value, f"line {n_pre + 1}: the {key} block is given twice")
            target.update(value)
    else:
        raise _fail("file", str(path), "has no header line (column names) after the comments")
    header_line = n_pre + 1  # 1-based
    try:
        raw_names = next(csv.reader([lines[n_pre]]))
    except csv.Error as exc:
        raise _fail("file", path.name, f"line {header_line}: not a CSV header ({exc})") from None
    names = [n.strip() for n in raw_names]  # "p0_kPa, tip_x_mm" is read like "p0_kPa,tip_x_mm"
    _check_duplicates(names)
    labels = [r for r, n in zip(raw_names, names, strict=True) if _base(n) in _LABELS]
    body = "\n".join(lines[n_pre:]) + "\n"
    try:
        df = pd.read_csv(
            io.StringIO(body),
            skip_blank_lines=False,
            skipinitialspace=True,
            # Ids stay text ("007" is not 7); keys as pandas may spell the header name.
            dtype=dict.fromkeys([*labels, *(r.lstrip() for r in labels)], str),
        )
    except (pd.errors.ParserError, ValueError, csv.Error) as exc:
        ragged = re.search(r"Expected (\d+) fields in line (\d+), saw (\d+)", str(exc))
        if ragged:
            want, line, saw = (int(g) for g in ragged.groups())
            raise _fail(
                f"line {line + n_pre}",
                f"{saw} values",
                f"the header has {want} columns; every row needs one value per column "
                "(quote a value that contains a comma)",
            ) from None
        raise _fail("file", path.name, f"is not a valid CSV table: {exc}") from None
    df.columns = names
    # Blank lines at the end of a file are not rows.
    empty = df.isna().all(axis=1).to_numpy()
    n = len(df)
    while n and empty[n - 1]:
        n -= 1
    df = df.iloc[:n]
    return df, units, meta, _Where("line", first=header_line + 1)


def _read_parquet(path: Path) -> tuple[pd.DataFrame, dict, dict, _Where]:
    import pyarrow.parquet as pq

    try:
        table = pq.read_table(path)
    except Exception as exc:  # pyarrow raises its own error types for broken files
        raise _fail("file", str(path), f"is not a readable Parquet file: {exc}") from None
    _check_duplicates(table.column_names)
    kv = table.schema.metadata or {}
    blocks = []
    for key in (b"softrod.units", b"softrod.metadata"):
        raw = kv.get(key)
        if raw is None:
            blocks.append({})
            continue
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise _fail(key.decode(), raw[:80], f"Parquet metadata is not UTF-8 ({exc})") from None
        blocks.append(_json_block(text, key.decode(), "Parquet metadata"))
    if table.num_rows > V.MAX_ROWS:
        raise _fail("rows", table.num_rows, f"too many rows: at most {V.MAX_ROWS:,}")
    try:
        frame = table.to_pandas()
    except Exception as exc:  # pyarrow raises its own error types for unconvertible columns
        raise _fail("file", str(path), f"has columns pandas cannot read: {exc}") from None
    return frame, blocks[0], blocks[1], _Where("row")


def _check_duplicates(names: list) -> None:
    seen: dict[str, int] = {}
    for n in names:
        seen[n] = seen.get(n, 0) + 1
    dup = [n for n, c in seen.items() if c > 1]
    if dup:
        raise _fail("columns", dup, "duplicate column name(s): each column may appear once")


def load_dataset(
    source: PathLike | pd.DataFrame | Dataset,
    *,
    n_channels: int | None = None,
    design: DesignLike | None = None,
    units: Mapping[str, str] | None = None,
    extra: str = "error",
    unconverged: str = "error",
) -> Dataset:
    """Read and validate a dataset from a CSV or Parquet file or a pandas DataFrame.

    ``source``: a path (``.csv`` or ``.parquet``), the name of a bundled example dataset
    (``"spa130_synthetic"``, see :func:`example_datasets`), a DataFrame (units in the column
    names, in ``units`` or in ``frame.attrs["softrod.units"]``) or a Dataset (returned as
    is). Every table softrod writes (sweeps, trajectories, comparisons, identifications,
    predictions) loads too: its result columns, declared in its metadata, come back in
    :attr:`Dataset.extra`.
    ``n_channels`` / ``design``: the pressure channels the data must have (a Design or a
    design name gives ``design.n_channels``). ``units``: a units block (column -> unit) in
    addition to the file's. ``extra``: "error" (default: an unknown column is a typo until
    shown otherwise) or "ignore". ``unconverged``: what to do with the rows of a solver's
    table whose ``converged`` is False (they have no tip position): "error" (default) or
    "drop". Values come back SI. Raises :class:`InputError` naming the column, the value, the
    rule and the rows (CSV line numbers as a text editor shows them).
    """
    if isinstance(source, Dataset):
        want, what = _expected_channels(n_channels, design)
        if want is not None and source.n_channels != want:
            raise _fail(
                "pressures",
                f"shape {source.pressures.shape}",
                f"the data has {source.n_channels} pressure channel(s) but {what}",
            )
        if design is not None and source.tensions is not None:
            d = load_design(design)
            if source.n_tendons != d.n_tendons:
                raise _fail(
                    "tensions",
                    f"shape {source.tensions.shape}",
                    f"the data has {source.n_tendons} tendon tension channel(s) but design "
                    f"{d.name!r} has {d.n_tendons}",
                )
        return source
    V.choice(extra, ("error", "ignore"), "extra")
    V.choice(unconverged, ("error", "drop"), "unconverged")
    if units is not None and not isinstance(units, Mapping):
        raise _fail("units", units, "must be a mapping {column: unit string}")
    path = None
    if isinstance(source, pd.DataFrame):
        names = list(source.columns)
        bad = [n for n in names if not isinstance(n, str)]
        if bad:
            raise _fail("columns", bad, "column names must be strings")
        _check_duplicates(names)
        df = source.reset_index(drop=True)
        file_units = dict(source.attrs.get("softrod.units", {}))
        meta = dict(source.attrs.get("softrod.metadata", {}))
        where = _Where("index", labels=tuple(source.index))
    elif isinstance(source, (str, os.PathLike)):
        path = Path(source)
        if path.suffix == "" and not _exists(path) and str(source) in example_datasets():
            path = example_dataset_path(str(source))
        if path.suffix.lower() not in TABLE_SUFFIXES:
            if path.suffix == "" and not _exists(path):
                raise _fail(
                    "path",
                    str(path),
                    "no such file or bundled example dataset (bundled: "
                    f"{', '.join(example_datasets())}; files end in .csv or .parquet)",
                )
            check_table_path(path)  # raises with the list of formats
        if not _is_file(path):
            raise _fail("path", str(path), "no such file")
        reader = _read_csv if path.suffix.lower() == ".csv" else _read_parquet
        try:
            df, file_units, meta, where = reader(path)
        except InputError as exc:
            exc.args = (f"{path.name}: {exc.args[0]}",)
            raise
    else:
        raise _fail(
            "source",
            type(source).__name__,
            "must be a .csv/.parquet path, a DataFrame or a Dataset",
        )
    try:
        data = _from_frame(
            df,
            file_units,
            dict(units or {}),
            meta,
            where,
            path,
            n_channels,
            design,
            extra,
            unconverged,
        )
    except InputError as exc:
        if path is not None:
            exc.args = (f"{path.name}: {exc.args[0]}",)
        raise
    if path is not None and where.noun == "line" and len(data) == len(df):
        # Rows are the file's lines in order (none dropped): name them by line.
        object.__setattr__(data, "first_line", where.first)
    return data


def _number_column(raw: pd.Series, name: str, where, *, missing_ok: bool = False) -> np.ndarray:
    """A table column as finite floats, or an InputError naming the column, the value and
    the rows: text that is not a number, an empty cell, or a number beyond the float range
    (an integer with hundreds of digits; converted one by one, as pandas would overflow).
    ``missing_ok``: empty cells are NaN (a marker not seen in that row)."""
    _check_dtype(raw, name)
    try:
        num = pd.to_numeric(raw, errors="coerce")
    except OverflowError:
        num = pd.Series([_number_or_nan(v) for v in raw.array], index=raw.index, dtype=float)
    missing = raw.isna().to_numpy()
    empty = np.flatnonzero(missing)
    if empty.size and not missing_ok:
        raise _fail(name, "empty/NaN", f"empty or NaN value at {where(empty)}")
    text = np.flatnonzero(num.isna().to_numpy() & ~missing)
    if text.size:
        raise _fail(name, raw.iloc[text[0]], f"not a number at {where(text)}")
    a = num.to_numpy(dtype=float)
    bad = np.flatnonzero(~np.isfinite(a) & ~missing)
    if bad.size:
        value = raw.iloc[bad[0]]
        if isinstance(value, int) and abs(value) >= 10**20:  # beyond the float range
            value = f"{str(value)[:20]}... ({len(str(value))} digits)"
        else:
            value = a[bad[0]].item()
        raise _fail(name, value, f"must be finite, at {where(bad)}")
    return a


def _number_or_nan(v) -> float:
    """One cell as a float: beyond the float range it is inf (refused by the caller), text
    that is not a number NaN."""
    if v is None:
        return math.nan
    try:
        return float(v)
    except OverflowError:
        return math.inf if v > 0 else -math.inf
    except (TypeError, ValueError):
        return math.nan


def _check_dtype(column: pd.Series, name: str) -> None:
    """A number column holds numbers (or text to read as numbers), never dates, durations,
    booleans or complex values, which pandas would turn into numbers silently (a timestamp
    would become 1.58e18 Pa)."""
    kind = getattr(column.dtype, "kind", "O")
    what = {"M": "dates/times", "m": "durations", "b": "booleans", "c": "complex numbers"}
    if kind in what:
        raise _fail(name, str(column.dtype), f"must hold numbers, not {what[kind]}")
    if kind == "O":
        bad = next(
            (
                v
                for v in column.array
                if isinstance(v, (bool, np.bool_, complex, bytes))
                or (not isinstance(v, (str, int, float, np.number)) and v is not None)
            ),
            None,
        )
        if bad is not None:
            raise _fail(name, bad, f"must hold numbers, not {type(bad).__name__}")


def _expected_channels(n_channels, design) -> tuple[int | None, str]:
    want, what = None, ""
    if n_channels is not None:
        V.integer(n_channels, "n_channels", minimum=1, maximum=V.MAX_CHANNELS)
        want, what = int(n_channels), f"n_channels = {int(n_channels)}"
    if design is not None:
        d = load_design(design)
        if want is not None and want != d.n_channels:
            raise _fail(
                "n_channels",
                n_channels,
                f"disagrees with design {d.name!r}, which has {d.n_channels} channels",
            )
        want, what = d.n_channels, f"design {d.name!r} has {d.n_channels}"
    return want, what


def _from_frame(
    df, file_units, call_units, meta, where, path, n_channels, design, extra, unconverged
) -> Dataset:
    names = [str(c) for c in df.columns]
    # Units block: the file's and the caller's, a column in at most one of them.
    for label, block in (("units", file_units), ("units (argument)", call_units)):
        for k, v in block.items():
            if not isinstance(k, str) or not isinstance(v, str):
                raise _fail(f"{label}.{k}", v, "must map a column name to a unit string")
    both = sorted(set(file_units) & set(call_units))
    if both:
        raise _fail("units", both, "given both in the file's units block and in units=")
    block = {**file_units, **call_units}
    unused = sorted(set(block) - set(names))
    if unused:
        raise _fail(
            f"units.{unused[0]}", block[unused[0]], f"names no column (columns: {', '.join(names)})"
        )

    # Result columns a softrod writer declared in the metadata (name -> description).
    declared = meta.get("columns") or {}
    if not isinstance(declared, Mapping):
        raise _fail("metadata.columns", declared, "must map column names to descriptions")
    extras = [n for n in names if n in declared and _NAME.match(n) is None]

    # Column names -> base name and SI factor.
    columns: dict[str, tuple[str, float | None]] = {}  # base -> (column, factor)
    unknown = []
    for name in names:
        if name in extras:
            continue
        m = _NAME.match(name)
        if m is None:
            unknown.append(name)
            continue
        base, unit = m["base"], m["unit"]
        if base[0] == "p" or _TENSION.match(base):
            channel_index(base, name)
        kind = _kind(base)
        if unit is not None and name in block:
            raise _fail(
                name, block[name], "unit given twice: in the column name and in the units block"
            )
        if unit is None:
            unit = block.get(name)
        if kind is None:
            if unit is not None:
                what = "an identifier" if base in _LABELS else "dimensionless"
                raise _fail(
                    name, unit, f"{base} is {what} and takes no unit; name the column {base!r}"
                )
            factor = None
        elif unit is None:
            raise _fail(
                name,
                "no unit",
                f"a {kind} column needs a unit: in its name ({base}_{DEFAULT_UNITS[kind]}) "
                f'or in the units block (# units: {{"{base}": "{DEFAULT_UNITS[kind]}"}})',
            )
        else:
            factor = _unit_factor(unit, kind, name)
        if base in columns:
            raise _fail("columns", [columns[base][0], name], f"both give {base}: keep one")
        columns[base] = (name, factor)
    if unknown and extra == "error":
        raise _fail(
            "columns",
            unknown,
            f"unknown column(s); known names: {_KNOWN}, each <name>_<unit> for quantities with "
            "a unit (pass extra='ignore' to skip unknown columns)",
        )

    # Required columns and complete groups.
    channels = sorted(int(b[1:]) for b in columns if b[0] == "p")
    tendons = sorted(int(t[1]) for b in columns if (t := _TENSION.match(b)))
    marker_ids = sorted({int(m[1]) for b in columns if (m := _MARKER.match(b))})
    missing = [b for b in _TIP if b not in columns]
    reactions = any(b in columns for b in _REACTION_FORCE + _REACTION_MOMENT)
    if (marker_ids or reactions) and len(missing) == len(_TIP):
        missing = []  # markers or a reaction instead of the tip
    for k in marker_ids:
        missing += [f"marker{k}_{a}" for a in _XYZ if f"marker{k}_{a}" not in columns]
    if not channels and not tendons:
        missing.insert(0, "p0")
    for group in (_QUAT, _FORCE, _MOMENT, _REACTION_FORCE, _REACTION_MOMENT):
        present = [b for b in group if b in columns]
        if present:
            missing += [b for b in group if b not in columns]
    if missing:
        spelled = ", ".join(f"{b}_{DEFAULT_UNITS[k]}" if (k := _kind(b)) else b for b in missing)
        raise _fail(
            "columns",
            names,
            f"missing column(s) {', '.join(missing)} (spelled e.g. {spelled}); required are "
            "p0, p1, ... (or t0, t1, ... for a rod without chambers) and tip_x, tip_y, tip_z "
            "(or markers marker0_x, ..., or a held tip's reaction tip_reaction_fx, ...); the "
            "tip_q*, base_f*, base_m*, marker* and tip_reaction_* columns are optional but "
            "come in complete groups",
        )
    if marker_ids and marker_ids != list(range(len(marker_ids))):
        gaps = sorted(set(range(marker_ids[-1] + 1)) - set(marker_ids))
        raise _fail(
            "columns",
            names,
            f"markers must be numbered marker0, marker1, ... without gaps: "
            f"{', '.join(f'marker{k}' for k in gaps)} missing",
        )
    if len(marker_ids) > MAX_MARKERS:
        raise _fail("columns", f"{len(marker_ids)} markers", f"at most {MAX_MARKERS} markers")
    sites = _marker_sites(meta.get("markers"), len(marker_ids), bodies=True)
    gaps = sorted(set(range(channels[-1] + 1)) - set(channels)) if channels else []
    if gaps:
        raise _fail(
            "columns",
            [columns[f"p{k}"][0] for k in channels],
            f"pressure channels must be numbered p0, p1, ... without gaps: "
            f"{', '.join(f'p{k}' for k in gaps)} missing",
        )
    if tendons and tendons != list(range(len(tendons))):
        gaps = sorted(set(range(tendons[-1] + 1)) - set(tendons))
        raise _fail(
            "columns",
            [columns[f"t{k}"][0] for k in tendons],
            f"tendon tension channels must be numbered t0, t1, ... without gaps: "
            f"{', '.join(f't{k}' for k in gaps)} missing",
        )
    if tendons and design is not None:
        d = load_design(design)
        if len(tendons) != d.n_tendons:
            raise _fail(
                "columns",
                [columns[f"t{k}"][0] for k in tendons],
                f"the data has {len(tendons)} tendon tension channel(s) but design "
                f"{d.name!r} has {d.n_tendons}",
            )
    want, what = _expected_channels(n_channels, design)
    if want is not None and len(channels) != want:
        raise _fail(
            "columns",
            [columns[f"p{k}"][0] for k in channels],
            f"the data has {len(channels)} pressure channel(s) but {what}",
        )
    if len(df) == 0:
        raise _fail("rows", 0, "the table has no data rows")
    if len(df) > V.MAX_ROWS:
        raise _fail("rows", len(df), f"too many rows: at most {V.MAX_ROWS:,}")
    if "converged" in extras:
        df, where = _converged_rows(df, where, unconverged)

    # Values: empty cells, text in number columns, non-finite numbers. A marker not seen
    # in a row, or a reaction component not measured, leaves its cells empty.
    def unmeasured_ok(base: str) -> bool:
        return _MARKER.match(base) is not None or base in _REACTION_FORCE + _REACTION_MOMENT

    used = [columns[b][0] for b in columns if not unmeasured_ok(b)]
    isna = df[used].isna().to_numpy()
    if isna.any():
        blank = isna.all(axis=1)
        parts = [f"blank {where(np.flatnonzero(blank))}"] if blank.any() else []
        cols = [c for k, c in enumerate(used) if (isna[:, k] & ~blank).any()]
        parts += [f"{c} at {where(np.flatnonzero(isna[:, used.index(c)] & ~blank))}" for c in cols]
        n_rows = int(isna.any(axis=1).sum())
        raise _fail(
            ", ".join(cols) if cols else "rows",
            "empty/NaN",
            f"empty or NaN values in {n_rows} row(s): {'; '.join(parts)}; "
            "fill or delete these rows",
        )
    numeric: dict[str, np.ndarray] = {}
    for base, (col, factor) in columns.items():
        if base in _LABELS:
            continue
        a = _number_column(df[col], col, where, missing_ok=unmeasured_ok(base))
        numeric[base] = a if factor is None else a * factor

    pressures = np.column_stack([numeric[f"p{k}"] for k in channels] or [np.zeros((len(df), 0))])
    low = np.flatnonzero((pressures < V.VACUUM_PA).any(axis=1))
    if low.size:
        raise _fail(
            ", ".join(columns[f"p{k}"][0] for k in channels),
            [float(numeric[f"p{k}"][low[0]]) for k in channels],
            f"gauge pressures must be >= {V.VACUUM_PA:g} Pa (a perfect vacuum), at {where(low)}",
        )

    tensions = None
    if tendons:
        tensions = np.column_stack([numeric[f"t{k}"] for k in tendons])
        bad = np.flatnonzero((tensions < 0).any(axis=1))
        if bad.size:
            raise _fail(
                ", ".join(columns[f"t{k}"][0] for k in tendons),
                [float(v) for v in tensions[bad[0]]],
                f"tendon tensions must be >= 0 N (a tendon pulls or is slack), at {where(bad)}",
            )

    rotation = None
    if _QUAT[0] in columns:
        q = np.column_stack([numeric[b] for b in _QUAT])
        norm = np.linalg.norm(q, axis=1)
        bad = np.flatnonzero(np.abs(norm - 1.0) > QUATERNION_TOLERANCE)
        if bad.size:
            raise _fail(
                ", ".join(columns[b][0] for b in _QUAT),
                f"|q| = {norm[bad[0]]:.9g}",
                f"not a unit quaternion at {where(bad)}: |q| must be 1 within "
                f"{QUATERNION_TOLERANCE:g} (the columns are (w, x, y, z), scalar first; a norm "
                "far from 1 usually means another order, Euler angles or a missing column)",
            )
        rotation = _quat_to_matrix(q)

    labels = {}
    for base in _LABELS:
        if base in columns:
            labels[base] = _labels(
                df[columns[base][0]].to_numpy(), columns[base][0], base == "experiment"
            )

    def stack(group):
        return np.column_stack([numeric[b] for b in group]) if group[0] in columns else None

    markers = None
    if marker_ids:
        markers = np.stack(
            [np.column_stack([numeric[f"marker{k}_{a}"] for a in _XYZ]) for k in marker_ids],
            axis=1,
        )
        partial = np.isnan(markers).any(axis=2) & ~np.isnan(markers).all(axis=2)
        if partial.any():
            row, k = np.argwhere(partial)[0]
            raise _fail(
                ", ".join(columns[f"marker{k}_{a}"][0] for a in _XYZ),
                "partly empty",
                f"a marker is seen (x, y, z all given) or not (all three empty), at "
                f"{where(np.flatnonzero(partial[:, k]))}",
            )
    meta = dict(meta)
    return Dataset(
        pressures=pressures,
        tensions=tensions,
        markers=markers,
        marker_s=None if markers is None else sites[0],
        marker_offset=None if markers is None else sites[1],
        marker_body=None if markers is None else sites[2],
        tip_position=stack(_TIP),
        tip_rotation=rotation,
        base_force=stack(_FORCE),
        base_moment=stack(_MOMENT),
        tip_reaction_force=stack(_REACTION_FORCE),
        tip_reaction_moment=stack(_REACTION_MOMENT),
        experiment=labels.get("experiment"),
        mounting=labels.get("mounting"),
        time=numeric.get("time"),
        metadata=meta,
        source=path,
        extra={name: _extra_values(df[name]) for name in extras},
    )


def _marker_sites(entry, count: int, bodies: bool = False):
    """(s (K,), offset (K, 3)) in m from the metadata's ``markers`` entry
    ``{"marker0": {"s": "55 mm", "offset": ["12 mm", "0 mm"]}, ...}``; None without markers.
    With ``bodies`` (a dataset's table) an entry may say the body it sits on in a system
    of rods: ``{"body": "platform", "offset": [x, y, z]}`` (platform frame) or
    ``{"body": "rod1", "s": ..., "offset": ...}``; then (s, offset, body (K,) or None)."""
    if count == 0:
        if entry:
            raise _fail(
                "metadata.markers",
                list(entry),
                "describes markers, but the table has no marker columns",
            )
        return None
    if not isinstance(entry, Mapping):
        raise _fail(
            "metadata.markers",
            entry,
            'say where each marker sits: {"markers": {"marker0": {"s": "55 mm", "offset": '
            '["12 mm", "0 mm"]}, ...}} (arc length from the base, offset in the cross-section '
            "frame d1, d2[, d3])",
        )
    extra = sorted(set(entry) - {f"marker{k}" for k in range(count)})
    if extra:
        raise _fail(f"metadata.markers.{extra[0]}", entry[extra[0]], "has no marker columns")
    s, offset = np.zeros(count), np.zeros((count, 3))
    body = np.zeros(count, dtype=np.int64)
    keys = {"s", "offset", "body"} if bodies else {"s", "offset"}
    for k in range(count):
        key = f"marker{k}"
        site = entry.get(key)
        where = f"metadata.markers.{key}"
        if not isinstance(site, Mapping) or set(site) - keys:
            raise _fail(
                where,
                site,
                'must be {"s": "<arc length>", "offset": ["<d1>", "<d2>"(, "<d3>")]} with units'
                + (
                    ', or on a system\'s platform {"body": "platform", "offset": ["<x>", "<y>", '
                    '"<z>"]} (platform frame), or on its rod i {"body": "rod<i>", "s": ..., '
                    '"offset": ...}'
                    if bodies
                    else ""
                ),
            )
        named = site.get("body")
        if named is not None:
            body[k] = _body_index(named, f"{where}.body")
        if body[k] == PLATFORM_BODY:
            if "s" in site:
                raise _fail(
                    f"{where}.s",
                    site["s"],
                    "a marker on the platform has no arc length: give only its offset",
                )
            off = site.get("offset")
            if not isinstance(off, (list, tuple)) or len(off) != 3:
                raise _fail(
                    f"{where}.offset", off, "must be 3 lengths (x, y, z in the platform frame)"
                )
        else:
            if "s" not in site:
                raise _fail(where, site, 'needs "s", its arc length from the base (with a unit)')
            s[k] = V.quantity(site["s"], "length", f"{where}.s", bare="error")
            if s[k] < 0:
                raise _fail(f"{where}.s", site["s"], "must be an arc length >= 0")
            off = site.get("offset", [0.0, 0.0])
            if not isinstance(off, (list, tuple)) or len(off) not in (2, 3):
                raise _fail(f"{where}.offset", off, "must be 2 or 3 lengths (d1, d2[, d3])")
        for i, v in enumerate(off):
            offset[k, i] = V.quantity(v, "length", f"{where}.offset[{i}]", bare="error")
    if not bodies:
        return s, offset
    given = any(
        isinstance(entry.get(f"marker{k}"), Mapping) and "body" in entry[f"marker{k}"]
        for k in range(count)
    )
    if given and not all("body" in entry[f"marker{k}"] for k in range(count)):
        k = next(k for k in range(count) if "body" not in entry[f"marker{k}"])
        raise _fail(
            f"metadata.markers.marker{k}",
            entry[f"marker{k}"],
            'needs a "body" too: in a system\'s dataset every marker says the body it sits on',
        )
    return s, offset, body if given else None


def _body_index(name, field: str) -> int:
    """-1 for "platform", i for "rod<i>"."""
    if name == "platform":
        return PLATFORM_BODY
    if isinstance(name, str) and name.startswith("rod") and name[3:].isdigit():
        return int(name[3:])
    raise _fail(field, name, 'must be "platform" or "rod<i>" (rod0, rod1, ...)')


def parse_marker_sites(markers, length: float | None = None, field: str = "markers"):
    """(s (K,), offset (K, 3)) in m of markers given in the Python API, or None for None.

    ``markers``: a list of 1 to :data:`MAX_MARKERS` markers, each ``(s, offset)`` (arc
    length from the base and the offset in the cross-section frame, (d1, d2[, d3])) or ``s``
    alone (no offset); SI numbers or strings with units (``("55 mm", ["12 mm", "0 mm"])``).
    With ``length`` (the rod's L, m) every s must lie in [0, L] (the core's rule, with its
    round-off slack of 1e-12 L) and every offset within L of the centreline (a farther one
    is a unit slip, e.g. a bare 12 read as 12 m); errors name ``markers[k].s`` or
    ``markers[k].offset``."""
    if markers is None:
        return None
    if isinstance(markers, np.ndarray) and markers.ndim == 1:
        markers = markers.tolist()  # arc lengths alone
    if not isinstance(markers, (list, tuple)) or not 1 <= len(markers) <= MAX_MARKERS:
        shown = f"{len(markers)} markers" if isinstance(markers, (list, tuple)) else markers
        raise _fail(
            field,
            shown,
            f"must be a list of 1 to {MAX_MARKERS} markers, each (s, offset) or s alone "
            "(arc length from the base; offset (d1, d2[, d3]) in the cross-section frame)",
        )
    s, offset = np.zeros(len(markers)), np.zeros((len(markers), 3))
    for k, item in enumerate(markers):
        where = f"{field}[{k}]"
        if isinstance(item, (list, tuple)):
            if len(item) != 2:
                raise _fail(where, item, "must be a pair (s, offset) or an arc length s")
            raw_s, off = item
            if not isinstance(off, (list, tuple, np.ndarray)) or len(off) not in (2, 3):
                raise _fail(f"{where}.offset", off, "must be 2 or 3 lengths (d1, d2[, d3])")
            for i, v in enumerate(off):
                offset[k, i] = V.quantity(v, "length", f"{where}.offset[{i}]")
            reach = float(np.linalg.norm(offset[k]))
            if length is not None and reach > length:
                # A marker farther from the centreline than the rod is long is a unit slip
                # (a bare number is metres: [12, 0] is 12 m), not a marker on the body.
                raise _fail(
                    f"{where}.offset",
                    off,
                    f"must lie within the rod's length L = {length:g} m of the centreline "
                    f"(it is {reach:g} m away; bare numbers are metres: write '12 mm')",
                )
        elif isinstance(item, str) or V.is_real(item):
            raw_s = item
        else:
            raise _fail(where, item, "must be a pair (s, offset) or an arc length s")
        s[k] = V.quantity(raw_s, "length", f"{where}.s")
        top = math.inf if length is None else length * (1.0 + 1e-12)
        if not 0.0 <= s[k] <= top:
            rule = (
                "must be an arc length >= 0 m"
                if length is None
                else f"must lie in [0, L] = [0, {length:g}] m (arc length from the base)"
            )
            raise _fail(f"{where}.s", raw_s, rule)
    return s, offset


def parse_system_marker_sites(markers, lengths: Sequence[float], field: str = "markers"):
    """(s (K,), offset (K, 3), body (K,)) in m of a system's markers given in the Python
    API, or None for None. Each marker is ``("platform", offset)`` (a point fixed to the
    platform: 3 lengths in the platform frame) or ``("rod<i>", s, offset)`` (a point on
    rod i, as :func:`parse_marker_sites` reads ``(s, offset)``, checked against that
    rod's length ``lengths[i]``). Errors name ``markers[k]``."""
    if markers is None:
        return None
    if not isinstance(markers, (list, tuple)) or not 1 <= len(markers) <= MAX_MARKERS:
        raise _fail(
            field,
            markers,
            f"must be a list of 1 to {MAX_MARKERS} markers, each ('platform', offset) or "
            "('rod<i>', s, offset)",
        )
    s, offset = np.zeros(len(markers)), np.zeros((len(markers), 3))
    body = np.zeros(len(markers), dtype=np.int64)
    for k, item in enumerate(markers):
        where = f"{field}[{k}]"
        if not isinstance(item, (list, tuple)) or len(item) not in (2, 3):
            raise _fail(where, item, "must be ('platform', offset) or ('rod<i>', s, offset)")
        b = _body_index(item[0], f"{where}[0]")
        body[k] = b
        if b == PLATFORM_BODY:
            off = item[1] if len(item) == 2 else None
            if not isinstance(off, (list, tuple, np.ndarray)) or len(off) != 3:
                raise _fail(
                    where,
                    item,
                    "a platform marker is ('platform', [x, y, z]): 3 lengths in the platform frame",
                )
            for i, v in enumerate(off):
                offset[k, i] = V.quantity(v, "length", f"{where}.offset[{i}]")
            continue
        if b >= len(lengths):
            raise _fail(f"{where}[0]", item[0], f"the system has {len(lengths)} rods")
        site = (item[1], item[2]) if len(item) == 3 else item[1]
        one = parse_marker_sites([site], lengths[b], field=where)
        s[k], offset[k] = one[0][0], one[1][0]
    return s, offset, body


def _extra_values(column: pd.Series) -> np.ndarray:
    """A result column as a numpy array: numbers as float (empty cells NaN), flags as bool,
    anything else as text."""
    values = column.to_numpy()
    if values.dtype.kind in "biuf":
        return values
    if any(isinstance(v, (list, tuple, np.ndarray)) for v in values):
        out = np.empty(len(values), dtype=object)  # e.g. a trajectory's shape_m list column
        out[:] = list(values)
        return out
    as_bool = column.map({True: True, False: False, "True": True, "False": False})
    if as_bool.notna().all():
        return as_bool.to_numpy(dtype=bool)
    numbers = pd.to_numeric(column, errors="coerce")
    if (numbers.notna() | column.isna()).all():
        return numbers.to_numpy(dtype=float)
    return np.asarray(["" if pd.isna(v) else str(v) for v in values], dtype=str)


def _converged_rows(df: pd.DataFrame, where, unconverged: str):
    """The rows of a solver's table (a declared ``converged`` column) whose solve converged:
    a row that did not has no tip position, so it is an error unless the caller drops it."""
    flags = _extra_values(df["converged"])
    if flags.dtype != bool:
        raise _fail("converged", df["converged"].iloc[0], "must hold True or False in every row")
    if flags.all():
        return df, where
    failed = np.flatnonzero(~flags)
    if unconverged == "error":
        raise _fail(
            "converged",
            False,
            f"the solve did not converge at {where(failed)} ({failed.size} of {len(df)} rows), "
            "which therefore have no tip position; pass unconverged='drop' to load the "
            "converged rows only",
        )
    kept = np.flatnonzero(flags)
    if where.labels is not None:
        where = _Where(where.noun, where.first, tuple(where.labels[i] for i in kept))
    else:
        where = _KeptRows(where, kept)
    return df.iloc[kept].reset_index(drop=True), where


# --- writing -------------------------------------------------------------------------------------


def write_dataset(
    dataset: Dataset, path: PathLike, *, units: Mapping[str, str] | None = None
) -> Path:
    """Write ``dataset`` to ``path``: CSV (``.csv``) or Parquet (``.parquet``) by suffix.

    Units go into the column names (``units`` as in :meth:`Dataset.to_frame`); the metadata
    goes into a ``# metadata: {...}`` comment line (CSV) or the ``softrod.metadata`` entry
    (Parquet). Synthetic data says so in the first line of a CSV file. The file is written
    atomically: a temporary file in the same folder, renamed into place when complete, so a
    failure leaves no partial file (and an older file untouched). Returns the path.
    """
    if not isinstance(dataset, Dataset):
        raise _fail("dataset", type(dataset).__name__, "must be a softrod Dataset")
    path = check_table_path(path)
    frame = dataset.to_frame(units)
    if dataset.synthetic:
        first = (
            "SYNTHETIC softrod dataset: generated by the model "
            f"({dataset.metadata.get('design', '?')}), not measured"
        )
    else:
        first = "softrod dataset"
    return write_table(
        frame, path, header=(first, "schema: docs/datasets.md; units are in the column names")
    )


# --- synthetic data ------------------------------------------------------------------------------


def noise_seed(noise_mm, seed) -> int:
    """Check the noise (standard deviation, mm) and seed of synthetic data; return the seed
    (a fresh one, recorded in the metadata, when ``seed`` is None)."""
    V.real(noise_mm, "noise_mm", minimum=0.0, what="a standard deviation in mm")
    if seed is None:
        return int(np.random.SeedSequence().entropy % 2**63)
    return V.integer(seed, "seed", minimum=0, maximum=2**128)


def example_datasets() -> list[str]:
    """Names of the bundled example datasets (all synthetic)."""
    return sorted(p.stem for p in _EXAMPLES_DIR.glob("*") if p.suffix in TABLE_SUFFIXES)


def example_dataset_path(name: str) -> Path:
    """Path of a bundled example dataset, e.g. ``example_dataset_path("spa130_synthetic")``."""
    for suffix in ("", *TABLE_SUFFIXES):
        candidate = _EXAMPLES_DIR / f"{name}{suffix}"
        if isinstance(name, str) and name and _is_file(candidate):
            return candidate
    raise _fail(
        "name", name, f"no bundled example dataset (known: {', '.join(example_datasets())})"
    )
