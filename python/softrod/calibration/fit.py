"""Global calibration: fit design parameters to measured tip positions (paper 002's
identification of c_b, c_e, alpha, offsets and c_p; docs/calibration.md).

The cost is the sum of squared tip-position errors over the training samples. With
``method="lm"`` it is minimised by Levenberg-Marquardt (scipy's MINPACK) with the exact
Jacobian from the core (dual numbers through the shooting solve and the implicit function
theorem, ``Rod.sensitivity_batch``; every evaluation is one parallel batch over all
samples); positive parameters are optimised in log space so they stay positive. With
explicit ``bounds`` the same Jacobian drives scipy's trust-region-reflective method.
``method="nelder-mead"`` is paper 002's derivative-free simplex on the same cost.
Standard errors and correlations come from the Jacobian at the optimum (Gauss-Newton
covariance s^2 (J^T J)^-1 with s^2 = SSR / (n - P)).
"""

from __future__ import annotations

import json
import logging
import math
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from .. import _validate as V
from .._threads import one_blas_thread
from ..catalog import load_design
from ..datasets import Dataset, load_dataset
from ..design import Design
from ..errors import CalibrationWarning, ConvergenceError, DesignError, InputError
from ..progress import reporter
from ..schema import DISPLAY_UNITS, display
from ..statics import SolverOptions, _options
from ..units import number, to_si
from .metrics import tip_error_table
from .params import SIGMA_KINDS, Parameter, design_changes, parse_parameters

if TYPE_CHECKING:
    from .._types import ArrayLike, DesignLike, PathLike, Quantity, Units
    from ..pcc import PccFit
    from ..stiffness_map import StiffnessMap
    from .dynamic import DynamicCalibrationResult

logger = logging.getLogger(__name__)


def _evaluations(evaluations: int, rms_mm: float) -> tuple[float, str]:
    """A progress bar's position and text for calibrate's progress(evaluations, rms_mm)."""
    return evaluations, f"{evaluations} evaluations, RMS tip error {rms_mm:.3g} mm"


def warning_thresholds() -> str:
    """The rules behind the calibration warnings, as reports and the CLI state them."""
    return (
        f"warnings when a relative standard error exceeds {100 * POOR_RELATIVE_ERROR:g} %, a "
        f"correlation |r| exceeds {STRONG_CORRELATION:g} or the singular values of the scaled "
        f"Jacobian span more than {UNIDENTIFIABLE_CONDITION:.0e}"
    )


#: Residual scale: residuals are in mm so that the cost is O(1) for scipy's tolerances.
_MM = 1e-3
#: |r| above which a pair of parameters is reported as strongly correlated: at |r| = 0.9 the
#: data pin down one combination of the pair about 2.3 times (1 / sqrt(1 - r^2)) better than
#: either parameter alone, and each standard error is that much larger than it would be with
#: the other parameter fixed.
STRONG_CORRELATION = 0.9
#: Condition number of the column-scaled Jacobian above which the fit is reported as not
#: identifiable: a relative change of 1e-6 in the best-determined combination moves the
#: tips as much as a change of 1 in the worst.
UNIDENTIFIABLE_CONDITION = 1e6
#: A parameter whose standard error exceeds this fraction of its value is reported as poorly
#: determined: at 20 % its 95 % interval spans +-40 % of the value, too wide to compare
#: actuators or to publish the value as a material property.
POOR_RELATIVE_ERROR = 0.2
#: Penalty residual (mm) of a sample whose solve fails at a trial point, so that the
#: optimiser steps back instead of stopping on a NaN.
_FAILED_RESIDUAL_MM = 1e3
_ORIENTATIONS = ("hanging", "upright", "horizontal")


def _fail(field_: str, value, rule: str) -> InputError:
    return InputError(f"{field_} = {value!r}: {rule}", field_, value, rule)


# --- inputs --------------------------------------------------------------------------------


def _bounds(params: list[Parameter], bounds, design: Design, initial: np.ndarray):
    """(lower, upper) arrays in SI and whether the user gave any. Without bounds, positive
    parameters stay within 1e-3 to 1e3 times the design's values (a sanity box: points
    outside count as failed)."""
    lo = np.array(
        [1e-3 * v if p.positive else -math.inf for p, v in zip(params, initial, strict=True)]
    )
    hi = np.array(
        [1e3 * v if p.positive else math.inf for p, v in zip(params, initial, strict=True)]
    )
    if bounds is None:
        return lo, hi, False
    if not isinstance(bounds, Mapping):
        raise _fail("bounds", bounds, "must map parameter names to (lower, upper)")
    names = [p.name for p in params]
    kinds = {"Pa": "pressure", "m": "length"}
    for name, pair in bounds.items():
        if name not in names:
            raise _fail("bounds", name, f"is not a calibrated parameter ({', '.join(names)})")
        j = names.index(name)
        if not isinstance(pair, Sequence) or isinstance(pair, str) or len(pair) != 2:
            raise _fail(f"bounds[{name}]", pair, "must be a pair (lower, upper)")
        unit = params[j].unit
        vals = [
            to_si(v, kinds[unit], f"bounds[{name}]", InputError)
            if unit in kinds
            else number(v, f"bounds[{name}]", InputError)
            for v in pair
        ]
        if not vals[0] < vals[1]:
            raise _fail(f"bounds[{name}]", pair, "lower must be below upper")
        if params[j].positive and vals[0] <= 0:
            raise _fail(f"bounds[{name}]", pair, f"{params[j].kind} must stay > 0")
        if not vals[0] <= initial[j] <= vals[1]:
            raise _fail(f"bounds[{name}]", pair, f"must contain the design's value {initial[j]:g}")
        lo[j], hi[j] = vals
    return lo, hi, True


