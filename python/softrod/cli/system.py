"""``softrod solve-system`` and ``softrod simulate-system``: a system of rods holding one
platform (a system file or a bundled system), its equilibrium and its motion
(docs/model.md and docs/dynamics.md, "Systems of rods")."""

from __future__ import annotations

import json
import time
from pathlib import Path

import click

from ..errors import DesignError, InputError, design_error
from ._common import (
    PLOT_SUFFIXES,
    _alpha_option,
    _check_output,
    _contact_json,
    _energy_tol_option,
    _fmt_kpa,
    _fmt_vec,
    _for_option,
    _friction_steps_option,
    _handle_errors,
    _parse_pressures,
    _parse_vector,
    _print_warnings,
    _quantity,
    _quiet,
    _say,
    _staged,
    _stdout,
)

SYSTEM_TRAJECTORY_SUFFIXES = (".npz", ".csv", ".parquet")

_PER_ROD = "Give it once per rod, in the system file's order ({n} rods); default: {default}."


def _per_rod(texts: tuple[str, ...], system, option: str, parse) -> list | None:
    """One value per rod from an option given once per rod (None when not given): the
    error of a rod's value names the option, the rod and the item."""
    if not texts:
        return None
    n = len(system.rods)
    if len(texts) != n:
        raise design_error(
            option,
            list(texts),
            f"system {system.name} has {n} rods: give {option} once per rod, in the system "
            f"file's order (given {len(texts)} times)",
            InputError,
        )
    out = []
    for i, (text, rod) in enumerate(zip(texts, system.rods, strict=True)):
        try:
            out.append(parse(text, rod.design))
        except DesignError as exc:
            field = exc.field.replace(option, f"{option} of rod {i}", 1)
            raise design_error(field, exc.value, exc.rule, InputError) from None
    return out


def _tensions(text: str, design) -> list[float]:
    from .statics import _parse_tensions

    return _parse_tensions(text, design)


def _platform_load(force: str | None, moment: str | None):
    f = None if force is None else _parse_vector(force, "force", "--platform-force", 3)
    m = None if moment is None else _parse_vector(moment, "moment", "--platform-moment", 3)
    return f, m


def _system_argument(name: str):
    from ..system import load_system

    return load_system(name)


_pressure_option = click.option(
    "--pressure",
    "-p",
    "pressures",
    multiple=True,
    metavar="P1,P2,...",
    help="Gauge pressures of one rod's channels, e.g. 40kPa,0,0 (units required, zero "
    "needs none). " + _PER_ROD.format(n="n", default="0 on every channel"),
)
_tension_option = click.option(
    "--tension",
    "-t",
    "tensions",
    multiple=True,
    metavar="T1,T2,...",
    help="Tendon tensions of one rod (>= 0), e.g. 2N,0. "
    + _PER_ROD.format(n="n", default="every tendon slack"),
)
_force_option = click.option(
    "--platform-force",
    metavar="FX,FY,FZ",
    help='External force on the platform (world frame, at its origin), e.g. "0,0,-0.1 N" '
    "(replaces the system file's; the platform's weight always acts).",
)
_moment_option = click.option(
    "--platform-moment",
    metavar="MX,MY,MZ",
    help='External moment on the platform (world frame), e.g. "0,2,0 N*mm".',
)


