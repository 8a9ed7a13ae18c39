"""``softrod.calibrate``: the one entry of the calibration engine (docs/calibration.md).

It checks the arguments once, builds a :class:`~softrod.calibration.problem.Problem` (the
parameters with units, bounds and transforms; a model adapter with exact parameter
Jacobians; the observations with per-quantity weights; the split), hands it to the solver
layer (:mod:`softrod.calibration.solve`), reads standard errors and identifiability off the
Jacobian at the optimum (:mod:`softrod.calibration.diagnostics`) and returns one
:class:`~softrod.calibration.result.CalibrationResult`, whatever the model:

- ``model="cosserat"`` (default): equilibria of the rod (paper 002's fits), or with
  ``dynamic=True`` time series replayed (paper 000's tau and A_eff);
- ``model="pcc"``: paper 003's PCC model, equilibria and time series in one problem.

Motion-capture markers anywhere on the body enter beside (or instead of) the tip, and the
measurement frame (a rotation about the base axis and an offset, paper 000 Sec. III-D) is
fitted with the material parameters when ``registration_*`` parameters are named.
"""

from __future__ import annotations

import logging
import math
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import _validate as V
from .._threads import one_blas_thread
from ..catalog import load_design
from ..constraints import require_free_tip
from ..datasets import Dataset, load_dataset
from ..design import Design
from ..errors import CalibrationWarning, ConvergenceError
from ..progress import reporter
from ..statics import SolverOptions
from .diagnostics import (
    POOR_RELATIVE_ERROR,
    STRONG_CORRELATION,
    UNIDENTIFIABLE_CONDITION,
    diagnostics,
    warning_thresholds,
)
from .problem import (
    DEFAULT_SCALE_M,
    DEFAULT_SCALE_N,
    DEFAULT_SCALE_NM,
    QUANTITIES,
    REGISTRATION,
    Bounds,
    Observations,
    Problem,
    Registered,
    RegistrationParameter,
    Residual,
)
from .result import (
    CalibrationResult,
    error_tables,
    reaction_error_table,
    record,
    result_json,
)
from .solve import (
    METHODS,
    RESTART_SPREAD,
    Settings,
    check_restarts,
    default_bounds,
    run_starts,
    start_points,
)
from .solve import starts_table as _starts_table

if TYPE_CHECKING:
    from .._types import ArrayLike, DesignLike, PathLike, Quantity

__all__ = [
    "POOR_RELATIVE_ERROR",
    "RESTART_SPREAD",
    "STRONG_CORRELATION",
    "UNIDENTIFIABLE_CONDITION",
    "CalibrationResult",
    "CalibrationWarning",
    "calibrate",
    "result_json",
    "warning_thresholds",
]

logger = logging.getLogger(__name__)

#: SI unit of a parameter -> the quantity kind its bounds are read as.
_BOUND_KINDS = {
    "Pa": "pressure",
    "m": "length",
    "rad": "angle",
    "s": "time",
    "kg": "mass",
    "kg/m^3": "density",
    "N/m": "force_per_length",
    "N*s/m": "damping_linear",
    "N*m": "moment",
    "N*m*s": "damping_rotational",
}


def _evaluations(evaluations: int, rms_mm: float) -> tuple[float, str]:
    """A progress bar's position and text for calibrate's progress(evaluations, rms_mm)."""
    return evaluations, f"{evaluations} evaluations, RMS position error {rms_mm:.3g} mm"


# --- inputs --------------------------------------------------------------------------------


