"""``softrod solve``, ``softrod sweep`` and ``softrod demo``: static equilibria of a design."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import click

from ..errors import InputError, design_error
from ._common import (
    _channels,
    _contact_json,
    _fmt,
    _fmt_kpa,
    _fmt_vec,
    _for_option,
    _friction_steps_option,
    _full_factorial,
    _handle_errors,
    _parse_grid,
    _parse_pressures,
    _parse_vector,
    _print_warnings,
    _progress,
    _say,
    _scheduler,
    _scheduler_option,
    _stdout,
    _threads_option,
    _write_shape_plot,
)

MAX_SWEEP_ROWS = 10_000_000  # larger grids are refused (memory, and hours of compute)
SWEEP_CHUNK = 512  # rows per batch call: the progress bar advances per chunk
DEMO_DESIGN = "spa_three_chamber_130mm"
DEMO_CASES_KPA = [(0, 0, 0), (35, 0, 0), (70, 0, 0), (70, 70, 0), (70, 70, 70)]
DEMO_SWEEP = (0.0, 70e3, 7)  # Pa, Pa, points per channel: a 7^3 grid


def _parse_tensions(text: str | None, design) -> list[float] | None:
    """--tension T1,T2,...: one tension per tendon channel (N, >= 0), or None (slack)."""
    if text is None:
        return None
    n = design.n_tendons
    items = text.split(",")
    if n == 0 or len(items) != n:
        raise design_error(
            "--tension",
            text,
            f"design {design.name} has {n} tendon channel{'s' if n != 1 else ''}"
            + (
                f"; give {n} comma-separated tensions, e.g. " + ",".join(["2N"] + ["0"] * (n - 1))
                if n
                else "; leave --tension out"
            ),
            InputError,
        )
    from ._common import _parse_quantities

    values = _parse_quantities(items, "force", [f"--tension[{i}]" for i in range(n)])
    for i, t in enumerate(values):
        if not t >= 0:
            raise design_error(
                f"--tension[{i}]",
                items[i].strip(),
                "a tendon tension must be >= 0 (a tendon pulls or is slack, it cannot push)",
                InputError,
            )
    return values


def _friction_options(design, friction_steps: int | None):
    """SolverOptions with --friction-steps N (None: the defaults), refused on a design
    without friction, where it would be ignored."""
    from ..statics import SolverOptions

    if friction_steps is None:
        return None
    if design.frictional_obstacle is None:
        raise click.BadParameter(
            f"{friction_steps}: the design has no obstacle with friction > 0, so its "
            "solve has no load increments",
            param_hint="--friction-steps",
        )
    return SolverOptions(friction_steps=friction_steps)


def _lateral(sol) -> float:
    """Tip distance from the base tangent line (the straight reference axis), m."""
    import numpy as np

    d = sol.tip_position - sol.position[0]
    t0 = sol.rotation[0][:, 2]
    return float(np.linalg.norm(d - np.dot(d, t0) * t0))


def _run_sweep(design, pressures, threads: int, chunk: int, label: str, client=None, options=None):
    """Solve every row in chunks under a progress bar; return (BatchSolution, wall time s).
    With a Dask ``client`` the chunks run on its cluster (chunk size by softrod.cluster's
    rule). ``options``: the batch's SolverOptions (None: the defaults)."""
    import numpy as np

    from ..solution import BatchSolution
    from ..statics import solve_statics_batch

    m = len(pressures)
    if client is not None:
        t0 = time.perf_counter()
        with _progress(label, m) as advance:
            done = [0]

            def chunks_done(rows: int, _total: int) -> None:
                advance(rows - done[0])
                done[0] = rows

            batch = solve_statics_batch(
                design,
                pressures,
                threads=threads,
                executor=client,
                progress=chunks_done,
                on_unstable="ignore",
                options=options,
            )
        return batch, time.perf_counter() - t0
    parts = []
    t0 = time.perf_counter()
    with _progress(label, m) as advance:
        for lo in range(0, m, chunk):
            hi = min(lo + chunk, m)
            parts.append(
                solve_statics_batch(
                    design,
                    pressures[lo:hi],
                    threads=threads,
                    on_unstable="ignore",
                    options=options,
                )
            )
            advance(hi - lo)
    wall = time.perf_counter() - t0

    def stack(name):
        return np.concatenate([getattr(b, name) for b in parts])

    fields = ("tip_position", "tip_rotation", "base_force", "base_moment", "converged")
    held = bool(parts) and parts[0].tip_reaction_force is not None
    frictional = bool(parts) and parts[0].contact_force is not None
    batch = BatchSolution(
        pressures=np.asarray(pressures, dtype=float),
        **{name: stack(name) for name in fields},
        iterations=stack("iterations"),
        residual=stack("residual"),
        stable=stack("stable"),
        stability_assessed=stack("stability_assessed"),
        violation=stack("violation"),
        metadata=parts[0].metadata if parts else {},
        tip_constraint=parts[0].tip_constraint if parts else "free",
        tip_reaction_force=stack("tip_reaction_force") if held else None,
        tip_reaction_moment=stack("tip_reaction_moment") if held else None,
        contact_force=stack("contact_force") if frictional else None,
        friction_force=stack("friction_force") if frictional else None,
    )
    return batch, wall


