"""``softrod solve``, ``softrod sweep`` and ``softrod demo``: static equilibria of a design."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import click
import numpy as np
from rich.console import Console
from rich.progress import Progress
from rich.table import Table
from rich.text import Text

from ..catalog import load_design
from ..design import Design
from ..errors import InputError, design_error
from ..io import check_table_path, write_table
from ..statics import StaticSolution, solve_statics, solve_statics_batch
from ._common import (
    _fmt,
    _fmt_kpa,
    _fmt_vec,
    _for_option,
    _full_factorial,
    _handle_errors,
    _parse_grid,
    _parse_pressures,
    _parse_vector,
    _progress_columns,
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



def _lateral(sol: StaticSolution) -> float:
    """Tip distance from the base tangent line (the straight reference axis), m."""
    d = sol.tip_position - sol.position[0]
    t0 = sol.rotation[0][:, 2]
    return float(np.linalg.norm(d - np.dot(d, t0) * t0))


def _run_sweep(
    design: Design,
    pressures: np.ndarray,
    threads: int,
    chunk: int,
    console: Console,
    label: str,
    client=None,
) -> tuple[dict[str, np.ndarray], float]:
    """Solve every row in chunks under a progress bar; return (results, wall time s). With a
    Dask ``client`` the chunks run on its cluster (chunk size by softrod.cluster's rule)."""
    m = len(pressures)
    if client is not None:
        t0 = time.perf_counter()
        with Progress(*_progress_columns(), console=console) as progress:
            task = progress.add_task(label, total=m)
            out = solve_statics_batch(
                design,
                pressures,
                threads=threads,
                executor=client,
                progress=lambda done, _total: progress.update(task, completed=done),
            )
        wall = time.perf_counter() - t0
        res = {
            "tip_position": out.tip_position,
            "converged": out.converged,
            "iterations": out.iterations,
        }
        return res, wall
    tips = np.empty((m, 3))
    converged = np.empty(m, dtype=bool)
    iterations = np.empty(m, dtype=np.int64)
    t0 = time.perf_counter()
    with Progress(*_progress_columns(), console=console) as progress:
        task = progress.add_task(label, total=m)
        for lo in range(0, m, chunk):
            hi = min(lo + chunk, m)
            out = solve_statics_batch(design, pressures[lo:hi], threads=threads)
            tips[lo:hi] = out.tip_position
            converged[lo:hi] = out.converged
            iterations[lo:hi] = out.iterations
            progress.advance(task, hi - lo)
    wall = time.perf_counter() - t0
    return {"tip_position": tips, "converged": converged, "iterations": iterations}, wall


def _sweep_frame(pressures: np.ndarray, res: dict[str, np.ndarray]):
    import pandas as pd

    cols: dict[str, np.ndarray] = {}
    for k in range(pressures.shape[1]):
        cols[f"p{k + 1}_Pa"] = pressures[:, k]
    tips_mm = res["tip_position"] * 1e3
    cols["x_mm"], cols["y_mm"], cols["z_mm"] = tips_mm[:, 0], tips_mm[:, 1], tips_mm[:, 2]
    cols["converged"] = res["converged"]
    cols["iterations"] = res["iterations"]
    return pd.DataFrame(cols)


@click.command()
@click.argument("design")
@click.option(
    "--pressure",
    "-p",
    metavar="P1,P2,...",
    help="Gauge pressure per channel, comma-separated, e.g. 30kPa,0,0 or 0.3bar,0,0. "
    "A bare number is Pa; a unit on the last item alone applies to all. "
    "Default: 0 on every channel.",
)
@click.option(
    "--tip-force",
    metavar="FX,FY,FZ",
    help='Dead tip force in the world frame, e.g. "0,0,-1 N" (replaces the design\'s).',
)
@click.option(
    "--tip-moment",
    metavar="MX,MY,MZ",
    help='Dead tip moment in the world frame, e.g. "0,5,0 N*mm".',
)
@click.option("--json", "as_json", is_flag=True, help="Print a JSON object with SI values.")
@click.option(
    "--plot",
    "plot_path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the 3-D shape figure here (format from the suffix: .png, .pdf, .svg).",
)
@_handle_errors
def solve(design, pressure, tip_force, tip_moment, as_json, plot_path):
    """Static shape of DESIGN under the given chamber pressures."""
    d = load_design(design)
    if plot_path is not None:
        from ..plotting import check_figure_path

        _for_option(check_figure_path, plot_path, "--plot")
    p = _parse_pressures(pressure, d)
    tf = None if tip_force is None else _parse_vector(tip_force, "force", "--tip-force", 3)
    tm = None if tip_moment is None else _parse_vector(tip_moment, "moment", "--tip-moment", 3)
    t0 = time.perf_counter()
    sol = solve_statics(d, p, tip_force=tf, tip_moment=tm)
    elapsed = time.perf_counter() - t0

    if as_json:
        out = {
            "design": d.name,
            "pressures_Pa": [float(x) for x in p],
            "tip_position_m": sol.tip_position.tolist(),
            "tip_rotation": sol.tip_rotation.tolist(),
            "base_force_N": sol.base_force.tolist(),
            "base_moment_Nm": sol.base_moment.tolist(),
            "converged": bool(sol.converged),
            "iterations": int(sol.iterations),
            "residual": float(sol.residual),
            "shape": {"s_m": sol.s.tolist(), "position_m": sol.position.tolist()},
        }
        click.echo(json.dumps(out, indent=2))
    else:
        table = Table(title=f"{d.name}: static equilibrium", title_justify="left")
        table.add_column("quantity")
        table.add_column("value", justify="right")
        table.add_column("unit")
        table.add_row("pressures", _fmt_kpa(p), "kPa")
        table.add_row("tip position (x, y, z)", _fmt_vec(sol.tip_position, 1e3, 3), "mm")
        table.add_row("tip tangent d3", _fmt_vec(sol.tip_rotation[:, 2], 1.0, 4), "-")
        table.add_row("base force", _fmt_vec(sol.base_force, 1.0, 4), "N")
        table.add_row("base moment", _fmt_vec(sol.base_moment, 1e3, 3), "N mm")
        table.add_row("converged", "yes" if sol.converged else "no", "")
        table.add_row("iterations", f"{sol.iterations}", "")
        table.add_row("residual (scaled)", f"{sol.residual:.2e}", "")
        table.add_row("solve time", f"{elapsed * 1e6:,.0f}", "us")
        _stdout().print(table)

    if plot_path is not None:
        written = _write_shape_plot([sol], plot_path)
        # Keep stdout pure JSON with --json: say where the figure went on stderr instead.
        Console(stderr=as_json, highlight=False).print(Text(f"wrote {written}"), soft_wrap=True)


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
@_threads_option("Worker threads (0 = all cores; with --scheduler: per task, 0 = the "
                 "worker's share of its machine).")
@_scheduler_option("Run on the Dask cluster whose scheduler is at ADDRESS, e.g. "
                   "tcp://10.0.0.5:8786 (docs/cluster.md).")
@_handle_errors
def sweep(design, grids, out, threads, scheduler):
    """Tip positions over a full-factorial pressure grid of DESIGN.

    Rows run with channel 1 slowest and the last channel fastest, so consecutive rows are
    neighbours (warm starts). Columns: p1_Pa, p2_Pa, ..., x_mm, y_mm, z_mm, converged,
    iterations.
    """
    d = load_design(design)
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
    console.print(Text(f"{d.name}: {rows:,} rows ({' x '.join(str(len(a)) for a in axes)})"))
    with _scheduler(scheduler) as client:
        if client is not None:
            console.print(Text(f"on the Dask cluster at {scheduler}"), soft_wrap=True)
        res, wall = _run_sweep(d, pressures, threads, SWEEP_CHUNK, console, "sweep", client)
    write_table(_sweep_frame(pressures, res), out)
    n_ok = int(res["converged"].sum())
    style = "green" if n_ok == rows else "yellow"
    console.print(
        f"{rows:,} rows, [{style}]{n_ok:,} converged[/{style}], wall time {wall:.2f} s, "
        f"{rows / wall:,.0f} solves/s"
    )
    console.print(Text(f"wrote {out}"), soft_wrap=True)


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

    Writes shapes.png (the shapes in a 3-D view and a top view) and tips.csv to
    --out-dir.
    """
    import pandas as pd

    console = _stdout()
    d = load_design(DEMO_DESIGN)
    console.print(
        f"[bold]{d.name}[/bold]: {d.length * 1e3:.0f} mm, {d.n_channels} chambers, "
        f"hanging under gravity"
    )
    console.print(Text(d.citation, style="dim"))

    solutions, rows = [], []
    for case in DEMO_CASES_KPA:
        p = [1e3 * x for x in case]
        t0 = time.perf_counter()
        sol = solve_statics(d, p)
        dt = time.perf_counter() - t0
        solutions.append(sol)
        tip = sol.tip_position * 1e3
        rows.append(
            {
                **{f"p{k + 1}_kPa": float(case[k]) for k in range(len(case))},
                "x_mm": tip[0],
                "y_mm": tip[1],
                "z_mm": tip[2],
                "lateral_mm": _lateral(sol) * 1e3,
                "iterations": int(sol.iterations),
                "solve_time_us": round(dt * 1e6, 1),
            }
        )

    table = Table(
        title="tip positions (world frame; base at the origin, hanging along -z)",
        title_justify="left",
    )
    for name in (
        "p1\nkPa",
        "p2\nkPa",
        "p3\nkPa",
        "tip x\nmm",
        "tip y\nmm",
        "tip z\nmm",
        "lateral\nmm",
        "iter-\nations",
        "solve\ntime µs",
    ):
        table.add_column(name, justify="right")
    for r in rows:
        table.add_row(
            f"{r['p1_kPa']:g}",
            f"{r['p2_kPa']:g}",
            f"{r['p3_kPa']:g}",
            _fmt(r["x_mm"], 2),
            _fmt(r["y_mm"], 2),
            _fmt(r["z_mm"], 2),
            _fmt(r["lateral_mm"], 2),
            f"{r['iterations']}",
            f"{r['solve_time_us']:,.0f}",
        )
    console.print(table)

    out_dir.mkdir(parents=True, exist_ok=True)
    shapes = _write_shape_plot(solutions, out_dir / "shapes.png", title=f"{d.name}: static shapes")
    tips = write_table(pd.DataFrame(rows), out_dir / "tips.csv")

    start, stop, count = DEMO_SWEEP
    grid = _full_factorial([np.linspace(start, stop, count)] * d.n_channels)
    res, wall = _run_sweep(d, grid, 0, SWEEP_CHUNK, console, f"sweep {count}^{d.n_channels}")
    n_ok = int(res["converged"].sum())
    # The demo design hangs from the origin along -z: lateral reach is the distance from z.
    lateral = np.hypot(res["tip_position"][:, 0], res["tip_position"][:, 1]) * 1e3
    console.print(
        f"sweep of {len(grid)} pressure combinations, {start / 1e3:g}-{stop / 1e3:g} "
        f"kPa per chamber: {n_ok} converged"
    )
    console.print(
        f"  {wall * 1e3:.0f} ms, [bold]{len(grid) / wall:,.0f} solves/s[/bold]; "
        f"lateral reach up to {np.nanmax(lateral):.1f} mm"
    )
    console.print(Text(f"wrote {shapes}"), soft_wrap=True)
    console.print(Text(f"wrote {tips}"), soft_wrap=True)
