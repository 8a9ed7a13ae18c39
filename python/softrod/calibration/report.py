"""A calibration report as one self-contained HTML file.

:func:`write_report` writes the title, a summary, warnings, the parameter table, the
parameter correlation matrix, the tip-error tables and figures after paper 001 Figs. 5-7,
embedded as base64 PNG images (matplotlib, Agg canvas; no external files, inline CSS).
The file is written atomically: a failure at any step leaves no file and no temporary file.
:func:`save_figures` writes the same figures as PNG files.

Figures (tip positions in mm, world frame):

- ``tip_positions``: measured and predicted tips, top (x-y) and side (x-z) views, one colour
  per set (train, test, ...), each pair joined by a line;
- ``tip_error_boxes``: box plots of the Euclidean tip error per set, with the signed radial
  and height errors (measured minus predicted) of paper 001 Fig. 7 when the base and axis
  are given, and a % of L scale when the length L is given;
- ``tip_error_map``: measured tips coloured by the tip error, in top and side view (paper
  001 Fig. 6, bottom, shows them in 3-D);
- ``factors`` (with ``factors``): measured tips coloured by each identified stiffness factor,
  one row of top and side views per factor (paper 001 Fig. 5);
- ``error_vs_pressure`` (with ``pressures``): tip error against each chamber pressure.
"""

from __future__ import annotations

import base64
import html
import io
from collections.abc import Mapping, Sequence
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from ..errors import InputError, design_error
from ..io import as_path, atomic_path
from ..io import is_dir as _is_dir
from ..plotting import save_figure
from .diagnostics import STRONG_CORRELATION
from .metrics import ALL, _length, per_sample_errors

_CORRELATION_ROUNDING = 1e-9  # |r| may exceed 1 by rounding; more means it is no correlation
REPORT_SUFFIXES = (".html", ".htm")
_DPI = 110

_CSS = """
body { font-family: sans-serif; max-width: 1100px; margin: 1.5em auto; color: #222; }
h1 { font-size: 1.6em; } h2 { font-size: 1.25em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 0.5em 0 1em; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 3px 7px; text-align: right; }
th { background: #f0f0f0; }
td.key, th.key { text-align: left; }
td.strong { background: #f8c9c4; font-weight: bold; }
.warnings { background: #fff3cd; border: 1px solid #e0b100; padding: 0.5em 1em 0.5em 2em; }
.note { color: #555; font-size: 0.9em; }
.wide { overflow-x: auto; }
figure { margin: 1em 0; } figure img { max-width: 100%; }
figcaption { color: #444; font-size: 0.9em; }
footer { color: #777; font-size: 0.8em; margin-top: 2em; }
"""


# --------------------------------------------------------------------------- inputs


def _check_report_path(path) -> Path:
    path = as_path(path)
    if path.suffix.lower() not in REPORT_SUFFIXES:
        raise design_error(
            "path",
            str(path),
            f"a report is an HTML file: the name must end in {' or '.join(REPORT_SUFFIXES)}",
            InputError,
        )
    return path


def _per_sample_array(value, field: str, m: int, rule: str) -> np.ndarray:
    """(m,) or (m, k) floats as (m, k)."""
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise design_error(field, type(value).__name__, f"{rule}: {exc}", InputError) from None
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[0] != m or arr.shape[1] == 0:
        raise design_error(field, f"shape {arr.shape}", rule, InputError)
    return arr


def _names(names, k: int, field: str, default: str) -> list[str]:
    if names is None:
        return [f"{default} {i + 1}" for i in range(k)]
    names = [str(n) for n in names]
    if len(names) != k:
        raise design_error(field, names, f"must give {k} names, one per column", InputError)
    return names


