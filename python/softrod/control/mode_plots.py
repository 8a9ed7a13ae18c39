"""Mode shapes of a linearised rod or system of rods (:meth:`softrod.LinearSystem.plot_modes`,
:meth:`softrod.SystemLinearSystem.plot_modes`): the equilibrium's centrelines and each
mode's displaced nodes in a front (x-z) and a side (y-z) view."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from .. import _validate as V
from ..system_plots import VIEWS, style_views

if TYPE_CHECKING:
    from matplotlib.figure import Figure


# The figures read a linearisation by its fields: softrod.control.linear calls them from its
# plot_modes methods, so this module does not import it (no cycle).
class Linearised(Protocol):
    """What the figures read of a LinearSystem or SystemLinearSystem."""

    mass: np.ndarray
    nodes: Any
    equilibrium: Any

    def modes(self, count: int | None = None) -> Any: ...


#: Each mode is drawn with its largest node displacement at this fraction of the rod's
#: length: visible, and small enough that the picture stays a small motion about the shape.
AMPLITUDE = 0.15
_SCALE_NOTE = f"largest node displacement drawn at {AMPLITUDE:.0%} of the length"
#: A mode whose nodes move less than this fraction of the rod's length per radian of its
#: largest rotation is a twist: its translation is not drawn (scaling it up would draw noise).
TWIST = 1e-3


def plot_modes(
    system: Linearised,
    count: int = 3,
    path: str | os.PathLike | None = None,
    *,
    title: str | None = None,
) -> Figure:
    """The ``count`` lowest mode shapes of a rod's ``system`` (see the module docs): each
    mode's node displacements scaled so the largest is 15 % of the rod's length, joined
    from the base (and to a held tip), labelled with its frequency; a twist (nodes that
    hardly translate) is marked in its label and drawn as the shape. Written to ``path``
    when given (format from the suffix, atomically). Returns the Figure (pyplot's: close
    it when done)."""
    eq = system.equilibrium
    nodes = _along(eq, system.nodes)
    base, tip = eq.position[0], eq.position[-1]

    def chains(shape: np.ndarray, scale: float) -> list[np.ndarray]:
        chain = [base[None, :], nodes + scale * shape[:, :3]]
        if system.tip_constraint == "clamped":
            chain.append(tip[None, :])
        return [np.vstack(chain)]

    held = [tip] if system.tip_constraint != "free" else []
    return _draw(
        system,
        count,
        path,
        V.figure_title(title),
        f"{system.design.name}: mode shapes (tip {system.tip_constraint}; {_SCALE_NOTE})",
        rest=[eq.position],
        bases=[base],
        held=held,
        chains=chains,
        length=float(system.design.length),
    )


def plot_system_modes(
    system: Linearised,
    count: int = 3,
    path: str | os.PathLike | None = None,
    *,
    title: str | None = None,
) -> Figure:
    """The ``count`` lowest mode shapes of a system of rods (see the module docs): every
    rod from its base through its nodes to its tip, which moves with the platform (dp +
    psi x (r_tip - p)), and the platform's outline through the tips; the largest
    displacement drawn at 15 % of the rods' mean length. As :func:`plot_modes`
    otherwise."""
    eq = system.equilibrium
    rods = eq.rods
    nodes = [_along(r, v) for r, v in zip(rods, system.nodes, strict=True)]
    starts = np.cumsum([0] + [len(v) for v in system.nodes])
    p = np.asarray(eq.platform_position)
    tips = np.array([r.position[-1] for r in rods])

    def chains(shape: np.ndarray, scale: float) -> list[np.ndarray]:
        dp, psi = shape[-1, :3], shape[-1, 3:]
        moved_tips = tips + scale * (dp + np.cross(psi, tips - p))
        out = [
            np.vstack([r.position[0][None, :], nd + scale * shape[a:b, :3], t[None, :]])
            for r, nd, a, b, t in zip(rods, nodes, starts[:-1], starts[1:], moved_tips, strict=True)
        ]
        out.append(moved_tips if len(tips) < 3 else np.vstack([moved_tips, moved_tips[:1]]))
        return out

    def translation(shape: np.ndarray) -> float:
        dp, psi = shape[-1, :3], shape[-1, 3:]
        at_tips = dp + np.cross(psi, tips - p)
        return max(np.abs(shape[:-1, :3]).max(), np.abs(at_tips).max())

    return _draw(
        system,
        count,
        path,
        V.figure_title(title),
        f"{system.system.name}: mode shapes ({_SCALE_NOTE})",
        rest=[r.position for r in rods],
        bases=[r.position[0] for r in rods],
        held=[],
        chains=chains,
        length=float(np.mean([r.design.length for r in rods])),
        translation=translation,
    )


def _along(solution, s: np.ndarray) -> np.ndarray:
    """The equilibrium's centreline at arc lengths ``s`` (linear between its nodes)."""
    return np.array([np.interp(s, solution.s, solution.position[:, k]) for k in range(3)]).T


