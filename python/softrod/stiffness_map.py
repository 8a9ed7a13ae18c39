"""Pressure-dependent stiffness scaling sigma(p) (paper 001, eq. 13 and eqs. 23-25).

Paper 001 keeps the linear law but makes it depend on the operating point: K_se(p) and
K_bt(p). Here that is three positive factors per solve, sigma = (sigma_ext, sigma_bend_x,
sigma_bend_y), which the core applies to every section marked ``[sections.law]
stiffness_map = true``: EA * sigma_ext, EI_1 (about d1) * sigma_bend_x, EI_2 (about d2) *
sigma_bend_y and the product term EI_12 * sqrt(sigma_bend_x * sigma_bend_y).

A :class:`StiffnessMap` turns gauge pressures (m, n_channels) in Pa into sigma (m, 3). It is
built from a regular table (tensor-product PCHIP or multilinear interpolation), a CSV file,
a Python callable or a trained regressor with a ``predict`` method (one model for all three
factors, or three models as in the paper). Every evaluation is checked: sigma must be finite
and > 0, otherwise :class:`~softrod.errors.InputError` names the row and its pressures.
See docs/stiffness-map.md.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from . import _core
from . import _validate as V
from .errors import InputError, design_error
from .io import as_path
from .io import is_file as _is_file

SIGMA_NAMES = ("sigma_ext", "sigma_bend_x", "sigma_bend_y")
METHODS = ("pchip", "linear")
OUTSIDE = ("raise", "clamp")

# Pressures this close to a table's end (relative to the axis span) count as inside and are
# clamped silently: unit conversions such as "0.6 bar" -> Pa leave such round-off.
_EDGE_SLACK = 1e-9
# Rows interpolated together: bounds the temporary arrays (rows x grid points x 3).
_CHUNK_ELEMENTS = 1 << 20

_PRESSURE_COLUMN = re.compile(r"^p(\d+)_(.+)$")


def _pa_per(unit: str, field: str) -> float:
    """How many Pa one ``unit`` is; InputError unless ``unit`` is a pressure unit (read by
    the restricted unit grammar of softrod._validate)."""
    return V.unit_factor(unit, "pressure", field)


def _axis(values: Any, k: int) -> np.ndarray:
    """One table axis in Pa: numbers (Pa), strings with units, or a pint quantity array."""
    field = f"axes[{k}]"
    if hasattr(values, "to") and hasattr(values, "magnitude"):  # a pint quantity
        try:
            values = np.asarray(values.to("Pa").magnitude, dtype=float)
        except Exception as exc:
            raise design_error(field, values, f"must be pressures: {exc}", InputError) from None
    if isinstance(values, (list, tuple)):
        if len(values) > V.MAX_TABLE_POINTS:
            raise V.fail(field, values, f"too many points: at most {V.MAX_TABLE_POINTS}")
        axis = np.array(
            [V.quantity(v, "pressure", f"{field}[{i}]") for i, v in enumerate(values)],
            dtype=float,
        ).reshape(-1)
    else:
        axis = V.real_array(values, field, max_size=V.MAX_TABLE_POINTS, what="pressures (Pa)")
    if axis.ndim != 1:
        raise design_error(field, values, "must be a 1-D sequence of pressures (Pa)", InputError)
    if len(axis) < 2:
        raise design_error(
            field,
            values.tolist() if hasattr(values, "tolist") else values,
            "needs at least 2 pressures (a channel the map does not depend on still spans a range)",
            InputError,
        )
    if not np.all(np.isfinite(axis)):
        raise design_error(field, axis.tolist(), "must be finite pressures", InputError)
    if not np.all(np.diff(axis) > 0):
        raise design_error(field, axis.tolist(), "must be strictly increasing", InputError)
    axis.setflags(write=False)
    return axis


class _Axis:
    """One table axis, for multilinear interpolation along it.

    Arrays interpolated along this axis have shape (..., n, M, 3): n the axis' nodes, M the
    rows (M = 1 for the table itself, shared by every row), 3 the factors.
    """

    def __init__(self, x: np.ndarray):
        self.x = x
        self.h = np.diff(x)

    def collapse(self, y: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Interpolate linearly along this axis at one pressure per row ``q`` (m,). ``y`` is
        (..., n, M, 3) with M = 1 (the table, shared by every row) or m. Returns
        (..., m, 3)."""
        # Interval index in [0, n - 2] (pressures are already on the axis).
        i = np.searchsorted(self.x[1:-1], q, side="right")
        t = ((q - self.x[i]) / self.h[i])[:, None]
        col = np.arange(len(q)) if y.shape[-2] > 1 else np.zeros(len(q), dtype=np.intp)
        g = y[..., np.stack([i, i + 1]), col, :]  # (..., 2, m, 3)
        y0, y1 = g[..., 0, :, :], g[..., 1, :, :]
        return y0 + t * (y1 - y0)


