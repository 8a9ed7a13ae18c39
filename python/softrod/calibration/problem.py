"""A calibration problem: what is fitted, to what, through which model, on which rows.

- **Parameters**: objects with a ``name``, a ``unit`` (SI) and ``positive`` (optimised on
  log(theta), so they stay > 0); their starting values and bounds (:class:`Bounds`).
- **A model adapter** (:class:`ModelAdapter`): maps parameter values to predictions of the
  measured quantities for each dataset row, with exact parameter Jacobians (rod statics,
  rod dynamics replaying time series, PCC statics and dynamics; :mod:`softrod.calibration.
  adapters`). Registration parameters (the measurement frame against the model's) wrap any
  adapter (:class:`Registered`).
- **Observations** and their **weights**: the measured tip and marker positions, and a held
  tip's measured reaction (the blocked force and moment), each quantity divided by its own
  scale (the measurement's standard deviation: a length for positions, default 1 mm; a
  force or moment for the reaction, default :data:`DEFAULT_SCALE_N` and
  :data:`DEFAULT_SCALE_NM`), so that quantities with different noise and units combine.
- **A split**: the training rows enter the residual; test rows are predicted at the end.

The residual vector is, row by row, the tip block (x, y, z of every training row with a
measured tip) followed by the marker block (every seen marker of every training row), then
the reaction blocks (every measured component of the force, then of the moment); a
row whose model evaluation failed gets :data:`FAILED_RESIDUAL` in each of its entries and
zero derivatives, so that the optimiser steps back instead of stopping on a NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

#: Residual (in units of each quantity's scale) of an observation whose model evaluation
#: failed at a trial point.
FAILED_RESIDUAL = 1e3
#: The measured quantities a model can predict: positions in the world (measurement) frame.
POSITIONS = ("tip", "markers")
#: ... and a held tip's reaction (force, moment; world frame): the blocked force.
REACTIONS = ("reaction", "reaction_moment")
QUANTITIES = POSITIONS + REACTIONS
#: Default scale of every position residual: 1 mm, so that the cost is O(1) for scipy's
#: tolerances and the residuals read in mm.
DEFAULT_SCALE_M = 1e-3
#: Default scale of a reaction force residual: 5 mN, the noise of a bench load cell of a
#: few newtons' range (about 0.1 % of its full scale).
DEFAULT_SCALE_N = 5e-3
#: Default scale of a reaction moment residual: 0.5 N mm (5 mN at a 100 mm arm).
DEFAULT_SCALE_NM = 5e-4


@dataclass
class Prediction:
    """What a model adapter predicts for the dataset's rows (SI, world frame).

    tip: (m, 3); markers: (m, K, 3) or None; reaction, reaction_moment: (m, 3) the wrench a
    held tip's constraint applies to the tip (N, N m), or None (a free tip's model, or a
    model that does not predict it); d_tip (m, 3, P), d_markers (m, K, 3, P), d_reaction
    and d_reaction_moment (m, 3, P) the exact derivatives with respect to the parameters
    (None without ``jacobian``); ok: (m,) the model evaluation of the row succeeded. Rows
    not asked for hold NaN and ok False.
    """

    tip: np.ndarray
    ok: np.ndarray
    d_tip: np.ndarray | None = None
    markers: np.ndarray | None = None
    d_markers: np.ndarray | None = None
    reaction: np.ndarray | None = None
    d_reaction: np.ndarray | None = None
    reaction_moment: np.ndarray | None = None
    d_reaction_moment: np.ndarray | None = None

    #: The derivative fields.
    JACOBIANS = ("d_tip", "d_markers", "d_reaction", "d_reaction_moment")

    @classmethod
    def empty(
        cls, m: int, n_par: int, n_markers: int, jacobian: bool, reactions: bool = False
    ) -> Prediction:
        def nan(*shape):
            return np.full(shape, np.nan)

        return cls(
            tip=nan(m, 3),
            ok=np.zeros(m, dtype=bool),
            d_tip=nan(m, 3, n_par) if jacobian else None,
            markers=nan(m, n_markers, 3) if n_markers else None,
            d_markers=nan(m, n_markers, 3, n_par) if n_markers and jacobian else None,
            reaction=nan(m, 3) if reactions else None,
            d_reaction=nan(m, 3, n_par) if reactions and jacobian else None,
            reaction_moment=nan(m, 3) if reactions else None,
            d_reaction_moment=nan(m, 3, n_par) if reactions and jacobian else None,
        )

    def zero_jacobian(self) -> None:
        """Set every derivative to zero (a failed point: the optimiser steps back)."""
        for name in self.JACOBIANS:
            d = getattr(self, name)
            if d is not None:
                d[:] = 0.0

    def with_jacobian_of(self, other: Prediction) -> Prediction:
        """These values with ``other``'s derivatives."""
        return replace(self, **{name: getattr(other, name) for name in self.JACOBIANS})


