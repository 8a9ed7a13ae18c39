"""Model comparison on paper 002's experiments (Sec. V): tip positions along pressure ramps.

Each experiment ramps a pressure p (paper 002: 0 to 0.6 bar in 30 equal steps, 31 levels) on
some chambers and keeps the others at 0 (gauge):

====== ========== ==================================== ==============
name   mounting   chamber pressures                    paper figure
====== ========== ==================================== ==============
i-k    vertical   p_k = p, the others 0 (k = 0, 1, 2)  Fig. 6
ii-k   vertical   p_k = 0, the other two = p           Fig. 7
iii    vertical   p0 = p1 = p2 = p                     Fig. 5 bottom
a      horizontal p0 = p, p1 = p2 = 0                  Fig. 5 top
====== ========== ==================================== ==============

Channels are numbered from 0, as everywhere in softrod: paper 002's chambers 1, 2, 3 are
channels 0, 1, 2 (so the paper's experiment (i) on chamber 1 is ``i-0``).

:func:`compare_models` solves every (model, experiment) pair as one
``solve_statics_batch`` call (every level solved cold, as a single solve) and returns a
tidy table; :func:`plot_comparison` draws it like paper 002's Figs. 5-7 (tip coordinates in
the paper's frame against pressure). Models are the presets of paper 002's Sec. VI (M0-M3,
:mod:`softrod.presets`) or designs of your own (e.g. a calibrated one).

Frames. The paper reports the end point P in its inertial frame e_i (eq. 23), which the
clamping (eq. 26) ties to the base director triad: in the bundled paper-002 designs the
paper's e1, e2, e3 are softrod's d1, d2, d3 at the base. So the ``paper_*`` columns are the
tip in the clamp frame, R0^T (r_tip - r0), for any design: vertical, (x, y, z)_paper =
(x, -y, -z)_world; horizontal, (x, y, z)_paper = (z, -y, x)_world.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from . import _validate as V
from .catalog import load_design
from .design import Design
from .errors import DesignError, InputError, design_error
from .presets import PAPER002_MODELS, paper002_preset
from .statics import SolverOptions, _options, solve_statics_batch
from .units import to_si

if TYPE_CHECKING:
    import pandas as pd

    from ._types import ArrayLike


@dataclass(frozen=True)
class Experiment:
    """One protocol of paper 002 Sec. V: chamber pressures ``weights * p`` along a ramp."""

    name: str
    mounting: str  # "vertical" or "horizontal"
    weights: tuple[float, float, float]
    title: str


def _chambers(weights) -> str:
    on = [f"p{k}" for k, w in enumerate(weights) if w]
    off = [f"p{k}" for k, w in enumerate(weights) if not w]
    text = " = ".join(on) + " = p"
    return text + (f", {' = '.join(off)} = 0" if off else "")


def _experiments() -> dict[str, Experiment]:
    out = {}
    for k in range(3):
        w = tuple(float(j == k) for j in range(3))
        out[f"i-{k}"] = Experiment(f"i-{k}", "vertical", w, "")
    for k in range(3):
        w = tuple(float(j != k) for j in range(3))
        out[f"ii-{k}"] = Experiment(f"ii-{k}", "vertical", w, "")
    out["iii"] = Experiment("iii", "vertical", (1.0, 1.0, 1.0), "")
    out["a"] = Experiment("a", "horizontal", (1.0, 0.0, 0.0), "")
    return {
        n: Experiment(n, e.mounting, e.weights, f"({n}) {e.mounting}: {_chambers(e.weights)}")
        for n, e in out.items()
    }


EXPERIMENTS: dict[str, Experiment] = _experiments()
# Names that stand for several experiments.
EXPERIMENT_GROUPS: dict[str, tuple[str, ...]] = {
    "i": ("i-0", "i-1", "i-2"),
    "ii": ("ii-0", "ii-1", "ii-2"),
    "vertical": tuple(n for n, e in EXPERIMENTS.items() if e.mounting == "vertical"),
    "horizontal": ("a",),
    "all": tuple(EXPERIMENTS),
}
MOUNTINGS = ("vertical", "horizontal")

PAPER002_RAMP = (0.0, 0.6e5, 30)  # Pa, Pa, equal steps: 0 to 0.6 bar in 30 steps (Sec. V)
MAX_RAMP_STEPS = 100_000  # more levels than any experiment needs; refused as a likely typo

# The table of compare_models: the dataset schema (docs/datasets.md) with these columns,
# then the result columns of RESULT_COLUMNS.
COLUMNS = (
    "experiment",
    "mounting",
    "p0_kPa",
    "p1_kPa",
    "p2_kPa",
    "tip_x_mm",
    "tip_y_mm",
    "tip_z_mm",
    "tip_qw",
    "tip_qx",
    "tip_qy",
    "tip_qz",
    "base_fx_N",
    "base_fy_N",
    "base_fz_N",
    "base_mx_Nmm",
    "base_my_Nmm",
    "base_mz_Nmm",
)
RESULT_COLUMNS = (
    "model",
    "design",
    "step",
    "ramp_kPa",
    "paper_x_mm",
    "paper_y_mm",
    "paper_z_mm",
    "converged",
    "iterations",
)


def pressure_ramp(start=PAPER002_RAMP[0], stop=PAPER002_RAMP[1], steps=PAPER002_RAMP[2]):
    """Pressure levels in Pa from ``start`` to ``stop`` in ``steps`` equal steps
    (``steps + 1`` levels, both ends included). Pressures are SI numbers or strings with
    units ("0.6 bar"). The default is paper 002's ramp: 0 to 0.6 bar in 30 steps."""
    p0 = to_si(start, "pressure", "ramp.start", InputError)
    p1 = to_si(stop, "pressure", "ramp.stop", InputError)
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)):
        raise design_error("ramp.steps", steps, "must be an integer >= 1", InputError)
    if not 1 <= steps <= MAX_RAMP_STEPS:
        raise design_error(
            "ramp.steps", steps, f"must be an integer in [1, {MAX_RAMP_STEPS}]", InputError
        )
    return np.linspace(p0, p1, int(steps) + 1)


