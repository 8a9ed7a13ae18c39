"""Axial-only identification of a multi-chamber actuator (paper 004, Secs. 2.3-3.1).

From two axial measurements (docs/calibration-axial.md):

- blocked force: the axial force F (N) at the fixed reference length L0 against the chamber
  pressure p (Pa, all chambers equal), which gives the chamber force law
  F(p) = k p (+ b) and the effective chamber area A_eff = k / n_chambers;
- free elongation: the length L (m) of the pressurised, unloaded actuator against p, which
  gives the extensional stiffness E (N) of paper 004 eq. 23 through F(p) = E (L - L0)/L0,
  either one constant E or a force-dependent E(F);

then the bending stiffness of eqs. 29-31 with E_II = E_III = 0 and E_I = E / j,
B = (j/2) E_I r_I^2 L/L0 = (E r_I^2 / 2) L/L0, with r_I the chambers' distance from the
centreline, and a ready design (:meth:`AxialIdentification.to_design`).

Fits (all linear least squares, standard errors from the residual variance):

- force: ``"proportional"`` F = k p, or ``"affine"`` F = k p + b. The intercept b is read as a
  force offset of the set-up (sensor tare) and reported; the chamber force the model applies
  is always k p = n_chambers A_eff p.
- elongation, in strain e = (L - L0)/(L0 - rigid_length) against pressure:
  ``stiffness="constant"``: e = s1 p, so E = k / s1 (eq. 23 with F = k p);
  ``stiffness="table"``: e = s1 p + s2 p^2 (the progressive curve of Sec. 3.1), so the secant
  stiffness E(F) = F / e = 1 / (c1 + c2 F) with c1 = s1/k, c2 = s2/k^2. This smooth law is
  monotone in F for any c1, c2 and needs no derivative of noisy data; per-point secants
  F_i / e_i would amplify the length noise at small strains. It is written as softrod's
  ``axial = "table"`` law at the force of every measured pressure level (and 0), where the
  design reproduces the fit exactly. With an unknown L0 the fit has an intercept
  (L = a0 + a1 p [+ a2 p^2], L0 = a0), else it goes through the origin in strain.

The chamber force F(p) measured at L0 is used at every length, as the paper does (Sec. 3.1).
Everything inside is SI (Pa, N, m); printed values state their units.
"""

from __future__ import annotations

import copy
import math
import os
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from .._threads import one_blas_thread
from ..catalog import load_design
from ..datasets import (
    _checked_metadata,
    _fail,
    _read_csv,
    _runs,
    _unit_factor,
    _Where,
)
from ..design import PACKAGE_DIR, Design
from ..errors import InputError
from ..io import atomic_path, check_target
from ..io import exists as _exists
from ..io import is_file as _is_file
from ..io import metadata_json as _metadata_json
from ..units import to_si

__all__ = [
    "AXIAL_EXAMPLE",
    "AxialData",
    "AxialIdentification",
    "FitQuality",
    "axial_example_paths",
    "calibrate_axial",
    "identify_axial",
    "load_axial_data",
    "synthesize_axial_data",
    "write_axial_data",
]

FORCE_LAWS = ("proportional", "affine")
STIFFNESS_LAWS = ("constant", "table")

# Per-chamber pressure columns (p0, p1, ...) must agree within this fraction of the largest
# pressure of the table: the identification assumes all chambers at one pressure (paper 004
# Sec. 3.1, "always equally"); a larger spread is a different experiment (it bends the
# actuator). 1 % of 96 kPa is about 1 kPa.
EQUAL_PRESSURE_RTOL = 0.01

# Chamber distances of one section must agree within this (relative): eqs. 15, 20 and 28
# put all chambers on one circle of radius r_I.
_DISTANCE_RTOL = 1e-9

_COLUMN = re.compile(
    r"^(?P<base>pressure|force|length|p(?:0|[1-9][0-9]*))"
    r"(?:\s*\[(?P<bracket>[^\]]*)\]|_(?P<suffix>.+))?$"
)
_EXAMPLES_DIR = PACKAGE_DIR / "data" / "examples" / "axial"


# --- data ------------------------------------------------------------------------------------


def _readonly(a) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


def _rows(idx) -> str:
    return f"row{'s' if len(idx) > 1 else ''} {_runs(idx)}"


def _check_rows(name: str, values: np.ndarray, bad: np.ndarray, rule: str, where) -> None:
    """InputError naming the rows where ``bad`` holds (``where`` formats row positions)."""
    idx = np.flatnonzero(bad)
    if idx.size:
        raise _fail(name, values[idx[0]].item(), f"{rule}, at {where(idx)}")


def _is_channel(base: str) -> bool:
    """A per-chamber pressure column (p0, p1, ...)."""
    return re.fullmatch(r"p[0-9]+", base) is not None