def _bounds(params, bounds, initial: np.ndarray) -> Bounds:
    """Bounds in SI: the user's, else the sanity box of :func:`solve.default_bounds`."""
    out = default_bounds(params, initial)
    if bounds is None:
        return out
    if not isinstance(bounds, Mapping):
        raise V.fail("bounds", bounds, "must map parameter names to (lower, upper)")
    lo, hi, given = out.lower.copy(), out.upper.copy(), out.given.copy()
    names = [p.name for p in params]
    for name, pair in bounds.items():
        if name not in names:
            raise V.fail("bounds", name, f"is not a calibrated parameter ({', '.join(names)})")
        j = names.index(name)
        if not isinstance(pair, Sequence) or isinstance(pair, str) or len(pair) != 2:
            raise V.fail(f"bounds[{name}]", pair, "must be a pair (lower, upper)")
        kind = _BOUND_KINDS.get(params[j].unit)
        vals = [
            V.quantity(v, kind, f"bounds[{name}]")
            if kind is not None
            else V.real(v, f"bounds[{name}]")
            for v in pair
        ]
        if not vals[0] < vals[1]:
            raise V.fail(f"bounds[{name}]", pair, "lower must be below upper")
        if params[j].positive and vals[0] <= 0:
            raise V.fail(f"bounds[{name}]", pair, f"{params[j].name} must stay > 0")
        if not vals[0] <= initial[j] <= vals[1]:
            raise V.fail(f"bounds[{name}]", pair, f"must contain the starting value {initial[j]:g}")
        lo[j], hi[j] = vals
        given[j] = True
    return Bounds(lo, hi, given)


def _split(dataset: Dataset, split, test) -> np.ndarray:
    """Boolean test mask."""
    m = len(dataset)
    if split is None:
        if test is not None:
            raise V.fail("test", test, "needs split='experiment' or split='mounting'")
        return np.zeros(m, dtype=bool)
    if isinstance(split, str):
        if split not in ("experiment", "mounting"):
            raise V.fail("split", split, "must be 'experiment', 'mounting', a mask or None")
        if getattr(dataset, split) is None:
            raise V.fail("split", split, f"the dataset has no {split} column")
        if test is None:
            if split == "mounting":
                raise V.fail("test", None, "name the test mounting(s)")
            ids = dataset.experiments
            if len(ids) < 2:
                raise V.fail(
                    "test", None, f"the dataset has {len(ids)} experiment: nothing to test"
                )
            test = ids[-1]  # documented default: the last experiment is the test set
        dataset.split(split, test=test)  # checks the ids
        labels = getattr(dataset, split)
        ids = [test] if isinstance(test, (str, int, np.integer)) else list(test)
        return np.isin(labels, ids)
    mask = np.asarray(split)
    if mask.dtype != bool or mask.shape != (m,):
        raise V.fail("split", f"array of shape {mask.shape}", f"a test mask must be bool ({m},)")
    if mask.all():
        raise V.fail("split", "all rows", "leaves nothing to train on")
    return mask.copy()


#: Per measured quantity: (its dataset field, the kind of its weight, default weight, SI).
_WEIGHTS = {
    "tip": ("tip_position", "length", DEFAULT_SCALE_M),
    "markers": ("markers", "length", DEFAULT_SCALE_M),
    "reaction": ("tip_reaction_force", "force", DEFAULT_SCALE_N),
    "reaction_moment": ("tip_reaction_moment", "moment", DEFAULT_SCALE_NM),
}


def _scales(weights, dataset: Dataset) -> dict[str, float]:
    """Residual scale (SI) of each measured quantity: ``weights`` = {quantity: standard
    deviation of its measurement} (a residual reads in units of it): lengths for "tip" and
    "markers" (default 1 mm), a force for "reaction" (default 5 mN) and a moment for
    "reaction_moment" (default 0.5 N mm)."""
    present = [q for q in QUANTITIES if getattr(dataset, _WEIGHTS[q][0]) is not None]
    scales = {q: _WEIGHTS[q][2] for q in present}
    if weights is None:
        return scales
    if not isinstance(weights, Mapping):
        raise V.fail(
            "weights",
            weights,
            "must map measured quantities ('tip', 'markers': lengths; 'reaction': a force; "
            "'reaction_moment': a moment) to standard deviations",
        )
    for key, value in weights.items():
        if key not in QUANTITIES:
            raise V.fail(
                f"weights[{key!r}]", value, f"unknown quantity (known: {', '.join(QUANTITIES)})"
            )
        if key not in present:
            raise V.fail(f"weights[{key!r}]", value, f"the dataset has no {key} columns")
        kind = _WEIGHTS[key][1]
        x = V.quantity(value, kind, f"weights[{key!r}]")
        if not x > 0:
            raise V.fail(
                f"weights[{key!r}]",
                value,
                f"must be {'an' if kind[0] in 'aeiou' else 'a'} {kind} > 0 (the "
                "measurement's standard deviation)",
            )
        scales[key] = x
    return scales