class ModelAdapter:
    """A model on a dataset: parameters in, predicted positions (and their exact parameter
    Jacobians) out. Subclasses set ``parameters`` and ``initial`` (SI values at the start)
    and implement :meth:`predict`, :meth:`calibrated_design` and :meth:`reference`.

    ``evaluations`` counts model evaluations (one evaluation predicts every requested row:
    a batch of static solves, or the replay of every requested experiment)."""

    #: "cosserat" or "pcc"
    model: str = "cosserat"
    #: Time series replayed (True) or equilibria (False).
    dynamic: bool = False
    #: Whether the adapter gives exact Jacobians (else only derivative-free fits work).
    exact_jacobian: bool = True
    #: Nelder-Mead's stopping rules (scipy's xatol on u = log theta, fatol on the cost,
    #: relative to the starting cost when ``fatol_relative``) and the first simplex's step
    #: in u (None: scipy's 5 %).
    nelder_mead: dict = {"xatol": 1e-8, "fatol": 1e-10, "fatol_relative": False, "step": None}
    #: Whether a prediction depends on theta alone (no warm starts from earlier
    #: evaluations): then the optimiser's own evaluation at the optimum, with its Jacobian,
    #: serves the standard errors instead of a repeated one.
    stateless: bool = False
    #: Levenberg-Marquardt also stops when its next Gauss-Newton step is below this
    #: fraction of every parameter's standard error (None: MINPACK's xtol/ftol only); see
    #: :func:`softrod.calibration.solve.optimise`.
    lm_stop_fraction: float | None = None

    def __init__(self) -> None:
        self.evaluations = 0
        self.parameters: tuple = ()
        self.initial = np.zeros(0)

    def reset(self) -> None:
        """Forget warm starts and the evaluation count (a fit starts cold)."""
        self.evaluations = 0

    def set_threads(self, threads: int) -> None:
        """The Rust core's worker threads (a Dask worker's share of its host's cores)."""

    def predict(self, theta: np.ndarray, rows: np.ndarray, jacobian: bool) -> Prediction:
        raise NotImplementedError

    def calibrated_design(self, theta: np.ndarray):
        """The design with the fitted values written in."""
        raise NotImplementedError

    def final_prediction(self, calibrated, theta: np.ndarray, rows: np.ndarray) -> Prediction:
        """The positions of ``rows`` at the fitted values (``calibrated``: the design with
        them written in)."""
        return self.predict(theta, rows, False)

    def reference(self, calibrated, theta: np.ndarray) -> Prediction:
        """The unpressurised positions of every row at the fitted values (for errors in %
        of the deflection)."""
        raise NotImplementedError

    def base_frame(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(base point, undeformed axis) in the world frame when one mounting holds for
        every row, else None."""
        return None


@dataclass(frozen=True)
class RegistrationParameter:
    """A parameter of the measurement frame relative to the model's world frame: the angle
    (rad) of a rotation about the base axis through the base point, or one component (m)
    of an offset (paper 000 Sec. III-D calibrates the rotation about the base z axis)."""

    name: str
    kind: str  # "angle" or "x", "y", "z"

    @property
    def unit(self) -> str:
        return "rad" if self.kind == "angle" else "m"

    positive = False


#: Registration parameter names (``registration_angle`` and the offset components).
REGISTRATION = {
    "registration_angle": "angle",
    "registration_x": "x",
    "registration_y": "y",
    "registration_z": "z",
}


def _rotation(axis: np.ndarray, angle: float) -> tuple[np.ndarray, np.ndarray]:
    """Rotation matrix about the unit ``axis`` and its derivative in the angle (Rodrigues)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    c, s = math.cos(angle), math.sin(angle)
    rot = np.eye(3) + s * k + (1.0 - c) * (k @ k)
    d_rot = c * k + s * (k @ k)
    return rot, d_rot


class Registered(ModelAdapter):
    """An adapter whose positions are seen in a measurement frame: y = Q (x - b) + b + t,
    Q the rotation by ``registration_angle`` about the base axis a through the base point
    b, t = (``registration_x``, ``_y``, ``_z``). The registration parameters follow the
    model's in ``parameters``; dy/dtheta = Q dx/dtheta, dy/dangle = Q' (x - b), dy/dt = I."""

    def __init__(self, inner: ModelAdapter, registration: list[RegistrationParameter]):
        super().__init__()
        frame = inner.base_frame()
        if frame is None:
            from ..errors import InputError, design_error

            raise design_error(
                "params",
                [p.name for p in registration],
                "registration needs one base frame for every row (one mounting)",
                InputError,
            )
        self.inner = inner
        self.registration = tuple(registration)
        self.base, self.axis = frame
        self.parameters = tuple(inner.parameters) + self.registration
        self.initial = np.concatenate([inner.initial, np.zeros(len(registration))])
        self.model, self.dynamic = inner.model, inner.dynamic
        self.exact_jacobian = inner.exact_jacobian
        self.stateless = inner.stateless
        self.lm_stop_fraction = inner.lm_stop_fraction
        # The inner model's stopping rules; scipy's first simplex (a step in log theta makes
        # no sense for an offset that starts at 0 m).
        self.nelder_mead = {**inner.nelder_mead, "step": None}

    @property
    def n_inner(self) -> int:
        return len(self.inner.parameters)

    def values(self, theta) -> tuple[float, np.ndarray]:
        """(angle, offset) of ``theta``'s registration part."""
        angle, offset = 0.0, np.zeros(3)
        for p, v in zip(self.registration, theta[self.n_inner :], strict=True):
            if p.kind == "angle":
                angle = float(v)
            else:
                offset["xyz".index(p.kind)] = float(v)
        return angle, offset

    def transform(self, pred: Prediction, theta) -> Prediction:
        angle, offset = self.values(theta)
        rot, d_rot = _rotation(self.axis, angle)
        n_in, n_par = self.n_inner, len(self.parameters)

        def points(x):  # (..., 3)
            return (x - self.base) @ rot.T + self.base + offset

        def derivatives(x, dx):  # x (..., 3), dx (..., 3, n_in) -> (..., 3, n_par)
            out = np.zeros(x.shape + (n_par,))
            out[..., :n_in] = np.einsum("ij,...jk->...ik", rot, dx)
            for j, p in enumerate(self.registration):
                if p.kind == "angle":
                    out[..., n_in + j] = (x - self.base) @ d_rot.T
                else:
                    out[..., "xyz".index(p.kind), n_in + j] = 1.0
            return out

        def vectors(v):  # a wrench component (..., 3): rotated, not moved
            return None if v is None else v @ rot.T

        def vector_derivatives(v, dv):  # d(Q v): Q dv, Q' v in the angle, 0 in the offset
            if dv is None:
                return None
            out = np.zeros(v.shape + (n_par,))
            out[..., :n_in] = np.einsum("ij,...jk->...ik", rot, dv)
            for j, p in enumerate(self.registration):
                if p.kind == "angle":
                    out[..., n_in + j] = v @ d_rot.T
            return out

        return Prediction(
            tip=points(pred.tip),
            ok=pred.ok,
            d_tip=None if pred.d_tip is None else derivatives(pred.tip, pred.d_tip),
            markers=None if pred.markers is None else points(pred.markers),
            d_markers=None if pred.d_markers is None else derivatives(pred.markers, pred.d_markers),
            reaction=vectors(pred.reaction),
            d_reaction=vector_derivatives(pred.reaction, pred.d_reaction),
            reaction_moment=vectors(pred.reaction_moment),
            d_reaction_moment=vector_derivatives(pred.reaction_moment, pred.d_reaction_moment),
        )

    def predict(self, theta, rows, jacobian):
        theta = np.asarray(theta, dtype=float)
        pred = self.inner.predict(theta[: self.n_inner], rows, jacobian)
        return self.transform(pred, theta)

    def reset(self) -> None:
        self.inner.reset()
        self.evaluations = 0

    def set_threads(self, threads: int) -> None:
        self.inner.set_threads(threads)

    @property
    def evaluations(self) -> int:
        return self.inner.evaluations if hasattr(self, "inner") else 0

    @evaluations.setter
    def evaluations(self, value: int) -> None:
        if hasattr(self, "inner"):
            self.inner.evaluations = value

    def calibrated_design(self, theta):
        return self.inner.calibrated_design(np.asarray(theta)[: self.n_inner])

    def final_prediction(self, calibrated, theta, rows):
        theta = np.asarray(theta, dtype=float)
        pred = self.inner.final_prediction(calibrated, theta[: self.n_inner], rows)
        return self.transform(pred, theta)

    def reference(self, calibrated, theta):
        theta = np.asarray(theta, dtype=float)
        return self.transform(self.inner.reference(calibrated, theta[: self.n_inner]), theta)

    def base_frame(self):
        return self.base, self.axis


@dataclass(frozen=True)
class Observations:
    """The measured positions (SI, measurement frame): ``tip`` (m, 3) or None, ``markers``
    (m, K, 3) with NaN where a marker was not seen, or None; a held tip's measured reaction
    ``reaction`` (N) and ``reaction_moment`` (N m), (m, 3) with NaN where a component was
    not measured, or None."""

    tip: np.ndarray | None
    markers: np.ndarray | None
    reaction: np.ndarray | None = None
    reaction_moment: np.ndarray | None = None

    @property
    def rows(self) -> int:
        """The number of rows (m)."""
        present = (self.tip, self.markers, self.reaction, self.reaction_moment)
        return next(len(a) for a in present if a is not None)

    @property
    def reactions(self) -> bool:
        """Whether a reaction (force or moment) was measured."""
        return self.reaction is not None or self.reaction_moment is not None


class Residual:
    """Weighted residuals of a prediction against the observations on ``rows``.

    ``scales``: {quantity: its measurement's standard deviation, SI (m, N, N m)}; residual
    = (predicted - measured) / scale."""

    def __init__(self, observed: Observations, rows: np.ndarray, scales: dict[str, float]):
        self.rows = np.asarray(rows)
        self.observed = observed
        self.scales = scales
        self.tip_rows = self.rows if observed.tip is not None else self.rows[:0]
        if observed.markers is not None:
            seen = np.isfinite(observed.markers[self.rows]).all(axis=2)  # (r, K)
            self.marker_seen = seen
        else:
            self.marker_seen = None
        # The measured components (r, 3) of each reaction quantity, in REACTIONS order.
        self.reaction_seen = {
            q: np.isfinite(a[self.rows])
            for q, a in zip(REACTIONS, (observed.reaction, observed.reaction_moment), strict=True)
            if a is not None
        }

    @property
    def n_positions(self) -> int:
        """The residual's position entries (the first ones)."""
        n = 3 * self.tip_rows.size
        if self.marker_seen is not None:
            n += 3 * int(self.marker_seen.sum())
        return n

    @property
    def size(self) -> int:
        return self.n_positions + sum(int(s.sum()) for s in self.reaction_seen.values())

    def _reaction_parts(self, pred: Prediction, jacobian: bool):
        """(quantity, predicted or its derivative, measured, seen) of each reaction block."""
        for q, seen in self.reaction_seen.items():
            value = pred.reaction if q == "reaction" else pred.reaction_moment
            d = pred.d_reaction if q == "reaction" else pred.d_reaction_moment
            measured = self.observed.reaction if q == "reaction" else self.observed.reaction_moment
            yield q, (d if jacobian else value), measured, seen

    def vector(self, pred: Prediction) -> np.ndarray:
        parts = []
        if self.tip_rows.size:
            r = (pred.tip[self.tip_rows] - self.observed.tip[self.tip_rows]) / self.scales["tip"]
            r[~pred.ok[self.tip_rows]] = FAILED_RESIDUAL
            parts.append(r.ravel())
        if self.marker_seen is not None:
            d = (pred.markers[self.rows] - self.observed.markers[self.rows]) / self.scales[
                "markers"
            ]
            d[~pred.ok[self.rows]] = FAILED_RESIDUAL
            parts.append(d[self.marker_seen].ravel())
        for q, value, measured, seen in self._reaction_parts(pred, False):
            d = (value[self.rows] - measured[self.rows]) / self.scales[q]
            d[~pred.ok[self.rows]] = FAILED_RESIDUAL
            parts.append(d[seen])
        return np.concatenate(parts) if parts else np.zeros(0)

    def jacobian(self, pred: Prediction) -> np.ndarray:
        """d residual / d theta (n_res, P)."""
        n_par = pred.d_tip.shape[-1]
        parts = []
        if self.tip_rows.size:
            j = pred.d_tip[self.tip_rows] / self.scales["tip"]
            j[~pred.ok[self.tip_rows]] = 0.0
            parts.append(j.reshape(-1, n_par))
        if self.marker_seen is not None:
            j = pred.d_markers[self.rows] / self.scales["markers"]
            j[~pred.ok[self.rows]] = 0.0
            parts.append(j[self.marker_seen].reshape(-1, n_par))
        for q, d, _, seen in self._reaction_parts(pred, True):
            j = d[self.rows] / self.scales[q]
            j[~pred.ok[self.rows]] = 0.0
            parts.append(j[seen])
        return np.concatenate(parts) if parts else np.zeros((0, n_par))

    def position_errors_m2(self, pred: Prediction) -> float:
        """Sum of squared position errors (m^2) of the residual's entries."""
        total = 0.0
        if self.tip_rows.size:
            e = pred.tip[self.tip_rows] - self.observed.tip[self.tip_rows]
            total += float(np.sum(e**2))
        if self.marker_seen is not None:
            e = (pred.markers[self.rows] - self.observed.markers[self.rows])[self.marker_seen]
            total += float(np.sum(e**2))
        return total


@dataclass(frozen=True)
class Bounds:
    """Lower and upper bounds (SI) of every parameter, and which ones the user gave."""

    lower: np.ndarray
    upper: np.ndarray
    given: np.ndarray  # bool per parameter

    @property
    def any_given(self) -> bool:
        return bool(self.given.any())


class Problem:
    """Parameters, adapter, residual and bounds: residual(u) and its Jacobian in the
    optimisation variables u (log theta for positive parameters, theta otherwise)."""

    def __init__(self, adapter: ModelAdapter, residual: Residual, bounds: Bounds):
        self.adapter = adapter
        self.residual = residual
        self.bounds = bounds
        self.positive = np.array([p.positive for p in adapter.parameters], dtype=bool)

    @property
    def parameters(self) -> tuple:
        return self.adapter.parameters

    def theta_of(self, u: np.ndarray) -> np.ndarray:
        # A step along an unidentifiable direction may overflow exp: inf lies outside the
        # bounds, so the point counts as failed and the optimiser steps back.
        with np.errstate(over="ignore"):
            return np.where(self.positive, np.exp(np.where(self.positive, u, 0.0)), u)

    def u_of(self, theta: np.ndarray) -> np.ndarray:
        theta = np.asarray(theta, dtype=float)
        return np.where(self.positive, np.log(np.where(self.positive, theta, 1.0)), theta)

    def inside(self, theta: np.ndarray) -> bool:
        return bool(np.all((theta >= self.bounds.lower) & (theta <= self.bounds.upper)))

    def predict(self, theta, jacobian: bool) -> Prediction:
        return self.adapter.predict(theta, self.residual.rows, jacobian)
