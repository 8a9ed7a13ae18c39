"""Dynamic calibration: fit the damping time tau and the effective chamber area A_eff (or
any other design parameter) to a measured tip trajectory, as paper 000 Sec. III-D did for
its arm (tau = 0.19 s, A_eff = 1.45 A_nom).

Each experiment of a time-series dataset (rows with ``time``, the chamber pressures and the
tip position) is replayed with :func:`softrod.simulate`: the measured pressures drive the
model (piecewise-linear between samples), the arm starts at rest in equilibrium under the
first row's pressures, and the simulated tip is compared with the measured one at every
sample. The fit minimises the sum of squared tip errors with Nelder-Mead on log(theta)
(derivative-free, like paper 002's fits; every evaluation is one simulation per
experiment).

Paper 000 Sec. II-G warns that A_eff cannot be fitted together with the mass, the
stiffness and the damping: scaling them together leaves the motion unchanged. Fitting
``area_scale`` with a stiffness parameter (c_b, c_e, c_s, c_t, E) raises a
:class:`CalibrationWarning`.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from .._threads import one_blas_thread
from .._validate import si_text
from ..catalog import load_design
from ..datasets import Dataset, load_dataset
from ..design import Design
from ..dynamics import PressureSchedule, Trajectory, simulate
from ..errors import CalibrationWarning, ConvergenceError, InputError
from .params import Parameter, design_changes, parse_parameters

__all__ = [
    "DAMPING_TIME",
    "DynamicCalibrationResult",
    "calibrate_dynamics",
    "synthesize_trajectory_dataset",
]

DAMPING_TIME = "damping_time"  # tau of [dynamics] (paper 000 eq. 8), s
_STIFFNESS = ("c_s", "c_e", "c_b", "c_t", "E")
_MM = 1e-3
_FAILED = 1e3  # mm, the residual of a sample whose simulation failed


def _fail(field_: str, value, rule: str) -> InputError:
    return InputError(f"{field_} = {value!r}: {rule}", field_, value, rule)


@dataclass(frozen=True)
class DynamicCalibrationResult:
    """A fitted dynamic model: ``values`` of ``names`` (SI; tau in s, area_scale relative
    to the initial design), ``design`` with them written in, the RMS tip error (mm) before
    and after, the fitted trajectories (one per experiment) and any warnings."""

    design: Design
    initial_design: Design
    names: tuple[str, ...]
    initial: np.ndarray
    values: np.ndarray
    rms_initial_mm: float
    rms_mm: float
    evaluations: int
    success: bool
    message: str
    warnings: tuple[str, ...]
    trajectories: tuple[Trajectory, ...] = field(repr=False)
    elapsed_s: float = 0.0

    def summary(self) -> str:
        rows = [
            f"  {n:>14s} = {v:.6g} (from {v0:.6g})"
            for n, v, v0 in zip(self.names, self.values, self.initial, strict=True)
        ]
        return "\n".join(
            [
                f"dynamic calibration of {self.design.name}: {self.message}",
                *rows,
                f"  RMS tip error {self.rms_initial_mm:.3f} mm -> {self.rms_mm:.3f} mm "
                f"({self.evaluations} simulations, {self.elapsed_s:.1f} s)",
                *(f"  warning: {w}" for w in self.warnings),
            ]
        )

    def __str__(self) -> str:
        return self.summary()


def _experiments(dataset: Dataset) -> list[np.ndarray]:
    """Row indices of each experiment, in time order; each needs >= 2 samples."""
    if dataset.time is None:
        raise _fail("dataset.time", None, "a dynamic calibration needs a time column (e.g. time_s)")
    ids = dataset.experiments or (None,)
    out = []
    for e in ids:
        rows = (
            np.arange(len(dataset.time)) if e is None else np.flatnonzero(dataset.experiment == e)
        )
        t = dataset.time[rows]
        if len(rows) < 2 or np.any(np.diff(t) <= 0):
            raise _fail(
                "dataset.time",
                f"experiment {e}",
                "each experiment needs >= 2 rows with strictly increasing time",
            )
        out.append(rows)
    return out


@one_blas_thread
def calibrate_dynamics(
    design,
    dataset,
    params: Sequence[str] | str = (DAMPING_TIME, "area_scale"),
    *,
    dt=5e-3,
    max_evaluations: int = 200,
    xatol: float = 1e-4,
    progress: Callable[[int, float], None] | None = None,
) -> DynamicCalibrationResult:
    """Fit ``params`` (default tau and the chamber area scale) of ``design`` to the tip
    trajectories of ``dataset`` (see the module docstring). ``params`` takes
    ``"damping_time"`` and the static parameter names of :func:`softrod.calibrate`
    (``area_scale``, ``c_b``, ...). ``dt``: the simulations' time step. ``xatol``: the
    simplex stops when the log-parameters agree to this. ``progress(evaluations, rms_mm)``
    is called after each simulation of the whole dataset."""
    from scipy.optimize import minimize

    start = time.perf_counter()
    design0 = load_design(design)
    if not isinstance(dataset, Dataset):
        dataset = load_dataset(dataset, design=design0)
    if dataset.n_channels != design0.n_channels:
        raise _fail(
            "dataset.pressures",
            f"{dataset.n_channels} channels",
            f"design {design0.name!r} has {design0.n_channels} pressure channels",
        )
    names = [params] if isinstance(params, str) and "," not in params else params
    if isinstance(names, str):
        names = [n.strip() for n in names.split(",") if n.strip()]
    names = list(names)
    with_tau = DAMPING_TIME in names
    static_names = [n for n in names if n != DAMPING_TIME]
    static: list[Parameter] = parse_parameters(static_names, design0) if static_names else []
    order = ([DAMPING_TIME] if with_tau else []) + [p.name for p in static]
    tau0 = design0.spec["dynamics"]["damping_time"]
    if with_tau and not tau0 > 0:
        raise _fail(
            "design.dynamics.damping_time",
            tau0,
            "give a starting damping time > 0 s in [dynamics] (the fit works on log tau)",
        )
    for p in static:
        if not p.positive:
            raise _fail("params", p.name, "dynamic calibration fits positive parameters only")
    theta0 = np.array(([tau0] if with_tau else []) + [p.value(design0) for p in static])
    found = []
    kinds = {p.kind for p in static}
    if "area_scale" in kinds and kinds & set(_STIFFNESS):
        found.append(
            "area_scale and a stiffness parameter ("
            + ", ".join(sorted(kinds & set(_STIFFNESS)))
            + ") trade off: the chamber moment over the stiffness sets the bending, so they "
            "are not separately identifiable (paper 000 Sec. II-G)"
        )
    for w in found:
        warnings.warn(w, CalibrationWarning, stacklevel=3)  # past the BLAS-thread wrapper
    if isinstance(max_evaluations, bool) or not isinstance(max_evaluations, int):
        raise _fail("max_evaluations", max_evaluations, "must be an integer >= 1")
    if max_evaluations < 1:
        raise _fail("max_evaluations", max_evaluations, "must be an integer >= 1")
    experiments = _experiments(dataset)
    measured = dataset.tip_position

    def design_of(theta) -> Design:
        changes = design_changes(static, theta[int(with_tau) :], design0) if static else {}
        if with_tau:
            changes["dynamics.damping_time"] = si_text(theta[0], "time")
        return design0.replace(changes) if changes else design0

    def run(theta) -> tuple[np.ndarray, list[Trajectory]]:
        d = design_of(theta)
        res, trajs = [], []
        for rows in experiments:
            t = dataset.time[rows]
            sched = PressureSchedule.piecewise_linear(t - t[0], dataset.pressures[rows])
            try:
                tr = simulate(d, sched, t[-1] - t[0], dt=dt, save_every=1, energy=False)
                tip = tr.tip_position_at(np.minimum(t - t[0], tr.time[-1]))
                res.append(((tip - measured[rows]) / _MM).ravel())
                trajs.append(tr)
            except ConvergenceError:
                res.append(np.full(3 * len(rows), _FAILED))
        return np.concatenate(res), trajs

    count = 0

    def objective(u) -> float:
        nonlocal count
        r, _ = run(np.exp(u))
        count += 1
        rms = math.sqrt(float(np.mean(r**2)))
        if progress is not None:
            progress(count, rms)
        return float(np.sum(r**2))

    u0 = np.log(theta0)
    r0, _ = run(theta0)
    rms0 = math.sqrt(float(np.mean(r0**2)))
    # An initial simplex of +-20 % per parameter: the fit's scale, not Nelder-Mead's 5 %.
    simplex = np.vstack([u0] + [u0 + 0.2 * np.eye(len(u0))[k] for k in range(len(u0))])
    out = minimize(
        objective,
        u0,
        method="Nelder-Mead",
        options={
            "maxfev": max_evaluations,
            "xatol": xatol,
            "fatol": 1e-9 * max(float(np.sum(r0**2)), 1e-300),
            "initial_simplex": simplex,
        },
    )
    theta = np.exp(out.x)
    r, trajs = run(theta)
    rms = math.sqrt(float(np.mean(r**2)))
    return DynamicCalibrationResult(
        design=design_of(theta),
        initial_design=design0,
        names=tuple(order),
        initial=theta0,
        values=theta,
        rms_initial_mm=rms0,
        rms_mm=rms,
        evaluations=count + 2,
        success=bool(out.success),
        message=str(out.message),
        warnings=tuple(found),
        trajectories=tuple(trajs),
        elapsed_s=time.perf_counter() - start,
    )


def synthesize_trajectory_dataset(
    design,
    schedule: PressureSchedule,
    t_end: float,
    *,
    rate: float = 50.0,
    noise_mm: float = 0.0,
    seed: int | None = None,
    dt=2e-3,
) -> Dataset:
    """A time-series dataset made by the model: ``schedule`` sampled at ``rate`` Hz (paper
    000 recorded at 50 Hz), the model driven by those samples joined linearly (as
    :func:`calibrate_dynamics` replays them), and its tip at the samples with Gaussian noise of
    ``noise_mm`` per coordinate. Marked synthetic in its metadata, with the seed."""
    d = load_design(design)
    rng = np.random.default_rng(seed)
    seed_used = seed
    times = np.arange(0.0, t_end + 0.5 / rate, 1.0 / rate)
    # The model is driven by the sampled pressures joined linearly, as a fit replays them.
    sampled = PressureSchedule.piecewise_linear(times, schedule.sample(times))
    tr = simulate(d, sampled, times[-1], dt=dt, energy=False)
    tip = tr.tip_position_at(times) + rng.normal(0.0, noise_mm * _MM, (len(times), 3))
    meta: Mapping = {
        "synthetic": True,
        "source": f"softrod.simulate of {d.name}, {rate:g} Hz, noise {noise_mm:g} mm",
        "seed": seed_used,
    }
    return Dataset(
        pressures=sampled.pressures,
        tip_position=tip,
        time=times,
        experiment=np.zeros(len(times), dtype=np.int64),
        metadata=dict(meta),
    )
