"""Per-sample stiffness identification (paper 001, Sec. III-A/B, eqs. 13-22).

For every measured static sample (pressures p, tip position r_* and, optionally, tip
rotation R_*) find the three stiffness factors sigma = (sigma_ext, sigma_bend_x,
sigma_bend_y) that scale EA, EI_1 and EI_2 of the stiffness-mapped sections (eq. 13; see
docs/stiffness-map.md) so that the model's tip matches the sample. The result is the
pressure -> stiffness table that :mod:`softrod.calibration.hybrid` learns (eqs. 23-25).

Cost (eqs. 14-20). softrod solves base to tip and enforces the tip force and moment exactly,
so the force and moment springs U_tc,2 and U_rc,2 of eqs. 18-19 vanish. What remains is the
position spring U_tc,1 = (c_t/2)|e_r|^2, e_r = r_* - r_N (eq. 14), and, when the dataset
has tip rotations, the rotation spring U_rc,1 = (c_r/2)|e_R|^2, e_R = Phi(log(R_N^T R_*))
(eq. 15), with c_t = n_high / r_high and c_r = m_high / R_high (eq. 20).

Deviation from the paper: eq. 21 minimises the sum of the *squared* energies. Here the sum
of the energies, U_tc,1 + U_rc,1, is minimised as a least-squares problem with the residual
(sqrt(c_t/2) e_r, sqrt(c_r/2) e_R). Its Gauss-Newton Hessian stays regular at a zero
residual (that of the squared energies vanishes there, so Newton-type steps stall), and
where the model can match the sample both costs have the same minimisers (zero).

Solver: Levenberg-Marquardt in log sigma (the factors stay positive; d/dlog sigma =
sigma d/dsigma), vectorised over the samples: every iteration is one parallel call of the
core's ``sensitivity_batch`` for all samples still iterating (exact tip-pose derivatives by
implicit differentiation, each solve warm-started from the sample's previous one), then all
3x3 damped normal equations are solved at once with numpy. Each sample has its own damping,
acceptance and stopping. sigma is kept in ``bounds``.

Identifiability (paper 001 Sec. V-A: the identification fails near the principal axes, where
a bending factor hardly moves the tip): the sensitivity of factor k is
1 / sqrt(((J^T J)^-1)_kk), with J the Jacobian of the residual, expressed as tip
displacement (m), with respect to log sigma. It is how far (m) the tip moves when log
sigma_k changes by 1 and the other two factors adjust to compensate as well as they can;
a measurement noise of s (m, per axis) gives log sigma_k a standard error of s /
sensitivity. A factor whose sensitivity is below ``min_sensitivity`` is not identifiable:
it is NaN in the result, never a noisy number.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from .. import _validate as V
from .._threads import one_blas_thread
from ..catalog import load_design
from ..constraints import require_free_tip
from ..datasets import Dataset
from ..design import Design
from ..errors import InputError, design_error
from ..progress import check_progress, reporter
from ..statics import SolverOptions
from ..stiffness_map import SIGMA_NAMES
from ..units import to_si

if TYPE_CHECKING:
    from .._types import ArrayLike, DesignLike, PathLike, Quantity, Units

__all__ = [
    "DEFAULT_BOUNDS",
    "MIN_SENSITIVITY_FRACTION",
    "STATUS",
    "StiffnessIdentification",
    "identify_stiffness",
    "stiffness_mapped_design",
]

# The core's names of the three factors (the solve's stiffness scaling, no sections).
_CORE_PARAMS = [("sigma_ext", []), ("sigma_bend_1", []), ("sigma_bend_2", [])]

# sigma is kept in this range (factors on the literature stiffness). Paper 001's bending
# factors lie within about 0.4-1.4 (Sec. V-A); a factor that runs to 1/20 or 20x is not a
# stiffness but a direction the data do not constrain, so it is reported (at_bound) and not
# identified.
DEFAULT_BOUNDS = (0.05, 20.0)

# Default min_sensitivity, as a fraction of the design's length: a factor counts as
# identifiable when changing it by a factor of e (one unit of log sigma) moves the tip by at
# least 1 % of L even after the other factors have compensated (1.3 mm on the 130 mm
# actuator of paper 001). With a tracking noise of 0.1 mm that bounds the standard error of
# log sigma by about 0.08; for noisier data raise min_sensitivity (noise / the relative error
# you accept).
MIN_SENSITIVITY_FRACTION = 0.01

# Virtual springs (eq. 20): "high" deviations that store the same energy, n_high r_high / 2
# = m_high R_high / 2 = 2.5 mJ. Only the ratio c_r / c_t matters here: 0.1 rad (5.7 deg) of
# tip rotation error weighs as much as 5 mm of tip position error.
N_HIGH = 1.0  # N
R_HIGH = 5e-3  # m
M_HIGH = 0.05  # N m
ROT_HIGH = 0.1  # rad
# The springs c_t, c_r a user may set: squared, times residuals up to metres, they must stay
# far inside float range (the defaults are 200 N/m and 0.5 N m/rad).
SPRING_RANGE = (1e-20, 1e20)

# Stopping (per sample): a step (accepted or not) below XTOL in every log sigma (relative
# change of sigma), a tip residual below RESIDUAL_TOL (m; the shooting solve is exact to
# ~1e-10 L), or a residual orthogonal to every acting column of J within GTOL (cosine; a
# minimum with a residual, e.g. noise that the acting factors cannot absorb).
XTOL = 1e-8
RESIDUAL_TOL = 1e-12
GTOL = 1e-8
_NULL_COLUMN = 1e-8  # a Jacobian column this small relative to the largest is zero
_TAU = 1e-3  # initial damping relative to the largest diagonal entry of J^T J
_MAX_NU = 2.0**20  # consecutive rejections double nu; past this no step can reduce the cost

STATUS = {
    "converged": "a stopping tolerance was met",
    "stalled": "no step reduces the cost any further (at the precision of the solves)",
    "max_iter": "max_iter iterations without meeting a tolerance: not identified",
    "solve_failed": "the model does not converge at the initial sigma: not identified",
}
_CONVERGED, _STALLED, _MAX_ITER, _FAILED, _RUNNING = range(5)
_STATUS_NAMES = np.array(["converged", "stalled", "max_iter", "solve_failed", "running"])


# --------------------------------------------------------------------------- design


def stiffness_mapped_design(design, sections: Sequence[str] | None = None) -> tuple[Design, tuple]:
    """The design with ``[sections.law] stiffness_map = true`` on the sections sigma scales,
    and their names.

    sections: names of the sections to scale. Default: the design's mapped sections if it has
    any, else every elastic (not rigid) section with chambers, the chambered body that paper
    001 scales. Named sections must exist and be elastic; sections not named are unmapped.
    Raises :class:`~softrod.errors.InputError` naming the field, the value and the rule.
    """
    design = load_design(design)
    require_free_tip(design, "identify_stiffness")
    secs = design.spec["sections"]
    names = [s["name"] for s in secs]
    if sections is None:
        chosen = [s["name"] for s in secs if (s.get("law") or {}).get("stiffness_map", False)]
        if not chosen:
            chosen = [s["name"] for s in secs if s["chambers"] and not s["rigid"]]
        if not chosen:
            raise design_error(
                "sections",
                None,
                f"design {design.name!r} has no elastic section with chambers (sections: "
                f"{', '.join(names)}); name the sections whose stiffness sigma scales with "
                "sections=[...]",
                InputError,
            )
    else:
        if isinstance(sections, str):
            sections = [sections]
        try:
            chosen = list(sections)
        except TypeError:
            raise design_error(
                "sections", sections, "must be a list of section names", InputError
            ) from None
        if not chosen:
            raise design_error(
                "sections",
                chosen,
                "name at least one section (or None for the default)",
                InputError,
            )
        for k, name in enumerate(chosen):
            if name not in names:
                raise design_error(
                    f"sections[{k}]",
                    name,
                    f"no such section in design {design.name!r} (sections: {', '.join(names)})",
                    InputError,
                )
            if secs[names.index(name)]["rigid"]:
                raise design_error(
                    f"sections[{k}]",
                    name,
                    "is a rigid section: it has no stiffness to scale",
                    InputError,
                )
        chosen = list(dict.fromkeys(chosen))
    changes = {}
    for i, sec in enumerate(design.document["sections"]):
        law = dict(sec.get("law") or {})
        want = names[i] in chosen
        if bool(law.get("stiffness_map", False)) != want:
            law["stiffness_map"] = want
            changes[f"sections[{i}].law"] = law
    mapped = design.replace(changes) if changes else design
    return mapped, tuple(n for n in names if n in chosen)


# --------------------------------------------------------------------------- rotations


def _vee(a: np.ndarray) -> np.ndarray:
    """Axial vector of the skew part of (..., 3, 3) matrices."""
    return 0.5 * np.stack(
        [a[..., 2, 1] - a[..., 1, 2], a[..., 0, 2] - a[..., 2, 0], a[..., 1, 0] - a[..., 0, 1]],
        axis=-1,
    )


def _hat(w: np.ndarray) -> np.ndarray:
    """(..., 3) -> (..., 3, 3) skew-symmetric matrices."""
    z = np.zeros(w.shape[:-1])
    x, y, v = w[..., 0], w[..., 1], w[..., 2]
    return np.stack(
        [np.stack([z, -v, y], -1), np.stack([v, z, -x], -1), np.stack([-y, x, z], -1)], -2
    )


def _log_so3(e: np.ndarray) -> np.ndarray:
    """Phi(log(E)) of (k, 3, 3) rotations: the rotation vector (eq. 15). Accurate up to
    angles just below pi (a tip rotation error of 180 degrees is a frame mistake, not a
    stiffness)."""
    c = np.clip((np.trace(e, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
    angle = np.arccos(c)
    small = angle < 1e-4
    safe = np.where(small, 1.0, angle)
    factor = np.where(small, 1.0 + angle**2 / 6.0, safe / np.sin(safe))
    return factor[:, None] * _vee(e)


def _left_jacobian_inv(phi: np.ndarray) -> np.ndarray:
    """J_l^-1(phi) of SO(3): log(exp(d^) exp(phi^)) = phi + J_l^-1(phi) d + O(d^2)."""
    angle = np.linalg.norm(phi, axis=1)
    small = angle < 1e-4
    t = np.where(small, 1.0, angle)
    beta = np.where(
        small,
        1.0 / 12.0 + angle**2 / 720.0,
        1.0 / t**2 - (1.0 + np.cos(t)) / (2.0 * t * np.sin(t)),
    )
    h = _hat(phi)
    return np.eye(3) - 0.5 * h + beta[:, None, None] * (h @ h)


# --------------------------------------------------------------------------- problem


@dataclass(frozen=True)
class _Problem:
    """The least-squares problem: measured tips, weights and how to call the core."""

    design: Design
    pressures: np.ndarray  # (m, c) Pa
    position: np.ndarray  # (m, 3) measured tip, m
    rotation: np.ndarray | None  # (m, 3, 3) measured tip rotation, or None: not used
    w_t: float  # sqrt(c_t / 2)
    w_r: float  # sqrt(c_r / 2)
    solver: dict
    threads: int

    def evaluate(self, rows: np.ndarray, sigma: np.ndarray, x0: np.ndarray | None) -> dict:
        """One core call for ``rows`` at ``sigma`` (k, 3): residuals (k, n_r) and their
        Jacobian (k, n_r, 3) with respect to log sigma; NaN where a solve failed."""
        tip = self.design.spec["tip"]
        out = self.design._rod.sensitivity_batch(
            np.ascontiguousarray(self.pressures[rows]),
            tip["force"],
            tip["moment"],
            _CORE_PARAMS,
            stiffness_scale=np.ascontiguousarray(sigma),
            x0=None if x0 is None else np.ascontiguousarray(x0),
            threads=self.threads,
            **self.solver,
        )
        r_n = out["tip_position"]
        # eq. 14; chain rule to log sigma: d/dlog sigma = sigma d/dsigma.
        res = [self.w_t * (self.position[rows] - r_n)]
        jac = [-self.w_t * out["d_tip_position"] * sigma[:, None, :]]
        if self.rotation is not None:
            rot_n = out["tip_rotation"]
            e_rot = _log_so3(np.einsum("kji,kjl->kil", rot_n, self.rotation[rows]))  # eq. 15
            # R_N -> R_N exp(w^) turns log(R_N^T R_*) by -J_l^-1(e_R) w, w = vee(R_N^T dR_N).
            omega = _vee(np.einsum("kji,kjlp->kpil", rot_n, out["d_tip_rotation"]))  # (k,P,3)
            d_rot = -np.einsum("kij,kpj->kip", _left_jacobian_inv(e_rot), omega)
            res.append(self.w_r * e_rot)
            jac.append(self.w_r * d_rot * sigma[:, None, :])
        return {
            "ok": np.asarray(out["converged"], dtype=bool),
            "res": np.concatenate(res, axis=1),
            "jac": np.concatenate(jac, axis=1),
            "x": out["x"],
            "tip": r_n,
        }


@dataclass
class _LMResult:
    theta: np.ndarray  # (m, 3) log sigma
    status: np.ndarray  # (m,) codes
    iterations: np.ndarray  # (m,)
    solved: np.ndarray  # (m,) the model converged at the initial sigma
    res: np.ndarray  # (m, n_r) at the final point
    jac: np.ndarray  # (m, n_r, 3)
    tip: np.ndarray  # (m, 3)
    calls: int


def _levenberg_marquardt(
    problem: _Problem,
    theta0: np.ndarray,
    bounds: tuple[float, float],
    max_iter: int,
    progress: Callable | None,
) -> _LMResult:
    """Levenberg-Marquardt in theta = log sigma, one independent problem per sample, all
    samples at once. Damping after Madsen, Nielsen and Tingleff (2004): A = J^T J + lambda I
    with the gain-ratio update of lambda; factors at a bound whose gradient points outwards
    are held there (projected steps)."""
    m = problem.pressures.shape[0]
    lo, hi = math.log(bounds[0]), math.log(bounds[1])
    theta = np.clip(theta0, lo, hi)
    status = np.full(m, _RUNNING)
    iterations = np.zeros(m, dtype=int)
    ev = problem.evaluate(np.arange(m), np.exp(theta), None)
    calls = 1
    solved = ev["ok"].copy()
    status[~solved] = _FAILED
    res, jac, tip, x = ev["res"], ev["jac"], ev["tip"], ev["x"]

    def normal_equations(r, j):
        return (
            np.einsum("ki,ki->k", r, r),
            np.einsum("kip,ki->kp", j, r),
            np.einsum("kip,kiq->kpq", j, j),
        )

    cost, grad, jtj = normal_equations(
        np.where(solved[:, None], res, 0.0), np.where(solved[:, None, None], jac, 0.0)
    )
    lam = _TAU * np.diagonal(jtj, axis1=1, axis2=2).max(axis=1)
    nu = np.full(m, 2.0)

    def stop_tests(idx):
        """Residual and gradient tests for samples ``idx`` at their current point."""
        small = np.sqrt(cost[idx]) / problem.w_t <= RESIDUAL_TOL
        d = np.diagonal(jtj[idx], axis1=1, axis2=2)
        # Columns below _NULL_COLUMN of the largest are zero to rounding (a factor that
        # does not act, e.g. a bending factor on a principal axis): their cosine is noise.
        acts = d > _NULL_COLUMN**2 * d.max(axis=1, initial=0.0)[:, None]
        free = acts & ~_held(theta[idx], grad[idx], lo, hi)
        cosine = np.abs(grad[idx]) / np.sqrt(np.maximum(d * cost[idx, None], 1e-300))
        flat = np.all(np.where(free, cosine <= GTOL, True), axis=1)
        return small | flat

    def report(it):
        if progress is not None:
            progress(it, int(np.sum(status == _RUNNING)), m)

    running = np.flatnonzero(status == _RUNNING)
    status[running[stop_tests(running)]] = _CONVERGED
    report(0)

    for it in range(1, max_iter + 1):
        active = np.flatnonzero(status == _RUNNING)
        if active.size == 0:
            break
        # Damped normal equations of all active samples at once; held factors get a unit row.
        held = _held(theta[active], grad[active], lo, hi)
        keep = ~held
        a = jtj[active] + lam[active, None, None] * np.eye(3)
        a = a * (keep[:, :, None] & keep[:, None, :]) + np.eye(3) * held[:, :, None]
        b = -np.where(held, 0.0, grad[active])
        step = np.linalg.solve(a, b[..., None])[..., 0]
        trial = np.clip(theta[active] + step, lo, hi)
        step = trial - theta[active]
        predicted = -(
            2.0 * np.einsum("kp,kp->k", step, grad[active])
            + np.einsum("kp,kpq,kq->k", step, jtj[active], step)
        )
        # One parallel core call for all active samples, each warm-started from its own x.
        ev = problem.evaluate(active, np.exp(trial), x[active])
        calls += 1
        iterations[active] += 1
        t_cost, t_grad, t_jtj = normal_equations(
            np.where(ev["ok"][:, None], ev["res"], 0.0),
            np.where(ev["ok"][:, None, None], ev["jac"], 0.0),
        )
        gain = cost[active] - t_cost
        accept = ev["ok"] & (gain > 0)
        # Gain ratio rho = actual / predicted decrease (Nielsen's update of lambda).
        rho = np.where(predicted > 0, gain / np.where(predicted > 0, predicted, 1.0), 1.0)
        acc, rej = active[accept], active[~accept]
        lam[acc] *= np.maximum(1.0 / 3.0, 1.0 - (2.0 * rho[accept] - 1.0) ** 3)
        nu[acc] = 2.0
        lam[rej] *= nu[rej]
        nu[rej] *= 2.0
        theta[acc] = trial[accept]
        res[acc], jac[acc] = ev["res"][accept], ev["jac"][accept]
        tip[acc], x[acc] = ev["tip"][accept], ev["x"][accept]
        cost[acc], grad[acc], jtj[acc] = t_cost[accept], t_grad[accept], t_jtj[accept]
        # A step below XTOL ends the sample, accepted or not: with more damping the next
        # one would be smaller still.
        tiny = np.abs(step).max(axis=1) <= XTOL
        status[acc[tiny[accept] | stop_tests(acc)]] = _CONVERGED
        status[rej[tiny[~accept]]] = _CONVERGED
        status[rej[~tiny[~accept] & (nu[rej] > _MAX_NU)]] = _STALLED
        report(it)
    status[status == _RUNNING] = _MAX_ITER
    return _LMResult(theta, status, iterations, solved, res, jac, tip, calls)


def _held(theta: np.ndarray, grad: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Factors at a bound whose descent direction (-grad) points out of the box."""
    return ((theta <= lo) & (grad > 0)) | ((theta >= hi) & (grad < 0))


