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

from . import _validate as V
from .errors import InputError, design_error
from .io import as_path, atomic_path, check_target
from .statics import StaticSolution
from .viewer.geometry import drawn_triangles, frame_along  # plain numpy: no viewer dependency

# Styles of the parts of a rod. Chambered (actuated) sections take the colour of their
# solution so several shapes stay distinguishable; passive and rigid parts are grey.
_PASSIVE = {"color": "0.55", "linewidth": 3.0, "solid_capstyle": "butt"}
_RIGID = {"color": "0.15", "linewidth": 5.0, "solid_capstyle": "butt"}
_CHAMBER_WIDTH = 3.0
_FRAME_COLOURS = ("tab:red", "tab:green", "tab:blue")  # d1, d2, d3
_OBSTACLE = {"color": "0.55", "alpha": 0.3}  # the design's obstacles (docs/contact.md)
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
    style_3d_axes(ax)


def style_3d_axes(ax) -> None:
    """Readable ticks and labels on a 3-D Axes whose box aspect is already set.

    Each axis gets a number of ticks in proportion to its length in the box (a short axis of
    a flat or slender shape gets 2 or 3, not 6 crowded ones), and the tick labels and axis
    labels stand off the axis lines, so a minus sign does not merge with a tick mark and a
    label does not sit on the tick labels.
    """
    from matplotlib.ticker import MaxNLocator

    box = np.asarray(ax.get_box_aspect(), dtype=float)
    box = box / box.max()
    for axis, side in zip((ax.xaxis, ax.yaxis, ax.zaxis), box, strict=True):
        axis.set_major_locator(MaxNLocator(nbins=max(2, int(round(4 * side))), steps=[1, 2, 5, 10]))
        # The tick marks point outwards by a few points; the labels start beyond them.
        axis.set_tick_params(pad=7 if axis is ax.zaxis else 4, labelsize="small")
        axis.labelpad = 14 if axis is ax.zaxis else 12
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")


def _tip_force(solution: StaticSolution) -> np.ndarray:
    """The tip force the solution was solved under (world frame, N): the call's or the
    design's, turned by the tip's rotation for a follower load. Not the total force at the
    tip, which also holds a held tip's reaction and the contact force on the rounded end."""
    design = solution.design
    loads = solution.tip_loads
    force = np.asarray(design.spec["tip"]["force"] if loads is None else loads[0], dtype=float)
    if design.spec["tip"].get("frame") == "body":
        return np.asarray(solution.rotation[-1], dtype=float) @ force
    return force


def _magnitude_label(newtons: float) -> str:
    return f"{newtons:.3g} N"