class StiffnessMap:
    """sigma(p): gauge pressures (m, n_channels) in Pa -> (m, 3) positive stiffness factors.

    Columns of sigma: (sigma_ext, sigma_bend_x, sigma_bend_y), scaling EA, EI_1 (about d1)
    and EI_2 (about d2) of every mapped section (``[sections.law] stiffness_map = true``).
    Build one with :meth:`from_table`, :meth:`from_csv`, :meth:`from_callable`,
    :meth:`from_regressor` or :meth:`constant`; pass it to ``solve_statics`` /
    ``solve_statics_batch`` as ``stiffness_map=``. Immutable.
    """

    __slots__ = (
        "_kind",
        "_n_channels",
        "_fn",
        "_describe",
        "_axes",
        "_values",
        "_method",
        "_outside",
        "_data",
    )

    def __init__(
        self, *, _kind: str, _n_channels: int, _fn: Callable, _describe: str, **table: Any
    ):
        # Private: use the from_* constructors.
        object.__setattr__(self, "_kind", _kind)
        object.__setattr__(self, "_n_channels", _n_channels)
        object.__setattr__(self, "_fn", _fn)
        object.__setattr__(self, "_describe", _describe)
        for key in ("_axes", "_values", "_method", "_outside", "_data"):
            object.__setattr__(self, key, table.get(key))

    def __setattr__(self, name, value):
        raise AttributeError("StiffnessMap is immutable; build a new one")

    def __delattr__(self, name):
        raise AttributeError("StiffnessMap is immutable; build a new one")

    # -- constructors -------------------------------------------------------------------------

    @classmethod
    def constant(cls, sigma: Sequence[float], n_channels: int) -> StiffnessMap:
        """The same sigma = (sigma_ext, sigma_bend_x, sigma_bend_y) at every pressure."""
        n = _channels(n_channels, 0)
        s = np.asarray(_sigma_row(sigma, "sigma"), dtype=float)
        s.setflags(write=False)
        return cls(
            _kind="constant",
            _n_channels=n,
            _fn=lambda p: np.tile(s, (p.shape[0], 1)),
            _describe=f"constant sigma=({s[0]:g}, {s[1]:g}, {s[2]:g})",
            _data={"sigma": s.tolist()},
        )

    @classmethod
    def from_table(
        cls,
        axes: Sequence[Any],
        sigma: Any,
        *,
        method: str = "pchip",
        outside: str = "raise",
    ) -> StiffnessMap:
        """Interpolate sigma on a regular grid of pressures.

        axes: one strictly increasing 1-D axis per channel (at least 2 points each), in Pa or
        as strings with units ("20 kPa") or a pint quantity array.
        sigma: array of shape (len(axes[0]), ..., len(axes[-1]), 3), finite and > 0.
        method: "pchip" (default; tensor-product monotone cubic, C1 along each channel with
        3 or more points, linear along a 2-point axis) or "linear" (multilinear). Both keep
        every interpolated value between the table's values at the surrounding nodes, so a
        positive table gives positive sigma.
        outside: "raise" (default): a pressure outside an axis raises InputError;
        "clamp": it is moved to the nearest end of the axis (sigma held constant beyond the
        table).
        """
        V.choice(method, METHODS, "method")
        V.choice(outside, OUTSIDE, "outside")
        if isinstance(axes, (str, bytes)) or not isinstance(axes, (Sequence, np.ndarray)):
            raise design_error(
                "axes", axes, "must be a list of 1-D pressure axes, one per channel", InputError
            )
        if len(axes) == 0:
            raise design_error(
                "axes",
                axes,
                "needs one axis per channel (for no channels use StiffnessMap.constant)",
                InputError,
            )
        if len(axes) > V.MAX_CHANNELS:
            raise V.fail("axes", f"{len(axes)} axes", f"at most {V.MAX_CHANNELS} channels")
        grid = tuple(_axis(a, k) for k, a in enumerate(axes))
        shape = tuple(len(a) for a in grid) + (3,)
        if math.prod(shape) > V.MAX_ROWS:
            grid_shape = "x".join(map(str, shape[:-1]))
            raise V.fail("axes", grid_shape, f"the grid has more than {V.MAX_ROWS:,} points")
        values = V.real_array(sigma, "sigma", what="stiffness factors")
        if values.shape != shape:
            raise design_error(
                "sigma",
                f"shape {values.shape}",
                f"must have shape {shape}: one (sigma_ext, sigma_bend_x, sigma_bend_y) per "
                "grid point",
                InputError,
            )
        bad = ~(np.isfinite(values) & (values > 0))
        if bad.any():
            idx = tuple(int(i) for i in np.argwhere(bad)[0])
            at = ", ".join(f"{grid[k][j]:g}" for k, j in enumerate(idx[:-1]))
            raise design_error(
                f"sigma[{', '.join(map(str, idx))}]",
                float(values[idx]),
                f"must be finite and > 0 (stiffness must stay positive); grid point ({at}) Pa, "
                f"{SIGMA_NAMES[idx[-1]]}",
                InputError,
            )
        values.setflags(write=False)
        grid_text = "x".join(str(len(a)) for a in grid)
        spans = ", ".join(
            f"p{k} in [{a[0] / 1e3:g}, {a[-1] / 1e3:g}] kPa" for k, a in enumerate(grid)
        )
        pchip = None
        if method == "pchip":
            # Tensor-product PCHIP in the Rust core (softrod_core::interp): a few us per row.
            pchip = _core.GridPchip([a.tolist() for a in grid], values.ravel().tolist(), 3)

            def evaluate(p: np.ndarray) -> np.ndarray:
                return pchip.eval(np.ascontiguousarray(_inside(grid, p, outside)))

        else:
            axes_ = [_Axis(a) for a in grid]
            table = values[..., None, :]  # (n_0, ..., n_c-1, 1, 3): one "row", shared
            chunk = max(1, _CHUNK_ELEMENTS // (3 * math.prod(len(a) for a in grid[:-1])))

            def evaluate(p: np.ndarray) -> np.ndarray:
                # Channel by channel, last first.
                p = _inside(grid, p, outside)
                out = np.empty((p.shape[0], 3))
                for start in range(0, p.shape[0], chunk):
                    rows = p[start : start + chunk]
                    y = axes_[-1].collapse(table, rows[:, -1])
                    for c in range(len(grid) - 2, -1, -1):
                        y = axes_[c].collapse(y, rows[:, c])
                    out[start : start + chunk] = y
                return out

        return cls(
            _kind="table",
            _n_channels=len(grid),
            _fn=evaluate,
            _describe=f"table {grid_text}, {spans}, method={method!r}, outside={outside!r}",
            _axes=grid,
            _values=values,
            _method=method,
            _outside=outside,
            _data={"pchip": pchip},
        )

    @classmethod
    def from_csv(
        cls, path: str | Path, *, method: str = "pchip", outside: str = "raise"
    ) -> StiffnessMap:
        """Read a table from CSV: one row per grid point, in any order.

        Header: one column per channel named ``p<k>_<unit>`` (``p0_kPa``, ``p1_bar``,
        ``p2_Pa``; channels 0..c-1, any pressure unit pint knows) and the columns
        ``sigma_ext``, ``sigma_bend_x``, ``sigma_bend_y``. The rows must cover the full grid
        (every combination of the distinct pressures of each column) exactly once. Errors
        name the line of the file. ``method`` and ``outside`` as in :meth:`from_table`.
        """
        path = as_path(path)
        if not _is_file(path):
            raise design_error("path", str(path), "no such file", InputError)
        from .io import read_text_file

        text = read_text_file(path)
        try:
            with io.StringIO(text, newline="") as fh:
                reader = csv.reader(fh)
                header = next(reader, None)
                if header is None:
                    raise design_error(str(path), "empty file", "needs a header line", InputError)
                header = [h.strip() for h in header]
                channels: dict[
                    int, tuple[int, float, str]
                ] = {}  # channel -> (column, Pa per unit, name)
                sig_cols: dict[str, int] = {}
                for col, name in enumerate(header):
                    m = _PRESSURE_COLUMN.match(name)
                    if name in SIGMA_NAMES:
                        if name in sig_cols:
                            raise design_error(
                                f"{path.name}: column {name}", name, "appears twice", InputError
                            )
                        sig_cols[name] = col
                    elif m:
                        from .schema import channel_index

                        k = channel_index("p" + m.group(1), name)
                        if k in channels:
                            raise design_error(
                                f"{path.name}: column {name}",
                                name,
                                f"a second column for channel {k}",
                                InputError,
                            )
                        per = _pa_per(m.group(2), f"{path.name}: column {name}")
                        channels[k] = (col, per, name)
                    else:
                        raise design_error(
                            f"{path.name}: column {name!r}",
                            name,
                            "unknown column: expected p<k>_<unit> (e.g. p0_kPa) per channel and "
                            f"{', '.join(SIGMA_NAMES)}",
                            InputError,
                        )
                missing = [s for s in SIGMA_NAMES if s not in sig_cols]
                if missing:
                    raise design_error(
                        f"{path.name}: header",
                        ",".join(header),
                        f"missing column(s) {', '.join(missing)}",
                        InputError,
                    )
                n = len(channels)
                if n == 0 or sorted(channels) != list(range(n)):
                    raise design_error(
                        f"{path.name}: header",
                        ",".join(header),
                        "needs one pressure column per channel 0..c-1, named p<k>_<unit> "
                        "(e.g. p0_kPa)",
                        InputError,
                    )
                cols = [channels[k][0] for k in range(n)] + [sig_cols[s] for s in SIGMA_NAMES]
                names = [channels[k][2] for k in range(n)] + list(SIGMA_NAMES)
                rows: list[list[float]] = []
                lines: list[int] = []
                for row in reader:
                    if not row or all(not c.strip() for c in row):
                        continue
                    line = reader.line_num
                    if len(row) != len(header):
                        raise design_error(
                            f"{path.name}: line {line}",
                            ",".join(row),
                            f"has {len(row)} fields, the header {len(header)}",
                            InputError,
                        )
                    vals = []
                    for col, name in zip(cols, names, strict=True):
                        text = row[col].strip()
                        try:
                            v = float(text)
                        except ValueError:
                            v = math.nan
                        if not math.isfinite(v):
                            raise design_error(
                                f"{path.name}: line {line}, {name}",
                                text,
                                "must be a finite number",
                                InputError,
                            )
                        vals.append(v)
                    if not all(v > 0 for v in vals[n:]):
                        raise design_error(
                            f"{path.name}: line {line}",
                            vals[n:],
                            "sigma must be > 0 (stiffness must stay positive)",
                            InputError,
                        )
                    rows.append(vals)
                    lines.append(line)
        except csv.Error as exc:
            rule = f"not a CSV table: {exc}"
            raise design_error(str(path), "unreadable", rule, InputError) from None
        if not rows:
            raise design_error(
                str(path), "no data rows", "needs one row per grid point", InputError
            )
        data = np.array(rows)
        # Axes in the file's own units (exact equality of the written values), then Pa.
        axes_file = [np.unique(data[:, k]) for k in range(n)]
        index = tuple(np.searchsorted(axes_file[k], data[:, k]) for k in range(n))
        shape = tuple(len(a) for a in axes_file)
        if math.prod(shape) > 2 * len(rows):  # many points missing: say so before allocating
            raise design_error(
                str(path),
                f"{len(rows)} rows",
                f"the rows must cover the full grid {'x'.join(map(str, shape))} "
                f"({math.prod(shape)} rows, got {len(rows)})",
                InputError,
            )
        flat = np.ravel_multi_index(index, shape)
        seen = np.full(math.prod(shape), -1)
        for r, f in enumerate(flat):
            if seen[f] >= 0:
                raise design_error(
                    f"{path.name}: line {lines[r]}",
                    ",".join(f"{v:g}" for v in data[r, :n]),
                    f"repeats the grid point of line {lines[seen[f]]}",
                    InputError,
                )
            seen[f] = r
        if (seen < 0).any():
            gap = np.unravel_index(int(np.argmin(seen)), shape)
            point = ", ".join(f"{names[k]} = {axes_file[k][j]:g}" for k, j in enumerate(gap))
            raise design_error(
                f"{path.name}: grid point ({point})",
                "missing",
                f"the rows must cover the full grid {'x'.join(map(str, shape))} "
                f"({math.prod(shape)} rows, got {len(rows)})",
                InputError,
            )
        sigma = data[seen, n:].reshape(shape + (3,))
        axes = [axes_file[k] * channels[k][1] for k in range(n)]
        m = cls.from_table(axes, sigma, method=method, outside=outside)
        object.__setattr__(m, "_describe", f"{m._describe}, from {path.name}")
        return m

    @classmethod
    def from_callable(
        cls,
        fn: Callable[[np.ndarray], Any],
        n_channels: int,
        *,
        derivative: Callable[[np.ndarray], Any] | None = None,
    ) -> StiffnessMap:
        """sigma = fn(P): P an (m, n_channels) float array of gauge pressures in Pa (a
        read-only copy), the result an (m, 3) array. ``derivative``: optional
        dfn(P) -> (m, 3, n_channels), d sigma / d p per Pa, which a mapped design's
        pressure Jacobian needs (:meth:`derivative`); softrod does not check it against
        ``fn``."""
        if not callable(fn):
            raise design_error(
                "fn", fn, "must be callable: fn(P (m, channels) Pa) -> (m, 3)", InputError
            )
        if derivative is not None and not callable(derivative):
            raise design_error(
                "derivative",
                derivative,
                "must be callable: dfn(P (m, channels) Pa) -> (m, 3, channels) per Pa, or None",
                InputError,
            )
        n = _channels(n_channels, 0)
        return cls(
            _kind="callable",
            _n_channels=n,
            _fn=fn,
            _describe=f"callable {_name(fn)}",
            _data={"derivative": derivative},
        )

    @classmethod
    def from_regressor(cls, model: Any, n_channels: int, pressure_unit: str = "Pa") -> StiffnessMap:
        """A trained regressor (scikit-learn style): ``model.predict(P)`` with P the
        pressures in ``pressure_unit`` (the unit it was trained in) returning (m, 3); or a
        list of three models, one per factor (sigma_ext, sigma_bend_x, sigma_bend_y) as in
        paper 001 eqs. 23-25, each returning (m,) or (m, 1)."""
        n = _channels(n_channels, 0)
        scale = 1.0 / _pa_per(pressure_unit, "pressure_unit")
        if isinstance(model, (list, tuple)):
            if len(model) != 3:
                raise design_error(
                    "model",
                    f"{len(model)} models",
                    "give one model for all of sigma or three (ext, bend_x, bend_y)",
                    InputError,
                )
            models = list(model)
        else:
            models = [model]
        for k, mdl in enumerate(models):
            if not callable(getattr(mdl, "predict", None)):
                where = "model" if len(models) == 1 else f"model[{k}]"
                raise design_error(
                    where, type(mdl).__name__, "must have a predict(P) method", InputError
                )

        def evaluate(p: np.ndarray) -> np.ndarray:
            x = p * scale
            if len(models) == 1:
                return models[0].predict(x)
            cols = []
            for k, mdl in enumerate(models):
                col = V.real_array(mdl.predict(x), f"model[{k}].predict", what="sigma values")
                if col.shape not in ((p.shape[0],), (p.shape[0], 1)):
                    raise design_error(
                        f"model[{k}].predict",
                        f"output shape {col.shape}",
                        f"must return ({p.shape[0]},) or ({p.shape[0]}, 1): {SIGMA_NAMES[k]} "
                        "per row",
                        InputError,
                    )
                cols.append(col.reshape(-1))
            return np.stack(cols, axis=1)

        names = ", ".join(type(m).__name__ for m in models)
        return cls(
            _kind="regressor",
            _n_channels=n,
            _fn=evaluate,
            _describe=f"regressor {names}, pressure_unit={pressure_unit!r}",
        )

    @classmethod
    def from_networks(cls, networks: Sequence[Mapping[str, Any]]) -> StiffnessMap:
        """Three neural networks, one per factor (sigma_ext, sigma_bend_x, sigma_bend_y), as
        plain arrays: the hybrid model of paper 001 (eqs. 23-25) evaluated with numpy, no
        scikit-learn needed. Each network is a mapping with ``input_mean`` and
        ``input_scale`` (c,) (pressures in Pa are standardised first), ``weights`` (a list of
        (n_in, n_out) matrices) and ``biases`` (a list of (n_out,) vectors) of the layers,
        ``activation`` of the hidden layers ("tanh", "relu" or "logistic"; the output layer
        is linear), and ``target_mean``, ``target_scale``: sigma = exp(target_mean +
        target_scale * net(p)) (a standardised log sigma, so sigma > 0 everywhere)."""
        if not isinstance(networks, (list, tuple)) or len(networks) != 3:
            raise design_error(
                "networks",
                f"{len(networks) if hasattr(networks, '__len__') else networks!r}",
                f"needs three networks, one per factor ({', '.join(SIGMA_NAMES)})",
                InputError,
            )
        nets = [_network(net, f"networks[{k}]") for k, net in enumerate(networks)]
        n = nets[0]["input_mean"].size
        for k, net in enumerate(nets):
            if net["input_mean"].size != n:
                raise design_error(
                    f"networks[{k}].input_mean",
                    f"{net['input_mean'].size} inputs",
                    f"every network takes the same pressures ({n} channels)",
                    InputError,
                )

        def evaluate(p: np.ndarray) -> np.ndarray:
            return np.column_stack([_forward(net, p) for net in nets])

        layers = "-".join(str(w.shape[0]) for w in nets[0]["weights"]) + "-1"
        return cls(
            _kind="mlp",
            _n_channels=n,
            _fn=evaluate,
            _describe=f"networks {layers} {nets[0]['activation']} x 3",
            _data={"networks": nets},
        )

    # -- files ----------------------------------------------------------------------------------

    def save(self, path: str | Path, *, metadata: Mapping[str, Any] | None = None) -> Path:
        """Write the map as a JSON file (whole or not at all); returns the path.

        The format (docs/stiffness-map.md) is plain JSON: ``format``
        ("softrod.stiffness_map"), ``version`` (:data:`FORMAT_VERSION`), ``kind``
        ("table", "constant" or "mlp"), ``n_channels``, the numbers (table axes in Pa and
        sigma values; or sigma; or the networks' arrays), ``metadata``. Floats are written
        to the shortest decimal that reads back to the same double, so :func:`load_stiffness_map`
        gives back the same map bit for bit. Maps made from a Python callable or a
        scikit-learn regressor are code, not data, and cannot be saved (InputError).
        """
        from .io import metadata_json

        doc = self._document()
        doc["metadata"] = json.loads(metadata_json(metadata or {}))
        return _write_json(doc, path)

    def _document(self) -> dict[str, Any]:
        """The map as the JSON object of :meth:`save` (without ``metadata``)."""
        if self._kind not in ("table", "constant", "mlp"):
            raise design_error(
                "stiffness_map",
                repr(self),
                f"a {self._kind} map is Python code, not data, and cannot be saved: build it "
                "with from_table, from_csv, constant or from_networks (HybridStiffnessModel's "
                "stiffness_map is saveable)",
                InputError,
            )
        doc: dict[str, Any] = {
            "format": FORMAT,
            "version": FORMAT_VERSION,
            "kind": self._kind,
            "n_channels": self._n_channels,
            "pressure_unit": "Pa",
        }
        if self._kind == "table":
            doc.update(
                axes=[a.tolist() for a in self._axes],
                sigma=self._values.tolist(),
                method=self._method,
                outside=self._outside,
            )
        elif self._kind == "constant":
            doc["sigma"] = list(self._data["sigma"])
        else:
            doc["networks"] = [
                {
                    "factor": name,
                    "input_mean": net["input_mean"].tolist(),
                    "input_scale": net["input_scale"].tolist(),
                    "weights": [w.tolist() for w in net["weights"]],
                    "biases": [b.tolist() for b in net["biases"]],
                    "activation": net["activation"],
                    "target_mean": net["target_mean"],
                    "target_scale": net["target_scale"],
                }
                for name, net in zip(SIGMA_NAMES, self._data["networks"], strict=True)
            ]
        return doc

    @classmethod
    def load(cls, path: str | Path, **options: Any) -> StiffnessMap:
        """Read a map file: the JSON of :meth:`save` or a table CSV (:meth:`from_csv`,
        which takes ``method`` and ``outside``). Same as :func:`load_stiffness_map`."""
        return load_stiffness_map(path, **options)

    # -- use ------------------------------------------------------------------------------------

    @property
    def n_channels(self) -> int:
        """Number of pressure channels (columns of P)."""
        return self._n_channels

    @property
    def kind(self) -> str:
        """ "table", "constant", "mlp" (networks as arrays), "callable" or "regressor"."""
        return self._kind

    @property
    def axes(self) -> tuple[np.ndarray, ...] | None:
        """The table's pressure axes in Pa (read-only), None unless built from a table."""
        return self._axes

    @property
    def values(self) -> np.ndarray | None:
        """The table's sigma (grid shape + (3,), read-only), None unless built from a table."""
        return self._values

    def __call__(self, pressures: Any) -> np.ndarray:
        """sigma (m, 3) for gauge pressures (m, n_channels) in Pa; a 1-D row of n_channels
        pressures gives sigma (3,). Raises InputError for a bad shape, non-finite pressures, a
        pressure outside a table (``outside="raise"``) or a sigma that is not finite and > 0."""
        p, single = self._rows(pressures)
        p.setflags(write=False)
        sigma = self._fn(p) if p.shape[0] else np.empty((0, 3))
        sigma = _check_output(sigma, p)
        return sigma[0] if single else sigma

    def _rows(self, pressures: Any) -> tuple[np.ndarray, bool]:
        """Gauge pressures as a finite (m, n_channels) array (Pa), and whether a single 1-D
        row was given; InputError naming the field and the row otherwise."""
        p = V.real_array(pressures, "pressures", what="gauge pressures (Pa)")
        single = p.ndim == 1 and p.shape[0] == self._n_channels
        if single:
            p = p[None, :]
        _check_pressure_rows(
            p,
            self._n_channels,
            f"the stiffness map takes an (m, {self._n_channels}) array of gauge pressures (Pa)",
        )
        finite = np.isfinite(p).all(axis=1)
        if not finite.all():
            r = int(np.argmin(finite))
            raise design_error(f"pressures[{r}]", p[r].tolist(), "must be finite (Pa)", InputError)
        return p, single

    def derivative(self, pressures: Any) -> np.ndarray:
        """d sigma / d p at gauge pressures (m, n_channels) in Pa: (m, 3, n_channels), per Pa
        (a 1-D row of n_channels pressures gives (3, n_channels)). It turns a mapped
        design's Jacobian at fixed sigma into the total derivative with respect to the
        pressures (``StaticSolution.jacobian``).

        Exact for a constant map (zero), a table (PCHIP: forward mode through the core's
        interpolation; linear: the slope of the cell), networks (forward mode through the
        layers) and a callable built with ``derivative=``. A pressure outside a clamped table
        has zero derivative along that channel; on a table's edge the derivative is the
        one-sided one from inside (the map is not defined beyond an edge with
        ``outside="raise"``). InputError where sigma has no derivative: a kink (a linear
        table's interior node where the two cells' slopes differ, the edge of a clamped
        table where the inner slope is not zero, a relu network's hinge), or where the map
        cannot give one (a regressor, a callable without ``derivative=``)."""
        p, single = self._rows(pressures)
        self(p)  # the map's own checks: inside a raising table, a valid sigma
        c = self._n_channels
        if self._kind == "constant":
            d = np.zeros((p.shape[0], 3, c))
        elif self._kind == "table":
            d = self._table_derivative(p)
        elif self._kind == "mlp":
            d = np.stack([_forward_derivative(net, p) for net in self._data["networks"]], axis=1)
        elif self._data is not None and self._data.get("derivative") is not None:
            d = _float_array(
                self._data["derivative"](p.copy()),
                "stiffness_map",
                "derivative",
                "the derivative= callable must return numbers",
            )
            if d.shape != (p.shape[0], 3, c) or not np.isfinite(d).all():
                raise design_error(
                    "stiffness_map",
                    f"derivative of shape {d.shape}",
                    f"the derivative= callable must return finite (m, 3, {c}) d sigma / d p "
                    "(per Pa)",
                    InputError,
                )
        else:
            raise design_error(
                "stiffness_map",
                self,
                f"a {self._kind} map gives no derivative d sigma / d p, which the pressures' "
                "Jacobian of a mapped design needs: build the map from a table or networks, or "
                "with StiffnessMap.from_callable(fn, n_channels, derivative=dfn)",
                InputError,
            )
        return d[0] if single else d

    def _table_derivative(self, p: np.ndarray) -> np.ndarray:
        """d sigma / d p of a table map (module docs of :meth:`derivative`)."""
        grid, m, c = self._axes, p.shape[0], self._n_channels
        lo = np.array([a[0] for a in grid])
        hi = np.array([a[-1] for a in grid])
        slack = _EDGE_SLACK * (hi - lo)
        q = np.minimum(np.maximum(p, lo), hi)
        if self._method == "pchip":
            d = np.asarray(self._data["pchip"].gradient(np.ascontiguousarray(q)), dtype=float)
        else:
            d = np.empty((m, 3, c))
            for k, a in enumerate(grid):
                # Multilinear: linear along channel k within a cell, so the cell's secant is
                # the derivative. At an interior node both cells' slopes must agree.
                i = np.clip(np.searchsorted(a, q[:, k], side="right") - 1, 0, len(a) - 2)
                d[:, :, k] = self._cell_slope(q, k, i)
                j = (
                    np.argmin(np.abs(q[:, k, None] - a[None, 1:-1]), axis=1) + 1
                    if len(a) > 2
                    else i
                )
                node = (len(a) > 2) & np.isclose(q[:, k], a[j], rtol=0.0, atol=slack[k])
                if node.any():
                    below = self._cell_slope(q[node], k, j[node] - 1)
                    above = self._cell_slope(q[node], k, j[node])
                    kink = ~np.isclose(below, above, rtol=1e-9, atol=0.0).all(axis=1)
                    if kink.any():
                        r = int(np.flatnonzero(node)[np.argmax(kink)])
                        raise design_error(
                            f"pressures[{r}]",
                            p[r].tolist(),
                            f"channel {k} = {p[r, k]:g} Pa is a node of the linear stiffness "
                            "table where the slopes of the two cells differ: sigma has no "
                            "derivative there (build the map with method='pchip', which is "
                            "continuously differentiable)",
                            InputError,
                        )
        if self._outside == "clamp":
            beyond = (p < lo - slack) | (p > hi + slack)
            edge = ~beyond & ((p <= lo + slack) | (p >= hi - slack))
            for r, k in np.argwhere(edge):
                if np.any(d[r, :, k] != 0.0):
                    raise design_error(
                        f"pressures[{r}]",
                        p[r].tolist(),
                        f"channel {k} = {p[r, k]:g} Pa is the edge of the clamped stiffness "
                        "table, where sigma stops changing: it has no derivative there (extend "
                        "the table past the pressures you differentiate at)",
                        InputError,
                    )
            d[np.broadcast_to(beyond[:, None, :], d.shape)] = 0.0
        return d

    def _cell_slope(self, q: np.ndarray, k: int, i: np.ndarray) -> np.ndarray:
        """(m, 3): the secant of sigma along channel k across cell i (per row)."""
        a = self._axes[k]
        left, right = q.copy(), q.copy()
        left[:, k], right[:, k] = a[i], a[i + 1]
        return (self._fn(right) - self._fn(left)) / (a[i + 1] - a[i])[:, None]

    def __repr__(self) -> str:
        plural = "s" if self._n_channels != 1 else ""
        return f"StiffnessMap({self._describe}, {self._n_channels} channel{plural})"


def _channels(n: Any, minimum: int) -> int:
    return V.integer(n, "n_channels", minimum=minimum, maximum=V.MAX_CHANNELS)


def _sigma_row(sigma: Any, field: str) -> list[float]:
    try:
        s = [float(x) for x in sigma]
    except (TypeError, ValueError, OverflowError):
        raise design_error(
            field, sigma, "must be 3 numbers (sigma_ext, sigma_bend_x, sigma_bend_y)", InputError
        ) from None
    if len(s) != 3:
        raise design_error(
            field, sigma, "must be 3 numbers (sigma_ext, sigma_bend_x, sigma_bend_y)", InputError
        )
    for k, x in enumerate(s):
        if not (math.isfinite(x) and x > 0):
            raise design_error(
                f"{field}[{k}]",
                x,
                "must be finite and > 0 (stiffness must stay positive)",
                InputError,
            )
    return s


def _name(fn: Any) -> str:
    return getattr(fn, "__qualname__", None) or type(fn).__name__


def _inside(grid: tuple[np.ndarray, ...], p: np.ndarray, outside: str) -> np.ndarray:
    """Pressures moved onto the table (clamp), or InputError for the first row outside."""
    lo = np.array([a[0] for a in grid])
    hi = np.array([a[-1] for a in grid])
    if outside == "raise":
        slack = _EDGE_SLACK * (hi - lo)
        out = (p < lo - slack) | (p > hi + slack)
        if out.any():
            r, k = (int(i) for i in np.argwhere(out)[0])
            raise design_error(
                f"pressures[{r}]",
                p[r].tolist(),
                f"channel {k} = {p[r, k]:g} Pa lies outside the stiffness table "
                f"[{lo[k]:g}, {hi[k]:g}] Pa ({int(out.any(axis=1).sum())} row(s) outside); extend "
                "the table or build the map with outside='clamp'",
                InputError,
            )
    return np.minimum(np.maximum(p, lo), hi)


def _float_array(value: Any, field: str, shown: Any, rule: str) -> np.ndarray:
    """``value`` as a new float array; InputError ``field = shown: rule: <numpy's reason>``
    when it is not numeric."""
    try:
        return np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise design_error(field, shown, f"{rule}: {exc}", InputError) from None


def _check_pressure_rows(p: np.ndarray, n_channels: int, rule: str) -> None:
    """InputError ``pressures = shape (...): rule`` unless ``p`` is an (m, n_channels) array
    (one row of gauge pressures per solve)."""
    if p.ndim != 2 or p.shape[1] != n_channels:
        raise design_error("pressures", f"shape {p.shape}", rule, InputError)


def _check_output(sigma: Any, p: np.ndarray) -> np.ndarray:
    m = p.shape[0]
    s = _float_array(sigma, "stiffness_map", type(sigma).__name__, "must return numbers")
    if s.shape != (m, 3):
        raise design_error(
            "stiffness_map",
            f"output shape {s.shape}",
            f"must return an ({m}, 3) array (sigma_ext, sigma_bend_x, sigma_bend_y) for {m} "
            "pressure row(s)",
            InputError,
        )
    good = (np.isfinite(s) & (s > 0)).all(axis=1)
    if not good.all():
        r = int(np.argmin(good))
        more = int((~good).sum()) - 1
        raise design_error(
            f"sigma[{r}]",
            s[r].tolist(),
            f"must be finite and > 0 (stiffness must stay positive); the stiffness map returned it "
            f"for pressures[{r}] = {p[r].tolist()} Pa"
            + (f" ({more} more row(s) bad)" if more else ""),
            InputError,
        )
    return s


# -- saved maps ---------------------------------------------------------------------------------

FORMAT = "softrod.stiffness_map"
#: Version of the JSON layout written by :meth:`StiffnessMap.save`. A file of a newer version
#: is an error that says to upgrade softrod, never a guess.
FORMAT_VERSION = 1
_ACTIVATIONS = {
    "tanh": np.tanh,
    "relu": lambda x: np.maximum(x, 0.0),
    "logistic": lambda x: 1.0 / (1.0 + np.exp(-x)),
}


def _vector(value: Any, field: str) -> np.ndarray:
    a = _float_array(value, field, type(value).__name__, "must be an array of numbers")
    if a.ndim != 1 or not np.all(np.isfinite(a)):
        raise design_error(field, f"shape {a.shape}", "must be a finite 1-D array", InputError)
    return a


def _network(net: Any, where: str) -> dict:
    """A network's arrays, checked: shapes that chain, finite numbers, positive scales."""
    if not isinstance(net, Mapping):
        raise design_error(where, type(net).__name__, "must be a mapping of arrays", InputError)
    keys = (
        "input_mean",
        "input_scale",
        "weights",
        "biases",
        "activation",
        "target_mean",
        "target_scale",
    )
    missing = [k for k in keys if k not in net]
    if missing:
        raise design_error(where, sorted(net), f"missing {', '.join(missing)}", InputError)
    mean = _vector(net["input_mean"], f"{where}.input_mean")
    scale = _vector(net["input_scale"], f"{where}.input_scale")
    if scale.shape != mean.shape or not np.all(scale > 0):
        raise design_error(
            f"{where}.input_scale", scale.tolist(), "must be > 0, one per input", InputError
        )
    weights, biases = net["weights"], net["biases"]
    if not isinstance(weights, (list, tuple)) or not isinstance(biases, (list, tuple)):
        raise design_error(f"{where}.weights", type(weights).__name__, "must be a list", InputError)
    if len(weights) != len(biases) or len(weights) < 1:
        raise design_error(
            f"{where}.weights",
            f"{len(weights)} layers",
            "one bias per layer, at least one layer",
            InputError,
        )
    ws, bs = [], []
    n_in = mean.size
    for i, (w, b) in enumerate(zip(weights, biases, strict=True)):
        w = _float_array(w, f"{where}.weights[{i}]", type(w).__name__, "must be a matrix")
        b = _vector(b, f"{where}.biases[{i}]")
        if w.ndim != 2 or w.shape[0] != n_in or w.shape[1] != b.size or not np.isfinite(w).all():
            raise design_error(
                f"{where}.weights[{i}]",
                f"shape {w.shape}",
                f"must be a finite ({n_in}, {b.size}) matrix (layer inputs x outputs)",
                InputError,
            )
        ws.append(w)
        bs.append(b)
        n_in = b.size
    if n_in != 1:
        raise design_error(
            f"{where}.biases[-1]", n_in, "the output layer has one neuron", InputError
        )
    activation = net["activation"]
    if activation not in _ACTIVATIONS:
        raise design_error(
            f"{where}.activation",
            activation,
            f"must be one of {', '.join(_ACTIVATIONS)}",
            InputError,
        )
    target = []
    for key in ("target_mean", "target_scale"):
        v = net[key]
        number = isinstance(v, (int, float, np.floating)) and not isinstance(v, bool)
        if not number or not math.isfinite(v):
            raise design_error(f"{where}.{key}", v, "must be a finite number", InputError)
        target.append(float(v))
    if not target[1] > 0:
        raise design_error(f"{where}.target_scale", target[1], "must be > 0", InputError)
    for a in (mean, scale, *ws, *bs):
        a.setflags(write=False)
    return {
        "input_mean": mean,
        "input_scale": scale,
        "weights": ws,
        "biases": bs,
        "activation": activation,
        "target_mean": target[0],
        "target_scale": target[1],
    }


# Rows per block of the forward pass: its temporaries (rows x layer width) stay in cache.
# Blocks cannot change a row's bits (see _forward).
_FORWARD_BLOCK = 4096


def _forward(net: dict, p: np.ndarray) -> np.ndarray:
    """sigma_k at pressures p (m, c) Pa: standardise, hidden layers, linear output, then
    undo the target's standardisation and the log. The same operations as scikit-learn's
    StandardScaler, MLPRegressor and TransformedTargetRegressor, with each layer's matrix
    product summed in one fixed order (``_row_product``).

    Every row's result depends on that row alone, bit for bit, whatever the other rows:
    every operation is elementwise on contiguous arrays (+, -, *, / are correctly rounded
    in IEEE arithmetic; tanh and exp are numpy's elementwise loops, the same for a row alone
    and in a block). So a batch evaluates all its rows in one call and each row equals the
    single solve's one-row evaluation (tests/test_stiffness_map.py checks it on blocks of
    many sizes)."""
    m = p.shape[0]
    if m > _FORWARD_BLOCK:
        return np.concatenate(
            [_forward(net, p[k : k + _FORWARD_BLOCK]) for k in range(0, m, _FORWARD_BLOCK)]
        )
    x = np.ascontiguousarray((p - net["input_mean"]) / net["input_scale"])
    act = _ACTIVATIONS[net["activation"]]
    last = len(net["weights"]) - 1
    for i, (w, b) in enumerate(zip(net["weights"], net["biases"], strict=True)):
        x = _row_product(x, w)
        x += b
        if i < last:
            x = act(x)
    out = np.ascontiguousarray(x[:, 0])
    return np.exp(out * net["target_scale"] + net["target_mean"])


def _forward_derivative(net: dict, p: np.ndarray) -> np.ndarray:
    """d sigma_k / d p (m, c) per Pa at pressures p (m, c): forward mode through the layers
    of :func:`_forward` (the Jacobian of each layer's output with respect to the pressures,
    carried along). A relu hinge (a pre-activation exactly 0) has no derivative: InputError."""
    x = (p - net["input_mean"]) / net["input_scale"]
    # dx (m, width, c): d layer output / d p.
    dx = np.broadcast_to(np.diag(1.0 / net["input_scale"]), (p.shape[0], p.shape[1], p.shape[1]))
    last = len(net["weights"]) - 1
    for i, (w, b) in enumerate(zip(net["weights"], net["biases"], strict=True)):
        z = x @ w + b
        dz = np.einsum("mjc,jk->mkc", dx, w)
        if i == last:
            x, dx = z, dz
            break
        if net["activation"] == "tanh":
            x = np.tanh(z)
            slope = 1.0 - x * x
        elif net["activation"] == "logistic":
            x = 1.0 / (1.0 + np.exp(-z))
            slope = x * (1.0 - x)
        else:
            hinge = z == 0.0
            if hinge.any():
                r = int(np.argwhere(hinge)[0][0])
                raise design_error(
                    f"pressures[{r}]",
                    p[r].tolist(),
                    "puts a relu unit of the stiffness network exactly on its hinge, where "
                    "sigma has no derivative",
                    InputError,
                )
            x = np.maximum(z, 0.0)
            slope = (z > 0.0).astype(float)
        dx = dz * slope[:, :, None]
    sigma = np.exp(x[:, 0] * net["target_scale"] + net["target_mean"])
    return (sigma * net["target_scale"])[:, None] * dx[:, 0, :]


def _row_product(x: np.ndarray, w: np.ndarray) -> np.ndarray:
    """x @ w (x (m, n), w (n, k)) with every entry summed over n in the order 0, 1, ...
    by elementwise products and sums, so that a row's entries do not depend on the other
    rows. (A BLAS matrix product blocks and vectorises its sums by the matrix sizes: a row
    rounds differently alone than in a block, which is why batches once evaluated network
    maps one row at a time.)"""
    out = x[:, 0:1] * w[0]
    for j in range(1, w.shape[0]):
        out += x[:, j : j + 1] * w[j]
    return out


def _write_json(doc: dict, path: str | Path) -> Path:
    """Write a map document (``.json``) atomically; floats as their shortest round-trip
    decimals, so reading gives the same doubles."""
    from .io import atomic_path

    path = as_path(path)
    if path.suffix.lower() != ".json":
        raise design_error("path", str(path), "a stiffness map file must end in .json", InputError)
    text = json.dumps(doc, allow_nan=False)
    with atomic_path(path) as tmp:
        tmp.write_text(text + "\n", encoding="utf-8")
    return path


def read_map_document(path: str | Path) -> dict:
    """The JSON object of a saved map, its format and version checked."""
    path = as_path(path)
    if path.suffix.lower() != ".json":
        raise design_error("path", str(path), "a saved map file ends in .json", InputError)
    if not _is_file(path):
        raise design_error("path", str(path), "no such file", InputError)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise design_error("path", str(path), f"is not valid JSON ({exc})", InputError) from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise design_error(
            "format",
            doc.get("format") if isinstance(doc, dict) else type(doc).__name__,
            f"{path.name} is not a softrod stiffness map (format {FORMAT!r})",
            InputError,
        )
    version = doc.get("version")
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise design_error("version", version, "must be an integer >= 1", InputError)
    if version > FORMAT_VERSION:
        raise design_error(
            "version",
            version,
            f"{path.name} was written by a newer softrod (stiffness map format {version}; this "
            f"softrod reads up to {FORMAT_VERSION}): upgrade softrod to read it",
            InputError,
        )
    return doc


def map_from_document(doc: dict, name: str) -> StiffnessMap:
    """The StiffnessMap of a saved map's JSON object (see :func:`read_map_document`)."""
    kind = doc.get("kind")
    if kind == "table":
        m = StiffnessMap.from_table(
            doc.get("axes"),
            doc.get("sigma"),
            method=doc.get("method", "pchip"),
            outside=doc.get("outside", "raise"),
        )
    elif kind == "constant":
        m = StiffnessMap.constant(doc.get("sigma"), doc.get("n_channels"))
    elif kind == "mlp":
        m = StiffnessMap.from_networks(doc.get("networks") or [])
    else:
        raise design_error("kind", kind, "must be 'table', 'constant' or 'mlp'", InputError)
    if doc.get("n_channels") != m.n_channels:
        raise design_error(
            "n_channels",
            doc.get("n_channels"),
            f"disagrees with the map ({m.n_channels})",
            InputError,
        )
    object.__setattr__(m, "_describe", f"{m._describe}, from {name}")
    return m


def load_stiffness_map(path: str | Path, **options) -> StiffnessMap:
    """A stiffness map from a file: the JSON written by :meth:`StiffnessMap.save` (also by
    ``HybridStiffnessModel.save``) or a table CSV (:meth:`StiffnessMap.from_csv`; ``options``
    ``method`` and ``outside`` apply to CSV tables only). A JSON file of a newer format
    version, or not a softrod map at all, is an InputError that says so."""
    path = as_path(path)
    if path.suffix.lower() == ".csv":
        return StiffnessMap.from_csv(path, **options)
    if path.suffix.lower() != ".json":
        raise design_error(
            "path",
            str(path),
            "a stiffness map file ends in .json (saved) or .csv (a table)",
            InputError,
        )
    if options:
        key = sorted(options)[0]
        raise design_error(
            key, options[key], "applies to CSV tables; a saved map keeps its own", InputError
        )
    return map_from_document(read_map_document(path), path.name)
