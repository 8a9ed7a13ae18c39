"""``softrod calibrate``, ``softrod calibrate-axial`` and ``softrod identify``: model parameters
from measurements (docs/calibration*.md)."""

from __future__ import annotations

import math
import re
import warnings
from pathlib import Path

import click

from .._limits import MAX_RESTARTS
from ..errors import InputError, design_error
from ._common import (
    PLOT_SUFFIXES,
    _as_option,
    _check_output,
    _fmt,
    _handle_errors,
    _is_bare,
    _num,
    _parse_quantities,
    _print_warnings,
    _progress,
    _quantity,
    _quiet,
    _renamed,
    _say,
    _scheduler,
    _scheduler_option,
    _staged,
    _stdout,
    _threads_option,
)

# calibrate()'s argument names -> the options that set them (for error messages).
_CALIBRATE_OPTIONS = {
    "params": "--params",
    "split": "--split",
    "test": "--test",
    "method": "--method",
    "threads": "--threads",
    "restarts": "--restarts",
    "seed": "--seed",
    "model": "--model",
    "dt": "--dt",
    "experiments": "--experiments",
    "weights": "--weights",
}


# Options that calibrate and calibrate-system share.
_max_evaluations_option = click.option(
    "--max-evaluations",
    default=200,
    show_default=True,
    type=click.IntRange(min=1),
    help="Stop after this many model evaluations (one evaluation solves every training row).",
)
_json_option = click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="Print the parameter and error tables as JSON (SI values) instead of tables.",
)
_restarts_option = click.option(
    "--restarts",
    default=0,
    show_default=True,
    type=click.IntRange(min=0, max=MAX_RESTARTS),
    help="Extra fits from random starting points (within --bounds, or within a factor 3 of "
    "a positive parameter's value); the best fit wins.",
)
_seed_option = click.option(
    "--seed",
    default=0,
    show_default=True,
    type=click.IntRange(min=0),
    help="Seed of the restarts' starting points.",
)
_bounds_option = click.option(
    "--bounds",
    "bounds_items",
    multiple=True,
    metavar="NAME=LO:HI",
    help='Bounds of one parameter, e.g. c_b=0.5:3 or "E=40kPa:200kPa" (a unit on HI alone '
    "applies to both; a bare number needs its unit). Repeat for several parameters.",
)


def _parse_pairs(items: tuple[str, ...], option: str, example: str) -> dict[str, str]:
    """KEY=VALUE items -> {key: value} (a key once)."""
    out: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        key, value = key.strip(), value.strip()
        if not sep or not key or not value:
            raise design_error(option, item, f"must read KEY=VALUE, e.g. {example}", InputError)
        if key in out:
            raise design_error(option, item, f"gives {key} twice", InputError)
        out[key] = value
    return out


def _parse_bounds(items: tuple[str, ...], params) -> tuple[dict, dict[str, str]]:
    """NAME=LO:HI items -> ({name: (lo, hi) in SI}, {"bounds[name]": the item as typed}).

    LO and HI take units ("E=40kPa:200kPa"; a unit on HI alone applies to both, "E=40:200kPa");
    a bare number other than 0 is refused. Dimensionless parameters take plain numbers."""
    from ..calibration.fit import _BOUND_KINDS as kinds

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


def _experiment_kinds(experiments: dict | None, dataset) -> dict | None:
    """--experiments ID=KIND with ids as the dataset spells them (ints stay ints)."""
    if experiments is None:
        return None
    labels = dataset.experiment
    ints = labels is not None and labels.dtype.kind in "iu"
    return {
        (int(k) if ints and re.fullmatch(r"[+-]?[0-9]+", k) else k): v
        for k, v in experiments.items()
    }


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

    def __init__(self, on_start=None, console=None) -> None:
        from rich.console import Console

        self._console = console or Console(stderr=True, highlight=False)
        self._progress = None
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
        if _quiet() or not self._console.is_terminal:
            return
        if self._progress is None:
            from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

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


def _parameter_table(result):
    from rich.table import Table
    from rich.text import Text

    from ..schema import DISPLAY_UNITS

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
        # softrod.schema.DISPLAY_UNITS: the units of summaries and reports too (SI in the
        # JSON and the TOML).
        unit, scale = DISPLAY_UNITS.get(row.unit, (row.unit, 1.0))
        unit = unit or "-"
        table.add_row(
            Text(row.parameter),
            _num(row.initial, scale),
            _num(row.value, scale),
            _num(row.std_error, scale, 3),
            "n/a" if not math.isfinite(row.rel_std_error_pct) else f"{row.rel_std_error_pct:.3g}",
            unit,
        )
    return table


