"""``softrod simulate``: a design's motion under a pressure schedule, with a progress bar
that shows the real-time factor; the trajectory, an animation and a tip plot are written
all or none (docs/dynamics.md)."""

from __future__ import annotations

import math
import time
from pathlib import Path

import click

from ..errors import InputError, design_error
from ._common import (
    PLOT_SUFFIXES,
    _alpha_option,
    _check_output,
    _energy_tol_option,
    _handle_errors,
    _parse_quantities,
    _quantity,
    _quiet,
    _say,
    _staged,
    _stdout,
)

TRAJECTORY_SUFFIXES = (".parquet", ".npz")
ANIMATION_SUFFIXES = (".gif", ".mp4")
BUILTIN_PULSES = {"paper000": "paper 000 Fig. 3 style square pulses (116 s, 3 channels)"}


def _seconds(text: str, option: str, *, positive: bool = True) -> float:
    x = _quantity(text, "time", option)
    if positive and not x > 0:
        raise design_error(option, text, "must be > 0 s", InputError)
    return x


@click.command("simulate")
@click.argument("design")
@click.option(
    "--input",
    "input_path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Commanded pressures over time: CSV or Parquet with time_s and p0_kPa, p1_kPa, "
    "... columns (units in the names; docs/dynamics.md).",
)
@click.option(
    "--pulses",
    type=click.Choice(sorted(BUILTIN_PULSES)),
    help="A built-in schedule instead of --input: paper000 = square pulses of 0.9-3.6 "
    "bar on each PAM in turn, 116 s (for a 3-channel design).",
)
@click.option(
    "--kind",
    type=click.Choice(["linear", "step"]),
    default=None,
    help="How --input's rows are joined (default: as recorded in the file, else linear).",
)
@click.option(
    "--t-end",
    "t_end",
    help="Simulated time with its unit, e.g. '10 s' (default: the schedule's last time).",
)
@click.option("--dt", default="2 ms", show_default=True, help="Time step.")
@click.option(
    "--save-every",
    default=5,
    show_default=True,
    type=click.IntRange(min=1),
    help="Keep every n-th step in the trajectory.",
)
@click.option(
    "--initial",
    type=click.Choice(["static", "straight", "reference"]),
    default="static",
    show_default=True,
    help="Start at rest in equilibrium under the first pressures, straight, or in the "
    "reference shape (the last two released at t = 0 with no internal force).",
)
@click.option(
    "--model",
    type=click.Choice(["cosserat", "pcc"]),
    default="cosserat",
    show_default=True,
    help="cosserat: paper 000's viscoelastic rod; pcc: paper 003's constant-curvature "
    "Lagrangian model with the design's [pcc] parameters (docs/pcc.md).",
)
@click.option(
    "--scheme",
    type=click.Choice(["bdf-alpha", "midpoint"]),
    default="bdf-alpha",
    show_default=True,
    help="Time integrator of the rod: bdf-alpha (numerical damping of unresolved modes, "
    "--alpha) or midpoint (conserves the energy of undamped runs; docs/dynamics.md).",
)
@_alpha_option
@click.option(
    "--error-tol",
    "error_tol",
    default=None,
    help="Adaptive time steps: the largest local error of the node positions per step, "
    "with its unit, e.g. '0.1 mm' (dt is then the output interval and the largest step).",
)
@_energy_tol_option
@click.option(
    "--tension",
    metavar="T1,T2,...",
    help="Tendon tension per tendon channel (>= 0), comma-separated, e.g. 2N,0 (units "
    "required, zero needs none), held over the run; the static start balances it. "
    "Default: every tendon slack.",
)
@click.option(
    "--marker",
    "marker_items",
    multiple=True,
    metavar="S[,D1,D2[,D3]]",
    help="A motion-capture marker to record at every sample: its arc length from the base "
    "and, optionally, its offset in the cross-section frame, with units, e.g. '100 mm' or "
    "'220 mm,5 mm,0' (a unit on the last value alone applies to all). Repeat for several; "
    "the trajectory gets marker0_x_m, ... columns.",
)
@click.option(
    "--out",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="Trajectory file, .parquet or .npz.",
)
@click.option(
    "--animate",
    "animation",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Also write a 3-D animation of the shape, .gif (or .mp4 with ffmpeg).",
)
@click.option(
    "--fps",
    default=20,
    show_default=True,
    type=click.IntRange(min=1, max=100),
    help="Animation frames per second (lowered when the clip would need more than "
    "--max-frames frames).",
)
@click.option(
    "--speed",
    default=None,
    type=click.FloatRange(min=0.01, max=1000),
    help="Animation playback speed (2 = twice as fast as real time). Default: real time "
    "for runs up to 15 s, faster for longer ones, so the clip lasts about 15 s.",
)
@click.option(
    "--max-frames",
    default=300,
    show_default=True,
    type=click.IntRange(min=2),
    help="Frame budget of the animation.",
)
@click.option(
    "--plot",
    "plot_path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Also write a plot of the tip position and pressures over time (.png/.pdf/.svg).",
)
@_handle_errors
def simulate_cmd(
    design,
    input_path,
    pulses,
    kind,
    t_end,
    dt,
    save_every,
    initial,
    model,
    scheme,
    alpha,
    error_tol,
    energy_tol,
    tension,
    marker_items,
    out,
    animation,
    fps,
    speed,
    max_frames,
    plot_path,
):
    """Simulate DESIGN's motion under commanded chamber pressures over time.

    The rod is paper 000's viscoelastic Cosserat rod (damping time from the design's
    [dynamics] table), integrated with BDF-alpha or the implicit midpoint rule in time and
    Gauss collocation in space; with --model pcc, paper 003's piecewise-constant-curvature
    model (implicit midpoint rule).
    Progress shows the simulated time and the real-time factor on stderr.
    """
    import numpy as np

    from ..catalog import load_design
    from ..dynamics import PressureSchedule, simulate
    from ..dynamics.trajectory import animation_plan
    from ..progress import reporter

    d = load_design(design)
    if (input_path is None) == (pulses is None):
        raise design_error(
            "--input", input_path, "give exactly one of --input FILE or --pulses", InputError
        )
    outputs = [_check_output(out, "--out", TRAJECTORY_SUFFIXES, "trajectory")]
    if animation is not None:
        outputs.append(_check_output(animation, "--animate", ANIMATION_SUFFIXES, "animation"))
    if plot_path is not None:
        outputs.append(_check_output(plot_path, "--plot", PLOT_SUFFIXES, "plot"))
    if len({p.resolve() for p in outputs}) != len(outputs):
        raise design_error("--out", str(out), "the output files must differ", InputError)
    if input_path is not None:
        schedule = PressureSchedule.from_file(input_path, kind=kind)
    else:
        schedule = PressureSchedule.paper000_square_pulses(n_channels=d.n_channels)
    schedule.check_channels(d.n_channels)
    step = _seconds(dt, "--dt")
    if t_end is None:
        if not schedule.t_end:
            raise design_error(
                "--t-end", None, "the schedule has no end time; give --t-end", InputError
            )
        duration = float(schedule.t_end)
    else:
        duration = _seconds(t_end, "--t-end")
    plan = None
    shapes = None
    if animation is not None:
        # Store just the shapes the clip shows: one per frame.
        plan = animation_plan(duration, fps=fps, speed=speed, max_frames=max_frames)
        shapes = plan.frame_interval_s
    console = _stdout()
    rod_options = {}
    if model == "pcc":
        what = "PCC model (paper 003)"
        defaults = {
            "--scheme": (scheme, "bdf-alpha"),
            "--alpha": (alpha, None),
            "--error-tol": (error_tol, None),
            "--energy-tol": (energy_tol, 0.02),
            "--tension": (tension, None),
            "--marker": (marker_items or None, None),
        }
        for option, (value, default) in defaults.items():
            if value != default:
                raise design_error(
                    option, value, "is a setting of the rod model (--model cosserat)", InputError
                )
    else:
        if scheme == "midpoint" and alpha is not None:
            raise design_error(
                "--alpha",
                alpha,
                "is BDF-alpha's parameter; --scheme midpoint has none: leave --alpha out",
                InputError,
            )
        what = f"Cosserat rod, damping time {d.spec['dynamics']['damping_time']:g} s"
        tol_m = None if error_tol is None else _quantity(error_tol, "length", "--error-tol")
        from .statics import _parse_tensions

        rod_options = {
            "scheme": scheme,
            "alpha": alpha,
            "error_tol": tol_m,
            "energy_tol": energy_tol,
            "tensions": _parse_tensions(tension, d),
            "markers": _parse_markers(marker_items, d.length),
        }
    _say(
        f"{d.name}: {duration:g} s at dt = {step * 1e3:g} ms "
        f"({math.ceil(duration / step):,} steps), {what}"
    )
    bar = not _quiet() and _stderr_is_terminal()  # progress bars: on a terminal only

    def simulated(done: float, total: float, wall: float):
        rtf = f"{done / wall:,.0f}" if wall > 0 else "--"
        return done, f"{done:.2f} / {total:g} s, {rtf}x real time"

    t0 = time.perf_counter()
    with reporter(bar, "simulate", duration, simulated) as report:
        traj = simulate(
            d,
            schedule,
            duration,
            dt=step,
            save_every=save_every,
            shapes=shapes,
            initial=initial,
            model=model,
            progress=report if report is not None else False,
            **rod_options,
        )
    wall = time.perf_counter() - t0
    meta = traj.metadata
    console.print(
        f"{meta['steps']:,} steps in {wall:.2f} s: {meta['real_time_factor']:,.0f}x real "
        f"time on one core ({meta['newton_iterations']:,} Newton iterations, "
        f"{meta['jacobians']:,} exact Jacobians)"
    )
    with _staged(outputs) as staged:
        traj.save(staged[0])
        k = 1
        if animation is not None:
            t1 = time.perf_counter()
            traj.animate(
                staged[k],
                fps=plan.fps,
                speed=plan.speed,
                max_frames=max_frames,
                progress=bar,
            )
            console.print(
                f"animation: {plan.n_frames} frames at {plan.fps:.3g} fps, "
                f"{plan.speed:.3g}x real time, a {plan.clip_s:.1f} s clip, rendered in "
                f"{time.perf_counter() - t1:.1f} s"
            )
            k += 1
        if plot_path is not None:
            traj.plot_tip(staged[k])
    tip = traj.tip_position
    reach = np.linalg.norm(tip - tip[0], axis=1).max()
    console.print(f"largest tip excursion from the start: {reach * 1e3:.1f} mm")
    for p in outputs:
        _say(f"wrote {p}")


def _parse_markers(items: tuple[str, ...], length: float) -> list | None:
    """--marker S[,D1,D2[,D3]] (repeated): the markers as simulate takes them (SI), each
    checked against the rod (s in [0, L]) with errors naming --marker[k]."""
    from ..datasets import parse_marker_sites

    if not items:
        return None
    markers = []
    for k, text in enumerate(items):
        parts = text.split(",")
        if len(parts) not in (1, 3, 4):
            raise design_error(
                f"--marker[{k}]",
                text,
                "give S, S,D1,D2 or S,D1,D2,D3 (arc length and offset in the cross-section "
                "frame, with units), e.g. '100 mm' or '220 mm,5 mm,0'",
                InputError,
            )
        names = [f"--marker[{k}].s"] + [f"--marker[{k}].offset[{i}]" for i in range(3)]
        values = _parse_quantities(parts, "length", names[: len(parts)])
        markers.append((values[0], values[1:]) if len(values) > 1 else values[0])
    parse_marker_sites(markers, length, field="--marker")  # s in [0, L], before any work
    return markers


def _stderr_is_terminal() -> bool:
    from rich.console import Console

    return Console(stderr=True).is_terminal