def _split(dataset: Dataset, split, test) -> np.ndarray:
    """Boolean test mask."""
    m = len(dataset)
    if split is None:
        if test is not None:
            raise _fail("test", test, "needs split='experiment' or split='mounting'")
        return np.zeros(m, dtype=bool)
    if isinstance(split, str):
        if split not in ("experiment", "mounting"):
            raise _fail("split", split, "must be 'experiment', 'mounting', a mask or None")
        if getattr(dataset, split) is None:
            raise _fail("split", split, f"the dataset has no {split} column")
        if test is None:
            if split == "mounting":
                raise _fail("test", None, "name the test mounting(s)")
            ids = dataset.experiments
            if len(ids) < 2:
                raise _fail("test", None, f"the dataset has {len(ids)} experiment: nothing to test")
            test = ids[-1]  # documented default: the last experiment is the test set
        dataset.split(split, test=test)  # checks the ids
        labels = getattr(dataset, split)
        ids = [test] if isinstance(test, (str, int, np.integer)) else list(test)
        return np.isin(labels, ids)
    mask = np.asarray(split)
    if mask.dtype != bool or mask.shape != (m,):
        raise _fail("split", f"array of shape {mask.shape}", f"a test mask must be bool ({m},)")
    if mask.all():
        raise _fail("split", "all rows", "leaves nothing to train on")
    return mask.copy()


def _groups(design: Design, dataset: Dataset) -> list[tuple[dict, np.ndarray]]:
    """(document changes for the mounting, row indices) per mounting label."""
    m = len(dataset)
    if dataset.mounting is None:
        return [({}, np.arange(m))]
    labels = list(dict.fromkeys(dataset.mounting.tolist()))
    if len(labels) == 1:  # one mounting: the design is mounted as the data were
        return [({}, np.arange(m))]
    out = []
    for label in labels:
        if label not in _ORIENTATIONS:
            raise _fail(
                "dataset.mounting",
                label,
                f"with several mountings each must be one of {', '.join(_ORIENTATIONS)}",
            )
        if "base_rotation" in design.document.get("mounting", {}):
            raise _fail(
                "design.mounting.base_rotation",
                "given",
                "mounting labels set the orientation; use mounting.orientation instead",
            )
        out.append(({"mounting.orientation": label}, np.flatnonzero(dataset.mounting == label)))
    return out


def _with_stiffness_map(design: Design, params: list[Parameter]) -> Design:
    """Sigma parameters need mapped sections: map the chambered elastic sections if none is."""
    if not any(p.kind in SIGMA_KINDS for p in params):
        return design
    from .per_sample import stiffness_mapped_design

    return stiffness_mapped_design(design)[0]


# --- the model on the dataset ----------------------------------------------------------------


class _Model:
    """Tip positions of the dataset's samples and their parameter derivatives at theta."""

    def __init__(self, design, dataset, params, groups, rows, options, threads):
        self.design, self.params, self.groups = design, params, groups
        self.rows = rows  # which rows take part (train)
        self.p = np.ascontiguousarray(dataset.pressures, dtype=float)
        self.opts = _options(options).as_kwargs()
        self.threads = threads
        self.x0 = np.full((len(dataset), 3), np.nan)
        self.sigma_index = {
            j: SIGMA_KINDS.index(p.kind) for j, p in enumerate(params) if p.kind in SIGMA_KINDS
        }
        self.evaluations = 0

    def designs(self, theta) -> list[Design]:
        changes = design_changes(self.params, theta, self.design)
        return [self.design.replace({**changes, **g}) for g, _ in self.groups]

    def sigma(self, theta, idx: np.ndarray) -> np.ndarray | None:
        """sigma of the rows ``idx``: the fitted constant one, the design's stiffness map
        (``[stiffness_map] file``), or None (no mapped sections)."""
        if not self.sigma_index:
            smap = self.design.stiffness_map
            return None if smap is None else np.ascontiguousarray(smap(self.p[idx]))
        s = np.ones(3)
        for j, k in self.sigma_index.items():
            s[k] = theta[j]
        return np.tile(s, (idx.size, 1))

    def __call__(self, theta, jacobian: bool, rows=None):
        """(tip (m, 3), d tip / d theta (m, 3, P) or None, converged (m,)) for ``rows``."""
        rows = self.rows if rows is None else rows
        m, n_par = len(self.p), len(self.params)
        tip = np.full((m, 3), np.nan)
        jac = np.full((m, 3, n_par), np.nan) if jacobian else None
        ok = np.zeros(m, dtype=bool)
        self.evaluations += 1
        try:
            designs = self.designs(theta)
        except DesignError:
            # A trial point outside what a design allows (e.g. a stiffness that is no longer
            # positive definite): every sample fails, so the optimiser steps back.
            return tip, jac, ok
        for d, (_, idx) in zip(designs, self.groups, strict=True):
            idx = idx[np.isin(idx, rows)]
            if idx.size == 0:
                continue
            tip_f = d.spec["tip"]["force"]
            tip_m = d.spec["tip"]["moment"]
            kw = dict(
                stiffness_scale=self.sigma(theta, idx),
                threads=self.threads,
                **self.opts,
            )
            if jacobian:
                out = d._rod.sensitivity_batch(
                    self.p[idx],
                    tip_f,
                    tip_m,
                    [p.core() for p in self.params],
                    x0=np.ascontiguousarray(self.x0[idx]),
                    **kw,
                )
                dj = out["d_tip_position"]
                for j, p in enumerate(self.params):
                    if p.kind == "area_scale":
                        # The core differentiates by a factor on the current areas, which
                        # are theta_j times the design's: d/d theta_j = (1/theta_j) d/dk.
                        dj[:, :, j] /= theta[j]
                jac[idx] = dj
            else:
                out = d._rod.solve_batch(self.p[idx], tip_f, tip_m, **kw)
            tip[idx] = out["tip_position"]
            ok[idx] = out["converged"]
            good = idx[out["converged"]]
            self.x0[good] = out["x"][out["converged"]]
        return tip, jac, ok


