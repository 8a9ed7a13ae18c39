"""``softrod inverse``, ``softrod workspace``, ``softrod modes`` and ``softrod track``:
control tools (docs/control.md). Heavy modules are imported inside the commands so that
``softrod --help`` stays fast."""

from __future__ import annotations

import json
import math
from pathlib import Path

import click

from ._common import _check_output, _handle_errors, _parse_vector, _stdout

_BOUNDS_HELP = (
    "Pressure bounds of every channel as LO:HI with a unit, e.g. 0:70kPa (default: the "
    "design's [operating_range])."
)
_TENSION_BOUNDS_HELP = (
    "Tension bounds of every tendon as LO:HI with a unit, e.g. 0:20N (LO >= 0; default: the "
    "design's [operating_range] tension)."
)


def _bounds(design, text):
    from ..control import pressure_bounds
    from ..errors import InputError, design_error

    try:
        return pressure_bounds(design, text)
    except InputError as exc:
        raise design_error("--bounds", text, exc.rule, InputError) from None


def _tension_bounds(design, text):
    from ..control import tension_bounds
    from ..errors import InputError, design_error

    try:
        return tension_bounds(design, text)
    except InputError as exc:
        raise design_error("--tension-bounds", text, exc.rule, InputError) from None


@click.command("inverse")
@click.argument("design")
@click.option(
    "--target",
    "-t",
    required=True,
    metavar="X,Y,Z",
    help="Target position of the tip (world frame), e.g. '10,5,-130 mm'.",
)
@click.option("--bounds", "bounds", default=None, metavar="LO:HI", help=_BOUNDS_HELP)
@click.option(
    "--tension-bounds", "tension_bounds", default=None, metavar="LO:HI", help=_TENSION_BOUNDS_HELP
)
@click.option(
    "--point",
    default=None,
    help="Arc length of the rod point that should reach the target (default: the "
    "tip), e.g. '65 mm'.",
)
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
@_handle_errors
def inverse(design, target, bounds, tension_bounds, point, as_json):
    """Chamber pressures and tendon tensions within the bounds that bring the tip of DESIGN
    to --target.

    An unreachable target gives the closest pose inside the bounds, marked NOT reached,
    with the distance left (exit code 0).
    """
    from ..catalog import load_design
    from ..control import solve_inverse
    from ..errors import InputError
    from ..units import to_si

    d = load_design(design)
    position = _parse_vector(target, "length", "--target", 3)
    s = None if point is None else to_si(point, "length", "--point", InputError, bare="error")
    sol = solve_inverse(
        d,
        position,
        pressure_bounds=_bounds(d, bounds),
        tension_bounds=_tension_bounds(d, tension_bounds),
        point=s,
    )
    if as_json:
        out = {
            "design": d.name,
            "point_mm": sol.point * 1e3,
            "target_mm": [v * 1e3 for v in sol.target_position],
            "pressures_kPa": [p / 1e3 for p in sol.pressures],
            "position_mm": [v * 1e3 for v in sol.point_position],
            "reached": sol.reached,
            "distance_mm": sol.distance * 1e3,
            "active_bounds": [int(a) for a in sol.active],
            "bounds_kPa": (sol.bounds / 1e3).tolist(),
            "tensions_N": [float(t) for t in sol.tensions],
            "tension_active_bounds": [int(a) for a in sol.tension_active],
            "tension_bounds_N": sol.tension_bounds.tolist(),
            "iterations": sol.iterations,
        }
        click.echo(json.dumps(out, indent=2))
        return
    console = _stdout()
    console.print(f"design {d.name}; target [{', '.join(f'{v * 1e3:.3f}' for v in position)}] mm")
    for line in sol.summary().splitlines():
        style = "bold yellow" if "NOT reached" in line else None
        console.print(line, style=style)


