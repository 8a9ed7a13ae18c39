"""Paper 003 Sec. V on softrod datasets: identify k_L, k_theta, b_L, b_theta from measured
tip positions, and synthesise the four experiments with the PCC model.

- :func:`identify_pcc`: paper 003's staged identification, each stage through the
  calibration engine (``softrod.calibrate(..., model="pcc")``, exact Jacobians, standard
  errors). Each parameter has its own experiment (rows of a :class:`~softrod.Dataset`):

  ========  ============  ==================================================================
  param     experiment    data (the closed-form start)
  ========  ============  ==================================================================
  k_L       elongation    equilibria under equal pressure on a symmetric set of chambers
                          (Hookean fit with an offset for the weight, Sec. V-B)
  k_theta   bending       equilibria under one-side pressure (M / theta, Sec. V-C; a table
                          k_theta(theta) with ``degree`` > 0)
  b_L       step          the time series of a pressure step (two modes with poles tied to
                          k_L and the model's mass, Sec. V-D)
  b_theta   free_decay    the time series after a release (logarithmic decrement with the
                          model's inertia, Sec. V-E)
  ========  ============  ==================================================================

  The closed-form fits of :mod:`softrod.pcc.identify` give each stage's starting value;
  the stage itself fits the PCC model (gravity, the arm's mass and inertia, the measured
  pressures) to the tip positions of its experiment, with the values of the earlier stages
  fixed. A last fit frees every parameter on all the experiments together (one problem),
  whose standard errors and correlations the result reports; ``result.stages`` lists the
  closed-form starts and the stage values.

- :func:`synthesize_pcc_experiments`: the same experiments made by the PCC model itself
  (statics and :func:`~softrod.pcc.run_pcc` in the Rust core), with seeded tip noise, as one
  dataset whose experiment ids are the experiment names above.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

from .. import _validate as V
from .._threads import one_blas_thread
from ..catalog import load_design
from ..datasets import Dataset, _matrix_to_quat, _quat_to_matrix, load_dataset, noise_seed
from ..design import Design
from ..errors import ConvergenceError, InputError
from ..units import to_si
from .identify import (
    bending_angle_from_tip,
    chamber_moment,
    fit_bending_damping,
    fit_bending_stiffness,
    fit_longitudinal_damping,
    fit_longitudinal_stiffness,
)
from .model import pcc_model, pcc_parameters

__all__ = [
    "EXPERIMENTS",
    "PCC_PARAMETERS",
    "identify_pcc",
    "synthesize_pcc_experiments",
]

#: The identifiable parameters in paper 003's order (Sec. V-B to V-E).
PCC_PARAMETERS = ("k_L", "k_theta", "b_L", "b_theta")

#: The experiment (and default experiment id) each parameter is identified from.
EXPERIMENTS = {"k_L": "elongation", "k_theta": "bending", "b_L": "step", "b_theta": "free_decay"}

# Angles below this (rad) carry no information on k_theta (the closed-form start drops them).
MIN_ANGLE = 0.05
# A channel below this fraction of its row's largest pressure counts as unpressurised.
ACTIVE_FRACTION = 0.05
# Static rows of a combined synthetic dataset get time = index * this (s) within their
# experiment, so that static and time-series experiments share one file.
STATIC_SAMPLE_PERIOD = 1.0
# Table entries of k_theta(theta) with degree > 0: this many angles over the bending data.
TABLE_ENTRIES = 8


# --- the design --------------------------------------------------------------------------------


def _arm(design: Design) -> dict:
    """The one section of a single-section arm with chambers (paper 003's arm is one PCC
    segment from base to tip; eq. 14 reads the bending angle off the tip of that arc)."""
    sections = design.spec["sections"]
    if len(sections) != 1 or sections[0].get("rigid", False):
        raise V.fail(
            "design.sections",
            f"{len(sections)} section(s) in {design.name!r}",
            "paper 003's identification needs a single deformable section (one PCC segment "
            "from base to tip, whose tip gives the bending angle by eq. 14)",
        )
    sec = design.sections()[0]
    if not sec["chambers"]:
        raise V.fail("design.sections[0].chambers", "none", "the arm needs pressure chambers")
    return sec


def _base_frame(design: Design, tip: np.ndarray) -> np.ndarray:
    """Tip positions (m, 3) in the base frame: x, y in the cross-section, z along the axis."""
    mount = design.spec["mounting"]
    rot = np.asarray(mount["base_rotation"], dtype=float)
    return (np.asarray(tip, dtype=float) - np.asarray(mount["base_position"])) @ rot


def _pcc_value(design: Design, name: str):
    """The design's [pcc] value of ``name`` (after the defaults; a table as a pair)."""
    return pcc_parameters(design)[0][name]