# --- the result --------------------------------------------------------------------------------


@dataclass(frozen=True)
class CalibrationResult:
    """What :func:`calibrate` found. Values and standard errors in SI (see ``units``)."""

    design: Design
    initial_design: Design
    parameters: tuple[Parameter, ...]
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
    cost_m2: float
    dataset: Dataset
    predicted: np.ndarray
    converged: np.ndarray
    labels: np.ndarray
    error_table: pd.DataFrame
    elapsed_s: float
    reference: np.ndarray = field(repr=False)
    #: One row per start (start and final values, cost in mm^2, success, evaluations)
    #: when ``restarts`` > 0, else None.
    starts: pd.DataFrame | None = field(default=None, repr=False)

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.parameters]

    @property
    def units(self) -> list[str]:
        return [p.unit for p in self.parameters]

    @property
    def residuals(self) -> np.ndarray:
        """Predicted minus measured tip position, (m, 3) m (NaN where a solve failed)."""
        return self.predicted - self.dataset.tip_position

    @property
    def stiffness_scale(self) -> np.ndarray | None:
        """The fitted constant sigma (3,), or None without sigma parameters."""
        idx = {p.kind: j for j, p in enumerate(self.parameters) if p.kind in SIGMA_KINDS}
        if not idx:
            return None
        return np.array([self.values[idx[k]] if k in idx else 1.0 for k in SIGMA_KINDS])

    @property
    def stiffness_map(self) -> StiffnessMap | None:
        """A constant :class:`~softrod.StiffnessMap` of the fitted sigma (or None), to pass
        as ``stiffness_map=`` with :attr:`design`."""
        from ..stiffness_map import StiffnessMap

        s = self.stiffness_scale
        return None if s is None else StiffnessMap.constant(s, self.design.n_channels)

    def _mountings(self) -> list:
        return [] if self.dataset.mounting is None else self.dataset.mounting.tolist()

    def parameter_table(self) -> pd.DataFrame:
        rel = np.abs(self.std_errors / np.where(self.values == 0, np.nan, self.values))
        return pd.DataFrame(
            {
                "parameter": self.names,
                "unit": self.units,
                "initial": self.initial,
                "value": self.values,
                "std_error": self.std_errors,
                "rel_std_error_pct": 100 * rel,
            }
        )

    def summary(self) -> str:
        lines = [
            f"Calibration of {self.initial_design.name} on {_dataset_name(self.dataset)} "
            f"({self.method}, {self.evaluations} model evaluations, {self.elapsed_s:.2f} s)",
            f"  {self.message}",
        ]
        for p, v0, v, s in zip(
            self.parameters, self.initial, self.values, self.std_errors, strict=True
        ):
            (v0, unit), (v, _), (s, _) = (display(x, p.unit) for x in (v0, v, s))
            unit = f" {unit}" if unit else ""
            rel = abs(s / v) if v != 0 and math.isfinite(s) else math.nan
            rel_text = f" ({100 * rel:.3g} %)" if math.isfinite(rel) else ""
            lines.append(f"  {p.name:<16} {v0:>12.6g} -> {v:>12.6g} +- {s:.3g}{unit}{rel_text}")
        cols = ["set", "n", "failed", "mean_error_mm", "median_error_mm", "max_error_mm"]
        lines.append(self.error_table[cols].to_string(index=False, float_format="%.3f"))
        lines += [f"  warning: {w}" for w in self.warnings]
        if not self.warnings:
            lines.append(f"  no warnings ({warning_thresholds()})")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def to_toml(self, path: PathLike) -> Path:
        """Write the calibrated design as a TOML design file (whole or not at all), with
        :meth:`Design.save`. Its name is the calibrated design's (``<name>_calibrated`` or
        the ``name`` given to :func:`calibrate`); ``[design.provenance]`` records the
        dataset, the fitted values with standard errors (SI, with their unit), the method,
        the softrod version and the date, and ``[design].assumptions`` says the same in a
        sentence."""
        if self.stiffness_scale is not None:
            raise _fail(
                "params",
                [p.name for p in self.parameters if p.kind in SIGMA_KINDS],
                "sigma factors are per-solve, not part of a design; use result.stiffness_map "
                "with result.design, or fit c_e and c_b instead",
            )
        return self.design.save(path)

    def to_frame(self, units: Units = None) -> pd.DataFrame:
        """The predictions, one row per sample, in the dataset schema (docs/datasets.md):
        the measured sample (``p0_kPa`` ..., ``tip_x_mm`` ..., and the dataset's other
        columns), then ``set`` (train or test), ``converged``, the calibrated model's tip
        ``model_tip_x_mm`` ... (empty where its solve failed) and ``error_mm`` (Euclidean
        distance measured - model). The metadata block names the calibrated and the initial
        design, the dataset, the fitted values with standard errors and the softrod
        version; ``load_dataset`` reads the table back."""
        from ..schema import Extra, schema_frame

        ds = self.dataset
        predicted = np.where(self.converged[:, None], self.predicted, np.nan)
        extras = [
            Extra("set", self.labels, "train or test"),
            Extra("converged", self.converged, "the calibrated model's solve converged"),
        ]
        extras += [
            Extra(f"model_tip_{a}", predicted[:, i], "calibrated model's tip", "length")
            for i, a in enumerate("xyz")
        ]
        error = np.linalg.norm(ds.tip_position - predicted, axis=1)
        extras.append(Extra("error", error, "|measured - model tip|", "length"))
        meta = {
            "generator": "softrod.calibrate",
            "synthetic": ds.synthetic,  # the tip columns are the dataset's
            **(self.design.provenance or {}),
            "design": self.design.name,
        }
        return schema_frame(
            pressures=ds.pressures,
            tip_position=ds.tip_position,
            tip_rotation=ds.tip_rotation,
            base_force=ds.base_force,
            base_moment=ds.base_moment,
            time=ds.time,
            experiment=ds.experiment,
            mounting=ds.mounting,
            extras=extras,
            units=units,
            metadata=meta,
        )

    def write_report(self, path: PathLike) -> Path:
        """An HTML report: parameters, correlations, error tables and figures."""
        from .report import write_report

        d = self.design
        return write_report(
            path,
            title=f"softrod calibration: {self.initial_design.name}",
            summary={
                "design": self.initial_design.name,
                "dataset": _dataset_name(self.dataset),
                "synthetic data": self.dataset.synthetic,
                "samples (train / test)": f"{(self.labels == 'train').sum()} / "
                f"{(self.labels == 'test').sum()}",
                "method": self.method,
                "model evaluations": self.evaluations,
                "final cost (sum of squared tip errors)": f"{self.cost_m2 * 1e6:.4g} mm^2",
                "status": self.message,
                "time": f"{self.elapsed_s:.2f} s",
            },
            parameter_table=_display_table(self.parameter_table()),
            error_table=self.error_table,
            measured=self.dataset.tip_position,
            predicted=self.predicted,
            labels=self.labels,
            pressures=self.dataset.pressures,
            warnings=self.warnings,
            correlation=self.correlation,
            param_names=self.names,
            length=d.length,
            axis=_axis(d) if len(set(self._mountings())) <= 1 else None,
            base_position=_base_position(d) if len(set(self._mountings())) <= 1 else None,
            warning_rules=warning_thresholds(),
        )