def resolve_experiments(experiments: str | Sequence[str] | None = None) -> list[str]:
    """Experiment names, groups expanded, duplicates dropped, in the canonical order.

    ``experiments`` is None (all), a comma-separated string ("i,iii,a") or a sequence of
    names from :data:`EXPERIMENTS` and :data:`EXPERIMENT_GROUPS`.
    """
    if experiments is None:
        return list(EXPERIMENTS)
    if isinstance(experiments, str):
        items = experiments.split(",")
    elif isinstance(experiments, (list, tuple)):
        items = list(experiments)
    else:
        raise design_error(
            "experiments",
            experiments,
            "must be None, a comma-separated string or a list of experiment names",
            InputError,
        )
    chosen: set[str] = set()
    for item in items:
        name = str(item).strip()
        if name in EXPERIMENTS:
            chosen.add(name)
        elif name in EXPERIMENT_GROUPS:
            chosen.update(EXPERIMENT_GROUPS[name])
        else:
            known = ", ".join([*EXPERIMENTS, *EXPERIMENT_GROUPS])
            raise design_error(
                "experiments", name, f"unknown experiment (known: {known})", InputError
            )
    if not chosen:
        raise design_error("experiments", experiments, "name at least one experiment", InputError)
    return [n for n in EXPERIMENTS if n in chosen]


def clamp_frame(design: Design, points) -> np.ndarray:
    """World points (..., 3) in m -> coordinates in the clamp frame (d1, d2, d3 at the base),
    the frame in which paper 002 reports tip positions (see the module docstring)."""
    r0 = np.asarray(design.spec["mounting"]["base_position"], dtype=float)
    rot = np.asarray(design.spec["mounting"]["base_rotation"], dtype=float)  # columns d1 d2 d3
    return (np.asarray(points, dtype=float) - r0) @ rot


def _model_designs(models, mountings: set[str]) -> dict[str, dict[str, Design]]:
    """{label: {mounting: Design}} for the mountings the experiments need."""
    if isinstance(models, str):
        models = models.split(",")
    if isinstance(models, Mapping):
        items = list(models.items())
    elif isinstance(models, (list, tuple)):
        items = [(str(m).strip(), None) for m in models]
    else:
        raise design_error(
            "models",
            type(models).__name__,
            "must be model names (a list or a comma-separated text) or a mapping",
            InputError,
        )
    if not items:
        raise design_error("models", models, "name at least one model", InputError)
    out: dict[str, dict[str, Design]] = {}
    for label, given in items:
        if label in out:
            raise design_error("models", label, "is given twice", InputError)
        if given is None:
            if label not in PAPER002_MODELS:
                raise design_error(
                    "models",
                    label,
                    f"unknown model: give one of {', '.join(PAPER002_MODELS)} (paper 002 "
                    "Table IV) or a mapping {label: {'vertical': design, 'horizontal': design}}",
                    InputError,
                )
            out[label] = {m: load_design(paper002_preset(label, m)) for m in sorted(mountings)}
            continue
        if not isinstance(given, Mapping):
            raise design_error(
                f"models[{label!r}]",
                type(given).__name__,
                "must map mountings ('vertical', 'horizontal') to designs",
                InputError,
            )
        unknown = sorted(set(given) - set(MOUNTINGS))
        if unknown:
            raise design_error(
                f"models[{label!r}]",
                unknown[0],
                f"unknown mounting (known: {', '.join(MOUNTINGS)})",
                InputError,
            )
        missing = sorted(mountings - set(given))
        if missing:
            raise design_error(
                f"models[{label!r}]",
                sorted(given),
                f"needs a design for the {missing[0]} mounting of the chosen experiments",
                InputError,
            )
        out[label] = {m: load_design(given[m]) for m in sorted(mountings)}
        for m, d in out[label].items():
            if d.n_channels != 3:
                raise design_error(
                    f"models[{label!r}][{m!r}]",
                    d.name,
                    f"has {d.n_channels} pressure channels; paper 002's experiments need 3",
                    InputError,
                )
    return out