# --- rows ----------------------------------------------------------------------------------------


def _params(params) -> list[str]:
    names = [params] if isinstance(params, str) else params
    if not isinstance(names, Sequence) or isinstance(names, str) or not names:
        raise V.fail("params", params, f"must be one or a list of {', '.join(PCC_PARAMETERS)}")
    unknown = [p for p in names if p not in PCC_PARAMETERS]
    if unknown:
        raise V.fail(
            "params",
            unknown,
            f"identify_pcc identifies {', '.join(PCC_PARAMETERS)} (paper 003 Sec. V)",
        )
    if len(set(names)) != len(names):
        raise V.fail("params", list(names), "names a parameter twice")
    return [p for p in PCC_PARAMETERS if p in names]


def _experiment_ids(value, name: str) -> list:
    ids = [value] if isinstance(value, (str, int, np.integer)) else value
    if (
        isinstance(value, bool)
        or not isinstance(ids, Sequence)
        or not ids
        or not all(isinstance(i, (str, int, np.integer)) and not isinstance(i, bool) for i in ids)
    ):
        raise V.fail(f"experiments[{name!r}]", value, "must be an experiment id or a list of ids")
    return list(ids)


def _same(a, b) -> bool:
    if isinstance(a, (int, np.integer)) and isinstance(b, (int, np.integer)):
        return int(a) == int(b)
    return isinstance(a, str) and isinstance(b, str) and a == b


def _rows(dataset: Dataset, param: str, experiments: Mapping, n_params: int) -> tuple:
    """(row indices, the experiment ids used) of the rows that identify ``param``."""
    ids = dataset.experiments
    if param in experiments:
        wanted = _experiment_ids(experiments[param], param)
        if dataset.experiment is None:
            raise V.fail(
                f"experiments[{param!r}]",
                experiments[param],
                "the dataset has no experiment column to select rows by",
            )
        unknown = [w for w in wanted if not any(_same(w, k) for k in ids)]
        if unknown:
            raise V.fail(
                f"experiments[{param!r}]",
                unknown,
                f"unknown experiment id(s); the dataset has {', '.join(map(repr, ids))}",
            )
        wanted = [next(k for k in ids if _same(w, k)) for w in wanted]
    elif EXPERIMENTS[param] in ids:
        wanted = [EXPERIMENTS[param]]
    elif n_params == 1 and len(ids) <= 1:
        return np.arange(len(dataset)), list(ids)
    else:
        raise V.fail(
            "experiments",
            dict(experiments),
            f"say which experiment identifies {param}, e.g. experiments={{{param!r}: id}} "
            f"(the dataset has experiments {', '.join(map(repr, ids)) or 'none'}; an experiment "
            f"named {EXPERIMENTS[param]!r} is used without being named)",
        )
    mask = np.zeros(len(dataset), dtype=bool)
    for w in wanted:
        mask |= dataset.experiment == w
    return np.flatnonzero(mask), wanted


def _after_last_change(dataset: Dataset, rows: np.ndarray) -> np.ndarray:
    """The rows of a time series from the last pressure change on (the response to the step
    or release that the closed-form fits describe)."""
    rows = rows[np.argsort(dataset.time[rows], kind="stable")]
    p = dataset.pressures[rows]
    scale = max(float(np.abs(p).max()), 1.0)
    differs = np.abs(p - p[-1]).max(axis=1) > 0.02 * scale
    start = int(np.flatnonzero(differs)[-1] + 1) if differs.any() else 0
    return rows[start:]