def _display_table(table: pd.DataFrame) -> pd.DataFrame:
    """The parameter table in display units (offsets in mm, E in kPa; docs: one unit per
    quantity kind wherever people read it)."""
    out = table.copy()
    factors, units = [], []
    for unit in table["unit"]:
        shown = DISPLAY_UNITS.get(unit, (unit, 1.0))
        units.append(shown[0] or "1")
        factors.append(shown[1])
    for col in ("initial", "value", "std_error"):
        out[col] = table[col].to_numpy() * np.asarray(factors)
    out["unit"] = units
    return out


def _axis(design: Design) -> np.ndarray:
    """The undeformed axis d3 at the base (world)."""
    return np.asarray(design.spec["mounting"]["base_rotation"])[:, 2]


def _base_position(design: Design) -> np.ndarray:
    return np.asarray(design.spec["mounting"]["base_position"])


def _plain(x):
    """Python scalars for TOML (numpy floats and ints are not TOML types)."""
    if isinstance(x, Mapping):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    return x


def _dataset_name(dataset: Dataset) -> str:
    name = dataset.source.name if dataset.source is not None else "in-memory dataset"
    return f"{name} (SYNTHETIC)" if dataset.synthetic else name


def _diagnostics(params, values, jac, ssr, n_res):
    """Covariance, standard errors, correlation and warnings from the Jacobian (m per SI
    unit) at the optimum."""
    n_par = len(params)
    found: list[str] = []
    dof = n_res - n_par
    if dof <= 0:
        found.append(f"{n_res} residuals for {n_par} parameters: no standard errors")
        nan = np.full((n_par, n_par), np.nan)
        return nan, np.full(n_par, np.nan), nan, found
    # Column scaling: relative changes (1 mm for offsets, which may be 0).
    scale = np.array([abs(v) if p.positive else 1e-3 for p, v in zip(params, values, strict=True)])
    js = jac * scale
    sv = np.linalg.svd(js, compute_uv=False)
    cond = sv[0] / sv[-1] if sv[-1] > 0 else math.inf
    s2 = ssr / dof
    if cond > UNIDENTIFIABLE_CONDITION:
        _, _, vt = np.linalg.svd(js)
        for k in np.flatnonzero(sv < sv[0] / UNIDENTIFIABLE_CONDITION):
            null = vt[k]
            involved = [
                f"{params[j].name} ({null[j]:+.2f})"
                for j in np.argsort(-np.abs(null))
                if abs(null[j]) > 0.1
            ]
            found.append(
                f"not identifiable: the tip positions barely change along the combination "
                f"{', '.join(involved)} of relative parameter changes (singular value ratio "
                f"{sv[k] / sv[0]:.1e} < 1/{UNIDENTIFIABLE_CONDITION:.0e}); fix some of these "
                "parameters"
            )
        cov = s2 * np.linalg.pinv(js.T @ js) * np.outer(scale, scale)
        std = np.sqrt(np.abs(np.diag(cov)))
        std[:] = np.inf
        corr = np.full((n_par, n_par), np.nan)
        return cov, std, corr, found
    inv = np.linalg.inv(js.T @ js)
    cov = s2 * inv * np.outer(scale, scale)
    std = np.sqrt(np.diag(cov))
    # From (J^T J)^-1 alone, so that it is defined for a perfect fit (s = 0) too.
    d = np.sqrt(np.diag(inv))
    corr = inv / np.outer(d, d)
    for a in range(n_par):
        for b in range(a + 1, n_par):
            if abs(corr[a, b]) > STRONG_CORRELATION:
                found.append(
                    f"{params[a].name} and {params[b].name} are strongly correlated "
                    f"(r = {corr[a, b]:+.3f}, |r| > {STRONG_CORRELATION:g}): the data "
                    "determine mainly a combination"
                )
    # Offsets may be 0, so a relative error means nothing for them: correlations judge them.
    for p, v, s in zip(params, values, std, strict=True):
        if p.positive and s > POOR_RELATIVE_ERROR * abs(v):
            (vd, unit), (sd, _) = display(v, p.unit), display(s, p.unit)
            unit = f" {unit}" if unit else ""
            found.append(
                f"{p.name} is poorly determined: standard error {sd:.3g}{unit} on {vd:.3g}{unit} "
                f"({100 * s / abs(v):.3g} % > {100 * POOR_RELATIVE_ERROR:g} %)"
            )
    return cov, std, corr, found