def _levels(p: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct pressures (sorted) and the mean of ``y`` at each."""
    levels, inverse = np.unique(p, return_inverse=True)
    return levels, np.bincount(inverse, weights=y) / np.bincount(inverse)


@dataclass(frozen=True, eq=False, repr=False)
class AxialData:
    """Axial measurements of one actuator, SI (paper 004 Sec. 3.1).

    force_pressure, force: (m_f,) chamber pressure (Pa, gauge, all chambers equal) and axial
    force (N, positive pushing) with the actuator held at its reference length L0.
    length_pressure, length: (m_l,) pressure (Pa) and length (m) of the unloaded actuator.
    n_chambers: chambers pressurised together (the force is their sum, eq. 22).
    L0: unpressurised length (m) of what ``length`` measures, or None to fit it.
    rigid_length: stiff parts (end caps) included in ``length`` (m); the strain is
    (L - L0) / (L0 - rigid_length), the chambers' stretch L_c/L_c0 - 1 of Sec. 3.1.
    metadata: dict; ``metadata["synthetic"]`` is True for generated data.
    sources: the files read (force, length) or None.

    Rows at the same pressure are repeats of one pressure level (give set-point pressures);
    the mean force and the mean length must increase strictly from level to level.
    """

    force_pressure: np.ndarray
    force: np.ndarray
    length_pressure: np.ndarray
    length: np.ndarray
    n_chambers: int = 3
    L0: float | None = None
    rigid_length: float = 0.0
    metadata: dict = field(default_factory=lambda: {"synthetic": False})
    sources: tuple[Path, Path] | None = None

    def __post_init__(self):
        set_ = object.__setattr__
        n = self.n_chambers
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise _fail("n_chambers", n, "must be an integer >= 1")
        set_(self, "n_chambers", int(n))
        for p_name, y_name, kind in (
            ("force_pressure", "force", "force"),
            ("length_pressure", "length", "length"),
        ):
            p, y = _readonly(getattr(self, p_name)), _readonly(getattr(self, y_name))
            if p.ndim != 1 or p.shape != y.shape:
                raise _fail(
                    f"{p_name}, {y_name}",
                    f"shapes {p.shape}, {y.shape}",
                    "must be 1-d arrays of equal length (one row per measurement)",
                )
            for name, a in ((p_name, p), (y_name, y)):
                _check_rows(name, a, ~np.isfinite(a), "must be finite", _rows)
            _check_rows(p_name, p, p < 0, "must be >= 0 (gauge pressure, Pa)", _rows)
            if kind == "length":
                _check_rows(y_name, y, y <= 0, "must be > 0 (m)", _rows)
            _check_increasing(p, y, y_name, "N" if kind == "force" else "mm")
            set_(self, p_name, p)
            set_(self, y_name, y)
        rigid = self.rigid_length
        if (
            isinstance(rigid, bool)
            or not isinstance(rigid, (int, float))
            or not 0 <= rigid < math.inf
        ):
            raise _fail("rigid_length", rigid, "must be a length >= 0 (m)")
        set_(self, "rigid_length", float(rigid))
        if self.L0 is not None:
            L0 = self.L0
            if isinstance(L0, bool) or not isinstance(L0, (int, float)) or not math.isfinite(L0):
                raise _fail("L0", L0, "must be a length (m) or None (fitted)")
            if not L0 > self.rigid_length:
                raise _fail("L0", L0, f"must exceed rigid_length = {self.rigid_length:g} m")
            set_(self, "L0", float(L0))
        set_(self, "metadata", _checked_metadata(self.metadata))

    @property
    def synthetic(self) -> bool:
        """True for data generated by :func:`synthesize_axial_data` (not measurements)."""
        return bool(self.metadata["synthetic"])

    def __repr__(self) -> str:
        def span(p):
            return f"{p.min() / 1e3:g}-{p.max() / 1e3:g} kPa"

        parts = [
            f"force: {self.force.size} rows, {span(self.force_pressure)}",
            f"length: {self.length.size} rows, {span(self.length_pressure)}",
            f"{self.n_chambers} chambers",
        ]
        if self.synthetic:
            parts.append("SYNTHETIC")
        return f"AxialData({'; '.join(parts)})"

    def to_frames(self) -> tuple[pd.DataFrame, pd.DataFrame]:
        """(force table, length table) with units in the column names (kPa, N, mm);
        ``attrs["softrod.metadata"]`` keeps the metadata for :func:`load_axial_data`."""
        force = pd.DataFrame({"pressure [kPa]": self.force_pressure / 1e3, "force [N]": self.force})
        length = pd.DataFrame(
            {"pressure [kPa]": self.length_pressure / 1e3, "length [mm]": self.length * 1e3}
        )
        for frame in (force, length):
            frame.attrs["softrod.metadata"] = dict(self.metadata)
        return force, length


def _check_increasing(p: np.ndarray, y: np.ndarray, name: str, unit: str) -> None:
    """Level means must increase strictly with pressure (and there must be two levels)."""
    levels, means = _levels(p, y)
    if levels.size < 2:
        raise _fail(
            name,
            f"{p.size} rows at {levels.size} pressure level(s)",
            "too few points: at least two pressure levels are needed",
        )
    scale = 1e3 if unit == "mm" else 1.0
    drop = np.flatnonzero(np.diff(means) <= 0)
    if drop.size:
        steps = ", ".join(
            f"{levels[i] / 1e3:g} -> {levels[i + 1] / 1e3:g} kPa "
            f"({means[i] * scale:.6g} -> {means[i + 1] * scale:.6g} {unit})"
            for i in drop[:5]
        )
        raise _fail(
            name,
            "non-monotone",
            f"the mean {name} per pressure level must increase strictly with pressure; it does "
            f"not at {steps}",
        )


# --- loading and writing ---------------------------------------------------------------------


def _read_table(source, value: str, n_chambers: int, extra: str, rtol: float):
    """(pressure Pa, values SI, metadata, path) from a CSV path or a DataFrame."""
    path = None
    if isinstance(source, pd.DataFrame):
        names = list(source.columns)
        bad = [c for c in names if not isinstance(c, str)]
        if bad:
            raise _fail("columns", bad, "column names must be strings")
        df = source.reset_index(drop=True)
        block: dict = dict(source.attrs.get("softrod.units", {}))
        meta = dict(source.attrs.get("softrod.metadata", {}))
        where = _Where("index", labels=tuple(source.index))
    elif isinstance(source, (str, os.PathLike)):
        path = Path(source)
        bundled = _EXAMPLES_DIR / f"{source}.csv"
        if path.suffix == "" and not _exists(path) and _is_file(bundled):
            path = bundled  # a bundled example by name, e.g. modular_axial_force_synthetic
        if path.suffix.lower() != ".csv":
            raise _fail("path", str(path), "must be a .csv file (or pass a DataFrame)")
        if not _is_file(path):
            raise _fail("path", str(path), "no such file")
        df, block, meta, where = _read_csv(path)
    else:
        raise _fail(value, type(source).__name__, "must be a .csv path or a pandas DataFrame")

    columns: dict[str, tuple[str, float]] = {}  # base -> (column, SI factor)
    unknown = []
    for name in (str(c) for c in df.columns):
        m = _COLUMN.match(name.strip())
        base = None if m is None else m["base"]
        if base is None or base not in ("pressure", value) and not _is_channel(base):
            unknown.append(name)
            continue
        unit = m["bracket"] if m["bracket"] is not None else m["suffix"]
        if unit is None:
            unit = block.get(name)
        elif name in block:
            raise _fail(name, block[name], "unit given twice: in the name and the units block")
        col_kind = value if base == value else "pressure"
        if unit is None:
            example = {"pressure": "kPa", "force": "N", "length": "mm"}[col_kind]
            raise _fail(name, "no unit", f"a {col_kind} column needs a unit: '{base} [{example}]'")
        if base in columns:
            raise _fail("columns", [columns[base][0], name], f"both give {base}: keep one")
        columns[base] = (name, _unit_factor(unit, col_kind, name))
    if unknown and extra == "error":
        raise _fail(
            "columns",
            unknown,
            f"unknown column(s) in the {value} table; known: 'pressure [unit]' (or per-chamber "
            f"'p0 [unit]', 'p1 [unit]', ...) and '{value} [unit]' (pass extra='ignore' to skip "
            "other columns)",
        )
    channels = sorted(int(b[1:]) for b in columns if _is_channel(b))
    if "pressure" in columns and channels:
        raise _fail("columns", list(df.columns), "give 'pressure' or p0, p1, ..., not both")
    if channels and channels != list(range(n_chambers)):
        raise _fail(
            "columns",
            [columns[f"p{k}"][0] for k in channels],
            f"per-chamber pressures must be p0 ... p{n_chambers - 1} (n_chambers = {n_chambers})",
        )
    missing = [value] if value not in columns else []
    if "pressure" not in columns and not channels:
        missing.insert(0, "pressure")
    if missing:
        raise _fail(
            "columns",
            list(df.columns),
            f"missing {' and '.join(missing)} column(s) in the {value} table, e.g. "
            f"'pressure [kPa]', '{value} [{'N' if value == 'force' else 'mm'}]'",
        )
    if len(df) == 0:
        raise _fail("rows", 0, f"the {value} table has no data rows")
    used = [columns[b][0] for b in columns]
    isna = df[used].isna().to_numpy()
    if isna.any():
        rows = np.flatnonzero(isna.any(axis=1))
        cols = [c for k, c in enumerate(used) if isna[:, k].any()]
        raise _fail(
            ", ".join(cols),
            "empty/NaN",
            f"empty or NaN values in {rows.size} row(s) at {where(rows)}; fill or delete them",
        )
    si: dict[str, np.ndarray] = {}
    for base, (col, factor) in columns.items():
        values = pd.to_numeric(df[col], errors="coerce")
        text = np.flatnonzero(values.isna().to_numpy())
        if text.size:
            raise _fail(col, df[col].iloc[text[0]], f"not a number at {where(text)}")
        a = values.to_numpy(dtype=float)
        _check_rows(col, a, ~np.isfinite(a), "must be finite", where)
        si[base] = a * factor
    if channels:
        per = np.column_stack([si[f"p{k}"] for k in channels])
        spread = per.max(axis=1) - per.min(axis=1)
        limit = rtol * per.max()
        _check_rows(
            ", ".join(columns[f"p{k}"][0] for k in channels),
            spread / 1e3,
            spread > limit,
            f"chamber pressures differ by more than {limit / 1e3:g} kPa (EQUAL_PRESSURE_RTOL = "
            f"{rtol:g} of the largest): the axial identification needs equal pressures",
            where,
        )
        pressure = per.mean(axis=1)
    else:
        pressure = si["pressure"]
    p_col = columns["pressure" if "pressure" in columns else "p0"][0]
    _check_rows(p_col, pressure / 1e3, pressure < 0, "must be >= 0 (gauge pressure)", where)
    if value == "length":
        _check_rows(columns[value][0], si[value], si[value] <= 0, "must be > 0", where)
    return pressure, si[value], meta, path


def load_axial_data(
    force,
    length,
    *,
    n_chambers: int = 3,
    L0=None,
    rigid_length=0.0,
    extra: str = "error",
    equal_pressure_rtol: float = EQUAL_PRESSURE_RTOL,
) -> AxialData:
    """Read and check axial measurements from two CSV files or DataFrames.

    ``force``: blocked-force table, columns ``pressure [kPa]`` and ``force [N]``; ``length``:
    free-elongation table, ``pressure [kPa]`` and ``length [mm]``. Any unit pint knows works,
    written ``name [unit]`` or ``name_unit`` or in a ``# units: {...}`` comment line.
    Instead of ``pressure``, per-chamber columns ``p0 [kPa]`` ... ``p<n-1> [kPa]`` may be
    given; they must agree within ``equal_pressure_rtol`` of the largest pressure and their
    mean is used. ``L0`` and ``rigid_length``: lengths ("44.8 mm" or metres), see
    :class:`AxialData`. ``extra="ignore"`` skips unknown columns (default: an error).

    Raises :class:`~softrod.errors.InputError` naming the column, the value, the rule and the
    rows (CSV line numbers as an editor shows them; DataFrame index labels).
    """
    if extra not in ("error", "ignore"):
        raise _fail("extra", extra, "must be 'error' or 'ignore'")
    if isinstance(n_chambers, bool) or not isinstance(n_chambers, int) or n_chambers < 1:
        raise _fail("n_chambers", n_chambers, "must be an integer >= 1")
    L0 = None if L0 is None else to_si(L0, "length", "L0", InputError)
    rigid = to_si(rigid_length, "length", "rigid_length", InputError)
    sources = {"force": force, "length": length}

    def located(exc: InputError, value: str) -> InputError:
        """The error with the table it concerns in front (file name, or force/length)."""
        source = sources[value]
        name = Path(source).name if isinstance(source, (str, os.PathLike)) else value
        exc.args = (f"{name}: {exc.args[0]}",)
        return exc

    tables = {}
    for value, source in sources.items():
        try:
            tables[value] = _read_table(source, value, n_chambers, extra, equal_pressure_rtol)
        except InputError as exc:
            raise located(exc, value) from None
    (pf, f, meta_f, path_f), (pl, ln, meta_l, path_l) = tables["force"], tables["length"]
    if meta_f == meta_l:
        meta = dict(meta_f)
    else:
        synthetic = any(bool(m.get("synthetic", False)) for m in (meta_f, meta_l))
        meta = {"synthetic": synthetic, "force": meta_f, "length": meta_l}
    paths = (path_f, path_l) if path_f is not None and path_l is not None else None
    try:
        return AxialData(pf, f, pl, ln, n_chambers, L0, rigid, meta, paths)
    except InputError as exc:  # level checks (monotone, enough levels) name their table
        for value in sources:
            if exc.field.startswith(value):
                raise located(exc, value) from None
        raise


def write_axial_data(data: AxialData, force_path, length_path) -> tuple[Path, Path]:
    """Write ``data`` as two CSV files (kPa, N, mm), each whole or not at all.

    The first line says whether the data is synthetic; a ``# metadata: {...}`` line keeps
    the metadata. ``n_chambers``, ``L0`` and ``rigid_length`` are not stored in the files
    (give them to :func:`load_axial_data`). Returns the two paths.
    """
    if not isinstance(data, AxialData):
        raise _fail("data", type(data).__name__, "must be an AxialData")
    paths = (Path(force_path), Path(length_path))
    for p in paths:
        if p.suffix.lower() != ".csv":
            raise _fail("path", str(p), "must end in .csv")
    meta = _metadata_json(data.metadata)
    if data.synthetic:
        first = "# SYNTHETIC softrod axial data: generated by synthesize_axial_data, not measured"
    else:
        first = "# softrod axial data"
    frames = data.to_frames()
    what = ("blocked force at the reference length", "free elongation, unloaded")
    with atomic_path(paths[0]) as tmp_f, atomic_path(paths[1]) as tmp_l:
        for tmp, frame, about in zip((tmp_f, tmp_l), frames, what, strict=True):
            with open(tmp, "w", encoding="utf-8", newline="") as fh:
                fh.write(f"{first}\n# {about}; docs/calibration-axial.md\n# metadata: {meta}\n")
                frame.to_csv(fh, index=False, lineterminator="\n")
    return paths


# --- least squares ---------------------------------------------------------------------------


@dataclass(frozen=True)
class FitQuality:
    """Quality of one linear least-squares fit.

    n: rows; dof: rows minus parameters; rms: root-mean-square residual in ``unit``;
    r_squared: 1 - SSR/SST with SST about the mean of the fitted quantity.
    """

    n: int
    dof: int
    rms: float
    r_squared: float
    unit: str


def _lstsq(X: np.ndarray, y: np.ndarray, p: np.ndarray, what: str, model: str):
    """coef, covariance (residual variance times (X^T X)^-1), residuals, dof.

    Columns are scaled to unit maximum first: p and p^2 in Pa differ by 1e5.
    """
    n, k = X.shape
    scale = np.abs(X).max(axis=0)
    scale[scale == 0] = 1.0
    Xs = X / scale
    if n < k + 1 or np.linalg.matrix_rank(Xs) < k:
        raise _fail(
            what,
            f"{n} rows at {np.unique(p).size} pressure level(s)",
            f"too few points for the {model} fit ({k} parameter(s)): it needs {k} distinct "
            f"pressure levels (other than 0 for a fit through the origin) and at least {k + 1} "
            "rows, one more than parameters for a standard error",
        )
    coef_s, *_ = np.linalg.lstsq(Xs, y, rcond=None)
    res = y - Xs @ coef_s
    dof = n - k
    cov_s = (res @ res / dof) * np.linalg.inv(Xs.T @ Xs)
    return coef_s / scale, cov_s / np.outer(scale, scale), res, dof


def _quality(y: np.ndarray, res: np.ndarray, dof: int, factor: float, unit: str) -> FitQuality:
    sst = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - float(res @ res) / sst if sst > 0 else float("nan")
    return FitQuality(y.size, dof, float(np.sqrt(np.mean(res**2))) * factor, r2, unit)


def _strain_fit(data: AxialData, degree: int):
    """Strain law e(p) = sum_k s_k p^k (k = 1..degree) from the length data.

    Returns (s, cov_s, L0, L0_se, length residuals in m, quality). With an unknown L0 the
    length itself is fitted, L = a0 + (a0 - r) e(p), i.e. L = a0 + a1 p + ..., and
    s_k = a_k / (a0 - r) with its covariance by the delta method.
    """
    p, L, r = data.length_pressure, data.length, data.rigid_length
    powers = np.column_stack([p**k for k in range(1, degree + 1)])
    model = "constant-E" if degree == 1 else "E(F)"
    if data.L0 is not None:
        span = data.L0 - r
        y = (L - data.L0) / span
        s, cov, res, dof = _lstsq(powers, y, p, "length", f"{model} (L0 given)")
        return s, cov, data.L0, 0.0, res * span, _quality(y, res, dof, span, "m")
    X = np.column_stack([np.ones_like(p), powers])
    a, cov_a, res, dof = _lstsq(X, L, p, "length", f"{model} (L0 fitted)")
    span = a[0] - r
    if not span > 0:
        raise _fail("L0", a[0], f"the fitted L0 must exceed rigid_length = {r:g} m")
    s = a[1:] / span
    J = np.zeros((degree, degree + 1))  # d s_k / d (a0, a1, ...)
    J[:, 0] = -s / span
    J[:, 1:] = np.eye(degree) / span
    return s, J @ cov_a @ J.T, a[0], math.sqrt(cov_a[0, 0]), res, _quality(L, res, dof, 1, "m")


# --- identification --------------------------------------------------------------------------


@dataclass(frozen=True, eq=False, repr=False)
class AxialIdentification:
    """Result of :func:`identify_axial`. SI; ``*_se`` are standard errors.

    force_slope (N/Pa) = dF/dp of all chambers together; force_offset (N): the intercept of
    the affine law (0 for proportional), a set-up offset not applied by the model.
    A_eff (m^2): effective area per chamber, force_slope / n_chambers.
    L0 (m): reference length (given: se 0). E (N): constant extensional stiffness (eq. 23),
    the degree-1 fit also in table mode, where it sets the bending stiffness.
    compliance (table mode): (c1 in 1/N, c2 in 1/N^2) of E(F) = 1 / (c1 + c2 F).
    table_force, table_stiffness (N): E(F) at 0 and at the force of each length-data pressure
    level (table mode; None otherwise). force_residuals (N), length_residuals (m): data minus
    fit, in the order of the data rows.
    """

    data: AxialData
    force_law: str
    stiffness: str
    n_chambers: int
    force_slope: float
    force_slope_se: float
    force_offset: float
    force_offset_se: float
    A_eff: float
    A_eff_se: float
    L0: float
    L0_se: float
    L0_fitted: bool
    E: float
    E_se: float
    strain_coefficients: np.ndarray  # (s1[, s2]): e = s1 p + s2 p^2, 1/Pa and 1/Pa^2
    compliance: tuple[float, float] | None
    compliance_se: tuple[float, float] | None
    table_force: np.ndarray | None
    table_stiffness: np.ndarray | None
    table_stiffness_se: np.ndarray | None
    force_residuals: np.ndarray
    length_residuals: np.ndarray
    force_quality: FitQuality
    length_quality: FitQuality

    def chamber_force(self, pressure) -> np.ndarray:
        """Axial force of all chambers (N) at equal pressure (Pa): n A_eff p (eq. 22)."""
        return self.force_slope * np.asarray(pressure, dtype=float)

    def predict_force(self, pressure) -> np.ndarray:
        """The fitted blocked-force law (N), offset included."""
        return self.chamber_force(pressure) + self.force_offset

    def predict_strain(self, pressure) -> np.ndarray:
        """Chamber strain L_c/L_c0 - 1 of the unloaded actuator at pressure (Pa)."""
        p = np.asarray(pressure, dtype=float)
        return sum(s * p ** (k + 1) for k, s in enumerate(self.strain_coefficients))

    def predict_length(self, pressure) -> np.ndarray:
        """Length (m) of the unloaded actuator at pressure (Pa), as measured by the data."""
        return self.L0 + (self.L0 - self.data.rigid_length) * self.predict_strain(pressure)

    def stiffness_at(self, force) -> np.ndarray:
        """Extensional stiffness (N) at axial force (N): E, or E(F) = 1/(c1 + c2 F)."""
        f = np.asarray(force, dtype=float)
        if self.compliance is None:
            return np.full_like(f, self.E)
        c1, c2 = self.compliance
        return 1.0 / (c1 + c2 * f)

    def bending_stiffness(self, r_I: float, stretch=1.0):
        """B = (j/2) E_I r_I^2 L/L0 with E_I = E/j, E_II = E_III = 0 (eqs. 29-31), N m^2."""
        return 0.5 * self.E * r_I**2 * np.asarray(stretch, dtype=float)

    def summary(self) -> str:
        """The identified values with units and standard errors, as printed text."""
        d, fq, lq = self.data, self.force_quality, self.length_quality

        def kpa(p):
            return f"{p.min() / 1e3:g}-{p.max() / 1e3:g} kPa"

        law = "F = k p" if self.force_law == "proportional" else "F = k p + b"
        lines = [
            "Axial identification (paper 004, eqs. 22-23, 29-31)"
            + (" -- SYNTHETIC data" if d.synthetic else ""),
            f"  blocked force: {fq.n} rows, {kpa(d.force_pressure)}, {self.force_law} {law}",
            f"    k = dF/dp    {self.force_slope * 1e3:.5g} N/kPa  "
            f"(se {self.force_slope_se * 1e3:.2g})",
        ]
        if self.force_law == "affine":
            lines.append(
                f"    b (offset)   {self.force_offset:.4g} N  (se {self.force_offset_se:.2g}), "
                "not applied by the model"
            )
        lines += [
            f"    A_eff        {self.A_eff * 1e6:.5g} mm^2 per chamber  (se "
            f"{self.A_eff_se * 1e6:.2g}), {self.n_chambers} chambers",
            f"    fit          rms {fq.rms:.3g} N, R^2 {fq.r_squared:.6f}, dof {fq.dof}",
            f"  free elongation: {lq.n} rows, {kpa(d.length_pressure)}, "
            + ("constant E" if self.stiffness == "constant" else "E(F) = 1/(c1 + c2 F)"),
            f"    L0           {self.L0 * 1e3:.5g} mm  "
            + (f"(fitted, se {self.L0_se * 1e3:.2g})" if self.L0_fitted else "(given)"),
            f"    E (constant) {self.E:.5g} N  (se {self.E_se:.2g})",
        ]
        if self.compliance is not None:
            (c1, c2), (e1, e2) = self.compliance, self.compliance_se
            lines += [
                f"    c1           {c1:.5g} 1/N  (se {e1:.2g})",
                f"    c2           {c2:.5g} 1/N^2  (se {e2:.2g})",
                "    E(F) table   F [N]: " + " ".join(f"{x:.4g}" for x in self.table_force),
                "                 E [N]: " + " ".join(f"{x:.4g}" for x in self.table_stiffness),
            ]
        lines += [
            f"    fit          rms {lq.rms * 1e3:.3g} mm, R^2 {lq.r_squared:.6f}, dof {lq.dof}",
            "  bending: B = (j/2) E_I r_I^2 L_c/L_c0 = (E r_I^2 / 2) L_c/L_c0 "
            "(E_I = E/j, E_II = E_III = 0)",
        ]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def __repr__(self) -> str:
        return (
            f"AxialIdentification(A_eff={self.A_eff * 1e6:.5g} mm^2, E={self.E:.5g} N, "
            f"stiffness={self.stiffness!r}, force_law={self.force_law!r})"
        )

    def to_design(self, base_design, out_path=None, *, name: str | None = None) -> Design:
        """A design with the identified stiffnesses and chamber areas, optionally written.

        Every elastic section of ``base_design`` with chambers gets: each chamber's ``area``
        = A_eff (a ``radius`` stays for the geometry); ``stiffness="constant"``: the
        partition of eqs. 23, 29-31, ``[sections.partition] j = n_chambers, E_I = E/j,
        r_I = the chambers' distance`` (E_II = E_III = 0), so EA = E and B = (E r_I^2/2) v3;
        ``stiffness="table"``: ``[sections.law] axial = "table"`` with E(F), ``EI = E r_I^2/2``
        and nominal ``EA = E`` (E the constant fit) and ``stretch_bending = true``. Direct
        EA/EI/EI1/EI2 and the factors c_e, c_b of those sections are removed (the identified
        values are the stiffnesses). ``[design].assumptions`` gains a line saying what was
        identified from which data; ``name`` renames the design (default: "<base>_axial").

        ``out_path`` (``.toml``): the design is written there atomically (whole or not at all;
        nothing is written when any check fails) and loaded back from the file.
        """
        base = load_design(base_design)
        if out_path is not None and Path(out_path).suffix.lower() != ".toml":
            raise _fail("out_path", str(out_path), "must end in .toml")
        if out_path is not None:
            try:
                check_target(out_path)
            except InputError as exc:
                raise _fail("out_path", str(out_path), exc.rule) from None
        changes: dict = {}
        described, r_I = [], set()
        for i, (sec, spec) in enumerate(
            zip(base.document["sections"], base.spec["sections"], strict=True)
        ):
            if spec["rigid"] or not spec["chambers"]:
                continue
            changes[f"sections[{i}]"] = self._section(sec, spec, i)
            described.append(spec["name"])
            r_I.add(spec["chambers"][0]["distance"])
        if not changes:
            raise _fail(
                "base_design", base.name, "has no elastic section with chambers to calibrate"
            )
        changes["design.assumptions"] = [*base.assumptions, self._assumption(described, r_I)]
        changes["design.name"] = name if name is not None else f"{base.name}_axial"
        design = base.replace(changes)
        if out_path is None:
            return design
        import tomli_w

        header = (
            f"# Written by softrod.calibration.axial from design {base.name!r}: stiffness and "
            "chamber areas\n# identified from axial measurements (see [design].assumptions).\n"
        )
        with atomic_path(out_path) as tmp:
            tmp.write_text(header + tomli_w.dumps(design.document), encoding="utf-8")
        return load_design(out_path)

    def _section(self, sec: Mapping, spec: Mapping, i: int) -> dict:
        """The document table of section i with the identified law and chamber areas."""
        where = f"sections[{i}]"
        chambers = spec["chambers"]
        if len(chambers) != self.n_chambers:
            raise _fail(
                f"{where}.chambers",
                f"{len(chambers)} chambers",
                f"the data was taken with n_chambers = {self.n_chambers}",
            )
        dist = np.array([c["distance"] for c in chambers])
        if np.ptp(dist) > _DISTANCE_RTOL * dist.max():
            raise _fail(
                f"{where}.chambers",
                f"distances {dist * 1e3} mm",
                "must be equal: paper 004's partition puts all chambers on one circle r_I",
            )
        law = dict(sec.get("law", {}))
        for key in ("c_p", "p_ref", "stiffness_map"):
            if law.get(key, False) is not False:
                raise _fail(
                    f"{where}.law.{key}",
                    law[key],
                    "changes the chamber force or stiffness with pressure, which the axial "
                    "identification (chamber force A_eff p) does not model; remove it first",
                )
        out = copy.deepcopy(dict(sec))
        for key in ("EA", "EI", "EI1", "EI2", "c_e", "c_b", "partition"):
            out.pop(key, None)
        for key in ("axial", "alpha", "axial_force", "axial_stiffness", "stretch_bending"):
            law.pop(key, None)
        r_I = float(dist[0])
        if self.stiffness == "constant":
            out["partition"] = {  # eqs. 23, 29-31 with E_II = E_III = 0
                "j": self.n_chambers,
                "E_I": f"{self.E / self.n_chambers:.12g} N",
                "r_I": f"{r_I * 1e3:.12g} mm",
            }
        else:
            # The table gives the axial strain; EA (the constant fit) is the nominal value the
            # design format requires with direct stiffnesses.
            out["EA"] = f"{self.E:.12g} N"
            out["EI"] = f"{float(self.bending_stiffness(r_I)):.12g} N*m^2"
            law.update(
                axial="table",
                axial_force=[f"{x:.12g} N" for x in self.table_force],
                axial_stiffness=[f"{x:.12g} N" for x in self.table_stiffness],
                stretch_bending=True,
            )
        if law:
            out["law"] = law
        else:
            out.pop("law", None)
        out["chambers"] = [
            {**c, "area": f"{self.A_eff * 1e6:.12g} mm^2"} for c in out.get("chambers", [])
        ]
        return out

    def _assumption(self, sections: list[str], r_I: set[float]) -> str:
        d = self.data
        src = d.sources
        force_src = "blocked-force data" + (f" {src[0].name}" if src else "")
        length_src = "free-elongation data" + (f" {src[1].name}" if src else "")
        synthetic = " (SYNTHETIC data)" if d.synthetic else ""
        r_text = ", ".join(f"{r * 1e3:.5g}" for r in sorted(r_I))
        if self.stiffness == "constant":
            stiff = (
                f"E = {self.E:.5g} +- {self.E_se:.2g} N (constant, eq. 23) from {length_src} "
                f"({d.length.size} rows, L0 = {self.L0 * 1e3:.5g} mm), set as "
                f"[sections.partition] j = {self.n_chambers}, E_I = E/j, E_II = E_III = 0"
            )
        else:
            stiff = (
                f"E(F) = 1/(c1 + c2 F) from {length_src} ({d.length.size} rows, L0 = "
                f"{self.L0 * 1e3:.5g} mm), set as axial = 'table' at {self.table_force.size} "
                f"forces; bending EI = E r_I^2/2 with the constant fit E = {self.E:.5g} N, "
                "times the stretch"
            )
        return (
            f"Axial identification (softrod.calibration.axial, paper 004 Sec. 3.1){synthetic}: "
            f"chamber area A_eff = {self.A_eff * 1e6:.5g} +- {self.A_eff_se * 1e6:.2g} mm^2 "
            f"from {force_src} ({d.force.size} rows, {self.force_law} law); {stiff}; "
            f"r_I = chamber distance {r_text} mm, so B = (E r_I^2/2) L_c/L_c0 (eqs. 29-31); "
            f"sections {', '.join(sections)} (these replace the base design's stiffness and "
            "chamber area)."
        )


@one_blas_thread
def identify_axial(
    data: AxialData, *, force_law: str = "proportional", stiffness: str = "constant"
) -> AxialIdentification:
    """Identify A_eff, E (or E(F)) and thereby B from axial measurements (paper 004).

    ``force_law``: "proportional" (F = k p, the paper's finding) or "affine" (F = k p + b,
    b reported as an offset). ``stiffness``: "constant" (one E) or "table" (E(F) = 1/(c1 +
    c2 F), written as softrod's ``axial = "table"`` law). See the module docstring for the
    fits. Raises :class:`~softrod.errors.InputError` if the data cannot support the fit.
    """
    if not isinstance(data, AxialData):
        raise _fail("data", type(data).__name__, "must be an AxialData (see load_axial_data)")
    if force_law not in FORCE_LAWS:
        raise _fail("force_law", force_law, f"must be one of {', '.join(FORCE_LAWS)}")
    if stiffness not in STIFFNESS_LAWS:
        raise _fail("stiffness", stiffness, f"must be one of {', '.join(STIFFNESS_LAWS)}")
    n = data.n_chambers

    # Chamber force law (eq. 22: F = sum of the chamber forces), fitted at L = L0.
    pf, f = data.force_pressure, data.force
    X = pf[:, None] if force_law == "proportional" else np.column_stack([pf, np.ones_like(pf)])
    kb, cov_f, res_f, dof_f = _lstsq(X, f, pf, "force", force_law)
    k, k_se = float(kb[0]), math.sqrt(cov_f[0, 0])
    if not k > 0:
        raise _fail("force", f"dF/dp = {k:.4g} N/Pa", "the fitted force must grow with pressure")
    b, b_se = (float(kb[1]), math.sqrt(cov_f[1, 1])) if force_law == "affine" else (0.0, 0.0)

    # Constant E (eq. 23): e = F/E = (k/E) p, so E = k / s1; the relative variances add
    # (independent experiments).
    s, cov_s, L0, L0_se, res_l, quality_l = _strain_fit(data, 1)
    if not s[0] > 0:
        raise _fail("length", f"strain/pressure = {s[0]:.4g} 1/Pa", "must grow with pressure")
    E = k / s[0]
    E_se = E * math.hypot(math.sqrt(cov_s[0, 0]) / s[0], k_se / k)

    compliance = compliance_se = table_f = table_e = table_se = None
    if stiffness == "table":
        # e = s1 p + s2 p^2 with p = F/k: E(F) = F/e = 1/(c1 + c2 F), c1 = s1/k, c2 = s2/k^2.
        s, cov_s, L0, L0_se, res_l, quality_l = _strain_fit(data, 2)
        c1, c2 = s[0] / k, s[1] / k**2
        Jc = np.array([[1 / k, 0.0, -s[0] / k**2], [0.0, 1 / k**2, -2 * s[1] / k**3]])
        cov = np.zeros((3, 3))  # (s1, s2, k), the two experiments independent
        cov[:2, :2], cov[2, 2] = cov_s, k_se**2
        cov_c = Jc @ cov @ Jc.T
        compliance = (float(c1), float(c2))
        compliance_se = (math.sqrt(cov_c[0, 0]), math.sqrt(cov_c[1, 1]))
        table_f = k * np.concatenate(
            [[0.0], np.unique(data.length_pressure[data.length_pressure > 0])]
        )
        denom = c1 + c2 * table_f
        if not np.all(denom > 0):
            raise _fail(
                "length",
                f"c1 = {c1:.4g} 1/N, c2 = {c2:.4g} 1/N^2",
                "the E(F) fit gives a non-positive stiffness within the data's forces",
            )
        table_e = 1.0 / denom
        grad = -(table_e**2)[:, None] * np.column_stack([np.ones_like(table_f), table_f])
        table_se = np.sqrt(np.einsum("ij,jk,ik->i", grad, cov_c, grad))

    return AxialIdentification(
        data=data,
        force_law=force_law,
        stiffness=stiffness,
        n_chambers=n,
        force_slope=k,
        force_slope_se=k_se,
        force_offset=b,
        force_offset_se=b_se,
        A_eff=k / n,
        A_eff_se=k_se / n,
        L0=float(L0),
        L0_se=float(L0_se),
        L0_fitted=data.L0 is None,
        E=float(E),
        E_se=float(E_se),
        strain_coefficients=_readonly(s),
        compliance=compliance,
        compliance_se=compliance_se,
        table_force=None if table_f is None else _readonly(table_f),
        table_stiffness=None if table_e is None else _readonly(table_e),
        table_stiffness_se=None if table_se is None else _readonly(table_se),
        force_residuals=_readonly(res_f),
        length_residuals=_readonly(res_l),
        force_quality=_quality(f, res_f, dof_f, 1, "N"),
        length_quality=quality_l,
    )


@one_blas_thread
def calibrate_axial(
    force,
    length,
    base_design,
    out_path=None,
    *,
    n_chambers: int = 3,
    L0=None,
    rigid_length=0.0,
    force_law: str = "proportional",
    stiffness: str = "constant",
    name: str | None = None,
    extra: str = "error",
) -> tuple[AxialIdentification, Design]:
    """Load axial data, identify, and emit the design in one call (for scripts and the CLI).

    :func:`load_axial_data` (force, length, n_chambers, L0, rigid_length, extra), then
    :func:`identify_axial` (force_law, stiffness), then
    :meth:`AxialIdentification.to_design` (base_design, out_path, name).
    """
    data = load_axial_data(
        force, length, n_chambers=n_chambers, L0=L0, rigid_length=rigid_length, extra=extra
    )
    result = identify_axial(data, force_law=force_law, stiffness=stiffness)
    return result, result.to_design(base_design, out_path, name=name)


# --- synthetic data --------------------------------------------------------------------------


def _paper_cycles(levels_kPa, cycles: int) -> np.ndarray:
    """Pressure up and down through the levels, ``cycles`` times, ending at the first (Pa)."""
    up = list(levels_kPa)
    one = up + up[-2:0:-1]
    return np.array(one * cycles + up[:1], dtype=float) * 1e3


def synthesize_axial_data(
    *,
    E: float | Callable[[np.ndarray], np.ndarray] = 200.0,
    A_eff: float = 33.0 / (3 * 96e3),
    n_chambers: int = 3,
    L0: float = 44.8e-3,
    force_pressure=None,
    length_pressure=None,
    force_offset: float = 0.0,
    force_noise_N: float = 0.0,
    length_noise_mm: float = 0.0,
    seed: int | None = None,
) -> AxialData:
    """SYNTHETIC axial data from a known E (N) or E(F) and A_eff (m^2), plus noise.

    Force: F = n_chambers A_eff p + force_offset; length: L = L0 (1 + F_c / E(F_c)) with the
    chamber force F_c = n_chambers A_eff p (eq. 23 with the secant stiffness E(F)). ``E`` is
    a number or a vectorised callable E(F). Pressures in Pa; defaults: the paper's protocol
    (Sec. 3.1), 0-96 kPa in 24 kPa steps, three cycles up and down for the force, three
    repeats of each level for the length. Gaussian noise of standard deviation
    ``force_noise_N`` (N) and ``length_noise_mm`` (mm), reproducible with ``seed`` (drawn and
    recorded if None). Defaults are paper 004's actuator: E = 200 N, 33 N at 96 kPa for three
    chambers, L_c0 = 44.8 mm. ``metadata["synthetic"]`` is True and records all of this.
    """
    from .. import __version__

    def positive(name, value, allow_zero=False):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        if not (ok and math.isfinite(value) and (value >= 0 if allow_zero else value > 0)):
            raise _fail(name, value, f"must be a finite number {'>=' if allow_zero else '>'} 0")
        return float(value)

    A_eff, L0 = positive("A_eff", A_eff), positive("L0", L0)
    noise_f = positive("force_noise_N", force_noise_N, True)
    noise_l = positive("length_noise_mm", length_noise_mm, True)
    if not (isinstance(force_offset, (int, float)) and math.isfinite(force_offset)):
        raise _fail("force_offset", force_offset, "must be a finite number (N)")
    if seed is None:
        seed = int(np.random.SeedSequence().entropy % 2**63)
    elif isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise _fail("seed", seed, "must be an integer >= 0 or None")
    levels = [0.0, 24.0, 48.0, 72.0, 96.0]
    pf = _paper_cycles(levels, 3) if force_pressure is None else np.asarray(force_pressure, float)
    pl = (
        np.repeat(levels, 3) * 1e3
        if length_pressure is None
        else np.asarray(length_pressure, float)
    )
    fc = n_chambers * A_eff * pl
    if callable(E):
        stiff = np.asarray(E(fc), dtype=float)
        E_meta = f"E(F) = {getattr(E, '__name__', repr(E))}"
    else:
        stiff = np.full_like(fc, positive("E", E))
        E_meta = float(E)
    if stiff.shape != fc.shape or not np.all(np.isfinite(stiff) & (stiff > 0)):
        raise _fail("E", E_meta, "must give a finite stiffness > 0 (N) at every force")
    rng = np.random.default_rng(int(seed))
    force = n_chambers * A_eff * pf + force_offset + rng.normal(0.0, noise_f, pf.shape)
    length = L0 * (1.0 + fc / stiff) + rng.normal(0.0, noise_l * 1e-3, pl.shape)
    meta = {
        "synthetic": True,
        "note": "SYNTHETIC: generated by softrod.calibration.axial, not measurements",
        "generator": "softrod.calibration.synthesize_axial_data",
        "softrod_version": __version__,
        "E_N": E_meta,
        "A_eff_m2": A_eff,
        "n_chambers": n_chambers,
        "L0_m": L0,
        "force_offset_N": float(force_offset),
        "force_noise_N": noise_f,
        "length_noise_mm": noise_l,
        "noise": "independent Gaussian on force and length; pressures exact",
        "seed": int(seed),
    }
    return AxialData(pf, force, pl, length, n_chambers, None, 0.0, meta)


# --- bundled example -------------------------------------------------------------------------

# How the bundled example was made (paper 004's actuator, Sec. 3.1 and Table 1);
# softrod._examples.write_examples() rebuilds it, and a test checks it still does.
AXIAL_EXAMPLE = {
    "E_N": 200.0,  # Sec. 4.1 / Table 3
    "force_at_96kPa_N": 33.0,  # Sec. 3.1, three chambers
    "n_chambers": 3,
    "L0_mm": 44.8,  # Table 1, Actuator 2 (L_c,0)
    "force_noise_N": 0.2,
    "length_noise_mm": 0.1,
    "seed": 4,
    "files": ("modular_axial_force_synthetic.csv", "modular_axial_length_synthetic.csv"),
}


def _axial_example() -> AxialData:
    spec = AXIAL_EXAMPLE
    return synthesize_axial_data(
        E=spec["E_N"],
        A_eff=spec["force_at_96kPa_N"] / (spec["n_chambers"] * 96e3),
        n_chambers=spec["n_chambers"],
        L0=spec["L0_mm"] * 1e-3,
        force_noise_N=spec["force_noise_N"],
        length_noise_mm=spec["length_noise_mm"],
        seed=spec["seed"],
    )


def axial_example_paths() -> tuple[Path, Path]:
    """(force CSV, length CSV) of the bundled SYNTHETIC axial example."""
    return tuple(_EXAMPLES_DIR / name for name in AXIAL_EXAMPLE["files"])


def _write_axial_examples(folder: str | os.PathLike | None = None) -> list[Path]:
    """Regenerate the bundled axial example (called by softrod._examples.write_examples)."""
    folder = Path(folder) if folder is not None else _EXAMPLES_DIR
    folder.mkdir(exist_ok=True)
    names = AXIAL_EXAMPLE["files"]
    return list(write_axial_data(_axial_example(), folder / names[0], folder / names[1]))
