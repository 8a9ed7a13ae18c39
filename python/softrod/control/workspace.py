"""The reachable workspace of a point of the rod under pressure (and tendon tension) bounds:
the images of the faces of the input box, solved in parallel by the Rust batch
(docs/control.md).

The inputs are the pressure channels followed by the tendon channels. For c inputs the box
[lo, hi]^c has 2c faces (one channel at a bound, the others free);
each face is sampled on a grid of ``samples`` values per free channel, in serpentine order so
that every row warm-starts from its neighbour. When the map from pressures to the tip is
injective (three chambers and a position), the image of the box's boundary is the boundary of
the reachable set (invariance of domain), so these samples outline the workspace. With more
channels than task dimensions the sweep still gives the faces' images, but the workspace's
boundary may also contain interior fold points; say so when you use it there.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.figure import Figure

    from .._types import ArrayLike, DesignLike, PathLike
    from ..statics import SolverOptions

import itertools
from dataclasses import dataclass, field

import numpy as np

from .. import _validate as V
from .._validate import integer
from ..catalog import load_design
from ..constraints import require_free_tip
from ..design import Design
from ..errors import InputError, design_error
from .inverse import pressure_bounds as _bounds
from .inverse import tension_bounds as _tension_bounds

__all__ = ["MAX_WORKSPACE_SOLVES", "Workspace", "workspace"]

#: Most equilibria one workspace sweep may solve (2 c samples^(c-1)).
MAX_WORKSPACE_SOLVES = 2_000_000


def _serpentine(samples: int, dims: int) -> np.ndarray:
    """Grid indices (samples^dims, dims) in boustrophedon order: consecutive rows differ
    in one index by one."""
    if dims == 0:
        return np.zeros((1, 0), dtype=int)
    inner = _serpentine(samples, dims - 1)
    rows = []
    for i in range(samples):
        block = inner if i % 2 == 0 else inner[::-1]
        rows.append(np.column_stack([np.full(len(block), i), block]))
    return np.vstack(rows)


@dataclass(frozen=True)
class Workspace:
    """Samples of the workspace boundary (SI).

    pressures (m, c) Pa; tensions (m, k) N (tendon designs; (m, 0) otherwise);
    tip_position (m, 3) m (NaN where a solve failed); converged (m,); face (m,) index into
    ``faces``, a list of (input, "lo" | "hi") with the inputs numbered pressures first, then
    tendons (``input_names``: p0 ..., t0 ...); grid (m, c + k - 1) the sample's indices on
    its face. ``bounds`` (c, 2) Pa, ``tension_bounds`` (k, 2) N, ``samples`` per free input.
    """

    design: Design
    bounds: np.ndarray
    samples: int
    faces: list
    pressures: np.ndarray
    tip_position: np.ndarray
    converged: np.ndarray
    face: np.ndarray
    grid: np.ndarray
    wall_time_s: float = field(default=float("nan"), compare=False)
    tensions: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    tension_bounds: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    def __repr__(self) -> str:
        return (
            f"Workspace({self.design.name!r}, {len(self.tip_position)} boundary samples, "
            f"{int(np.sum(self.converged))} converged, {self.samples} per free input)"
        )

    @property
    def input_names(self) -> tuple[str, ...]:
        """Names of the inputs the faces refer to: p0 ... (pressures), t0 ... (tensions)."""
        return tuple(f"p{c}" for c in range(self.pressures.shape[1])) + tuple(
            f"t{k}" for k in range(len(self.tension_bounds))
        )

    @property
    def points(self) -> np.ndarray:
        """The converged boundary points (k, 3), m."""
        return self.tip_position[self.converged]

    def summary(self) -> dict:
        """Extent along x, y, z (m), the largest distance from the base in the horizontal
        plane, the convex hull's volume (m^3) and how many solves converged."""
        from scipy.spatial import ConvexHull

        pts = self.points
        base = np.asarray(self.design.spec["mounting"]["base_position"], dtype=float)
        out = {
            "samples": int(len(self.converged)),
            "converged": int(self.converged.sum()),
            "min": pts.min(axis=0),
            "max": pts.max(axis=0),
            "reach_xy": float(np.max(np.hypot(*(pts[:, :2] - base[:2]).T))),
        }
        try:
            out["hull_volume"] = float(ConvexHull(pts).volume)
        except Exception:  # degenerate (flat or a curve): no volume
            out["hull_volume"] = 0.0
        return out

    def distance_to(self, point: ArrayLike) -> float:
        """Distance (m) from ``point`` to the nearest sampled boundary point."""
        p = V.real_array(point, "point", what="positions (m)")
        if p.shape != (3,):
            raise design_error("point", p.tolist(), "must be 3 positions (m)", InputError)
        return float(np.min(np.linalg.norm(self.points - p, axis=1)))

    def to_frame(self) -> pd.DataFrame:
        """One row per sample: face, the input held at a bound (its index ``channel`` and
        name ``input``) and side, pressures (kPa), tensions (N), tip (mm), converged."""
        import pandas as pd

        names = self.input_names
        cols = {
            "face": self.face,
            "channel": [self.faces[f][0] for f in self.face],
            "input": [names[self.faces[f][0]] for f in self.face],
            "side": [self.faces[f][1] for f in self.face],
        }
        for c in range(self.pressures.shape[1]):
            cols[f"p{c}_kPa"] = self.pressures[:, c] / 1e3
        for k in range(len(self.tension_bounds)):
            cols[f"t{k}_N"] = self.tensions[:, k]
        for k, axis in enumerate("xyz"):
            cols[f"tip_{axis}_mm"] = self.tip_position[:, k] * 1e3
        cols["converged"] = self.converged
        return pd.DataFrame(cols)

    def plot(self, path: PathLike | None = None, *, title: str | None = None) -> Figure:
        """3-D view of the boundary (one surface per face for three channels, points
        otherwise) beside top (x-y) and side (x-z) views at equal scale; saved to ``path``
        when given. Returns the figure."""
        title = V.figure_title(title)
        import matplotlib

        if path is not None:
            from ..plotting import check_figure_path

            path = check_figure_path(path)  # before drawing: a bad name fails at once
            matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt

        fig = plt.figure(figsize=(14, 5.0))
        grid = fig.add_gridspec(
            1, 3, width_ratios=[1.3, 1, 1], wspace=0.35, left=0.02, right=0.98, bottom=0.2, top=0.88
        )
        ax3 = fig.add_subplot(grid[0], projection="3d")
        top = fig.add_subplot(grid[1])
        side = fig.add_subplot(grid[2])
        mm = self.tip_position * 1e3
        names = self.input_names
        colours = plt.cm.tab10(np.linspace(0, 1, 10))
        for f, (channel, sidename) in enumerate(self.faces):
            rows = self.face == f
            label = f"{names[channel]} = {'lo' if sidename == 'lo' else 'hi'}"
            col = colours[f % 10]
            if len(names) == 3:
                g = self.grid[rows]
                surf = np.full((self.samples, self.samples, 3), np.nan)
                surf[g[:, 0], g[:, 1]] = mm[rows]
                ax3.plot_surface(
                    surf[..., 0],
                    surf[..., 1],
                    surf[..., 2],
                    color=col,
                    alpha=0.45,
                    linewidth=0,
                    shade=True,
                )
            else:
                ax3.scatter(*mm[rows].T, s=2, color=col)
            top.scatter(mm[rows, 0], mm[rows, 1], s=1.5, color=col, label=label)
            side.scatter(mm[rows, 0], mm[rows, 2], s=1.5, color=col)
        ax3.set_xlabel("x (mm)", labelpad=8)
        ax3.set_ylabel("y (mm)", labelpad=8)
        ax3.set_zlabel("z (mm)", labelpad=10)
        ax3.set_title("boundary of the workspace")
        span = np.nanmax(mm, axis=0) - np.nanmin(mm, axis=0)
        ax3.set_box_aspect(np.maximum(span, 0.25 * span.max()))
        # A short axis of the box would crowd its tick labels into each other.
        from matplotlib.ticker import MaxNLocator

        for axis in (ax3.xaxis, ax3.yaxis, ax3.zaxis):
            axis.set_major_locator(MaxNLocator(3))
        for ax, (a, b) in ((top, ("x", "y")), (side, ("x", "z"))):
            ax.set_aspect("equal", adjustable="datalim")
            ax.set_xlabel(f"{a} (mm)")
            ax.set_ylabel(f"{b} (mm)")
            ax.grid(True, alpha=0.3)
        top.set_title("top view")
        side.set_title("side view")
        handles, labels = top.get_legend_handles_labels()
        fig.legend(
            handles,
            labels,
            loc="lower center",
            ncol=min(len(labels), 6),
            fontsize=8,
            markerscale=4,
            title="face of the input box",
            title_fontsize=8,
        )
        ranges = []
        if len(self.bounds):
            lo, hi = self.bounds[0] / 1e3
            ranges.append(f"{lo:g}-{hi:g} kPa")
        if len(self.tension_bounds):
            lo, hi = self.tension_bounds[0]
            ranges.append(f"{lo:g}-{hi:g} N")
        fig.suptitle(
            title
            or f"{self.design.name}: tip workspace, {', '.join(ranges)}, "
            f"{self.samples} samples per free input and face"
        )
        if path is not None:
            from ..io import atomic_path

            with atomic_path(path) as tmp:
                fig.savefig(tmp, dpi=130, format=path.suffix[1:])
        return fig


