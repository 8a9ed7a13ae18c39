"""Trajectories: the result of a dynamic simulation, with files, plots and animations.

A :class:`Trajectory` holds, at n sample times, the commanded and actual chamber pressures,
the tip pose and velocity, the mechanical energy and its books (kinetic, elastic, potential,
work of the inputs, dissipation), the positions of motion-capture markers on the body if
any, plus the full centreline at k of those times (the "shapes"). Everything is SI (s, Pa,
m, m/s, J). Files:

- Parquet (``.parquet``): one row per sample time, units in the column names (see
  :meth:`Trajectory.to_frame`), the shapes in a list column ``shape_m``, the metadata as JSON
  in the schema metadata. Layout in docs/dynamics.md.
- NumPy (``.npz``): one array per field (SI) plus the metadata as JSON.

Both are written atomically (whole or not at all) and read back exactly by
:meth:`Trajectory.load`.
"""

from __future__ import annotations

import json
import logging
import math
import os
import re
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from .. import _validate as V
from ..datasets import _MARKER, MAX_MARKERS, _fail, _marker_sites
from ..errors import InputError
from ..io import as_path, atomic_path, check_target
from ..io import is_file as _is_file
from ..io import metadata_json as _metadata_json
from ..schema import Extra, schema_frame
from ..schema import unit_factor as _unit_factor

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from .._types import ArrayLike, Progress, Units

__all__ = [
    "ENERGY_PARTS",
    "TRAJECTORY_FORMAT",
    "TRAJECTORY_SUFFIXES",
    "AnimationPlan",
    "Trajectory",
    "animation_plan",
]

logger = logging.getLogger(__name__)

TRAJECTORY_SUFFIXES = (".parquet", ".npz")
# Version of the file layout, written into every file. 2: the dataset schema's tip_q* columns
# and velocity names tip_v*_m/s (version 1: tip_v*_m_s, no quaternion; still read). 3: the
# markers (marker<k>_x_m ... columns and their sites in the metadata's "markers" block;
# npz marker_position, marker_s, marker_offset), which a reader of version 2 would drop
# without a word, so it is told to upgrade instead.
TRAJECTORY_FORMAT = 3
_READABLE_FORMATS = (1, 2, 3)
ANIMATION_SUFFIXES = (".gif", ".mp4")
# Animation defaults: a watchable clip, fast to render (docs/dynamics.md).
DEFAULT_FPS = 20  # frames per second of clip
TARGET_CLIP_S = 15.0  # longer runs play faster than real time to last about this long
MAX_FRAMES = 300  # frame budget: fps drops below DEFAULT_FPS rather than exceed it

_XYZ = ("x", "y", "z")
_ROT = tuple(f"tip_R{i + 1}{j + 1}" for i in range(3) for j in range(3))  # R[i, j], row-major
_FIELDS = (
    "time",
    "command",
    "pressure",
    "tip_position",
    "tip_rotation",
    "tip_velocity",
    "energy",
    "shape_time",
    "shape_s",
    "shape_position",
)
_MARKER_FIELDS = ("marker_position", "marker_s", "marker_offset")
# The energy books (J, (n,), NaN where not recorded): optional in files, so that
# trajectories written before they existed still load.
ENERGY_PARTS = ("kinetic", "elastic", "potential", "work_in", "dissipated")
ENERGY_DESCRIPTIONS = {
    "kinetic": "kinetic energy (empty: not recorded)",
    "elastic": "stored energy of the law at the current pressures (empty: not recorded)",
    "potential": "potential of gravity and dead forces (empty: not recorded)",
    "work_in": "work of the inputs since t = 0 (empty: not recorded)",
    "dissipated": "Kelvin-Voigt dissipation since t = 0 (empty: not recorded)",
}
_PARQUET_KEY = b"softrod.trajectory"  # layout facts (format, channels, shape_s_m)
_META_KEY = b"softrod.metadata"  # the metadata dict
_NPZ_FORMAT = "softrod.trajectory"


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


def _array(value, name: str, shape: tuple, what: str) -> np.ndarray:
    """A float copy of ``value`` with ``shape`` (None entries: any size)."""
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        # OverflowError: an integer beyond the float range (1e400 as an int).
        raise _fail(name, type(value).__name__, f"must be an array of numbers: {what}") from None
    ok = a.ndim == len(shape) and all(
        w is None or w == h for w, h in zip(shape, a.shape, strict=False)
    )
    if not ok:
        want = "(" + ", ".join("*" if w is None else str(w) for w in shape) + ")"
        raise _fail(name, f"shape {a.shape}", f"must have shape {want}: {what}")
    return a


def _finite(a: np.ndarray, name: str) -> None:
    bad = np.flatnonzero(~np.isfinite(a.reshape(a.shape[0], -1)).all(axis=1)) if a.size else []
    if len(bad):
        raise _fail(name, "non-finite", f"must be finite; first bad sample at index {bad[0]}")


def _increasing(t: np.ndarray, name: str) -> None:
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        i = bad[0] + 1
        raise _fail(
            f"{name}[{i}]",
            t[i].item(),
            f"must be strictly increasing, but {name}[{i - 1}] = {t[i - 1]!r}",
        )