# --- closed-form starting values -----------------------------------------------------------------


def _start_k_L(design, sec, dataset, rows) -> float:
    p = dataset.pressures[rows]
    force = sum(p[:, ch] * area for area, _, _, ch in sec["chambers"])
    elong = _base_frame(design, dataset.tip_position[rows])[:, 2] - design.length
    # n p A summed over the chambers is the generalised force on L; the offset force takes
    # the weight (Sec. V-B).
    fit = fit_longitudinal_stiffness(force, elong, area=1.0, n_chambers=1, offset=True)
    return fit.values["k_L"]


def _start_k_theta(design, dataset, rows, degree: int):
    local = _base_frame(design, dataset.tip_position[rows])
    theta = bending_angle_from_tip(np.hypot(local[:, 0], local[:, 1]), local[:, 2])
    moment = chamber_moment(design, dataset.pressures[rows])
    fit = fit_bending_stiffness(
        theta, moment, degree=degree, n_table=TABLE_ENTRIES, min_angle=MIN_ANGLE
    )
    return fit.values["k_theta"], (fit.table if degree > 0 else None)


def _start_b_L(design, dataset, rows) -> float:
    rows = _after_last_change(dataset, rows)
    core = pcc_model(design)
    mass = float(core.mass_matrix(list(core.statics(list(dataset.pressures[rows[-1]]))["x"]))[0][0])
    elong = _base_frame(design, dataset.tip_position[rows])[:, 2] - design.length
    k = float(_pcc_value(design, "k_L"))
    fit = fit_longitudinal_damping(dataset.time[rows], elong, k_L=k, mass=mass, poles="tied")
    return fit.values["b_L"]


def _start_b_theta(design, dataset, rows) -> float:
    rows = _after_last_change(dataset, rows)
    local = _base_frame(design, dataset.tip_position[rows])
    xy = local[:, :2]
    _, _, vt = np.linalg.svd(xy, full_matrices=False)
    u = vt[0] if xy[0] @ vt[0] >= 0 else -vt[0]
    theta = bending_angle_from_tip(xy @ u, local[:, 2])
    core = pcc_model(design)
    x = core.statics(list(dataset.pressures[rows[-1]]))["x"]
    mm = np.asarray(core.mass_matrix(list(x)))
    j = float(mm[1, 1]) if core.planar else float(u @ mm[1:3, 1:3] @ u)
    k = _pcc_value(design, "k_theta")
    k = float(np.interp(0.0, *k)) if isinstance(k, (tuple, list)) else float(k)
    fit = fit_bending_damping(dataset.time[rows], theta, k_theta=k, inertia=j)
    # J theta'' + b theta' + k_eff theta = 0: b = 2 zeta omega_n J (with k_eff, gravity
    # included, from the period).
    return 2.0 * fit.details["damping_ratio"] * fit.details["omega_n"] * j


def _closed_form(name, design, sec, dataset, rows, degree):
    """(start value, table or None, how it was found)."""
    try:
        if name == "k_L":
            return _start_k_L(design, sec, dataset, rows), None, "Hookean fit (Sec. V-B)"
        if name == "k_theta":
            value, table = _start_k_theta(design, dataset, rows, degree)
            return value, table, "M / theta (Sec. V-C)"
        if dataset.time is None:
            raise V.fail(
                "dataset.time",
                None,
                f"{name} is identified from a time series ({EXPERIMENTS[name]}); the dataset "
                "has no time column",
            )
        if name == "b_L":
            return _start_b_L(design, dataset, rows), None, "tied two-mode fit (Sec. V-D)"
        return _start_b_theta(design, dataset, rows), None, "logarithmic decrement (Sec. V-E)"
    except (ConvergenceError, np.linalg.LinAlgError) as exc:
        # The closed form's own assumption failed on these data (e.g. a decay without
        # oscillation): the stage starts from the design's value instead, and says so.
        value = _pcc_value(design, name)
        if isinstance(value, (tuple, list)):
            value = float(np.interp(0.0, *value))
        return float(value), None, f"design value (closed form failed: {exc})"


# --- the entry point -----------------------------------------------------------------------------