@click.command("workspace")
@click.argument("design")
@click.option("--bounds", "bounds", default=None, metavar="LO:HI", help=_BOUNDS_HELP)
@click.option(
    "--tension-bounds", "tension_bounds", default=None, metavar="LO:HI", help=_TENSION_BOUNDS_HELP
)
@click.option(
    "--samples",
    default=21,
    show_default=True,
    type=click.IntRange(min=2),
    help="Samples per free channel on each face of the pressure box.",
)
@click.option(
    "--output",
    "-o",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write every boundary sample to a table (.csv or .parquet).",
)
@click.option(
    "--figure",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the 3-D, top and side views (.png, .pdf or .svg).",
)
@click.option(
    "--threads",
    default=0,
    show_default=True,
    type=click.IntRange(min=0),
    help="Cores for the batch (0 = all).",
)
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@_handle_errors
def workspace_cmd(design, bounds, tension_bounds, samples, output, figure, threads, as_json):
    """Reachable tip positions of DESIGN under the pressure (and tension) bounds: the images
    of the faces of the input box, solved in parallel."""
    from ..catalog import load_design
    from ..control import workspace
    from ..io import check_table_path, write_table

    d = load_design(design)
    if output is not None:
        check_table_path(output)
    if figure is not None:
        _check_output(figure, "--figure", (".png", ".pdf", ".svg"), "a figure")
    ws = workspace(
        d,
        pressure_bounds=_bounds(d, bounds),
        tension_bounds=_tension_bounds(d, tension_bounds),
        samples=samples,
        threads=threads,
    )
    summary = ws.summary()
    if output is not None:
        write_table(ws.to_frame(), output)
    if figure is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig = ws.plot(figure)
        plt.close(fig)
    if as_json:
        click.echo(
            json.dumps(
                {
                    "design": d.name,
                    "bounds_kPa": (ws.bounds / 1e3).tolist(),
                    "tension_bounds_N": ws.tension_bounds.tolist(),
                    "samples_per_face": samples,
                    "solves": summary["samples"],
                    "converged": summary["converged"],
                    "min_mm": (summary["min"] * 1e3).tolist(),
                    "max_mm": (summary["max"] * 1e3).tolist(),
                    "reach_xy_mm": summary["reach_xy"] * 1e3,
                    "hull_volume_cm3": summary["hull_volume"] * 1e6,
                    "wall_time_s": ws.wall_time_s,
                },
                indent=2,
            )
        )
        return
    from rich.table import Table

    table = Table(title=f"{d.name}: tip workspace, {samples} x {samples} samples per face")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    lo, hi = summary["min"] * 1e3, summary["max"] * 1e3
    for k, axis in enumerate("xyz"):
        table.add_row(f"{axis} range (mm)", f"{lo[k]:.2f} .. {hi[k]:.2f}")
    table.add_row("largest horizontal reach (mm)", f"{summary['reach_xy'] * 1e3:.2f}")
    table.add_row("convex hull volume (cm^3)", f"{summary['hull_volume'] * 1e6:.3f}")
    table.add_row("solves (converged)", f"{summary['samples']} ({summary['converged']})")
    table.add_row("wall time (s)", f"{ws.wall_time_s:.3f}")
    _stdout().print(table)


@click.command("track")
@click.argument("design")
@click.option(
    "--path",
    "path_file",
    required=True,
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    help="Target path: CSV with time_s and x_mm, y_mm, z_mm (or x_m, ...).",
)
@click.option("--bounds", "bounds", default=None, metavar="LO:HI", help=_BOUNDS_HELP)
@click.option(
    "--rate",
    default=100.0,
    show_default=True,
    type=click.FloatRange(min=0, min_open=True),
    help="Control rate, Hz.",
)
@click.option(
    "--kp",
    default=0.5,
    show_default=True,
    type=click.FloatRange(min=0),
    help="Proportional gain on the tip error.",
)
@click.option(
    "--ki",
    default=2.0,
    show_default=True,
    type=click.FloatRange(min=0),
    help="Integral gain on the tip error, 1/s.",
)
@click.option(
    "--output",
    "-o",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the tip, reference and error at every step (.csv or .parquet).",
)
@click.option(
    "--plot",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the tracking plot (.png, .pdf or .svg).",
)
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@_handle_errors
def track(design, path_file, bounds, rate, kp, ki, output, plot, as_json):
    """Make the tip of DESIGN follow a path in the dynamic simulation: inverse statics as
    feed-forward plus a PI correction on the tip error, at --rate."""
    from ..catalog import load_design
    from ..control import TargetPath, TrackingController, run_closed_loop
    from ..control.closed_loop import tracking_frame, tracking_plot
    from ..io import check_table_path, write_table

    d = load_design(design)
    if output is not None:
        check_table_path(output)
    if plot is not None:
        _check_output(plot, "--plot", (".png", ".pdf", ".svg"), "a plot")
    path = TargetPath.from_file(path_file)
    ctrl = TrackingController(d, path, rate=rate, kp=kp, ki=ki, pressure_bounds=_bounds(d, bounds))
    start = ctrl.problem.solve(path.at(0.0))
    result = run_closed_loop(d, ctrl, float(path.time[-1]), rate=rate, pressures=start.pressures)
    frame = tracking_frame(ctrl, result)
    err = frame["error_mm"].to_numpy()
    rms, worst = float((err**2).mean() ** 0.5), float(err.max())
    if output is not None:
        write_table(frame, output)
    if plot is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig = tracking_plot(ctrl, result, plot)
        plt.close(fig)
    if as_json:
        click.echo(
            json.dumps(
                {
                    "design": d.name,
                    "duration_s": float(path.time[-1]),
                    "rate_Hz": rate,
                    "kp": kp,
                    "ki": ki,
                    "rms_error_mm": rms,
                    "max_error_mm": worst,
                },
                indent=2,
            )
        )
        return
    _stdout().print(
        f"{d.name}: tracked {path_file.name} for {path.time[-1]:.3g} s at "
        f"{rate:g} Hz; tip error RMS {rms:.3f} mm, max {worst:.3f} mm"
    )


