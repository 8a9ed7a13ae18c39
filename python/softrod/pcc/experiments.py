"""Paper 003 Sec. V on softrod datasets: identify k_L, k_theta, b_L, b_theta from measured
tip positions, and synthesise the four experiments with the PCC model.

- :func:`identify_pcc`: the identification behind ``softrod.calibrate(..., model="pcc")``.
  Each parameter comes from its own experiment (rows of a :class:`~softrod.Dataset`):

  ========  ============  ==================================================================
  param     experiment    data and method
  ========  ============  ==================================================================
  k_L       elongation    static rows, equal pressure on a symmetric set of chambers;
                          elongation along the base axis; Hookean fit with an offset (V-B)
  k_theta   bending       static rows, chambers on one side; angle of the arc through the
                          tip; k = M / theta, the gravity moment removed by the model (V-C)
  b_L       step          time series after a pressure step (equal, symmetric); two modes
                          with poles tied to k_L and the model's mass (V-D)
  b_theta   free_decay    time series after a release; logarithmic decrement (V-E)
  ========  ============  ==================================================================

- :func:`synthesize_pcc_experiments`: the same experiments made by the PCC model itself
  (statics and :func:`~softrod.pcc.run_pcc` in the Rust core), with seeded tip noise, as one
  dataset whose experiment ids are the experiment names above.

The physics is the core's: Python selects rows, turns tip positions into elongations and
angles, and calls the fits of :mod:`softrod.pcc.identify` and the core's statics.
"""

from __future__ import annotations

import copy
import json
import math
from collections.abc import Mapping, Sequence

import numpy as np

from .. import _core
from .._threads import one_blas_thread
from ..catalog import load_design
from ..datasets import (
    Dataset,
    _matrix_to_quat,
    _quat_to_matrix,
    _runs,
    load_dataset,
    noise_seed,
)
from ..design import Design
from ..errors import ConvergenceError, InputError, design_error
from ..units import to_si
from .identify import (
    PccFit,
    bending_angle_from_tip,
    chamber_moment,
    fit_bending_damping,
    fit_bending_stiffness,
    fit_longitudinal_damping,
    fit_longitudinal_stiffness,
)
from .model import pcc_parameters

__all__ = [
    "EXPERIMENTS",
    "PCC_PARAMETERS",
    "identify_pcc",
    "synthesize_pcc_experiments",
]

#: The identifiable parameters in paper 003's order (Sec. V-B to V-E); a list of several is
#: fitted in this order, each fit using the values found before it.
PCC_PARAMETERS = ("k_L", "k_theta", "b_L", "b_theta")

#: The experiment (and default experiment id) each parameter is identified from.
EXPERIMENTS = {"k_L": "elongation", "k_theta": "bending", "b_L": "step", "b_theta": "free_decay"}

# A channel below this fraction of its row's largest pressure counts as unpressurised (a
# pressure sensor reads a few hundred Pa on a vented chamber).
ACTIVE_FRACTION = 0.05
# The pressurised channels of an elongation row must agree within this fraction of the row's
# largest pressure: the paper sets one pressure on three regulators, measured values differ
# by the regulators' accuracy (about 1 %).
EQUAL_PRESSURE_RTOL = 0.02
# Elongation rows must not bend the arm: |sum p A rho| <= BALANCE_RTOL * sum p A |rho|.
# Bending rows must: their moment must exceed it.
BALANCE_RTOL = 0.02
# Angles below this (rad) carry no information on k_theta (the fit drops them, as
# fit_bending_stiffness does by default).
MIN_ANGLE = 0.05
# A free decay must swing the bending angle by at least this (rad, 0.6 deg): less is not a
# decay of bending (an elongation record has round-off angles).
DECAY_MIN_SWING = 0.01
# Static rows of a combined synthetic dataset get time = index * this (s) within their
# experiment, so that static and time-series experiments share one file.
STATIC_SAMPLE_PERIOD = 1.0


def _fail(field: str, value, rule: str) -> InputError:
    return design_error(field, value, rule, InputError)


# --- the design --------------------------------------------------------------------------------