@one_blas_thread
def identify_pcc(
    design,
    dataset,
    params=PCC_PARAMETERS,
    *,
    experiments: Mapping | None = None,
    degree: int = 0,
    k_L=None,
    k_theta=None,
    dt="1 ms",
    threads: int = 0,
):
    """Identify PCC parameters of ``design`` from the tip positions of ``dataset`` as paper
    003 Sec. V does: one parameter per experiment, in the paper's order, each stage a fit of
    the PCC model through the calibration engine, then all of them together.

    params: "k_L", "k_theta", "b_L", "b_theta" or a list of them (fitted in that order).
    experiments: ``{param: id or [ids]}``, the experiment rows that identify each parameter.
    A parameter left out uses the experiment named after its kind ("elongation", "bending",
    "step", "free_decay", as :func:`synthesize_pcc_experiments` names them), or, when only
    one parameter is fitted and the dataset has at most one experiment, every row.
    degree: 0 (default) fits a constant k_theta; > 0 a table k_theta(theta) of
    TABLE_ENTRIES angles over the bending data (paper 003 Fig. 5c), started from a
    polynomial of this degree through M / theta, each entry a parameter ``k_theta[j]``.
    k_L, k_theta: values (SI or "246 N/m") to use instead of the design's when they are not
    fitted. dt: the time step of the replayed time series. threads: the core's workers.

    Returns the :class:`~softrod.calibration.CalibrationResult` of the last, joint fit
    (values, standard errors, correlations, warnings; ``result.design`` holds the values
    and ``result.to_toml`` writes it), with ``result.stages``: one row per parameter with
    its experiment, the closed-form start, how it was found, and the stage's value and
    standard error.
    """
    from ..calibration import calibrate

    design = load_design(design)
    if not isinstance(dataset, Dataset):
        dataset = load_dataset(dataset, design=design)
    if dataset.n_channels != design.n_channels:
        raise V.fail(
            "dataset.pressures",
            f"{dataset.n_channels} channels",
            f"design {design.name!r} has {design.n_channels} pressure channels",
        )
    dataset.require_tip("identify_pcc")
    names = _params(params)
    sec = _arm(design)
    if experiments is None:
        experiments = {}
    if not isinstance(experiments, Mapping):
        raise V.fail("experiments", experiments, "must map parameter names to experiment ids")
    extra = [k for k in experiments if k not in names]
    if extra:
        raise V.fail("experiments", extra, f"names parameters that are not fitted ({names})")
    if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)) or degree < 0:
        raise V.fail("degree", degree, "must be an integer >= 0 (0: a constant k_theta)")
    work = design  # the design with the values known so far: given, then fitted
    for name, value, kind in (("k_L", k_L, "force_per_length"), ("k_theta", k_theta, "moment")):
        if value is None:
            continue
        if name in names:
            raise V.fail(name, value, f"{name} is fitted here; do not also give it")
        si = to_si(value, kind, name, InputError)
        if not si > 0:
            raise V.fail(name, value, "must be > 0")
        work = work.replace({f"pcc.{name}": f"{si!r} {'N/m' if name == 'k_L' else 'N*m'}"})

    stages, used_rows, fitted, kinds = [], [], [], {}
    for name in names:
        rows, used = _rows(dataset, name, experiments, len(names))
        if rows.size == 0:
            raise V.fail(f"experiments[{name!r}]", used, "selects no rows")
        start, table, how = _closed_form(name, work, sec, dataset, rows, int(degree))
        if not (math.isfinite(start) and start > 0):
            value = _pcc_value(work, name)
            start = float(np.interp(0.0, *value)) if isinstance(value, (tuple, list)) else value
            how = "design value (the closed form gave no positive value)"
        if table is not None:
            angles, stiff = table
            work = work.replace(
                {
                    "pcc.k_theta": {
                        "angle": [f"{float(a)!r} rad" for a in angles],
                        "stiffness": [f"{float(k)!r} N*m" for k in stiff],
                    }
                }
            )
            stage_params = [f"k_theta[{j}]" for j in range(len(stiff))]
        else:
            work = work.replace({f"pcc.{name}": f"{float(start)!r} {_UNITS[name]}"})
            stage_params = [name]
        # Stiffnesses from equilibria, dampings from time series (Sec. V).
        kind = "static" if name in ("k_L", "k_theta") else "dynamic"
        for e in used:
            kinds[e] = kind
        stage = calibrate(
            work,
            dataset.subset(rows),
            stage_params,
            model="pcc",
            **_replay(dataset, used, kind),
            # A stiffness stage replays no time series: no time step.
            dt=dt if kind == "dynamic" else None,
            threads=threads,
            progress=False,
            # A stage's design keeps the name (the joint fit's result gets the new one).
            name=design.name if len(names) > 1 else None,
        )
        work = stage.design
        fitted += stage_params
        used_rows.append(rows)
        for p, v, s in zip(stage.names, stage.values, stage.std_errors, strict=True):
            stages.append(
                {
                    "parameter": p,
                    "experiments": ", ".join(map(str, used)),
                    "start": float(start) if table is None else np.nan,
                    "start_from": how,
                    "stage_value": float(v),
                    "stage_std_error": float(s),
                }
            )
    if len(names) == 1:
        result = stage
    else:
        rows = np.unique(np.concatenate(used_rows))
        result = calibrate(
            work,
            dataset.subset(rows),
            fitted,
            model="pcc",
            experiments=kinds,
            dt=dt if "dynamic" in kinds.values() else None,
            threads=threads,
            progress=False,
        )
    return dataclasses.replace(result, stages=pd.DataFrame(stages))