def plot_shape(
    solutions,
    *,
    ax=None,
    title: str | None = None,
    show_frames: bool = False,
    top_view: bool = True,
):
    """Draw the centrelines of one or more static solutions; return the Figure.

    Without ``ax``: a 3-D view and, with ``top_view`` (default), a top view (x-y) beside it,
    both in world coordinates in mm at equal scale, and the legend below them. With ``ax`` (a
    3-D Axes, ``projection="3d"``): the 3-D view only, drawn into it. Chambered (actuated)
    sections are drawn in the solution's colour, passive sections (caps) in light grey and
    rigid parts in dark grey; the base is a black square and the tip a dot. The legend gives
    each shape's chamber pressures in kPa. A dead tip force (the call's ``tip_force`` or the
    design's ``[tip] force``) is an arrow at the tip, in the shape's colour, with its
    magnitude in the legend; the arrows share one scale, the largest as long as a quarter of
    the shape (a follower load is drawn as it acts, turned with the tip; a held tip's
    reaction and contact forces are not tip forces: :attr:`StaticSolution.tip_reaction_force`
    and :attr:`StaticSolution.contact` give them). The designs' obstacles within half the
    shapes' extent of them are drawn translucent grey in the 3-D view, at their true size
    beside the centrelines (a rod touching one is its radius away from it): planes and
    infinite cylinders and capsules cut to the view, spheres whole, meshes as their
    triangles cut to the view. ``show_frames`` adds the
    director triads d1, d2, d3 (red, green, blue) at a few nodes. Solutions that did not
    converge are listed but not drawn.
    """
    title = V.figure_title(title)
    import matplotlib as mpl
    from matplotlib.lines import Line2D

    sols = _as_list(solutions)
    if ax is None:
        import matplotlib.pyplot as plt

        if top_view:
            fig = plt.figure(figsize=(12.0, 6.4), layout="constrained")
            grid = fig.add_gridspec(1, 2, width_ratios=[1.1, 1.0])
            ax = fig.add_subplot(grid[0], projection="3d")
            top = fig.add_subplot(grid[1])
        else:
            fig = plt.figure(figsize=(7.0, 6.8), layout="constrained")
            ax = fig.add_subplot(projection="3d")
            top = None
        own_figure = True
    elif not hasattr(ax, "zaxis"):
        raise design_error(
            "ax", type(ax).__name__, "must be a 3-D Axes (projection='3d')", InputError
        )
    else:
        top, own_figure = None, False
    fig = ax.figure

    colours = mpl.rcParams["axes.prop_cycle"].by_key().get("color", ["C0"])

    handles: list = []
    kinds_seen: set[str] = set()
    drawn: list[np.ndarray] = []
    loads: list[tuple[np.ndarray, np.ndarray, str]] = []  # (tip mm, force N, colour)
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
            if top is not None:
                top.plot(seg[:, 0], seg[:, 1], **style)
        ax.scatter(*pos[0], marker="s", s=40, color="black", depthshade=False)
        ax.scatter(*pos[-1], marker="o", s=36, color=colour, edgecolors="black", depthshade=False)
        if top is not None:
            top.scatter(*pos[0, :2], marker="s", s=40, color="black", zorder=3)
            top.scatter(*pos[-1, :2], marker="o", s=36, color=colour, edgecolors="black", zorder=3)
        force = _tip_force(sol)
        if np.all(np.isfinite(force)) and np.linalg.norm(force) > 1e-9:
            loads.append((pos[-1], force, colour))
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

    points = np.concatenate(drawn) if drawn else None
    if loads and points is not None:
        extent = float(np.ptp(points, axis=0).max()) or 1.0
        scale = 0.25 * extent / max(np.linalg.norm(f) for _, f, _ in loads)  # mm per N
        ends = []
        for tip, force, colour in loads:
            arrow = force * scale
            ax.quiver(
                *tip, *arrow, color=colour, linewidth=1.8, arrow_length_ratio=0.25, normalize=False
            )
            if top is not None and np.hypot(*arrow[:2]) > 0.05 * np.linalg.norm(arrow):
                top.annotate(
                    "",
                    xy=tuple(tip[:2] + arrow[:2]),
                    xytext=tuple(tip[:2]),
                    arrowprops={"arrowstyle": "-|>", "color": colour, "linewidth": 1.8},
                    annotation_clip=False,
                )
                top.update_datalim([tip[:2] + arrow[:2]])
            ends.append(tip + arrow)
        points = np.concatenate([points, np.array(ends)])
        magnitudes = sorted({_magnitude_label(float(np.linalg.norm(f))) for _, f, _ in loads})
        handles.append(
            Line2D(
                [],
                [],
                color="0.3",
                linewidth=1.8,
                marker=">",
                markevery=[-1],
                label=f"tip force {', '.join(magnitudes)} (arrows to scale)",
            )
        )
    obstacles = _obstacles(sols) if points is not None else []
    if obstacles:
        obstacles, extra = _near_obstacles(obstacles, points)
        points = np.concatenate([points, extra])
    if points is not None:
        _equal_box(ax, points)
    else:
        style_3d_axes(ax)
    if obstacles:
        lo = np.array([ax.get_xlim()[0], ax.get_ylim()[0], ax.get_zlim()[0]])
        hi = np.array([ax.get_xlim()[1], ax.get_ylim()[1], ax.get_zlim()[1]])
        _draw_obstacles(ax, obstacles, lo, hi)
        from matplotlib.patches import Patch

        handles.append(Patch(label="obstacle (3-D view; rods as centrelines)", **_OBSTACLE))
    handles.append(Line2D([], [], color="black", marker="s", linestyle="none", label="base"))
    if "passive" in kinds_seen:
        handles.append(Line2D([], [], label="passive section (cap)", **_PASSIVE))
    if "rigid" in kinds_seen:
        handles.append(Line2D([], [], label="rigid part", **_RIGID))
    if show_frames and drawn:
        for name, c in zip(("d1", "d2", "d3"), _FRAME_COLOURS, strict=True):
            handles.append(Line2D([], [], color=c, linewidth=1.0, label=name))
    if title is None:
        names = sorted({s.design.name for s in sols})
        title = ", ".join(names)
    if top is not None:
        top.set_aspect("equal", adjustable="datalim")
        top.set_xlabel("x (mm)")
        top.set_ylabel("y (mm)")
        top.set_title("top view (x-y), base at the black square", fontsize="medium")
        top.grid(True, alpha=0.3)
        ax.set_title("3-D view", fontsize="medium")
    if own_figure:
        fig.suptitle(title)
        fig.legend(handles=handles, loc="outside right center", fontsize="small", frameon=False)
    else:
        ax.set_title(title)
        ax.legend(handles=handles, loc="upper left", fontsize="small", framealpha=0.85)
    return fig


