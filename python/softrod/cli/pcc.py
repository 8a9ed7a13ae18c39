"""``softrod compare-pcc`` and ``softrod pcc-identify``: the PCC model of paper 003."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import InputError, design_error
from ..io import exists as _exists
from ..io import is_file as _is_file
from ._common import (
    _check_output,
    _for_option,
    _handle_errors,
    _parse_vector,
    _progress,
    _pyplot,
    _quantity,
    _say,
    _stdout,
)

KINDS = ("longitudinal-stiffness", "bending-stiffness", "longitudinal-damping", "bending-damping")


def _channels(text: str) -> list[int]:
    try:
        return [int(t) for t in text.split(",")]
    except ValueError:
        raise design_error(
            "--channels", text, "give comma-separated channel indices, e.g. 0,1,5", InputError
        ) from None


def _read_columns(path: Path, needed: list[str]) -> dict:
    """The SI columns of an array table (CSV or Parquet), each a finite float array."""
    import io

    import pandas as pd

    from .. import _validate as V
    from ..io import read_text_file

    try:
        if path.suffix.lower() == ".parquet":
            df = pd.read_parquet(path)
        else:
            df = pd.read_csv(io.StringIO(read_text_file(path)))
    except InputError:
        raise
    except Exception as exc:  # pandas and pyarrow raise many types for unreadable tables
        rule = f"not a CSV/Parquet table: {exc}"
        raise design_error(str(path), "unreadable", rule, InputError) from None
    missing = [c for c in needed if c not in df.columns]
    if missing:
        raise design_error(
            str(path),
            ", ".join(df.columns),
            f"needs the column(s) {', '.join(missing)} (SI units in the names)",
            InputError,
        )
    return {
        c: V.real_array(df[c].to_numpy(), f"{path.name}: {c}", ndim=1)
        for c in df.columns
        if c in needed
    }


def _compare_dynamic(d, chans, pmax, force, input_path, t_end, dt):
    """compare-pcc --dynamic: the runs (with a progress bar) and the figure."""
    import numpy as np

    from ..dynamics import PressureSchedule
    from ..pcc.compare import compare_pcc_dynamics, plot_pcc_dynamics_comparison

    duration = _quantity(t_end, "time", "--t-end")
    step = _quantity(dt, "time", "--dt")
    for name, value, given in (("--t-end", duration, t_end), ("--dt", step, dt)):
        if not value > 0:
            raise design_error(name, given, "must be > 0 s", InputError)
    if input_path is not None:
        schedule = PressureSchedule.from_file(input_path)
        schedule.check_channels(d.n_channels)
        what = str(input_path)
    else:
        on = np.zeros(d.n_channels)
        on[chans] = pmax
        zero = np.zeros(d.n_channels)
        schedule = PressureSchedule.steps([0.0, 0.1, duration / 2], [zero, on, zero])
        what = (
            f"{pmax / 1e3:g} kPa pulse on channels {', '.join(map(str, chans))} "
            f"from 0.1 s to {duration / 2:g} s"
        )
    with _progress("runs", 6) as advance:
        df = compare_pcc_dynamics(d, schedule, duration, dt=step, tip_force=force, progress=advance)
    _pyplot()
    fig = plot_pcc_dynamics_comparison(df, title=f"{d.name}: PCC vs Cosserat rod, {what}")
    return df, fig, f"dynamics, dt = {step * 1e3:g} ms"


@click.command("compare-pcc")
@click.argument("design")
@click.option(
    "--channels",
    required=True,
    help="Channels pressurised together, numbered from 0 as everywhere in softrod, e.g. 5,0,1.",
)
@click.option("--p-max", "p_max", default="1 bar", show_default=True, help="Largest pressure.")
@click.option("--steps", default=11, show_default=True, help="Pressure levels from 0.")
@click.option(
    "--tip-force",
    "tip_force",
    default="0,0,-0.0981 N",
    show_default=True,
    help="Tip load of the third case, world frame (default: a 10 g weight).",
)
@click.option(
    "--out",
    "out",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="Figure (.png, .pdf, .svg): tip error vs pressure and tip paths.",
)
@click.option(
    "--table",
    "table",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Also write the numbers (.csv or .parquet, the dataset schema: one row per case, "
    "level and model).",
)
@click.option(
    "--dynamic",
    is_flag=True,
    help="Compare motions instead of equilibria: CHANNELS get a P_MAX pulse from 0.1 s "
    "to half of --t-end (or the commands of --input), tip error vs time.",
)
@click.option(
    "--input",
    "input_path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="With --dynamic: commanded pressures over time (CSV/Parquet, as for simulate).",
)
@click.option("--t-end", "t_end", default="3 s", show_default=True, help="With --dynamic.")
@click.option("--dt", default="2 ms", show_default=True, help="With --dynamic: time step.")
@_handle_errors
def compare_pcc_cmd(
    design, channels, p_max, steps, tip_force, out, table, dynamic, input_path, t_end, dt
):
    """PCC model vs Cosserat rod on DESIGN: tip positions while CHANNELS ramp to P_MAX,
    weightless, with gravity, and with gravity and a tip load (docs/pcc.md). With
    --dynamic, the tip trajectories of both models under the same pressures."""
    from ..catalog import load_design
    from ..io import atomic_path, check_table_path, write_table
    from ..pcc.compare import compare_pcc, plot_pcc_comparison

    d = load_design(design)
    chans = _channels(channels)
    if any(c < 0 or c >= d.n_channels for c in chans):
        raise design_error(
            "--channels", channels, f"must be channel indices 0..{d.n_channels - 1}", InputError
        )
    pmax = _quantity(p_max, "pressure", "--p-max")
    force = _parse_vector(tip_force, "force", "--tip-force", 3)
    out = _check_output(out, "--out", (".png", ".pdf", ".svg"), "a figure")
    if table is not None:
        table = _for_option(check_table_path, table, "--table")
    if input_path is not None and not dynamic:
        raise design_error("--input", str(input_path), "needs --dynamic", InputError)
    console = _stdout()
    if dynamic:
        df, fig, key = _compare_dynamic(d, chans, pmax, force, input_path, t_end, dt)
    else:
        with _progress("solves", 3 * 2 * steps) as advance:
            df = compare_pcc(d, chans, pmax, steps=steps, tip_force=force, progress=advance)
        _pyplot()
        on = ", ".join(map(str, chans))
        fig = plot_pcc_comparison(
            df, title=f"{d.name}: PCC vs Cosserat rod, channels {on} to {pmax / 1e3:g} kPa"
        )
        key = "statics"
    plt = _pyplot()
    try:
        with atomic_path(out) as tmp:
            fig.savefig(tmp, format=out.suffix[1:], dpi=150)
    finally:
        plt.close(fig)
    if table is not None:
        write_table(df, table)
    rod = df[df["model"] == "cosserat"]
    for case, sub in rod.groupby("experiment", sort=False):
        worst = sub["error_mm"].max()
        console.print(f"{case:>20}: largest tip difference {worst:8.3f} mm ({key})")
    _say(f"wrote {out}" + (f" and {table}" if table else ""))


@click.command("pcc-identify")
@click.argument("kind", type=click.Choice([*KINDS, "all"]))
@click.argument("data", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--design", "design", help="Design (for chamber areas, moments, k values).")
@click.option(
    "--chambers", default=3, show_default=True, help="Chambers pressurised (k_L, array CSV)."
)
@click.option("--k-L", "k_l", help="k_L for longitudinal-damping (default: the design's).")
@click.option("--k-theta", "k_theta", help="k_theta for bending-damping (default: the design's).")
@click.option(
    "--degree",
    type=int,
    help="k_theta(theta) polynomial degree (default: 2 for array CSVs, 0 = a constant for "
    "datasets).",
)
@click.option(
    "--experiment",
    "experiment",
    multiple=True,
    help="Dataset rows to use: an experiment id, or PARAM=ID (k_L, k_theta, b_L, b_theta); "
    "repeat for several (default: the experiments named elongation, bending, step, "
    "free_decay).",
)
@click.option(
    "--dt",
    default="1 ms",
    show_default=True,
    help="Time step of the replayed time series (datasets).",
)
@click.option(
    "--write-design",
    "write_design",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write --design with the fitted values as this .toml design file.",
)
@_handle_errors
def pcc_identify(kind, data, design, chambers, k_l, k_theta, degree, experiment, dt, write_design):
    """Identify PCC parameters from DATA as in paper 003 Sec. V (docs/pcc.md).

    DATA is a softrod dataset (CSV/Parquet with tip_x/y/z and p0.. columns, as
    load_dataset reads it; needs --design), identified with softrod.pcc.identify_pcc: one
    stage per parameter through the calibration engine (closed-form start, the PCC model
    fitted to the tip positions), then all together; KIND all fits k_L, k_theta, b_L and
    b_theta in that order. Or DATA is an
    array table with SI columns: longitudinal-stiffness p_Pa, d_m; bending-stiffness
    p0_Pa..p<N-1>_Pa (channels from 0), theta_rad; longitudinal-damping t_s, z_m;
    bending-damping t_s, theta_rad. Prints each value, its standard error and the [pcc]
    line to put in the design; --write-design writes that design (whole or not at all)."""
    import numpy as np

    from ..catalog import load_design
    from ..datasets import example_dataset_path, example_datasets
    from ..pcc import identify as idf
    from ..pcc.model import pcc_parameters

    if not _exists(data) and data.suffix == "" and str(data) in example_datasets():
        data = example_dataset_path(str(data))
    if not _is_file(data):
        raise design_error("DATA", str(data), "no such file or bundled dataset", InputError)
    d = load_design(design) if design else None

    def need_design(what):
        if d is None:
            raise design_error("--design", None, f"is needed for {what}", InputError)
        return d

    if write_design is not None:
        need_design("--write-design")
        write_design = _check_output(write_design, "--write-design", (".toml",), "a design file")
    console = _stdout()
    if kind == "all" or _is_dataset(data):
        result = _identify_dataset(
            kind,
            data,
            need_design("a dataset"),
            experiment,
            {
                "dt": dt,
                **({"degree": degree} if degree is not None else {}),
                **({"k_L": k_l} if k_l else {}),
                **({"k_theta": k_theta} if k_theta else {}),
            },
        )
        _print_result(console, result)
        if write_design is not None:
            result.to_toml(write_design)
            console.print(f"wrote {write_design}", soft_wrap=True)
        return
    else:
        if experiment:
            raise design_error(
                "--experiment",
                list(experiment),
                "applies to softrod datasets (tip_x/y/z columns), not to array tables",
                InputError,
            )
        degree = 2 if degree is None else degree
        if kind == "longitudinal-stiffness":
            cols = _read_columns(data, ["p_Pa", "d_m"])
            sec = next(s for s in need_design("the chamber area").sections() if s["chambers"])
            fit = idf.fit_longitudinal_stiffness(
                cols["p_Pa"], cols["d_m"], area=sec["chambers"][0][0], n_chambers=chambers
            )
        elif kind == "bending-stiffness":
            dd = need_design("the chamber moment")
            names = [f"p{k}_Pa" for k in range(dd.n_channels)]
            cols = _read_columns(data, [*names, "theta_rad"])
            moment = idf.chamber_moment(dd, np.column_stack([cols[n] for n in names]))
            fit = idf.fit_bending_stiffness(cols["theta_rad"], moment, degree=degree)
        elif kind == "longitudinal-damping":
            cols = _read_columns(data, ["t_s", "z_m"])
            k = (
                _quantity(k_l, "force_per_length", "--k-L")
                if k_l
                else pcc_parameters(need_design("k_L"))[0]["k_L"]
            )
            fit = idf.fit_longitudinal_damping(cols["t_s"], cols["z_m"], k_L=k)
        else:
            cols = _read_columns(data, ["t_s", "theta_rad"])
            k = (
                _quantity(k_theta, "moment", "--k-theta")
                if k_theta
                else pcc_parameters(need_design("k_theta"))[0]["k_theta"]
            )
            fit = idf.fit_bending_damping(cols["t_s"], cols["theta_rad"], k_theta=k)
    _print_fit(console, fit)
    if write_design is not None:
        fit.to_toml(write_design, d)
        console.print(f"wrote {write_design}", soft_wrap=True)


# --- pcc-identify on softrod datasets ----------------------------------------------------------

#: The parameter each pcc-identify KIND identifies.
KIND_PARAMETERS = {
    "longitudinal-stiffness": ["k_L"],
    "bending-stiffness": ["k_theta"],
    "longitudinal-damping": ["b_L"],
    "bending-damping": ["b_theta"],
    "all": ["k_L", "k_theta", "b_L", "b_theta"],
}


def _columns(path: Path) -> list[str]:
    """The column names of a CSV (after its # comment lines) or Parquet file."""
    import csv

    from ..io import read_text_file

    try:
        if path.suffix.lower() == ".parquet":
            import pyarrow.parquet as pq

            return list(pq.read_schema(path).names)
        lines = (line for line in read_text_file(path).splitlines() if not line.startswith("#"))
        return [c.strip() for c in next(csv.reader(lines), [])]
    except InputError:
        raise
    except Exception as exc:  # pyarrow and csv raise their own types for unreadable files
        rule = f"not a CSV/Parquet table: {exc}"
        raise design_error(str(path), "unreadable", rule, InputError) from None


def _is_dataset(path: Path) -> bool:
    """A softrod dataset has tip position columns (tip_x, tip_x_mm, ...)."""
    return any(c == "tip_x" or c.startswith("tip_x_") for c in _columns(path))


def _experiment_id(text: str):
    text = text.strip()
    return int(text) if text.lstrip("-").isdigit() else text


def _identify_dataset(kind: str, path: Path, design, experiment: tuple, options: dict):
    from ..datasets import load_dataset
    from ..pcc import identify_pcc

    params = KIND_PARAMETERS[kind]
    chosen: dict = {}
    for item in experiment:
        name, sep, value = item.partition("=")
        if not sep:
            if len(params) != 1:
                raise design_error(
                    "--experiment",
                    item,
                    "with KIND all, give PARAM=ID (k_L, k_theta, b_L, b_theta)",
                    InputError,
                )
            name, value = params[0], item
        name = name.strip()
        if name not in params:
            raise design_error(
                "--experiment", item, f"PARAM must be one of {', '.join(params)}", InputError
            )
        chosen.setdefault(name, []).append(_experiment_id(value))
    dataset = load_dataset(path, design=design)
    return identify_pcc(
        design,
        dataset,
        params,
        experiments={k: v[0] if len(v) == 1 else v for k, v in chosen.items()},
        **options,
    )


def _print_result(console, result) -> None:
    """Value, standard error and [pcc] line of each parameter of an engine result."""
    from ..pcc.model import pcc_parameters

    for name, unit, val, se in zip(
        result.names, result.units, result.values, result.std_errors, strict=True
    ):
        console.print(f"{name} = {val:.6g} {unit} +- {se:.3g} (1 s.e.)", markup=False)
        if "[" not in name:
            console.print(f'[pcc] line: {name} = "{val:.6g} {unit}"', markup=False)
    table = pcc_parameters(result.design)[0]["k_theta"]
    if isinstance(table, (tuple, list)):
        a, k = table
        console.print(
            "[pcc] table: k_theta = { angle = ["
            + ", ".join(f"{x:.4f}" for x in a)
            + "], stiffness = ["
            + ", ".join(f"{x:.5g}" for x in k)
            + "] }",
            markup=False,
            soft_wrap=True,
        )
    console.print(f"RMS tip error {result.rms_error_mm:.3g} mm", markup=False)
    for w in result.warnings:
        console.print(f"warning: {w}", markup=False, soft_wrap=True)


def _print_fit(console, fit) -> None:
    """Value, standard error and [pcc] line of each parameter, then the fit residual."""
    for key, val in fit.values.items():
        unit = fit.unit(key)
        console.print(f"{key} = {val:.6g} {unit} +- {fit.stderr[key]:.3g} (1 s.e.)")
        console.print(f'[pcc] line: {key} = "{val:.6g} {unit}"', markup=False)
        if key == "k_theta" and fit.table is not None:
            a, k = fit.table
            console.print(
                "[pcc] table: k_theta = { angle = ["
                + ", ".join(f"{x:.4f}" for x in a)
                + "], stiffness = ["
                + ", ".join(f"{x:.5g}" for x in k)
                + "] }",
                markup=False,
                soft_wrap=True,
            )
        info = fit.details.get(key)
        if isinstance(info, dict) and "residual" in info:
            console.print(f"fit residual (RMS): {info['residual']:.3g} {info['residual_unit']}")
    if not any(isinstance(fit.details.get(k), dict) for k in fit.values):
        console.print(f"fit residual (RMS): {fit.residual:.3g} {fit.residual_unit}")