def _print_growing_poles(poles) -> None:
    """The linearisation's growing poles (positive real part; one of each complex pair) on
    stderr: growth rate in 1/s and frequency in Hz, fastest first, at most four."""
    from rich.console import Console

    growing = [z for z in poles if z.real > 1e-6 * abs(z) and z.imag >= 0][:4]
    if not growing:  # merged undamped modes that damping keeps stable: the error says so
        return
    text = "; ".join(f"{z.real:.4g} 1/s at {z.imag / (2 * math.pi):.4g} Hz" for z in growing)
    Console(stderr=True, highlight=False, soft_wrap=True).print(
        f"growing poles of the linearisation (growth rate, frequency): {text}"
    )


@click.command("modes")
@click.argument("design")
@click.option(
    "--pressure",
    "-p",
    metavar="P1,P2,...",
    help="Gauge pressure per channel of the equilibrium, comma-separated, e.g. 30kPa,0,0 "
    "(units required, zero needs none). Default: 0 on every channel.",
)
@click.option(
    "--tension",
    "-t",
    metavar="T1,T2,...",
    help="Tendon tension per tendon channel (>= 0), e.g. 2N,0. Default: every tendon slack.",
)
@click.option(
    "--nodes",
    default=12,
    show_default=True,
    type=click.IntRange(min=1, max=200),
    help="Nodes carrying the coordinates (at most the design's integration steps).",
)
@click.option(
    "--count",
    default=6,
    show_default=True,
    type=click.IntRange(min=1),
    help="How many of the lowest modes to list.",
)
@click.option(
    "--output",
    "-o",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the modes to a table (.csv or .parquet).",
)
@click.option(
    "--figure",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the mode shapes (at most the 8 lowest), front and side views (.png, .pdf or .svg).",
)
@click.option("--json", "as_json", is_flag=True, help="Print the modes as JSON.")
@_handle_errors
def modes(design, pressure, tension, nodes, count, output, figure, as_json):
    """Natural frequencies and damping of DESIGN about its equilibrium under --pressure: the
    linearised dynamics' lowest modes (docs/control.md, 'Linearised dynamics and modes'),
    with the design's tip loads and [tip] constraint."""
    from ..catalog import load_design
    from ..control import linearise
    from ..errors import InputError, design_error
    from ..io import check_table_path, write_table
    from .statics import _parse_pressures, _parse_tensions

    d = load_design(design)
    if output is not None:
        check_table_path(output)
    if figure is not None:
        _check_output(figure, "--figure", (".png", ".pdf", ".svg"), "a figure")
    p = _parse_pressures(pressure, d)
    system = linearise(d, p, nodes=nodes, tensions=_parse_tensions(tension, d))
    n = system.mass.shape[0]
    if count > n:
        raise design_error(
            "--count", count, f"must be at most the {n} coordinates of {nodes} nodes", InputError
        )
    try:
        found = system.modes(count)
    except InputError as exc:
        if exc.field == "equilibrium":  # unstable: show what grows before the error line
            _print_growing_poles(system.poles())
        raise
    frame = found.to_frame()
    if output is not None:
        write_table(frame, output)
    if figure is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        plt.close(system.plot_modes(min(count, 8), figure))
    if as_json:
        click.echo(
            json.dumps(
                {
                    "design": d.name,
                    "pressures_kPa": [v / 1e3 for v in p],
                    "tip_constraint": system.tip_constraint,
                    "nodes": nodes,
                    "frequency_Hz": found.frequency.tolist(),
                    "damping_ratio": found.damping_ratio.tolist(),
                    # NaN (an overdamped mode) is not JSON: null.
                    "damped_frequency_Hz": [
                        None if v != v else float(v) for v in found.damped_frequency
                    ],
                },
                indent=2,
            )
        )
        return
    from rich.table import Table

    console = _stdout()
    follower = " (follower tip load)" if d.spec["tip"].get("frame") == "body" else ""
    console.print(
        f"design {d.name}; pressures [{', '.join(f'{v / 1e3:g}' for v in p)}] kPa; "
        f"tip {system.tip_constraint}{follower}; {nodes} nodes"
    )
    table = Table()
    table.add_column("mode", justify="right")
    table.add_column("frequency (Hz)", justify="right")
    table.add_column("damping ratio", justify="right")
    table.add_column("damped frequency (Hz)", justify="right")
    for k in range(count):
        damped = found.damped_frequency[k]
        table.add_row(
            str(k + 1),
            f"{found.frequency[k]:.4g}",
            f"{found.damping_ratio[k]:.3g}",
            "overdamped" if damped != damped else f"{damped:.4g}",
        )
    console.print(table)