# --- one fit from one start, and restarts -----------------------------------------------------

#: Restarts of a positive parameter without bounds start within this factor of the design's
#: value (log-uniformly in [v / RESTART_SPREAD, v * RESTART_SPREAD]).
RESTART_SPREAD = 3.0


@dataclass(frozen=True)
class _FitSetup:
    """Everything one fit needs except the design (which travels as TOML text)."""

    dataset: Dataset
    params: tuple[Parameter, ...]
    groups: list
    train: np.ndarray
    options: SolverOptions | None
    lo: np.ndarray
    hi: np.ndarray
    user_bounds: bool
    method: str
    max_evaluations: int


def _optimise(design: Design, setup: _FitSetup, theta_start, threads: int, progress) -> dict:
    """One fit of ``setup`` from ``theta_start``: the optimiser's best point u (log theta for
    positive parameters), its cost 0.5 sum r^2 (mm^2), success, message, method and model
    evaluations."""
    from scipy.optimize import least_squares, minimize

    params, train, lo, hi = list(setup.params), setup.train, setup.lo, setup.hi
    dataset = setup.dataset
    model = _Model(design, dataset, params, setup.groups, train, setup.options, threads)
    measured = dataset.tip_position
    positive = np.array([p.positive for p in params])

    # Optimisation variable u: log(theta) for positive parameters, theta otherwise.
    def theta_of(u):
        return np.where(positive, np.exp(np.where(positive, u, 0.0)), u)

    theta_start = np.asarray(theta_start, dtype=float)
    u0 = np.where(positive, np.log(np.where(positive, theta_start, 1.0)), theta_start)

    def residual(tip, ok):
        r = (tip[train] - measured[train]) / _MM
        r[~ok[train]] = _FAILED_RESIDUAL_MM
        return r.ravel()

    cache: dict = {}

    def evaluate(u, jacobian):
        key = u.tobytes()
        if key in cache and (cache[key][1] is not None or not jacobian):
            return cache[key]
        theta = theta_of(u)
        if np.all((theta >= lo) & (theta <= hi)):
            tip, jac, ok = model(theta, jacobian)
        else:
            # Outside the sanity box (default 1e-3 to 1e3 times the design's values): a
            # failed point, so that an unidentifiable direction cannot run off to 1e150.
            tip, ok = np.full((len(dataset), 3), np.nan), np.zeros(len(dataset), dtype=bool)
            jac = np.zeros((len(dataset), 3, len(params))) if jacobian else None
        r = residual(tip, ok)
        cache.clear()
        cache[key] = (r, jac, ok)
        if progress is not None:
            progress(model.evaluations, float(np.sqrt(np.mean(r.reshape(-1, 3) ** 2) * 3)))
        return cache[key]

    def jac_u(u):
        r, jac, ok = evaluate(u, True)
        j = jac[train] / _MM
        j[~ok[train]] = 0.0
        # d/du = theta d/dtheta for the log-transformed parameters
        return (j * np.where(positive, theta_of(u), 1.0)).reshape(-1, len(params))

    ulo = np.where(positive, np.log(np.where(positive, lo, 1.0)), lo)
    uhi = np.where(positive, np.log(np.where(positive, hi, 1.0)), hi)
    if setup.method == "lm":
        use_bounds = setup.user_bounds
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
            max_nfev=setup.max_evaluations,
        )
        method_used = "lm (MINPACK)" if not use_bounds else "trf (bounded, exact Jacobian)"
        cost = float(sol.cost)
    else:
        sol = minimize(
            lambda u: 0.5 * float(np.sum(evaluate(u, False)[0] ** 2)),
            u0,
            method="Nelder-Mead",
            bounds=list(zip(ulo, uhi, strict=True)) if setup.user_bounds else None,
            options={"maxfev": setup.max_evaluations, "xatol": 1e-8, "fatol": 1e-10},
        )
        method_used = "nelder-mead"
        cost = float(sol.fun)
    return {
        "start": theta_start,
        "u": np.asarray(sol.x, dtype=float),
        "values": theta_of(np.asarray(sol.x, dtype=float)),
        "cost": cost,
        "success": bool(sol.success),
        "message": str(sol.message),
        "method": method_used,
        "evaluations": model.evaluations,
    }


def _start_points(params, theta0, lo, hi, bounded, restarts, seed) -> np.ndarray:
    """The design's values, then ``restarts`` points drawn with ``seed``: uniformly within a
    parameter's bounds (log-uniformly for positive ones), or, for a positive parameter
    without bounds, log-uniformly within RESTART_SPREAD of its value."""
    if isinstance(restarts, bool) or not isinstance(restarts, (int, np.integer)) or restarts < 0:
        raise _fail("restarts", restarts, "must be an integer >= 0 (extra starting points)")
    if restarts == 0:
        return theta0[None, :]
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise _fail("seed", seed, "must be an integer >= 0 (it makes the restarts repeatable)")
    for p, b in zip(params, bounded, strict=True):
        if not (b or p.positive):
            raise _fail(
                "restarts",
                restarts,
                f"{p.name} can be negative: give its bounds so that restarts know where to "
                "start (bounds={'" + p.name + "': (lower, upper)})",
            )
    positive = np.array([p.positive for p in params])
    a = np.where(bounded, lo, theta0 / RESTART_SPREAD)
    b = np.where(bounded, hi, theta0 * RESTART_SPREAD)
    rng = np.random.default_rng(seed)
    x = rng.random((int(restarts), len(params)))
    log_a = np.log(np.where(positive, a, 1.0))
    log_b = np.log(np.where(positive, b, 1.0))
    drawn = np.where(positive, np.exp(log_a + x * (log_b - log_a)), a + x * (b - a))
    return np.vstack([theta0[None, :], drawn])