def _what(dataset: Dataset, dynamic: bool) -> str:
    parts = []
    if dataset.tip_position is not None:
        parts.append("tip")
    if dataset.markers is not None:
        parts.append("marker")
    texts = [f"the {' and '.join(parts)} positions"] if parts else []
    if dataset.tip_reaction_force is not None or dataset.tip_reaction_moment is not None:
        texts.append("the held tip's reactions")
    return " and ".join(texts) + (" along the replayed trajectories" if dynamic else "")


def _split_params(names, design: Design, model: str):
    """(model parameter names, registration parameters) of ``params``."""
    if isinstance(names, str):
        import re

        names = [n.strip() for n in re.split(r",(?![^\[]*\])", names) if n.strip()]
    if not isinstance(names, (list, tuple)):
        raise V.fail("params", names, "must be a name, a comma-separated string or a list of names")
    reg, rest = [], []
    for n in names:
        key = n.strip() if isinstance(n, str) else n
        if isinstance(key, str) and key in REGISTRATION:
            if any(p.name == key for p in reg):
                raise V.fail("params", key, "is named twice")
            reg.append(RegistrationParameter(key, REGISTRATION[key]))
        else:
            rest.append(n)
    if not rest and not reg:
        raise V.fail("params", names, "name at least one parameter")
    return rest, reg


def resolve_parameters(design: Design, params, model: str = "cosserat") -> list:
    """The parameter objects (name, unit, positive) that ``params`` names for ``model``, in
    order: the model's, then the registration's (for messages and the CLI's units)."""
    V.choice(model, ("cosserat", "pcc"), "model")
    names, registration = _split_params(params, design, model)
    if model == "pcc":
        from .adapters.pcc import parse_pcc_parameters

        found = parse_pcc_parameters(names) if names else []
    else:
        from .params import parse_parameters

        found = parse_parameters(names, design) if names else []
    return [*found, *registration]


# --- the entry point ---------------------------------------------------------------------------