def _sensitivity(jac_m: np.ndarray) -> np.ndarray:
    """(k, n_r, 3) Jacobian in m per unit log sigma -> (k, 3) sensitivity in m:
    1 / sqrt(((J^T J)^-1)_kk), the Schur complement of the other two factors (0 for a column
    that the others span or that is zero)."""
    a = np.einsum("kip,kiq->kpq", jac_m, jac_m)
    out = np.empty(a.shape[:2])
    for k in range(3):
        o = [j for j in range(3) if j != k]
        a_oo = a[:, o][:, :, o]
        a_ok = a[:, o, k]
        schur = a[:, k, k] - np.einsum("ki,kij,kj->k", a_ok, np.linalg.pinv(a_oo), a_ok)
        out[:, k] = np.sqrt(np.maximum(schur, 0.0))
    return out


# --------------------------------------------------------------------------- result


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class StiffnessIdentification:
    """Result of :func:`identify_stiffness`: one row per sample of ``dataset`` (m rows).

    sigma: (m, 3) identified (sigma_ext, sigma_bend_x, sigma_bend_y); NaN where a factor is
        not identifiable (see ``identifiable``).
    identifiable: (m, 3) bool: the sample's solve converged (status "converged" or
        "stalled"), the factor's sensitivity is at least ``min_sensitivity`` and it is not at a
        bound.
    sensitivity: (m, 3) m: tip displacement per unit change of log sigma_k with the other
        factors compensating (module docstring); NaN where the solve failed.
    at_bound: (m, 3) bool: the factor ended at a bound of ``settings["bounds"]``.
    sigma_solver: (m, 3) the solver's final point, every factor included; at factors that are
        not identifiable its value is arbitrary (it barely moves the tip). ``tip_position``
        and the residuals belong to it.
    tip_position: (m, 3) m, the model's tip at ``sigma_solver`` (NaN where failed).
    residual_mm: (m,) |r_* - r_N| there, mm. rotation_residual_deg: (m,) |e_R| in degrees
        (NaN when rotations were not used).
    iterations: (m,) Levenberg-Marquardt iterations. status: (m,) one of :data:`STATUS`.
    design: the design with the mapped ``sections``; dataset: the samples.
    settings: bounds, min_sensitivity (m), c_t, c_r, use of rotations, tolerances.
    calls: core calls made (each one parallel batch); wall_time_s: seconds.
    """

    design: Design
    dataset: Dataset
    sections: tuple[str, ...]
    sigma: np.ndarray
    identifiable: np.ndarray
    sensitivity: np.ndarray
    at_bound: np.ndarray
    sigma_solver: np.ndarray
    tip_position: np.ndarray
    residual_mm: np.ndarray
    rotation_residual_deg: np.ndarray
    iterations: np.ndarray
    status: np.ndarray
    settings: dict = field(default_factory=dict)
    calls: int = 0
    wall_time_s: float = float("nan")

    def __len__(self) -> int:
        return self.sigma.shape[0]

    def __repr__(self) -> str:
        frac = ", ".join(
            f"{n} {100 * f:.0f}%"
            for n, f in zip(SIGMA_NAMES, self.identified_fraction, strict=True)
        )
        return (
            f"StiffnessIdentification({len(self)} samples, design {self.design.name!r}, "
            f"sections {', '.join(self.sections)}; identified: {frac})"
        )

    @property
    def identified_fraction(self) -> np.ndarray:
        """(3,) fraction of the samples at which each factor was identified."""
        return self.identifiable.mean(axis=0) if len(self) else np.zeros(3)

    def to_frame(self, units: Units = None) -> pd.DataFrame:
        """One row per sample in the dataset schema (docs/datasets.md): the measured
        sample (``p0_kPa`` ..., ``tip_x_mm`` ..., and whatever else the dataset has), then the
        result columns ``sigma_ext``, ``sigma_bend_x``, ``sigma_bend_y`` (empty where not
        identified), ``identifiable_*``, ``sensitivity_*_mm``, ``at_bound_*``,
        ``model_tip_x_mm`` ... (the model's tip at the solver's sigma), ``residual_mm``,
        ``rotation_residual_deg``, ``iterations`` and ``status``. The metadata block names the
        design, the scaled sections, the dataset and the settings; ``load_dataset`` reads
        the table back."""
        from ..schema import Extra, provenance, schema_frame

        ds = self.dataset
        extras = [
            Extra(name, self.sigma[:, k], f"identified {name} (empty: not identifiable)")
            for k, name in enumerate(SIGMA_NAMES)
        ]
        extras += [
            Extra(f"identifiable_{name}", self.identifiable[:, k], f"{name} was identified")
            for k, name in enumerate(SIGMA_NAMES)
        ]
        extras += [
            Extra(
                f"sensitivity_{name}",
                self.sensitivity[:, k],
                f"tip displacement per unit change of log {name}",
                "length",
            )
            for k, name in enumerate(SIGMA_NAMES)
        ]
        extras += [
            Extra(f"at_bound_{name}", self.at_bound[:, k], f"{name} ended at a bound")
            for k, name in enumerate(SIGMA_NAMES)
        ]
        extras += [
            Extra(f"model_tip_{a}", self.tip_position[:, i], "model tip (solver's sigma)", "length")
            for i, a in enumerate("xyz")
        ]
        extras += [
            Extra("residual", self.residual_mm * 1e-3, "|measured - model tip|", "length"),
            Extra("rotation_residual_deg", self.rotation_residual_deg, "tip rotation residual"),
            Extra("iterations", self.iterations, "Levenberg-Marquardt iterations"),
            Extra("status", self.status, f"one of {', '.join(STATUS)}"),
        ]
        dataset_meta = {k: v for k, v in ds.metadata.items() if k != "columns"}
        meta = provenance(
            "softrod.identify_stiffness",
            self.design,
            sections=list(self.sections),
            synthetic=ds.synthetic,  # the tip columns are the dataset's
            dataset=None if ds.source is None else ds.source.name,
            dataset_metadata=dataset_meta,
            settings=_plain_settings(self.settings),
        )
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

    def factor_table(self) -> pd.DataFrame:
        """Per factor: samples identified (count, fraction), at a bound, statistics of the
        identified values and the median sensitivity (mm)."""
        rows = []
        for k, name in enumerate(SIGMA_NAMES):
            s = self.sigma[self.identifiable[:, k], k]

            def stat(fn, s=s):
                return float(fn(s)) if s.size else float("nan")

            rows.append(
                {
                    "factor": name,
                    "identified": int(s.size),
                    "identified_fraction": s.size / max(len(self), 1),
                    "at_bound": int(self.at_bound[:, k].sum()),
                    "min": stat(np.min),
                    "median": stat(np.median),
                    "max": stat(np.max),
                    "median_sensitivity_mm": float(np.nanmedian(1e3 * self.sensitivity[:, k]))
                    if np.isfinite(self.sensitivity[:, k]).any()
                    else float("nan"),
                }
            )
        return pd.DataFrame(rows)

    def summary(self) -> dict:
        """Key numbers: samples, statuses, identified fractions, residuals, iterations."""
        ok = np.isfinite(self.residual_mm)
        out = {
            "design": self.design.name,
            "sections scaled": ", ".join(self.sections),
            "samples": len(self),
            "synthetic data": self.dataset.synthetic,
            "rotation used": self.settings.get("use_rotation", False),
        }
        for name in STATUS:
            out[f"status {name}"] = int(np.sum(self.status == name))
        for name, frac in zip(SIGMA_NAMES, self.identified_fraction, strict=True):
            out[f"{name} identified"] = f"{100 * frac:.1f} %"
        out["min_sensitivity (mm)"] = 1e3 * self.settings.get("min_sensitivity", float("nan"))
        out["bounds"] = str(self.settings.get("bounds"))
        out["median residual (mm)"] = (
            float(np.median(self.residual_mm[ok])) if ok.any() else float("nan")
        )
        out["max residual (mm)"] = float(np.max(self.residual_mm[ok])) if ok.any() else math.nan
        out["iterations (max)"] = int(self.iterations.max(initial=0))
        out["core calls"] = self.calls
        out["wall time (s)"] = round(self.wall_time_s, 3)
        return out

    def write_report(self, path: PathLike) -> Path:
        """An HTML report (:func:`softrod.calibration.report.write_report`): summary, the
        factor table, the tip residuals of the identified model and the measured tips coloured
        by each identified factor (paper 001 Fig. 5)."""
        from .metrics import tip_error_table
        from .report import write_report

        mount = self.design.spec["mounting"]
        axis = np.asarray(mount["base_rotation"])[:, 2]
        failed = np.isnan(self.tip_position).any(axis=1)
        flagged = (~self.identifiable).sum(axis=0)
        warnings = []
        if self.dataset.synthetic:
            warnings.append("The dataset is SYNTHETIC (generated by the model), not measured.")
        if failed.any():
            warnings.append(f"{int(failed.sum())} sample(s) without a converged model solve.")
        for name, n in zip(SIGMA_NAMES, flagged, strict=True):
            if n:
                warnings.append(
                    f"{name}: not identifiable at {int(n)} of {len(self)} samples (NaN)."
                )
        return write_report(
            path,
            title=f"Per-sample stiffness identification: {self.design.name}",
            summary=self.summary(),
            parameter_table=self.factor_table(),
            error_table=tip_error_table(
                self.dataset.tip_position,
                self.tip_position,
                length=self.design.length,
                base_position=mount["base_position"],
                axis=axis,
            ),
            measured=self.dataset.tip_position,
            predicted=self.tip_position,
            pressures=self.dataset.pressures,
            factors=self.sigma,
            factor_names=list(SIGMA_NAMES),
            warnings=warnings,
            length=self.design.length,
            axis=axis,
            base_position=mount["base_position"],
        )