def _run_starts(design, setup, starts, threads, progress, executor) -> list[dict]:
    """One fit per start, in process or on a Dask cluster; in the order of ``starts``."""
    from ..cluster import check_executor

    if check_executor(executor) is None:
        return [_optimise(design, setup, start, threads, progress) for start in starts]
    from ..cluster import design_text, run_chunks, task_slots

    _, per_host = task_slots(executor)
    text = design_text(design)
    report = None
    if progress is not None:

        def report(done, total):
            progress(done, float("nan"))

    return run_chunks(
        executor,
        _fit_start,
        [(text, setup, start, threads, per_host) for start in starts],
        progress=report,
        name="softrod-calibrate",
    )


def _fit_start(text, setup, start, threads, per_host) -> dict:
    """One restart on a worker: the design rebuilt from its TOML text."""
    from ..cluster import design_from_text, worker_threads

    return _optimise(
        design_from_text(text), setup, start, worker_threads(per_host, threads), None
    )


def _finite_or_inf(x: float) -> float:
    return x if math.isfinite(x) else math.inf


def _starts_table(params, fits, best) -> pd.DataFrame:
    rows = []
    for k, f in enumerate(fits):
        row = {"start": k, "best": k == best}
        for p, v0, v in zip(params, f["start"], f["values"], strict=True):
            row[f"{p.name} start"] = v0
            row[f"{p.name}"] = v
        row.update(
            cost_mm2=f["cost"], success=f["success"], evaluations=f["evaluations"]
        )
        rows.append(row)
    return pd.DataFrame(rows)


# --- the entry point ---------------------------------------------------------------------------