@click.command()
@click.argument("design")
@click.option(
    "--pressure",
    "-p",
    metavar="P1,P2,...",
    help="Gauge pressure per channel, comma-separated, e.g. 30kPa,0,0 or 0.3bar,0,0. "
    "Units are required (zero needs none); a unit on the last item alone applies to all. "
    "Default: 0 on every channel.",
)
@click.option(
    "--tip-force",
    metavar="FX,FY,FZ",
    help='Tip force in the design\'s tip frame (world, or body with [tip] frame = "body"), '
    'e.g. "0,0,-1 N" (replaces the design\'s).',
)
@click.option(
    "--tip-moment",
    metavar="MX,MY,MZ",
    help='Tip moment in the design\'s tip frame, e.g. "0,5,0 N*mm".',
)
@click.option(
    "--tension",
    "-t",
    metavar="T1,T2,...",
    help="Tendon tension per tendon channel (>= 0), comma-separated, e.g. 2N,0 "
    "(units required, zero needs none). Default: every tendon slack.",
)
@click.option(
    "--on-invalid",
    type=click.Choice(["raise", "warn"]),
    default="raise",
    show_default=True,
    help="A solution outside the validity range (strains beyond the model's range, "
    "pressures beyond the design's operating_range): an error, or a warning with the "
    "result (docs/model.md, 'Validity and stability').",
)
@_friction_steps_option("a frictional solve")
@click.option("--json", "as_json", is_flag=True, help="Print a JSON object with SI values.")
@click.option(
    "--plot",
    "plot_path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the 3-D shape figure here (format from the suffix: .png, .pdf, .svg).",
)
@_handle_errors
def solve(
    design, pressure, tip_force, tip_moment, tension, on_invalid, friction_steps, as_json, plot_path
):
    """Static shape of DESIGN under the given chamber pressures."""
    from rich.table import Table

    from ..catalog import load_design
    from ..statics import solve_statics

    d = load_design(design)
    options = _friction_options(d, friction_steps)
    if plot_path is not None:
        from ..plotting import check_figure_path

        _for_option(check_figure_path, plot_path, "--plot")
    p = _parse_pressures(pressure, d)
    tf = None if tip_force is None else _parse_vector(tip_force, "force", "--tip-force", 3)
    tm = None if tip_moment is None else _parse_vector(tip_moment, "moment", "--tip-moment", 3)
    tensions = _parse_tensions(tension, d)
    t0 = time.perf_counter()
    sol = solve_statics(
        d,
        p,
        tip_force=tf,
        tip_moment=tm,
        tensions=tensions,
        on_unstable="ignore",
        on_invalid=on_invalid,
        options=options,
    )
    elapsed = time.perf_counter() - t0
    notes = list(sol.violations)
    if sol.stable is None and sol.friction_state is not None:
        notes.append(
            "stability not assessed (friction has no potential; the answer follows a load "
            "path from the unloaded rod: docs/contact.md, 'Friction in the statics')"
        )
    elif sol.stable is None:
        notes.append("stability not assessed (follower loads are not conservative: docs/scope.md)")
    elif not sol.stable:
        notes.append(
            "the equilibrium is unstable: a small disturbance moves the rod away from it "
            "(above a buckling load, add a small lateral force to choose the side)"
        )

    if as_json:
        out = {
            "design": d.name,
            "pressures_Pa": [float(x) for x in p],
            "tip_position_m": sol.tip_position.tolist(),
            "tip_rotation": sol.tip_rotation.tolist(),
            "base_force_N": sol.base_force.tolist(),
            "base_moment_Nm": sol.base_moment.tolist(),
            "converged": bool(sol.converged),
            "stable": None if sol.stable is None else bool(sol.stable),
            "violations": list(sol.violations),
            "iterations": int(sol.iterations),
            "residual": float(sol.residual),
            "shape": {"s_m": sol.s.tolist(), "position_m": sol.position.tolist()},
        }
        if d.n_tendons:
            out["tensions_N"] = [float(x) for x in sol.tensions]
        if sol.tip_constraint != "free":
            out["tip_constraint"] = sol.tip_constraint
            out["tip_reaction_force_N"] = sol.tip_reaction_force.tolist()
            out["tip_reaction_moment_Nm"] = sol.tip_reaction_moment.tolist()
        out.update(_contact_json(sol))
        click.echo(json.dumps(out, indent=2))
    else:
        table = Table(title=f"{d.name}: static equilibrium", title_justify="left")
        table.add_column("quantity")
        table.add_column("value", justify="right")
        table.add_column("unit")
        if len(p):
            table.add_row(f"pressures {_channels('p', len(p))}", _fmt_kpa(p), "kPa")
        if len(sol.tensions):
            t_all = sol.tensions
            tensions = ", ".join(f"{x:g}" for x in t_all)
            table.add_row(f"tensions {_channels('t', len(t_all))}", tensions, "N")
        table.add_row("tip position (x, y, z)", _fmt_vec(sol.tip_position, 1e3, 3), "mm")
        table.add_row("tip tangent d3", _fmt_vec(sol.tip_rotation[:, 2], 1.0, 4), "-")
        table.add_row("base force", _fmt_vec(sol.base_force, 1.0, 4), "N")
        table.add_row("base moment", _fmt_vec(sol.base_moment, 1e3, 3), "N mm")
        if sol.tip_constraint != "free":
            held = f"tip reaction force ({sol.tip_constraint})"
            table.add_row(held, _fmt_vec(sol.tip_reaction_force, 1.0, 4), "N")
            if sol.tip_constraint == "clamped":
                moment = sol.tip_reaction_moment
                table.add_row("tip reaction moment (clamped)", _fmt_vec(moment, 1e3, 3), "N mm")
        if sol.contact is not None:
            for k, force in enumerate(sol.contact.total_force):
                table.add_row(f"contact force, obstacle {k}", _fmt_vec(force, 1.0, 4), "N")
            touching = int(sol.contact.in_contact.sum())
            depth = max(sol.contact.max_penetration, 0.0) * 1e3
            table.add_row("nodes in contact", f"{touching} of {len(sol.s)}", "")
            table.add_row("deepest penetration", f"{depth:.4f}", "mm")
        table.add_row("converged", "yes" if sol.converged else "no", "")
        stable = "not assessed" if sol.stable is None else "yes" if sol.stable else "NO"
        table.add_row("stable", stable, "")
        table.add_row("iterations", f"{sol.iterations}", "")
        table.add_row("residual (scaled)", f"{sol.residual:.2e}", "")
        table.add_row("solve time", f"{elapsed * 1e6:,.0f}", "us")
        _stdout().print(table)
    if notes:
        # Warnings go to stderr, so that --json output stays pure JSON.
        from rich.console import Console

        _print_warnings(Console(stderr=True, highlight=False), notes)

    if plot_path is not None:
        written = _write_shape_plot([sol], plot_path)
        # Keep stdout pure JSON with --json: say where the figure went on stderr instead.
        _say(f"wrote {written}", stderr=as_json)