def _arm(design: Design) -> dict:
    """The one section of a single-section arm with chambers (paper 003's arm is one PCC
    segment from base to tip; eq. 14 reads the bending angle off the tip of that arc)."""
    sections = design.spec["sections"]
    if len(sections) != 1 or sections[0].get("rigid", False):
        raise _fail(
            "design.sections",
            f"{len(sections)} section(s) in {design.name!r}",
            "paper 003's identification needs a single deformable section (one PCC segment "
            "from base to tip, whose tip gives the bending angle by eq. 14)",
        )
    sec = design.sections()[0]
    if not sec["chambers"]:
        raise _fail("design.sections[0].chambers", "none", "the arm needs pressure chambers")
    return sec


def _base_frame(design: Design, tip: np.ndarray) -> np.ndarray:
    """Tip positions (m, 3) in the base frame: x, y in the cross-section, z along the axis."""
    mount = design.spec["mounting"]
    rot = np.asarray(mount["base_rotation"], dtype=float)
    return (np.asarray(tip, dtype=float) - np.asarray(mount["base_position"])) @ rot


def _pcc_value(design: Design, name: str) -> float:
    """The design's [pcc] value (after the defaults) of k_L or k_theta (a table: at 0 rad)."""
    seg = pcc_parameters(design)[0]
    value = seg[name]
    if isinstance(value, (tuple, list)):
        angles, stiff = value
        return float(np.interp(0.0, angles, stiff))
    return float(value)


class _Core:
    """Core PCC models of the design with some [pcc] values replaced (SI), built from the
    design's spec directly (no re-validation of the document per trial value)."""

    def __init__(self, design: Design):
        self.spec = copy.deepcopy(design.spec)
        self.spec.setdefault("pcc", {})

    def model(self, **pcc) -> _core.PccModel:
        spec = copy.deepcopy(self.spec)
        for key, value in pcc.items():
            if key == "k_theta":
                spec["pcc"].pop("k_theta_table", None)
            spec["pcc"][key] = float(value)
        return _core.PccModel(json.dumps(spec))


# --- rows ----------------------------------------------------------------------------------------


def _params(params) -> list[str]:
    names = [params] if isinstance(params, str) else params
    if not isinstance(names, Sequence) or isinstance(names, str) or not names:
        raise _fail("params", params, f"must be one or a list of {', '.join(PCC_PARAMETERS)}")
    unknown = [p for p in names if p not in PCC_PARAMETERS]
    if unknown:
        raise _fail(
            "params",
            unknown,
            f"model='pcc' identifies {', '.join(PCC_PARAMETERS)} (paper 003 Sec. V)",
        )
    if len(set(names)) != len(names):
        raise _fail("params", list(names), "names a parameter twice")
    return [p for p in PCC_PARAMETERS if p in names]


def _experiment_ids(value, name: str) -> list:
    ids = [value] if isinstance(value, (str, int, np.integer)) else value
    if (
        isinstance(value, bool)
        or not isinstance(ids, Sequence)
        or not ids
        or not all(isinstance(i, (str, int, np.integer)) and not isinstance(i, bool) for i in ids)
    ):
        raise _fail(f"experiments[{name!r}]", value, "must be an experiment id or a list of ids")
    return list(ids)


