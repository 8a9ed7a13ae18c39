"""Pressure schedules: the commanded chamber pressures of a simulation as functions of time.

A :class:`PressureSchedule` maps a time t (s) to one gauge pressure per channel (Pa), the
commands that :func:`softrod.simulate` feeds to the pressure supply of the design (which may
lag or rate-limit them; that is the model's business, not the schedule's). Schedules are
immutable and SI inside; files carry their units in the column names like datasets
(``time_s``, ``p0_kPa``, ``p1_bar``; docs/datasets.md).

Kinds:

- ``"linear"``: piecewise-linear interpolation between knots;
- ``"step"``: zero-order hold, the value at ``times[i]`` holds until ``times[i + 1]``;
- ``"callable"``: a Python function of t.

For the table kinds the first value holds before the first knot and the last value after the
last knot. Pressures are gauge pressures and must be >= -101325 Pa (:data:`VACUUM_PA`, a
perfect vacuum); every value must be finite.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from .. import _validate as V
from ..datasets import (
    DEFAULT_UNITS,
    _check_duplicates,
    _fail,
    _number_column,
    _read_csv,
    _read_parquet,
    _unit_factor,
    _Where,
)
from ..errors import InputError
from ..io import TABLE_SUFFIXES, as_path, atomic_path, check_table_path, write_parquet_with_metadata
from ..io import is_file as _is_file
from ..io import metadata_json as _metadata_json
from ..schema import channel_index

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from ..design import Design

__all__ = ["KINDS", "VACUUM_PA", "PressureSchedule"]

VACUUM_PA = V.VACUUM_PA  # the lowest gauge pressure there is (absolute zero at 1 atm ambient)
KINDS = ("linear", "step")  # kinds of tabulated schedules (files and constructors)

# Schedule columns: time_<unit> and p<k>_<unit> (the datasets' base names and unit rules).
_COLUMN = re.compile(r"^(?P<base>time|p(?:0|[1-9][0-9]*))(?:_(?P<unit>.*))?$")
_FILE_KEY = "schedule_kind"  # the kind, recorded in the file's metadata by write()


def _is_int(x) -> bool:
    return isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_))


def _times(values, field: str = "times") -> np.ndarray:
    """Knot times: 1-d, non-empty, finite, >= 0, strictly increasing (s)."""
    t = V.real_array(values, field, max_size=V.MAX_ROWS, what="times (s)")
    if t.ndim != 1 or t.size == 0:
        raise _fail(field, f"shape {t.shape}", "must be a non-empty 1-d array of times (s)")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise _fail(f"{field}[{bad[0]}]", t[bad[0]].item(), "must be finite (s)")
    bad = np.flatnonzero(t < 0)
    if bad.size:
        raise _fail(f"{field}[{bad[0]}]", t[bad[0]].item(), "must be >= 0 s")
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        i = bad[0] + 1
        raise _fail(
            f"{field}[{i}]",
            t[i].item(),
            f"times must be strictly increasing, but {field}[{i - 1}] = {t[i - 1]:g} s",
        )
    return t


def _pressures(values, n: int | None, field: str = "pressures") -> np.ndarray:
    """(n, channels) finite gauge pressures >= VACUUM_PA (Pa)."""
    p = V.real_array(values, field, max_size=V.MAX_ROWS * V.MAX_CHANNELS, what="pressures (Pa)")
    if p.ndim != 2 or p.shape[1] < 1 or p.shape[1] > V.MAX_CHANNELS:
        raise _fail(
            field,
            f"shape {p.shape}",
            "must be an (n, channels) array in Pa, one row per time and one column per channel "
            "(for one channel use shape (n, 1))",
        )
    if n is not None and p.shape[0] != n:
        raise _fail(field, f"shape {p.shape}", f"needs one row per time: {n} rows")
    _check_values(p, lambda i: f"{field}[{i}]")
    return p


def _check_values(p: np.ndarray, name: Callable[[int], str]) -> None:
    """Finite and >= vacuum, row by row; ``name(row)`` names a row in the message."""
    rows = np.flatnonzero(~np.isfinite(p).all(axis=1))
    if rows.size:
        i = rows[0]
        raise _fail(name(i), p[i].tolist(), "pressures must be finite (Pa)")
    rows = np.flatnonzero((p < VACUUM_PA).any(axis=1))
    if rows.size:
        i = rows[0]
        raise _fail(
            name(i),
            p[i].tolist(),
            f"gauge pressures must be >= {VACUUM_PA:g} Pa (a perfect vacuum)",
        )


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


def _n_channels(n, field: str = "n_channels") -> int:
    return V.integer(n, field, minimum=1, maximum=V.MAX_CHANNELS)


def _positive(x, field: str, *, zero: bool = False) -> float:
    return V.real(x, field, minimum=0.0, exclusive=not zero, what="a number of seconds")


class PressureSchedule:
    """Commanded gauge pressures of ``n_channels`` channels as a function of time (Pa).

    Make one with :meth:`piecewise_linear`, :meth:`steps`, :meth:`constant`,
    :meth:`square_pulses`, :meth:`paper000_square_pulses`, :meth:`from_file` or
    :meth:`from_callable`. Immutable: ``times`` and ``pressures`` are read-only arrays.

    Attributes: ``kind`` ("linear", "step" or "callable"); ``times`` (n,) knot times in s and
    ``pressures`` (n, channels) knot pressures in Pa (None for callables); ``n_channels``;
    ``t_end`` (the last knot time in s; None for callables); ``fn`` (the callable or None).
    """

    __slots__ = ("_fn", "_kind", "_n", "_pressures", "_times")

    def __init__(
        self,
        kind: str,
        times: ArrayLike,
        pressures: ArrayLike,
        fn: Callable[[float], Sequence[float]] | None = None,
        n_channels: int | None = None,
    ):
        """Internal: use the class methods. ``kind``: "linear", "step" or "callable"."""
        set_ = object.__setattr__
        if kind == "callable":
            if not callable(fn):
                raise _fail("fn", fn, "must be callable: fn(t in s) -> pressures in Pa")
            set_(self, "_kind", kind)
            set_(self, "_times", None)
            set_(self, "_pressures", None)
            set_(self, "_fn", fn)
            set_(self, "_n", _n_channels(n_channels))
            return
        if kind not in KINDS:
            raise _fail("kind", kind, f"must be one of {', '.join(map(repr, KINDS))}")
        t = _times(times)
        p = _pressures(pressures, t.size)
        set_(self, "_kind", kind)
        set_(self, "_times", _readonly(t))
        set_(self, "_pressures", _readonly(p))
        set_(self, "_fn", None)
        set_(self, "_n", p.shape[1])

    def __setattr__(self, name, value):
        raise AttributeError(f"PressureSchedule is immutable: cannot set {name!r}")

    def __delattr__(self, name):
        raise AttributeError(f"PressureSchedule is immutable: cannot delete {name!r}")

    def __reduce__(self):  # pickle and copy through the constructor (attributes are frozen)
        return (type(self), (self._kind, self._times, self._pressures, self._fn, self._n))

    # --- constructors ------------------------------------------------------------------------

    @classmethod
    def piecewise_linear(cls, times: ArrayLike, pressures: ArrayLike) -> PressureSchedule:
        """Linear interpolation between knots ``(times[i], pressures[i])``.

        ``times``: (n,) s, finite, >= 0, strictly increasing. ``pressures``: (n, channels)
        gauge pressures in Pa, finite, >= -101325 Pa. The first value holds before
        ``times[0]`` and the last after ``times[-1]``.
        """
        return cls("linear", times, pressures)

    @classmethod
    def steps(cls, times: ArrayLike, pressures: ArrayLike) -> PressureSchedule:
        """Zero-order hold: ``pressures[i]`` holds on ``[times[i], times[i + 1])``.

        Same arguments and rules as :meth:`piecewise_linear`; the first value also holds
        before ``times[0]`` and the last after ``times[-1]``.
        """
        return cls("step", times, pressures)

    @classmethod
    def constant(cls, pressures: ArrayLike) -> PressureSchedule:
        """The same pressures (one per channel: Pa, or strings with units as
        :func:`~softrod.solve_statics` takes them) at all times: a step schedule with its
        single knot at t = 0 (so ``t_end`` is 0)."""
        if isinstance(pressures, (list, tuple)) and any(isinstance(x, str) for x in pressures):
            pressures = [
                V.quantity(x, "pressure", f"pressures[{i}]") for i, x in enumerate(pressures)
            ]
        if not _numeric(pressures) or np.ndim(pressures) != 1:
            raise _fail(
                "pressures", pressures, "must be a 1-d sequence of pressures, one per channel (Pa)"
            )
        return cls("step", [0.0], V.real_array(pressures, "pressures")[None, :])

    @classmethod
    def from_callable(
        cls, fn: Callable[[float], Sequence[float]], n_channels: int
    ) -> PressureSchedule:
        """A schedule computed by ``fn(t)``: t in s (a float) -> ``n_channels`` pressures in Pa.

        ``fn`` is called once per sample time by :meth:`sample`, which checks every result
        (length ``n_channels``, finite, >= -101325 Pa) and names the time in its error.
        ``t_end`` is None: the caller of :func:`softrod.simulate` gives the end time.
        """
        return cls("callable", None, None, fn=fn, n_channels=n_channels)

    @classmethod
    def square_pulses(
        cls,
        n_channels: int,
        pulses: Sequence[tuple[int | Sequence[int], float | Sequence[float], float]],
        *,
        rest: float = 5.0,
        start: float = 0.0,
        base: float | ArrayLike = 0.0,
    ) -> PressureSchedule:
        """Square pressure pulses separated by rests: a step schedule (zero-order hold).

        ``pulses``: a sequence of ``(channels, pressure, duration)``:

        - ``channels``: a channel index or a sequence of them (0-based);
        - ``pressure``: gauge pressure in Pa of those channels during the pulse, one number
          for all of them or one per listed channel. It is the absolute level, not added to
          ``base``; the channels not listed stay at ``base``;
        - ``duration``: length of the pulse in s (> 0).

        The timeline is: ``base`` on ``[0, start)``; pulse 1 on ``[start, start + d1)``;
        ``base`` for ``rest`` s; pulse 2; ... ; the last pulse, then ``base`` from its end on
        (no rest is appended after the last pulse). So
        ``t_end = start + sum(durations) + rest * (len(pulses) - 1)``, the end of the last
        pulse. ``base``: the rest pressure in Pa, one number or one per channel (default 0).
        ``rest``, ``start``: s, >= 0. With ``rest = 0`` pulses follow each other directly.

        Example (paper 000, Fig. 3 style: each PAM in turn, 5 s pulses, 5 s rests)::

            S = PressureSchedule.square_pulses(
                3, [(0, 1.2e5, 5.0), (1, 1.2e5, 5.0), (2, 1.2e5, 5.0), (0, 2.4e5, 5.0)],
                rest=5.0, start=1.0)
            # t_end = 1 + 4 * 5 + 3 * 5 = 36 s
        """
        n = _n_channels(n_channels)
        rest = _positive(rest, "rest", zero=True)
        start = _positive(start, "start", zero=True)
        if not _numeric(base) or np.ndim(base) > 1 or (np.ndim(base) == 1 and np.size(base) != n):
            raise _fail("base", base, f"must be one pressure or one per channel ({n}), Pa")
        b = np.broadcast_to(V.real_array(base, "base", what="pressures (Pa)"), (n,)).copy()
        _check_values(b[None, :], lambda i: "base")
        if isinstance(pulses, (str, bytes)) or not isinstance(pulses, Sequence) or not pulses:
            raise _fail(
                "pulses", pulses, "must be a non-empty sequence of (channels, pressure, duration)"
            )
        if len(pulses) > V.MAX_ROWS // 2:
            raise _fail("pulses", f"{len(pulses)} pulses", f"too many: at most {V.MAX_ROWS // 2}")
        times: list[float] = []
        rows: list[np.ndarray] = []

        def knot(t: float, p: np.ndarray) -> None:
            if times and t == times[-1]:  # zero-length rest: the new level replaces the old
                rows[-1] = p
            else:
                times.append(t)
                rows.append(p)

        t = 0.0
        if start > 0:
            knot(0.0, b.copy())
            t = start
        for i, pulse in enumerate(pulses):
            field = f"pulses[{i}]"
            if not isinstance(pulse, Sequence) or isinstance(pulse, str) or len(pulse) != 3:
                raise _fail(field, pulse, "must be a tuple (channels, pressure in Pa, duration s)")
            channels, level, duration = pulse
            chans = [channels] if _is_int(channels) else channels
            if (
                not isinstance(chans, Sequence)
                or isinstance(chans, str)
                or not chans
                or not all(_is_int(c) for c in chans)
            ):
                raise _fail(f"{field}.channels", channels, "must be a channel index or a list")
            bad = [c for c in chans if not 0 <= c < n]
            if bad:
                raise _fail(f"{field}.channels", channels, f"channels are 0 ... {n - 1}")
            if len(set(chans)) != len(chans):
                raise _fail(f"{field}.channels", channels, "lists a channel twice")
            if not _numeric(level) or np.ndim(level) > 1:
                raise _fail(f"{field}.pressure", level, "must be a number or a list (Pa)")
            lv = V.real_array(level, f"{field}.pressure", what="pressures (Pa)")
            if lv.ndim == 1 and lv.size != len(chans):
                raise _fail(
                    f"{field}.pressure",
                    level,
                    f"one pressure for all channels or one per listed channel ({len(chans)})",
                )
            p = b.copy()
            p[list(chans)] = lv
            _check_values(p[None, :], lambda _, field=field: f"{field}.pressure")
            d = _positive(duration, f"{field}.duration")
            if i > 0 and rest > 0:
                knot(t, b.copy())
                t += rest
            knot(t, p)
            t += d
        knot(t, b.copy())
        return cls("step", times, np.array(rows))

    @classmethod
    def paper000_square_pulses(
        cls,
        *,
        n_channels: int = 3,
        levels: Sequence[float] = (0.9e5, 1.8e5, 2.7e5, 3.6e5),
        duration: float = 5.0,
        rest: float = 5.0,
        start: float = 1.0,
    ) -> PressureSchedule:
        """A 116 s sequence in the style of paper 000's dynamic validation (Sec. IV, Fig. 3).

        REPRESENTATIVE, NOT THE PAPER'S DATA: paper 000 shows its input pulses only as a
        plot; it does not publish their magnitudes or order in numbers. What it states, and
        what this follows: alternating square pulses applied independently to each of the
        three PAMs, 5 s each, of varying magnitudes up to 3.6 bar (a 3.6 bar pulse is active
        at 115 s), the robot at rest at zero pressure before the start, a 116 s run.

        Sequence (defaults): zero on [0, 1) s; then for each level in ``levels`` (Pa; 0.9,
        1.8, 2.7, 3.6 bar) a pulse on channel 0, then 1, ..., then ``n_channels - 1``, each
        ``duration`` s, separated by ``rest`` s at zero: 12 pulses, the last one on channel 2
        at 3.6 bar on [111, 116) s; ``t_end`` = 116 s. See :meth:`square_pulses` for the
        exact timeline. Designed for ``designs/pam_arm_220mm.toml`` (3 channels).
        """
        n = _n_channels(n_channels)
        if isinstance(levels, (str, bytes)) or not isinstance(levels, Sequence) or not levels:
            raise _fail("levels", levels, "must be a non-empty sequence of pressures (Pa)")
        pulses = [(ch, level, duration) for level in levels for ch in range(n)]
        return cls.square_pulses(n, pulses, rest=rest, start=start)

    @classmethod
    def from_file(
        cls, path: str | os.PathLike, *, kind: str | None = None, extra: str = "error"
    ) -> PressureSchedule:
        """Read a tabulated schedule from a CSV or Parquet file.

        Columns: ``time_<unit>`` (e.g. ``time_s``, ``time_ms``) and ``p0_<unit>``,
        ``p1_<unit>``, ... numbered from 0 without gaps (``p0_kPa``, ``p0_Pa``, ``p0_bar``),
        with the unit conventions of datasets (a unit in the name or in a ``# units: {...}``
        comment line / ``softrod.units`` Parquet metadata; docs/datasets.md). One row per
        knot; times strictly increasing, >= 0; values finite, pressures >= -101325 Pa.

        ``kind``: "linear" or "step"; None (default) takes the kind that :meth:`write`
        recorded in the file's metadata, else "linear". ``extra``: "error" (default) rejects
        other columns; "ignore" skips them (e.g. the tip columns of a measured dataset).
        Raises :class:`InputError` naming the file, the column, the value and the row (CSV:
        line numbers as a text editor shows them; Parquet: 0-based rows).
        """
        if kind is not None and kind not in KINDS:
            raise _fail("kind", kind, f"must be one of {', '.join(map(repr, KINDS))} or None")
        if extra not in ("error", "ignore"):
            raise _fail("extra", extra, "must be 'error' or 'ignore'")
        path = as_path(path)
        if path.suffix.lower() not in TABLE_SUFFIXES:
            check_table_path(path)  # raises with the list of formats
        if not _is_file(path):
            raise _fail("path", str(path), "no such file")
        reader = _read_csv if path.suffix.lower() == ".csv" else _read_parquet
        try:
            df, units, meta, where = reader(path)
            t, p = _from_frame(df, units, where, extra)
            recorded = meta.get(_FILE_KEY)
            if recorded is not None and recorded not in KINDS:
                raise _fail(f"metadata.{_FILE_KEY}", recorded, f"must be one of {KINDS}")
            chosen = kind or recorded or "linear"
            return cls(chosen, t, p)
        except InputError as exc:
            exc.args = (f"{path.name}: {exc.args[0]}",)
            raise

    # --- properties --------------------------------------------------------------------------

    @property
    def kind(self) -> str:
        """ "linear", "step" or "callable"."""
        return self._kind

    @property
    def n_channels(self) -> int:
        """Number of pressure channels (columns of :meth:`sample`)."""
        return self._n

    @property
    def times(self) -> np.ndarray | None:
        """(n,) knot times in s (read-only), None for a callable schedule."""
        return self._times

    @property
    def pressures(self) -> np.ndarray | None:
        """(n, channels) knot pressures in Pa (read-only), None for a callable schedule."""
        return self._pressures

    @property
    def fn(self) -> Callable | None:
        """The function of a callable schedule, else None."""
        return self._fn

    @property
    def t_end(self) -> float | None:
        """Time of the last knot in s (after it the last value holds); None for callables."""
        return None if self._times is None else float(self._times[-1])

    def __repr__(self) -> str:
        if self._kind == "callable":
            return f"PressureSchedule(callable, {self._n} channels, fn={self._fn!r})"
        return (
            f"PressureSchedule({self._kind}, {self._n} channels, {self._times.size} knots, "
            f"t_end = {self.t_end:g} s, max {self._pressures.max() / 1e3:g} kPa)"
        )

    # --- evaluation --------------------------------------------------------------------------

    def sample(self, times: ArrayLike) -> np.ndarray:
        """Commanded pressures at ``times`` (s; a number or a 1-d array): (len(times),
        n_channels) in Pa. A number gives one row. Times must be finite; they may lie before
        the first or after the last knot (the end values hold there)."""
        t = np.atleast_1d(V.real_array(times, "times", max_size=V.MAX_ROWS, what="times (s)"))
        if t.ndim != 1:
            raise _fail("times", f"shape {t.shape}", "must be a number or a 1-d array (s)")
        if self._kind == "callable":
            return self._call(t)
        kt, kp = self._times, self._pressures
        if self._kind == "step":
            idx = np.searchsorted(kt, t, side="right") - 1
            return kp[np.clip(idx, 0, kt.size - 1)].copy()
        # A loop over the (few) channels; np.interp holds the end values outside the knots.
        return np.column_stack([np.interp(t, kt, kp[:, k]) for k in range(self._n)])

    def _call(self, t: np.ndarray) -> np.ndarray:
        out = np.empty((t.size, self._n))
        for i, ti in enumerate(t):
            raw = self._fn(float(ti))
            row = V.real_array(
                raw, f"fn(t = {ti:g} s)", max_size=V.MAX_CHANNELS, what="numbers (Pa)"
            )
            if row.ndim == 0 and self._n == 1:
                row = row.reshape(1)
            if row.shape != (self._n,):
                raise _fail(
                    f"fn(t = {ti:g} s)",
                    raw,
                    f"must return a sequence of {self._n} pressures (Pa), one per channel; "
                    f"got shape {row.shape}",
                )
            _check_values(row[None, :], lambda _, ti=ti: f"fn(t = {ti:g} s)")
            out[i] = row
        return out

    def check_channels(self, n: int | Design) -> None:
        """Raise :class:`InputError` unless the schedule has ``n`` channels (an int, or an
        object with ``n_channels`` such as a :class:`~softrod.Design`)."""
        what = f"{n}"
        if hasattr(n, "n_channels"):
            name = getattr(n, "name", None)
            what = f"design {name!r} has {n.n_channels}" if name else f"{n.n_channels}"
            n = n.n_channels
        n = _n_channels(n, "n")
        if n != self._n:
            raise _fail(
                "pressure_schedule.n_channels",
                self._n,
                f"must equal the number of pressure channels ({what}): give one pressure "
                "column per channel, numbered like the design's chambers",
            )

    # --- tables and files --------------------------------------------------------------------

    def to_frame(self, times: ArrayLike | None = None) -> pd.DataFrame:
        """A DataFrame with ``time_s`` and ``p0_kPa``, ``p1_kPa``, ... at ``times`` (s).

        Without ``times``: the knots (required for a callable schedule).
        ``frame.attrs["softrod.metadata"]`` records the kind.
        """
        if times is None:
            if self._kind == "callable":
                raise _fail("times", None, "a callable schedule needs times to tabulate")
            t = np.array(self._times)
            p = np.array(self._pressures)
        else:
            t = np.atleast_1d(V.real_array(times, "times", what="times (s)"))
            p = self.sample(t)
        cols = {"time_s": t}
        for k in range(self._n):
            cols[f"p{k}_kPa"] = p[:, k] / 1e3
        frame = pd.DataFrame(cols)
        kind = "linear" if self._kind == "callable" else self._kind
        frame.attrs["softrod.metadata"] = {_FILE_KEY: kind}
        return frame

    def write(self, path: str | os.PathLike, *, times: ArrayLike | None = None) -> Path:
        """Write the schedule to a CSV or Parquet file (by suffix), atomically.

        The columns are those of :meth:`to_frame` (``time_s``, ``p<k>_kPa``); the kind goes
        into the metadata (CSV: a ``# metadata: {...}`` comment line; Parquet: the
        ``softrod.metadata`` entry) so :meth:`from_file` reads the same schedule back. A
        callable schedule needs ``times`` and is written as a linear table of its samples.
        Returns the path.
        """
        path = check_table_path(path)
        frame = self.to_frame(times)
        meta = _metadata_json(frame.attrs["softrod.metadata"])
        with atomic_path(path) as tmp:
            if path.suffix.lower() == ".csv":
                with open(tmp, "w", encoding="utf-8", newline="") as fh:
                    fh.write("# softrod pressure schedule (docs/dynamics.md)\n")
                    fh.write(f"# metadata: {meta}\n")
                    frame.to_csv(fh, index=False, lineterminator="\n")
            else:
                write_parquet_with_metadata(frame, tmp, meta)
        return path


def _numeric(x) -> bool:
    """True if ``x`` is a number or nested sequences of numbers (no bools, text, complex or
    masked values)."""
    if V.is_real(x):
        return True
    try:
        V.real_array(x, "x", max_size=V.MAX_ROWS * V.MAX_CHANNELS)
    except InputError:
        return False
    return True


def _from_frame(df: pd.DataFrame, units: dict, where: _Where, extra: str):
    """(times in s, pressures in Pa) of a schedule table, checked."""
    names = [str(c) for c in df.columns]
    _check_duplicates(names)
    for k, v in units.items():
        if not isinstance(v, str):
            raise _fail(f"units.{k}", v, "must map a column name to a unit string")
    unused = sorted(set(units) - set(names))
    if unused:
        raise _fail(f"units.{unused[0]}", units[unused[0]], f"names no column (columns: {names})")
    columns: dict[str, tuple[str, float]] = {}
    unknown = []
    for name in names:
        m = _COLUMN.match(name)
        if m is None:
            unknown.append(name)
            continue
        base, unit = m["base"], m["unit"]
        if base != "time":
            channel_index(base, name)
        kind = "time" if base == "time" else "pressure"
        if unit is not None and name in units:
            raise _fail(name, units[name], "unit given twice: in the column name and units block")
        unit = unit if unit is not None else units.get(name)
        if unit is None:
            raise _fail(
                name,
                "no unit",
                f"a {kind} column needs a unit in its name, e.g. {base}_{DEFAULT_UNITS[kind]}",
            )
        if base in columns:
            raise _fail("columns", [columns[base][0], name], f"both give {base}: keep one")
        columns[base] = (name, _unit_factor(unit, kind, name))
    if unknown and extra == "error":
        raise _fail(
            "columns",
            unknown,
            "unknown column(s) for a pressure schedule; it has time_<unit> and p0_<unit>, "
            "p1_<unit>, ... (e.g. time_s, p0_kPa); pass extra='ignore' to skip other columns",
        )
    channels = sorted(int(b[1:]) for b in columns if b != "time")
    missing = [b for b in ("time",) if b not in columns] + ([] if channels else ["p0"])
    if missing:
        spelled = ", ".join("time_s" if b == "time" else "p0_kPa" for b in missing)
        raise _fail(
            "columns",
            names,
            f"missing column(s) {', '.join(missing)} (spelled e.g. {spelled}); a schedule "
            "needs a time column and pressure columns p0, p1, ...",
        )
    gaps = sorted(set(range(channels[-1] + 1)) - set(channels))
    if gaps:
        raise _fail(
            "columns",
            [columns[f"p{k}"][0] for k in channels],
            "pressure channels must be numbered p0, p1, ... without gaps: "
            f"{', '.join(f'p{k}' for k in gaps)} missing",
        )
    if len(df) == 0:
        raise _fail("rows", 0, "the table has no data rows")
    if len(df) > V.MAX_ROWS:
        raise _fail("rows", len(df), f"too many rows: at most {V.MAX_ROWS:,}")
    values = {}
    for base, (col, factor) in columns.items():
        values[base] = _number_column(df[col], col, where) * factor
    t = values["time"]
    tcol = columns["time"][0]
    bad = np.flatnonzero(t < 0)
    if bad.size:
        raise _fail(tcol, t[bad[0]].item(), f"times must be >= 0, at {where(bad)}")
    bad = np.flatnonzero(np.diff(t) <= 0) + 1
    if bad.size:
        raw = df[tcol].iloc[bad[0]]
        raise _fail(
            tcol,
            raw.item() if isinstance(raw, np.generic) else raw,
            f"times must be strictly increasing, at {where(bad)} (each is <= the time before)",
        )
    p = np.column_stack([values[f"p{k}"] for k in channels])
    bad = np.flatnonzero((p < VACUUM_PA).any(axis=1))
    if bad.size:
        raise _fail(
            ", ".join(columns[f"p{k}"][0] for k in channels),
            p[bad[0]].tolist(),
            f"gauge pressures must be >= {VACUUM_PA:g} Pa (a perfect vacuum), at {where(bad)}",
        )
    return t, p


if TYPE_CHECKING:
    #: What ``simulate`` takes as a schedule: a PressureSchedule, a CSV/Parquet file of
    #: commands, a function of t (s) returning one pressure per channel (Pa), or constant
    #: pressures (Pa, or strings with units).
    ScheduleLike = (
        PressureSchedule | str | os.PathLike[str] | Callable[[float], Sequence[float]] | ArrayLike
    )