def _correlation(correlation, param_names) -> tuple[np.ndarray, list[str]]:
    if hasattr(correlation, "columns") and param_names is None:
        param_names = list(correlation.columns)
    try:
        r = np.array(correlation, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise design_error(
            "correlation", type(correlation).__name__, f"must be numbers: {exc}", InputError
        ) from None
    if r.ndim != 2 or r.shape[0] != r.shape[1] or r.shape[0] == 0:
        raise design_error(
            "correlation", f"shape {r.shape}", "must be a square (k, k) matrix", InputError
        )
    if np.any(np.abs(r[~np.isnan(r)]) > 1.0 + _CORRELATION_ROUNDING):
        raise design_error(
            "correlation",
            float(np.nanmax(np.abs(r))),
            "entries must lie in [-1, 1]: pass the correlation, not the covariance",
            InputError,
        )
    return r, _names(param_names, r.shape[0], "param_names", "parameter")


# --------------------------------------------------------------------------- figures


def _new_figure(width: float, height: float):
    """A Figure on an Agg canvas, independent of pyplot (nothing to close)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _set_styles(sets: np.ndarray) -> dict[str, dict]:
    import matplotlib as mpl

    colours = mpl.rcParams["axes.prop_cycle"].by_key().get("color", ["C0"])
    markers = ("o", "^", "s", "D", "v", "P")
    return {
        name: {"color": colours[i % len(colours)], "marker": markers[i % len(markers)]}
        for i, name in enumerate(dict.fromkeys(sets))
    }


def _positions_figure(meas: np.ndarray, pred: np.ndarray, samples, point: str = "tip"):
    """Measured and predicted tips (or ``point``s) in top and side view (paper 001 Fig. 5
    shows the tips)."""
    from matplotlib.collections import LineCollection

    fig = _new_figure(10.0, 4.8)
    sets = samples["set"].to_numpy()
    failed = samples["failed"].to_numpy()
    styles = _set_styles(sets)
    for ax, (i, j) in zip(fig.subplots(1, 2), ((0, 1), (0, 2)), strict=True):
        ok = ~failed
        pairs = np.stack([meas[ok][:, [i, j]], pred[ok][:, [i, j]]], axis=1)
        ax.add_collection(LineCollection(pairs, colors="0.6", linewidths=0.7, zorder=1))
        for name, style in styles.items():
            s = (sets == name) & ok
            ax.scatter(meas[s, i], meas[s, j], s=22, alpha=0.85, label=f"{name} measured", **style)
            ax.scatter(
                pred[s, i],
                pred[s, j],
                s=26,
                facecolors="none",
                edgecolors=style["color"],
                marker=style["marker"],
                label=f"{name} predicted",
            )
        if failed.any():
            ax.scatter(
                meas[failed, i],
                meas[failed, j],
                s=40,
                marker="x",
                color="tab:red",
                label=f"prediction failed ({int(failed.sum())})",
            )
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel(f"{'xyz'[i]} (mm)")
        ax.set_ylabel(f"{'xyz'[j]} (mm)")
        ax.set_title("top view (x-y)" if j == 1 else "side view (x-z)")
        ax.grid(True, alpha=0.3)
    fig.axes[0].legend(fontsize="small", framealpha=0.85)
    fig.suptitle(f"{point.capitalize()} positions: measured (filled) and predicted (open)")
    return fig


def _groups(samples, column: str) -> tuple[list[np.ndarray], list[str]]:
    """Values of ``column`` per set (then "all" if several), failed samples left out."""
    ok = samples[~samples["failed"]]
    names = list(dict.fromkeys(samples["set"]))
    data = [ok.loc[ok["set"] == n, column].to_numpy() for n in names]
    if len(names) > 1:
        names.append(ALL)
        data.append(ok[column].to_numpy())
    return data, names


def _box(ax, samples, column: str, ylabel: str, length_mm: float | None) -> None:
    data, names = _groups(samples, column)
    filled = [k for k, d in enumerate(data) if d.size]
    if filled:
        ax.boxplot([data[k] for k in filled], positions=np.arange(len(filled)), widths=0.5)
    ax.set_xticks(np.arange(len(filled)))
    # Long set names or many sets would run into each other side by side: stand them up.
    upright = len(filled) > 4 or max((len(str(names[k])) for k in filled), default=0) > 8
    sep = " " if upright else "\n"
    texts = [f"{names[k]}{sep}(n = {data[k].size})" for k in filled]
    ax.set_xticklabels(texts, rotation=90 if upright else 0)
    if not filled:
        ax.text(0.5, 0.5, "no successful prediction", ha="center", transform=ax.transAxes)
    ax.set_ylabel(ylabel)
    ax.ticklabel_format(axis="y", useOffset=False)  # mm as they are, no "+1.73e-1" above
    ax.grid(True, axis="y", alpha=0.3)
    if length_mm is not None:
        sec = ax.secondary_yaxis(
            "right",
            functions=(lambda mm: 100.0 * mm / length_mm, lambda pct: pct * length_mm / 100.0),
        )
        sec.set_ylabel(f"% of L (L = {length_mm:g} mm)")


def _error_box_figure(samples, length_mm: float | None, point: str = "tip"):
    """Box plots of the tip (``point``) error per set; radial and height errors as in
    paper 001 Fig. 7."""
    split = bool(samples["radial_error_mm"].notna().any())
    fig = _new_figure(12.0 if split else 5.5, 4.5)
    axes = fig.subplots(1, 3 if split else 1, squeeze=False)[0]
    _box(axes[0], samples, "error_mm", "|measured - predicted| (mm)", length_mm)
    axes[0].set_title(f"Euclidean {point} error")
    if split:
        for ax, col, what in zip(
            axes[1:], ("radial_error_mm", "height_error_mm"), ("radial", "height"), strict=True
        ):
            _box(ax, samples, col, f"measured - predicted, {what} (mm)", length_mm)
            ax.axhline(0.0, color="0.4", linewidth=0.8)
            ax.set_title(f"{what} error")
    return fig


VIEWS = ((0, 1, "top view (x-y)"), (0, 2, "side view (x-z)"))


def _map_views(fig, axes, points: np.ndarray, values: np.ndarray, label: str, **kw) -> None:
    """Points coloured by ``values`` in top and side view (2-D, equal scale), one colour bar.

    Two flat views instead of one 3-D scatter: every point and tick stays readable, the
    workspace of a hanging actuator being a shallow bowl (paper 001 Figs. 5-6 show it in 3-D).
    """
    norm = None
    if values.size:
        from matplotlib.colors import Normalize

        norm = Normalize(float(values.min()), float(values.max()))
    sc = None
    for ax, (i, j, name) in zip(axes, VIEWS, strict=True):
        if values.size:
            sc = ax.scatter(
                points[:, i], points[:, j], c=values, cmap="viridis", norm=norm, s=16, **kw
            )
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel(f"{'xyz'[i]} (mm)")
        ax.set_ylabel(f"{'xyz'[j]} (mm)")
        ax.set_title(name, fontsize="medium")
        ax.grid(True, alpha=0.3)
    if sc is not None:
        fig.colorbar(sc, ax=list(axes), shrink=0.9, label=label)


def _residual_figure(meas: np.ndarray, samples, point: str = "tip"):
    """Measured tips (``point``s) coloured by their error (like paper 001 Fig. 6, bottom)."""
    fig = _new_figure(10.0, 4.6)
    axes = fig.subplots(1, 2)
    failed = samples["failed"].to_numpy()
    err = samples["error_mm"].to_numpy()
    ok = ~failed
    _map_views(fig, axes, meas[ok], err[ok], f"Euclidean {point} error (mm)")
    if failed.any():
        for ax, (i, j, _) in zip(axes, VIEWS, strict=True):
            ax.scatter(
                meas[failed, i],
                meas[failed, j],
                marker="x",
                color="tab:red",
                s=36,
                label=f"prediction failed ({int(failed.sum())})",
            )
        axes[0].legend(fontsize="small")
    fig.suptitle(f"{point.capitalize()} error over the workspace (at the measured {point}s)")
    return fig


def _factor_figure(meas: np.ndarray, factors: np.ndarray, names: list[str]):
    """Measured tips coloured by each identified factor (paper 001 Fig. 5): one row per
    factor, top and side view."""
    k = factors.shape[1]
    fig = _new_figure(10.0, 3.9 * k + 0.5)
    rows = fig.subplots(k, 2, squeeze=False)
    for axes, name, f in zip(rows, names, factors.T, strict=True):
        ok = np.isfinite(f)
        _map_views(fig, axes, meas[ok], f[ok], f"{name} (-)")
        missing = int((~ok).sum())
        axes[0].set_title(
            f"{name}: top view (x-y)" + (f", {missing} not identified" if missing else ""),
            fontsize="medium",
        )
        axes[1].set_title(f"{name}: side view (x-z)", fontsize="medium")
    fig.suptitle("Identified factors at the measured tips (dimensionless)")
    return fig


def _pressure_figure(samples, pressures_pa: np.ndarray, point: str = "tip"):
    """Tip (``point``) error against each chamber pressure."""
    k = pressures_pa.shape[1]
    fig = _new_figure(min(4.0 * k, 12.0), 3.8)
    sets = samples["set"].to_numpy()
    ok = ~samples["failed"].to_numpy()
    err = samples["error_mm"].to_numpy()
    styles = _set_styles(sets)
    axes = fig.subplots(1, k, squeeze=False, sharey=True)[0]
    for c, ax in enumerate(axes):
        for name, style in styles.items():
            s = (sets == name) & ok
            ax.scatter(pressures_pa[s, c] / 1e3, err[s], s=16, alpha=0.8, label=name, **style)
        ax.set_xlabel(f"p{c} (kPa)")
        ax.grid(True, alpha=0.3)
    axes[0].set_ylabel(f"Euclidean {point} error (mm)")
    axes[0].legend(fontsize="small")
    fig.suptitle(f"{point.capitalize()} error against chamber pressure (gauge)")
    return fig


def _figures(
    measured,
    predicted,
    *,
    labels=None,
    pressures=None,
    factors=None,
    factor_names=None,
    length=None,
    axis=None,
    base_position=None,
    point: str = "tip",
) -> list[tuple[str, str, object]]:
    """(file stem, caption, Figure) of every figure the inputs allow; inputs are checked
    before any figure is made. ``point`` names what was measured in titles and captions
    ("tip", "platform", "marker"); the file stems stay."""
    samples = per_sample_errors(
        measured, predicted, length=length, axis=axis, base_position=base_position, labels=labels
    )
    m = len(samples)
    length_mm = None if length is None else 1e3 * _length(length, "length")
    if pressures is not None:
        p = _per_sample_array(
            pressures, "pressures", m, f"must be ({m}, channels) gauge pressures in Pa"
        )
        if not np.all(np.isfinite(p)):
            raise design_error("pressures", "non-finite entry", "must be finite (Pa)", InputError)
    if factors is not None:
        f = _per_sample_array(factors, "factors", m, f"must be ({m}, k) factors, NaN if none")
        f_names = _names(factor_names, f.shape[1], "factor_names", "factor")
    meas = 1e3 * np.asarray(measured, dtype=float)
    pred = 1e3 * np.asarray(predicted, dtype=float)

    out = [
        (
            "tip_positions",
            f"Measured (filled) and predicted (open) {point} positions, top and side views; "
            "grey lines join each pair.",
            _positions_figure(meas, pred, samples, point),
        ),
        (
            "tip_error_boxes",
            f"{point.capitalize()} error per set (box: quartiles, whiskers: 1.5 IQR); radial "
            "and height errors as in paper 001 Fig. 7 when the base and axis are given.",
            _error_box_figure(samples, length_mm, point),
        ),
        (
            "tip_error_map",
            f"{point.capitalize()} error at the measured {point} positions, top and side view "
            "(like paper 001 Fig. 6, bottom).",
            _residual_figure(meas, samples, point),
        ),
    ]
    if factors is not None:
        out.append(
            (
                "factors",
                "Identified factors at the measured tip positions, top and side view (like paper "
                "001 Fig. 5).",
                _factor_figure(meas, f, f_names),
            )
        )
    if pressures is not None:
        out.append(
            (
                "error_vs_pressure",
                f"{point.capitalize()} error against each chamber pressure.",
                _pressure_figure(samples, p, point),
            )
        )
    return out


def _png_base64(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=_DPI)
    return base64.b64encode(buf.getvalue()).decode("ascii")


# --------------------------------------------------------------------------- HTML


def _fmt(value) -> str:
    if isinstance(value, (float, np.floating)):
        return f"{value:.6g}"
    return str(value)


def _table_html(df, field: str) -> str:
    import pandas as pd

    if not isinstance(df, pd.DataFrame):
        raise design_error(field, type(df).__name__, "must be a pandas DataFrame", InputError)
    table = df.to_html(
        index=not isinstance(df.index, pd.RangeIndex),
        float_format=lambda v: f"{v:.4g}",
        na_rep="n/a",
        border=0,
    )
    return f'<div class="wide">{table}</div>'


def _summary_html(summary: Mapping) -> str:
    rows = "".join(
        f'<tr><th class="key">{html.escape(str(k))}</th>'
        f'<td class="key">{html.escape(_fmt(v))}</td></tr>'
        for k, v in summary.items()
    )
    return f"<table>{rows}</table>"


def _warnings_html(items: Sequence[str], rules: str | None) -> str:
    note = f'<p class="note">Rules: {html.escape(rules)}.</p>' if rules else ""
    if not items:
        return '<p class="note">No warnings.</p>' + note
    li = "".join(f"<li>{html.escape(str(w))}</li>" for w in items)
    return f'<ul class="warnings">{li}</ul>' + note


def _correlation_html(r: np.ndarray, names: list[str]) -> str:
    head = "".join(f"<th>{html.escape(n)}</th>" for n in names)
    rows = []
    for i, name in enumerate(names):
        cells = []
        for j in range(len(names)):
            strong = i != j and abs(r[i, j]) > STRONG_CORRELATION
            cls = ' class="strong"' if strong else ""
            cells.append(f"<td{cls}>{r[i, j]:.3f}</td>")
        rows.append(f'<tr><th class="key">{html.escape(name)}</th>{"".join(cells)}</tr>')
    return (
        f'<div class="wide"><table><tr><th></th>{head}</tr>{"".join(rows)}</table></div>'
        '<p class="note">Highlighted: '
        f"|r| &gt; {STRONG_CORRELATION:g}; such parameters cannot be told apart well by these "
        "data.</p>"
    )


def _document(title, sections: list[tuple[str, str]]) -> str:
    from .._core import __version__

    body = "".join(f"<h2>{html.escape(h)}</h2>\n{content}\n" for h, content in sections)
    stamp = datetime.now(timezone.utc).isoformat(timespec="seconds")
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f"<title>{html.escape(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n"
        f"<h1>{html.escape(title)}</h1>\n{body}"
        f"<footer>Written by softrod {html.escape(__version__)} on {stamp} (UTC).</footer>\n"
        "</body>\n</html>\n"
    )


def write_report(
    path,
    *,
    title: str,
    summary: Mapping,
    parameter_table,
    error_table,
    measured,
    predicted,
    labels=None,
    pressures=None,
    factors=None,
    factor_names=None,
    reaction_table=None,
    warnings: Sequence[str] = (),
    correlation=None,
    param_names=None,
    length=None,
    axis=None,
    base_position=None,
    warning_rules: str | None = None,
    error_title: str = "Tip errors",
    point: str = "tip",
) -> Path:
    """Write a calibration report to ``path`` (``.html``): one self-contained file.

    title: the heading. summary: key/value pairs (design, dataset, method, iterations, cost,
    date, ...). parameter_table, error_table: pandas DataFrames (e.g. from
    :func:`~softrod.calibration.metrics.tip_error_table`), shown with their column names
    (which carry the units). measured, predicted: (m, 3) tip positions in m (world frame),
    NaN rows of ``predicted`` for failed predictions; labels: the set of each sample; both
    None without measured positions (no figures); ``error_title`` heads the error table,
    ``point`` names what was measured in the figures ("tip", "platform", "marker").
    reaction_table: a DataFrame of a held
    tip's reaction errors (in mN), shown after the tip errors, or None.
    pressures: (m, channels) gauge pressures in Pa (adds the error-against-pressure figure).
    factors, factor_names: (m, k) identified dimensionless factors per sample, NaN where
    none was found (adds paper 001 Fig. 5). warnings: shown highlighted near the top, with
    ``warning_rules`` (the thresholds behind them) below.
    correlation, param_names: the (k, k) parameter correlation matrix (a DataFrame gives its
    own names); entries with |r| > :data:`STRONG_CORRELATION` are highlighted.
    length, axis, base_position: as in :func:`~softrod.calibration.metrics.per_sample_errors`;
    with ``length`` the box plots get a % of L scale, with ``axis`` and ``base_position``
    radial and height errors (paper 001 Fig. 7).

    The file is written atomically; on any error (a missing folder raises
    :class:`InputError`) no file is left behind. Returns the path.
    """
    path = _check_report_path(path)
    tables = [
        ("Parameters", _table_html(parameter_table, "parameter_table")),
        (error_title, _table_html(error_table, "error_table")),
    ]
    if reaction_table is not None:
        tables.append(("Reaction errors", _table_html(reaction_table, "reaction_table")))
    if correlation is not None:
        tables.insert(
            1, ("Parameter correlation", _correlation_html(*_correlation(correlation, param_names)))
        )
    if isinstance(warnings, str):
        warnings = [warnings]
    with atomic_path(path) as tmp:
        figures = (
            []
            if measured is None
            else _figures(
                measured,
                predicted,
                labels=labels,
                pressures=pressures,
                factors=factors,
                factor_names=factor_names,
                length=length,
                axis=axis,
                base_position=base_position,
                point=point,
            )
        )
        images = "".join(
            f'<figure><img alt="{html.escape(stem)}" src="data:image/png;base64,'
            f'{_png_base64(fig)}"><figcaption>{html.escape(caption)}</figcaption></figure>\n'
            for stem, caption, fig in figures
        )
        sections = [
            ("Summary", _summary_html(summary)),
            ("Warnings", _warnings_html(list(warnings), warning_rules)),
            *tables,
            ("Figures", images),
        ]
        tmp.write_text(_document(str(title), sections), encoding="utf-8")
    return path


def save_figures(
    folder,
    measured,
    predicted,
    *,
    labels=None,
    pressures=None,
    factors=None,
    factor_names=None,
    length=None,
    axis=None,
    base_position=None,
) -> list[Path]:
    """Write the report's figures as ``<folder>/<name>.png`` (names in the module
    docstring), each atomically; arguments as in :func:`write_report`. Returns the paths."""
    folder = Path(folder)
    if not _is_dir(folder):
        raise design_error("folder", str(folder), "folder does not exist", InputError)
    figures = _figures(
        measured,
        predicted,
        labels=labels,
        pressures=pressures,
        factors=factors,
        factor_names=factor_names,
        length=length,
        axis=axis,
        base_position=base_position,
    )
    return [save_figure(fig, folder / f"{stem}.png") for stem, _, fig in figures]
