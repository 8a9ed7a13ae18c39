"""``softrod`` command line: solve one equilibrium, sweep a pressure grid, compare models on
a paper's experiments, calibrate parameters to measured tip positions, identify a design from
axial measurements, list designs and presets, run the demo.

Units at the boundary: pressures and loads are read with pint ("30kPa", "0.3bar", "-1 N");
a bare number is SI (Pa, N, N m). Outputs state their units (table headers, JSON keys,
column names such as ``x_mm``).

Exit codes: 0 success; 2 bad design, input or output path (also click's usage errors);
3 the solver did not converge. Errors print one red line ``error: <message>`` on stderr.
"""

from __future__ import annotations

import contextlib
import functools
import json
import math
import os
import re
import tempfile
import time
import warnings
from pathlib import Path

import click
import numpy as np
from rich.console import Console
from rich.padding import Padding
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    ProgressColumn,
    SpinnerColumn,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Table
from rich.text import Text

from . import __version__
from .design import Design, bundled_designs, load_design
from .errors import ConvergenceError, DesignError, InputError, design_error
from .io import check_table_path, write_table
from .statics import StaticSolution, solve_statics, solve_statics_batch
from .units import registry, to_si

MAX_SWEEP_ROWS = 10_000_000  # larger grids are refused (memory, and hours of compute)
SWEEP_CHUNK = 512  # rows per batch call: the progress bar advances per chunk
ATM = 101_325.0  # Pa; gauge pressures below -1 atm are impossible
DEMO_DESIGN = "spa_three_chamber_130mm"
DEMO_CASES_KPA = [(0, 0, 0), (35, 0, 0), (70, 0, 0), (70, 70, 0), (70, 70, 70)]
DEMO_SWEEP = (0.0, 70e3, 7)  # Pa, Pa, points per channel: a 7^3 grid


# --------------------------------------------------------------------------- helpers


def _stdout() -> Console:
    # Made per call so that it writes to the current sys.stdout (click's test runner swaps it).
    return Console(highlight=False)


def _fail(message: str, code: int) -> None:
    line = " ".join(str(message).split())  # one line, whatever the message contains
    err = Console(stderr=True, highlight=False, soft_wrap=True)
    err.print(Text(f"error: {line}", style="bold red"))
    raise click.exceptions.Exit(code)


