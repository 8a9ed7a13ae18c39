"""Plots of static shapes (matplotlib, imported lazily).

``plot_shape`` draws one or more :class:`~softrod.StaticSolution` in 3-D with the axes in mm;
``save_figure`` writes a figure atomically, the format taken from the file suffix.
This module never selects a matplotlib backend; the CLI uses Agg.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from .errors import InputError, design_error
from .io import atomic_path, check_target
from .statics import StaticSolution

# Styles of the parts of a rod. Chambered (actuated) sections take the colour of their
# solution so several shapes stay distinguishable; passive and rigid parts are grey.
_PASSIVE = {"color": "0.55", "linewidth": 3.0, "solid_capstyle": "butt"}
_RIGID = {"color": "0.15", "linewidth": 5.0, "solid_capstyle": "butt"}
_CHAMBER_WIDTH = 3.0
_FRAME_COLOURS = ("tab:red", "tab:green", "tab:blue")  # d1, d2, d3
_N_FRAMES = 7  # director triads drawn along each rod with show_frames=True


def pressure_label(pressures: Iterable[float]) -> str:
    """'p = (0, 35, 0) kPa' for gauge pressures given in Pa."""
    values = ", ".join(f"{p / 1e3:g}" for p in np.asarray(pressures, dtype=float).ravel())
    return f"p = ({values}) kPa"


def _as_list(solutions) -> list[StaticSolution]:
    if isinstance(solutions, StaticSolution):
        return [solutions]
    try:
        items = list(solutions)
    except TypeError:
        items = None
    if not items or not all(isinstance(s, StaticSolution) for s in items):
        raise design_error(
            "solutions",
            type(solutions).__name__,
            "must be a StaticSolution or a non-empty sequence of them",
            InputError,
        )
    return items


def _spans(solution: StaticSolution) -> list[tuple[np.ndarray, str]]:
    """(node indices, kind) per section, kind in {'chambers', 'rigid', 'passive'}.

    A node carries the index of the section that ends there, so section k runs from the last
    node of section k-1 to its own last node.
    """
    props = solution.design.sections()
    section = np.asarray(solution.section)
    spans = []
    for k, sec in enumerate(props):
        idx = np.flatnonzero(section == k)
        if idx.size == 0:
            continue
        if idx[0] > 0:
            idx = np.concatenate(([idx[0] - 1], idx))
        kind = "rigid" if sec["rigid"] else ("chambers" if sec["chambers"] else "passive")
        spans.append((idx, kind))
    return spans


def _equal_box(ax, points_mm: np.ndarray) -> None:
    """Limits and box aspect from the data ranges so one mm is as long on every axis."""
    lo, hi = points_mm.min(axis=0), points_mm.max(axis=0)
    centre = 0.5 * (lo + hi)
    half = 0.5 * (hi - lo)
    # A straight or planar shape has a (near) zero range on some axis; give every axis at
    # least 30 % of the largest range so the box stays readable (the scale stays equal: the
    # limits widen, the box aspect follows them), and pad by 5 %.
    half = np.maximum(half, 0.3 * max(half.max(), 1.0)) * 1.05
    ax.set_xlim(centre[0] - half[0], centre[0] + half[0])
    ax.set_ylim(centre[1] - half[1], centre[1] + half[1])
    ax.set_zlim(centre[2] - half[2], centre[2] + half[2])
    ax.set_box_aspect(tuple(2.0 * half))


def plot_shape(solutions, *, ax=None, title: str | None = None, show_frames: bool = False):
    """Draw the centrelines of one or more static solutions in 3-D; return the Figure.

    Axes are world coordinates in mm with equal scale. Chambered (actuated) sections are
    drawn in the solution's colour, passive sections (caps) in light grey and rigid parts in
    dark grey; the base is a black square and the tip a dot. The legend gives each shape's
    chamber pressures in kPa. ``show_frames`` adds the director triads d1, d2, d3 (red, green,
    blue) at a few nodes. ``ax`` must be a 3-D Axes (``projection="3d"``); without it a new
    figure is made with pyplot. Solutions that did not converge are listed but not drawn.
    """
    import matplotlib as mpl
    from matplotlib.lines import Line2D
    from matplotlib.ticker import MaxNLocator

    sols = _as_list(solutions)
    if ax is None:
        import matplotlib.pyplot as plt

        fig = plt.figure(figsize=(7.0, 6.5))
        ax = fig.add_subplot(projection="3d")
    elif not hasattr(ax, "zaxis"):
        raise design_error(
            "ax", type(ax).__name__, "must be a 3-D Axes (projection='3d')", InputError
        )
    fig = ax.figure

    colours = mpl.rcParams["axes.prop_cycle"].by_key().get("color", ["C0"])

    handles: list = []
    kinds_seen: set[str] = set()
    drawn: list[np.ndarray] = []
    for i, sol in enumerate(sols):
        colour = colours[i % len(colours)]
        label = pressure_label(sol.pressures)
        pos = np.asarray(sol.position, dtype=float) * 1e3
        if not sol.converged or not np.all(np.isfinite(pos)):
            handles.append(
                Line2D([], [], color=colour, linestyle=":", label=f"{label} (not converged)")
            )
            continue
        drawn.append(pos)
        for idx, kind in _spans(sol):
            kinds_seen.add(kind)
            seg = pos[idx]
            if kind == "chambers":
                style = {"color": colour, "linewidth": _CHAMBER_WIDTH, "solid_capstyle": "butt"}
            else:
                style = _RIGID if kind == "rigid" else _PASSIVE
            ax.plot(seg[:, 0], seg[:, 1], seg[:, 2], **style)
        ax.scatter(*pos[0], marker="s", s=40, color="black", depthshade=False)
        ax.scatter(*pos[-1], marker="o", s=36, color=colour, edgecolors="black", depthshade=False)
        handles.append(
            Line2D(
                [],
                [],
                color=colour,
                linewidth=_CHAMBER_WIDTH,
                marker="o",
                markeredgecolor="black",
                label=label,
            )
        )
        if show_frames:
            _draw_frames(ax, pos, np.asarray(sol.rotation, dtype=float))

    if drawn:
        _equal_box(ax, np.concatenate(drawn))
    handles.append(Line2D([], [], color="black", marker="s", linestyle="none", label="base"))
    if "passive" in kinds_seen:
        handles.append(Line2D([], [], label="passive section (cap)", **_PASSIVE))
    if "rigid" in kinds_seen:
        handles.append(Line2D([], [], label="rigid part", **_RIGID))
    if show_frames and drawn:
        for name, c in zip(("d1", "d2", "d3"), _FRAME_COLOURS, strict=True):
            handles.append(Line2D([], [], color=c, linewidth=1.0, label=name))
    ax.legend(handles=handles, loc="upper left", fontsize="small", framealpha=0.85)
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):  # short axes get crowded ticks otherwise
        axis.set_major_locator(MaxNLocator(nbins=5))
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)", labelpad=10)
    if title is None:
        names = sorted({s.design.name for s in sols})
        title = ", ".join(names)
    ax.set_title(title)
    return fig


def _draw_frames(ax, pos_mm: np.ndarray, rot: np.ndarray) -> None:
    extent = float(np.ptp(pos_mm, axis=0).max()) if len(pos_mm) > 1 else 1.0
    length = 0.08 * max(extent, 1.0)
    nodes = np.unique(np.linspace(0, len(pos_mm) - 1, _N_FRAMES).round().astype(int))
    for j, colour in enumerate(_FRAME_COLOURS):
        d = rot[nodes, :, j]  # column j of R is d_{j+1} in world coordinates
        p = pos_mm[nodes]
        ax.quiver(
            p[:, 0],
            p[:, 1],
            p[:, 2],
            d[:, 0],
            d[:, 1],
            d[:, 2],
            length=length,
            color=colour,
            linewidth=1.0,
            arrow_length_ratio=0.2,
        )


def check_figure_path(path: str | os.PathLike) -> Path:
    """The path as a Path if matplotlib can write its suffix as a figure, else InputError.

    Call it before a computation whose figure is to be saved, so a typo fails at once.
    """
    from matplotlib.backend_bases import FigureCanvasBase

    path = Path(path)
    supported = FigureCanvasBase.get_supported_filetypes()
    if path.suffix.lower().lstrip(".") not in supported:
        raise design_error(
            "path",
            str(path),
            f"unknown figure format {path.suffix or '(no suffix)'!r}: the file name must end in "
            f"one of {', '.join('.' + k for k in sorted(supported))}",
            InputError,
        )
    return check_target(path)


def save_figure(fig, path: str | os.PathLike) -> Path:
    """Write ``fig`` (a Figure, or an Axes of one) to ``path`` atomically.

    The format comes from the suffix (``.png``, ``.pdf``, ``.svg``, ... whatever the canvas
    supports); an unknown or missing suffix raises :class:`InputError`. Returns the path.
    """
    from matplotlib.figure import Figure

    if not isinstance(fig, Figure):
        fig = getattr(fig, "figure", None)
        if not isinstance(fig, Figure):
            raise design_error("fig", type(fig).__name__, "must be a matplotlib Figure", InputError)
    path = check_figure_path(path)
    fmt = path.suffix.lower().lstrip(".")
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=fmt, dpi=150, bbox_inches="tight")
    return path