@one_blas_thread
def calibrate(
    design: DesignLike,
    dataset: Dataset | PathLike,
    params: Sequence[str] | str,
    *,
    bounds: Mapping[str, Sequence] | None = None,
    method: str | None = None,
    split: str | ArrayLike | None = None,
    test: Any = None,
    options: SolverOptions | None = None,
    threads: int = 0,
    max_evaluations: int = 200,
    progress: Callable[[int, float], None] | None = None,
    dynamic: bool = False,
    dt: Quantity | None = None,
    model: str = "cosserat",
    experiments: Mapping | None = None,
    weights: Mapping[str, Quantity] | None = None,
    restarts: int = 0,
    seed: int = 0,
    executor: Any = None,
    name: str | None = None,
) -> CalibrationResult:
    """Fit ``params`` of ``design`` to the measured positions in ``dataset``.

    design: a design (path, bundled name, preset or :class:`~softrod.Design`).
    dataset: a :class:`~softrod.Dataset` or a path to one, with tip positions, markers
    anywhere on the body (docs/datasets.md; in time series too, ``dynamic=True``), or
    both. Rows with a ``mounting`` of "hanging", "upright" or "horizontal" are solved with
    that orientation (paper 002 fits vertical and horizontal experiments together). The
    design's tip loads apply to all rows.
    params: names such as ``["c_b", "c_e", "alpha", "offset_1", "offset_2", "c_p"]`` (see
    :mod:`softrod.calibration.params`); with ``dynamic=True`` also ``"damping_time"``; with
    ``model="pcc"`` the PCC parameters ``"k_L"``, ``"k_theta"`` (or ``"k_theta[j]"``, the
    j-th stiffness of the design's k_theta table), ``"b_L"``, ``"b_theta"``, ``"k_phi"``,
    ``"b_phi"``. Any model takes the registration parameters ``"registration_angle"``
    (rotation about the base axis, rad) and ``"registration_x"``, ``"_y"``, ``"_z"`` (offset
    of the measurement frame, m), fitted jointly (paper 000 Sec. III-D).
    bounds: optional ``{name: (lower, upper)}`` in SI or with units ("40 kPa").
    method: "lm" (exact Jacobian; the default: Levenberg-Marquardt, trust-region reflective
    with bounds) or "nelder-mead" (derivative-free simplex, an explicit fallback; the
    standard errors come from the exact Jacobian at its optimum). The rod's time series
    (``dynamic=True``) get their exact Jacobian from the core's forward sensitivities
    through every time step (BDF-alpha with fixed steps; every design feature, contact with
    obstacles included: docs/calibration.md). A design whose ``[tip]`` pins or clamps the
    tip is fitted in statics with the held tip's exact sensitivities (the tip stays at its
    prescribed position, so the dataset must have markers or the measured reaction, the
    blocked force: columns ``tip_reaction_fx_N`` ..., docs/datasets.md; without either
    ``calibrate`` raises an InputError naming ``dataset.markers`` and the reaction columns,
    since no parameter moves a held tip); the dynamic fit fits a held tip's markers along
    the trajectories with the same exact derivatives (without markers it raises an
    InputError naming ``dataset.markers``; it reads no reaction), and ``model="pcc"``
    refuses it (``tip_constraint``). A free tip has no reaction: a dataset with reaction
    columns is refused for it (``dataset.tip_reaction_force``).
    weights: ``{quantity: standard deviation}`` per measured quantity: "tip", "markers"
    (lengths, default 1 mm), "reaction" (a force, default 5 mN) and "reaction_moment" (a
    moment, default 0.5 N mm), e.g. ``{"tip": "0.2 mm", "reaction": "2 mN"}``: each
    residual is divided by its quantity's value, so that quantities measured with
    different noise and units combine.
    dynamic: fit time series instead of equilibria: each experiment of ``dataset`` (a
    ``time`` column, one experiment per run) is replayed from rest in equilibrium under its
    first row's pressures and tendon tensions, both joined linearly between the samples
    (tension columns ``t0_N``, ...: inputs, not parameters), with time step ``dt``
    (default :data:`DEFAULT_DT`; paper 000 Sec. III-D). ``dt`` of a fit that replays no time
    series is refused (a forgotten ``dynamic=True`` would otherwise fit the samples as
    equilibria). model="pcc": ``experiments`` maps experiment ids to "static"
    (equilibria) or "dynamic" (replayed time series); by default the experiments called
    "step" and "free_decay" (as :func:`softrod.pcc.synthesize_pcc_experiments` names them)
    are time series and the others equilibria, or every experiment is a time series with
    ``dynamic=True``.
    split: None (fit on all rows), "experiment" or "mounting" with ``test`` ids (default
    for "experiment": the last experiment), or a boolean test mask.
    restarts: extra fits from ``restarts`` starting points drawn with ``seed`` (within each
    parameter's bounds, or within a factor RESTART_SPREAD = 3 of a positive parameter's
    value when it has none); the fit with the lowest cost wins (ties: the earliest) and
    ``result.starts`` lists them all. executor: a ``distributed.Client``: the starts run on
    its cluster, one task each (docs/cluster.md).
    progress: None (a bar in interactive sessions), True, False, or a callable called as
    ``progress(evaluations, rms_error_mm)`` after every evaluation (:mod:`softrod.progress`).
    options: :class:`~softrod.SolverOptions` of the static solves. threads: the Rust core's
    worker threads (0: all cores). max_evaluations: the optimiser's budget of model
    evaluations (one evaluation predicts every training row).
    name: the calibrated design's name (default ``<design name>_calibrated``); its
    ``[design.provenance]`` records the dataset, the values with standard errors, the
    method, the softrod version and the date (``result.design.provenance``).

    Returns a :class:`CalibrationResult`; emits a :class:`CalibrationWarning` for each
    identifiability problem (also listed in ``result.warnings``): a relative standard error
    above :data:`POOR_RELATIVE_ERROR` (20 %), a correlation with ``|r|`` above
    :data:`STRONG_CORRELATION` (0.9), a Jacobian whose singular values span more than
    :data:`UNIDENTIFIABLE_CONDITION` (with the combination of parameters the data cannot
    separate), or an optimiser that did not converge.

    The fit runs BLAS on one thread (:mod:`softrod._threads`): the same inputs give the same
    result whatever the BLAS settings; ``threads`` sets the Rust core's workers.
    """
    start = time.perf_counter()
    V.choice(model, ("cosserat", "pcc"), "model")
    V.boolean(dynamic, "dynamic")
    method = "lm" if method is None else method
    V.choice(method, METHODS, "method")
    threads = V.threads(threads)
    V.integer(max_evaluations, "max_evaluations", minimum=1, maximum=V.MAX_ITERATIONS)
    check_restarts(restarts, seed)
    design0 = load_design(design)
    if model == "pcc":
        require_free_tip(design0, "calibrate(model='pcc')")
    if not isinstance(dataset, Dataset):
        dataset = load_dataset(dataset, design=design0)
    if dataset.marker_body is not None:
        raise V.fail(
            "dataset.marker_body",
            dataset.marker_body.tolist(),
            "the markers sit on the bodies of a system of rods (its platform, rod<i>): fit "
            "a system with calibrate_system",
        )
    reactions = dataset.tip_reaction_force is not None or dataset.tip_reaction_moment is not None
    if dynamic and model == "cosserat" and design0.tip_constraint is not None:
        _check_held_trajectories(design0, dataset, reactions)
    if design0.tip_constraint is not None and dataset.markers is None and not reactions:
        raise V.fail(
            "dataset.markers",
            "(none)",
            f"the design's [tip] constraint ({design0.tip_constraint.kind}) holds the tip at "
            "its prescribed position, which no parameter moves: a fit of a held tip needs "
            "markers on the rod or the measured reaction (tip_reaction_fx_N, ... columns, "
            "dataset.tip_reaction_force; its tip columns carry no information)",
        )
    if design0.tip_constraint is None and reactions:
        raise V.fail(
            f"dataset.{_reaction_field(dataset)}",
            "given",
            f"design {design0.name!r} has a free tip, which no constraint holds, so it has no "
            "reaction to fit: give the design the [tip] constraint of the measurement "
            "(pinned or clamped) or drop the tip_reaction_* columns",
        )
    if dataset.n_channels != design0.n_channels:
        raise V.fail(
            "dataset.pressures",
            f"{dataset.n_channels} channels",
            f"design {design0.name!r} has {design0.n_channels} pressure channels",
        )
    if dataset.tensions is not None and dataset.n_tendons != design0.n_tendons:
        raise V.fail(
            "dataset.tensions",
            f"{dataset.n_tendons} tension channels",
            f"design {design0.name!r} has {design0.n_tendons} tendon channels",
        )
    if model == "pcc":
        dataset.require_slack("calibrate(model='pcc')")
    names, registration = _split_params(params, design0, model)
    if experiments is not None and model != "pcc":
        raise V.fail("experiments", experiments, "applies to model='pcc' only")
    adapter = _adapter(model, dynamic, design0, dataset, names, options, threads, dt, experiments)
    if registration:
        adapter = Registered(adapter, registration)
    if method == "lm" and not adapter.exact_jacobian:
        raise V.fail(
            "method",
            method,
            "this model gives no exact Jacobian yet; use method='nelder-mead'",
        )
    params_all = list(adapter.parameters)
    theta0 = np.asarray(adapter.initial, dtype=float)
    box = _bounds(params_all, bounds, theta0)
    test_mask = _split(dataset, split, test)
    train = np.flatnonzero(~test_mask)
    scales = _scales(weights, dataset)
    observed = Observations(
        dataset.tip_position,
        dataset.markers,
        dataset.tip_reaction_force,
        dataset.tip_reaction_moment,
    )
    residual = Residual(observed, train, scales)
    problem = Problem(adapter, residual, box)
    logger.info(
        "calibrate %s (%s%s): %s on %d training samples (%d test), method %s",
        design0.name,
        model,
        ", dynamic" if adapter.dynamic else "",
        ", ".join(p.name for p in params_all),
        train.size,
        int(test_mask.sum()),
        method,
    )
    starts = start_points(params_all, theta0, box, restarts, seed)
    settings = Settings(method, int(max_evaluations))
    with reporter(progress, "calibrate", None, _evaluations) as report:
        fits = run_starts(problem, settings, starts, report, executor, threads)
    best = min(range(len(fits)), key=lambda k: (_finite_or_inf(fits[k]["cost"]), k))
    success, message = fits[best]["success"], fits[best]["message"]
    method_used = fits[best]["method"]
    values = problem.theta_of(fits[best]["u"])
    logger.info(
        "calibrate %s: %s after %d model evaluations (%s)",
        design0.name,
        "converged" if success else "stopped",
        sum(f["evaluations"] for f in fits),
        message,
    )

    # The Jacobian at the optimum (cold solves, as every start began): the optimiser's own
    # where the adapter's predictions depend on theta alone and it has one there.
    adapter.reset()
    adapter.evaluations = sum(f["evaluations"] for f in fits)
    pred = fits[best].get("prediction") if adapter.exact_jacobian else None
    if pred is None:
        pred = problem.predict(values, adapter.exact_jacobian)
    if not pred.ok[train].all():
        bad = train[~pred.ok[train]]
        raise ConvergenceError(
            f"calibrate: the model failed for {bad.size} training samples at the fitted "
            f"parameters ({dataset.rows_text(bad)}); check the data and the bounds"
        )
    r = residual.vector(pred)
    ssr = float(r @ r)
    if adapter.exact_jacobian:
        jac = residual.jacobian(pred)
        cov, std, corr, found = diagnostics(
            params_all, values, jac, ssr, r.size, _what(dataset, adapter.dynamic)
        )
    else:
        n_par = len(params_all)
        nan = np.full((n_par, n_par), np.nan)
        cov, std, corr = nan, np.full(n_par, np.nan), nan.copy()
        found = [
            "no standard errors or identifiability checks: this model gives no exact "
            "parameter Jacobian yet, so the fit ran derivative-free (Nelder-Mead)"
        ]
    if not success:
        found.insert(0, f"the optimiser stopped without converging: {message}")
    evaluations = adapter.evaluations

    calibrated = adapter.calibrated_design(values)
    what = ("time series" if adapter.dynamic else "equilibria") + f", {model} model"
    calibrated = record(
        calibrated, design0, name, params_all, values, std, method_used, dataset, train.size, what
    )
    all_rows = np.arange(len(dataset))
    final = adapter.final_prediction(calibrated, values, all_rows)
    reference = adapter.reference(calibrated, values)
    labels = np.where(test_mask, "test", "train")
    table = error_tables(
        dataset,
        final,
        final.ok,
        reference,
        labels if test_mask.any() else None,
        calibrated.length,
        None if registration else adapter.base_frame(),
    )
    reaction_table = reaction_error_table(
        dataset, final, final.ok, labels if test_mask.any() else None
    )
    for w in found:
        warnings.warn(w, CalibrationWarning, stacklevel=3)  # past the BLAS-thread wrapper
    reg = None
    if registration:
        angle, offset = adapter.values(values)
        reg = {"angle": angle, "offset": offset}
    return CalibrationResult(
        design=calibrated,
        initial_design=design0,
        parameters=tuple(params_all),
        initial=theta0,
        values=values,
        std_errors=std,
        covariance=cov,
        correlation=corr,
        warnings=tuple(found),
        method=method_used,
        success=success,
        message=message,
        evaluations=evaluations,
        cost_m2=residual.position_errors_m2(pred),
        dataset=dataset,
        predicted=final.tip,
        converged=final.ok,
        labels=labels,
        error_table=table,
        elapsed_s=time.perf_counter() - start,
        reference=reference.tip,
        starts=_starts_table(params_all, fits, best) if len(fits) > 1 else None,
        model=model,
        dynamic=adapter.dynamic,
        predicted_markers=final.markers,
        registration=reg,
        scales=scales,
        cost=ssr,
        reaction_error_table=reaction_table,
        predicted_reaction=final.reaction,
        predicted_reaction_moment=final.reaction_moment,
    )


