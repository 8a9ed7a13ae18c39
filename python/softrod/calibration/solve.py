"""The solver layer: one fit of a :class:`~softrod.calibration.problem.Problem` from one
start, and restarts (in process or on a Dask cluster).

- ``"lm"``: scipy's ``least_squares`` with the adapter's exact Jacobian: MINPACK's
  Levenberg-Marquardt without user bounds, the trust-region-reflective method with them.
- ``"nelder-mead"``: derivative-free simplex on the same cost, an explicit fallback (paper
  002 fitted with it) for models without exact Jacobians.

Positive parameters are optimised on log(theta) so that they stay positive. Without user
bounds a positive parameter stays within 1e-3 to 1e3 times its starting value (a sanity box:
points outside count as failed, so an unidentifiable direction cannot run off to 1e150).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .. import _validate as V
from .problem import Bounds, Prediction, Problem

#: Restarts of a positive parameter without bounds start within this factor of its starting
#: value (log-uniformly in [v / RESTART_SPREAD, v * RESTART_SPREAD]).
RESTART_SPREAD = 3.0
#: The sanity box of a positive parameter without bounds, as factors on its start.
SANITY_FACTOR = 1e3
METHODS = ("lm", "nelder-mead")


def default_bounds(params, initial: np.ndarray) -> Bounds:
    pairs = list(zip(params, initial, strict=True))
    lo = np.array([v / SANITY_FACTOR if p.positive else -math.inf for p, v in pairs])
    hi = np.array([v * SANITY_FACTOR if p.positive else math.inf for p, v in pairs])
    return Bounds(lo, hi, np.zeros(len(params), dtype=bool))


@dataclass(frozen=True)
class Settings:
    method: str
    max_evaluations: int


def optimise(problem: Problem, settings: Settings, theta_start, progress=None) -> dict:
    """One fit from ``theta_start``: the optimiser's best point u, its cost 0.5 sum r^2, success,
    message, method and the model evaluations."""
    from scipy.optimize import least_squares, minimize

    adapter = problem.adapter
    n_par = len(problem.parameters)
    n_markers = (
        0
        if problem.residual.observed.markers is None
        else (problem.residual.observed.markers.shape[1])
    )
    m = problem.residual.observed.rows
    reactions = problem.residual.observed.reactions
    positive = problem.positive
    theta_start = np.asarray(theta_start, dtype=float)
    u0 = problem.u_of(theta_start)
    adapter.reset()
    # The last point, or the last few where predictions depend on theta alone (a repeated
    # evaluation would give the same numbers): scipy's MINPACK driver evaluates the
    # Jacobian again at the best point after a rejected trial step, and the fit's standard
    # errors need it too. Warm-started models keep evaluating again, as they always have.
    cache: dict = {}
    kept = CACHED_POINTS if adapter.stateless else 1

    def evaluate(u, jacobian):
        key = u.tobytes()
        if key in cache and (cache[key][1] is not None or not jacobian):
            cache[key] = cache.pop(key)  # most recent last
            return cache[key]
        theta = problem.theta_of(u)
        if problem.inside(theta):
            pred = problem.predict(theta, jacobian)
        else:
            # Outside the sanity box: a failed point.
            pred = Prediction.empty(m, n_par, n_markers, jacobian, reactions)
            pred.zero_jacobian()
        r = problem.residual.vector(pred)
        cache.pop(key, None)
        while len(cache) >= kept:
            cache.pop(next(iter(cache)))
        cache[key] = (r, pred if jacobian else None, pred)
        if progress is not None:
            progress(adapter.evaluations, _rms(r[: problem.residual.n_positions]))
        return cache[key]

    # The largest Gauss-Newton step of the last accepted point, in standard errors.
    last_step: list[float] = []

    def jac_u(u):
        r, pred, _ = evaluate(u, True)
        j = problem.residual.jacobian(pred)
        # d/du = theta d/dtheta for the log-transformed parameters
        j = j * np.where(positive, problem.theta_of(u), 1.0)
        gn = None if stop_fraction is None else _gauss_newton(j, r)
        if gn is None:
            return j
        step, size = gn
        if size <= stop_fraction:
            raise _Converged(np.array(u, dtype=float))
        # Gauss-Newton contracts near the optimum: from two accepted points, the rate is
        # that of their steps and the error left after this step rate / (1 - rate) of it
        # (Newton's estimate, as the core's refinement stops, ``dynamics::sensitivity``).
        # Below stop_fraction of every standard error, the point after the step is the
        # fit: one replay without the Jacobian there (its cost, which must not rise)
        # instead of one with it that would only confirm the step.
        rate = size / last_step[-1] if last_step else math.inf
        last_step.append(size)
        if rate <= GN_RATE_MAX and size * rate / (1.0 - rate) <= stop_fraction:
            u_next = np.asarray(u, dtype=float) + step
            if problem.inside(problem.theta_of(u_next)):
                r_next, _, pred_next = evaluate(u_next, False)
                if np.all(np.isfinite(r_next)) and r_next @ r_next <= r @ r:
                    raise _Converged(u_next, jacobian_of=pred)
        return j

    stop_fraction = adapter.lm_stop_fraction

    stepped = None  # the prediction with the Jacobian of the last step's start, if any
    bounds = problem.bounds
    ulo = np.where(positive, np.log(np.where(positive, bounds.lower, 1.0)), bounds.lower)
    uhi = np.where(positive, np.log(np.where(positive, bounds.upper, 1.0)), bounds.upper)
    if settings.method == "lm":
        use_bounds = bounds.any_given
        try:
            sol = least_squares(
                lambda u: evaluate(u, True)[0],
                u0,
                jac=jac_u,
                method="trf" if use_bounds else "lm",
                bounds=(ulo, uhi) if use_bounds else (-np.inf, np.inf),
                x_scale=1.0,
                xtol=1e-10,
                ftol=1e-10,
                gtol=1e-10,
                max_nfev=settings.max_evaluations,
            )
        except _Converged as done:
            # The Jacobian MINPACK asked for (at its current, accepted point) says the next
            # step is below stop_fraction of every standard error: that point is the fit;
            # or that the error left after the next step is: the point after it is.
            r = evaluate(done.u, done.jacobian_of is None)[0]
            message = (
                f"the next Gauss-Newton step is below {stop_fraction:g} of every "
                "parameter's standard error"
                if done.jacobian_of is None
                else f"the error left after the last Gauss-Newton step is below {stop_fraction:g} "
                "of every parameter's standard error"
            )
            sol = _Stopped(x=done.u, cost=0.5 * float(r @ r), success=True, message=message)
            stepped = done.jacobian_of
        method_used = "lm (MINPACK)" if not use_bounds else "trf (bounded, exact Jacobian)"
        cost = float(sol.cost)
    else:

        def cost_of(u) -> float:
            return 0.5 * float(np.sum(evaluate(u, False)[0] ** 2))

        nm = adapter.nelder_mead
        options = {"maxfev": settings.max_evaluations, "xatol": nm["xatol"], "fatol": nm["fatol"]}
        if nm["fatol_relative"]:  # the start's cost, cached: the simplex's first vertex
            options["fatol"] *= max(cost_of(u0), 1e-300)
        if nm["step"] is not None:
            options["initial_simplex"] = np.vstack([u0, u0 + nm["step"] * np.eye(u0.size)])
        sol = minimize(
            cost_of,
            u0,
            method="Nelder-Mead",
            bounds=list(zip(ulo, uhi, strict=True)) if bounds.any_given else None,
            options=options,
        )
        method_used = "nelder-mead"
        cost = float(sol.fun)
    u_best = np.asarray(sol.x, dtype=float)
    at_best = cache.get(u_best.tobytes())
    prediction = at_best[1] if adapter.stateless and at_best is not None else None
    if prediction is None and stepped is not None and at_best is not None:
        # Stopped after a last Gauss-Newton step below stop_fraction of every standard
        # error: the positions are the result's, their Jacobian that of the step's start,
        # which the step moved by less than that; the standard errors and correlations
        # change by the same small fraction (second order in it), far below their own
        # accuracy, about 1 / sqrt(2 (m - P)) for m residuals.
        prediction = at_best[2].with_jacobian_of(stepped)
    return {
        "start": theta_start,
        "u": u_best,
        # The prediction with its Jacobian at the result, where the adapter's predictions
        # depend on theta alone (None otherwise, or when the optimiser never asked for it).
        "prediction": prediction,
        "values": problem.theta_of(np.asarray(sol.x, dtype=float)),
        "cost": cost,
        "success": bool(sol.success),
        "message": str(sol.message),
        "method": method_used,
        "evaluations": adapter.evaluations,
    }


#: Points the optimiser's evaluation cache keeps (see ``optimise``).
CACHED_POINTS = 4


#: The largest contraction rate of Gauss-Newton's steps with which the error left after a
#: step is estimated from the step (as Newton's matrix is kept, ``collocation::newton_with``).
GN_RATE_MAX = 0.25


class _Converged(Exception):
    """Raised from the Jacobian callback to end MINPACK's iteration at ``u`` (with
    ``jacobian_of``: a Gauss-Newton step from that prediction's point, whose Jacobian the
    result keeps)."""

    def __init__(self, u: np.ndarray, jacobian_of: Prediction | None = None):
        super().__init__("converged")
        self.u = u
        self.jacobian_of = jacobian_of


@dataclass
class _Stopped:
    x: np.ndarray
    cost: float
    success: bool
    message: str


def _gauss_newton(j: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, float] | None:
    """The Gauss-Newton step from this point, -(J^T J)^-1 J^T r, and its largest size in
    standard errors, max_i |step_i| / sqrt(s^2 (J^T J)^-1_ii), s^2 = r.r / (m - P) (both in
    the optimiser's variables; the ratio does not depend on them). None where the standard
    errors are undefined (m <= P, a singular J^T J)."""
    m, n_par = j.shape
    if m <= n_par or not (np.all(np.isfinite(j)) and np.all(np.isfinite(r))):
        return None
    try:
        jtj_inv = np.linalg.inv(j.T @ j)
    except np.linalg.LinAlgError:
        return None
    step = -jtj_inv @ (j.T @ r)
    se = np.sqrt(float(r @ r) / (m - n_par) * np.diag(jtj_inv))
    if not (np.all(np.isfinite(step)) and np.all(np.isfinite(se)) and np.all(se > 0)):
        return None
    return step, float(np.max(np.abs(step) / se))


def _within_standard_errors(j: np.ndarray, r: np.ndarray, fraction: float) -> bool:
    """Whether the Gauss-Newton step from this point is below ``fraction`` of every
    parameter's standard error (:func:`_gauss_newton`; False where they are undefined)."""
    gn = _gauss_newton(j, r)
    return gn is not None and gn[1] <= fraction


def _rms(r: np.ndarray) -> float:
    """RMS of the 3-d position errors of a residual (in units of the residual scale)."""
    return float(np.sqrt(np.mean(r.reshape(-1, 3) ** 2) * 3)) if r.size else math.nan


def check_restarts(restarts, seed) -> tuple[int, int]:
    """``restarts`` (0 ... MAX_RESTARTS: each is a whole fit) and the ``seed`` of their
    starting points (numpy's generators take any integer >= 0); checked before any work."""
    restarts = V.integer(
        restarts, "restarts", minimum=0, maximum=V.MAX_RESTARTS, hint=" (extra starting points)"
    )
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise V.fail("seed", seed, "must be an integer >= 0 (it makes the restarts repeatable)")
    return restarts, int(seed)


def start_points(params, theta0, bounds: Bounds, restarts, seed) -> np.ndarray:
    """The starting values, then ``restarts`` points drawn with ``seed``: uniformly within a
    parameter's bounds (log-uniformly for positive ones), or, for a positive parameter
    without bounds, log-uniformly within RESTART_SPREAD of its value."""
    restarts, seed = check_restarts(restarts, seed)
    if restarts == 0:
        return theta0[None, :]
    bounded = bounds.given
    for p, b in zip(params, bounded, strict=True):
        if not (b or p.positive):
            raise V.fail(
                "restarts",
                restarts,
                f"{p.name} can be negative: give its bounds so that restarts know where to "
                "start (bounds={'" + p.name + "': (lower, upper)})",
            )
    positive = np.array([p.positive for p in params])
    a = np.where(bounded, bounds.lower, theta0 / RESTART_SPREAD)
    b = np.where(bounded, bounds.upper, theta0 * RESTART_SPREAD)
    rng = np.random.default_rng(seed)
    x = rng.random((int(restarts), len(params)))
    log_a = np.log(np.where(positive, a, 1.0))
    log_b = np.log(np.where(positive, b, 1.0))
    drawn = np.where(positive, np.exp(log_a + x * (log_b - log_a)), a + x * (b - a))
    return np.vstack([theta0[None, :], drawn])


def run_starts(
    problem: Problem,
    settings: Settings,
    starts: np.ndarray,
    progress: Callable | None,
    executor,
    threads: int,
) -> list[dict]:
    """One fit per start, in process or on a Dask cluster; in the order of ``starts``."""
    from ..cluster import check_executor

    if check_executor(executor) is None:
        return [optimise(problem, settings, start, progress) for start in starts]
    from ..cluster import run_chunks, task_slots

    _, per_host = task_slots(executor)
    report = None
    if progress is not None:

        def report(done, total):
            progress(done, float("nan"))

    return run_chunks(
        executor,
        _fit_start,
        [(problem, settings, start, threads, per_host) for start in starts],
        progress=report,
        name="softrod-calibrate",
    )


def _fit_start(problem: Problem, settings, start, threads, per_host) -> dict:
    """One restart on a worker (the adapter rebuilt its design from TOML text when it was
    unpickled), with the worker's share of the cores."""
    from ..cluster import worker_threads

    problem.adapter.set_threads(worker_threads(per_host, threads))
    return optimise(problem, settings, start, None)


def starts_table(params, fits, best) -> pd.DataFrame:
    rows = []
    for k, f in enumerate(fits):
        row = {"start": k, "best": k == best}
        for p, v0, v in zip(params, f["start"], f["values"], strict=True):
            row[f"{p.name} start"] = v0
            row[f"{p.name}"] = v
        row.update(cost_mm2=f["cost"], success=f["success"], evaluations=f["evaluations"])
        rows.append(row)
    return pd.DataFrame(rows)