@one_blas_thread
def calibrate(
    design: DesignLike,
    dataset: Dataset | PathLike | pd.DataFrame,
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
    dt: Quantity = 5e-3,
    model: str = "cosserat",
    experiments: Mapping | None = None,
    restarts: int = 0,
    seed: int = 0,
    executor: Any = None,
    name: str | None = None,
) -> CalibrationResult | DynamicCalibrationResult | PccFit:
    """Fit ``params`` of ``design`` to the tip positions of ``dataset``.

    design: a design (path, bundled name, preset or :class:`~softrod.Design`).
    dataset: a :class:`~softrod.Dataset` or a path to one. Rows with a ``mounting`` of
    "hanging", "upright" or "horizontal" are solved with that orientation (paper 002 fits
    vertical and horizontal experiments together). The design's tip loads apply to all rows.
    params: names such as ``["c_b", "c_e", "alpha", "offset_1", "offset_2", "c_p"]`` (see
    :mod:`softrod.calibration.params`).
    bounds: optional ``{name: (lower, upper)}`` in SI or with units ("40 kPa").
    method: "lm" (exact Jacobian; the default) or "nelder-mead" (paper 002's simplex, no
    derivatives).
    dynamic: fit tip *trajectories* instead of equilibria: ``dataset`` is a time series
    (``time`` column, one experiment per run), ``params`` may include ``"damping_time"``
    (tau), and each evaluation simulates every experiment with time step ``dt``
    (paper 000 Sec. III-D; see :func:`softrod.calibration.calibrate_dynamics`, which this
    calls and whose result it returns). Dynamic fits use Nelder-Mead.
    restarts: extra fits from ``restarts`` starting points drawn with ``seed`` (within each
    parameter's bounds, or within a factor RESTART_SPREAD = 3 of a positive parameter's
    value when it has none); the fit with the lowest cost wins (ties: the earliest) and
    ``result.starts`` lists them all. executor: a ``distributed.Client``: the starts run on
    its cluster, one task each (docs/cluster.md).
    split: None (fit on all rows), "experiment" or "mounting" with ``test`` ids (default
    for "experiment": the last experiment), or a boolean test mask.
    progress: None (a bar in interactive sessions), True, False, or a callable called as
    ``progress(evaluations, rms_error_mm)`` after every evaluation (:mod:`softrod.progress`).
    model: "cosserat" (default: the rod, everything above) or "pcc": paper 003's
    identification of the PCC model (Sec. V, docs/pcc.md). ``params`` is then one or a list
    of "k_L", "k_theta", "b_L", "b_theta", each identified from its own experiment:
    equal-pressure elongation (static rows: Hookean fit with an offset that takes the
    weight), one-side bending (static rows: k = M/theta, gravity moment taken out by the
    model), an elongation step and a free bending decay (time series). A list is fitted in
    that order, each fit using the values before it. ``experiments={"k_L": id, ...}``
    names the experiment rows of each parameter (default: the experiment called
    "elongation", "bending", "step" or "free_decay"), and ``options`` is a dict of the
    further settings of :func:`softrod.pcc.identify_pcc` (``degree``, ``gravity``, ``k_L``,
    ``k_theta``, ``inertia``). Returns a :class:`softrod.pcc.PccFit` (``fit.to_toml(path)``
    writes the design with the values). bounds, method, split, test, progress, threads,
    max_evaluations and dynamic do not apply.

    name: the calibrated design's name (default ``<design name>_calibrated``); its
    ``[design.provenance]`` records the dataset, the values with standard errors, the
    method, the softrod version and the date (``result.design.provenance``).

    Returns a :class:`CalibrationResult`; emits a :class:`CalibrationWarning` for each
    identifiability problem (also listed in ``result.warnings``): a relative standard error
    above :data:`POOR_RELATIVE_ERROR` (20 %), a correlation with ``|r|`` above
    :data:`STRONG_CORRELATION` (0.9), a Jacobian whose singular values span more than
    :data:`UNIDENTIFIABLE_CONDITION`, or an optimiser that did not converge.

    The fit runs BLAS on one thread (:mod:`softrod._threads`): the same inputs give the same
    result whatever the BLAS settings; ``threads`` sets the Rust core's workers.
    """

    V.choice(model, ("cosserat", "pcc"), "model")
    if model == "pcc":
        from ..pcc.experiments import identify_pcc

        unused = {
            name: value
            for name, value, default in (
                ("bounds", bounds, None),
                ("name", name, None),
                ("method", method, None),
                ("split", split, None),
                ("test", test, None),
                ("progress", progress, None),
                ("threads", threads, 0),
                ("max_evaluations", max_evaluations, 200),
                ("dynamic", dynamic, False),
                ("restarts", restarts, 0),
                ("executor", executor, None),
            )
            if (value is not None if default is None else value != default)
        }
        if unused:
            name, value = next(iter(unused.items()))
            raise _fail(
                name,
                value,
                "does not apply to model='pcc' (paper 003's closed-form fits, one per experiment)",
            )
        settings = ("degree", "gravity", "k_L", "k_theta", "inertia")
        if options is not None and (
            not isinstance(options, Mapping) or any(k not in settings for k in options)
        ):
            raise _fail(
                "options",
                options,
                f"with model='pcc' a dict of softrod.pcc.identify_pcc settings "
                f"({', '.join(settings)})",
            )
        return identify_pcc(design, dataset, params, experiments=experiments, **(options or {}))
    if experiments is not None:
        raise _fail("experiments", experiments, "applies to model='pcc' only")

    if dynamic:
        from .dynamic import calibrate_dynamics

        if method not in (None, "nelder-mead"):
            raise _fail(
                "method",
                method,
                "dynamic fits use 'nelder-mead' (trajectory sensitivities are not exact yet)",
            )
        if bounds is not None or split is not None or test is not None:
            raise _fail(
                "dynamic",
                True,
                "bounds, split and test are not available for dynamic fits (yet)",
            )
        if restarts != 0 or executor is not None:
            raise _fail(
                "dynamic", True, "restarts and executor are not available for dynamic fits (yet)"
            )
        if name is not None:
            raise _fail("name", name, "applies to static fits (dynamic=False)")
        return calibrate_dynamics(
            design, dataset, params, dt=dt, max_evaluations=max_evaluations, progress=progress
        )
    method = "lm" if method is None else method
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
    V.choice(method, ("lm", "nelder-mead"), "method")
    threads = V.threads(threads)
    V.integer(max_evaluations, "max_evaluations", minimum=1, maximum=V.MAX_ITERATIONS)
    params = parse_parameters(params, design0)
    sigma_names = [p.name for p in params if p.kind in SIGMA_KINDS]
    if sigma_names and design0.stiffness_map is not None:
        raise _fail(
            "params",
            sigma_names,
            f"design {design0.name!r} has a stiffness map ([stiffness_map] file): the constant "
            "sigma factors would replace it; fit them on the design without the map "
            "(design.with_stiffness_map(None)) or fit other parameters",
        )
    design0 = _with_stiffness_map(design0, params)
    for p in params:  # the core checks each parameter against the design
        design0._rod.sensitivity_batch(
            np.zeros((0, design0.n_channels)), [0.0] * 3, [0.0] * 3, [p.core()]
        )
    theta0 = np.array([p.value(design0) for p in params])
    lo, hi, user_bounds = _bounds(params, bounds, design0, theta0)
    test_mask = _split(dataset, split, test)
    train = np.flatnonzero(~test_mask)
    groups = _groups(design0, dataset)
    measured = dataset.tip_position
    logger.info(
        "calibrate %s: %s on %d training samples (%d test), method %s",
        design0.name,
        ", ".join(p.name for p in params),
        train.size,
        int(test_mask.sum()),
        method,
    )
    setup = _FitSetup(
        dataset=dataset,
        params=tuple(params),
        groups=groups,
        train=train,
        options=options,
        lo=lo,
        hi=hi,
        user_bounds=user_bounds,
        method=method,
        max_evaluations=max_evaluations,
    )
    bounded = np.array([p.name in (bounds or {}) for p in params], dtype=bool)
    starts = _start_points(params, theta0, lo, hi, bounded, restarts, seed)
    with reporter(progress, "calibrate", None, _evaluations) as report:
        fits = _run_starts(design0, setup, starts, threads, report, executor)
    best = min(range(len(fits)), key=lambda k: (_finite_or_inf(fits[k]["cost"]), k))
    u_best = fits[best]["u"]
    success, message = fits[best]["success"], fits[best]["message"]
    method_used = fits[best]["method"]
    model = _Model(design0, dataset, list(params), groups, train, options, threads)
    model.evaluations = sum(f["evaluations"] for f in fits)
    positive = np.array([p.positive for p in params])

    def theta_of(u):
        return np.where(positive, np.exp(np.where(positive, u, 0.0)), u)


    logger.info(
        "calibrate %s: %s after %d model evaluations (%s)",
        design0.name,
        "converged" if success else "stopped",
        model.evaluations,
        message,
    )
    values = theta_of(u_best)
    tip_train, jac, ok = model(values, True)
    if not ok[train].all():
        bad = train[~ok[train]]
        raise ConvergenceError(
            f"calibrate: the model did not converge for {bad.size} training samples at the "
            f"fitted parameters ({dataset.rows_text(bad)}); check the data and the bounds"
        )
    r = (tip_train[train] - measured[train]).ravel()
    ssr = float(r @ r)
    j = jac[train].reshape(-1, len(params))
    cov, std, corr, found = _diagnostics(params, values, j, ssr, r.size)
    if not success:
        found.insert(0, f"the optimiser stopped without converging: {message}")

    calibrated = design0.replace(design_changes(params, values, design0))
    calibrated = _record(
        calibrated, design0, name, params, values, std, method_used, dataset, train.size
    )
    # Predictions on every row (train and test) with the calibrated design.
    all_rows = np.arange(len(dataset))
    final = _Model(calibrated, dataset, [], groups, all_rows, options, threads)
    sigma_params = [p for p in params if p.kind in SIGMA_KINDS]
    if sigma_params:
        final = _Model(calibrated, dataset, list(sigma_params), groups, all_rows, options, threads)
        predicted, _, converged = final(
            np.array([values[params.index(p)] for p in sigma_params]), False
        )
    else:
        predicted, _, converged = final(np.zeros(0), False)
    reference = _reference(calibrated, groups, len(dataset), options)
    labels = np.where(test_mask, "test", "train")
    table = tip_error_table(
        measured,
        np.where(converged[:, None], predicted, np.nan),
        length=calibrated.length,
        reference=reference,
        # Radial and height errors need one undeformed axis: one mounting only.
        base_position=None if len(groups) > 1 else _base_position(calibrated),
        axis=None if len(groups) > 1 else _axis(calibrated),
        labels=labels if test_mask.any() else None,
    )
    for w in found:
        warnings.warn(w, CalibrationWarning, stacklevel=3)  # past the BLAS-thread wrapper
    return CalibrationResult(
        design=calibrated,
        initial_design=design0,
        parameters=tuple(params),
        initial=theta0,
        values=values,
        std_errors=std,
        covariance=cov,
        correlation=corr,
        warnings=tuple(found),
        method=method_used,
        success=success,
        message=message,
        evaluations=model.evaluations,
        cost_m2=ssr,
        dataset=dataset,
        predicted=predicted,
        converged=converged,
        labels=labels,
        error_table=table,
        elapsed_s=time.perf_counter() - start,
        reference=reference,
        starts=_starts_table(params, fits, best) if len(fits) > 1 else None,
    )