_UNITS = {"k_L": "N/m", "k_theta": "N*m", "b_L": "N*s/m", "b_theta": "N*m*s"}


def _replay(dataset: Dataset, used: list, kind: str) -> dict:
    """calibrate's arguments that make the experiments ``used`` equilibria or time series."""
    if dataset.experiment is None or not used:
        return {"dynamic": kind == "dynamic"}
    return {"experiments": dict.fromkeys(used, kind)}


# --- synthetic experiments -----------------------------------------------------------------------


_SETTINGS = {"pressure", "channels", "levels", "duration", "release", "id"}


def _default_channels(sec: dict, kind: str) -> list[int]:
    """Elongation and step: every channel; bending and decay: the chambers within 90 deg of
    the first one (chambers 6, 1, 2 of six, paper 003 Fig. 2 Case IV)."""
    if kind in ("elongation", "step"):
        return sorted({ch for *_, ch in sec["chambers"]})
    _, cx0, cy0, _ = sec["chambers"][0]
    a0 = math.atan2(cy0, cx0)
    return sorted(
        {ch for _, cx, cy, ch in sec["chambers"] if math.cos(math.atan2(cy, cx) - a0) > 1e-9}
    )


def _released(design: Design, sec: dict, pattern: np.ndarray, release, kind: str) -> np.ndarray:
    """Pressures after a release: zero, or "balanced": one pressure on every channel with the
    same axial force sum p A, so that the elongation does not creep back during the decay."""
    if release == "zero":
        return np.zeros_like(pattern)
    if release != "balanced":
        raise V.fail(f"experiments[{kind!r}].release", release, "must be 'zero' or 'balanced'")
    areas = np.zeros_like(pattern)
    for area, *_, ch in sec["chambers"]:
        areas[ch] += area
    out = np.full_like(pattern, float(pattern @ areas) / float(areas.sum()))
    if chamber_moment(design, out[None, :])[0] > 1e-9 * float(out @ areas) * design.length:
        raise V.fail(
            f"experiments[{kind!r}].release",
            release,
            "needs chambers whose equal pressure does not bend the arm",
        )
    return out


def _positive_number(value, name: str, kind: str | None = None) -> float:
    x = to_si(value, kind, name, InputError) if kind else value
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not (math.isfinite(x) and x > 0):
        raise V.fail(name, value, "must be a finite number > 0")
    return float(x)