def _obstacles(sols: list[StaticSolution]) -> list[dict]:
    """The obstacles of the designs drawn (SI, as in the spec), each once."""
    out: list[dict] = []
    for sol in sols:
        for ob in sol.design.spec.get("obstacles", []):
            if ob not in out:
                out.append(ob)
    return out


def _near_obstacles(obstacles: list[dict], points_mm: np.ndarray) -> tuple[list[dict], np.ndarray]:
    """The obstacles within half the shapes' extent of them, and points (mm) the view must
    hold to show them: a sphere's or capsule's bounding corners, the feet of the shapes'
    points on a plane, or on a cylinder's axis or a capsule's segment and the box of its
    radius around them (so a table under a finger is in the view, a floor a metre below a
    13 cm arm is not)."""
    reach = 0.5 * max(float(np.ptp(points_mm, axis=0).max()), 1.0)
    near, extra = [], []
    for ob in obstacles:
        kind = ob["kind"]
        if kind == "plane":
            n = np.asarray(ob["normal"], float)
            n /= np.linalg.norm(n)
            gap = (points_mm - np.asarray(ob["point"]) * 1e3) @ n
            feet = points_mm - np.outer(gap, n)
            pts = feet
        elif kind == "cylinder":
            a = np.asarray(ob["axis"], float)
            a /= np.linalg.norm(a)
            p = np.asarray(ob["point"]) * 1e3
            feet = p + np.outer((points_mm - p) @ a, a)
            r = ob["radius"] * 1e3
            gap = np.linalg.norm(points_mm - feet, axis=1) - r
            pts = np.concatenate([feet - r, feet + r])  # its surface around those feet
        elif kind == "mesh":
            # The mesh's bounding box: its nearest points to the shapes' points bound the
            # mesh's distance from below. The view holds those feet and the mesh's vertices
            # within reach of the shapes' box: the part of a big mesh (a terrain, a bowl)
            # near the rod, not all of it.
            v = np.asarray(ob["vertices"], float) * 1e3
            feet = np.clip(points_mm, v.min(axis=0), v.max(axis=0))
            gap = np.linalg.norm(points_mm - feet, axis=1)
            lo, hi = points_mm.min(axis=0) - reach, points_mm.max(axis=0) + reach
            close = v[np.all((v >= lo) & (v <= hi), axis=1)]
            pts = np.concatenate([feet, close[:: max(1, len(close) // 5000)]])
        else:
            ends = [ob["center"]] * 2 if kind == "sphere" else [ob["start"], ob["end"]]
            r = ob["radius"] * 1e3
            a, b = (np.asarray(e, float) * 1e3 for e in ends)
            # The nearest points of the segment a-b (a sphere's is a point) and the box of
            # the radius around them: a long pin across the arm widens the view by its
            # radius, not its length (it is cut to the view when drawn).
            ab = b - a
            t = np.clip((points_mm - a) @ ab / max(float(ab @ ab), 1e-300), 0.0, 1.0)
            feet = a + np.outer(t, ab)
            gap = np.linalg.norm(points_mm - feet, axis=1) - r
            pts = np.concatenate([feet - r, feet + r])
        if np.min(gap) <= reach:
            near.append(ob)
            extra.append(pts)
    return near, (np.concatenate(extra) if extra else np.zeros((0, 3)))


def _plane_in_box(point, normal, lo, hi) -> np.ndarray:
    """The polygon (m, 3) where a plane cuts the box [lo, hi], ordered around its centre
    (empty when the plane misses the box)."""
    n = np.asarray(normal, float)
    corners = np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )
    dist = (corners - np.asarray(point, float)) @ n
    pts = []
    for i in range(8):
        for j in range(i + 1, 8):
            if np.count_nonzero(corners[i] != corners[j]) != 1:
                continue  # not an edge of the box
            if dist[i] * dist[j] < 0 or (dist[i] == 0.0):
                t = dist[i] / (dist[i] - dist[j]) if dist[i] != dist[j] else 0.0
                pts.append(corners[i] + t * (corners[j] - corners[i]))
    if len(pts) < 3:
        return np.zeros((0, 3))
    pts = np.array(pts)
    rot = frame_along(n)
    e1, e2 = rot[:, 0], rot[:, 1]
    c = pts.mean(axis=0)
    order = np.argsort(np.arctan2((pts - c) @ e2, (pts - c) @ e1))
    return pts[order]


def _clip_to_box(poly: np.ndarray, lo, hi) -> np.ndarray:
    """The convex polygon (m, 3) cut to the box [lo, hi] (Sutherland and Hodgman: one side
    of the box after the other)."""
    pts = [np.asarray(p, float) for p in poly]
    for axis in range(3):
        for bound, sign in ((lo[axis], 1.0), (hi[axis], -1.0)):
            out = []
            for k, p in enumerate(pts):
                q = pts[k - 1]
                dp, dq = sign * (p[axis] - bound), sign * (q[axis] - bound)
                if (dp >= 0) != (dq >= 0):
                    out.append(q + dq / (dq - dp) * (p - q))
                if dp >= 0:
                    out.append(p)
            pts = out
            if not pts:
                return np.zeros((0, 3))
    return np.array(pts)


def _tube_surface(ax, a, b, radius) -> None:
    """A cylinder of ``radius`` from a to b (mm), as a translucent surface."""
    rot = frame_along(np.asarray(b) - np.asarray(a))
    e1, e2 = rot[:, 0], rot[:, 1]
    th = np.linspace(0.0, 2.0 * np.pi, 25)
    ring = radius * (np.outer(np.cos(th), e1) + np.outer(np.sin(th), e2))
    grid = np.stack([np.asarray(a) + ring, np.asarray(b) + ring])  # (2, 25, 3)
    ax.plot_surface(grid[..., 0], grid[..., 1], grid[..., 2], linewidth=0, **_OBSTACLE)


def _ball_surface(ax, centre, radius) -> None:
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 25), np.linspace(0, np.pi, 13))
    x = centre[0] + radius * np.cos(u) * np.sin(v)
    y = centre[1] + radius * np.sin(u) * np.sin(v)
    z = centre[2] + radius * np.cos(v)
    ax.plot_surface(x, y, z, linewidth=0, **_OBSTACLE)


def _draw_obstacles(ax, obstacles: list[dict], lo, hi) -> None:
    """Draw the obstacles (mm) in the 3-D view whose limits are [lo, hi]: planes, cylinders
    and capsules as their part inside the view, spheres whole."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    for ob in obstacles:
        kind = ob["kind"]
        if kind == "plane":
            poly = _plane_in_box(np.asarray(ob["point"]) * 1e3, ob["normal"], lo, hi)
            if len(poly):
                ax.add_collection3d(
                    Poly3DCollection(
                        [poly],
                        facecolor=_OBSTACLE["color"],
                        edgecolor="0.4",
                        alpha=_OBSTACLE["alpha"],
                    )
                )
        elif kind == "sphere":
            _ball_surface(ax, np.asarray(ob["center"]) * 1e3, ob["radius"] * 1e3)
        elif kind == "mesh":
            # The triangles (at most MAX_DRAWN_TRIANGLES of them) cut to the view: those
            # inside whole, those across its border clipped to it.
            tri = drawn_triangles(ob) * 1e3
            inside = np.all((tri >= lo) & (tri <= hi), axis=(1, 2))
            across = ~inside & np.all(tri.max(axis=1) >= lo, axis=1)
            across &= np.all(tri.min(axis=1) <= hi, axis=1)
            polys = list(tri[inside])
            for t in tri[across]:
                poly = _clip_to_box(t, lo, hi)
                if len(poly) >= 3:
                    polys.append(poly)
            if polys:
                ax.add_collection3d(
                    Poly3DCollection(
                        polys,
                        facecolor=_OBSTACLE["color"],
                        edgecolor="0.55",
                        linewidth=0.2,
                        alpha=_OBSTACLE["alpha"],
                    )
                )
        elif kind in ("capsule", "cylinder"):
            # The axis cut to the view (slab method on the box widened by the radius); a
            # capsule's segment also to its ends, whose balls are drawn where in the view.
            if kind == "capsule":
                p, end = np.asarray(ob["start"]) * 1e3, np.asarray(ob["end"]) * 1e3
                d = end - p
                span = (0.0, float(np.linalg.norm(d)))
            else:
                p, d, span = np.asarray(ob["point"]) * 1e3, np.asarray(ob["axis"], float), None
            d = d / np.linalg.norm(d)
            r = ob["radius"] * 1e3
            t0, t1 = (-np.inf, np.inf) if span is None else span
            for i in range(3):
                if abs(d[i]) < 1e-12:
                    if not lo[i] - r <= p[i] <= hi[i] + r:
                        t0, t1 = 1.0, 0.0  # parallel to this slab and outside it
                    continue
                ta, tb = sorted(((lo[i] - r - p[i]) / d[i], (hi[i] + r - p[i]) / d[i]))
                t0, t1 = max(t0, ta), min(t1, tb)
            if t0 < t1:
                _tube_surface(ax, p + t0 * d, p + t1 * d, r)
            if span is not None:
                for c in (p, p + span[1] * d):
                    if np.all(c >= lo - r) and np.all(c <= hi + r):
                        _ball_surface(ax, c, r)


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

    if not isinstance(path, (str, os.PathLike)):
        raise design_error(
            "path", type(path).__name__, "must be a file name (text or a path) or None", InputError
        )
    path = as_path(path)
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