def _rows(dataset: Dataset, param: str, experiments: Mapping, n_params: int) -> tuple:
    """(row indices, the experiment ids used) of the rows that identify ``param``."""
    ids = dataset.experiments
    if param in experiments:
        wanted = _experiment_ids(experiments[param], param)
        if dataset.experiment is None:
            raise _fail(
                f"experiments[{param!r}]",
                experiments[param],
                "the dataset has no experiment column to select rows by",
            )
        unknown = [w for w in wanted if not any(_same(w, k) for k in ids)]
        if unknown:
            raise _fail(
                f"experiments[{param!r}]",
                unknown,
                f"unknown experiment id(s); the dataset has {', '.join(map(repr, ids))}",
            )
    elif EXPERIMENTS[param] in ids:
        wanted = [EXPERIMENTS[param]]
    elif n_params == 1 and len(ids) <= 1:
        return np.arange(len(dataset)), list(ids)
    else:
        raise _fail(
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


def _same(a, b) -> bool:
    if isinstance(a, (int, np.integer)) and isinstance(b, (int, np.integer)):
        return int(a) == int(b)
    return isinstance(a, str) and isinstance(b, str) and a == b


def _time_series(dataset: Dataset, rows: np.ndarray, param: str, used: list) -> np.ndarray:
    """The rows of one time series sorted by time, from the last pressure change on (the
    response to the step or release that the fit describes)."""
    if dataset.time is None:
        raise _fail(
            "dataset.time",
            None,
            f"{param} is identified from a time series ({EXPERIMENTS[param]}); the dataset has "
            "no time column",
        )
    if len(used) > 1:
        raise _fail(
            f"experiments[{param!r}]", used, "name one experiment (one time series) per fit"
        )
    rows = rows[np.argsort(dataset.time[rows], kind="stable")]
    t = dataset.time[rows]
    if np.any(np.diff(t) <= 0):
        raise _fail(
            "dataset.time",
            f"repeated times in experiment {used[0] if used else ''!r}",
            "a time series must have one row per time",
        )
    p = dataset.pressures[rows]
    scale = max(float(np.abs(p).max()), 1.0)
    differs = np.abs(p - p[-1]).max(axis=1) > EQUAL_PRESSURE_RTOL * scale
    start = int(np.flatnonzero(differs)[-1] + 1) if differs.any() else 0
    rows = rows[start:]
    if rows.size < 5:
        raise _fail(
            "rows",
            f"{rows.size} samples after the last pressure change",
            f"{param} needs a time series of the response (>= 5 samples)",
        )
    return rows


def _row_checks(design: Design, sec: dict, p: np.ndarray, rows: np.ndarray, balanced: bool):
    """Sum of p A (N) per row; raise if a row of an elongation (``balanced``) experiment
    bends the arm or has unequal pressures, or a row of a bending one does not bend it."""
    force = np.zeros(len(p))
    lever = np.zeros(len(p))
    for area, cx, cy, ch in sec["chambers"]:
        force += p[:, ch] * area
        lever += np.abs(p[:, ch]) * area * math.hypot(cx, cy)
    moment = chamber_moment(design, p) if len(p) else np.zeros(0)
    top = np.abs(p).max(axis=1) if len(p) else np.zeros(0)
    loaded = top > 0
    if balanced:
        spread = np.zeros(len(p))
        for i in np.flatnonzero(loaded):
            act = p[i][p[i] > ACTIVE_FRACTION * top[i]]
            spread[i] = (act.max() - act.min()) / top[i]
        bad = np.flatnonzero(spread > EQUAL_PRESSURE_RTOL)
        if bad.size:
            raise _fail(
                "dataset.pressures",
                f"rows {_runs(rows[bad])}",
                "k_L and b_L need equal pressure on every pressurised channel "
                f"(within {EQUAL_PRESSURE_RTOL:.0%}; paper 003 Sec. V-B)",
            )
        bad = np.flatnonzero(moment > BALANCE_RTOL * lever)
        if bad.size:
            raise _fail(
                "dataset.pressures",
                f"rows {_runs(rows[bad])}",
                "the pressurised chambers bend the arm (their moment exceeds "
                f"{BALANCE_RTOL:.0%} of sum p A |rho|): k_L and b_L need a symmetric set "
                "such as chambers 1, 3, 5 of six",
            )
    else:
        bad = np.flatnonzero(loaded & (moment <= BALANCE_RTOL * lever))
        if bad.size:
            raise _fail(
                "dataset.pressures",
                f"rows {_runs(rows[bad])}",
                "k_theta needs one-side pressurisation (paper 003 Sec. V-C); these rows "
                "pressurise a symmetric set that does not bend the arm",
            )
    return force


# --- the four fits -----------------------------------------------------------------------------


def _fit_k_L(design, sec, dataset, rows):
    p = dataset.pressures[rows]
    force = _row_checks(design, sec, p, rows, balanced=True)
    if np.ptp(force) <= 0:
        raise _fail(
            "dataset.pressures",
            f"one pressure level in {rows.size} rows",
            "k_L needs at least two pressure levels",
        )
    local = _base_frame(design, dataset.tip_position[rows])
    elong = local[:, 2] - design.length
    # n p A summed over the chambers is the generalised force on L; pass it as the
    # "pressure" on one chamber of unit area.
    fit = fit_longitudinal_stiffness(force, elong, area=1.0, n_chambers=1, offset=True)
    details = dict(fit.details)
    details["reference"] = (
        "elongation = tip along the base axis minus the design's length; the offset force "
        "takes the weight and any error of the reference"
    )
    return fit.values["k_L"], fit.stderr["k_L"], fit.residual, fit.residual_unit, details, None


def _secant_stiffness(core: _Core, p, theta: float, start: float, row: int):
    """The constant k_theta with which the core's statics (with gravity) bends the arm to
    ``theta`` at pressures ``p``: k_theta theta = (pressure - gravity) moment at that state,
    the secant stiffness at theta (brentq on k, derivative-free)."""
    from scipy.optimize import brentq

    guess = [None]

    def angle(k):
        model = core.model(k_theta=k)
        try:
            out = model.statics(list(p), guess=guess[0])
        except ConvergenceError:
            out = model.statics(list(p))  # the warm start may be on the wrong side
        guess[0] = out["x"]
        return abs(out["q"][1]) - theta

    try:
        lo = hi = start
        f_lo = f_hi = angle(start)
        for _ in range(60):
            if f_hi < 0 < f_lo:
                break
            if f_lo <= 0:  # too stiff: soften
                hi, f_hi = lo, f_lo
                lo /= 1.25
                f_lo = angle(lo)
            else:  # too soft: stiffen
                lo, f_lo = hi, f_hi
                hi *= 1.25
                f_hi = angle(hi)
        else:
            raise ConvergenceError(f"no stiffness brackets {theta:.4g} rad")
        return brentq(angle, lo, hi, xtol=1e-14, rtol=1e-12)
    except ConvergenceError as exc:
        raise ConvergenceError(
            f"row {row}: the PCC model with gravity does not reach the measured bending angle "
            f"{math.degrees(theta):.2f} deg for any k_theta ({exc}); use gravity='include'",
            0,
            float("nan"),
            1.0,
            "k_theta gravity correction",
        ) from None


def _fit_k_theta(design, sec, dataset, rows, degree, gravity):
    p = dataset.pressures[rows]
    _row_checks(design, sec, p, rows, balanced=False)
    local = _base_frame(design, dataset.tip_position[rows])
    theta = bending_angle_from_tip(np.hypot(local[:, 0], local[:, 1]), local[:, 2])
    moment = chamber_moment(design, p)
    raw = fit_bending_stiffness(theta, moment, degree=degree, min_angle=MIN_ANGLE)
    g = float(np.linalg.norm(design.spec["mounting"]["gravity"]))
    details: dict = {"gravity": gravity}
    if gravity == "include" or g == 0:
        fit = raw
    else:
        core = _Core(design)
        use = np.flatnonzero(theta >= MIN_ANGLE)
        k_i = np.array(
            [_secant_stiffness(core, p[i], theta[i], moment[i] / theta[i], rows[i]) for i in use]
        )
        fit = fit_bending_stiffness(
            theta[use], k_i * theta[use], degree=degree, min_angle=MIN_ANGLE
        )
        details["k_theta_gravity_included"] = raw.values["k_theta"]
        details["gravity_moment"] = moment[use] - k_i * theta[use]
        details["k_per_sample"] = k_i
    details.update(fit.details)
    details["theta"] = theta
    table = fit.table if degree > 0 else None
    return (
        fit.values["k_theta"],
        fit.stderr["k_theta"],
        fit.residual,
        fit.residual_unit,
        details,
        table,
    )


def _fit_b_L(design, sec, dataset, rows, used):
    rows = _time_series(dataset, rows, "b_L", used)
    p = dataset.pressures[rows]
    _row_checks(design, sec, p[-1:], rows[-1:], balanced=True)
    core = _Core(design).model()
    x = core.statics(list(p[-1]))["x"]
    mass = float(core.mass_matrix(list(x))[0][0])
    k = _pcc_value(design, "k_L")
    local = _base_frame(design, dataset.tip_position[rows])
    elong = local[:, 2] - design.length
    fit = fit_longitudinal_damping(dataset.time[rows], elong, k_L=k, mass=mass, poles="tied")
    details = {**fit.details, "k_L": k, "samples": int(rows.size)}
    return fit.values["b_L"], fit.stderr["b_L"], fit.residual, fit.residual_unit, details, None


def _fit_b_theta(design, sec, dataset, rows, used, inertia):
    rows = _time_series(dataset, rows, "b_theta", used)
    p = dataset.pressures[rows]
    local = _base_frame(design, dataset.tip_position[rows])
    # The plane of the decay: principal direction of the tip's (x, y) in the base frame,
    # signed so that the first sample is on the positive side.
    xy = local[:, :2]
    _, _, vt = np.linalg.svd(xy, full_matrices=False)
    u = vt[0] if xy[0] @ vt[0] >= 0 else -vt[0]
    theta = bending_angle_from_tip(xy @ u, local[:, 2])
    swing = float(np.ptp(theta))
    if swing < DECAY_MIN_SWING:
        raise _fail(
            "rows",
            f"bending angle range {math.degrees(swing):.3g} deg",
            f"b_theta needs a free decay of bending (the angle must swing by at least "
            f"{math.degrees(DECAY_MIN_SWING):.2g} deg; paper 003 Sec. V-E)",
        )
    core = _Core(design).model()
    x = core.statics(list(p[-1]))["x"]
    mm = np.asarray(core.mass_matrix(list(x)))
    if inertia is not None:
        j = inertia
    elif core.planar:
        j = float(mm[1, 1])
    else:
        # The bending vector (theta_x, theta_y) points where the tip moves (docs/pcc.md).
        j = float(u @ mm[1:3, 1:3] @ u)
    k = _pcc_value(design, "k_theta")
    fit = fit_bending_damping(dataset.time[rows], theta, k_theta=k, inertia=j)
    zeta, wn = fit.details["damping_ratio"], fit.details["omega_n"]
    # Damped oscillator J theta'' + b theta' + k_eff theta = 0: b = 2 zeta omega_n J. k_eff
    # = J omega_n^2 is the stiffness the decay shows, gravity included; paper 003's
    # b = 2 zeta sqrt(k_theta J) is the same when k_theta = k_eff.
    b = 2.0 * zeta * wn * j
    se = b * math.hypot(
        fit.details["damping_ratio_stderr"] / zeta, fit.details["omega_n_stderr"] / wn
    )
    details = {
        **fit.details,
        "k_theta_from_period": j * wn**2,
        "b_theta_paper": fit.values["b_theta"],
        "k_theta_paper": k,
        "samples": int(rows.size),
    }
    return b, se, fit.residual, fit.residual_unit, details, None


# --- the entry point -----------------------------------------------------------------------------


@one_blas_thread
def identify_pcc(
    design,
    dataset,
    params,
    *,
    experiments: Mapping | None = None,
    degree: int = 0,
    gravity: str = "subtract",
    k_L=None,
    k_theta=None,
    inertia=None,
) -> PccFit:
    """Identify PCC parameters of ``design`` from the tip positions of ``dataset`` as paper
    003 Sec. V does (``softrod.calibrate(design, dataset, params, model="pcc")`` calls this).

    params: "k_L", "k_theta", "b_L", "b_theta" or a list of them, fitted in that order, each
    fit using the values found before it (b_L uses k_L, the gravity correction of k_theta
    uses k_L, b_theta reports the paper's formula with k_theta).
    experiments: ``{param: id or [ids]}``, the experiment rows that identify each parameter.
    A parameter left out uses the experiment named after its kind ("elongation", "bending",
    "step", "free_decay", as :func:`synthesize_pcc_experiments` names them), or, when only
    one parameter is fitted and the dataset has at most one experiment, every row.
    degree: k_theta(theta) = M/theta as a polynomial of this degree; 0 (default) fits a
    constant, > 0 also a table (``fit.table``) that ``to_design`` writes.
    gravity: "subtract" (default): k_theta of each bent sample is the constant stiffness with
    which the design's PCC model (its mass, mounting and k_L) reaches the measured angle at
    the measured pressures, so the gravity moment is taken out and the model reproduces the
    data; "include": paper 003's M/theta with the chamber moment alone, an effective stiffness
    that contains the gravity moment of the experiment's mounting.
    k_L, k_theta: values (SI or "246 N/m") to use instead of the design's when they are not
    fitted. inertia: J (kg m^2) for b_theta instead of the model's (the mass matrix at rest).

    Returns a :class:`~softrod.pcc.PccFit` whose ``details[param]`` holds each fit's
    residual, residual unit, the experiments and rows used and the fit's own details; its
    ``design`` is ``design``, so ``fit.to_toml(path)`` writes the identified design.
    """
    design = load_design(design)
    if not isinstance(dataset, Dataset):
        dataset = load_dataset(dataset, design=design)
    if dataset.n_channels != design.n_channels:
        raise _fail(
            "dataset.pressures",
            f"{dataset.n_channels} channels",
            f"design {design.name!r} has {design.n_channels} pressure channels",
        )
    names = _params(params)
    sec = _arm(design)
    if experiments is None:
        experiments = {}
    if not isinstance(experiments, Mapping):
        raise _fail("experiments", experiments, "must map parameter names to experiment ids")
    extra = [k for k in experiments if k not in names]
    if extra:
        raise _fail("experiments", extra, f"names parameters that are not fitted ({names})")
    if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)) or degree < 0:
        raise _fail("degree", degree, "must be an integer >= 0 (0: a constant k_theta)")
    if gravity not in ("subtract", "include"):
        raise _fail("gravity", gravity, "must be 'subtract' or 'include'")
    work = design  # the design with the values known so far: given, then fitted
    for name, value, kind in (("k_L", k_L, "force_per_length"), ("k_theta", k_theta, "moment")):
        if value is None:
            continue
        if name in names:
            raise _fail(name, value, f"{name} is fitted here; do not also give it")
        si = to_si(value, kind, name, InputError)
        if not si > 0:
            raise _fail(name, value, "must be > 0")
        work = PccFit({name: si}, {name: 0.0}, 0.0, "").to_design(work)
    j = None
    if inertia is not None:
        j = to_si(inertia, "inertia", "inertia", InputError)
        if not j > 0:
            raise _fail("inertia", inertia, "must be > 0 kg m^2")

    values, stderr, details = {}, {}, {}
    table = None
    residual, residual_unit = float("nan"), ""
    for name in names:
        rows, used = _rows(dataset, name, experiments, len(names))
        if rows.size == 0:
            raise _fail(f"experiments[{name!r}]", used, "selects no rows")
        if name == "k_L":
            out = _fit_k_L(work, sec, dataset, rows)
        elif name == "k_theta":
            out = _fit_k_theta(work, sec, dataset, rows, int(degree), gravity)
        elif name == "b_L":
            out = _fit_b_L(work, sec, dataset, rows, used)
        else:
            out = _fit_b_theta(work, sec, dataset, rows, used, j)
        value, se, res, unit, info, tab = out
        values[name], stderr[name] = float(value), float(se)
        details[name] = {
            "residual": float(res),
            "residual_unit": unit,
            "experiments": used,
            "rows": int(rows.size),
            **info,
        }
        if tab is not None:
            table = tab
        residual, residual_unit = (float(res), unit) if len(names) == 1 else (residual, "")
        # The later fits use this value (and the design written at the end gets it).
        step = PccFit({name: values[name]}, {name: stderr[name]}, res, unit, table=tab)
        work = step.to_design(work)
    return PccFit(values, stderr, residual, residual_unit, details, table, design=design)


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
        raise _fail(f"experiments[{kind!r}].release", release, "must be 'zero' or 'balanced'")
    areas = np.zeros_like(pattern)
    for area, *_, ch in sec["chambers"]:
        areas[ch] += area
    out = np.full_like(pattern, float(pattern @ areas) / float(areas.sum()))
    if chamber_moment(design, out[None, :])[0] > 1e-9 * float(out @ areas) * design.length:
        raise _fail(
            f"experiments[{kind!r}].release",
            release,
            "needs chambers whose equal pressure does not bend the arm",
        )
    return out