@click.command("solve-system")
@click.argument("system")
@_pressure_option
@_tension_option
@_force_option
@_moment_option
@click.option(
    "--on-invalid",
    type=click.Choice(["raise", "warn"]),
    default="raise",
    show_default=True,
    help="A rod outside its validity range: an error, or a warning with the result.",
)
@_friction_steps_option("the system's frictional solve")
@click.option("--json", "as_json", is_flag=True, help="Print a JSON object with SI values.")
@click.option(
    "--plot",
    "plot_path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write front and side views of the equilibrium here (.png, .pdf, .svg).",
)
@_handle_errors
def solve_system_cmd(
    system,
    pressures,
    tensions,
    platform_force,
    platform_moment,
    on_invalid,
    friction_steps,
    as_json,
    plot_path,
):
    """Static equilibrium of SYSTEM: rods clamped at their bases and holding one platform.

    SYSTEM is a system file (TOML, docs/model.md "Systems of rods") or the name of a bundled
    system (two_spa_platform). Prints the platform's pose, every rod's tip and the wrench
    the platform applies to it, and whether the whole system's equilibrium is stable. Where
    a rod's obstacle has friction the system follows a load path from the unloaded rods in
    --friction-steps increments (docs/contact.md, "Friction in the statics").
    """
    from rich.table import Table

    from ..system import solve_system

    sysm = _system_argument(system)
    options = _system_friction_options(sysm, friction_steps)
    if plot_path is not None:
        _check_output(plot_path, "--plot", PLOT_SUFFIXES, "figure")
    ps = _per_rod(pressures, sysm, "--pressure", _parse_pressures)
    ts = _per_rod(tensions, sysm, "--tension", _tensions)
    force, moment = _platform_load(platform_force, platform_moment)
    t0 = time.perf_counter()
    sol = solve_system(
        sysm,
        ps,
        tensions=ts,
        platform_force=force,
        platform_moment=moment,
        options=options,
        on_invalid=on_invalid,
        on_unstable="ignore",
    )
    elapsed = time.perf_counter() - t0
    from ..system_plots import platform_tilt_deg

    tilt = float(platform_tilt_deg(sol.platform_rotation))
    notes = [v for r in sol.rods for v in r.violations]
    if sol.friction_state is not None:
        notes.append(
            "stability not assessed (friction has no potential; the answer follows a load "
            "path from the unloaded rods: docs/contact.md, 'Friction in the statics')"
        )
    if sol.stable is False:
        notes.append(
            "the system's equilibrium is unstable: a small disturbance moves it away "
            "(docs/model.md, 'Systems of rods')"
        )
    if as_json:
        out = {
            "system": sysm.name,
            "platform_position_m": sol.platform_position.tolist(),
            "platform_rotation": sol.platform_rotation.tolist(),
            "platform_tilt_deg": tilt,
            "rods": [
                {
                    "design": rod.design.name,
                    "pressures_Pa": [float(x) for x in r.pressures],
                    "tensions_N": [float(x) for x in r.tensions],
                    "tip_position_m": r.tip_position.tolist(),
                    "tip_reaction_force_N": r.tip_reaction_force.tolist(),
                    "tip_reaction_moment_Nm": r.tip_reaction_moment.tolist(),
                    "base_force_N": r.base_force.tolist(),
                    "base_moment_Nm": r.base_moment.tolist(),
                    **_contact_json(r),
                }
                for rod, r in zip(sysm.rods, sol.rods, strict=True)
            ],
            "converged": bool(sol.converged),
            "stable": None if sol.stable is None else bool(sol.stable),
            "iterations": int(sol.iterations),
            "residual": float(sol.residual),
        }
        click.echo(json.dumps(out, indent=2))
    else:
        table = Table(title=f"{sysm.name}: static equilibrium", title_justify="left")
        table.add_column("quantity")
        table.add_column("value", justify="right")
        table.add_column("unit")
        table.add_row("platform position (x, y, z)", _fmt_vec(sol.platform_position, 1e3, 3), "mm")
        table.add_row("platform tilt", f"{tilt:.3f}", "deg")
        for i, r in enumerate(sol.rods):
            if len(r.pressures):
                table.add_row(f"rod {i}: pressures", _fmt_kpa(r.pressures), "kPa")
            if len(r.tensions):
                table.add_row(f"rod {i}: tensions", _fmt_vec(r.tensions, 1.0, 3), "N")
            table.add_row(f"rod {i}: tip position", _fmt_vec(r.tip_position, 1e3, 3), "mm")
            table.add_row(
                f"rod {i}: platform's force on its tip", _fmt_vec(r.tip_reaction_force, 1.0, 4), "N"
            )
            table.add_row(
                f"rod {i}: platform's moment on its tip",
                _fmt_vec(r.tip_reaction_moment, 1e3, 3),
                "N mm",
            )
            if r.contact is not None:
                for k, (force, fric) in enumerate(
                    zip(r.contact.total_force, r.contact.friction_force, strict=True)
                ):
                    table.add_row(
                        f"rod {i}: contact force, obstacle {k}", _fmt_vec(force, 1.0, 4), "N"
                    )
                    if sol.friction_state is not None:
                        table.add_row(f"rod {i}:   its friction part", _fmt_vec(fric, 1.0, 4), "N")
        stable = "not assessed" if sol.stable is None else "yes" if sol.stable else "NO"
        table.add_row("stable", stable, "")
        table.add_row("iterations", f"{sol.iterations}", "")
        table.add_row("residual (scaled)", f"{sol.residual:.2e}", "")
        table.add_row("solve time", f"{elapsed * 1e3:,.2f}", "ms")
        _stdout().print(table)
    if notes:
        from rich.console import Console

        _print_warnings(Console(stderr=True, highlight=False), notes)
    if plot_path is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        plt.close(sol.plot(plot_path))  # written atomically
        # Keep stdout pure JSON with --json: say where the figure went on stderr instead.
        _say(f"wrote {plot_path}", stderr=as_json)


