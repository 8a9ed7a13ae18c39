"""``softrod simulate``: a design's motion under a pressure schedule, with a progress bar
that shows the real-time factor; the trajectory, an animation and a tip plot are written
all or none (docs/dynamics.md)."""

from __future__ import annotations

import math
import time
from pathlib import Path

import click
import numpy as np
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn
from rich.text import Text

from ..catalog import load_design
from ..dynamics import PressureSchedule, simulate
from ..errors import InputError, design_error
from ._common import _check_output, _handle_errors, _quantity, _staged, _stdout

TRAJECTORY_SUFFIXES = (".parquet", ".npz")
ANIMATION_SUFFIXES = (".gif", ".mp4")
PLOT_SUFFIXES = (".png", ".pdf", ".svg")
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
    type=click.Choice(["static", "straight"]),
    default="static",
    show_default=True,
    help="Start at rest in equilibrium under the first pressures, or straight.",
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
@click.option("--fps", default=20, show_default=True, type=click.IntRange(min=1, max=100))
@click.option(
    "--speed",
    default=1.0,
    show_default=True,
    type=click.FloatRange(min=0.01, max=1000),
    help="Animation playback speed (2 = twice as fast as real time).",
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
    out,
    animation,
    fps,
    speed,
    plot_path,
):
    """Simulate DESIGN's motion under commanded chamber pressures over time.

    The rod is paper 000's viscoelastic Cosserat rod (damping time from the design's
    [dynamics] table), integrated with BDF-alpha in time and shooting in space; with
    --model pcc, paper 003's piecewise-constant-curvature model (implicit midpoint rule).
    Progress shows the simulated time and the real-time factor on stderr.
    """
    d = load_design(design)
    if (input_path is None) == (pulses is None):
        raise design_error(
            "--input", input_path, "give exactly one of --input FILE or --pulses", InputError
        )
    outputs = [_check_output(out, "--out", TRAJECTORY_SUFFIXES, "trajectory")]
    if animation is not None:
        outputs.append(
            _check_output(animation, "--animate", ANIMATION_SUFFIXES, "animation")
        )
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
    shapes = 1.0 / fps if animation is not None else None
    console = _stdout()
    if model == "pcc":
        what = "PCC model (paper 003)"
    else:
        what = f"Cosserat rod, damping time {d.spec['dynamics']['damping_time']:g} s"
    console.print(
        Text(
            f"{d.name}: {duration:g} s at dt = {step * 1e3:g} ms "
            f"({math.ceil(duration / step):,} steps), {what}"
        )
    )
    err = Console(stderr=True)
    with Progress(
        TextColumn("[bold]simulate"),
        BarColumn(bar_width=24),
        TextColumn("{task.fields[t]} / {task.fields[total_s]} s"),
        TextColumn("{task.fields[rtf]}x real time"),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        console=err,
        transient=True,
    ) as bar:
        task = bar.add_task(
            "simulate", total=duration, t="0", total_s=f"{duration:g}", rtf="--"
        )

        def report(done: float, total: float, wall: float) -> None:
            rtf = f"{done / wall:,.0f}" if wall > 0 else "--"
            bar.update(task, completed=done, t=f"{done:.2f}", rtf=rtf)

        t0 = time.perf_counter()
        traj = simulate(
            d,
            schedule,
            duration,
            dt=step,
            save_every=save_every,
            shapes=shapes,
            initial=initial,
            model=model,
            progress=report,
        )
        wall = time.perf_counter() - t0
    with _staged(outputs) as staged:
        traj.save(staged[0])
        k = 1
        if animation is not None:
            traj.animate(staged[k], fps=fps, speed=speed)
            k += 1
        if plot_path is not None:
            traj.plot_tip(staged[k])
    tip = traj.tip_position
    reach = np.linalg.norm(tip - tip[0], axis=1).max()
    meta = traj.metadata
    console.print(
        f"{meta['steps']:,} steps in {wall:.2f} s: {meta['real_time_factor']:,.0f}x real "
        f"time on one core ({meta['newton_iterations']:,} Newton iterations, "
        f"{meta['jacobians']:,} exact Jacobians)"
    )
    console.print(f"largest tip excursion from the start: {reach * 1e3:.1f} mm")
    for p in outputs:
        console.print(Text(f"wrote {p}"), soft_wrap=True)