def _draw(
    system,
    count,
    path,
    title: str | None,
    default_title: str,
    *,
    rest: list[np.ndarray],
    bases: list[np.ndarray],
    held: list[np.ndarray],
    chains,
    length: float,
    translation=None,
) -> Figure:
    """The figure: the equilibrium's ``rest`` lines in grey, ``chains(shape, scale)`` of
    each mode in its colour, ``bases`` as squares and ``held`` tips as triangles; the
    suptitle ``title``, or ``default_title``."""
    n = system.mass.shape[0]
    count = V.integer(count, "count", minimum=1, maximum=min(n, 8), hint=" (8 at most: legible)")
    import matplotlib.pyplot as plt

    from ..plotting import check_figure_path, save_figure

    if path is not None:
        check_figure_path(path)
    modes = system.modes(count)
    fig, axes = plt.subplots(1, 2, figsize=(9.5, 5.4), sharey=True)
    colours = plt.cm.viridis(np.linspace(0.0, 0.85, max(count, 2)))
    for ax, (_, a, b) in zip(axes, VIEWS, strict=True):
        for j, line in enumerate(rest):
            ax.plot(
                line[:, a] * 1e3,
                line[:, b] * 1e3,
                color="0.6",
                lw=3,
                label="equilibrium" if ax is axes[0] and j == 0 else None,
            )
    for k in range(count):
        shape = modes.shapes[k]
        moved = np.abs(shape[:, :3]).max() if translation is None else translation(shape)
        twist = moved < TWIST * length * np.abs(shape[:, 3:]).max()
        scale = 0.0 if twist else AMPLITUDE * length / moved
        label = f"mode {k + 1}: {modes.frequency[k]:.3g} Hz" + (" (twist)" if twist else "")
        for ax, (_, a, b) in zip(axes, VIEWS, strict=True):
            for j, line in enumerate(chains(shape, scale)):
                ax.plot(
                    line[:, a] * 1e3,
                    line[:, b] * 1e3,
                    "o-",
                    color=colours[k],
                    lw=1.5,
                    ms=4,
                    label=label if ax is axes[0] and j == 0 else None,
                )
    for ax, (_, a, b) in zip(axes, VIEWS, strict=True):
        for point in bases:
            ax.plot(point[a] * 1e3, point[b] * 1e3, "s", color="black", ms=7)
        for point in held:
            ax.plot(point[a] * 1e3, point[b] * 1e3, "^", color="black", ms=8)
    style_views(axes)
    # The legend below the views: long labels never cover the rod.
    handles, _ = axes[0].get_legend_handles_labels()
    fig.legend(handles=handles, loc="lower center", ncol=min(count + 1, 4), fontsize=8)
    rows = -(-(count + 1) // 4)
    fig.suptitle(title or default_title)
    fig.tight_layout(rect=(0.0, 0.05 * rows + 0.02, 1.0, 1.0))
    if path is not None:
        save_figure(fig, path)
    return fig