def _reaction_field(dataset: Dataset) -> str:
    """The dataset's measured-reaction field an error names (the force's when it has both)."""
    return "tip_reaction_force" if dataset.tip_reaction_force is not None else "tip_reaction_moment"


def _check_held_trajectories(design: Design, dataset: Dataset, reactions: bool) -> None:
    """A dynamic fit of a held tip reads the markers along the trajectories: the tip stays
    at its prescribed pose, and the reaction's derivatives along a trajectory are not
    carried."""
    kind = design.tip_constraint.kind
    if dataset.markers is None:
        raise V.fail(
            "dataset.markers",
            "(none)",
            f"the design's [tip] constraint ({kind}) holds the tip, whose trajectory no "
            "parameter moves: calibrate(dynamic=True) of a held tip needs markers on the rod "
            "(marker0_x, ... columns with their arc lengths and offsets, docs/datasets.md)",
        )
    if reactions:
        raise V.fail(
            f"dataset.{_reaction_field(dataset)}",
            "given",
            "calibrate(dynamic=True) fits the markers of a held tip, not its reaction (fit the "
            "reaction in statics, dynamic=False, or drop the tip_reaction_* columns)",
        )


#: The time step of replayed time series when ``dt`` is not given, s.
DEFAULT_DT = 5e-3
_STATIC_DT = (
    "is the time step of replayed time series; this fit replays none (it fits equilibria): "
    "add dynamic=True to replay the experiments, or leave dt out"
)


