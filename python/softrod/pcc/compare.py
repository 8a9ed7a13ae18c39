"""Side by side: the PCC model and the Cosserat rod on the same design and inputs.

- :func:`compare_pcc`: static tip positions while chambers ramp up (tip error vs pressure);
- :func:`compare_pcc_dynamics`: tip trajectories under one pressure schedule (tip error vs
  time);

each in three cases: weightless and unloaded, with gravity, and with gravity and a tip load.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from .. import _validate as V
from ..catalog import load_design
from ..errors import InputError, design_error
from ..statics import solve_statics

__all__ = [
    "compare_pcc",
    "compare_pcc_dynamics",
    "plot_pcc_comparison",
    "plot_pcc_dynamics_comparison",
]

CASES = ("weightless", "gravity", "gravity + tip load")


def compare_pcc(
    design,
    channels: Sequence[int],
    p_max: float,
    *,
    steps: int = 11,
    tip_force: Sequence[float] = (0.0, 0.0, -0.0981),
    progress: Callable[[int], None] | None = None,
):
    """Tip positions of both models while ``channels`` (indices) ramp together from 0 to
    ``p_max`` (Pa) in ``steps`` levels, in three cases: weightless and unloaded (gravity
    off, no tip body or tip load: both models must give the same arc when the rod's law is
    linear), with gravity, and with gravity plus ``tip_force`` (N, world frame; default a
    10 g weight). ``progress(n)`` is called after every n solves.

    Returns a pandas DataFrame in the dataset schema (docs/datasets.md), two rows per case
    and level (one per model): ``experiment`` (the case), ``p0_kPa`` ... (every channel),
    ``tip_x_mm`` ... and ``tip_q*`` of that model's tip, then the result columns ``model``
    ("pcc" or "cosserat"), ``level_kPa`` (the ramp level), ``error_mm`` (distance between the
    two models' tips) and ``rel_error`` (error / tip travel of the rod). The metadata block
    names the design, the channels and the cases; ``load_dataset`` reads it back.
    """
    from ..schema import Extra, provenance, schema_frame

    d = load_design(design)
    chans = [int(c) for c in channels]
    if not chans or any(c < 0 or c >= d.n_channels for c in chans):
        raise design_error(
            "channels", list(channels), f"must be channel indices 0..{d.n_channels - 1}", InputError
        )
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 2:
        raise design_error("steps", steps, "must be an integer >= 2", InputError)
    if not (np.isfinite(p_max) and p_max > 0):
        raise design_error("p_max", p_max, "must be a pressure > 0 Pa", InputError)
    levels = np.linspace(0.0, p_max, steps)
    zero = [0.0, 0.0, 0.0]
    setups = _cases(d, tip_force)
    rows = []
    for case, (des, force) in setups.items():
        prev = {"pcc": None, "cosserat": None}
        start = None
        for p in levels:
            pr = np.zeros(d.n_channels)
            pr[chans] = p
            sols = {}
            for model in ("pcc", "cosserat"):
                sol = solve_statics(
                    des, pr, model=model, tip_force=force, tip_moment=zero, initial=prev[model]
                )
                prev[model] = sol
                sols[model] = sol
            if start is None:
                start = sols["cosserat"].tip_position
            err = float(np.linalg.norm(sols["pcc"].tip_position - sols["cosserat"].tip_position))
            travel = float(np.linalg.norm(sols["cosserat"].tip_position - start))
            rel = err / travel if travel > 0 else np.nan
            for model in ("pcc", "cosserat"):
                rows.append((case, model, p, pr, sols[model], err, rel))
            if progress is not None:
                progress(2)
    frame = schema_frame(
        pressures=np.array([r[3] for r in rows]),
        tip_position=np.array([r[4].tip_position for r in rows]),
        tip_rotation=np.array([r[4].tip_rotation for r in rows]),
        experiment=np.array([r[0] for r in rows]),
        extras=[
            Extra("model", np.array([r[1] for r in rows]), "pcc or cosserat (the rod)"),
            Extra("level", np.array([r[2] for r in rows]), "ramp level", "pressure"),
            Extra("error", np.array([r[5] for r in rows]), "|tip_PCC - tip_rod|", "length"),
            Extra("rel_error", np.array([r[6] for r in rows]), "error / tip travel of the rod"),
        ],
        metadata=provenance(
            "softrod.pcc.compare_pcc",
            d,
            channels=chans,
            p_max_kPa=p_max / 1e3,
            steps=steps,
            tip_force_N=[float(f) for f in tip_force],
            cases=list(setups),
        ),
    )
    return frame


def _cases(d, tip_force) -> dict:
    """The three cases as (design, tip force N): weightless (gravity off, no tip body),
    with gravity, with gravity and ``tip_force``."""
    force = [float(f) for f in tip_force]
    if len(force) != 3 or not np.all(np.isfinite(force)):
        raise design_error("tip_force", list(tip_force), "must be 3 finite forces (N)", InputError)
    weightless = d.replace({"mounting.gravity": "0 m/s^2", "tip.mass": "0 kg"})
    zero = [0.0, 0.0, 0.0]
    return {CASES[0]: (weightless, zero), CASES[1]: (d, zero), CASES[2]: (d, force)}


def compare_pcc_dynamics(
    design,
    schedule,
    t_end,
    *,
    dt=2e-3,
    save_every: int = 5,
    tip_force: Sequence[float] = (0.0, 0.0, -0.0981),
    progress: Callable[[int], None] | None = None,
):
    """Tip trajectories of both models under the same pressure ``schedule`` (anything
    :func:`softrod.simulate` takes) for ``t_end`` at time step ``dt``, in the three cases of
    :func:`compare_pcc` (weightless means gravity off and no tip body; the arm keeps its
    mass). Both start at rest in equilibrium under the first pressures and see the same
    supplied pressures; each model uses its own damping (the rod: the design's
    ``[dynamics]`` Kelvin-Voigt time; PCC: ``[pcc]`` b_L, b_theta). ``progress(1)`` is
    called after every run (6 runs).

    Returns a pandas DataFrame in the dataset schema, one row per saved step, case and
    model: ``experiment`` (the case), ``time_s``, ``p0_kPa`` ... (the supplied chamber
    pressures), ``tip_x_mm`` ..., ``tip_q*``, then ``model`` ("pcc" or "cosserat") and
    ``error_mm`` (distance between the two models' tips at that time).
    """
    import pandas as pd

    from ..dynamics import simulate
    from ..schema import Extra, provenance, schema_frame

    d = load_design(design)
    frames = []
    for case, (des, force) in _cases(d, tip_force).items():
        if any(force):
            des = des.replace({"tip.force": [f"{f!r} N" for f in force]})
        runs = {}
        for model in ("pcc", "cosserat"):
            runs[model] = simulate(
                des, schedule, t_end, dt=dt, save_every=save_every, model=model, progress=False
            )
            if progress is not None:
                progress(1)
        error = np.linalg.norm(runs["pcc"].tip_position - runs["cosserat"].tip_position, axis=1)
        for model, tr in runs.items():
            n = len(tr)
            frames.append(
                schema_frame(
                    pressures=tr.pressure,
                    tip_position=tr.tip_position,
                    tip_rotation=tr.tip_rotation,
                    time=tr.time,
                    experiment=np.full(n, case),
                    extras=[
                        Extra("model", np.full(n, model), "pcc or cosserat (the rod)"),
                        Extra("error", error, "|tip_PCC - tip_rod| at this time", "length"),
                    ],
                    metadata=provenance(
                        "softrod.pcc.compare_pcc_dynamics",
                        d,
                        dt_s=float(runs[model].metadata.get("dt_s", dt)),
                        save_every=save_every,
                        tip_force_N=[float(f) for f in tip_force],
                    ),
                )
            )
    df = pd.concat(frames, ignore_index=True)
    df.attrs["softrod.metadata"] = frames[0].attrs["softrod.metadata"]
    return df


def _models(df, case):
    """The rows of one case: (rod rows, PCC rows), each in the table's order."""
    sub = df[df["experiment"] == case]
    return sub[sub["model"] == "cosserat"], sub[sub["model"] == "pcc"]


def plot_pcc_dynamics_comparison(df, title: str | None = None):
    """Figure: tip error vs time per case (left) and both models' lateral tip distance
    from the axis over time (right: rod solid, PCC dashed)."""
    title = V.figure_title(title)
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4.2))
    for k, case in enumerate(CASES):
        rod, pcc = _models(df, case)
        if rod.empty:
            continue
        color = f"C{k}"
        ax1.plot(rod["time_s"], rod["error_mm"], color=color, label=case)
        for sub, style in ((rod, "-"), (pcc, "--")):
            h = np.hypot(sub["tip_x_mm"], sub["tip_y_mm"])
            ax2.plot(sub["time_s"], h, style, color=color)
    ax1.set_xlabel("time (s)")
    ax1.set_ylabel("|tip_PCC - tip_rod| (mm)")
    ax1.legend(fontsize=8)
    ax1.grid(alpha=0.3)
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel("lateral tip distance from the axis (mm)")
    ax2.set_title("rod (solid), PCC (dashed)", fontsize=9)
    ax2.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def plot_pcc_comparison(df, title: str | None = None):
    """Figure: tip error vs pressure per case (left) and both models' tip paths (right)."""
    title = V.figure_title(title)
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4.2))
    for k, case in enumerate(CASES):
        rod, pcc = _models(df, case)
        if rod.empty:
            continue
        color = f"C{k}"
        ax1.plot(rod["level_kPa"], rod["error_mm"], "o-", color=color, label=case)
        # Tip paths in the plane of largest travel: horizontal distance vs height.
        for sub, style, marker in ((pcc, "--", "."), (rod, "-", "")):
            h = np.hypot(sub["tip_x_mm"], sub["tip_y_mm"])
            ax2.plot(h, sub["tip_z_mm"], style, color=color, marker=marker)
    ax1.set_xlabel("pressure (kPa)")
    ax1.set_ylabel("|tip_PCC - tip_rod| (mm)")
    ax1.legend(fontsize=8)
    ax1.grid(alpha=0.3)
    ax2.set_xlabel("horizontal tip distance (mm)")
    ax2.set_ylabel("tip height z (mm)")
    ax2.set_title("tip paths: rod (solid), PCC (dashed)", fontsize=9)
    ax2.grid(alpha=0.3)
    ax2.set_aspect("equal", adjustable="datalim")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def plot_pcc_step_response(runs, rest_length: float, title: str | None = None):
    """Figure: the PCC model's step responses, one column per run (paper 003 Figs. 8-9).

    runs: ``{label: out}`` with ``out`` from :func:`~softrod.pcc.run_pcc` (one segment).
    Top row: elongation L - ``rest_length`` (mm); bottom row: bending angle theta (deg); one
    axis per quantity, shared time axis (s).
    """
    title = V.figure_title(title)
    import matplotlib.pyplot as plt

    if not runs:
        raise design_error("runs", "{}", "give at least one {label: run_pcc output}", InputError)
    n = len(runs)
    fig, axes = plt.subplots(
        2, n, figsize=(5.0 * n, 5.4), sharex="col", squeeze=False, layout="constrained"
    )
    for k, (label, out) in enumerate(runs.items()):
        q = np.asarray(out["q"], dtype=float)
        t = np.asarray(out["time"], dtype=float)
        top, bottom = axes[0, k], axes[1, k]
        elongation_mm, theta_deg = 1e3 * (q[:, 0] - rest_length), np.degrees(q[:, 1])
        top.plot(t, elongation_mm, color="C0")
        bottom.plot(t, theta_deg, color="C1")
        # A quantity that stays at zero (no bending under equal chambers) is round-off, not a
        # curve: show at least +-1 mm or +-1 deg instead of blowing 1e-14 up to the axis.
        for ax, values in ((top, elongation_mm), (bottom, theta_deg)):
            lo, hi = float(np.min(values)), float(np.max(values))
            if hi - lo < 2.0:
                mid = 0.5 * (lo + hi)
                ax.set_ylim(mid - 1.0, mid + 1.0)
        top.set_title(str(label), fontsize="medium")
        top.set_ylabel("elongation L - L0 (mm)")
        bottom.set_ylabel("bending angle theta (deg)")
        bottom.set_xlabel("time (s)")
        for ax in (top, bottom):
            ax.grid(True, alpha=0.3)
    if title:
        fig.suptitle(title)
    return fig