def workspace(
    design: DesignLike,
    *,
    pressure_bounds: ArrayLike | str | None = None,
    tension_bounds: ArrayLike | str | None = None,
    samples: int = 21,
    tip_force: ArrayLike | None = None,
    tip_moment: ArrayLike | None = None,
    threads: int = 0,
    options: SolverOptions | None = None,
) -> Workspace:
    """Sample the boundary of the tip workspace of ``design`` under ``pressure_bounds`` and,
    for a design with tendons, ``tension_bounds`` (N, lo >= 0; default: the design's
    operating range): ``samples`` values per free input on each face of the input box,
    solved in parallel by the Rust batch on ``threads`` cores (0 = all). Failed solves are
    kept with ``converged=False``. With an obstacle's friction > 0 every sample is its own
    load path from the unloaded rod (``options.friction_steps`` increments, as
    :func:`~softrod.solve_statics_batch` solves it): the workspace reached by loading from
    rest."""
    import time

    from ..statics import solve_statics_batch

    design = load_design(design)
    require_free_tip(design, "workspace")
    n_p = design.n_channels
    if n_p == 0 and design.n_tendons == 0:
        raise design_error(
            "design", design.name, "has neither pressure channels nor tendons", InputError
        )
    p_bounds = _bounds(design, pressure_bounds)
    t_bounds = _tension_bounds(design, tension_bounds)
    bounds = np.vstack([p_bounds, t_bounds])  # every input: pressures, then tensions
    nc = len(bounds)
    samples = integer(samples, "samples", minimum=2, maximum=10_000)
    count = 2 * nc * samples ** (nc - 1) if nc > 1 else samples
    if count > MAX_WORKSPACE_SOLVES:
        raise design_error(
            "samples",
            samples,
            f"gives {count} solves for {nc} inputs (2 c samples^(c-1)); the limit is "
            f"{MAX_WORKSPACE_SOLVES}: lower samples",
            InputError,
        )
    axes = [np.linspace(lo, hi, samples) for lo, hi in bounds]
    rows, face_of, grid_of, faces = [], [], [], []
    if nc == 1:
        # One channel: the workspace is the curve of the whole interval.
        faces.append((0, "all"))
        rows.append(axes[0][:, None])
        face_of.append(np.zeros(samples, dtype=int))
        grid_of.append(np.arange(samples)[:, None])
    else:
        for c, side in itertools.product(range(nc), ("lo", "hi")):
            free = [k for k in range(nc) if k != c]
            idx = _serpentine(samples, nc - 1)
            p = np.empty((len(idx), nc))
            p[:, c] = bounds[c, 0 if side == "lo" else 1]
            for j, k in enumerate(free):
                p[:, k] = axes[k][idx[:, j]]
            faces.append((c, side))
            rows.append(p)
            face_of.append(np.full(len(idx), len(faces) - 1))
            grid_of.append(idx)
    inputs = np.vstack(rows)
    pressures, tensions = inputs[:, :n_p], inputs[:, n_p:]
    t0 = time.perf_counter()
    batch = solve_statics_batch(
        design,
        pressures,
        tip_force=tip_force,
        tip_moment=tip_moment,
        threads=threads,
        options=options,
        tensions=tensions if design.n_tendons else None,
    )
    wall = time.perf_counter() - t0
    return Workspace(
        design=design,
        bounds=p_bounds,
        tension_bounds=t_bounds,
        tensions=tensions,
        samples=samples,
        faces=faces,
        pressures=pressures,
        tip_position=np.asarray(batch.tip_position),
        converged=np.asarray(batch.converged, dtype=bool),
        face=np.concatenate(face_of),
        grid=np.vstack(grid_of),
        wall_time_s=wall,
    )