def synthesize_pcc_experiments(
    design,
    experiments: Mapping,
    *,
    noise_mm: float = 0.0,
    seed: int | None = None,
    levels: int = 11,
    duration="3 s",
    rate=100.0,
    dt="1 ms",
) -> Dataset:
    """Paper 003's identification experiments made by the PCC model of ``design``.

    experiments: ``{kind: pressure}`` or ``{kind: {"pressure": ..., "channels": [...],
    "levels": n, "duration": "2 s", "id": ...}}`` with kind one of

    - "elongation": static equilibria at ``levels`` pressures from 0 to ``pressure`` on
      ``channels`` (default: every channel) at once (Sec. V-B);
    - "bending": the same on one side (default: the chambers within 90 deg of chamber 1;
      Sec. V-C);
    - "step": at rest under zero pressure, then ``pressure`` on ``channels`` (default every
      channel) from the second sample on, ``duration`` long (Sec. V-D);
    - "free_decay": at rest bent under ``pressure`` on one side, released from the second
      sample on, ``duration`` long (Sec. V-E). ``"release": "zero"`` (default) vents every chamber;
      the elongation the pressure caused then creeps back with the slow pole k_L / b_L
      during the decay, which changes the arm's inertia and reads as less damping (docs/
      pcc.md). ``"release": "balanced"`` sets every channel to the pressure with the same
      axial force instead, so that only the bending decays.

    Statics are the core's PCC equilibria, time series :func:`~softrod.pcc.run_pcc` with time
    step ``dt``, sampled at ``rate`` (Hz; 1 / (rate dt) must be an integer). A time series
    is driven by its sampled pressures joined linearly (a step rises over one sample
    interval), from rest in equilibrium under the first sample: exactly what
    ``softrod.calibrate(..., model="pcc")`` replays. The tip positions get isotropic Gaussian
    noise of ``noise_mm`` (per axis) from ``seed`` (drawn and recorded when None); rotations
    are noise-free. Experiment ids are the kinds (or ``id``). When any time series is present,
    static rows get time = index * 1 s within their experiment, so that all rows have a time.

    Returns one :class:`~softrod.Dataset`, ``metadata["synthetic"]`` True, with the design,
    its PCC parameters (``true_parameters``), the settings, noise and seed.
    """
    from .. import __version__
    from .model import run_pcc

    design = load_design(design)
    sec = _arm(design)
    if not isinstance(experiments, Mapping) or not experiments:
        raise V.fail(
            "experiments",
            experiments,
            "must map experiment kinds (elongation, bending, step, free_decay) to a pressure "
            "or a dict of settings",
        )
    seed = noise_seed(noise_mm, seed)
    dt_s = _positive_number(dt, "dt", "time")
    rate_hz = _positive_number(rate, "rate")
    ratio = 1.0 / (rate_hz * dt_s)
    save_every = int(round(ratio))
    if save_every < 1 or abs(ratio - save_every) > 1e-9 * ratio:
        raise V.fail("rate", rate, f"1 / (rate dt) must be an integer (dt = {dt_s:g} s)")

    model = pcc_model(design)
    kinds = tuple(EXPERIMENTS.values())
    parts, settings = [], {}
    for kind, spec in experiments.items():
        if kind not in kinds:
            raise V.fail("experiments", kind, f"unknown kind (known: {', '.join(kinds)})")
        spec = dict(spec) if isinstance(spec, Mapping) else {"pressure": spec}
        unknown = set(spec) - _SETTINGS
        if unknown:
            raise V.fail(
                f"experiments[{kind!r}]",
                sorted(unknown),
                f"unknown setting(s) (known: {', '.join(sorted(_SETTINGS))})",
            )
        if "pressure" not in spec:
            raise V.fail(f"experiments[{kind!r}]", spec, "needs a pressure")
        pressure = _positive_number(spec["pressure"], f"experiments[{kind!r}].pressure", "pressure")
        channels = spec.get("channels", _default_channels(sec, kind))
        if (
            not isinstance(channels, Sequence)
            or not channels
            or not all(
                isinstance(c, (int, np.integer)) and 0 <= c < design.n_channels for c in channels
            )
        ):
            raise V.fail(
                f"experiments[{kind!r}].channels",
                channels,
                f"must be channel indices 0..{design.n_channels - 1}",
            )
        pattern = np.zeros(design.n_channels)
        pattern[list(channels)] = pressure
        label = spec.get("id", kind)
        settings[kind] = {"id": label, "pressure_Pa": pressure, "channels": list(channels)}
        if kind in ("elongation", "bending"):
            n = spec.get("levels", levels)
            if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 3:
                raise V.fail(f"experiments[{kind!r}].levels", n, "must be an integer >= 3")
            p = np.outer(np.linspace(0.0, 1.0, int(n)), pattern)
            tips, rots, guess = [], [], None
            for row in p:
                out = model.statics(list(row), guess=guess)
                guess = out["x"]
                tips.append(out["tip_position"])
                rots.append(out["tip_rotation"])
            parts.append((label, p, np.array(tips), np.array(rots), None))
            settings[kind]["levels"] = int(n)
        else:
            dur = _positive_number(
                spec.get("duration", duration), f"experiments[{kind!r}].duration", "time"
            )
            n_steps = int(round(dur / dt_s / save_every)) * save_every
            if n_steps < 5 * save_every:
                raise V.fail(
                    f"experiments[{kind!r}].duration", dur, "must cover at least 5 samples"
                )
            # The samples: before (row 0) and after (rows 1..) the step or release.
            samples = np.zeros((n_steps // save_every + 1, design.n_channels))
            if kind == "step":
                samples[1:] = pattern
            else:
                samples[0] = pattern
                samples[1:] = _released(design, sec, pattern, spec.get("release", "zero"), kind)
                settings[kind]["release"] = spec.get("release", "zero")
            # The model is driven by the samples joined linearly, from rest in equilibrium
            # under the first sample, as calibrate replays a time series.
            t_s = np.arange(samples.shape[0]) * save_every * dt_s
            t_k = np.arange(n_steps + 1) * dt_s
            p = np.column_stack(
                [np.interp(t_k, t_s, samples[:, c]) for c in range(samples.shape[1])]
            )
            out = run_pcc(design, dt_s, p, save_every=save_every, initial="static")
            parts.append((label, samples, out["tip_position"], out["tip_rotation"], out["time"]))
            settings[kind]["duration_s"] = n_steps * dt_s
    labels = [lab for lab, *_ in parts]
    if len(set(map(str, labels))) != len(labels):
        raise V.fail("experiments", labels, "experiment ids must differ")
    timed = any(t is not None for *_, t in parts)
    rng = np.random.default_rng(int(seed))
    pressures = np.vstack([p for _, p, *_ in parts])
    tip = np.vstack([t for _, _, t, _, _ in parts])
    rot = np.concatenate([r for _, _, _, r, _ in parts])
    noise = rng.normal(0.0, noise_mm * 1e-3, tip.shape) if noise_mm > 0 else np.zeros(tip.shape)
    ids = np.concatenate([[lab] * len(p) for lab, p, *_ in parts])
    stamps = [
        t if t is not None else np.arange(len(p)) * STATIC_SAMPLE_PERIOD for _, p, *_, t in parts
    ]
    time = np.concatenate(stamps) if timed else None
    truth = pcc_parameters(design)[0]
    truth = {
        k: (list(map(list, v)) if isinstance(v, tuple) else v)
        for k, v in truth.items()
        if k != "name"
    }
    meta = {
        "synthetic": True,
        "note": "SYNTHETIC: generated by the softrod PCC model, not measurements",
        "generator": "softrod.pcc.synthesize_pcc_experiments",
        "softrod_version": __version__,
        "design": design.name,
        "design_source": None if design.source is None else design.source.name,
        "true_parameters": truth,
        "experiments": settings,
        "dt_s": dt_s,
        "rate_Hz": rate_hz,
        "noise_mm": float(noise_mm),
        "noise": "isotropic Gaussian on tip_position only (per axis, independent); "
        "tip_rotation is noise-free",
        "seed": int(seed),
    }
    return Dataset(
        pressures=pressures,
        tip_position=tip + noise,
        # Through the quaternion once, so the stored rotation is exactly what a file holds.
        tip_rotation=_quat_to_matrix(_matrix_to_quat(rot)),
        experiment=ids,
        time=time,
        metadata=meta,
    )