def _positive_number(value, name: str, kind: str | None = None) -> float:
    x = to_si(value, kind, name, InputError) if kind else value
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not (math.isfinite(x) and x > 0):
        raise _fail(name, value, "must be a finite number > 0")
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
      channel) from t = 0, ``duration`` long (Sec. V-D);
    - "free_decay": at rest bent under ``pressure`` on one side, released at t = 0,
      ``duration`` long (Sec. V-E). ``"release": "zero"`` (default) vents every chamber;
      the elongation the pressure caused then creeps back with the slow pole k_L / b_L
      during the decay, which changes the arm's inertia and reads as less damping (docs/
      pcc.md). ``"release": "balanced"`` sets every channel to the pressure with the same
      axial force instead, so that only the bending decays.

    Statics are the core's PCC equilibria, time series :func:`~softrod.pcc.run_pcc` with time
    step ``dt``, sampled at ``rate`` (Hz; 1 / (rate dt) must be an integer). Pressures apply
    from the step times (the first step of a step or release averages the two rows, as
    run_pcc's midpoint rule does). The tip positions get isotropic Gaussian noise of
    ``noise_mm`` (per axis) from ``seed`` (drawn and recorded when None); rotations are
    noise-free. Experiment ids are the kinds (or ``id``). When any time series is present,
    static rows get time = index * 1 s within their experiment, so that all rows have a time.

    Returns one :class:`~softrod.Dataset`, ``metadata["synthetic"]`` True, with the design,
    its PCC parameters (``true_parameters``), the settings, noise and seed.
    """
    from .. import __version__
    from .model import run_pcc

    design = load_design(design)
    sec = _arm(design)
    if not isinstance(experiments, Mapping) or not experiments:
        raise _fail(
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
        raise _fail("rate", rate, f"1 / (rate dt) must be an integer (dt = {dt_s:g} s)")

    model = _Core(design).model()
    kinds = tuple(EXPERIMENTS.values())
    parts, settings = [], {}
    for kind, spec in experiments.items():
        if kind not in kinds:
            raise _fail("experiments", kind, f"unknown kind (known: {', '.join(kinds)})")
        spec = dict(spec) if isinstance(spec, Mapping) else {"pressure": spec}
        unknown = set(spec) - _SETTINGS
        if unknown:
            raise _fail(
                f"experiments[{kind!r}]",
                sorted(unknown),
                f"unknown setting(s) (known: {', '.join(sorted(_SETTINGS))})",
            )
        if "pressure" not in spec:
            raise _fail(f"experiments[{kind!r}]", spec, "needs a pressure")
        pressure = _positive_number(spec["pressure"], f"experiments[{kind!r}].pressure", "pressure")
        channels = spec.get("channels", _default_channels(sec, kind))
        if (
            not isinstance(channels, Sequence)
            or not channels
            or not all(
                isinstance(c, (int, np.integer)) and 0 <= c < design.n_channels for c in channels
            )
        ):
            raise _fail(
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
                raise _fail(f"experiments[{kind!r}].levels", n, "must be an integer >= 3")
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
                raise _fail(f"experiments[{kind!r}].duration", dur, "must cover at least 5 samples")
            p = np.zeros((n_steps + 1, design.n_channels))
            if kind == "step":
                p[1:] = pattern
                initial = "rest"
            else:
                p[0] = pattern
                p[1:] = _released(design, sec, pattern, spec.get("release", "zero"), kind)
                settings[kind]["release"] = spec.get("release", "zero")
                initial = "static"
            out = run_pcc(design, dt_s, p, save_every=save_every, initial=initial)
            parts.append(
                (label, p[::save_every], out["tip_position"], out["tip_rotation"], out["time"])
            )
            settings[kind]["duration_s"] = n_steps * dt_s
    labels = [lab for lab, *_ in parts]
    if len(set(map(str, labels))) != len(labels):
        raise _fail("experiments", labels, "experiment ids must differ")
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
