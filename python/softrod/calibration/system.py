"""Calibration of a system of rods holding one platform (a parallel continuum robot) from
what a lab measures: the platform's position (the dataset's tip columns) and
motion-capture markers on the platform and on the rods (``Dataset.marker_body``).

The fit is :func:`softrod.calibrate`'s engine (weighted residuals, Levenberg-Marquardt on
exact Jacobians or Nelder-Mead, restarts, standard errors and identifiability warnings);
the model is the system's statics with the exact parameter derivatives of its platform
pose and markers (``_core.rod_system_sensitivity_batch``: the implicit function theorem
on the system's residual, docs/calibration.md "Systems of rods").

Parameters are the rods' (:mod:`softrod.calibration.params`) and the platform's mass:

- ``"E"``, ``"c_b[body]"``, ...: one value acting on every rod of the system (identical
  rods share their material and factors); every rod must have what it acts on, and the
  rods must share its starting value.
- ``"rods[1].c_b"``: rod 1's alone.
- ``"platform_mass"``: the platform's mass (kg; it must start > 0).
- ``"registration_angle"``, ``"registration_x"``, ``"_y"``, ``"_z"``: the measurement
  frame, a rotation about the rods' mean base axis through the centroid of their bases,
  then an offset (as :func:`softrod.calibrate` fits a lone rod's, paper 000 Sec. III-D).
- ``"damping_time"`` (time series only, ``dynamic=True``): the rods' damping time, on
  every rod (they must share it) or ``"rods[i].damping_time"``.

With ``dynamic=True`` the rows are time series (:class:`SystemDynamic`): every experiment
is replayed from rest in equilibrium under its first pressures, the measured pressures
joined linearly between the samples, and the core carries the exact forward
sensitivities of every step of the system (``SystemSimulator::track_sensitivities``:
the implicit function theorem on each step's coupled equations, docs/calibration.md
"Systems of rods").
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
import re
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from .. import _core
from .. import _validate as V
from .._threads import one_blas_thread
from ..datasets import Dataset, load_dataset
from ..errors import (
    CalibrationWarning,
    ConvergenceError,
    DesignError,
    InputError,
    design_error,
)
from ..progress import reporter
from ..schema import PLATFORM_BODY
from ..statics import SolverOptions, _options
from ..system import (
    System,
    _batch_entries,
    _platform_args,
    check_rods,
    load_system,
    rod_blocks,
    system_sigma,
)
from .diagnostics import diagnostics, warning_thresholds
from .fit import _bounds, _evaluations, _scales, _split, _split_params
from .params import DYNAMIC_KINDS, KINDS, SIGMA_KINDS, Parameter, design_changes, parse_parameter
from .problem import ModelAdapter, Observations, Prediction, Problem, Registered, Residual
from .result import display_table, error_tables, fit_summary, record, report_points
from .solve import METHODS, Settings, check_restarts, run_starts, start_points, starts_table

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from .._types import PathLike, Quantity

logger = logging.getLogger("softrod.calibrate")

#: The platform's mass parameter.
PLATFORM_MASS = "platform_mass"
_ON_ROD = re.compile(r"^\s*rods\[\s*(\d+)\s*\]\s*\.\s*(.+?)\s*$")


@dataclass(frozen=True)
class SystemParameter:
    """One calibration parameter of a system: a rod parameter on the listed rods (each
    rod's own :class:`~softrod.calibration.params.Parameter`, with its own sections), or
    the platform's mass (no rods)."""

    name: str
    kind: str
    rods: tuple[tuple[int, Parameter], ...] = ()

    @property
    def unit(self) -> str:
        return "kg" if self.kind == PLATFORM_MASS else self.rods[0][1].unit

    @property
    def positive(self) -> bool:
        return self.kind == PLATFORM_MASS or self.rods[0][1].positive

    def core(self) -> tuple[str, list[tuple[int, list[int]]]]:
        """The binding's (kind, [(rod, sections)])."""
        return self.kind, [(i, list(p.sections)) for i, p in self.rods]

    def value(self, system: System) -> float:
        """Its value in ``system`` (SI)."""
        if self.kind == PLATFORM_MASS:
            return float(system.platform.mass)
        i, p = self.rods[0]
        return p.value(system.rods[i].design)


def parse_system_parameters(
    names: Sequence[str] | str, system: System, *, dynamic: bool = False
) -> list[SystemParameter]:
    """Resolve parameter names of a system (see the module's docstring; the damping time
    only with ``dynamic``). Errors name the parameter, the rod and the rule."""
    if isinstance(names, str):
        names = [n for n in re.split(r",(?![^\[]*\])", names) if n.strip()]
    if not isinstance(names, (list, tuple)) or not names:
        raise V.fail(
            "params",
            names,
            "name at least one parameter: a list such as ['E', 'platform_mass'] or a "
            "comma-separated string",
        )
    out: list[SystemParameter] = []
    n = len(system.rods)
    for name in names:
        if not isinstance(name, str):
            raise V.fail(
                "params", name, "each parameter must be a name such as 'E' or 'rods[1].c_b'"
            )
        if name.strip() == PLATFORM_MASS:
            if not system.platform.mass > 0:
                raise V.fail(
                    "params",
                    name,
                    f"system {system.name!r} has a massless platform; give it a starting mass "
                    "> 0 (the mass is fitted on a log scale, so it stays > 0)",
                )
            out.append(SystemParameter(PLATFORM_MASS, PLATFORM_MASS))
            continue
        one = _ON_ROD.match(name)
        rods = [int(one.group(1))] if one else list(range(n))
        inner = one.group(2) if one else name
        if one and rods[0] >= n:
            raise V.fail(
                "params", name, f"system {system.name!r} has {n} rods (rods[0] ... rods[{n - 1}])"
            )
        kind = re.match(r"\s*([A-Za-z_0-9]+)", inner)
        if kind is None or kind.group(1) not in KINDS:
            raise V.fail(
                "params",
                name,
                f"unknown parameter; a system takes {PLATFORM_MASS} and the rods' kinds "
                f"({', '.join(k for k in KINDS if k not in SIGMA_KINDS + DYNAMIC_KINDS)}), "
                "on every rod or on one as rods[i].kind, and the registration parameters",
            )
        entries = []
        for i in rods:
            try:
                p = parse_parameter(inner, system.rods[i].design)
            except InputError as e:
                raise V.fail(
                    "params",
                    name,
                    f"on rods[{i}] (design {system.rods[i].design.name!r}): {e.rule}"
                    + (
                        ""
                        if one
                        else f"; a parameter of one rod alone is written rods[i].{inner.strip()}"
                    ),
                ) from None
            if p.kind in SIGMA_KINDS or (p.kind in DYNAMIC_KINDS and not dynamic):
                raise V.fail(
                    "params",
                    name,
                    "a system's static fit takes the rods' design parameters and platform_mass "
                    "(stiffness scaling factors are not fitted on systems; the damping time "
                    "only in time series, dynamic=True)",
                )
            entries.append((i, p))
        # A parameter on several rods is one value: rods that differ need one each. Checked
        # here, before any solve (the core refuses it too, at its first evaluation).
        values = [p.value(system.rods[i].design) for i, p in entries]
        if any(v != values[0] for v in values):
            listed = ", ".join(
                f"rods[{i}] has {v:g}" for (i, _), v in zip(entries, values, strict=True)
            )
            raise V.fail(
                "params",
                name,
                f"is one value on every rod, but the rods differ ({listed}): name one per rod, "
                f"e.g. rods[0].{inner.strip()} and rods[1].{inner.strip()}",
            )
        out.append(SystemParameter(name.strip(), entries[0][1].kind, tuple(entries)))
    seen: dict[tuple, str] = {}
    for p in out:
        keys = [(i, p.kind, s) for i, q in p.rods for s in q.sections] or [(None, p.kind, None)]
        for key in keys:
            if key in seen:
                raise V.fail("params", p.name, f"acts on the same thing as {seen[key]!r}")
            seen[key] = p.name
    return out


def resolve_system_parameters(names, system: System, *, dynamic: bool = False) -> list:
    """The parameter objects (name, unit, positive) that ``names`` gives a system's fit, in
    order: the system's (:func:`parse_system_parameters`), then the registration's (for
    messages and the command line's units)."""
    rest, registration = _split_params(names, None, "cosserat")
    found = parse_system_parameters(rest, system, dynamic=dynamic) if rest else []
    return [*found, *registration]


def calibrated_system(system: System, params: Sequence[SystemParameter], values) -> System:
    """``system`` with the parameters set to ``values`` (SI): each rod's design rewritten
    (:func:`~softrod.calibration.params.design_changes`), the platform's mass replaced."""
    per_rod: dict[int, tuple[list[Parameter], list[float]]] = {}
    platform = system.platform
    for p, v in zip(params, values, strict=True):
        if p.kind == PLATFORM_MASS:
            platform = dataclasses.replace(platform, mass=float(v))
            continue
        for i, q in p.rods:
            ps, vs = per_rod.setdefault(i, ([], []))
            ps.append(q)
            vs.append(float(v))
    rods = tuple(
        dataclasses.replace(rod, design=rod.design.replace(design_changes(*per_rod[i], rod.design)))
        if i in per_rod
        else rod
        for i, rod in enumerate(system.rods)
    )
    return dataclasses.replace(system, rods=rods, platform=platform)


def _markers_core(dataset: Dataset) -> list[tuple[int | None, float, list[float]]]:
    """The binding's markers of a system's dataset: (rod or None for the platform, s,
    offset)."""
    if dataset.markers is None:
        return []
    return [
        (None if int(b) == PLATFORM_BODY else int(b), float(s), [float(v) for v in o])
        for b, s, o in zip(
            dataset.marker_body, dataset.marker_s, dataset.marker_offset, strict=True
        )
    ]


class SystemStatic(ModelAdapter):
    """The platform position (the dataset's "tip") and the markers of every row's system
    equilibrium, with their exact parameter derivatives."""

    model = "cosserat"
    dynamic = False

    def __init__(self, system: System, dataset: Dataset, params, options, threads: int):
        super().__init__()
        self.system = system
        self.params = list(params)
        self.parameters = tuple(params)
        self.initial = np.array([p.value(system) for p in params])
        self.p = np.ascontiguousarray(dataset.pressures, dtype=float)
        self.t = None if dataset.tensions is None else np.ascontiguousarray(dataset.tensions)
        # sigma of the stiffness-mapped rods depends on the pressures alone, not on the
        # fitted parameters: every row's, and the unactuated system's, evaluated once from
        # the rods' design maps.
        maps = check_rods(system)
        widths = [rod.design.n_channels for rod in system.rods]
        self.sigma = system_sigma(maps, rod_blocks(self.p, widths))
        self.sigma_rest = system_sigma(maps, rod_blocks(np.zeros((1, self.p.shape[1])), widths))
        self.markers = _markers_core(dataset)
        self.opts = _options(options).as_kwargs()
        self.threads = threads
        self.x0: np.ndarray | None = None

    # --- pickling for Dask workers: the rods' designs travel as TOML text ---------------------

    def __getstate__(self):
        from ..cluster import design_text

        state = dict(self.__dict__)
        rods = tuple(dataclasses.replace(r, design=design_text(r.design)) for r in self.system.rods)
        state["system"] = dataclasses.replace(self.system, rods=rods)
        return state

    def __setstate__(self, state):
        from ..cluster import design_from_text

        sysm = state["system"]
        rods = tuple(dataclasses.replace(r, design=design_from_text(r.design)) for r in sysm.rods)
        state["system"] = dataclasses.replace(sysm, rods=rods)
        self.__dict__.update(state)

    def set_threads(self, threads: int) -> None:
        self.threads = threads

    def reset(self) -> None:
        self.evaluations = 0
        self.x0 = None

    def _solve(
        self, system: System, params, rows, jacobian: bool, warm: bool, theta=None
    ) -> Prediction:
        out = Prediction.empty(len(self.p), len(params), len(self.markers), jacobian)
        x0 = None
        if warm and self.x0 is not None:
            x0 = np.ascontiguousarray(self.x0[rows])
        res = _core.rod_system_sensitivity_batch(
            _batch_entries(system),
            _platform_args(system, None, None),
            np.ascontiguousarray(self.p[rows]),
            [p.core() for p in params] if jacobian else [],
            tensions=None if self.t is None else np.ascontiguousarray(self.t[rows]),
            markers=self.markers,
            x0=x0,
            threads=self.threads,
            stiffness_scale=None if self.sigma is None else np.ascontiguousarray(self.sigma[rows]),
            **self.opts,
        )
        ok = np.asarray(res["converged"], dtype=bool)
        out.tip[rows] = res["platform_position"]
        if out.markers is not None:
            out.markers[rows] = res["marker_position"]
        if jacobian:
            dp, dm = res["d_platform_position"], res["d_marker_position"]
            for j, p in enumerate(params):
                if p.kind == "area_scale":
                    # The core differentiates by a factor on the current areas, which are
                    # theta_j times the design's: d/d theta_j = (1/theta_j) d/dk.
                    dp[..., j] /= theta[j]
                    dm[..., j] /= theta[j]
            out.d_tip[rows] = dp
            if out.d_markers is not None:
                out.d_markers[rows] = dm
        out.ok[rows] = ok
        if warm:
            if self.x0 is None:
                self.x0 = np.full((len(self.p), res["x"].shape[1]), np.nan)
            good = np.asarray(rows)[ok]
            self.x0[good] = res["x"][ok]
        return out

    def predict(self, theta, rows, jacobian: bool) -> Prediction:
        self.evaluations += 1
        rows = np.asarray(rows)
        try:
            system = calibrated_system(self.system, self.params, theta)
        except DesignError:
            # A trial point outside what a design allows: every row fails, so the optimiser
            # steps back.
            return Prediction.empty(len(self.p), len(self.params), len(self.markers), jacobian)
        return self._solve(system, self.params, rows, jacobian, warm=True, theta=theta)

    def calibrated_design(self, theta) -> System:
        return calibrated_system(self.system, self.params, theta)

    def final_prediction(self, calibrated: System, theta, rows) -> Prediction:
        return self._solve(calibrated, [], np.asarray(rows), False, warm=False)

    def base_frame(self):
        """(the centroid of the rods' base points, their mean base axis): the axis a
        registration turns the measurement frame about; None where the base axes cancel
        (rods mounted against each other)."""
        mounts = [rod.design.spec["mounting"] for rod in self.system.rods]
        base = np.mean([m["base_position"] for m in mounts], axis=0)
        axis = np.sum([np.asarray(m["base_rotation"])[:, 2] for m in mounts], axis=0)
        norm = float(np.linalg.norm(axis))
        if norm < 1e-6 * len(mounts):
            return None
        return base, axis / norm

    def reference(self, calibrated: System, theta) -> Prediction:
        """The unactuated system's platform and markers (zero pressures, slack tendons)."""
        m = len(self.p)
        rest = SystemStatic.__new__(SystemStatic)
        rest.__dict__.update(self.__dict__)
        rest.p = np.zeros((1, self.p.shape[1]))
        rest.t = None if self.t is None else np.zeros((1, self.t.shape[1]))
        rest.sigma = self.sigma_rest
        one = rest._solve(calibrated, [], np.arange(1), False, warm=False)
        out = Prediction.empty(m, 0, len(self.markers), False)
        out.tip[:] = one.tip[0]
        if out.markers is not None:
            out.markers[:] = one.markers[0]
        out.ok[:] = one.ok[0]
        return out


class SystemDynamic(ModelAdapter):
    """The platform position (the dataset's "tip") and the markers of every sample of every
    replayed experiment (rows with ``time``; experiment ids split them), with their exact
    parameter derivatives: each experiment starts at rest in the system's equilibrium
    under its first pressures, the measured pressures (rod 0's channels, then rod 1's, ...)
    drive it joined linearly between the samples, and the model is read at the sample
    times (linear between the steps of dt). The core carries the forward sensitivities of
    every step (``SystemSimulator::track_sensitivities``), run as
    :func:`softrod.system_trajectory_sensitivities` runs them (its
    ``system_dynamics.tracked_run``)."""

    model = "cosserat"
    dynamic = True
    exact_jacobian = True
    #: As :class:`~softrod.calibration.adapters.rod_dynamic.RodDynamic`: every evaluation
    #: replays every experiment (the same reasons for each setting).
    nelder_mead = {"xatol": 1e-4, "fatol": 1e-9, "fatol_relative": True, "step": 0.2}
    stateless = True
    lm_stop_fraction = 1e-3

    def __init__(self, system: System, dataset: Dataset, params, dt: float, tol: float, threads):
        from .adapters.rod_dynamic import experiment_rows

        super().__init__()
        for p in params:
            if not p.positive:
                raise V.fail("params", p.name, "dynamic calibration fits positive parameters only")
            if p.kind == "damping_time" and not p.value(system) > 0:
                raise V.fail(
                    f"system.rods[{p.rods[0][0]}].design.dynamics.damping_time",
                    p.value(system),
                    "give a starting damping time > 0 s in [dynamics] (the fit works on log tau)",
                )
        self.system = system
        self.params = list(params)
        self.parameters = tuple(params)
        self.initial = np.array([p.value(system) for p in params])
        self.dt = dt
        self.tol = tol
        self.threads = threads
        self.experiments = experiment_rows(dataset)
        self.time = np.asarray(dataset.time, dtype=float)
        self.p = np.ascontiguousarray(dataset.pressures, dtype=float)
        # Tendon tensions (N) of every sample, inputs joined linearly as the pressures are;
        # None: every tendon slack.
        self.t = None if dataset.tensions is None else np.asarray(dataset.tensions, dtype=float)
        self.markers = _markers_core(dataset)
        self.m = len(dataset)
        self.widths = [r.design.n_channels for r in system.rods]
        self.tendon_widths = [r.design.n_tendons for r in system.rods]

    def set_threads(self, threads: int) -> None:
        self.threads = threads

    def _commands(self, p: np.ndarray, widths=None) -> list[list[float]]:
        """One row of inputs (all channels: pressures, or tensions with the tendon widths)
        as one list per rod."""
        out, o = [], 0
        for w in self.widths if widths is None else widths:
            out.append([float(v) for v in p[o : o + w]])
            o += w
        return out

    def _replay(self, system: System, exp: np.ndarray, jacobian: bool):
        """The platform position (k, 3), markers (k, K, 3) and, with ``jacobian``, their
        derivatives (k, 3, P), (k, K, 3, P) at the sample times of one experiment; None: the
        run failed."""
        from ..system_dynamics import SystemSimulation, tracked_run

        t = self.time[exp] - self.time[exp][0]

        def joined(values: np.ndarray, widths=None):
            # The inputs joined linearly between the samples (held after the last), read
            # at every step's end.
            def at(time: float) -> list[list[float]]:
                row = [np.interp(time, t, values[:, c]) for c in range(values.shape[1])]
                return self._commands(np.array(row), widths)

            return at

        p = self.p[exp]
        tensions = None if self.t is None else self.t[exp]
        tw = self.tendon_widths
        try:
            sim = SystemSimulation(
                system,
                self._commands(p[0]),
                tensions=None if tensions is None else self._commands(tensions[0], tw),
                dt=self.dt,
                tol=self.tol,
                on_unstable="ignore",
            )
            run = tracked_run(
                sim,
                self.params if jacobian else [],
                self.markers,
                t[-1],
                joined(p),
                None if tensions is None else joined(tensions, tw),
                field="dataset.time",
            )
        except ConvergenceError:  # InvalidStateError included
            return None
        time_s = run["time"]

        def sample(a):
            flat = a.reshape(a.shape[0], -1)
            cols = [
                np.interp(np.minimum(t, time_s[-1]), time_s, flat[:, c])
                for c in range(flat.shape[1])
            ]
            return np.column_stack(cols).reshape((len(t),) + a.shape[1:])

        pos = sample(run["platform_position"])
        mk = sample(run["marker_position"]) if self.markers else None
        if not jacobian:
            return pos, None, mk, None
        dp = sample(run["d_platform_position"])
        dm = sample(run["d_marker_position"]) if self.markers else None
        return pos, dp, mk, dm

    def predict(self, theta, rows, jacobian: bool) -> Prediction:
        out = Prediction.empty(self.m, len(self.params), len(self.markers), jacobian)
        self.evaluations += 1
        try:
            system = calibrated_system(self.system, self.params, theta)
        except DesignError:
            return out
        wanted = np.zeros(self.m, dtype=bool)
        wanted[rows] = True
        todo = [exp for exp in self.experiments if wanted[exp].any()]
        # Each replay steps in the core with the GIL released: threads overlap the runs (in
        # order: the same result on any count).
        workers = min(len(todo), self.threads or os.cpu_count() or 1)
        if workers > 1:
            with ThreadPoolExecutor(workers) as pool:
                runs = list(pool.map(lambda exp: self._replay(system, exp, jacobian), todo))
        else:
            runs = [self._replay(system, exp, jacobian) for exp in todo]
        from .adapters.rod_dynamic import fill_replays

        return fill_replays(out, todo, runs, self.params, theta, jacobian)

    def calibrated_design(self, theta) -> System:
        return calibrated_system(self.system, self.params, theta)

    def final_prediction(self, calibrated: System, theta, rows) -> Prediction:
        return self.predict(theta, rows, False)

    def base_frame(self):
        return SystemStatic.base_frame(self)  # type: ignore[arg-type]

    def reference(self, calibrated: System, theta) -> Prediction:
        """The unactuated system's platform and markers (zero pressures, slack tendons), as
        the static fit's reference."""
        first = Dataset(
            pressures=self.p[:1],
            tensions=None if self.t is None else self.t[:1],
            tip_position=np.zeros((1, 3)),
        )
        rest = SystemStatic(calibrated, first, [], None, 1)
        rest.markers = self.markers
        one = SystemStatic.reference(rest, calibrated, theta)
        out = Prediction.empty(self.m, 0, len(self.markers), False)
        out.tip[:] = one.tip[0]
        if out.markers is not None:
            out.markers[:] = one.markers[0]
        out.ok[:] = one.ok[0]
        return out


@dataclass(frozen=True)
class SystemCalibrationResult:
    """What :func:`calibrate_system` found. Values and standard errors in SI (``units``).

    system: the calibrated system (each fitted rod's design renamed ``<name>_calibrated``
    with ``[design.provenance]`` of this fit; the platform's fitted mass); predicted,
    predicted_markers: the calibrated model's platform positions (m, 3) and markers (m, K,
    3) or None, NaN where the model failed (``converged`` False); labels: "train" or
    "test" per row; error_table: the errors per measured quantity ("platform": its
    position, the dataset's tip columns; "markers") and set; cost: the weighted sum of
    squared training residuals, cost_m2 the plain sum of squared position errors (m^2)."""

    system: System
    initial_system: System
    parameters: tuple[SystemParameter, ...]
    initial: np.ndarray
    values: np.ndarray
    std_errors: np.ndarray
    covariance: np.ndarray
    correlation: np.ndarray
    warnings: tuple[str, ...]
    method: str
    success: bool
    message: str
    evaluations: int
    cost: float
    cost_m2: float
    dataset: Dataset
    predicted: np.ndarray
    predicted_markers: np.ndarray | None
    converged: np.ndarray
    labels: np.ndarray
    error_table: pd.DataFrame
    scales: Mapping[str, float]
    elapsed_s: float
    metadata: dict = field(default_factory=dict)
    registration: dict | None = None
    starts: pd.DataFrame | None = None

    @property
    def units(self) -> dict[str, str]:
        """Each parameter's SI unit."""
        return {p.name: p.unit for p in self.parameters}

    def parameter_table(self) -> pd.DataFrame:
        """One row per parameter: initial and fitted values, standard error (SI, unit
        column) and the standard error in % of the value."""
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = np.abs(self.std_errors / np.where(self.values == 0, np.nan, self.values))
        return pd.DataFrame(
            {
                "parameter": [p.name for p in self.parameters],
                "unit": [p.unit for p in self.parameters],
                "initial": self.initial,
                "value": self.values,
                "std_error": self.std_errors,
                "rel_std_error_pct": 100 * rel,
            }
        )

    def to_frame(self) -> pd.DataFrame:
        """One row per sample: the measured and the calibrated model's platform position
        (m), the distance between them (mm; NaN where not measured or the model failed)
        and the set ("train" or "test")."""
        measured = self.dataset.tip_position
        cols: dict[str, Any] = {}
        for i, a in enumerate("xyz"):
            if measured is not None:
                cols[f"platform_{a}_m"] = measured[:, i]
            cols[f"model_platform_{a}_m"] = self.predicted[:, i]
        if measured is not None:
            cols["error_mm"] = 1e3 * np.linalg.norm(self.predicted - measured, axis=1)
        cols["converged"] = self.converged
        cols["set"] = self.labels
        return pd.DataFrame(cols)

    def plot(
        self, path: str | os.PathLike | None = None, *, initial: np.ndarray | None = None
    ) -> Figure:
        """Measured against predicted platform positions (front view, x-z) and each row's
        platform error, train and test rows marked; ``initial``: (m, 3) platform positions
        of another model (e.g. the system before calibration) drawn and compared too.
        Written to ``path`` when given (.png, .pdf, .svg); returns the Figure."""
        import matplotlib.pyplot as plt

        measured = self.dataset.tip_position
        if measured is None:
            raise design_error(
                "dataset.tip_position",
                None,
                "plot draws the platform's measured positions; this dataset has markers only",
                InputError,
            )
        # The arguments are checked before anything is drawn.
        if initial is not None:
            initial = V.real_array(initial, "initial", what="platform positions (m)")
            if initial.shape != measured.shape:
                raise design_error(
                    "initial",
                    f"shape {initial.shape}",
                    f"must be {measured.shape}: one platform position per row (m)",
                    InputError,
                )
        if path is not None:
            from ..plotting import check_figure_path

            path = check_figure_path(path)
        after = self.predicted
        fig, (front, err) = plt.subplots(1, 2, figsize=(11, 4.4), constrained_layout=True)
        rows = np.arange(len(measured))
        test = self.labels == "test"
        front.plot(*(measured[:, [0, 2]] * 1e3).T, "o", mfc="none", color="k", label="measured")
        bars = [(after, "tab:blue", "calibrated")]
        if initial is not None:
            front.plot(*(initial[:, [0, 2]] * 1e3).T, "x", color="tab:red", label="initial")
            bars.insert(0, (initial, "tab:red", "initial"))
        front.plot(*(after[:, [0, 2]] * 1e3).T, "+", ms=9, color="tab:blue", label="calibrated")
        if test.any():
            front.plot(
                *(measured[test][:, [0, 2]] * 1e3).T,
                "s",
                mfc="none",
                ms=10,
                color="tab:gray",
                label="test rows",
            )
        front.set_xlabel("platform x (mm)")
        front.set_ylabel("platform z (mm)")
        front.set_title("platform positions, front view")
        front.legend(loc="best")
        width = 0.8 / len(bars)
        top = 0.0
        for k, (pred, colour, label) in enumerate(bars):
            e = np.linalg.norm(pred - measured, axis=1) * 1e3
            top = max(top, float(np.nanmax(e)) if np.isfinite(e).any() else 0.0)
            err.bar(
                rows + (k - (len(bars) - 1) / 2) * width, e, width=width, color=colour, label=label
            )
        err.set_ylim(0, 1.35 * top if top > 0 else 1.0)  # room for the legend
        err.set_xlabel(
            "row"
            + (
                " (test rows: " + ", ".join(map(str, rows[test])) + ")"
                if 0 < test.sum() <= 6
                else ""
            )
        )
        err.set_ylabel("platform position error (mm)")
        err.set_title("error per row")
        err.legend(loc="upper right")
        fig.suptitle(f"calibrate_system: {self.initial_system.name}")
        if path is not None:
            from ..plotting import save_figure

            save_figure(fig, path)
        return fig

    def write_report(self, path: str | os.PathLike) -> Path:
        """An HTML report in one self-contained file, written whole or not at all: the
        summary (system, dataset, method, cost, registration), the parameters with their
        standard errors and correlations, the errors per measured quantity (the platform's
        position, the markers) and set, and the figures of a rod's calibration report
        (measured against predicted positions, errors per set and against the pressures)
        for the platform's positions, or the markers' where the dataset has no platform
        position. Returns the path."""
        from .report import write_report

        points = report_points(
            self.dataset, self.predicted, self.predicted_markers, self.labels, "platform"
        )
        rods = self.initial_system.rods
        dynamic = bool(self.metadata.get("dynamic", False))
        summary = {
            "system": self.initial_system.name,
            "rods": ", ".join(r.design.name for r in rods),
            "model": "Cosserat rods held by one rigid platform"
            + (" (time series replayed)" if dynamic else " (equilibria)"),
            **fit_summary(self),
        }
        return write_report(
            path,
            title=f"softrod system calibration: {self.initial_system.name}",
            summary=summary,
            parameter_table=display_table(self.parameter_table()),
            error_table=self.error_table,
            error_title="Platform and marker errors",
            **points,
            warnings=self.warnings,
            correlation=self.correlation,
            param_names=[p.name for p in self.parameters],
            length=float(np.mean([r.design.length for r in rods])),
            warning_rules=warning_thresholds(),
        )

    def __repr__(self) -> str:
        parts = ", ".join(
            f"{p.name} = {v:.4g} +- {s:.2g} {p.unit}"
            for p, v, s in zip(self.parameters, self.values, self.std_errors, strict=True)
        )
        rms = self.error_table
        train = rms[rms["set"] == "train"] if (rms["set"] == "train").any() else rms
        err = ", ".join(
            f"{q} RMS {r:.3g} mm"
            for q, r in zip(train["quantity"], train["rms_error_mm"], strict=True)
        )
        return (
            f"SystemCalibrationResult({self.initial_system.name!r}: {parts}; {err}; "
            f"{self.method}, {'converged' if self.success else 'not converged'}, "
            f"{self.evaluations} evaluations)"
        )


@one_blas_thread
def calibrate_system(
    system: System | str | PathLike,
    dataset: Dataset | PathLike,
    params: Sequence[str] | str,
    *,
    bounds: Mapping[str, Sequence] | None = None,
    method: str | None = None,
    split: str | np.ndarray | None = None,
    test: Any = None,
    weights: Mapping[str, Quantity] | None = None,
    options: SolverOptions | None = None,
    threads: int = 0,
    max_evaluations: int = 200,
    restarts: int = 0,
    seed: int = 0,
    progress: Callable[[int, float], None] | bool | None = None,
    executor: Any = None,
    dynamic: bool = False,
    dt: Any = None,
) -> SystemCalibrationResult:
    """Fit ``params`` of a :class:`~softrod.System` to measured equilibria.

    dataset: a :class:`~softrod.Dataset` or a path to one whose rows are the system's
    equilibria: pressure columns p0, p1, ... are rod 0's channels, then rod 1's, ... (and
    tension columns likewise); the tip columns are the platform origin's position (world);
    markers sit on the platform or on a rod (``Dataset.marker_body``; in a file each
    marker's metadata names its ``body``, "platform" or "rod<i>", docs/datasets.md). Rows
    are solved as :func:`~softrod.solve_system` solves them (frictionless obstacles only:
    friction makes an equilibrium depend on its load path). A stiffness-mapped rod takes
    each row's sigma from its design's map (``[stiffness_map] file``; sigma depends on the
    pressures alone, not on the fitted parameters, and is not itself fitted on a system).
    params: rod parameters (acting on every rod, or ``"rods[i].kind"`` on one) and
    ``"platform_mass"`` (see :mod:`softrod.calibration.system`). bounds, method, split,
    test, weights, options, threads, max_evaluations, restarts, seed, progress and executor
    (a ``distributed.Client``: the starts run on its cluster, one task each) as in
    :func:`~softrod.calibrate` (weights: "tip" and "markers").
    dynamic: fit time series instead of equilibria (:class:`SystemDynamic`): each
    experiment of ``dataset`` (rows with ``time``; ``experiment`` ids split them) is
    replayed from rest in equilibrium under its first pressures with time step ``dt``
    (s or a string with units; default :data:`~softrod.calibration.fit.DEFAULT_DT`), the
    measured pressures joined linearly between the samples, with the exact Jacobians of
    the system's forward sensitivities; ``"damping_time"`` may then be fitted. ``dt``
    without ``dynamic`` is refused.

    Returns a :class:`SystemCalibrationResult`; a :class:`CalibrationWarning` for each
    identifiability problem, as :func:`~softrod.calibrate` does. Bad input raises
    :class:`~softrod.errors.InputError` naming the field before any solve.
    """
    start = time.perf_counter()
    method = "lm" if method is None else method
    V.choice(method, METHODS, "method")
    threads = V.threads(threads)
    V.integer(max_evaluations, "max_evaluations", minimum=1, maximum=V.MAX_ITERATIONS)
    check_restarts(restarts, seed)
    if not isinstance(system, System):
        system = load_system(system)
    for i, rod in enumerate(system.rods):
        if rod.design.frictional_obstacle is not None:
            raise V.fail(
                f"system.rods[{i}].design",
                rod.design.name,
                "has an obstacle with friction > 0: a frictional equilibrium depends on its "
                "load path, so it has no parameter derivatives at one point; calibrate with "
                "frictionless obstacles",
            )
    if not isinstance(dataset, Dataset):
        dataset = load_dataset(dataset)
    _check_dataset(system, dataset)
    V.boolean(dynamic, "dynamic")
    if dt is not None and not dynamic:
        from .fit import _STATIC_DT

        raise V.fail("dt", dt, _STATIC_DT)
    names, registration = _split_params(params, None, "cosserat")
    parameters = parse_system_parameters(names, system, dynamic=dynamic) if names else []
    if dynamic:
        from ..dynamics.simulate import _seconds
        from ..system_dynamics import SystemSimulation
        from .fit import DEFAULT_DT

        step = _seconds(DEFAULT_DT if dt is None else dt, "dt")
        tol = _options(options).tol
        inner: ModelAdapter = SystemDynamic(system, dataset, parameters, step, tol, threads)
        # The core checks every parameter against its rods (one value, known sections, a
        # damping time that acts) when it starts tracking, before any step.
        probe = SystemSimulation(
            system, inner._commands(inner.p[0]), dt=step, tol=tol, on_unstable="ignore"
        )
        probe._sim.track_sensitivities([p.core() for p in parameters])
    else:
        inner = SystemStatic(system, dataset, parameters, options, threads)
        # The core checks every parameter against its rods (one value, known sections) on
        # an empty batch, before any solve.
        _core.rod_system_sensitivity_batch(
            _batch_entries(system),
            _platform_args(system, None, None),
            np.zeros((0, dataset.n_channels)),
            [p.core() for p in parameters],
            tensions=None if dataset.tensions is None else np.zeros((0, dataset.n_tendons)),
            stiffness_scale=None if inner.sigma is None else np.ones((0, len(system.rods), 3)),
        )
    # The measurement frame (registration_*): the engine's wrapper of any adapter.
    adapter = Registered(inner, registration) if registration else inner
    params_all = list(adapter.parameters)
    theta0 = np.asarray(adapter.initial, dtype=float)
    box = _bounds(params_all, bounds, theta0)
    test_mask = _split(dataset, split, test)
    train = np.flatnonzero(~test_mask)
    scales = _scales(weights, dataset)
    observed = Observations(dataset.tip_position, dataset.markers)
    residual = Residual(observed, train, scales)
    problem = Problem(adapter, residual, box)
    logger.info(
        "calibrate_system %s: %s on %d training samples (%d test), method %s",
        system.name,
        ", ".join(p.name for p in params_all),
        train.size,
        int(test_mask.sum()),
        method,
    )
    starts = start_points(params_all, theta0, box, restarts, seed)
    settings = Settings(method, int(max_evaluations))
    with reporter(progress, "calibrate_system", None, _evaluations) as report:
        fits = run_starts(problem, settings, starts, report, executor, threads)
    best = min(
        range(len(fits)),
        key=lambda k: (fits[k]["cost"] if math.isfinite(fits[k]["cost"]) else math.inf, k),
    )
    success, message = fits[best]["success"], fits[best]["message"]
    values = problem.theta_of(fits[best]["u"])
    adapter.reset()
    adapter.evaluations = sum(f["evaluations"] for f in fits)
    pred = fits[best].get("prediction")
    if pred is None:
        pred = problem.predict(values, True)
    if not pred.ok[train].all():
        bad = train[~pred.ok[train]]
        raise ConvergenceError(
            f"calibrate_system: the model failed for {bad.size} training samples at the "
            f"fitted parameters ({dataset.rows_text(bad)}); check the data and the bounds"
        )
    r = residual.vector(pred)
    ssr = float(r @ r)
    what = "the platform" + (" and marker" if dataset.markers is not None else "") + " positions"
    cov, std, corr, found = diagnostics(
        params_all, values, residual.jacobian(pred), ssr, r.size, what
    )
    if not success:
        found.insert(0, f"the optimiser stopped without converging: {message}")
    n_in = len(parameters)
    fitted = calibrated_system(system, parameters, values[:n_in])
    fitted = _with_provenance(
        fitted,
        system,
        parameters,
        values[:n_in],
        std[:n_in],
        fits[best]["method"],
        dataset,
        train.size,
    )
    all_rows = np.arange(len(dataset))
    final = adapter.final_prediction(fitted, values, all_rows)
    reference = adapter.reference(fitted, values)
    labels = np.where(test_mask, "test", "train")
    length = float(np.mean([rod.design.length for rod in system.rods]))
    table = error_tables(
        dataset, final, final.ok, reference, labels if test_mask.any() else None, length, None
    )
    # The dataset's tip columns are the platform's position.
    table["quantity"] = table["quantity"].replace({"tip": "platform"})
    for w in found:
        warnings.warn(w, CalibrationWarning, stacklevel=3)
    reg = None
    if registration:
        angle, offset = adapter.values(values)
        reg = {"angle": angle, "offset": offset}
    return SystemCalibrationResult(
        system=fitted,
        initial_system=system,
        parameters=tuple(params_all),
        initial=theta0,
        values=values,
        std_errors=std,
        covariance=cov,
        correlation=corr,
        warnings=tuple(found),
        method=fits[best]["method"],
        success=success,
        message=message,
        evaluations=adapter.evaluations,
        cost=ssr,
        cost_m2=residual.position_errors_m2(pred),
        dataset=dataset,
        predicted=final.tip,
        predicted_markers=final.markers,
        converged=final.ok,
        labels=labels,
        error_table=table,
        scales=scales,
        elapsed_s=time.perf_counter() - start,
        metadata={
            "system": system.name,
            "training_samples": int(train.size),
            "dynamic": bool(dynamic),
        },
        registration=reg,
        starts=starts_table(params_all, fits, best) if len(fits) > 1 else None,
    )


def _check_dataset(system: System, dataset: Dataset) -> None:
    nc = [r.design.n_channels for r in system.rods]
    nt = [r.design.n_tendons for r in system.rods]
    if dataset.n_channels != sum(nc):
        raise V.fail(
            "dataset.pressures",
            f"{dataset.n_channels} channels",
            f"system {system.name!r} has {sum(nc)} pressure channels ({nc} per rod): the "
            "p columns are rod 0's channels, then rod 1's, ...",
        )
    if dataset.tensions is not None and dataset.n_tendons != sum(nt):
        raise V.fail(
            "dataset.tensions",
            f"{dataset.n_tendons} tension channels",
            f"system {system.name!r} has {sum(nt)} tendon channels ({nt} per rod)",
        )
    if dataset.markers is not None:
        if dataset.marker_body is None:
            raise V.fail(
                "dataset.marker_body",
                None,
                "say which body each marker sits on (-1 the platform, i rod i; in a file the "
                'markers\' metadata "body": "platform" or "rod<i>")',
            )
        for k, (b, s) in enumerate(zip(dataset.marker_body, dataset.marker_s, strict=True)):
            if b >= len(system.rods):
                raise V.fail(
                    f"dataset.marker_body[{k}]",
                    int(b),
                    f"system {system.name!r} has {len(system.rods)} rods",
                )
            if b >= 0 and s > system.rods[b].design.length * (1 + 1e-12):
                raise V.fail(
                    f"dataset.marker_s[{k}]",
                    float(s),
                    f"must lie in [0, L] = [0, {system.rods[b].design.length:g}] m on rods[{b}]",
                )
    if (
        (
            dataset.tip_rotation is not None
            or dataset.tip_reaction_force is not None
            or dataset.tip_reaction_moment is not None
        )
        and dataset.tip_position is None
        and dataset.markers is None
    ):
        raise V.fail(
            "dataset",
            "no positions",
            "a system's fit needs the platform's position (tip columns) or markers",
        )
    if dataset.tip_reaction_force is not None or dataset.tip_reaction_moment is not None:
        raise V.fail(
            "dataset.tip_reaction_force",
            "given",
            "a system's rods hold the platform: a tip reaction has no place in its dataset",
        )
    if dataset.mounting is not None and len(set(dataset.mounting.tolist())) > 1:
        raise V.fail(
            "dataset.mounting",
            sorted(set(dataset.mounting.tolist())),
            "a system is mounted as its file says: fit each mounting separately",
        )


def _with_provenance(fitted, initial, params, values, std, method, dataset, n_train) -> System:
    """Each fitted rod's design renamed ``<name>_calibrated`` with the provenance of its
    own parameters (:func:`~softrod.calibration.result.record`)."""
    rods = list(fitted.rods)
    for i in range(len(rods)):
        # The rod's parameters under the system's names ("rods[1].c_e", "E").
        own = [
            (dataclasses.replace(q, name=p.name), v, s)
            for p, v, s in zip(params, values, std, strict=True)
            for k, q in p.rods
            if k == i
        ]
        if not own:
            continue
        # Each rod's own design (rods of one design file differ in their mounting).
        qs, vs, ss = zip(*own, strict=True)
        calibrated = record(
            rods[i].design,
            initial.rods[i].design,
            None,
            list(qs),
            list(vs),
            list(ss),
            method,
            dataset,
            n_train,
            f"system {initial.name!r}: platform and marker positions of equilibria",
            tool="softrod.calibrate_system",
        )
        rods[i] = dataclasses.replace(rods[i], design=calibrated)
    return dataclasses.replace(fitted, rods=tuple(rods))