def compare_models(
    models: Sequence[str] | Mapping[str, Mapping[str, Any]] = PAPER002_MODELS,
    *,
    experiments: str | Sequence[str] | None = None,
    pressures: ArrayLike | None = None,
    threads: int = 0,
    options: SolverOptions | None = None,
    progress: Callable[[str, int], None] | None = None,
) -> pd.DataFrame:
    """Tip positions of several models along paper 002's pressure ramps; a pandas DataFrame.

    models: paper 002 model names ("M0".."M3", the presets ``paper002_<M>_<mounting>``), or a
        mapping ``{label: {"vertical": design, "horizontal": design}}`` (designs with three
        channels; only the mountings of the chosen experiments are needed).
    experiments: names or groups (see :func:`resolve_experiments`); default all eight.
    pressures: the ramp levels p in Pa, in order (default :func:`pressure_ramp`: 0 to
        0.6 bar in 30 steps); every experiment applies ``weights * p``.
    threads, options: passed to :func:`softrod.solve_statics_batch`.
    progress: None (a bar in interactive sessions), True, False or a callable called as
        ``progress(label, rows)`` after each (model, experiment) batch
        (:mod:`softrod.progress`).

    One row per model, experiment and level, in that nesting order, in the dataset schema
    (docs/datasets.md): ``experiment``, ``mounting``, the chamber pressures ``p0_kPa``,
    ``p1_kPa``, ``p2_kPa``, the tip in softrod's world frame ``tip_x_mm`` ... with its
    orientation ``tip_q*`` and the base wrench (:data:`COLUMNS`), then the result columns
    ``model``, ``design``, ``step``, ``ramp_kPa`` (the ramp level p), the tip in the paper's
    frame ``paper_x_mm`` ... (see the module docstring), ``converged`` and Newton
    ``iterations`` (:data:`RESULT_COLUMNS`). Rows that did not converge are kept with NaN
    coordinates. ``frame.attrs["softrod.metadata"]`` holds the metadata block (models, ramp,
    softrod version); ``load_dataset`` reads the table back.
    """
    import pandas as pd

    from .progress import reporter
    from .schema import Extra, provenance, schema_frame

    names = resolve_experiments(experiments)
    solver = _options(options).as_kwargs()  # a bad one is named here, before any solve
    ramp = (
        pressure_ramp()
        if pressures is None
        else V.real_array(pressures, "pressures", unit_kind="pressure", what="ramp levels (Pa)")
    )
    if ramp.ndim != 1 or ramp.size == 0:
        raise design_error(
            "pressures",
            f"shape {ramp.shape}",
            "must be a non-empty 1-D array of finite ramp levels (Pa)",
            InputError,
        )
    designs = _model_designs(models, {EXPERIMENTS[n].mounting for n in names})
    meta = provenance(
        "softrod.compare_models",
        protocol="paper002",
        models={
            label: {mounting: d.name for mounting, d in by.items()} for label, by in designs.items()
        },
        experiments=names,
        ramp_kPa=(ramp / 1e3).tolist(),
        solver=solver,
    )
    frames = []
    total = len(designs) * len(names) * len(ramp)
    done = [0]

    def rows_done(label: str, n: int) -> tuple[float, str]:
        done[0] += n
        return done[0], label

    with reporter(progress, "compare", total, rows_done) as report:
        for label, by_mounting in designs.items():
            for name in names:
                exp = EXPERIMENTS[name]
                design = by_mounting[exp.mounting]
                pressures_pa = ramp[:, None] * np.asarray(exp.weights)[None, :]
                try:
                    out = solve_statics_batch(
                        design, pressures_pa, threads=threads, options=options
                    )
                except DesignError as exc:  # e.g. a ramp that swells a chamber through the wall
                    exc.args = (f"model {label}, experiment {name}: {exc.args[0]}",)
                    raise
                paper = clamp_frame(design, out.tip_position)
                n = len(ramp)
                extras = [
                    Extra("model", np.full(n, label), "model label"),
                    Extra("design", np.full(n, design.name), "design solved"),
                    Extra("step", np.arange(n), "index of the ramp level"),
                    Extra("ramp", ramp, "ramp level p of the experiment", "pressure"),
                ]
                extras += [
                    Extra(f"paper_{a}", paper[:, k], "tip in paper 002's frame e_i", "length")
                    for k, a in enumerate("xyz")
                ]
                extras += [
                    Extra("converged", np.asarray(out.converged, dtype=bool), "solve converged"),
                    Extra("iterations", np.asarray(out.iterations, dtype=np.int64), "Newton"),
                ]
                frames.append(
                    schema_frame(
                        pressures=pressures_pa,
                        tip_position=out.tip_position,
                        tip_rotation=out.tip_rotation,
                        base_force=out.base_force,
                        base_moment=out.base_moment,
                        experiment=np.full(n, name),
                        mounting=np.full(n, exp.mounting),
                        extras=extras,
                        metadata=meta,
                    )
                )
                if report is not None:
                    report(f"{label} {name}", n)
    df = pd.concat(frames, ignore_index=True)
    df.attrs["softrod.metadata"] = frames[0].attrs["softrod.metadata"]
    return df