def _adapter(model, dynamic, design0, dataset, names, options, threads, dt, experiments):
    """The model adapter of the call."""
    step = DEFAULT_DT if dt is None else dt
    if model == "pcc":
        from .adapters.pcc import PccAdapter

        adapter = PccAdapter(design0, dataset, names, dynamic, experiments, step, threads)
        if dt is not None and not adapter.dynamic:
            raise V.fail("dt", dt, _STATIC_DT)
        return adapter
    from .params import SIGMA_KINDS, parse_parameters

    params = parse_parameters(names, design0) if names else []
    if dynamic:
        from .adapters.rod_dynamic import RodDynamic

        return RodDynamic(design0, dataset, params, step, threads)
    if dt is not None:
        raise V.fail("dt", dt, _STATIC_DT)
    dyn = [p.name for p in params if p.kind == "damping_time"]
    if dyn:
        raise V.fail("params", dyn, "damping_time acts in dynamic fits only (dynamic=True)")
    sigma_names = [p.name for p in params if p.kind in SIGMA_KINDS]
    if sigma_names and design0.stiffness_map is not None:
        raise V.fail(
            "params",
            sigma_names,
            f"design {design0.name!r} has a stiffness map ([stiffness_map] file): the constant "
            "sigma factors would replace it; fit them on the design without the map "
            "(design.with_stiffness_map(None)) or fit other parameters",
        )
    if sigma_names:
        from .per_sample import stiffness_mapped_design

        design0 = stiffness_mapped_design(design0)[0]
    elif design0.mapped_sections and design0.stiffness_map is None:
        raise V.fail(
            "design.stiffness_map",
            None,
            f"section(s) {', '.join(design0.mapped_sections)} of design {design0.name!r} set "
            "[sections.law] stiffness_map = true but the design references no map: reference "
            "one (design.with_stiffness_map(path), or [stiffness_map] file in the design file) "
            f"or fit constant factors ({', '.join(SIGMA_KINDS)}); sigma is never assumed to be 1",
        )
    for p in params:  # the core checks each parameter against the design
        design0._rod.sensitivity_batch(
            np.zeros((0, design0.n_channels)), [0.0] * 3, [0.0] * 3, [p.core()]
        )
    from .adapters.rod_static import RodStatic

    return RodStatic(design0, dataset, params, options, threads)


def _finite_or_inf(x: float) -> float:
    return x if math.isfinite(x) else math.inf