# --------------------------------------------------------------------------- entry point


def _samples_done(step: int, active: int, total: int) -> tuple[float, str]:
    """A progress bar's position and text for identify's progress(step, active, total)."""
    return total - active, f"{total - active}/{total} samples done"


def _plain_settings(settings: dict) -> dict:
    """The settings as JSON values (tuples as lists, numpy scalars as numbers)."""
    out = {}
    for key, value in settings.items():
        if isinstance(value, tuple):
            value = list(value)
        if isinstance(value, np.generic):
            value = value.item()
        out[key] = value
    return out


def _positive(value, name: str, kind: str) -> float:
    x = to_si(value.item() if isinstance(value, np.generic) else value, kind, name, InputError)
    if not (math.isfinite(x) and x > 0):
        raise design_error(name, value, f"must be a positive {kind}", InputError)
    return x


def _check_bounds(bounds) -> tuple[float, float]:
    try:
        if isinstance(bounds, (str, bytes)) or not isinstance(bounds, (list, tuple, np.ndarray)):
            raise TypeError
        lo, hi = (V.real(b, "bounds") for b in bounds)
    except (TypeError, ValueError):
        raise design_error(
            "bounds",
            bounds,
            "must be two numbers (lower, upper) with 0 < lower < 1 < upper",
            InputError,
        ) from None
    if not (0 < lo < 1 < hi < math.inf):
        raise design_error(
            "bounds",
            bounds,
            "must satisfy 0 < lower < 1 < upper (factors on the literature stiffness)",
            InputError,
        )
    return lo, hi


