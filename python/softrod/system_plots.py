"""Figures of systems of rods (matplotlib, imported lazily): equilibria in front and side
views (:func:`plot_system`) and a motion's platform against time
(:func:`plot_system_motion`). Axes in mm, degrees and kPa; files are written atomically by
:func:`softrod.plotting.save_figure`. This module never selects a matplotlib backend.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

from . import _validate as V
from .errors import InputError

if TYPE_CHECKING:
    from matplotlib.figure import Figure


# The figures read results by their fields: softrod.system and softrod.system_dynamics
# call them from their plot methods, so this module does not import those (no cycle).
@runtime_checkable
class SystemSolutionLike(Protocol):
    """What plot_system reads of a system's equilibrium (a softrod.SystemSolution)."""

    rods: Any
    platform_position: np.ndarray
    platform_rotation: np.ndarray
    converged: bool


@runtime_checkable
class SystemTrajectoryLike(Protocol):
    """What plot_system_motion reads of a system's motion (a softrod.SystemTrajectory)."""

    system: Any
    time: np.ndarray
    platform_position: np.ndarray
    platform_rotation: np.ndarray
    pressures: Any


def _is_solution(obj) -> bool:
    return isinstance(obj, SystemSolutionLike)


def _is_trajectory(obj) -> bool:
    return isinstance(obj, SystemTrajectoryLike) and not _is_solution(obj)


# The two views of plot_system: (horizontal axis, vertical axis) indices into (x, y, z).
VIEWS = (("front view (x-z)", 0, 2), ("side view (y-z)", 1, 2))