def _reference(design: Design, groups, m: int, options) -> np.ndarray:
    """The model's unpressurised tip position of every row's mounting (for % deflection)."""
    ref = np.full((m, 3), np.nan)
    zero = np.zeros((1, design.n_channels))
    smap = design.stiffness_map
    sigma = None if smap is None else np.ascontiguousarray(smap(zero))
    for changes, idx in groups:
        d = design.replace(changes) if changes else design
        out = d._rod.solve_batch(
            zero,
            d.spec["tip"]["force"],
            d.spec["tip"]["moment"],
            stiffness_scale=sigma,
            **_options(options).as_kwargs(),
        )
        ref[idx] = out["tip_position"][0]
    return ref


def _record(design, initial, name, params, values, std, method, dataset, n_train) -> Design:
    """The calibrated design under its new name, with ``[design.provenance]`` (what was
    fitted to what, by which softrod, when) and a sentence in ``[design].assumptions``."""
    import datetime

    from .. import __version__

    if name is None:
        name = f"{initial.name}_calibrated"
    if not isinstance(name, str) or not name.strip():
        raise _fail("name", name, "must be a non-empty string (the calibrated design's name)")
    fitted = [
        (p, v, s) for p, v, s in zip(params, values, std, strict=True) if p.kind not in SIGMA_KINDS
    ]
    source = dataset.source
    provenance = {
        "tool": "softrod.calibrate",
        "softrod_version": __version__,
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "initial_design": initial.name,
        "dataset": "in-memory dataset" if source is None else source.name,
        "synthetic_data": dataset.synthetic,
        "training_samples": int(n_train),
        "method": method,
        "parameters": [
            {
                "name": p.name,
                "value": float(v),
                "std_error": float(s) if math.isfinite(s) else "not determined",
                "unit": p.unit,
            }
            for p, v, s in fitted
        ],
    }
    changes: dict = {"design.name": name, "design.provenance": provenance}
    if fitted:
        shown = ", ".join(f"{p.name} = {_shown(v, s, p.unit)}" for p, v, s in fitted)
        line = (
            f"Calibrated with softrod.calibrate ({method}) on {_dataset_name(dataset)}, "
            f"{n_train} training samples: {shown} (standard errors from the Jacobian)."
        )
        changes["design.assumptions"] = list(design.document["design"].get("assumptions", []))
        changes["design.assumptions"].append(line)
    return design.replace(changes)


def _shown(value: float, std: float, unit: str) -> str:
    """'0.500126 +- 0.0078 mm': a value and its standard error in the display unit."""
    from ..schema import display

    v, shown_unit = display(value, unit)
    s, _ = display(std, unit)
    return f"{v:.6g} +- {s:.2g}" + (f" {shown_unit}" if shown_unit else "")


def result_json(result: CalibrationResult) -> str:
    """The parameter table and error table as standard JSON (non-finite numbers as null),
    for scripts and the CLI."""

    def finite(x):
        if isinstance(x, dict):
            return {k: finite(v) for k, v in x.items()}
        if isinstance(x, list):
            return [finite(v) for v in x]
        if isinstance(x, (float, np.floating)):
            return float(x) if math.isfinite(x) else None
        if isinstance(x, np.generic):
            return x.item()
        return x

    return json.dumps(
        finite(
            {
                "parameters": result.parameter_table().to_dict(orient="records"),
                "errors": result.error_table.to_dict(orient="records"),
                "warnings": list(result.warnings),
            }
        ),
        indent=2,
        allow_nan=False,
    )