def _handle_errors(func):
    """Turn softrod's exceptions into one red line and an exit code, never a traceback."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except ConvergenceError as exc:
            _fail(exc, 3)
        except DesignError as exc:  # includes InputError
            _fail(exc, 2)
        except OSError as exc:
            where = f" ({exc.filename})" if getattr(exc, "filename", None) else ""
            _fail(f"{exc.strerror or exc}{where}", 2)

    return wrapper


def _is_bare(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _parse_quantities(items: list[str], kind: str, fields: list[str]) -> list[float]:
    """SI values of quantity strings, with one shorthand and one safety rule.

    - If only the last item carries a unit, it applies to every item ("0,0,-1 N",
      "10,20,30kPa", and in grids "0:70kPa").
    - Otherwise every item stands alone and a bare number is SI; but a non-zero bare number
      next to items with units ("30kPa,5,0") is refused as ambiguous (5 Pa or 5 kPa?).
    """
    items = [t.strip() for t in items]
    for t, f in zip(items, fields, strict=True):
        if not t:
            raise design_error(f, t, f"is empty: give a {kind} such as '30kPa'", InputError)
    bare = [_is_bare(t) for t in items]
    if len(items) > 1 and not bare[-1] and all(bare[:-1]):
        to_si(items[-1], kind, fields[-1], InputError)  # a bad unit is named where it was given
        unit = registry().Quantity(items[-1]).units
        items = [f"{t} {unit}" if b else t for t, b in zip(items, bare, strict=True)]
    elif not all(bare):
        for t, b, f in zip(items, bare, fields, strict=True):
            if b and float(t) != 0.0:
                raise design_error(
                    f,
                    t,
                    "bare number next to values with units is ambiguous: give it a unit "
                    "(a unit on the last item alone applies to all items)",
                    InputError,
                )
    return [to_si(t, kind, f, InputError) for t, f in zip(items, fields, strict=True)]


def _parse_vector(text: str, kind: str, option: str, count: int) -> list[float]:
    items = text.split(",")
    if len(items) != count:
        raise design_error(option, text, f"give {count} comma-separated {kind} values", InputError)
    return _parse_quantities(items, kind, [f"{option}[{i}]" for i in range(count)])


def _parse_pressures(text: str | None, design: Design) -> list[float]:
    n = design.n_channels
    if text is None:
        return [0.0] * n
    items = text.split(",")
    if len(items) != n:
        raise design_error(
            "--pressure",
            text,
            f"design {design.name} has {n} pressure channel{'s' if n != 1 else ''}; give {n} "
            "comma-separated gauge pressures, e.g. " + ",".join(["30kPa"] + ["0"] * (n - 1)),
            InputError,
        )
    values = _parse_quantities(items, "pressure", [f"--pressure[{i}]" for i in range(n)])
    for i, p in enumerate(values):
        if p < -ATM:
            raise design_error(
                f"--pressure[{i}]",
                items[i].strip(),
                "gauge pressure must be >= -1 atm (-101325 Pa)",
                InputError,
            )
    return values


def _parse_span(text: str, option: str, form: str, check_n) -> tuple[float, float, int]:
    """START:STOP:N with pressures START and STOP -> (start Pa, stop Pa, N). ``form``: the rule
    when the text is not three parts; ``check_n(start, stop, n, raw)`` rejects a bad N (n = 0
    when ``raw`` is not an integer), before both ends are checked to be >= -1 atm."""
    parts = text.split(":")
    if len(parts) != 3:
        raise design_error(option, text, form, InputError)
    start, stop = _parse_quantities(parts[:2], "pressure", [f"{option}.start", f"{option}.stop"])
    try:
        n = int(parts[2])
    except ValueError:
        n = 0
    check_n(start, stop, n, parts[2])
    for name, value, raw in (
        (f"{option}.start", start, parts[0]),
        (f"{option}.stop", stop, parts[1]),
    ):
        if value < -ATM:
            raise design_error(
                name, raw.strip(), "gauge pressure must be >= -1 atm (-101325 Pa)", InputError
            )
    return start, stop, n


def _parse_grid(text: str, option: str = "--grid") -> np.ndarray:
    """START:STOP:COUNT -> COUNT evenly spaced pressures in Pa (both ends included)."""

    def check_count(start: float, stop: float, count: int, raw: str) -> None:
        if count < 1:
            raise design_error(f"{option}.count", raw, "must be an integer >= 1", InputError)
        if count == 1 and start != stop:
            raise design_error(
                f"{option}.count",
                raw,
                "COUNT = 1 needs START = STOP (or give COUNT >= 2)",
                InputError,
            )

    start, stop, count = _parse_span(
        text, option, "must read START:STOP:COUNT, e.g. 0:70kPa:21", check_count
    )
    return np.linspace(start, stop, count)


def _full_factorial(axes: list[np.ndarray]) -> np.ndarray:
    """All combinations, channel 0 slowest and the last channel fastest (C order)."""
    mesh = np.meshgrid(*axes, indexing="ij")
    return np.stack([m.ravel() for m in mesh], axis=1)


def _fmt(x: float, digits: int) -> str:
    # round first, then + 0.0 turns the -0.0 of tiny negative values into 0.0
    return f"{round(float(x), digits) + 0.0:.{digits}f}"


def _fmt_vec(v, scale: float = 1.0, digits: int = 3) -> str:
    return "(" + ", ".join(_fmt(x * scale, digits) for x in v) + ")"


def _fmt_kpa(pressures) -> str:
    return ", ".join(f"{p / 1e3:g}" for p in pressures)


def _lateral(sol: StaticSolution) -> float:
    """Tip distance from the base tangent line (the straight reference axis), m."""
    d = sol.tip_position - sol.position[0]
    t0 = sol.rotation[0][:, 2]
    return float(np.linalg.norm(d - np.dot(d, t0) * t0))


def _for_option(check, path: Path, option: str) -> Path:
    """Run a path check; name the command-line option in the error instead of 'path'."""
    try:
        return check(path)
    except InputError as exc:
        raise design_error(option, str(path), exc.rule, InputError) from None


def _pyplot():
    # The CLI only writes files, never opens windows: the non-interactive Agg backend works
    # with and without a display. Selected here, never when the library is imported.
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _write_shape_plot(solutions, path: Path, title: str | None = None) -> Path:
    plt = _pyplot()
    from .plotting import plot_shape, save_figure

    fig = plot_shape(solutions, title=title)
    try:
        return save_figure(fig, path)
    finally:
        plt.close(fig)


class _RateColumn(ProgressColumn):
    """Rows per second of a progress task."""

    def render(self, task) -> Text:
        # The mean rate since the start: steadier than rich's windowed estimate, and defined
        # after a single advance (a sweep of one chunk).
        elapsed = task.elapsed
        if not elapsed or not task.completed:
            return Text("-- rows/s", style="cyan")
        return Text(f"{task.completed / elapsed:,.0f} rows/s", style="cyan")


def _progress_columns() -> tuple:
    return (  # fits in 80 columns
        TextColumn("[bold]{task.description}"),
        BarColumn(bar_width=24),
        MofNCompleteColumn(),
        _RateColumn(),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
    )


def _run_sweep(
    design: Design, pressures: np.ndarray, threads: int, chunk: int, console: Console, label: str
) -> tuple[dict[str, np.ndarray], float]:
    """Solve every row in chunks under a progress bar; return (results, wall time s)."""
    m = len(pressures)
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


def _threads_option(help_text: str):
    """The ``--threads`` option of the commands that solve batches (0 = all cores)."""
    return click.option(
        "--threads", default=0, show_default=True, type=click.IntRange(min=0), help=help_text
    )


# --------------------------------------------------------------------------- commands


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, "--version", prog_name="softrod", message="%(prog)s %(version)s")
def main():
    """softrod: Cosserat-rod models of soft pneumatic actuators.

    DESIGN arguments are a TOML file or the name of a bundled design (see `softrod designs`).
    Quantities take units ("30kPa", "0.3bar", "-1 N"); a bare number is SI.
    Exit codes: 0 ok, 2 bad design or input, 3 no convergence.
    """


@main.command()
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
        from .plotting import check_figure_path

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


@main.command()
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
@_threads_option("Worker threads (0 = all cores).")
@_handle_errors
def sweep(design, grids, out, threads):
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
    res, wall = _run_sweep(d, pressures, threads, SWEEP_CHUNK, console, "sweep")
    write_table(_sweep_frame(pressures, res), out)
    n_ok = int(res["converged"].sum())
    style = "green" if n_ok == rows else "yellow"
    console.print(
        f"{rows:,} rows, [{style}]{n_ok:,} converged[/{style}], wall time {wall:.2f} s, "
        f"{rows / wall:,.0f} solves/s"
    )
    console.print(Text(f"wrote {out}"), soft_wrap=True)


@main.command()
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

    Writes shapes.png (all shapes in one 3-D figure) and tips.csv to --out-dir.
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


def _parse_ramp(text: str, option: str = "--pressure-ramp") -> np.ndarray:
    """START:STOP:STEPS -> STEPS + 1 pressure levels in Pa (STEPS equal steps, both ends)."""
    from .compare import MAX_RAMP_STEPS, pressure_ramp

    def check_steps(start: float, stop: float, steps: int, raw: str) -> None:
        if not 1 <= steps <= MAX_RAMP_STEPS:
            raise design_error(
                f"{option}.steps", raw, f"must be an integer in [1, {MAX_RAMP_STEPS}]", InputError
            )

    start, stop, steps = _parse_span(
        text,
        option,
        "must read START:STOP:STEPS, e.g. '0 bar:0.6 bar:30' (STEPS equal steps, STEPS + 1 levels)",
        check_steps,
    )
    return pressure_ramp(start, stop, steps)


def _renamed(option: str, func, *args):
    """Call func; name the command-line option in an InputError instead of the API field."""
    try:
        return func(*args)
    except InputError as exc:
        raise design_error(option, exc.value, exc.rule, InputError) from None


def _on_chambers(exp) -> str:
    """'1, 2' for an experiment that ramps chambers 1 and 2."""
    return ", ".join(str(k + 1) for k, w in enumerate(exp.weights) if w)


def _parse_models(text: str) -> list[str]:
    from .presets import PAPER002_MODELS

    names = [m.strip() for m in text.split(",")]
    for name in names:
        if name not in PAPER002_MODELS:
            raise design_error(
                "--models",
                name,
                f"unknown model: give a comma-separated list of {', '.join(PAPER002_MODELS)} "
                "(paper 002 Table IV)",
                InputError,
            )
    if len(set(names)) != len(names):
        raise design_error("--models", text, "names a model twice", InputError)
    return names


@main.command()
@click.argument(
    "protocol",
    type=click.Choice(["paper002"]),
    default="paper002",
    required=False,
    metavar="[PROTOCOL]",
)
@click.option(
    "--models",
    default="M0,M1,M2,M3",
    show_default=True,
    metavar="M0,M1,...",
    help="Comma-separated models of paper 002 Table IV (the paper002_<M>_<mounting> presets).",
)
@click.option(
    "--experiments",
    default="all",
    show_default=True,
    metavar="NAMES",
    help="Comma-separated experiments of paper 002 Sec. V: i-1, i-2, i-3 (one chamber), "
    "ii-1, ii-2, ii-3 (all but chamber k), iii (all three), a (horizontal, chamber 1); "
    "groups i, ii, vertical, horizontal, all.",
)
@click.option(
    "--pressure-ramp",
    "ramp",
    default="0 bar:0.6 bar:30",
    show_default=True,
    metavar="START:STOP:STEPS",
    help="Ramp of the pressure p in STEPS equal steps (STEPS + 1 levels); a unit on STOP "
    "alone applies to both ends.",
)
@click.option(
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the table here, .csv or .parquet (written whole or not at all).",
)
@click.option(
    "--figure",
    "figure_path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the figure here (tip x, y, z vs p per experiment; .png, .pdf, .svg).",
)
@_threads_option("Worker threads per batch (0 = all cores).")
@_handle_errors
def compare(protocol, models, experiments, ramp, out, figure_path, threads):
    """Compare models on the experiments of a paper (PROTOCOL: paper002, the default).

    paper002 (Sec. V): every experiment ramps p on some chambers of the 134 mm actuator and
    each (model, experiment) pair is one ordered batch solve. Tip coordinates are reported
    in the paper's frame e_i (paper_x_mm, ...) and in softrod's world frame (world_x_mm, ...);
    see docs/compare.md for all columns.
    """
    from .compare import EXPERIMENTS, compare_models, resolve_experiments

    names = _parse_models(models)
    exps = _renamed("--experiments", resolve_experiments, experiments)
    levels = _parse_ramp(ramp)
    if out is not None:
        out = _for_option(check_table_path, out, "--out")
    if figure_path is not None:
        from .plotting import check_figure_path

        figure_path = _for_option(check_figure_path, figure_path, "--figure")

    console = _stdout()
    rows = len(names) * len(exps) * len(levels)
    console.print(
        Text(
            f"{protocol}: {len(names)} model{'s' if len(names) != 1 else ''} x {len(exps)} "
            f"experiment{'s' if len(exps) != 1 else ''} x {len(levels)} levels "
            f"({levels[0] / 1e3:g} to {levels[-1] / 1e3:g} kPa) = {rows:,} solves"
        )
    )
    t0 = time.perf_counter()
    with Progress(*_progress_columns(), console=console) as progress:
        task = progress.add_task("compare", total=rows)

        def advance(label: str, n: int) -> None:
            progress.update(task, advance=n, description=f"compare {label}")

        df = compare_models(
            names, experiments=exps, pressures=levels, threads=threads, progress=advance
        )
        progress.update(task, description="compare")
    wall = time.perf_counter() - t0

    table = Table(
        title=f"tip at p = {levels[-1] / 1e3:g} kPa, paper frame e_i (mm)",
        title_justify="left",
        caption="i-k, ii-k, iii: vertical mounting; a: horizontal (paper 002 Sec. V)",
        caption_justify="left",
    )
    for name, justify in (
        ("experi-\nment", "left"),
        ("chambers\nat p", "left"),
        ("model", "left"),
        ("x\nmm", "right"),
        ("y\nmm", "right"),
        ("z\nmm", "right"),
        ("lateral\nmm", "right"),
        ("converged", "right"),
    ):
        table.add_column(name, justify=justify)
    for exp in exps:
        sub = df[df["experiment"] == exp]
        for k, model in enumerate(names):
            r = sub[sub["model"] == model]
            last = r.iloc[-1]
            x, y, z = (float(last[f"paper_{a}_mm"]) for a in "xyz")
            table.add_row(
                exp if k == 0 else "",
                _on_chambers(EXPERIMENTS[exp]) if k == 0 else "",
                model,
                _fmt(x, 2),
                _fmt(y, 2),
                _fmt(z, 2),
                _fmt(math.hypot(x, y), 2),  # distance from the clamp axis e3
                f"{int(r['converged'].sum())}/{len(r)}",
                end_section=k == len(names) - 1,
            )
    console.print(table)
    n_ok = int(df["converged"].sum())
    style = "green" if n_ok == rows else "yellow"
    console.print(f"{rows:,} solves, [{style}]{n_ok:,} converged[/{style}], wall time {wall:.2f} s")
    if out is not None:
        write_table(df, out)
        console.print(Text(f"wrote {out}"), soft_wrap=True)
    if figure_path is not None:
        plt = _pyplot()
        from .compare import plot_comparison
        from .plotting import save_figure

        fig = plot_comparison(
            df, title=f"{protocol}: tip position vs pressure, models {', '.join(names)}"
        )
        try:
            save_figure(fig, figure_path)
        finally:
            plt.close(fig)
        console.print(Text(f"wrote {figure_path}"), soft_wrap=True)


# --------------------------------------------------------------------------- calibration

# Calibrated values are shown in these units (SI in the JSON and the TOML).
_DISPLAY_UNITS = {"Pa": ("kPa", 1e-3), "m": ("mm", 1e3), "1": ("-", 1.0)}
# calibrate()'s argument names -> the options that set them (for error messages).
_CALIBRATE_OPTIONS = {
    "params": "--params",
    "split": "--split",
    "test": "--test",
    "method": "--method",
    "threads": "--threads",
}


def _check_output(path: Path, option: str, suffixes: tuple[str, ...], what: str) -> Path:
    """Fail fast on an output path (suffix, existing folder), before a long computation."""
    if path.suffix.lower() not in suffixes:
        raise design_error(
            option,
            str(path),
            f"{what}: the file name must end in {' or '.join(suffixes)}",
            InputError,
        )
    if not path.parent.is_dir():
        raise design_error(
            option, str(path), f"folder {str(path.parent)!r} does not exist", InputError
        )
    return path


@contextlib.contextmanager
def _staged(paths: list[Path]):
    """Yield a temporary path per destination (same file name, in a hidden folder beside it).
    When the block succeeds every file is moved into place; when it fails none is, and the
    destinations are left as they were: several outputs are written all or none."""
    with contextlib.ExitStack() as stack:
        staged = []
        for path in paths:
            folder = stack.enter_context(
                tempfile.TemporaryDirectory(dir=path.parent, prefix=f".{path.name}.")
            )
            staged.append(Path(folder) / path.name)
        yield staged
        for tmp, path in zip(staged, paths, strict=True):
            os.replace(tmp, path)


def _as_option(exc: InputError, renames: dict[str, str], values: dict[str, str] | None = None):
    """The error with the command-line option in place of the API field it names (others
    unchanged); ``values`` replaces the value by what was typed for that option."""
    option = renames.get(exc.field)
    if option is None:
        return exc
    value = (values or {}).get(exc.field, exc.value)
    return design_error(option, value, exc.rule, InputError)


def _parse_bounds(items: tuple[str, ...], params) -> tuple[dict, dict[str, str]]:
    """NAME=LO:HI items -> ({name: (lo, hi) in SI}, {"bounds[name]": the item as typed}).

    LO and HI take units ("E=40kPa:200kPa"; a unit on HI alone applies to both, "E=40:200kPa");
    a bare number is SI. Dimensionless parameters take plain numbers."""
    kinds = {"Pa": "pressure", "m": "length"}
    by_name = {p.name: p for p in params}
    bounds: dict[str, tuple[float, float]] = {}
    typed: dict[str, str] = {}
    for item in items:
        name, sep, span = item.partition("=")
        name = name.strip()
        parts = span.split(":")
        if not sep or not name or len(parts) != 2 or not all(x.strip() for x in parts):
            raise design_error(
                "--bounds",
                item,
                "must read NAME=LO:HI, e.g. c_b=0.5:3 or E=40kPa:200kPa",
                InputError,
            )
        if name not in by_name:
            raise design_error(
                "--bounds",
                item,
                f"{name!r} is not one of the calibrated --params ({', '.join(by_name)})",
                InputError,
            )
        if name in bounds:
            raise design_error("--bounds", item, f"gives {name} twice", InputError)
        unit = by_name[name].unit
        fields = [f"--bounds {name}.lower", f"--bounds {name}.upper"]
        if unit in kinds:
            lo, hi = _parse_quantities(parts, kinds[unit], fields)
        else:
            vals = []
            for x, f in zip(parts, fields, strict=True):
                if not _is_bare(x):
                    raise design_error(
                        f, x.strip(), f"must be a number ({name} is dimensionless)", InputError
                    )
                vals.append(float(x))
            lo, hi = vals
        bounds[name] = (lo, hi)
        typed[f"bounds[{name}]"] = item
    return bounds, typed


def _parse_test_ids(text: str | None, split: str | None, dataset) -> list | None:
    """--test ids (None: calibrate's default); numeric ones become ints when the dataset's
    experiment ids are integers. Checks that the --split column exists."""
    if split is not None and getattr(dataset, split) is None:
        raise design_error(
            "--split", split, f"the dataset has no {split} column to split by", InputError
        )
    if text is None:
        if split == "mounting":
            known = ", ".join(dict.fromkeys(dataset.mounting.tolist()))
            raise design_error(
                "--test", None, f"name the test mounting(s) (the dataset has {known})", InputError
            )
        return None
    if split is None:
        raise design_error(
            "--test", text, "needs --split experiment or --split mounting", InputError
        )
    ids: list = [t.strip() for t in text.split(",")]
    if not all(ids):
        raise design_error("--test", text, "give comma-separated ids, e.g. 3 or 3,4", InputError)
    labels = getattr(dataset, split)
    if labels is not None and labels.dtype.kind in "iu":
        ids = [int(t) if re.fullmatch(r"[+-]?[0-9]+", t) else t for t in ids]
    return ids


class _FitProgress:
    """The live line of a fit on stderr: model evaluations and the RMS tip error (current
    and best). ``on_start`` runs at the first evaluation, so an input error found before the
    fit prints nothing else. The line shows only on a terminal and disappears at the end (a
    summary line follows); redirected, stderr stays empty."""

    def __init__(self, on_start=None, console: Console | None = None) -> None:
        self._console = console or Console(stderr=True, highlight=False)
        self._progress: Progress | None = None
        self._task = None
        self._on_start = on_start
        self.evaluations = 0
        self.best = math.inf

    def __call__(self, evaluations: int, rms_mm: float) -> None:
        if self._on_start is not None:
            self._on_start()
            self._on_start = None
        self.evaluations = evaluations
        if math.isfinite(rms_mm):
            self.best = min(self.best, rms_mm)
        if not self._console.is_terminal:
            return
        if self._progress is None:
            self._progress = Progress(
                SpinnerColumn(),
                TextColumn("[bold]calibrate[/bold] {task.fields[evaluations]} evaluations"),
                TextColumn("RMS tip error {task.fields[rms]} mm (best {task.fields[best]} mm)"),
                TimeElapsedColumn(),
                console=self._console,
                transient=True,
            )
            self._task = self._progress.add_task(
                "calibrate", total=None, evaluations=0, rms="--", best="--"
            )
            self._progress.start()
        self._progress.update(
            self._task,
            evaluations=evaluations,
            rms=f"{rms_mm:.3g}",
            best=f"{self.best:.3g}",
        )

    def __enter__(self) -> _FitProgress:
        return self

    def __exit__(self, *exc) -> None:
        if self._progress is not None:
            self._progress.stop()


def _num(x: float, scale: float = 1.0, digits: int = 6) -> str:
    x = float(x)
    if math.isnan(x):
        return "n/a"
    if math.isinf(x):
        return "inf"
    return f"{x * scale:.{digits}g}"


def _parameter_table(result) -> Table:
    table = Table(title="calibrated parameters", title_justify="left")
    for name, justify in (
        ("parameter", "left"),
        ("initial", "right"),
        ("value", "right"),
        ("std error", "right"),
        ("std error\n% of value", "right"),
        ("unit", "left"),
    ):
        table.add_column(name, justify=justify)
    for row in result.parameter_table().itertuples(index=False):
        unit, scale = _DISPLAY_UNITS.get(row.unit, (row.unit, 1.0))
        table.add_row(
            Text(row.parameter),
            _num(row.initial, scale),
            _num(row.value, scale),
            _num(row.std_error, scale, 3),
            "n/a" if not math.isfinite(row.rel_std_error_pct) else f"{row.rel_std_error_pct:.3g}",
            unit,
        )
    return table


def _error_table(result) -> Table:
    length_mm = result.design.length * 1e3
    table = Table(
        title=f"tip errors (Euclidean; % of the length L = {length_mm:.4g} mm)",
        title_justify="left",
    )
    columns = (
        ("set", "left", "set", None),
        ("n", "right", "n", None),
        ("failed", "right", "failed", None),
        ("mean\nmm", "right", "mean_error_mm", 3),
        ("median\nmm", "right", "median_error_mm", 3),
        ("max\nmm", "right", "max_error_mm", 3),
        ("RMS\nmm", "right", "rms_error_mm", 3),
        ("mean\n% of L", "right", "mean_error_pct_L", 2),
        ("max\n% of L", "right", "max_error_pct_L", 2),
    )
    for header, justify, _, _ in columns:
        table.add_column(header, justify=justify)
    for row in result.error_table.to_dict(orient="records"):
        cells = []
        for _, _, key, digits in columns:
            v = row[key]
            if digits is None:
                cells.append(Text(str(v)))
            else:
                cells.append("n/a" if not math.isfinite(v) else _fmt(v, digits))
        table.add_row(*cells)
    return table


def _print_warnings(console: Console, messages: list[str]) -> None:
    for message in messages:
        console.print(Text(f"warning: {message}", style="bold yellow"))


@main.command()
@click.argument("design")
@click.argument("data")
@click.option(
    "--params",
    required=True,
    metavar="NAMES",
    help="Comma-separated parameters to fit, e.g. c_b,c_e,alpha; a selector names sections or "
    "a material: c_b[cap_a,cap_c], E[ecoflex_00_50]. Kinds: c_s, c_e, c_b, c_t, E, alpha, c_p, "
    "offset_1, offset_2, area_scale, sigma_ext, sigma_bend_1, sigma_bend_2 "
    "(docs/calibration.md).",
)
@click.option(
    "--split",
    type=click.Choice(["experiment", "mounting"]),
    help="Hold out a test set by the dataset's experiment or mounting column "
    "(default: fit on all rows).",
)
@click.option(
    "--test",
    "test_ids",
    metavar="ID[,ID...]",
    help="The test experiment(s) or mounting(s) with --split (default with --split "
    "experiment: the last experiment).",
)
@click.option(
    "--method",
    type=click.Choice(["lm", "nelder-mead"]),
    default="lm",
    show_default=True,
    help="lm: Levenberg-Marquardt with the exact Jacobian (trust-region reflective with "
    "--bounds); nelder-mead: paper 002's simplex, no derivatives.",
)
@click.option(
    "--bounds",
    "bounds_items",
    multiple=True,
    metavar="NAME=LO:HI",
    help='Bounds of one parameter, e.g. c_b=0.5:3 or "E=40kPa:200kPa" (a unit on HI alone '
    "applies to both; a bare number is SI). Repeat for several parameters.",
)
@click.option(
    "--max-evaluations",
    default=200,
    show_default=True,
    type=click.IntRange(min=1),
    help="Stop after this many model evaluations (one evaluation solves every training row).",
)
@click.option(
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the calibrated design here (.toml; fitted values noted in its assumptions).",
)
@click.option(
    "--report",
    "report_path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write an HTML report here (.html: tables, correlations, figures).",
)
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="Print the parameter and error tables as JSON (SI values) instead of tables.",
)
@_threads_option("Worker threads per model evaluation (0 = all cores).")
@_handle_errors
def calibrate(
    design,
    data,
    params,
    split,
    test_ids,
    method,
    bounds_items,
    max_evaluations,
    out,
    report_path,
    as_json,
    threads,
):
    """Fit parameters of DESIGN to the measured tip positions in DATA.

    DATA is a dataset table (.csv or .parquet, docs/datasets.md) with one chamber pressure
    column per channel of DESIGN. Prints the fitted values with standard errors, the tip
    errors on the training and test sets, and warnings about parameters that the data
    cannot determine. Every output file is written whole or not at all.
    """
    from .calibration.fit import CalibrationWarning, result_json
    from .calibration.fit import calibrate as fit
    from .calibration.params import SIGMA_KINDS, parse_parameters
    from .calibration.report import REPORT_SUFFIXES
    from .datasets import load_dataset

    d = load_design(design)
    parsed = _renamed("--params", parse_parameters, params, d)
    bounds, typed = _parse_bounds(bounds_items, parsed)
    sigma = [p.name for p in parsed if p.kind in SIGMA_KINDS]
    outputs = []
    if out is not None:
        out = _check_output(out, "--out", (".toml",), "a design file")
        if sigma:
            raise design_error(
                "--out",
                str(out),
                f"cannot hold {', '.join(sigma)}: sigma factors scale each solve and are not "
                "part of a design (fit c_e and c_b instead, or drop --out)",
                InputError,
            )
        outputs.append(out)
    if report_path is not None:
        report_path = _check_output(report_path, "--report", REPORT_SUFFIXES, "a report is HTML")
        outputs.append(report_path)
    try:
        dataset = load_dataset(data, design=d)
    except InputError as exc:
        raise _as_option(exc, {"path": "DATA"}) from None
    test = _parse_test_ids(test_ids, split, dataset)

    note = Console(stderr=True, highlight=False) if as_json else _stdout()

    def header() -> None:  # once the fit runs (the inputs have passed calibrate's checks)
        if not as_json:
            src = Path(data).name + (" (SYNTHETIC)" if dataset.synthetic else "")
            note.print(
                Text(
                    f"calibrate {', '.join(p.name for p in parsed)} of {d.name} on {src}: "
                    f"{len(dataset)} samples, method {method}"
                ),
                soft_wrap=True,
            )

    renames = {**_CALIBRATE_OPTIONS, **{k: "--bounds" for k in typed}}
    with warnings.catch_warnings(record=True) as caught:
        # Record calibration warnings whatever the filters (print them once, below); others
        # keep the caller's filters and are passed on after the fit.
        warnings.simplefilter("always", CalibrationWarning)
        try:
            with _FitProgress(header) as progress:
                result = fit(
                    d,
                    dataset,
                    params,
                    bounds=bounds or None,
                    method=method,
                    split=split,
                    test=test,
                    threads=threads,
                    max_evaluations=max_evaluations,
                    progress=progress,
                )
        except InputError as exc:
            raise _as_option(exc, renames, typed) from None
    found = [str(w.message) for w in caught if issubclass(w.category, CalibrationWarning)]
    for w in caught:
        if not issubclass(w.category, CalibrationWarning):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)

    if as_json:
        click.echo(result_json(result))
    else:
        style = "green" if result.success else "yellow"
        note.print(
            Text.assemble(
                (f"{result.method}: ", style),
                f"{result.evaluations} model evaluations, {result.elapsed_s:.2f} s; ",
                (result.message, style),
            ),
            soft_wrap=True,
        )
        note.print(_parameter_table(result))
        note.print(_error_table(result))
    _print_warnings(note, found)

    if outputs:
        with _staged(outputs) as staged:
            for tmp, path in zip(staged, outputs, strict=True):
                if path == out:
                    result.to_toml(tmp)
                else:
                    result.write_report(tmp)
        for path in outputs:
            note.print(Text(f"wrote {path}"), soft_wrap=True)


@main.command("calibrate-axial")
@click.argument("force_csv")
@click.argument("length_csv")
@click.option(
    "--design",
    "base",
    required=True,
    metavar="BASE",
    help="The design whose chambered sections get the identified stiffness and chamber area "
    "(a TOML file or a bundled name, e.g. modular_two_module).",
)
@click.option(
    "--chambers",
    default=3,
    show_default=True,
    type=click.IntRange(min=1),
    help="Chambers pressurised together in the measurements.",
)
@click.option(
    "--stiffness",
    type=click.Choice(["constant", "table"]),
    default="constant",
    show_default=True,
    help="constant: one extensional stiffness E; table: E(F) = 1/(c1 + c2 F) from a "
    "quadratic stretch curve.",
)
@click.option(
    "--force-law",
    type=click.Choice(["proportional", "affine"]),
    default="proportional",
    show_default=True,
    help="Blocked force F = k p, or F = k p + b (b reported as a set-up offset).",
)
@click.option(
    "--L0",
    "L0",
    metavar="LENGTH",
    help='Unpressurised length of what LENGTH_CSV measures, e.g. "44.8 mm" (default: fitted).',
)
@click.option(
    "--rigid-length",
    default="0",
    show_default=True,
    metavar="LENGTH",
    help='Stiff parts (end caps) included in the measured length, e.g. "4 mm".',
)
@click.option("--name", help="Name of the new design (default: <BASE>_axial).")
@click.option(
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the identified design here (.toml; written whole or not at all).",
)
@_handle_errors
def calibrate_axial(
    force_csv, length_csv, base, chambers, stiffness, force_law, L0, rigid_length, name, out
):
    """Identify chamber area and axial/bending stiffness from axial measurements (paper 004).

    FORCE_CSV: blocked force at the reference length, columns "pressure [kPa]" and
    "force [N]"; LENGTH_CSV: free elongation, "pressure [kPa]" and "length [mm]" (any
    pint unit; docs/calibration-axial.md). Prints the identified values with standard errors
    and builds a design from BASE with them.
    """
    from .calibration.axial import calibrate_axial as identify

    d = load_design(base)
    if out is not None:
        out = _check_output(out, "--out", (".toml",), "a design file")
    renames = {
        "L0": "--L0",
        "rigid_length": "--rigid-length",
        "n_chambers": "--chambers",
        "base_design": "--design",
        "out_path": "--out",
    }
    try:
        result, new = identify(
            force_csv,
            length_csv,
            d,
            out,
            n_chambers=chambers,
            L0=L0,
            rigid_length=rigid_length,
            force_law=force_law,
            stiffness=stiffness,
            name=name,
        )
    except InputError as exc:
        if exc.field == "path":  # a data file that cannot be read: name the argument
            renames["path"] = "FORCE_CSV" if exc.value == str(Path(force_csv)) else "LENGTH_CSV"
        raise _as_option(exc, renames) from None
    console = _stdout()
    console.print(Text(result.summary()), soft_wrap=True)
    console.print(Text(f"design {new.name} (from {d.name})"), soft_wrap=True)
    if out is not None:
        console.print(Text(f"wrote {out}"), soft_wrap=True)
    else:
        console.print(Text("not written: give --out design.toml to write it"), style="dim")


@main.command()
@click.argument("design")
@click.argument("data", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--sections",
    help="Comma-separated names of the sections sigma scales (default: the chambered "
    "elastic sections, as paper 001 scales its body).",
)
@click.option(
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the identified factors per sample here (.csv or .parquet).",
)
@click.option(
    "--report",
    "report_path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write an HTML report here (factors over the workspace, paper 001 Fig. 5).",
)
@_threads_option("Worker threads per core call (0 = all cores).")
@_handle_errors
def identify(design, data, sections, out, report_path, threads):
    """Identify the stiffness factors sigma of every sample in DATA (paper 001 eqs. 14-22).

    For each measured pose: sigma = (sigma_ext, sigma_bend_x, sigma_bend_y) that puts the
    model tip on the measured tip. A factor the pose cannot determine (deflection near a
    principal axis) is left empty and flagged. docs/calibration-per-sample.md.
    """
    from .calibration.per_sample import identify_stiffness, stiffness_mapped_design
    from .calibration.report import REPORT_SUFFIXES
    from .datasets import load_dataset
    from .io import TABLE_SUFFIXES

    d = load_design(design)
    outputs = []
    if out is not None:
        outputs.append(_check_output(out, "--out", TABLE_SUFFIXES, "a table"))
    if report_path is not None:
        outputs.append(_check_output(report_path, "--report", REPORT_SUFFIXES, "a report is HTML"))
    try:
        dataset = load_dataset(data, design=d)
    except InputError as exc:
        raise _as_option(exc, {"path": "DATA"}) from None
    names = None if sections is None else [n.strip() for n in sections.split(",") if n.strip()]
    try:  # check the sections before the progress bar starts
        stiffness_mapped_design(d, names)
    except InputError as exc:
        raise _as_option(exc, {"sections": "--sections"}) from None
    console = _stdout()
    with Progress(*_progress_columns(), console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task("identify", total=len(dataset))

        def progress(iteration: int, active: int, total: int) -> None:
            bar.update(task, completed=total - active, description=f"iteration {iteration}")

        result = identify_stiffness(d, dataset, sections=names, threads=threads, progress=progress)
    table = Table(show_header=False, box=None, padding=(0, 2))
    for key, value in result.summary().items():
        table.add_row(str(key), f"{value:.4g}" if isinstance(value, float) else str(value))
    console.print(table)
    if outputs:
        with _staged(outputs) as staged:
            k = 0
            if out is not None:
                write_table(result.to_frame(), staged[k])
                k += 1
            if report_path is not None:
                result.write_report(staged[k])
        for path in outputs:
            console.print(Text(f"wrote {path}"), soft_wrap=True)


@main.command()
@_handle_errors
def designs():
    """List the bundled designs and the presets with their channel count and source."""
    from .presets import list_presets

    console = _stdout()
    console.print(Text("bundled designs (use the name as DESIGN):", style="bold"))
    for name in bundled_designs():
        _list_design(console, name, lambda d: d.citation)
    console.print()
    console.print(
        Text(
            "presets (published models built from a bundled design; use the name as DESIGN):",
            style="bold",
        )
    )
    summaries = {p.name: p.summary for p in list_presets()}
    for name, summary in summaries.items():
        _list_design(console, name, lambda d, s=summary: s)


def _list_design(console: Console, name: str, note) -> None:
    try:
        d = load_design(name)
    except DesignError as exc:
        console.print(Text(name, style="bold"), Text(f"cannot load: {exc}", style="red"))
        return
    n = d.n_channels
    console.print(
        Text.assemble(
            (name, "bold cyan"),
            f"  {n} channel{'s' if n != 1 else ''}, {d.length * 1e3:.1f} mm",
        )
    )
    console.print(Padding(Text(note(d), style="dim"), (0, 0, 0, 4)))


def _register_simulate() -> None:
    import sys

    from .cli_simulate import add_simulate_command

    add_simulate_command(main, sys.modules[__name__])


_register_simulate()

from .cli_pcc import add_pcc_commands  # noqa: E402

add_pcc_commands(main)


if __name__ == "__main__":  # pragma: no cover
    main()