def _check_dataset(dataset, design: Design) -> Dataset:
    if not isinstance(dataset, Dataset):
        raise design_error(
            "dataset",
            type(dataset).__name__,
            "must be a softrod Dataset (softrod.load_dataset or Dataset(...))",
            InputError,
        )
    if dataset.n_channels != design.n_channels:
        raise design_error(
            "dataset.pressures",
            f"shape {dataset.pressures.shape}",
            f"has {dataset.n_channels} pressure channel(s) but design {design.name!r} has "
            f"{design.n_channels}: one column per channel",
            InputError,
        )
    if len(dataset) == 0:
        raise design_error("dataset", "0 rows", "needs at least one sample", InputError)
    dataset.require_slack("the per-sample identification (paper 001)")
    labels = [] if dataset.mounting is None else sorted(set(dataset.mounting.tolist()))
    if len(labels) > 1:
        # Every sample is solved with the design as mounted: samples of another mounting
        # would be fitted to the wrong equilibrium (refused, not answered silently).
        raise design_error(
            "dataset.mounting",
            labels,
            "the per-sample identification solves every sample with the design as mounted: "
            "identify each mounting separately, with the design mounted that way",
            InputError,
        )
    return dataset


def _initial(initial, m: int, bounds) -> np.ndarray:
    if initial is None:
        return np.ones((m, 3))
    try:
        s = np.array(initial, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise design_error("initial", initial, "must be numbers", InputError) from None
    if s.shape not in ((3,), (m, 3)):
        raise design_error(
            "initial", f"shape {s.shape}", f"must be (3,) or ({m}, 3) factors", InputError
        )
    if not (np.isfinite(s).all() and (s >= bounds[0]).all() and (s <= bounds[1]).all()):
        raise design_error(
            "initial", "out of range", f"factors must lie within bounds {bounds}", InputError
        )
    return np.broadcast_to(s, (m, 3)).copy()


def _problem(design, dataset, *, use_rotation, n_high, r_high, m_high, R_high, options, threads):
    if options is None:
        options = SolverOptions()
    if not isinstance(options, SolverOptions):
        raise design_error("options", options, "must be a softrod.SolverOptions", InputError)
    threads = V.threads(threads)
    c_t = _positive(n_high, "n_high", "force") / _positive(r_high, "r_high", "length")  # eq. 20
    c_r = _positive(m_high, "m_high", "moment") / _positive(R_high, "R_high", "angle")
    for name, c, unit in (("n_high / r_high", c_t, "N/m"), ("m_high / R_high", c_r, "N m/rad")):
        if not SPRING_RANGE[0] <= c <= SPRING_RANGE[1]:
            raise design_error(
                name,
                f"{c:g} {unit}",
                f"the virtual spring of eq. 20 must lie within {SPRING_RANGE[0]:g} ... "
                f"{SPRING_RANGE[1]:g} (beyond, the least-squares sums overflow or vanish)",
                InputError,
            )
    if not isinstance(use_rotation, bool):
        raise design_error("use_rotation", use_rotation, "must be True or False", InputError)
    rotation = dataset.tip_rotation if use_rotation else None
    problem = _Problem(
        design=design,
        pressures=np.asarray(dataset.pressures, dtype=float),
        position=np.asarray(dataset.require_tip("identify_stiffness"), dtype=float),
        rotation=None if rotation is None else np.asarray(rotation, dtype=float),
        w_t=math.sqrt(c_t / 2.0),
        w_r=math.sqrt(c_r / 2.0),
        solver=options.as_kwargs(),
        threads=threads,
    )
    return problem, c_t, c_r


@one_blas_thread
def identify_stiffness(
    design: DesignLike,
    dataset: Dataset,
    *,
    sections: Sequence[str] | None = None,
    min_sensitivity: Quantity | None = None,
    bounds: tuple[float, float] = DEFAULT_BOUNDS,
    use_rotation: bool = True,
    n_high: Quantity = N_HIGH,
    r_high: Quantity = R_HIGH,
    m_high: Quantity = M_HIGH,
    R_high: Quantity = ROT_HIGH,
    initial: ArrayLike | None = None,
    max_iter: int = 30,
    options: SolverOptions | None = None,
    threads: int = 0,
    progress: Callable[[int, int, int], None] | None = None,
    executor: Any = None,
    chunk_size: int | None = None,
) -> StiffnessIdentification:
    """Identify sigma = (sigma_ext, sigma_bend_x, sigma_bend_y) for every sample (paper 001
    eqs. 14-22; method in the module docstring and docs/calibration-per-sample.md).

    design: a :class:`~softrod.Design` or name; ``sections`` as in
        :func:`stiffness_mapped_design` (default: the chambered elastic sections).
    dataset: the samples (:class:`~softrod.Dataset`): pressures, tip positions and,
        optionally, tip rotations. The design's tip force and moment act in every sample.
    min_sensitivity: a length (m, or a string such as "1.3 mm"): factors whose sensitivity
        is below it are not identifiable (NaN). Default :data:`MIN_SENSITIVITY_FRACTION` of
        the design's length.
    bounds: (lower, upper) range of every factor, default :data:`DEFAULT_BOUNDS`.
    use_rotation: use the dataset's tip rotations (eq. 15) when it has them.
    n_high, r_high, m_high, R_high: "high" deviations of eq. 20 (N, m, N m, rad; strings with
        units allowed): c_t = n_high / r_high, c_r = m_high / R_high.
    initial: starting sigma, (3,) or (m, 3); default 1 (the literature stiffness).
    max_iter: Levenberg-Marquardt iterations (core calls after the first).
    options: :class:`~softrod.SolverOptions` of the shooting solves; threads: cores (0 =
        all). progress: None (a bar in interactive sessions), True, False, or a callable
        called as ``progress(iteration, n_active, n_total)`` after each iteration
        (:mod:`softrod.progress`).
    executor: a ``distributed.Client``: the samples are identified on its cluster in chunks
        of ``chunk_size`` samples (default: the rule in :mod:`softrod.cluster`), each chunk
        this function on a worker (``threads`` as in ``solve_statics_batch``), and the rows
        come back in order; ``progress`` is then called as ``progress(chunks_done,
        samples_left, samples)`` after each chunk (docs/cluster.md). Every sample's fit is
        its own problem, so chunking changes no sample's result once batch rows do not
        depend on their neighbours.

    Raises :class:`~softrod.errors.InputError` for bad inputs (naming field, value, rule).
    Samples whose model does not converge are kept with status "solve_failed".
    """
    t0 = time.perf_counter()
    mapped, names = stiffness_mapped_design(design, sections)
    dataset = _check_dataset(dataset, mapped)
    bounds = _check_bounds(bounds)
    max_iter = V.integer(max_iter, "max_iter", minimum=1, maximum=V.MAX_ITERATIONS)
    check_progress(progress)
    if min_sensitivity is None:
        min_sens = MIN_SENSITIVITY_FRACTION * mapped.length
    else:
        min_sens = to_si(
            min_sensitivity.item() if isinstance(min_sensitivity, np.generic) else min_sensitivity,
            "length",
            "min_sensitivity",
            InputError,
        )
        if not (math.isfinite(min_sens) and min_sens >= 0):
            raise design_error(
                "min_sensitivity", min_sensitivity, "must be a length >= 0 (m)", InputError
            )
    problem, c_t, c_r = _problem(
        mapped,
        dataset,
        use_rotation=use_rotation,
        n_high=n_high,
        r_high=r_high,
        m_high=m_high,
        R_high=R_high,
        options=options,
        threads=threads,
    )
    m = len(dataset)
    theta0 = np.log(_initial(initial, m, bounds))
    from ..cluster import check_executor

    if check_executor(executor) is not None:
        kwargs = dict(
            min_sensitivity=min_sens,
            bounds=bounds,
            use_rotation=use_rotation,
            n_high=n_high,
            r_high=r_high,
            m_high=m_high,
            R_high=R_high,
            max_iter=max_iter,
            options=options,
        )
        with reporter(progress, "identify_stiffness", len(dataset), _samples_done) as report:
            return _identify_on_cluster(
                executor,
                mapped,
                names,
                dataset,
                np.exp(theta0),
                kwargs,
                threads,
                chunk_size,
                report,
                t0,
            )
    if chunk_size is not None:
        raise design_error("chunk_size", chunk_size, "applies with executor= only", InputError)
    with reporter(progress, "identify_stiffness", len(dataset), _samples_done) as report:
        lm = _levenberg_marquardt(problem, theta0, bounds, max_iter, report)

    sigma_solver = np.exp(lm.theta)
    solved = lm.solved & np.isin(lm.status, (_CONVERGED, _STALLED))
    jac_m = lm.jac / problem.w_t  # residual as tip displacement (m)
    sensitivity = np.where(
        lm.solved[:, None], _sensitivity(np.where(lm.solved[:, None, None], jac_m, 0.0)), np.nan
    )
    lo, hi = math.log(bounds[0]), math.log(bounds[1])
    at_bound = lm.solved[:, None] & ((lm.theta <= lo) | (lm.theta >= hi))
    identifiable = solved[:, None] & (sensitivity >= min_sens) & ~at_bound
    res_pos = np.where(lm.solved[:, None], lm.res[:, :3] / problem.w_t, np.nan)
    if problem.rotation is not None:
        e_rot = np.where(lm.solved[:, None], lm.res[:, 3:] / problem.w_r, np.nan)
        rot_deg = np.degrees(np.linalg.norm(e_rot, axis=1))
    else:
        rot_deg = np.full(m, np.nan)
    return StiffnessIdentification(
        design=mapped,
        dataset=dataset,
        sections=names,
        sigma=_readonly(np.where(identifiable, sigma_solver, np.nan)),
        identifiable=_readonly(identifiable),
        sensitivity=_readonly(sensitivity),
        at_bound=_readonly(at_bound),
        sigma_solver=_readonly(np.where(lm.solved[:, None], sigma_solver, np.nan)),
        tip_position=_readonly(np.where(lm.solved[:, None], lm.tip, np.nan)),
        residual_mm=_readonly(1e3 * np.linalg.norm(res_pos, axis=1)),
        rotation_residual_deg=_readonly(rot_deg),
        iterations=_readonly(lm.iterations),
        status=_readonly(_STATUS_NAMES[lm.status].astype(object)),
        settings={
            "bounds": bounds,
            "min_sensitivity": min_sens,
            "use_rotation": problem.rotation is not None,
            "c_t": c_t,
            "c_r": c_r,
            "max_iter": max_iter,
            "xtol": XTOL,
            "residual_tol": RESIDUAL_TOL,
            "gtol": GTOL,
            "solver": problem.solver,
        },
        calls=lm.calls,
        wall_time_s=time.perf_counter() - t0,
    )


# --------------------------------------------------------------------------- on a cluster

_ROW_FIELDS = (
    "sigma",
    "identifiable",
    "sensitivity",
    "at_bound",
    "sigma_solver",
    "tip_position",
    "residual_mm",
    "rotation_residual_deg",
    "iterations",
    "status",
)


def _identify_chunk(text, names, dataset, initial, kwargs, threads, per_host) -> dict:
    """One chunk of samples on a worker: the arrays of :func:`identify_stiffness` (a result
    object holds a compiled design, which never travels)."""
    from ..cluster import design_from_text, worker_threads

    result = identify_stiffness(
        design_from_text(text),
        dataset,
        sections=list(names),
        initial=initial,
        threads=worker_threads(per_host, threads),
        **kwargs,
    )
    out = {name: np.array(getattr(result, name)) for name in _ROW_FIELDS}
    out["calls"] = result.calls
    out["settings"] = result.settings
    return out


def _identify_on_cluster(
    executor, mapped, names, dataset, initial, kwargs, threads, chunk_size, progress, t0
) -> StiffnessIdentification:
    from ..cluster import chunk_rows, design_text, run_chunks, task_slots

    m = len(dataset)
    slots, per_host = task_slots(executor)
    rows = chunk_rows(m, slots, chunk_size)
    bounds = [(lo, min(lo + rows, m)) for lo in range(0, m, rows)]
    text = design_text(mapped)
    chunks = [
        (text, names, dataset.subset(np.arange(lo, hi)), initial[lo:hi], kwargs, threads, per_host)
        for lo, hi in bounds
    ]
    report = None
    if progress is not None:
        finished = [0]

        def report(done, total):
            finished[0] += 1
            progress(finished[0], total - done, total)

    parts = run_chunks(
        executor,
        _identify_chunk,
        chunks,
        sizes=[hi - lo for lo, hi in bounds],
        progress=report,
        name="softrod-identify",
    )
    fields = {name: _readonly(np.concatenate([p[name] for p in parts])) for name in _ROW_FIELDS}
    return StiffnessIdentification(
        design=mapped,
        dataset=dataset,
        sections=tuple(names),
        settings=parts[0]["settings"],
        calls=sum(p["calls"] for p in parts),
        wall_time_s=time.perf_counter() - t0,
        **fields,
    )