def _error_table(result, length_m: float | None = None, what: str = "the length"):
    from rich.table import Table
    from rich.text import Text

    length_mm = (result.design.length if length_m is None else length_m) * 1e3
    table = Table(
        title=f"position errors (Euclidean; % of {what} L = {length_mm:.4g} mm)",
        title_justify="left",
    )
    columns = (
        ("quantity", "left", "quantity", None),
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


def _reaction_table(result):
    """A held tip's reaction errors (Euclidean over the measured components)."""
    from rich.table import Table

    table = Table(title="tip reaction errors (Euclidean)", title_justify="left")
    for header in ("quantity", "set", "n", "failed", "unit", "mean", "median", "max", "RMS"):
        table.add_column(header, justify="left" if header in ("quantity", "set") else "right")
    for row in result.reaction_error_table.to_dict(orient="records"):
        stats = [row[k] for k in ("mean_error", "median_error", "max_error", "rms_error")]
        table.add_row(
            str(row["quantity"]),
            str(row["set"]),
            str(row["n"]),
            str(row["failed"]),
            str(row["unit"]),
            *("n/a" if not math.isfinite(v) else _fmt(v, 3) for v in stats),
        )
    return table


def _captured_fit(go, typed: dict):
    """Run the fit ``go()`` recording its calibration warnings whatever the filters (they are
    printed once, by :func:`_print_fit`; others keep the caller's filters and are passed on
    after the fit); an InputError names the command's option. Returns (result, warnings)."""
    from ..errors import CalibrationWarning

    renames = {**_CALIBRATE_OPTIONS, **{k: "--bounds" for k in typed}}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", CalibrationWarning)
        try:
            result = go()
        except InputError as exc:
            raise _as_option(exc, renames, typed) from None
    found = [str(w.message) for w in caught if issubclass(w.category, CalibrationWarning)]
    for w in caught:
        if not issubclass(w.category, CalibrationWarning):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return result, found


def _print_fit(note, result, found: list[str], as_json: bool, tables: list) -> None:
    """A fit's summary line, parameter table and ``tables`` (not with --json), then its
    warnings and the rules they follow."""
    from rich.text import Text

    from ..calibration.fit import warning_thresholds

    if not as_json:
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
        for table in tables:
            note.print(table)
    _print_warnings(note, found)
    if not as_json:
        lead = "no warnings" if not found else "rules"
        note.print(Text(f"{lead}: {warning_thresholds()}", style="dim"))


@click.command()
@click.argument("design")
@click.argument("data")
@click.option(
    "--params",
    required=True,
    metavar="NAMES",
    help="Comma-separated parameters to fit, e.g. c_b,c_e,alpha; a selector names sections or "
    "a material: c_b[cap_a,cap_c], E[ecoflex_00_50]. Kinds: c_s, c_e, c_b, c_t, E, alpha, c_p, "
    "offset_1, offset_2, area_scale, density, mass, sigma_ext, sigma_bend_1, sigma_bend_2, "
    "damping_time (with --dynamic), registration_angle, registration_x, registration_y, "
    "registration_z (docs/calibration.md).",
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
    "--bounds); nelder-mead: paper 002's simplex, no derivatives during the fit (an "
    "explicit fallback).",
)
@_bounds_option
@_max_evaluations_option
@click.option(
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the calibrated design here (.toml; its [design.provenance] records the "
    "dataset, the fitted values with standard errors, the softrod version and the date).",
)
@click.option(
    "--name",
    help="Name of the calibrated design (default: <DESIGN's name>_calibrated).",
)
@click.option(
    "--predictions",
    "predictions_path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the measured and predicted tip of every sample here (.csv or .parquet, the "
    "dataset schema with model_tip_*, error and set columns).",
)
@click.option(
    "--report",
    "report_path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write an HTML report here (.html: tables, correlations, figures).",
)
@_json_option
@_restarts_option
@_seed_option
@click.option(
    "--model",
    type=click.Choice(["cosserat", "pcc"]),
    default="cosserat",
    show_default=True,
    help="cosserat: the rod; pcc: paper 003's PCC model (params k_L, k_theta, k_theta[j], "
    "b_L, b_theta, k_phi, b_phi).",
)
@click.option(
    "--dynamic",
    is_flag=True,
    help="Replay the time series of DATA (time column, one experiment per run) instead of "
    "fitting equilibria (paper 000's tau: --params damping_time,area_scale; exact "
    "trajectory sensitivities, so lm with standard errors).",
)
@click.option(
    "--dt",
    default=None,
    help="Time step of the replayed time series (default 5 ms; with --dynamic or the "
    "PCC model's time series only).",
)
@click.option(
    "--experiments",
    "experiment_items",
    multiple=True,
    metavar="ID=KIND",
    help="With --model pcc: whether an experiment is 'static' (equilibria) or 'dynamic' "
    "(a time series), e.g. step=dynamic; repeat for every experiment (default: the "
    "experiments step and free_decay are time series).",
)
@click.option(
    "--weights",
    "weight_items",
    multiple=True,
    metavar="QUANTITY=VALUE",
    help="Standard deviation of a measured quantity, e.g. tip=0.2mm markers=0.5mm "
    "reaction=5mN: each residual is divided by it (tip, markers: default 1 mm each; a held "
    "tip's reaction: default 5 mN; reaction_moment: default 0.5 N*mm).",
)
@_threads_option("Worker threads per model evaluation (0 = all cores).")
@_scheduler_option(
    "Run the restarts on the Dask cluster whose scheduler is at ADDRESS (docs/cluster.md)."
)
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
    name,
    predictions_path,
    report_path,
    as_json,
    restarts,
    seed,
    model,
    dynamic,
    dt,
    experiment_items,
    weight_items,
    threads,
    scheduler,
):
    """Fit parameters of DESIGN to the measured positions in DATA.

    DATA is a dataset table (.csv or .parquet, docs/datasets.md), or the name of a bundled
    example dataset, with one chamber pressure column per channel of DESIGN and the tip
    position, markers on the body, or both. One engine for every model: the rod's
    equilibria (default), its time series (--dynamic), or the PCC model (--model pcc);
    --params registration_angle,registration_x,... fits the measurement frame too. Prints
    the fitted values with standard errors, the errors on the training and test sets, and
    warnings about parameters that the data cannot determine (relative standard error above
    20 %, correlation |r| above 0.9, near-singular Jacobian). Every output file is written
    whole or not at all.
    """
    from rich.console import Console
    from rich.text import Text

    from ..calibration.fit import calibrate as fit
    from ..calibration.fit import resolve_parameters, result_json
    from ..calibration.params import SIGMA_KINDS
    from ..calibration.report import REPORT_SUFFIXES
    from ..catalog import load_design
    from ..datasets import load_dataset
    from ..io import TABLE_SUFFIXES, write_table

    d = load_design(design)
    parsed = _renamed("--params", resolve_parameters, d, params, model)
    bounds, typed = _parse_bounds(bounds_items, parsed)
    sigma = [p.name for p in parsed if getattr(p, "kind", None) in SIGMA_KINDS]
    experiments = _parse_pairs(experiment_items, "--experiments", "step=dynamic") or None
    weights = _parse_pairs(weight_items, "--weights", "tip=0.2mm") or None
    outputs = {}
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
        outputs["design"] = out
    if predictions_path is not None:
        outputs["predictions"] = _check_output(
            predictions_path, "--predictions", TABLE_SUFFIXES, "a table"
        )
    if report_path is not None:
        outputs["report"] = _check_output(
            report_path, "--report", REPORT_SUFFIXES, "a report is HTML"
        )
    try:
        dataset = load_dataset(data, design=d)
    except InputError as exc:
        raise _as_option(exc, {"path": "DATA"}) from None
    test = _parse_test_ids(test_ids, split, dataset)

    note = Console(stderr=True, highlight=False) if as_json else _stdout()

    def header() -> None:  # once the fit runs (the inputs have passed calibrate's checks)
        if not as_json and not _quiet():
            src = dataset.source.name if dataset.source is not None else str(data)
            src += " (SYNTHETIC)" if dataset.synthetic else ""
            note.print(
                Text(
                    f"calibrate {', '.join(p.name for p in parsed)} of {d.name} "
                    f"({model}{', time series' if dynamic else ''}) on {src}: "
                    f"{len(dataset)} samples, method {method}"
                ),
                soft_wrap=True,
            )

    def go():
        with _scheduler(scheduler) as client, _FitProgress(header) as progress:
            return fit(
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
                restarts=restarts,
                seed=seed,
                executor=client,
                name=name,
                model=model,
                dynamic=dynamic,
                dt=dt,
                experiments=_experiment_kinds(experiments, dataset),
                weights=weights,
            )

    result, found = _captured_fit(go, typed)
    if as_json:
        click.echo(result_json(result))
    tables = [_error_table(result)] if len(result.error_table) else []
    if result.reaction_error_table is not None:
        tables.append(_reaction_table(result))
    _print_fit(note, result, found, as_json, tables)

    if outputs:
        paths = list(outputs.values())
        with _staged(paths) as staged:
            for tmp, (kind, _path) in zip(staged, outputs.items(), strict=True):
                if kind == "design":
                    result.to_toml(tmp)
                elif kind == "predictions":
                    write_table(result.to_frame(), tmp)
                else:
                    result.write_report(tmp)
        for path in paths:
            _say(f"wrote {path}", stderr=as_json)


@click.command("calibrate-system")
@click.argument("system")
@click.argument("data")
@click.option(
    "--params",
    required=True,
    metavar="NAMES",
    help="Comma-separated parameters to fit: the rods' kinds on every rod (E, c_b[body], "
    "...), rods[i].KIND on rod i alone, and platform_mass (docs/calibration.md, 'Systems "
    "of rods').",
)
@click.option(
    "--split",
    type=click.Choice(["experiment"]),
    help="Hold out a test set by the dataset's experiment column (default: fit on all rows).",
)
@click.option(
    "--test",
    "test_ids",
    metavar="ID[,ID...]",
    help="The test experiment(s) with --split (default: the last experiment).",
)
@click.option(
    "--method",
    type=click.Choice(["lm", "nelder-mead"]),
    default="lm",
    show_default=True,
    help="lm: Levenberg-Marquardt with the exact Jacobian; nelder-mead: derivative-free.",
)
@_bounds_option
@click.option(
    "--weights",
    "weight_items",
    multiple=True,
    metavar="QUANTITY=VALUE",
    help="Standard deviation of a measured quantity, e.g. tip=0.2mm markers=0.5mm (the "
    "tip is the platform's position; default 1 mm each).",
)
@_max_evaluations_option
@click.option(
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the calibrated system here (.toml) and its rods' designs beside it "
    "(<stem>_rod<i>.toml, with their [design.provenance]); all files or none.",
)
@click.option(
    "--predictions",
    "predictions_path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the measured and predicted platform of every sample here (.csv or .parquet).",
)
@click.option(
    "--plot",
    "plot_path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Draw the measured against the predicted platform positions and each row's error "
    "(.png, .pdf or .svg).",
)
@click.option(
    "--report",
    "report_path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write an HTML report here (.html: tables, correlations, figures).",
)
@click.option(
    "--dynamic",
    is_flag=True,
    help="Replay the time series of DATA (time column, one experiment per run) instead of "
    "fitting equilibria (exact trajectory sensitivities of the whole system; "
    "--params may then include damping_time).",
)
@click.option(
    "--dt",
    default=None,
    help="Time step of the replayed time series (default 5 ms; with --dynamic only).",
)
@_json_option
@_restarts_option
@_seed_option
@_threads_option("Worker threads per model evaluation (0 = all cores).")
@_scheduler_option(
    "Run the restarts on the Dask cluster whose scheduler is at ADDRESS (docs/cluster.md)."
)
@_handle_errors
def calibrate_system_cmd(
    system,
    data,
    params,
    split,
    test_ids,
    method,
    bounds_items,
    weight_items,
    max_evaluations,
    out,
    predictions_path,
    plot_path,
    report_path,
    dynamic,
    dt,
    as_json,
    restarts,
    seed,
    threads,
    scheduler,
):
    """Fit parameters of a SYSTEM of rods (a system file or a bundled system) to the
    equilibria in DATA: the platform's position (the tip columns) and markers on the
    platform and the rods (docs/calibration.md, "Systems of rods"). The p columns are rod
    0's channels, then rod 1's, ... Prints the fitted values with standard errors, the
    errors on the training and test sets, and warnings about parameters that the data
    cannot determine.
    """
    import json

    import matplotlib.pyplot as plt
    import numpy as np
    from rich.console import Console
    from rich.text import Text

    from ..calibration.report import REPORT_SUFFIXES
    from ..calibration.system import calibrate_system, resolve_system_parameters
    from ..datasets import load_dataset
    from ..io import TABLE_SUFFIXES, write_table
    from ..system import load_system

    sysm = load_system(system)
    parsed = _renamed(
        "--params", lambda *a: resolve_system_parameters(*a, dynamic=dynamic), params, sysm
    )
    bounds, typed = _parse_bounds(bounds_items, parsed)
    weights = _parse_pairs(weight_items, "--weights", "tip=0.2mm") or None
    if out is not None:
        out = _check_output(out, "--out", (".toml",), "a system file")
    outputs = {}
    if predictions_path is not None:
        outputs["predictions"] = _check_output(
            predictions_path, "--predictions", TABLE_SUFFIXES, "a table"
        )
    if plot_path is not None:
        outputs["plot"] = _check_output(plot_path, "--plot", PLOT_SUFFIXES, "a figure")
    if report_path is not None:
        outputs["report"] = _check_output(
            report_path, "--report", REPORT_SUFFIXES, "a report is HTML"
        )
    try:
        dataset = load_dataset(data)
    except InputError as exc:
        raise _as_option(exc, {"path": "DATA"}) from None
    test = _parse_test_ids(test_ids, split, dataset)
    note = Console(stderr=True, highlight=False) if as_json else _stdout()
    if not as_json and not _quiet():
        src = dataset.source.name if dataset.source is not None else str(data)
        src += " (SYNTHETIC)" if dataset.synthetic else ""
        note.print(
            Text(
                f"calibrate {', '.join(p.name for p in parsed)} of system {sysm.name} on "
                f"{src}: {len(dataset)} samples, method {method}"
            ),
            soft_wrap=True,
        )

    def go():
        with _scheduler(scheduler) as client, _FitProgress() as progress:
            return calibrate_system(
                sysm,
                dataset,
                params,
                bounds=bounds or None,
                method=method,
                split=split,
                test=test,
                weights=weights,
                threads=threads,
                max_evaluations=max_evaluations,
                progress=progress,
                restarts=restarts,
                seed=seed,
                executor=client,
                dynamic=dynamic,
                dt=dt,
            )

    result, found = _captured_fit(go, typed)
    length = float(np.mean([rod.design.length for rod in sysm.rods]))
    if as_json:
        click.echo(
            json.dumps(
                {
                    "system": sysm.name,
                    "method": result.method,
                    "success": bool(result.success),
                    "evaluations": int(result.evaluations),
                    "parameters": result.parameter_table().to_dict(orient="records"),
                    "errors": result.error_table.to_dict(orient="records"),
                    "warnings": found,
                },
                default=float,
            )
        )
    tables = (
        [_error_table(result, length, "the rods' mean length")] if len(result.error_table) else []
    )
    _print_fit(note, result, found, as_json, tables)
    if outputs:
        with _staged(list(outputs.values())) as staged:
            for tmp, kind in zip(staged, outputs, strict=True):
                if kind == "predictions":
                    write_table(result.to_frame(), tmp)
                elif kind == "report":
                    result.write_report(tmp)
                else:
                    plt.close(result.plot(tmp))
        for path in outputs.values():
            _say(f"wrote {path}", stderr=as_json)
    if out is not None:
        result.system.save(out)
        _say(f"wrote {out} and its rods' designs", stderr=as_json)


@click.command("calibrate-axial")
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
    pint unit; docs/calibration-axial.md). Either may be the name of a bundled example
    (modular_axial_force_synthetic, modular_axial_length_synthetic). Prints the identified
    values with standard errors and builds a design from BASE with them.
    """
    from rich.text import Text

    from ..calibration.axial import calibrate_axial as identify
    from ..catalog import load_design

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
            L0=None if L0 is None else _quantity(L0, "length", "--L0"),
            rigid_length=_quantity(rigid_length, "length", "--rigid-length"),
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
        _say(f"wrote {out}")
    elif not _quiet():
        console.print(Text("not written: give --out design.toml to write it"), style="dim")


@click.command()
@click.argument("design")
@click.argument("data")
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
@_scheduler_option(
    "Identify the samples on the Dask cluster whose scheduler is at ADDRESS (docs/cluster.md)."
)
@_handle_errors
def identify(design, data, sections, out, report_path, threads, scheduler):
    """Identify the stiffness factors sigma of every sample in DATA (paper 001 eqs. 14-22).

    For each measured pose: sigma = (sigma_ext, sigma_bend_x, sigma_bend_y) that puts the
    model tip on the measured tip. A factor the pose cannot determine (deflection near a
    principal axis) is left empty and flagged. docs/calibration-per-sample.md.
    """
    from rich.table import Table

    from ..calibration.per_sample import identify_stiffness, stiffness_mapped_design
    from ..calibration.report import REPORT_SUFFIXES
    from ..catalog import load_design
    from ..datasets import load_dataset
    from ..io import TABLE_SUFFIXES, write_table

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
    with _scheduler(scheduler) as client, _progress("identify", len(dataset)) as advance:
        done = [0]

        def progress(iteration: int, active: int, total: int) -> None:
            advance(total - active - done[0])
            done[0] = total - active

        result = identify_stiffness(
            d,
            dataset,
            sections=names,
            threads=threads,
            progress=progress,
            executor=client,
        )
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
            _say(f"wrote {path}")
