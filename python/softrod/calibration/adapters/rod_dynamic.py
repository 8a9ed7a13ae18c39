"""Cosserat-rod time series on a dataset (paper 000 Sec. III-D): every experiment (rows with
``time``, the chamber pressures, the tendon tensions if the dataset records them, and the
measured positions) is replayed: the measured pressures and tensions drive the model
(joined linearly between samples; the tensions are read at every time step), the arm starts
at rest in equilibrium under the experiment's first pressures and tensions, and the model's
tip and motion-capture markers anywhere on the body (``Simulator::set_markers``: between
the nodes the collocation's continuous extension, docs/dynamics.md "Markers on the moving
rod") are read at every sample time (linear between the steps). A design whose ``[tip]``
pins or clamps the tip is replayed held and fitted by its markers. With ``jacobian`` the core
carries the exact forward sensitivities of every step (``softrod_core::dynamics::
sensitivity``: the implicit function theorem on each step's collocation equations), so the
tip's and the markers' derivatives come with the replay at about 3.3-3.6 times its cost
(two parameters, CPU time on one thread; benchmarks/README.md), and Levenberg-Marquardt
fits with standard errors."""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ... import _validate as V
from ...design import Design
from ...errors import ConvergenceError, DesignError
from ..params import SIGMA_KINDS, Parameter, design_changes
from ..problem import ModelAdapter, Prediction
from .rod_static import marker_sites, rest_prediction


def experiment_rows(dataset) -> list[np.ndarray]:
    """Row indices of each experiment, in time order; each needs >= 2 samples."""
    if dataset.time is None:
        raise V.fail(
            "dataset.time", None, "a dynamic calibration needs a time column (e.g. time_s)"
        )
    ids = dataset.experiments or (None,)
    out = []
    for e in ids:
        rows = (
            np.arange(len(dataset.time)) if e is None else np.flatnonzero(dataset.experiment == e)
        )
        rows = rows[np.argsort(dataset.time[rows], kind="stable")]
        t = dataset.time[rows]
        if len(rows) < 2 or np.any(np.diff(t) <= 0):
            raise V.fail(
                "dataset.time",
                f"experiment {e}",
                "each experiment needs >= 2 rows with strictly increasing time",
            )
        out.append(rows)
    return out


def experiment_mountings(design: Design, dataset, experiments) -> list[dict]:
    """Each experiment's mounting as document changes ({}: the design's own), by the static
    fits' rule (``rod_static.mounting_groups``); an experiment's rows share one mounting."""
    from .rod_static import mounting_groups

    changes = [{}] * len(experiments)
    groups = mounting_groups(design, dataset)
    if len(groups) == 1:
        return changes
    label_of = np.empty(len(dataset), dtype=int)
    for g, (_, rows) in enumerate(groups):
        label_of[rows] = g
    for k, rows in enumerate(experiments):
        mine = np.unique(label_of[rows])
        if mine.size > 1:
            e = dataset.experiment[rows[0]] if dataset.experiment is not None else None
            raise V.fail(
                "dataset.mounting",
                f"experiment {e}",
                "an experiment is one run in one mounting: its rows must share one label",
            )
        changes[k] = groups[mine[0]][0]
    return changes


def _rows(tensions: np.ndarray, dt: float):
    """The tensions at the step times k dt (rows k = 0, 1, ...) as ``simulate`` reads them: a
    function of t (s), evaluated at the steps' ends (the same numbers as the sensitivity
    run's rows)."""
    return lambda t: tensions[int(round(t / dt))]


def step_tensions(t: np.ndarray, knots: np.ndarray, dt: float) -> np.ndarray:
    """The tendon tensions ``knots`` (k, channels) sampled at the times ``t`` (from 0) at
    the start and at every step's end (the core reads a step's tensions at its end), joined
    linearly between the samples as the pressures are."""
    from ...dynamics.simulate import step_count

    at = np.minimum(dt * np.arange(step_count(t[-1], dt) + 1), t[-1])
    return np.column_stack([np.interp(at, t, k) for k in knots.T])


def sample_run(run: dict, key: str, t: np.ndarray) -> np.ndarray | None:
    """``run[key]`` (one row per step, from :func:`~softrod.dynamics.simulate.
    tracked_trajectory`) at the times ``t``, linear between the steps (derivatives
    alike: the same weights); None when the run has no ``key``."""
    if key not in run:
        return None
    time = run["time"]
    at = np.minimum(t, time[-1])
    flat = run[key].reshape(len(time), -1)
    cols = [np.interp(at, time, flat[:, c]) for c in range(flat.shape[1])]
    return np.column_stack(cols).reshape((len(at),) + run[key].shape[1:])


