"""``softrod compare``: several models on the experiments of a paper (paper 002 Sec. V)."""

from __future__ import annotations

import time
from pathlib import Path

import click

from ..errors import InputError, design_error
from ._common import (
    _fmt,
    _for_option,
    _handle_errors,
    _parse_span,
    _progress,
    _pyplot,
    _renamed,
    _say,
    _stdout,
    _threads_option,
)


def _parse_ramp(text: str, option: str = "--pressure-ramp"):
    """START:STOP:STEPS -> STEPS + 1 pressure levels in Pa (STEPS equal steps, both ends)."""
    from ..compare import MAX_RAMP_STEPS, pressure_ramp

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


def _on_chambers(exp) -> str:
    """'p0,p1' for an experiment that ramps channels 0 and 1."""
    return ",".join(f"p{k}" for k, w in enumerate(exp.weights) if w)


def _parse_models(text: str) -> list[str]:
    from ..presets import PAPER002_MODELS

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


@click.command()
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
    help="Comma-separated experiments of paper 002 Sec. V: i-0, i-1, i-2 (channel k alone), "
    "ii-0, ii-1, ii-2 (all but channel k), iii (all three), a (horizontal, channel 0); "
    "groups i, ii, vertical, horizontal, all. Channels count from 0: paper 002's chamber 1 "
    "is p0.",
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
    each (model, experiment) pair is one ordered batch solve. The table is in the dataset
    schema (p0_kPa.., tip_x_mm.. in softrod's world frame) with the tip in the paper's frame
    e_i as paper_x_mm, ... and the model, ramp level and solver columns; see
    docs/compare.md for all columns.
    """
    import math

    from rich.table import Table

    from ..compare import EXPERIMENTS, compare_models, resolve_experiments
    from ..io import check_table_path, write_table

    names = _parse_models(models)
    exps = _renamed("--experiments", resolve_experiments, experiments)
    levels = _parse_ramp(ramp)
    if out is not None:
        out = _for_option(check_table_path, out, "--out")
    if figure_path is not None:
        from ..plotting import check_figure_path

        figure_path = _for_option(check_figure_path, figure_path, "--figure")

    console = _stdout()
    rows = len(names) * len(exps) * len(levels)
    _say(
        f"{protocol}: {len(names)} model{'s' if len(names) != 1 else ''} x {len(exps)} "
        f"experiment{'s' if len(exps) != 1 else ''} x {len(levels)} levels "
        f"({levels[0] / 1e3:g} to {levels[-1] / 1e3:g} kPa) = {rows:,} solves"
    )
    t0 = time.perf_counter()
    with _progress("compare", rows) as advance:
        df = compare_models(
            names,
            experiments=exps,
            pressures=levels,
            threads=threads,
            progress=lambda label, n: advance(n),
        )
    wall = time.perf_counter() - t0

    table = Table(
        title=f"tip at p = {levels[-1] / 1e3:g} kPa, paper frame e_i (mm)",
        title_justify="left",
        caption="i-k, ii-k, iii: vertical mounting; a: horizontal (paper 002 Sec. V); "
        "channels p0, p1, p2 are the paper's chambers 1, 2, 3",
        caption_justify="left",
    )
    for name, justify in (
        ("experi-\nment", "left"),
        ("channels\nat p", "left"),
        ("model", "left"),
        ("x\nmm", "right"),
        ("y\nmm", "right"),
        ("z\nmm", "right"),
        ("lateral\nmm", "right"),
        ("converged", "right"),
    ):
        table.add_column(name, justify=justify, no_wrap=True)
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
        _say(f"wrote {out}")
    if figure_path is not None:
        plt = _pyplot()
        from ..compare import plot_comparison
        from ..plotting import save_figure

        fig = plot_comparison(
            df, title=f"{protocol}: tip position vs pressure, models {', '.join(names)}"
        )
        try:
            save_figure(fig, figure_path)
        finally:
            plt.close(fig)
        _say(f"wrote {figure_path}")