@dataclass(frozen=True, eq=False, repr=False)
class Trajectory:
    """A simulated motion, SI, n samples, c pressure channels, k shapes of p nodes each.

    - ``time`` (n,) s, finite, strictly increasing (n >= 1);
    - ``command`` (n, c) Pa: commanded gauge pressures (the schedule);
    - ``pressure`` (n, c) Pa: actual chamber gauge pressures (after the supply's lag);
    - ``tension`` (n, k) N: tendon tensions, those held over the step that ended at each
      sample (k = 0 for a design without tendons; None gives that), each >= 0;
    - ``tip_position`` (n, 3) m, world frame; ``tip_rotation`` (n, 3, 3): the tip frame
      [d1 d2 d3] as columns in world coordinates; ``tip_velocity`` (n, 3) m/s;
    - ``energy`` (n,) J: total mechanical energy (kinetic + elastic + potential), NaN
      where not defined (default: all NaN);
    - ``kinetic``, ``elastic``, ``potential`` (n,) J: its parts (elastic: the law's stored
      energy at the current pressures; potential: gravity and dead forces), and
      ``work_in``, ``dissipated`` (n,) J: the work of the inputs (pressure and load
      changes, dead moments) and the Kelvin-Voigt dissipation since t = 0, NaN where not
      recorded; ``energy_balance`` = energy - energy[0] - (work_in - work_in[0]) +
      (dissipated - dissipated[0]) is zero for the exact motion;
    - ``contact_force`` (n, 3) N: total contact force of the obstacles on the rod (normal
      and friction, world frame), and ``penetration`` (n,) m: the deepest penetration of
      the rod's surface into an obstacle (<= 0: no contact), for a design with obstacles
      (None otherwise; docs/contact.md);
    - ``tip_reaction_force`` (n, 3) N and ``tip_reaction_moment`` (n, 3) N m: the wrench a
      pinned or clamped tip's constraint applies to the tip (world frame; zero moment when
      pinned), for a run with a held tip (None otherwise; docs/model.md "End constraints");
    - ``marker_position`` (n, K, 3) m: the world positions of K motion-capture markers on the
      body (``simulate(..., markers=...)``), with their sites ``marker_s`` (K,) m (arc length
      from the base, >= 0) and ``marker_offset`` (K, 3) m (offset in the cross-section frame
      d1, d2, d3), all three or none (None: no markers);
    - ``shape_time`` (k,) s: times of the stored centrelines, each exactly one of ``time``
      (k may be 0); ``shape_s`` (p,) m: reference arc length of the nodes, strictly
      increasing; ``shape_position`` (k, p, 3) m: the centrelines;
    - ``metadata``: a JSON-serialisable dict (design, model, dt, method, wall time,
      real-time factor, ...).

    Every array but ``energy`` must be finite. Arrays are stored as read-only float copies.
    """

    time: np.ndarray
    command: np.ndarray
    pressure: np.ndarray
    tip_position: np.ndarray
    tip_rotation: np.ndarray
    tip_velocity: np.ndarray
    energy: np.ndarray | None = None
    shape_time: np.ndarray | None = None
    shape_s: np.ndarray | None = None
    shape_position: np.ndarray | None = None
    metadata: dict = field(default_factory=dict)
    kinetic: np.ndarray | None = None
    elastic: np.ndarray | None = None
    potential: np.ndarray | None = None
    work_in: np.ndarray | None = None
    dissipated: np.ndarray | None = None
    tension: np.ndarray | None = None
    contact_force: np.ndarray | None = None
    penetration: np.ndarray | None = None
    tip_reaction_force: np.ndarray | None = None
    tip_reaction_moment: np.ndarray | None = None
    marker_position: np.ndarray | None = None
    marker_s: np.ndarray | None = None
    marker_offset: np.ndarray | None = None

    def __post_init__(self):
        set_ = object.__setattr__
        t = _array(self.time, "time", (None,), "the sample times in s")
        if t.size == 0:
            raise _fail("time", "shape (0,)", "needs at least one sample")
        _finite(t, "time")
        _increasing(t, "time")
        n = t.size
        set_(self, "time", _readonly(t))
        cmd = _array(self.command, "command", (n, None), f"(n = {n}, channels) in Pa")
        c = cmd.shape[1]  # 0 for a design without chambers
        specs = {
            "command": (cmd, (n, c), f"(n = {n}, channels) in Pa"),
            "pressure": (self.pressure, (n, c), f"(n = {n}, channels = {c}) in Pa"),
            "tip_position": (self.tip_position, (n, 3), f"(n = {n}, 3) in m"),
            "tip_rotation": (self.tip_rotation, (n, 3, 3), f"(n = {n}, 3, 3), [d1 d2 d3]"),
            "tip_velocity": (self.tip_velocity, (n, 3), f"(n = {n}, 3) in m/s"),
        }
        for name, (value, shape, what) in specs.items():
            a = _array(value, name, shape, what)
            _finite(a, name)
            set_(self, name, _readonly(a))
        tens = np.zeros((n, 0)) if self.tension is None else self.tension
        tens = _array(tens, "tension", (n, None), f"(n = {n}, tendon channels) in N")
        _finite(tens, "tension")
        negative = np.argwhere(tens < 0)
        if negative.size:
            i, k = negative[0]
            raise _fail(f"tension[{i}, {k}]", tens[i, k].item(), "must be >= 0 N (a tendon pulls)")
        set_(self, "tension", _readonly(tens))
        if (self.contact_force is None) != (self.penetration is None):
            raise _fail(
                "contact_force",
                "given" if self.penetration is None else None,
                "contact_force and penetration come together (a design with obstacles)",
            )
        if self.contact_force is not None:
            for name, shape, what in (
                ("contact_force", (n, 3), f"(n = {n}, 3) in N"),
                ("penetration", (n,), f"(n = {n},) in m"),
            ):
                a = _array(getattr(self, name), name, shape, what)
                _finite(a, name)
                set_(self, name, _readonly(a))
        if (self.tip_reaction_force is None) != (self.tip_reaction_moment is None):
            raise _fail(
                "tip_reaction_force",
                "given" if self.tip_reaction_moment is None else None,
                "tip_reaction_force and tip_reaction_moment come together (a held tip)",
            )
        if self.tip_reaction_force is not None:
            for name, what in (
                ("tip_reaction_force", f"(n = {n}, 3) in N"),
                ("tip_reaction_moment", f"(n = {n}, 3) in N m"),
            ):
                a = _array(getattr(self, name), name, (n, 3), what)
                _finite(a, name)
                set_(self, name, _readonly(a))
        self._check_markers(n)
        for name in ("energy", *ENERGY_PARTS):
            v = getattr(self, name)
            e = np.full(n, np.nan) if v is None else v
            set_(self, name, _readonly(_array(e, name, (n,), f"(n = {n},) in J, NaN allowed")))

        st = np.zeros(0) if self.shape_time is None else self.shape_time
        st = _array(st, "shape_time", (None,), "the times of the stored shapes in s")
        _finite(st, "shape_time")
        _increasing(st, "shape_time")
        if st.size:
            pos = np.searchsorted(t, st).clip(0, n - 1)
            bad = np.flatnonzero(t[pos] != st)
            if bad.size:
                i = bad[0]
                raise _fail(
                    f"shape_time[{i}]",
                    st[i].item(),
                    "every shape time must be one of the sample times (exactly, e.g. "
                    "time[::save_every])",
                )
        k = st.size
        ss = np.zeros(0) if self.shape_s is None else self.shape_s
        ss = _array(ss, "shape_s", (None,), "the arc length of the shape nodes in m")
        _finite(ss, "shape_s")
        _increasing(ss, "shape_s")
        if k and ss.size < 2:
            raise _fail("shape_s", f"shape {ss.shape}", "shapes need at least 2 nodes")
        p = ss.size
        sp = np.zeros((k, p, 3)) if self.shape_position is None else self.shape_position
        sp = _array(sp, "shape_position", (k, p, 3), f"(k = {k}, p = {p}, 3) in m")
        _finite(sp, "shape_position")
        for name, a in (("shape_time", st), ("shape_s", ss), ("shape_position", sp)):
            set_(self, name, _readonly(a))
        if not isinstance(self.metadata, dict):
            raise _fail("metadata", self.metadata, "must be a dict")
        meta = json.loads(_metadata_json(self.metadata))  # checks it, and a plain copy
        set_(self, "metadata", meta)

    def _check_markers(self, n: int) -> None:
        given = [name for name in _MARKER_FIELDS if getattr(self, name) is not None]
        if not given:
            return
        if len(given) < len(_MARKER_FIELDS):
            missing = [name for name in _MARKER_FIELDS if name not in given]
            raise _fail(
                missing[0],
                None,
                "marker_position, marker_s and marker_offset come together (the markers' "
                "positions and where each sits on the body)",
            )
        if isinstance(self.metadata, dict) and "markers" in self.metadata:
            raise _fail(
                "metadata.markers",
                "given",
                "is where the tables and files put the markers' sites (marker_s, "
                "marker_offset): keep other information under another key",
            )
        s = _array(self.marker_s, "marker_s", (None,), "the markers' arc lengths in m")
        k = s.size
        if not 1 <= k <= MAX_MARKERS:
            raise _fail("marker_s", f"shape {s.shape}", f"needs 1 to {MAX_MARKERS} markers")
        _finite(s, "marker_s")
        if np.any(s < 0):
            i = int(np.flatnonzero(s < 0)[0])
            raise _fail(f"marker_s[{i}]", s[i].item(), "must be an arc length >= 0 m")
        offset = _array(self.marker_offset, "marker_offset", (k, 3), f"(K = {k}, 3) in m")
        pos = _array(
            self.marker_position, "marker_position", (n, k, 3), f"(n = {n}, K = {k}, 3) in m"
        )
        for name, a in (("marker_s", s), ("marker_offset", offset), ("marker_position", pos)):
            _finite(a, name)
            object.__setattr__(self, name, _readonly(a))

    @property
    def n_markers(self) -> int:
        """Number of markers (K; 0 without)."""
        return 0 if self.marker_s is None else self.marker_s.size

    # --- basic facts -------------------------------------------------------------------------

    def __len__(self) -> int:
        return self.time.size

    def __repr__(self) -> str:
        name = self.metadata.get("design")
        what = f", design {name!r}" if name else ""
        markers = f", {self.n_markers} markers" if self.n_markers else ""
        return (
            f"Trajectory({len(self)} samples, t = {self.time[0]:g} ... {self.time[-1]:g} s, "
            f"{self.n_channels} channels, {self.shape_time.size} shapes of "
            f"{self.shape_s.size} nodes{markers}{what})"
        )

    @property
    def n_channels(self) -> int:
        """Number of pressure channels."""
        return self.command.shape[1]

    @property
    def n_tendons(self) -> int:
        """Number of tendon channels (columns of :attr:`tension`)."""
        return self.tension.shape[1]

    @property
    def energy_balance(self) -> np.ndarray:
        """(n,) J: energy - energy[0] - (work_in - work_in[0]) + (dissipated -
        dissipated[0]), zero for the exact motion (the simulation stops when it grows
        beyond its energy_tol; docs/dynamics.md)."""
        return (
            self.energy
            - self.energy[0]
            - (self.work_in - self.work_in[0])
            + (self.dissipated - self.dissipated[0])
        )

    @property
    def duration(self) -> float:
        """``time[-1] - time[0]`` in s."""
        return float(self.time[-1] - self.time[0])

    # --- tables and files --------------------------------------------------------------------

    def to_frame(self, units: Units = None) -> pd.DataFrame:
        """The tip table in the dataset schema (docs/datasets.md), one row per sample.

        Columns: ``time_s``; ``p0_kPa``, ... (actual chamber pressures); ``t0_N``, ...
        (tendon tensions, for a design with tendons); ``tip_x_mm``, ``tip_y_mm``,
        ``tip_z_mm``; ``tip_qw`` ... ``tip_qz`` (the tip frame as a unit quaternion, scalar
        first); ``marker0_x_mm``, ``marker0_y_mm``, ``marker0_z_mm``, ``marker1_x_mm``, ...
        (the markers, world frame; where each sits is the metadata's ``markers`` block, as
        in a dataset); then the result columns ``cmd0_kPa``, ... (commanded pressures),
        ``tip_vx_mm/s``, ``tip_vy_mm/s``, ``tip_vz_mm/s`` (tip velocity, world frame),
        ``energy_J`` and its books ``kinetic_J``, ``elastic_J``, ``potential_J``,
        ``work_in_J``, ``dissipated_J``. ``units`` as in :meth:`softrod.Dataset.to_frame`
        (also "velocity" and "energy"; ``units="SI"`` for Pa, m, m/s). The same quantities
        have the same names as in :meth:`softrod.BatchSolution.to_frame`. The metadata block
        (``frame.attrs["softrod.metadata"]``) is :attr:`metadata` with the result columns
        declared, so ``load_dataset(frame)`` reads it back.
        """
        return schema_frame(
            pressures=self.pressure,
            tensions=self._tensions(),
            tip_position=self.tip_position,
            tip_rotation=self.tip_rotation,
            time=self.time,
            **self._marker_columns(),
            extras=self._extras(),
            units=units,
            metadata=self._table_metadata(),
        )

    def _marker_columns(self) -> dict:
        """schema_frame's marker arguments (none without markers)."""
        if self.marker_position is None:
            return {}
        return {
            "markers": self.marker_position,
            "marker_s": self.marker_s,
            "marker_offset": self.marker_offset,
        }

    def _tensions(self) -> np.ndarray | None:
        """The tension columns of the tables (none without tendons)."""
        return self.tension if self.n_tendons else None

    def _table_metadata(self) -> dict:
        """The metadata of the tables: the trajectory's, marked as made by the model."""
        return {"synthetic": True, **self.metadata}

    def _extras(self) -> list[Extra]:
        extras = [
            Extra(f"cmd{k}", self.command[:, k], f"commanded pressure of channel {k}", "pressure")
            for k in range(self.n_channels)
        ]
        extras += [
            Extra(f"tip_v{a}", self.tip_velocity[:, i], "tip velocity, world frame", "velocity")
            for i, a in enumerate(_XYZ)
        ]
        extras.append(
            Extra("energy", self.energy, "total mechanical energy (empty: not defined)", "energy")
        )
        extras += [
            Extra(name, getattr(self, name), what, "energy")
            for name, what in ENERGY_DESCRIPTIONS.items()
        ]
        if self.contact_force is not None:
            what = "total contact force on the rod, world frame"
            extras += [
                Extra(f"contact_f{a}", self.contact_force[:, i], what, "force")
                for i, a in enumerate(_XYZ)
            ]
            what = "deepest penetration into an obstacle (<= 0: none)"
            extras.append(Extra("penetration", self.penetration, what, "length"))
        if self.tip_reaction_force is not None:
            for key, arr, kind in (
                ("f", self.tip_reaction_force, "force"),
                ("m", self.tip_reaction_moment, "moment"),
            ):
                what = f"{kind} the tip's constraint applies to the tip, world frame"
                extras += [
                    Extra(f"tip_reaction_{key}{a}", arr[:, i], what, kind)
                    for i, a in enumerate(_XYZ)
                ]
        return extras

    def save(self, path: str | os.PathLike) -> Path:
        """Write to ``.parquet`` or ``.npz`` (by suffix), atomically; returns the path.

        Parquet: the columns of :meth:`to_frame` plus ``shape_m``, a list column holding the
        flattened centreline (p nodes x 3, node-major: x0, y0, z0, x1, ...) in m in the rows
        whose time is a shape time and null elsewhere; the schema metadata holds
        ``softrod.metadata`` (the metadata as JSON, with the markers' sites in its
        ``markers`` block as in a dataset) and ``softrod.trajectory`` (JSON with
        ``format``, ``n_channels``, ``n_nodes`` and ``shape_s_m``, the node arc lengths).
        NPZ: one array per field under its field name (SI), ``metadata_json`` and ``format``.
        """
        path = _check_path(path)
        meta = _metadata_json(self.metadata)
        with atomic_path(path) as tmp:
            if path.suffix.lower() == ".npz":
                arrays = {
                    name: getattr(self, name) for name in (*_FIELDS, *ENERGY_PARTS, "tension")
                }
                if self.contact_force is not None:
                    arrays.update(contact_force=self.contact_force, penetration=self.penetration)
                if self.tip_reaction_force is not None:
                    arrays.update(
                        tip_reaction_force=self.tip_reaction_force,
                        tip_reaction_moment=self.tip_reaction_moment,
                    )
                if self.marker_position is not None:
                    arrays.update({name: getattr(self, name) for name in _MARKER_FIELDS})
                with open(tmp, "wb") as fh:  # a file object: numpy would append ".npz"
                    np.savez_compressed(
                        fh,
                        **arrays,
                        metadata_json=np.array(meta),
                        format=np.array(f"{_NPZ_FORMAT}/{TRAJECTORY_FORMAT}"),
                    )
            else:
                self._write_parquet(tmp)
        return path

    def _write_parquet(self, tmp: Path) -> None:
        import pyarrow as pa
        import pyarrow.parquet as pq

        # SI columns, and the rotation matrix beside its quaternion: load() gets every bit back.
        exact = [
            Extra(name, self.tip_rotation[:, i, j], f"tip rotation R[{i}, {j}] (d{j + 1} column)")
            for name, (i, j) in zip(_ROT, np.ndindex(3, 3), strict=True)
        ]
        frame = schema_frame(
            pressures=self.pressure,
            tensions=self._tensions(),
            tip_position=self.tip_position,
            tip_rotation=self.tip_rotation,
            time=self.time,
            **self._marker_columns(),
            extras=self._extras() + exact,
            units="SI",
            metadata=self._table_metadata(),
        )
        meta = frame.attrs["softrod.metadata"]
        meta["columns"]["shape_m"] = (
            "centreline, node-major (x0, y0, z0, x1, ...) in m; empty: no shape stored"
        )
        table = pa.Table.from_pandas(frame, preserve_index=False)
        n, p = len(self), self.shape_s.size
        rows = np.searchsorted(self.time, self.shape_time)  # exact members (checked)
        lengths = np.zeros(n, dtype=np.int32)
        lengths[rows] = 3 * p
        offsets = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int32)
        is_null = np.ones(n, dtype=bool)
        is_null[rows] = False
        shapes = pa.ListArray.from_arrays(
            pa.array(offsets),
            pa.array(self.shape_position.reshape(-1), type=pa.float64()),
            mask=pa.array(is_null),
        )
        table = table.append_column("shape_m", shapes)
        layout = {
            "format": TRAJECTORY_FORMAT,
            "n_channels": self.n_channels,
            "n_tendons": self.n_tendons,
            "n_nodes": p,
            "shape_s_m": self.shape_s.tolist(),  # JSON floats round-trip exactly
            "shape_layout": "shape_m: node-major (x0, y0, z0, x1, ...) in m; null: no shape",
            # Metadata entries the table adds (load() takes them out again).
            "table_metadata": sorted(set(meta) - set(self.metadata)),
        }
        kv = dict(table.schema.metadata or {})
        kv.pop(b"pandas", None)  # the table is read back column by column, not via pandas
        kv[_META_KEY] = _metadata_json(meta).encode("utf-8")
        kv[_PARQUET_KEY] = json.dumps(layout).encode("utf-8")
        pq.write_table(table.replace_schema_metadata(kv), tmp)

    @classmethod
    def load(cls, path: str | os.PathLike) -> Trajectory:
        """Read a trajectory written by :meth:`save` (``.parquet`` or ``.npz``), exactly."""
        path = _check_path(path, must_exist=True)
        try:
            if path.suffix.lower() == ".npz":
                return _load_npz(path)
            return _load_parquet(path)
        except InputError as exc:
            exc.args = (f"{path.name}: {exc.args[0]}",)
            raise

    # --- interpolation and errors ------------------------------------------------------------

    def tip_position_at(self, times: ArrayLike) -> np.ndarray:
        """Tip positions (m, 3) in m at ``times`` (m,) s, linear in time between samples.

        Every time must lie in ``[time[0], time[-1]]`` (with a round-off slack of 1e-9 of
        the duration: a clock of n * dt may end a few 1e-13 s off a nominal end); otherwise
        :class:`InputError` naming the first sample outside.
        """
        return self._at(times, self.tip_position)

    def marker_position_at(self, times: ArrayLike) -> np.ndarray:
        """Marker positions (m, K, 3) in m at ``times`` (m,) s, linear in time between
        samples, as :meth:`tip_position_at` (the same interval rule); an InputError naming
        ``marker_position`` for a trajectory without markers."""
        return self._at(times, self._markers())

    def _markers(self) -> np.ndarray:
        """``marker_position``, or an InputError naming it for a trajectory without."""
        if self.marker_position is None:
            raise _fail(
                "marker_position",
                None,
                "this trajectory has no markers: simulate with markers=[...] "
                "(docs/dynamics.md, 'Markers on the moving rod')",
            )
        return self.marker_position

    def _at(self, times: ArrayLike, values: np.ndarray) -> np.ndarray:
        """``values`` (n, ...) linear in time at ``times`` (m,): (m, ...)."""
        t = _array(times, "times", (None,), "the times in s")
        _finite(t, "times")
        lo, hi = self.time[0], self.time[-1]
        slack = 1e-9 * max(hi - lo, 1e-300)
        bad = np.flatnonzero((t < lo - slack) | (t > hi + slack))
        if bad.size:
            i = bad[0]
            raise _fail(
                f"times[{i}]",
                t[i].item(),
                f"outside the simulated interval [{lo:g}, {hi:g}] s "
                f"({bad.size} of {t.size} times are); simulate longer or trim the measurements",
            )
        flat = values.reshape(len(self), -1)
        out = np.column_stack([np.interp(t, self.time, flat[:, i]) for i in range(flat.shape[1])])
        return out.reshape(t.size, *values.shape[1:])

    def tip_error(self, measured_time: ArrayLike, measured_position: ArrayLike) -> np.ndarray:
        """Euclidean tip error (m,) in m between measured tip positions and the trajectory.

        ``measured_time`` (m,) s and ``measured_position`` (m, 3) m, world frame; the
        trajectory is interpolated linearly at the measured times (see
        :meth:`tip_position_at`; times outside the simulated interval are an error).
        """
        t = _array(measured_time, "measured_time", (None,), "sample times in s")
        pos = _array(measured_position, "measured_position", (t.size, 3), f"(m = {t.size}, 3) in m")
        _finite(pos, "measured_position")
        return np.linalg.norm(self._measured_at(t, self.tip_position) - pos, axis=1)

    def marker_error(self, measured_time: ArrayLike, measured_position: ArrayLike) -> np.ndarray:
        """Euclidean marker errors (m, K) in m between measured marker positions and the
        trajectory's markers, NaN where a marker was not seen.

        ``measured_time`` (m,) s and ``measured_position`` (m, K, 3) m, world frame, the
        markers in the trajectory's order, all three coordinates of a marker NaN where it
        was not seen (as a dataset's ``markers``); the trajectory is interpolated linearly
        at the measured times (:meth:`marker_position_at`; times outside the simulated
        interval are an error)."""
        markers = self._markers()
        t = _array(measured_time, "measured_time", (None,), "sample times in s")
        k = self.n_markers
        pos = _array(
            measured_position,
            "measured_position",
            (t.size, k, 3),
            f"(m = {t.size}, K = {k}, 3) in m",
        )
        seen = np.isfinite(pos).all(axis=2)
        bad = np.argwhere(~seen & ~np.isnan(pos).all(axis=2))
        if bad.size:
            i, j = bad[0]
            raise _fail(
                f"measured_position[{i}, {j}]",
                pos[i, j].tolist(),
                "a marker is seen (x, y, z all finite) or not (all three NaN)",
            )
        err = np.linalg.norm(
            self._measured_at(t, markers) - np.where(seen[..., None], pos, 0.0), axis=2
        )
        return np.where(seen, err, np.nan)

    def _measured_at(self, t: np.ndarray, values: np.ndarray) -> np.ndarray:
        """:meth:`_at` with errors naming ``measured_time``."""
        try:
            return self._at(t, values)
        except InputError as exc:
            exc.args = (exc.args[0].replace("times[", "measured_time[", 1),)
            raise

    # --- plots -------------------------------------------------------------------------------

    def plot_tip(
        self,
        path: str | os.PathLike | None = None,
        *,
        reference: Any = None,
        title: str | None = None,
    ) -> Figure:
        """Tip x, y, z (mm) and chamber pressures (kPa) against time (s); returns the Figure.

        Top panel: the tip coordinates (solid), with ``reference`` overlaid (dashed, same
        colour per axis) as in paper 000, Fig. 3. ``reference``: another Trajectory, a
        Dataset with times, a DataFrame with ``time_<unit>`` and ``tip_x_<unit>``,
        ``tip_y_<unit>``, ``tip_z_<unit>`` columns (e.g. ``time_s``, ``tip_x_mm``), or a
        tuple ``(time in s (m,), position in m (m, 3))``. Bottom panel: actual pressures
        (solid) and commands (dotted) per channel. With ``path`` the figure is also written
        atomically (format from the suffix). Made with pyplot: close it when done.
        """
        title = V.figure_title(title)
        from ..plotting import check_figure_path, save_figure

        if path is not None:
            path = check_figure_path(path)
        ref = None if reference is None else _reference(reference)
        import matplotlib.pyplot as plt

        fig, (ax, axp) = plt.subplots(
            2, 1, sharex=True, figsize=(8.0, 6.0), gridspec_kw={"height_ratios": [2, 1]}
        )
        model = {"cosserat": "rod", "pcc": "PCC"}.get(self.metadata.get("model"), "model")
        for i, a in enumerate(_XYZ):
            ax.plot(self.time, self.tip_position[:, i] * 1e3, color=f"C{i}", label=f"{a} {model}")
            if ref is not None:
                ax.plot(
                    ref[0],
                    ref[1][:, i] * 1e3,
                    color=f"C{i}",
                    linestyle="--",
                    linewidth=1.0,
                    label=f"{a} {ref[2]}",
                )
        ax.set_ylabel("tip position (mm)")
        ax.legend(loc="upper right", fontsize="small", ncol=2 if ref is not None else 1)
        ax.grid(True, alpha=0.3)
        for k in range(self.n_channels):
            colour = f"C{(k + 3) % 10}"
            axp.plot(self.time, self.pressure[:, k] / 1e3, color=colour, label=f"p{k}")
            axp.plot(
                self.time,
                self.command[:, k] / 1e3,
                color=colour,
                linestyle=":",
                linewidth=1.0,
            )
        from matplotlib.lines import Line2D

        axp.set_xlabel("time (s)")
        axp.set_ylabel("pressure (kPa)")
        handles, _ = axp.get_legend_handles_labels()
        handles.append(Line2D([], [], color="k", linestyle=":", linewidth=1.0, label="command"))
        # Beside the panel: with many channels a legend inside would hide the curves.
        axp.legend(
            handles=handles,
            loc="upper left",
            bbox_to_anchor=(1.01, 1.0),
            fontsize="small",
            frameon=False,
        )
        axp.grid(True, alpha=0.3)
        if title is None:
            title = self.metadata.get("design") or "tip trajectory"
        ax.set_title(str(title))
        fig.tight_layout()
        if path is not None:
            save_figure(fig, path)
        return fig

    def animate(
        self,
        path: str | os.PathLike,
        *,
        fps: float = DEFAULT_FPS,
        speed: float | None = None,
        max_frames: int | None = MAX_FRAMES,
        trail: bool = True,
        elev: float = 20.0,
        azim: float = -60.0,
        dpi: int = 80,
        figsize: tuple[float, float] = (5.0, 5.0),
        progress: Progress = None,
    ) -> Path:
        """Write a 3-D animation of the stored shapes as ``.gif`` or ``.mp4``; returns the path.

        The clip is meant to be watched: ``speed`` (simulated seconds per second of clip)
        defaults to :func:`animation_plan`'s choice, real time for runs up to
        :data:`TARGET_CLIP_S` (15 s) and faster for longer ones so the clip lasts about 15 s;
        at most ``max_frames`` (300) frames are drawn, at ``fps`` (20) or fewer when the clip
        would need more (``max_frames=None``: no cap). Frame j shows the stored shape nearest
        to ``shape_time[0] + j * speed / fps``. Simulate with ``shapes=`` at the plan's
        ``frame_interval_s`` to store just the shapes the clip shows.

        Axes in mm with equal scale, fixed over the whole run; the base is a black square,
        the tip a dot, ``trail`` draws the tip path so far (from the tip samples), a
        trajectory's markers are small red dots (kept with the tip samples, so shown at the
        sample nearest the shape's time: exactly with ``shapes="saved"``), and a label gives
        the time of the shape shown. ``elev``, ``azim``: view angles in degrees. Only
        the moving parts are redrawn per frame (the axes are drawn once), so a frame takes a
        few ms. ``progress``: see :mod:`softrod.progress`; a callable gets
        ``progress(frames_done, n_frames)``.

        GIF is written with Pillow (8-bit palette frames; GIF timing has a resolution of
        10 ms, and identical consecutive frames are merged). MP4 needs the ``ffmpeg``
        program on PATH. Needs at least 2 shapes. The file is written atomically.
        """
        from ..progress import check_progress, reporter

        path = as_path(path)
        suffix = path.suffix.lower()
        if suffix not in ANIMATION_SUFFIXES:
            raise _fail(
                "path",
                str(path),
                f"unknown animation format {path.suffix or '(no suffix)'!r}: the file name must "
                f"end in {' or '.join(ANIMATION_SUFFIXES)}",
            )
        check_progress(progress)
        if self.shape_time.size < 2:
            raise _fail(
                "shape_time",
                f"{self.shape_time.size} shape(s)",
                "an animation needs at least 2 stored shapes (simulate with shapes=...)",
            )
        plan = animation_plan(
            float(self.shape_time[-1] - self.shape_time[0]),
            fps=fps,
            speed=speed,
            max_frames=max_frames,
        )
        if suffix == ".mp4":
            if shutil.which("ffmpeg") is None:
                raise _fail(
                    "path",
                    str(path),
                    "writing .mp4 needs the ffmpeg program on PATH: install ffmpeg "
                    "(e.g. apt install ffmpeg, conda install ffmpeg) or write a .gif",
                )
        frames = self._frame_indices(plan.fps, plan.speed)
        logger.info(
            "animate %s: %d frames at %.3g fps, %.3g x real time, a %.1f s clip",
            path.name,
            frames.size,
            plan.fps,
            plan.speed,
            frames.size / plan.fps,
        )
        t0 = time.perf_counter()
        with (
            reporter(
                progress,
                f"animate {path.name}",
                frames.size,
                lambda done, total: (done, f"{done}/{total} frames"),
            ) as report,
            atomic_path(path) as tmp,
        ):
            # The temporary's name ends in the target's, so the writers pick the format.
            self._render(tmp, frames, plan.fps, trail, elev, azim, dpi, figsize, report)
        logger.info("animate %s: written in %.2f s", path.name, time.perf_counter() - t0)
        return path

    def _frame_indices(self, fps: float, speed: float) -> np.ndarray:
        """Index of the stored shape shown in each frame (nearest in time)."""
        st = self.shape_time
        step = speed / fps  # simulated seconds per frame
        n = int(math.floor((st[-1] - st[0]) / step * (1 + 1e-12))) + 1
        tf = st[0] + np.arange(n) * step
        hi = np.searchsorted(st, tf).clip(1, st.size - 1)
        lo = hi - 1
        return np.where(tf - st[lo] <= st[hi] - tf, lo, hi)

    def _nearest_samples(self, times: np.ndarray) -> np.ndarray:
        """Index of the tip sample nearest each of ``times`` (s)."""
        hi = np.searchsorted(self.time, times).clip(1, max(self.time.size - 1, 1))
        lo = hi - 1
        if self.time.size == 1:
            return np.zeros(np.shape(times), dtype=int)
        return np.where(times - self.time[lo] <= self.time[hi] - times, lo, hi)

    def _animation_scene(self, trail, elev, azim, dpi, figsize):
        """(Figure, Agg canvas, draw) of an animation: ``draw(i)`` shows stored shape i and
        returns the frame's RGBA pixels."""
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        from ..plotting import _equal_box

        fig = Figure(figsize=figsize, dpi=dpi)
        canvas = FigureCanvasAgg(fig)
        # Margins around the 3-D box: its tick and axis labels stand outside the box, and a
        # slender arm's box fills the height (the labels would leave the frame otherwise).
        ax = fig.add_axes((0.06, 0.16, 0.78, 0.72), projection="3d")
        shapes = self.shape_position * 1e3
        tips = self.tip_position * 1e3
        shown = self.time <= self.shape_time[-1]
        _equal_box(ax, np.concatenate([shapes.reshape(-1, 3), tips[shown]]))
        ax.view_init(elev=elev, azim=azim)
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        ax.set_zlabel("z (mm)")
        name = self.metadata.get("design")
        if name:
            ax.set_title(str(name), fontsize="medium")
        base = shapes[0, 0]
        ax.plot([base[0]], [base[1]], [base[2]], marker="s", color="black", linestyle="none")
        (rod,) = ax.plot([], [], [], color="C0", linewidth=3.0, animated=True)
        (tip,) = ax.plot([], [], [], marker="o", color="C0", markeredgecolor="black", animated=True)
        (path_line,) = ax.plot([], [], [], color="C1", linewidth=1.0, alpha=0.8, animated=True)
        label = ax.text2D(0.02, 0.95, "", transform=ax.transAxes, animated=True)
        moving = [path_line, rod, tip, label]
        markers = None if self.marker_position is None else self.marker_position * 1e3
        if markers is not None:
            # Markers are kept with the tip samples: shown at the sample nearest the shape.
            (dots,) = ax.plot(
                [], [], [], marker="o", markersize=3.0, color="C3", linestyle="none", animated=True
            )
            moving.append(dots)
            nearest = self._nearest_samples(self.shape_time)
        # The view is fixed: draw the axes, panes and ticks once and keep the pixels; each
        # frame restores them and draws only the moving artists (blitting on the Agg canvas).
        canvas.draw()
        background = canvas.copy_from_bbox(fig.bbox)
        upto = np.searchsorted(self.time, self.shape_time, side="right")

        def draw(i: int) -> np.ndarray:
            s = shapes[i]
            rod.set_data_3d(s[:, 0], s[:, 1], s[:, 2])
            tip.set_data_3d([s[-1, 0]], [s[-1, 1]], [s[-1, 2]])
            if trail:
                past = tips[: upto[i]]
                path_line.set_data_3d(past[:, 0], past[:, 1], past[:, 2])
            label.set_text(f"t = {self.shape_time[i]:.2f} s")
            if markers is not None:
                m = markers[nearest[i]]
                dots.set_data_3d(m[:, 0], m[:, 1], m[:, 2])
            canvas.restore_region(background)
            for artist in moving:
                ax.draw_artist(artist)
            return np.asarray(canvas.buffer_rgba())

        return fig, canvas, draw

    def _render(self, out: Path, frames, fps, trail, elev, azim, dpi, figsize, report) -> None:
        _fig, canvas, draw = self._animation_scene(trail, elev, azim, dpi, figsize)
        n = len(frames)
        if out.suffix == ".gif":
            from PIL import Image

            images = []
            for j, i in enumerate(frames):
                rgba = draw(int(i))
                img = Image.fromarray(rgba[..., :3].copy(), "RGB")
                images.append(img.quantize(colors=255, method=Image.Quantize.FASTOCTREE))
                if report is not None:
                    report(j + 1, n)
            images[0].save(
                out,
                format="GIF",
                save_all=True,
                append_images=images[1:],
                duration=max(int(round(1000.0 / fps)), 10),
                loop=0,
            )
        else:
            import subprocess

            width, height = canvas.get_width_height()
            command = [
                shutil.which("ffmpeg") or "ffmpeg",
                "-loglevel",
                "error",
                "-y",
                "-f",
                "rawvideo",
                "-pix_fmt",
                "rgba",
                "-s",
                f"{width}x{height}",
                "-r",
                f"{fps:.6g}",
                "-i",
                "-",
                "-vf",
                "pad=ceil(iw/2)*2:ceil(ih/2)*2",  # yuv420p needs even sizes
                "-vcodec",
                "libx264",
                "-pix_fmt",
                "yuv420p",
                str(out),
            ]
            with subprocess.Popen(command, stdin=subprocess.PIPE, stderr=subprocess.PIPE) as proc:
                try:
                    for j, i in enumerate(frames):
                        proc.stdin.write(np.ascontiguousarray(draw(int(i))).tobytes())
                        if report is not None:
                            report(j + 1, n)
                finally:
                    proc.stdin.close()
                err = proc.stderr.read().decode(errors="replace")
            if proc.returncode != 0:
                raise _fail("path", str(out), f"ffmpeg failed ({proc.returncode}): {err.strip()}")