class RodDynamic(ModelAdapter):
    """The tip (and the markers) of every sample of every replayed experiment."""

    model = "cosserat"
    dynamic = True
    exact_jacobian = True
    #: Nelder-Mead's settings for the explicit fallback (method="nelder-mead"): every
    #: evaluation replays every experiment, so the simplex starts at +-20 % (the fit's
    #: scale, not scipy's 5 %) and stops at 1e-4 in log theta (0.01 %, well below the
    #: scatter that measurement noise leaves) or a cost change of 1e-9 of the start's.
    nelder_mead = {"xatol": 1e-4, "fatol": 1e-9, "fatol_relative": True, "step": 0.2}
    #: Every replay starts from rest in equilibrium: no warm starts.
    stateless = True
    #: An evaluation replays every experiment with its sensitivities, so LM stops once its
    #: next step would move every parameter by less than 1e-3 of its standard error: the
    #: point is then the least-squares optimum to 1e-3 of the uncertainty the noise leaves:
    #: its cost exceeds the optimum's by about P (1e-3)^2 s^2 / 2 (P parameters, s^2 the
    #: residual variance), 1e-6 s^2 against a cost of (m - P) s^2 / 2 over m residuals,
    #: and the further steps MINPACK's xtol of 1e-10 would take move the result by nothing
    #: the data resolve. Or once the error left after its next step, estimated from the
    #: contraction of the last two points' steps, is below that: the point after the step
    #: is then the fit, replayed without the sensitivities (``solve.optimise``).
    lm_stop_fraction = 1e-3

    def __init__(self, design: Design, dataset, params: list[Parameter], dt, threads: int):
        from ...dynamics.simulate import _seconds

        super().__init__()
        sigma = [p.name for p in params if p.kind in SIGMA_KINDS]
        if sigma:
            raise V.fail("params", sigma, "sigma factors belong to static fits")
        if any(p.kind == "damping_time" for p in params):
            tau0 = design.spec["dynamics"]["damping_time"]
            if not tau0 > 0:
                raise V.fail(
                    "design.dynamics.damping_time",
                    tau0,
                    "give a starting damping time > 0 s in [dynamics] (the fit works on log tau)",
                )
        for p in params:
            if not p.positive:
                raise V.fail("params", p.name, "dynamic calibration fits positive parameters only")
        self.design = design
        self.params = list(params)
        self.parameters = tuple(params)
        self.initial = np.array([p.value(design) for p in params])
        self.dt = _seconds(dt, "dt")
        self.threads = threads
        self.experiments = experiment_rows(dataset)
        #: Each experiment's mounting (document changes; {} for the design's own), as a
        #: static fit solves each row in its mounting.
        self.mountings = experiment_mountings(design, dataset, self.experiments)
        self.time = dataset.time
        self.pressures = dataset.pressures
        #: (m, tendon channels) N, or None: every tendon slack (calibrate checked the count).
        self.tensions = dataset.tensions
        #: The core's (s, offset) of every marker (empty without markers: no marker work),
        #: checked by the core against the rod before any replay.
        self.markers = marker_sites(dataset)
        if self.markers:
            design._rod.sensitivity_batch(
                np.zeros((0, design.n_channels)), [0.0] * 3, [0.0] * 3, [], markers=self.markers
            )
        self.m = len(dataset)
        #: (theta, the experiments replayed, the prediction) of the last evaluation.
        self._last = None

    def design_of(self, theta) -> Design:
        return self.design.replace(design_changes(self.params, theta, self.design))

    def set_threads(self, threads: int) -> None:
        self.threads = threads

    def _replay(self, design: Design, exp: np.ndarray, jacobian: bool):
        """The model's tip (k, 3) and markers (k, K, 3, or None) at the sample times of one
        experiment and, with ``jacobian``, their derivatives (k, 3, P) and (k, K, 3, P) per
        SI unit of each parameter (else None); None: the run failed."""
        from ...dynamics import PressureSchedule, simulate
        from ...dynamics.simulate import tracked_trajectory

        t = self.time[exp] - self.time[exp][0]
        sched = PressureSchedule.piecewise_linear(t, self.pressures[exp])
        tensions = None if self.tensions is None else step_tensions(t, self.tensions[exp], self.dt)
        try:
            if not jacobian and not self.markers:
                tr = simulate(
                    design,
                    sched,
                    t[-1],
                    dt=self.dt,
                    save_every=1,
                    energy=False,
                    progress=False,
                    tensions=None if tensions is None else _rows(tensions, self.dt),
                )
                return tr.tip_position_at(np.minimum(t, tr.time[-1])), None, None, None
            params = [p.core() for p in self.params] if jacobian else []
            run = tracked_trajectory(design, sched, t[-1], self.dt, params, tensions, self.markers)
        except ConvergenceError:  # InvalidStateError included
            return None
        keys = ("tip_position", "d_tip_position", "marker_position", "d_marker_position")
        return tuple(sample_run(run, key, t) for key in keys)

    def predict(self, theta, rows, jacobian: bool) -> Prediction:
        out = Prediction.empty(self.m, len(self.params), len(self.markers), jacobian)
        self.evaluations += 1
        try:
            d = self.design_of(theta)
        except DesignError:
            return out
        wanted = np.zeros(self.m, dtype=bool)
        wanted[rows] = True
        replayed = [k for k, exp in enumerate(self.experiments) if wanted[exp].any()]
        todo = [self.experiments[k] for k in replayed]
        # The experiments replay side by side: each run steps in the core with the GIL
        # released, so threads overlap the runs (in order: the same result on any count).
        workers = min(len(todo), self.threads or os.cpu_count() or 1)
        try:
            mounted = [d.replace(self.mountings[k]) if self.mountings[k] else d for k in replayed]
        except DesignError:
            return out
        jobs = list(zip(mounted, todo, strict=True))
        if workers > 1:
            with ThreadPoolExecutor(workers) as pool:
                runs = list(pool.map(lambda job: self._replay(*job, jacobian), jobs))
        else:
            runs = [self._replay(*job, jacobian) for job in jobs]
        self._last = (np.array(theta, dtype=float).tobytes(), set(replayed), out)
        return fill_replays(out, todo, runs, self.params, theta, jacobian)

    def calibrated_design(self, theta) -> Design:
        return self.design_of(theta)

    def final_prediction(self, calibrated, theta, rows) -> Prediction:
        """The positions at the fitted values: those of the last evaluation when it was at
        ``theta`` and replayed every experiment of ``rows`` (a replay depends on theta
        alone, and one with sensitivities gives the same positions), else a replay."""
        if self._last is not None:
            key, done, pred = self._last
            wanted = np.zeros(self.m, dtype=bool)
            wanted[rows] = True
            needed = [k for k, exp in enumerate(self.experiments) if wanted[exp].any()]
            if key == np.array(theta, dtype=float).tobytes() and done.issuperset(needed):
                out = Prediction.empty(self.m, 0, len(self.markers), False)
                for k in needed:
                    exp = self.experiments[k]
                    out.tip[exp], out.ok[exp] = pred.tip[exp], pred.ok[exp]
                    if out.markers is not None:
                        out.markers[exp] = pred.markers[exp]
                return out
        return self.predict(theta, rows, False)

    def reference(self, calibrated: Design, theta) -> Prediction:
        """The unpressurised equilibrium's tip (and markers) for every row, in its
        experiment's mounting."""
        out = Prediction.empty(self.m, 0, len(self.markers), False)
        for changes, exp in zip(self.mountings, self.experiments, strict=True):
            d = calibrated.replace(changes) if changes else calibrated
            rest = rest_prediction(d, self.markers, 1)
            out.tip[exp], out.ok[exp] = rest.tip[0], rest.ok[0]
            if out.markers is not None:
                out.markers[exp] = rest.markers[0]
        return out

    def base_frame(self):
        if any(self.mountings):
            return None  # several mountings: no one base frame
        mount = self.design.spec["mounting"]
        return (
            np.asarray(mount["base_position"], dtype=float),
            np.asarray(mount["base_rotation"], dtype=float)[:, 2],
        )


def fill_replays(out: Prediction, todo, runs, params, theta, jacobian: bool) -> Prediction:
    """``out`` with each replayed experiment's samples (``runs``: (position, its
    derivatives, markers, theirs) per experiment of ``todo``, None where the replay failed:
    zero derivatives, so the optimiser steps back). The core differentiates ``area_scale``
    by a factor on the current areas, which are theta_j times the design's: d/d theta_j =
    (1/theta_j) d/dk."""
    for exp, run in zip(todo, runs, strict=True):
        if run is None:
            if jacobian:
                out.d_tip[exp] = 0.0
                if out.d_markers is not None:
                    out.d_markers[exp] = 0.0
            continue
        out.tip[exp], dj, markers, dm = run
        if markers is not None:
            out.markers[exp] = markers
        out.ok[exp] = True
        if jacobian:
            for j, p in enumerate(params):
                if p.kind == "area_scale":
                    dj[..., j] /= theta[j]
                    if dm is not None:
                        dm[..., j] /= theta[j]
            out.d_tip[exp] = dj
            if dm is not None:
                out.d_markers[exp] = dm
    return out