@click.command()
@click.argument("design")
@click.option(
    "--grid",
    "grids",
    multiple=True,
    required=True,
    metavar="START:STOP:COUNT",
    help="Pressures per channel, e.g. 0:70kPa:21 (a unit on STOP alone applies to "
    "both ends). Give it once for every channel, or once per channel.",
)
@click.option(
    "--out",
    "out",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="Output table, .csv or .parquet (written whole or not at all).",
)
@_threads_option(
    "Worker threads (0 = all cores; with --scheduler: per task, 0 = the "
    "worker's share of its machine)."
)
@_scheduler_option(
    "Run on the Dask cluster whose scheduler is at ADDRESS, e.g. "
    "tcp://10.0.0.5:8786 (docs/cluster.md)."
)
@_friction_steps_option("every row's frictional load path")
@_handle_errors
def sweep(design, grids, out, threads, scheduler, friction_steps):
    """Tip positions over a full-factorial pressure grid of DESIGN.

    Rows run with channel 0 slowest and the last channel fastest; every row is solved cold,
    exactly as `softrod solve` would. The table is in the dataset schema (docs/datasets.md):
    p0_kPa, p1_kPa, ..., tip_x_mm, tip_y_mm, tip_z_mm, tip_qw..tip_qz, base_fx_N..,
    base_mx_Nmm.., then converged, iterations, residual and stable; its metadata block names the
    design, the softrod version and the grid. Rows that did not converge are kept with
    empty tip cells. A design whose [tip] pins or clamps the tip is swept with the tip held
    there (docs/model.md, "End constraints"): the table adds the constraint's reaction on
    the tip, tip_reaction_fx_N..fz_N and tip_reaction_mx_Nmm..mz_Nmm (world frame; zero
    moment when pinned), and its metadata block the constraint. A design whose obstacle
    has friction > 0 is swept with every row its own load path from the unloaded rod, as
    `softrod solve` follows it (--friction-steps increments; docs/contact.md, "Friction in
    the statics"): the table adds each obstacle's contact force contact0_fx_N.. and its
    friction part friction0_fx_N.., and stability is not assessed.
    """
    from ..catalog import load_design
    from ..io import check_table_path, write_table

    d = load_design(design)
    options = _friction_options(d, friction_steps)
    n = d.n_channels
    if n == 0:
        raise design_error(
            "design",
            d.name,
            "has no pressure channels: nothing to sweep (use `softrod solve`)",
            InputError,
        )
    out = _for_option(check_table_path, out, "--out")
    if len(grids) == 1:
        axes = [_parse_grid(grids[0])] * n
    elif len(grids) == n:
        axes = [_parse_grid(g, f"--grid[{k}]") for k, g in enumerate(grids)]
    else:
        raise design_error(
            "--grid",
            list(grids),
            f"give one --grid for all {n} channels or one per channel ({n}), not {len(grids)}",
            InputError,
        )
    rows = math.prod(len(a) for a in axes)
    if rows > MAX_SWEEP_ROWS:
        raise design_error(
            "--grid",
            list(grids),
            f"the grid has {rows:,} rows; the limit is {MAX_SWEEP_ROWS:,} "
            "(use fewer points per channel)",
            InputError,
        )
    pressures = _full_factorial(axes)
    console = _stdout()
    _say(f"{d.name}: {rows:,} rows ({' x '.join(str(len(a)) for a in axes)})")
    with _scheduler(scheduler) as client:
        if client is not None:
            _say(f"on the Dask cluster at {scheduler}")
        batch, wall = _run_sweep(
            d, pressures, threads, SWEEP_CHUNK, "sweep", client, options=options
        )
    frame = batch.to_frame()
    frame.attrs["softrod.metadata"].update(
        generator="softrod sweep", grid=list(grids), chunk_rows=SWEEP_CHUNK
    )
    write_table(frame, out)
    n_ok = int(batch.converged.sum())
    # Rows whose stability was not assessed (friction, follower loads) are not unstable.
    n_unstable = int((batch.converged & batch.stability_assessed & ~batch.stable).sum())
    style = "green" if n_ok == rows and n_unstable == 0 else "yellow"
    console.print(
        f"{rows:,} rows, [{style}]{n_ok:,} converged, {n_unstable:,} unstable[/{style}], "
        f"wall time {wall:.2f} s, {rows / wall:,.0f} solves/s"
    )
    _say(f"wrote {out}")