@dataclass(frozen=True)
class AnimationPlan:
    """How a run of ``duration`` s becomes a clip: ``speed`` (simulated s per clip s),
    ``fps`` (frames per clip s), ``n_frames`` and ``frame_interval_s`` (simulated s between
    frames: the ``shapes=`` interval to simulate with)."""

    duration: float
    speed: float
    fps: float
    n_frames: int

    @property
    def frame_interval_s(self) -> float:
        return self.speed / self.fps

    @property
    def clip_s(self) -> float:
        return self.n_frames / self.fps


def animation_plan(
    duration: float,
    *,
    fps: float = DEFAULT_FPS,
    speed: float | None = None,
    max_frames: int | None = MAX_FRAMES,
) -> AnimationPlan:
    """The clip of a ``duration`` s run: ``speed`` None picks real time up to
    :data:`TARGET_CLIP_S` and ``duration / TARGET_CLIP_S`` beyond (a clip of about 15 s);
    ``fps`` is lowered when the clip would need more than ``max_frames`` frames."""
    for name, value in (("fps", fps), ("speed", speed), ("duration", duration)):
        if value is None and name == "speed":
            continue
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float, np.integer, np.floating))
            or not math.isfinite(value)
            or value <= 0
        ):
            raise _fail(name, value, "must be a finite number > 0")
    if max_frames is not None and (
        isinstance(max_frames, bool)
        or not isinstance(max_frames, (int, np.integer))
        or max_frames < 2
    ):
        raise _fail("max_frames", max_frames, "must be an integer >= 2 or None (no cap)")
    duration = float(duration)
    if speed is None:
        speed = max(1.0, duration / TARGET_CLIP_S)
    speed, fps = float(speed), float(fps)
    if max_frames is not None and duration / speed * fps + 1 > max_frames:
        fps = (max_frames - 1) * speed / duration
    n = int(math.floor(duration / (speed / fps) * (1 + 1e-12))) + 1
    return AnimationPlan(duration=duration, speed=speed, fps=fps, n_frames=n)