def style_views(axes) -> None:
    """Title, labels (mm), equal aspect and grid of the front (x-z) and side (y-z) views."""
    for ax, (name, a, _) in zip(axes, VIEWS, strict=True):
        ax.set_title(name)
        ax.set_xlabel(f"{'xyz'[a]} (mm)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("z (mm)")


def platform_tilt_deg(rotation: np.ndarray) -> np.ndarray:
    """The angle (deg) between the platform's d3 axis and the world z axis, for one (3, 3)
    rotation or a stack (n, 3, 3): 0 for a platform level with its nominal frame."""
    r = np.asarray(rotation, dtype=float)
    return np.degrees(np.arccos(np.clip(r[..., 2, 2], -1.0, 1.0)))


def _pressure_text(solution: SystemSolutionLike) -> str:
    """'rod 0: 40, 0, 0 | rod 1: 0, 0, 0 kPa' from the rods' pressures."""
    parts = [
        f"rod {i}: " + ", ".join(f"{p / 1e3:g}" for p in np.ravel(r.pressures))
        for i, r in enumerate(solution.rods)
    ]
    return " | ".join(parts) + " kPa"


def plot_system(
    solutions: SystemSolutionLike | Sequence[SystemSolutionLike],
    path: str | os.PathLike | None = None,
    *,
    labels: Sequence[str] | None = None,
    title: str | None = None,
) -> Figure:
    """Front (x-z) and side (y-z) views of one or more equilibria of a system: every rod's
    centreline, the platform as the outline through the rods' tips, the bases as black
    squares, the rods' obstacles near them (planes seen edge-on, spheres, meshes projected)
    and their contact points; one colour per solution, labelled with ``labels`` (default: the rods'
    pressures and the platform's tilt). Written to ``path`` when given (format from the
    suffix, atomically). Returns the Figure (pyplot's: close it when done)."""
    title = V.figure_title(title)
    import matplotlib.pyplot as plt

    from .plotting import check_figure_path, save_figure

    if _is_solution(solutions):
        sols = [solutions]
    elif isinstance(solutions, Sequence) and not isinstance(solutions, str):
        sols = list(solutions)
    else:
        sols = []
    if not sols or not all(_is_solution(s) for s in sols):
        raise V.fail(
            "solutions",
            type(solutions).__name__,
            "must be a SystemSolution or a non-empty list of them",
            InputError,
        )
    if labels is not None and not (
        isinstance(labels, (list, tuple))
        and len(labels) == len(sols)
        and all(isinstance(x, str) for x in labels)
    ):
        raise V.fail(
            "labels",
            labels,
            f"must give one label per solution ({len(sols)}): a list of text",
            InputError,
        )
    if path is not None:
        check_figure_path(path)
    fig, axes = plt.subplots(1, 2, figsize=(9.5, 5.4), sharey=True)
    colours = plt.cm.viridis(np.linspace(0.0, 0.85, max(len(sols), 2)))
    for k, sol in enumerate(sols):
        tips = np.array([r.tip_position for r in sol.rods]) * 1e3
        # The platform's outline: a segment for two rods, a closed polygon for more.
        outline = tips if len(tips) < 3 else np.vstack([tips, tips[:1]])
        tilt = float(platform_tilt_deg(sol.platform_rotation))
        label = labels[k] if labels is not None else f"{_pressure_text(sol)} (tilt {tilt:.1f} deg)"
        for ax, (_, a, b) in zip(axes, VIEWS, strict=True):
            for r in sol.rods:
                ax.plot(r.position[:, a] * 1e3, r.position[:, b] * 1e3, color=colours[k], lw=2)
            ax.plot(
                outline[:, a],
                outline[:, b],
                color=colours[k],
                lw=5,
                solid_capstyle="butt",
                label=label if ax is axes[0] else None,
            )
    bases = np.array([r.position[0] for r in sols[0].rods]) * 1e3
    extra = _draw_contacts(axes, sols, colours)
    for ax, (_, a, b) in zip(axes, VIEWS, strict=True):
        ax.plot(bases[:, a], bases[:, b], "s", color="black", ms=7)
    style_views(axes)
    # The legend below the views: long labels never cover the rods.
    handles, _ = axes[0].get_legend_handles_labels()
    fig.legend(handles=handles + extra, loc="lower center", ncol=1, fontsize=8, frameon=False)
    fig.suptitle(title or f"{sols[0].system.name}: equilibria")
    fig.tight_layout(rect=(0.0, 0.04 + 0.035 * (len(sols) + len(extra)), 1.0, 1.0))
    if path is not None:
        save_figure(fig, path)
    return fig


def _draw_contacts(axes, sols, colours) -> list:
    """The rods' obstacles near the shapes in both views (a plane seen edge-on as a line, a
    sphere as its outline, a mesh as its projected triangles; others are not drawn in these
    views) and each solution's
    contact points (docs/contact.md); returns legend entries for what was drawn."""
    from matplotlib.collections import PolyCollection
    from matplotlib.lines import Line2D
    from matplotlib.patches import Circle

    from .plotting import _OBSTACLE, _near_obstacles
    from .viewer.geometry import drawn_triangles

    specs: list[dict] = []
    for sol in sols:
        for r in sol.rods:
            for ob in r.design.spec.get("obstacles", []):
                if ob not in specs:
                    specs.append(ob)
    points = np.concatenate([r.position for sol in sols for r in sol.rods]) * 1e3
    near, extra = _near_obstacles(specs, points) if specs else ([], np.zeros((0, 3)))
    drawn = False
    for ax, (_, a, b) in zip(axes, VIEWS, strict=True):
        for ob in near:
            if ob["kind"] == "plane":
                n = np.asarray(ob["normal"], float)
                n = n / np.linalg.norm(n)
                if np.hypot(n[a], n[b]) < 0.99:
                    continue  # not edge-on in this view
                c = np.asarray(ob["point"], float)[[a, b]] * 1e3
                ax.axline(tuple(c), tuple(c + [-n[b], n[a]]), lw=3, **_OBSTACLE)
                # Hold the plane in the view where the shapes' points meet it.
                ax.update_datalim(extra[:, [a, b]])
                drawn = True
            elif ob["kind"] == "sphere":
                c = np.asarray(ob["center"], float)[[a, b]] * 1e3
                ax.add_patch(Circle(tuple(c), ob["radius"] * 1e3, **_OBSTACLE))
                ax.update_datalim(extra[:, [a, b]])
                drawn = True
            elif ob["kind"] == "mesh":
                # Its triangles projected onto the view (at most MAX_DRAWN_TRIANGLES): the
                # mesh's shadow, a table's edge-on strip; the view holds its part near the
                # shapes (`_near_obstacles`' points), not a big mesh's far corners.
                tri = drawn_triangles(ob)[:, :, [a, b]] * 1e3
                # Edges drawn too: a flat mesh seen edge-on (a table) is a line.
                ax.add_collection(
                    PolyCollection(
                        list(tri),
                        facecolor=_OBSTACLE["color"],
                        edgecolor=_OBSTACLE["color"],
                        linewidth=1.5,
                        alpha=_OBSTACLE["alpha"],
                    ),
                    autolim=False,
                )
                ax.update_datalim(extra[:, [a, b]])
                drawn = True
        for k, sol in enumerate(sols):
            for r in sol.rods:
                if r.contact is not None and r.contact.in_contact.any():
                    pts = r.contact.point[r.contact.in_contact] * 1e3
                    ax.plot(pts[:, a], pts[:, b], "o", color=colours[k], ms=4)
    handles = []
    if drawn:
        handles.append(Line2D([], [], lw=3, label="obstacle (seen edge-on)", **_OBSTACLE))
    if any(r.contact is not None and r.contact.in_contact.any() for s in sols for r in s.rods):
        handles.append(Line2D([], [], marker="o", ls="none", color="0.3", label="contact"))
    return handles


def plot_system_motion(
    trajectory: SystemTrajectoryLike,
    path: str | os.PathLike | None = None,
    *,
    reference: SystemSolutionLike | None = None,
    title: str | None = None,
) -> Figure:
    """A system's motion against time in three panels: the platform's displacement from its
    start (x, y, z, mm), its tilt (deg, :func:`platform_tilt_deg`) and every rod's commanded
    pressures (kPa). ``reference``: an equilibrium (e.g. :func:`softrod.solve_system` under
    the final inputs) drawn dashed in the first two panels. Written to ``path`` when given
    (format from the suffix, atomically). Returns the Figure (pyplot's: close it when
    done)."""
    title = V.figure_title(title)
    import matplotlib.pyplot as plt

    from .plotting import check_figure_path, save_figure

    if not _is_trajectory(trajectory):
        raise V.fail(
            "trajectory", type(trajectory).__name__, "must be a SystemTrajectory", InputError
        )
    if reference is not None and not _is_solution(reference):
        raise V.fail(
            "reference", type(reference).__name__, "must be a SystemSolution or None", InputError
        )
    if path is not None:
        check_figure_path(path)
    t = trajectory.time
    scale, unit = (1e3, "ms") if t[-1] - t[0] < 2.0 else (1.0, "s")
    ts = t * scale
    fig, axes = plt.subplots(3, 1, figsize=(8.5, 7.2), sharex=True)
    start = trajectory.platform_position[0]
    colours = ("tab:blue", "tab:orange", "tab:green")
    for k, (name, colour) in enumerate(zip("xyz", colours, strict=True)):
        axes[0].plot(
            ts, (trajectory.platform_position[:, k] - start[k]) * 1e3, color=colour, label=name
        )
        if reference is not None:
            level = (reference.platform_position[k] - start[k]) * 1e3
            axes[0].axhline(level, color=colour, ls="--", lw=1)
    axes[0].set_ylabel("platform displacement (mm)")
    axes[0].legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=8)
    tilt = platform_tilt_deg(trajectory.platform_rotation)
    axes[1].plot(ts, tilt, color="tab:purple", label="simulated")
    if reference is not None:
        axes[1].axhline(
            float(platform_tilt_deg(reference.platform_rotation)),
            color="tab:purple",
            ls="--",
            lw=1,
            label="equilibrium",
        )
    axes[1].set_ylabel("platform tilt (deg)")
    axes[1].legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=8)
    styles = ("-", "--", ":", "-.")
    for i, p in enumerate(trajectory.pressures):
        for c in range(p.shape[1]):
            axes[2].plot(
                ts,
                p[:, c] / 1e3,
                ls=styles[i % len(styles)],
                color=f"C{c}",
                label=f"rod {i} p{c}",
            )
    axes[2].set_ylabel("pressure (kPa)")
    axes[2].set_xlabel(f"time ({unit})")
    if any(p.shape[1] for p in trajectory.pressures):
        # Beside the panels, not over the curves.
        axes[2].legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=7)
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle(title or f"{trajectory.system.name}: motion")
    fig.tight_layout()
    if path is not None:
        save_figure(fig, path)
    return fig
