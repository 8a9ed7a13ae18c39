"""Mode shapes of a linearised rod (:meth:`softrod.LinearSystem.plot_modes`): the
equilibrium's centreline and each mode's displaced nodes in a front (x-z) and a side (y-z)
view."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np

from .. import _validate as V

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from .linear import LinearSystem

_VIEWS = (("front view (x-z)", 0, 2), ("side view (y-z)", 1, 2))
#: Each mode is drawn with its largest node displacement at this fraction of the rod's
#: length: visible, and small enough that the picture stays a small motion about the shape.
AMPLITUDE = 0.15
#: A mode whose nodes move less than this fraction of the rod's length per radian of its
#: largest rotation is a twist: its translation is not drawn (scaling it up would draw noise).
TWIST = 1e-3


def plot_modes(
    system: LinearSystem,
    count: int = 3,
    path: str | os.PathLike | None = None,
    *,
    title: str | None = None,
) -> Figure:
    """The ``count`` lowest mode shapes of ``system`` (see the module docs): each mode's
    node displacements scaled so the largest is 15 % of the rod's length, joined from the
    base (and to a clamped tip), labelled with its frequency; a twist (nodes that hardly
    translate) is marked in its label and drawn as the shape. Written to ``path`` when given
    (format from the suffix, atomically). Returns the Figure (pyplot's: close it when
    done)."""
    title = V.figure_title(title)
    n = system.mass.shape[0]
    count = V.integer(count, "count", minimum=1, maximum=min(n, 8), hint=" (8 at most: legible)")
    import matplotlib.pyplot as plt

    from ..plotting import check_figure_path, save_figure

    if path is not None:
        check_figure_path(path)
    modes = system.modes(count)
    eq = system.equilibrium
    length = float(system.design.length)
    nodes_xyz = np.array([np.interp(system.nodes, eq.s, eq.position[:, k]) for k in range(3)]).T
    base, tip = eq.position[0], eq.position[-1]
    fig, axes = plt.subplots(1, 2, figsize=(9.5, 5.4), sharey=True)
    colours = plt.cm.viridis(np.linspace(0.0, 0.85, max(count, 2)))
    for ax, (_, a, b) in zip(axes, _VIEWS, strict=True):
        ax.plot(
            eq.position[:, a] * 1e3,
            eq.position[:, b] * 1e3,
            color="0.6",
            lw=3,
            label="equilibrium" if ax is axes[0] else None,
        )
    for k in range(count):
        shape = modes.shapes[k]
        moved = np.abs(shape[:, :3]).max()
        twist = moved < TWIST * length * np.abs(shape[:, 3:]).max()
        scale = 0.0 if twist else AMPLITUDE * length / moved
        points = nodes_xyz + scale * shape[:, :3]
        chain = [base[None, :], points]
        if system.tip_constraint == "clamped":
            chain.append(tip[None, :])
        line = np.vstack(chain) * 1e3
        label = f"mode {k + 1}: {modes.frequency[k]:.3g} Hz" + (" (twist)" if twist else "")
        for ax, (_, a, b) in zip(axes, _VIEWS, strict=True):
            ax.plot(
                line[:, a],
                line[:, b],
                "o-",
                color=colours[k],
                lw=1.5,
                ms=4,
                label=label if ax is axes[0] else None,
            )
    for ax, (name, a, b) in zip(axes, _VIEWS, strict=True):
        ax.plot(base[a] * 1e3, base[b] * 1e3, "s", color="black", ms=7)
        if system.tip_constraint != "free":
            ax.plot(tip[a] * 1e3, tip[b] * 1e3, "^", color="black", ms=8)
        ax.set_title(name)
        ax.set_xlabel(f"{'xyz'[a]} (mm)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("z (mm)")
    # The legend below the views: long labels never cover the rod.
    handles, _ = axes[0].get_legend_handles_labels()
    fig.legend(handles=handles, loc="lower center", ncol=min(count + 1, 4), fontsize=8)
    rows = -(-(count + 1) // 4)
    fig.suptitle(
        title
        or f"{system.design.name}: mode shapes (tip {system.tip_constraint}; largest node "
        f"displacement drawn at {AMPLITUDE:.0%} of the length)"
    )
    fig.tight_layout(rect=(0.0, 0.05 * rows + 0.02, 1.0, 1.0))
    if path is not None:
        save_figure(fig, path)
    return fig