@click.command()
@click.option(
    "--out-dir",
    default="softrod-demo",
    show_default=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="Folder for shapes.png and tips.csv (created if needed).",
)
@_handle_errors
def demo(out_dir):
    """Tour: solve, plot and sweep the bundled three-chamber actuator (a few seconds).

    Writes shapes.png (the shapes in a 3-D view and a top view) and tips.csv (the dataset
    schema, docs/datasets.md) to --out-dir.
    """
    import numpy as np
    from rich.table import Table
    from rich.text import Text

    from ..catalog import load_design
    from ..io import write_table
    from ..schema import Extra, provenance, schema_frame
    from ..statics import solve_statics

    console = _stdout()
    d = load_design(DEMO_DESIGN)
    console.print(
        f"[bold]{d.name}[/bold]: {d.length * 1e3:.0f} mm, {d.n_channels} chambers, "
        f"hanging under gravity"
    )
    console.print(Text(d.citation, style="dim"))

    solutions, times = [], []
    for case in DEMO_CASES_KPA:
        t0 = time.perf_counter()
        solutions.append(solve_statics(d, [1e3 * x for x in case]))
        times.append(time.perf_counter() - t0)
    lateral = np.array([_lateral(sol) for sol in solutions])
    frame = schema_frame(
        pressures=np.array([sol.pressures for sol in solutions]),
        tip_position=np.array([sol.tip_position for sol in solutions]),
        tip_rotation=np.array([sol.tip_rotation for sol in solutions]),
        base_force=np.array([sol.base_force for sol in solutions]),
        base_moment=np.array([sol.base_moment for sol in solutions]),
        extras=[
            Extra("lateral", lateral, "tip distance from the base tangent line", "length"),
            Extra("iterations", [sol.iterations for sol in solutions], "Newton iterations"),
            Extra("solve_time_us", np.round(np.array(times) * 1e6, 1), "wall time of the solve"),
        ],
        metadata=provenance("softrod demo", d),
    )

    table = Table(
        title="tip positions (world frame; base at the origin, hanging along -z)",
        title_justify="left",
    )
    headers = [f"p{k}\nkPa" for k in range(d.n_channels)]
    headers += ["tip x\nmm", "tip y\nmm", "tip z\nmm", "lateral\nmm", "iter-\nations"]
    for name in [*headers, "solve\ntime µs"]:
        table.add_column(name, justify="right")
    for case, sol, lat, dt in zip(DEMO_CASES_KPA, solutions, lateral, times, strict=True):
        tip = sol.tip_position * 1e3
        table.add_row(
            *(f"{x:g}" for x in case),
            *(_fmt(x, 2) for x in tip),
            _fmt(lat * 1e3, 2),
            f"{sol.iterations}",
            f"{dt * 1e6:,.0f}",
        )
    console.print(table)

    out_dir.mkdir(parents=True, exist_ok=True)
    shapes = _write_shape_plot(solutions, out_dir / "shapes.png", title=f"{d.name}: static shapes")
    tips = write_table(frame, out_dir / "tips.csv")

    start, stop, count = DEMO_SWEEP
    grid = _full_factorial([np.linspace(start, stop, count)] * d.n_channels)
    batch, wall = _run_sweep(d, grid, 0, SWEEP_CHUNK, f"sweep {count}^{d.n_channels}")
    n_ok = int(batch.converged.sum())
    # The demo design hangs from the origin along -z: lateral reach is the distance from z.
    reach = np.hypot(batch.tip_position[:, 0], batch.tip_position[:, 1]) * 1e3
    console.print(
        f"sweep of {len(grid)} pressure combinations, {start / 1e3:g}-{stop / 1e3:g} "
        f"kPa per chamber: {n_ok} converged"
    )
    console.print(
        f"  {wall * 1e3:.0f} ms, [bold]{len(grid) / wall:,.0f} solves/s[/bold]; "
        f"lateral reach up to {np.nanmax(reach):.1f} mm"
    )
    _say(f"wrote {shapes}")
    _say(f"wrote {tips}")