def _check_path(path, *, must_exist: bool = False) -> Path:
    path = as_path(path)
    if path.suffix.lower() not in TRAJECTORY_SUFFIXES:
        raise _fail(
            "path",
            str(path),
            f"unknown trajectory format {path.suffix or '(no suffix)'!r}: the file name must "
            f"end in {' or '.join(TRAJECTORY_SUFFIXES)}",
        )
    if must_exist and not _is_file(path):
        raise _fail("path", str(path), "no such file")
    return path if must_exist else check_target(path)


def _json_block(raw, key: str) -> dict:
    try:
        value = json.loads(raw if isinstance(raw, str) else raw.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise _fail(key, str(raw)[:80], f"is not valid JSON ({exc})") from None
    except RecursionError:
        raise _fail(key, str(raw)[:80], "is nested too deeply") from None
    if not isinstance(value, dict):
        raise _fail(key, value, "must be a JSON object")
    V.check_depth(value, key)
    return value


def _check_format(version, field: str) -> int:
    """The file layout's version as an int; InputError for one this softrod cannot read."""
    try:
        number = int(version)
    except (TypeError, ValueError):
        number = None
    if number is None or str(number) != str(version) or number < 1:
        raise _fail(field, version, "not a softrod trajectory format version")
    if number > TRAJECTORY_FORMAT:
        raise _fail(
            field,
            version,
            f"written by a newer softrod (trajectory format {number}; this softrod reads "
            f"{', '.join(map(str, _READABLE_FORMATS))}): upgrade softrod to read it",
        )
    if number not in _READABLE_FORMATS:
        raise _fail(field, version, f"unsupported version (this softrod reads {_READABLE_FORMATS})")
    return number


def _load_npz(path: Path) -> Trajectory:
    try:
        data = np.load(path, allow_pickle=False)
    except Exception as exc:  # zipfile / numpy raise several types for broken files
        raise _fail("file", str(path), f"is not a readable .npz file: {exc}") from None
    with data:
        try:
            fmt = str(data["format"]) if "format" in data.files else None
        except Exception as exc:  # a damaged archive: zipfile, zlib and numpy errors
            raise _fail("file", str(path), f"is a damaged .npz file: {exc}") from None
        if fmt is None or not fmt.startswith(_NPZ_FORMAT + "/"):
            raise _fail("format", fmt, "not a softrod trajectory file (written by save)")
        _check_format(fmt.split("/", 1)[1], "format")
        missing = [n for n in (*_FIELDS, "metadata_json") if n not in data.files]
        if missing:
            raise _fail("arrays", sorted(data.files), f"missing {', '.join(missing)}")
        try:
            arrays = {n: data[n] for n in _FIELDS}
            # Optional: files written before they existed load with none.
            arrays.update(
                {
                    n: data[n]
                    for n in (
                        *ENERGY_PARTS,
                        "tension",
                        "contact_force",
                        "penetration",
                        "tip_reaction_force",
                        "tip_reaction_moment",
                        *_MARKER_FIELDS,
                    )
                    if n in data.files
                }
            )
            meta_text = str(data["metadata_json"])
        except Exception as exc:  # a damaged archive: zipfile, zlib and numpy errors
            raise _fail("file", str(path), f"is a damaged .npz file: {exc}") from None
        meta = _json_block(meta_text, "metadata_json")
    return Trajectory(**arrays, metadata=meta)


def _load_parquet(path: Path) -> Trajectory:
    import pyarrow.parquet as pq

    try:
        table = pq.read_table(path)
    except Exception as exc:  # pyarrow raises its own error types for broken files
        raise _fail("file", str(path), f"is not a readable Parquet file: {exc}") from None
    kv = table.schema.metadata or {}
    if _PARQUET_KEY not in kv:
        raise _fail("file", str(path), "not a softrod trajectory (no softrod.trajectory metadata)")
    layout = _json_block(kv[_PARQUET_KEY], _PARQUET_KEY.decode())
    version = _check_format(layout.get("format"), "softrod.trajectory.format")
    meta = _json_block(kv.get(_META_KEY, b"{}"), _META_KEY.decode())
    marker_ids = {
        int(m[1])
        for name in table.column_names
        if name.endswith("_m") and (m := _MARKER.match(name[:-2]))
    }
    # Where the markers sit: the metadata block a dataset has, read by the dataset's reader
    # (its errors name metadata.markers.marker<k>).
    sites = _marker_sites(meta.get("markers"), len(marker_ids)) if marker_ids else None
    for key in layout.get("table_metadata", ["columns"]):
        meta.pop(key, None)  # e.g. the declaration of the result columns, added by save
    c = layout.get("n_channels")
    if not isinstance(c, int) or isinstance(c, bool) or c < 0:
        raise _fail("softrod.trajectory.n_channels", c, "must be an integer >= 0")
    n_tendons = layout.get("n_tendons", 0)  # absent in files written before tensions
    if not isinstance(n_tendons, int) or isinstance(n_tendons, bool) or n_tendons < 0:
        raise _fail("softrod.trajectory.n_tendons", n_tendons, "must be an integer >= 0")
    names = set(table.column_names)

    def col(name: str) -> np.ndarray:
        if name not in names:
            raise _fail("columns", sorted(names), f"missing column {name!r}")
        return table.column(name).to_numpy().astype(float, copy=False)

    n = table.num_rows

    def cols(fmt: str, keys) -> np.ndarray:
        keys = list(keys)
        if not keys:
            return np.zeros((n, 0))
        return np.column_stack([col(fmt.format(k)) for k in keys])

    time = col("time_s")
    rotation = cols("{}", _ROT).reshape(n, 3, 3)
    ss = np.asarray(layout.get("shape_s_m", []), dtype=float)
    shapes = table.column("shape_m").combine_chunks() if "shape_m" in names else None
    if shapes is None:
        raise _fail("columns", sorted(names), "missing column 'shape_m'")
    has = shapes.is_valid().to_numpy(zero_copy_only=False)
    values = shapes.flatten().to_numpy(zero_copy_only=False).astype(float, copy=False)
    k, p = int(has.sum()), ss.size
    if values.size != k * p * 3:
        raise _fail(
            "shape_m",
            f"{values.size} values in {k} rows",
            f"each shape row must hold {p} nodes x 3 = {3 * p} values (shape_s_m has {p})",
        )
    return Trajectory(
        time=time,
        command=cols("cmd{}_Pa", range(c)),
        pressure=cols("p{}_Pa", range(c)),
        tension=cols("t{}_N", range(n_tendons)),
        tip_position=cols("tip_{}_m", _XYZ),
        tip_rotation=rotation,
        tip_velocity=cols("tip_v{}_m_s" if version == 1 else "tip_v{}_m/s", _XYZ),
        energy=col("energy_J"),
        **{p: col(f"{p}_J") for p in ENERGY_PARTS if f"{p}_J" in names},
        **(
            {"contact_force": cols("contact_f{}_N", _XYZ), "penetration": col("penetration_m")}
            if "penetration_m" in names
            else {}
        ),
        **(
            {
                "tip_reaction_force": cols("tip_reaction_f{}_N", _XYZ),
                "tip_reaction_moment": cols("tip_reaction_m{}_Nm", _XYZ),
            }
            if "tip_reaction_fx_N" in names
            else {}
        ),
        shape_time=time[has],
        shape_s=ss,
        shape_position=values.reshape(k, p, 3),
        **(
            {
                "marker_position": np.stack(
                    [cols(f"marker{j}_{{}}_m", _XYZ) for j in range(len(marker_ids))], axis=1
                ),
                "marker_s": sites[0],
                "marker_offset": sites[1],
            }
            if sites is not None
            else {}
        ),
        metadata=meta,
    )


_REF_NAME = re.compile(r"^(?P<base>time|tip_[xyz])_(?P<unit>.+)$")


def _reference(reference) -> tuple[np.ndarray, np.ndarray, str]:
    """(time in s, tip position in m, label) of a reference for :meth:`Trajectory.plot_tip`."""
    from ..datasets import Dataset

    if isinstance(reference, Trajectory):
        return reference.time, reference.tip_position, "reference"
    if isinstance(reference, Dataset):
        if reference.time is None:
            raise _fail("reference", repr(reference), "the dataset has no time column")
        return reference.time, reference.tip_position, "measured"
    if isinstance(reference, pd.DataFrame):
        found: dict[str, np.ndarray] = {}
        for name in reference.columns:
            m = _REF_NAME.match(str(name))
            if m is None:
                continue
            kind = "time" if m["base"] == "time" else "length"
            factor = _unit_factor(m["unit"], kind, str(name))
            found[m["base"]] = pd.to_numeric(reference[name]).to_numpy(dtype=float) * factor
        missing = [b for b in ("time", "tip_x", "tip_y", "tip_z") if b not in found]
        if missing:
            raise _fail(
                "reference",
                list(map(str, reference.columns)),
                f"missing column(s) {', '.join(missing)} with units in the name "
                "(e.g. time_s, tip_x_mm, tip_y_mm, tip_z_mm)",
            )
        pos = np.column_stack([found["tip_x"], found["tip_y"], found["tip_z"]])
        return found["time"], pos, "measured"
    if isinstance(reference, tuple) and len(reference) == 2:
        t = _array(reference[0], "reference[0]", (None,), "times in s")
        pos = _array(reference[1], "reference[1]", (t.size, 3), f"(m = {t.size}, 3) in m")
        return t, pos, "measured"
    raise _fail(
        "reference",
        type(reference).__name__,
        "must be a Trajectory, a Dataset with times, a DataFrame (time_s, tip_x_mm, ...) or "
        "a tuple (time in s, position in m (m, 3))",
    )