# --------------------------------------------------------------------------- figure

# Paper 002 marks M1, M2, M3 with circles, pluses and crosses (Figs. 5-7); M0 gets squares.
_MODEL_STYLES = {
    "M0": {"marker": "s", "linestyle": "-"},
    "M1": {"marker": "o", "linestyle": "--"},
    "M2": {"marker": "+", "linestyle": "-."},
    "M3": {"marker": "x", "linestyle": ":"},
}
_OTHER_STYLES = [
    {"marker": m, "linestyle": ls}
    for m, ls in (("^", "-"), ("v", "--"), ("D", "-."), ("*", ":"), ("P", "-"), ("<", "--"))
]


def plot_comparison(df, *, experiments: str | Sequence[str] | None = None, title=None):
    """Figure of a :func:`compare_models` table like paper 002's Figs. 5-7.

    One row of panels per experiment (its title names the chambers pressurised), one panel
    per tip coordinate x, y, z in the paper's frame (mm) against the ramp pressure (kPa);
    each model has its own colour, marker and line style (M1 o, M2 +, M3 x as in the paper).
    ``experiments`` picks and orders the rows (default: those in ``df``).
    """
    title = V.figure_title(title)
    import matplotlib as mpl
    import matplotlib.pyplot as plt

    missing = [c for c in ("model", "experiment", "ramp_kPa", "paper_x_mm") if c not in df]
    if missing:
        raise design_error(
            "df", missing[0], "missing column: pass a table from compare_models", InputError
        )
    present = set(df["experiment"])
    names = [n for n in resolve_experiments(experiments) if n in present]
    if not names:
        raise design_error("experiments", experiments, "none of them is in the table", InputError)
    models = list(dict.fromkeys(df["model"]))
    colours = mpl.rcParams["axes.prop_cycle"].by_key().get("color", ["C0"])
    styles = {}
    for i, m in enumerate(models):
        style = _MODEL_STYLES.get(m, _OTHER_STYLES[i % len(_OTHER_STYLES)])
        styles[m] = {**style, "color": colours[i % len(colours)]}

    # A header row (title and legend) above one row of panels per experiment: a legend
    # placed "outside" the whole figure collides with a suptitle once there are subfigures.
    header = 0.75 if title else 0.55  # inches
    fig = plt.figure(figsize=(10.0, header + 2.35 * len(names)), layout="constrained")
    top, *subfigs = fig.subfigures(len(names) + 1, 1, height_ratios=[header] + [2.35] * len(names))
    for sub, name in zip(subfigs, names, strict=True):
        axes = sub.subplots(1, 3, sharex=True)
        sub.suptitle(EXPERIMENTS[name].title, fontsize="medium", fontweight="bold")
        rows = df[df["experiment"] == name]
        for ax, axis in zip(axes, "xyz", strict=True):
            for m in models:
                r = rows[rows["model"] == m]
                n = len(r)
                ax.plot(
                    r["ramp_kPa"],
                    r[f"paper_{axis}_mm"],
                    label=m,
                    markevery=max(1, n // 10),
                    markersize=5,
                    linewidth=1.3,
                    **styles[m],
                )
            ax.set_ylabel(f"{axis} (mm)")
            ax.set_xlabel("p (kPa)")
            ax.grid(True, alpha=0.3)
    handles, labels = subfigs[0].axes[0].get_legend_handles_labels()
    if title:
        top.suptitle(title, fontsize="large")
    top.legend(
        handles,
        labels,
        loc="lower center",
        ncols=len(models),
        title="model (tip in the paper's frame e_i)",
        frameon=False,
    )
    return fig