def _system_friction_options(sysm, friction_steps: int | None):
    """SolverOptions with --friction-steps N (None: the defaults), refused on a system
    without friction, where it would be ignored."""
    from ..statics import SolverOptions

    if friction_steps is None:
        return None
    if all(r.design.frictional_obstacle is None for r in sysm.rods):
        raise click.BadParameter(
            f"{friction_steps}: no rod of the system has an obstacle with friction > 0, so "
            "its solve has no load increments",
            param_hint="--friction-steps",
        )
    return SolverOptions(friction_steps=friction_steps)


@click.command("simulate-system")
@click.argument("system")
@_pressure_option
@_tension_option
@_force_option
@_moment_option
@click.option(
    "--start-pressure",
    "start_pressures",
    multiple=True,
    metavar="P1,P2,...",
    help="Gauge pressures of one rod at the start (the system starts at rest in their "
    "equilibrium; then --pressure acts, a step). "
    + _PER_ROD.format(n="n", default="0 on every channel"),
)
@click.option(
    "--input",
    "input_path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Commanded pressures over time instead of --pressure: CSV or Parquet with time_s "
    "and p0_kPa, p1_kPa, ... columns, every rod's channels in the system file's order "
    "(rod 0's first); joined linearly (docs/dynamics.md). The start is the equilibrium "
    "under its first row.",
)
@click.option(
    "--t-end",
    "t_end",
    help="Simulated time with its unit, e.g. '1 s' (default: --input's last time; "
    "required with --pressure).",
)
@click.option("--dt", default="2 ms", show_default=True, help="Time step (output interval).")
@_alpha_option
@_energy_tol_option
@click.option(
    "--out",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="The motion: .npz (every array and the rods' shapes, read back by "
    "softrod.SystemTrajectory.load), or a table .csv / .parquet.",
)
@click.option(
    "--plot",
    "plot_path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Also write the platform's displacement and tilt and the pressures over time "
    "(.png/.pdf/.svg), with the equilibrium under the final inputs dashed.",
)
@_handle_errors
def simulate_system_cmd(
    system,
    pressures,
    tensions,
    platform_force,
    platform_moment,
    start_pressures,
    input_path,
    t_end,
    dt,
    alpha,
    energy_tol,
    out,
    plot_path,
):
    """Simulate the motion of SYSTEM (rods holding one rigid platform) from rest.

    The rods are paper 000's viscoelastic Cosserat rods (each design's [dynamics] damping
    time), the platform a rigid body; BDF-alpha in time (docs/dynamics.md, "Systems of
    rods"). Inputs: a step from --start-pressure to --pressure at t = 0, or a schedule
    file (--input). Tensions and platform loads are held over the run.
    """
    import numpy as np

    from ..dynamics import PressureSchedule
    from ..dynamics.simulate import step_count
    from ..system_dynamics import SystemSimulation, SystemTrajectory

    sysm = _system_argument(system)
    outputs = [_check_output(out, "--out", SYSTEM_TRAJECTORY_SUFFIXES, "trajectory")]
    if plot_path is not None:
        outputs.append(_check_output(plot_path, "--plot", PLOT_SUFFIXES, "plot"))
    # --out and --plot take different suffixes, so they never name the same file.
    if input_path is not None and (pressures or start_pressures):
        raise design_error(
            "--input",
            str(input_path),
            "give --input or --pressure/--start-pressure, not both",
            InputError,
        )
    step = _quantity(dt, "time", "--dt")
    if not step > 0:
        raise design_error("--dt", dt, "must be > 0 s", InputError)
    widths = [r.design.n_channels for r in sysm.rods]
    offsets = np.cumsum([0, *widths])
    if input_path is not None:
        schedule = PressureSchedule.from_file(input_path)
        _for_option(schedule.check_channels, int(offsets[-1]), "--input")

        def split(row):
            return [list(row[a:b]) for a, b in zip(offsets[:-1], offsets[1:], strict=True)]

        def command(t: float):
            return split(schedule.sample([t])[0])

        start = command(0.0)
        if t_end is None:
            if not schedule.t_end:
                raise design_error(
                    "--t-end", None, "the schedule has no end time; give --t-end", InputError
                )
            duration = float(schedule.t_end)
        else:
            duration = _quantity(t_end, "time", "--t-end")
        final = command(duration)
    else:
        start = _per_rod(start_pressures, sysm, "--start-pressure", _parse_pressures)
        held = _per_rod(pressures, sysm, "--pressure", _parse_pressures)
        if t_end is None:
            raise design_error("--t-end", None, "give the simulated time, e.g. 1s", InputError)
        duration = _quantity(t_end, "time", "--t-end")
        start = start or [[0.0] * w for w in widths]
        final = held or start
        command = final
    if not duration > 0:
        raise design_error("--t-end", t_end, "must be > 0 s", InputError)
    ts = _per_rod(tensions, sysm, "--tension", _tensions)
    force, moment = _platform_load(platform_force, platform_moment)
    sim = SystemSimulation(
        sysm,
        start,
        tensions=ts,
        platform_force=force,
        platform_moment=moment,
        dt=step,
        alpha=alpha,
        energy_tol=energy_tol,
    )
    steps = step_count(duration, step, "--t-end")
    _say(f"{sysm.name}: {duration:g} s at dt = {step * 1e3:g} ms ({steps:,} steps)")
    begin = sim.state()
    t0 = time.perf_counter()
    traj = _run_with_progress(sim, command, duration, steps)
    wall = time.perf_counter() - t0
    traj = SystemTrajectory.concat([begin, traj])
    stats = sim.stats
    console = _stdout()
    console.print(
        f"{stats['steps']:,} steps in {wall:.2f} s: {duration / wall:,.2f}x real time on one "
        f"core ({stats['newton_iterations']:,} Newton iterations, {stats['jacobians']:,} "
        "exact Jacobians)"
    )
    reference = None
    if plot_path is not None:
        from ..system import solve_system

        reference = solve_system(
            sysm,
            final,
            tensions=ts,
            platform_force=force,
            platform_moment=moment,
            on_unstable="ignore",
            on_invalid="warn",
            check=False,
        )
        if not reference.converged:
            reference = None
    # The staged names end in the destinations' names, so each keeps its format.
    with _staged(outputs) as staged:
        traj.save(staged[0])
        if plot_path is not None:
            import matplotlib

            matplotlib.use("Agg")
            import matplotlib.pyplot as plt

            plt.close(traj.plot(staged[1], reference=reference))
    reach = np.linalg.norm(traj.platform_position - traj.platform_position[0], axis=1).max()
    console.print(f"largest platform excursion from the start: {reach * 1e3:.2f} mm")
    for p in outputs:
        _say(f"wrote {p}")


def _run_with_progress(sim, command, duration: float, steps: int):
    """Run in chunks under a progress bar of simulated time (on a terminal only)."""
    from ..progress import reporter
    from ..system_dynamics import SystemTrajectory
    from .simulate import _stderr_is_terminal

    bar = not _quiet() and _stderr_is_terminal()

    def simulated(done: float, total: float, wall: float):
        rtf = f"{done / wall:,.2f}" if wall > 0 else "--"
        return done, f"{done:.3f} / {total:g} s, {rtf}x real time"

    chunk = max(1, steps // 50)
    parts = []
    t_start = time.perf_counter()
    with reporter(bar, "simulate", duration, simulated) as report:
        done = 0
        while done < steps:
            k = min(chunk, steps - done)
            parts.append(sim.run(command, k * sim.dt))
            done += k
            if report is not None:
                report(min(done * sim.dt, duration), duration, time.perf_counter() - t_start)
    return SystemTrajectory.concat(parts)
