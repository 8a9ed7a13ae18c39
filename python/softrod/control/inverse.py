"""Inverse statics: the chamber pressures and tendon tensions, within bounds, that bring a
point of the rod to a target (docs/control.md). The solver lives in the Rust core
(``softrod_core::inverse``: projected Levenberg-Marquardt solved jointly with the
equilibrium, exact Jacobians); this module reads the arguments once (units, bounds,
weights) and packs the answer.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .._types import ArrayLike, DesignLike, Quantity

import math
import re
from dataclasses import dataclass, field

import numpy as np

from .. import _core
from .. import _validate as V
from .._validate import integer, real
from ..catalog import load_design
from ..constraints import require_free_tip
from ..design import Design
from ..errors import InputError, design_error
from ..solution import StaticSolution, _inputs
from ..units import to_si

__all__ = [
    "InverseProblem",
    "InverseSolution",
    "pressure_bounds",
    "solve_inverse",
    "tension_bounds",
]

_REGULARISATIONS = ("least_pressure", "previous")


def _quantity_list(value, kind: str, name: str, n: int) -> list[float]:
    """n quantities: a sequence (numbers in SI or strings with units) or one string such as
    "10,5,-130 mm" (a unit after the last entry applies to the bare numbers before it)."""
    if isinstance(value, str):
        parts = [p.strip() for p in value.split(",")]
        if len(parts) != n:
            raise design_error(
                name, value, f"must hold {n} comma-separated {kind} values", InputError
            )
        m = re.fullmatch(r"([-+0-9.eE]+)\s*(\S.*)", parts[-1])
        unit = m.group(2) if m and not _is_number_text(parts[-1]) else ""
        items = [f"{p} {unit}" if unit and _is_number_text(p) else p for p in parts[:-1]]
        items.append(parts[-1])
        return [
            to_si(v if not _is_number_text(v) else float(v), kind, f"{name}[{i}]", InputError)
            for i, v in enumerate(items)
        ]
    if isinstance(value, np.ma.MaskedArray):
        # (real_array's rule: the hidden values would be used.)
        V.real_array(value, name)
    if isinstance(value, np.ndarray) and value.dtype.kind in "fiu":
        arr = value.astype(float).ravel()
        if arr.size != n or not np.all(np.isfinite(arr)):
            raise design_error(
                name, value.tolist(), f"must be {n} finite {kind} values (SI)", InputError
            )
        return arr.tolist()
    try:
        items = list(value)
    except TypeError:
        raise design_error(name, value, f"must be {n} {kind} values", InputError) from None
    if len(items) != n:
        raise design_error(name, value, f"must be {n} {kind} values", InputError)
    return [to_si(v, kind, f"{name}[{i}]", InputError) for i, v in enumerate(items)]


def _is_number_text(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _input_bounds(
    design: Design,
    bounds,
    *,
    name: str,
    kind: str,
    unit: str,
    n: int,
    range_key: str,
    example: str,
    what: str,
) -> np.ndarray:
    """Per-input [lo, hi] (SI) of ``n`` inputs of one kind from ``bounds``: None (the
    design's operating range), a pair (every input), one pair per input, or a string
    "lo:hi unit"."""
    if n == 0:
        # (An empty array is what this function returns for no inputs: accept it back.)
        if bounds is not None and (isinstance(bounds, str) or np.size(bounds) != 0):
            raise design_error(
                name, bounds, f"design {design.name!r} has no {what}; leave {name} out", InputError
            )
        return np.zeros((0, 2))
    if bounds is None:
        rng = (design.spec.get("operating_range") or {}).get(range_key)
        if rng is None:
            raise design_error(
                name,
                None,
                f"design {design.name!r} has no [operating_range] {range_key}: give the "
                f"range the actuator may use, e.g. {example}",
                InputError,
            )
        return np.tile(np.asarray(rng, dtype=float), (n, 1))
    if isinstance(bounds, str):
        m = re.fullmatch(r"\s*([-+0-9.eE]+)\s*:\s*([-+0-9.eE]+)\s*(\S.*)?", bounds)
        if m is None:
            raise design_error(
                name, bounds, f"must read 'lo:hi unit', e.g. '0:70 {unit}'", InputError
            )
        text_unit = m.group(3) or ""
        if not text_unit:
            raise design_error(name, bounds, f"needs a unit, e.g. '0:70 {unit}'", InputError)
        pair = [to_si(f"{m.group(k)} {text_unit}", kind, name, InputError) for k in (1, 2)]
        out = np.tile(np.asarray(pair), (n, 1))
    else:
        arr = np.asarray(bounds, dtype=object)
        if arr.shape == (2,):
            pair = [to_si(v, kind, f"{name}[{i}]", InputError) for i, v in enumerate(arr)]
            out = np.tile(np.asarray(pair, dtype=float), (n, 1))
        elif arr.shape == (n, 2):
            out = np.array(
                [
                    [to_si(v, kind, f"{name}[{c}][{i}]", InputError) for i, v in enumerate(row)]
                    for c, row in enumerate(arr)
                ]
            )
        else:
            raise design_error(
                name,
                bounds,
                f"must be (lo, hi) for every channel or one (lo, hi) per channel ({n})",
                InputError,
            )
    for c, (lo, hi) in enumerate(out):
        if lo > hi:
            raise design_error(f"{name}[{c}]", (lo, hi), "lo must be <= hi", InputError)
    return out


def pressure_bounds(design: Design, bounds) -> np.ndarray:
    """Per-channel [lo, hi] in Pa from ``bounds``: None (the design's operating range), a
    pair (every channel), one pair per channel, or a string "lo:hi unit" such as
    "0:70 kPa". A design without chambers has none: (0, 2). Raises InputError naming the
    rule."""
    return _input_bounds(
        design,
        bounds,
        name="pressure_bounds",
        kind="pressure",
        unit="kPa",
        n=design.n_channels,
        range_key="pressure",
        example="pressure_bounds=(0, 70e3) or '0:70 kPa'",
        what="pressure channels",
    )


def tension_bounds(design: Design, bounds) -> np.ndarray:
    """Per-tendon [lo, hi] in N, like :func:`pressure_bounds` (default: the design's
    ``[operating_range] tension``). A tendon only pulls: lo >= 0, and lo = 0 lets it go
    slack. A design without tendons has none: (0, 2)."""
    out = _input_bounds(
        design,
        bounds,
        name="tension_bounds",
        kind="force",
        unit="N",
        n=design.n_tendons,
        range_key="tension",
        example="tension_bounds=(0, 20) or '0:20 N'",
        what="tendons",
    )
    for k, (lo, _) in enumerate(out):
        if lo < 0.0:
            raise design_error(
                f"tension_bounds[{k}]",
                tuple(out[k]),
                "a tendon can only pull: the lower bound must be >= 0 N (0 lets it go slack)",
                InputError,
            )
    return out


def _weights(weights, orientation: bool) -> tuple[list[float], float]:
    if weights is None:
        return [1.0, 1.0, 1.0], 1.0 if orientation else 0.0
    if not isinstance(weights, dict) or set(weights) - {"position", "orientation"}:
        raise design_error(
            "weights",
            weights,
            "must be a dict with 'position' (a number or 3 numbers: the weight of each "
            "component's error in rod lengths) and/or 'orientation' (the weight of the angle "
            "in rad)",
            InputError,
        )
    pos = weights.get("position", 1.0)
    pos = [pos] * 3 if not isinstance(pos, (list, tuple, np.ndarray)) else list(pos)
    if len(pos) != 3:
        raise design_error("weights.position", pos, "must be a number or 3 numbers", InputError)
    out = [real(w, f"weights.position[{i}]", minimum=0.0) for i, w in enumerate(pos)]
    wo = real(
        weights.get("orientation", 1.0 if orientation else 0.0), "weights.orientation", minimum=0.0
    )
    return out, float(wo)


@dataclass(frozen=True)
class InverseSolution:
    """The answer of an inverse solve (SI).

    pressures (c,) Pa, within the bounds; tensions (k,) N, the tendon tensions within
    ``tension_bounds`` (empty without tendons; 0 is a slack tendon); reached: the target
    was reached to ``tol``; distance (m): from the point to the target position; angle
    (rad): to the target orientation (NaN without one); active (c,) and tension_active
    (k,): -1 at the lower bound, +1 at the upper, 0 inside; point_position (3,),
    point_rotation (3, 3): the pose of the point at arc length ``point``; tip_position,
    tip_rotation: the tip's; stable: the equilibrium's stability (an unstable one is
    refused unless ``on_unstable`` says otherwise); violations: the validity-range
    violations accepted with ``on_invalid="warn"``. ``statics()`` gives the full
    equilibrium (shape, forces) as a :class:`StaticSolution`; pass the solution as
    ``initial=`` to warm-start the next inverse.
    """

    design: Design
    pressures: np.ndarray
    reached: bool
    distance: float
    angle: float
    active: np.ndarray
    point: float
    point_position: np.ndarray
    point_rotation: np.ndarray
    tip_position: np.ndarray
    tip_rotation: np.ndarray
    target_position: np.ndarray
    target_orientation: np.ndarray | None
    bounds: np.ndarray
    cost: float
    iterations: int
    passes: int
    shooting_unknowns: np.ndarray = field(repr=False)
    stable: bool = True
    violations: tuple[str, ...] = ()
    tip_force: tuple = field(default=(0.0, 0.0, 0.0), repr=False)
    tip_moment: tuple = field(default=(0.0, 0.0, 0.0), repr=False)
    tensions: np.ndarray = field(default_factory=lambda: np.zeros(0))
    tension_active: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    tension_bounds: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)), repr=False)
    #: The collocation unknowns z of the equilibrium when statics solves this design by
    #: collocation (a long, soft rod), None otherwise: :meth:`statics` starts there.
    collocation_unknowns: np.ndarray | None = field(default=None, repr=False, compare=False)

    def __repr__(self) -> str:
        parts = _inputs(self.design.name, self.pressures, self.tensions)
        reached = "reached" if self.reached else "not reached"
        parts.append(f"{reached}, {self.distance * 1e3:.3g} mm from the target")
        return f"InverseSolution({', '.join(parts)})"

    def _warm_start(self, model: str) -> list[float]:
        """This equilibrium's unknowns, to warm-start a solve (statics' ``initial``): its
        collocation unknowns when collocation solved it, else its shooting unknowns."""
        if model != "cosserat":
            raise V.fail("initial", "an InverseSolution", "warm-starts the Cosserat model only")
        if self.collocation_unknowns is not None:
            return [float(v) for v in self.collocation_unknowns]
        return [float(v) for v in self.shooting_unknowns]

    def statics(self) -> StaticSolution:
        """The equilibrium under these pressures, tensions and tip loads (shape, forces,
        strains)."""
        from ..statics import solve_statics

        return solve_statics(
            self.design,
            self.pressures,
            tensions=self.tensions if self.design.n_tendons else None,
            tip_force=self.tip_force,
            tip_moment=self.tip_moment,
            initial=self,
        )

    def summary(self) -> str:
        mm = ", ".join(f"{v * 1e3:.3f}" for v in self.point_position)
        where = (
            "tip"
            if self.point >= self.design.length * (1 - 1e-12)
            else f"point s = {self.point * 1e3:.2f} mm"
        )
        state = "reached" if self.reached else "NOT reached (closest pose in the bounds)"
        lines = []
        if len(self.pressures):
            kpa = ", ".join(f"{p / 1e3:.3f}" for p in self.pressures)
            lines.append(f"pressures: [{kpa}] kPa")
        if len(self.tensions):
            n = ", ".join(f"{t:.4f}" for t in self.tensions)
            lines.append(f"tensions: [{n}] N")
        lines += [
            f"{where}: [{mm}] mm",
            f"target {state}; distance {self.distance * 1e3:.3g} mm",
        ]
        if not math.isnan(self.angle):
            lines.append(f"angle to the target orientation: {math.degrees(self.angle):.3g} deg")
        at = [f"p{c} {'lower' if a < 0 else 'upper'}" for c, a in enumerate(self.active) if a]
        at += [
            f"t{k} {'lower (slack)' if a < 0 else 'upper'}"
            for k, a in enumerate(self.tension_active)
            if a
        ]
        lines.append("bounds active: " + (", ".join(at) if at else "none"))
        return "\n".join(lines)


class InverseProblem:
    """An inverse-statics problem of one design, set up once and solved for many targets
    (the fast path for control loops: arguments are read and checked here, not per call).
    The inputs are the design's pressure channels and its tendon tensions.

    - ``pressure_bounds``: per-channel [lo, hi] (Pa or strings with units, or "0:70 kPa");
      default: the design's ``[operating_range] pressure`` (required when it has chambers
      and no range).
    - ``tension_bounds``: per-tendon [lo, hi] (N or strings with units, or "0:20 N"), lo >= 0
      (a tendon only pulls; at lo = 0 it may go slack); default: the design's
      ``[operating_range] tension`` (required when it has tendons and no range). (0, 0)
      holds the tendons slack.
    - ``point``: arc length of the point that should reach the target (m or "65 mm");
      default the tip.
    - ``weights``: {"position": w or (wx, wy, wz), "orientation": w}: the cost is
      1/2 sum (w_i e_i)^2 with position errors in rod lengths and the orientation error in
      rad (a weight 0 ignores a component). Default 1 for each.
    - ``orientation``: True when targets come with an orientation.
    - ``regularisation``: how redundant channels (more free channels than weighted task
      dimensions) are resolved: "least_pressure" (closest to the lower bounds clipped to 0:
      least pressure and least tension) or "previous" (closest to the warm start's inputs).
      Default: "previous" when a solve is warm-started, else "least_pressure".
    - ``tip_force`` / ``tip_moment``: the dead tip loads (default: the design's).
    - ``tol``: the target counts as reached within tol L (position) and tol rad.
    - ``on_invalid``: "raise" (default), "warn" or "ignore" for solutions outside the
      validity ranges (strains, operating range); physical rules always raise.
    - ``on_unstable``: "raise" (default: an unstable equilibrium is never returned as an
      answer, :class:`InvalidStateError` with rule "stability"), "warn" or "ignore".
    """

    def __init__(
        self,
        design: DesignLike,
        *,
        pressure_bounds: ArrayLike | str | None = None,
        tension_bounds: ArrayLike | str | None = None,
        point: Quantity | None = None,
        weights: dict[str, Any] | None = None,
        regularisation: str | None = None,
        orientation: bool = False,
        tip_force: ArrayLike | None = None,
        tip_moment: ArrayLike | None = None,
        tol: float = 1e-10,
        max_iter: int = 100,
        on_invalid: str = "raise",
        on_unstable: str = "raise",
    ):
        from ..statics import _policy, _vec3

        self.design: Design = load_design(design)
        require_free_tip(self.design, "solve_inverse")
        d = self.design
        if d.n_channels == 0 and d.n_tendons == 0:
            raise design_error(
                "design", d.name, "has neither pressure channels nor tendons to invert", InputError
            )
        self.bounds = globals()["pressure_bounds"](d, pressure_bounds)
        self.tension_bounds = globals()["tension_bounds"](d, tension_bounds)
        inputs = np.vstack([self.bounds, self.tension_bounds])
        self.point = d.length if point is None else to_si(point, "length", "point", InputError)
        if not (0.0 <= self.point <= d.length * (1 + 1e-12)):
            raise design_error(
                "point", point, f"must lie on the rod: 0 <= s <= L = {d.length} m", InputError
            )
        if regularisation is not None and not (
            isinstance(regularisation, str) and regularisation in _REGULARISATIONS
        ):
            raise design_error(
                "regularisation",
                regularisation,
                "must be 'least_pressure' or 'previous'",
                InputError,
            )
        self.regularisation = regularisation
        self.orientation = V.boolean(orientation, "orientation")
        self.weights = _weights(weights, self.orientation)
        tip = d.spec["tip"]
        self.tip_force = tuple(_vec3(tip_force, "force", "tip_force", tip["force"]))
        self.tip_moment = tuple(_vec3(tip_moment, "moment", "tip_moment", tip["moment"]))
        tol = real(tol, "tol", minimum=0.0, exclusive=True, maximum=0.1)
        max_iter = integer(max_iter, "max_iter", minimum=1, maximum=10_000)
        self.on_unstable = _policy("on_unstable", on_unstable)
        self._least = np.clip(0.0, inputs[:, 0], inputs[:, 1])
        self._inputs = inputs
        self._solver = _core.InverseSolver(
            d._rod,
            inputs.tolist(),
            self._least.tolist(),
            float(self.point),
            self.weights[0],
            self.weights[1],
            list(self.tip_force),
            list(self.tip_moment),
            tol=float(tol),
            max_iter=int(max_iter),
            on_invalid=_policy("on_invalid", on_invalid),
        )

    def solve(
        self,
        target: ArrayLike | str,
        *,
        orientation: ArrayLike | None = None,
        initial: InverseSolution | StaticSolution | ArrayLike | None = None,
    ) -> InverseSolution:
        """Pressures and tensions that bring the point to ``target`` (3 positions: m,
        strings with units, or "10,5,-130 mm") and, when given, to ``orientation`` (a 3x3
        rotation [d1 d2 d3]).

        ``initial``: a previous :class:`InverseSolution` or :class:`StaticSolution` (warm
        start: its pressures, tensions and its equilibrium's unknowns, the collocation
        unknowns of a long, soft rod's included), or the start inputs: the pressures (Pa)
        followed by the tensions (N), one per channel.
        """
        # The fast path of a warm loop: a plain float array (not a masked one, whose hidden
        # values tolist() turns into None).
        if type(target) is np.ndarray and target.dtype == float and target.shape == (3,):
            position = target.tolist()
            if not all(map(math.isfinite, position)):
                raise design_error("target", position, "must be finite (m)", InputError)
        else:
            position = _quantity_list(target, "length", "target", 3)
        rot = None
        if orientation is not None:
            if type(orientation) is np.ndarray and orientation.dtype == float:
                rot = orientation  # the warm loop's fast path, as the target's
            else:
                rot = V.real_array(orientation, "orientation", what="rotation matrix entries")
            if rot.shape != (3, 3) or not np.all(np.isfinite(rot)):
                raise design_error(
                    "orientation", orientation, "must be a finite 3x3 rotation matrix", InputError
                )
        elif self.orientation:
            raise design_error(
                "orientation",
                None,
                "this problem was built with orientation=True: give a target rotation",
                InputError,
            )
        if rot is not None and not self.orientation:
            raise design_error(
                "orientation",
                "given",
                "this problem was built for positions only: build it with orientation=True",
                InputError,
            )
        x = None
        z = None
        nc, nt = self.design.n_channels, self.design.n_tendons
        if initial is None:
            u0 = self._least
        elif isinstance(initial, (InverseSolution, StaticSolution)):
            t0 = np.asarray(initial.tensions, dtype=float)
            u0 = np.concatenate(
                [np.asarray(initial.pressures, dtype=float), t0 if t0.size else np.zeros(nt)]
            )
            x = np.asarray(initial.shooting_unknowns, dtype=float).tolist()
            if not all(map(math.isfinite, x)):
                x = None
            elif initial.collocation_unknowns is not None:
                # A long, soft rod: its equilibrium starts from z (x does not determine it).
                z = initial.collocation_unknowns.tolist()
        else:
            u0 = V.real_array(initial, "initial", what="pressures (Pa) and tensions (N)")
        # (math.isfinite over a list: a warm call's checks cost microseconds at 10 kHz.)
        if u0.shape != (nc + nt,) or not all(map(math.isfinite, u0.tolist())):
            what = (
                f"{nc} finite pressures (Pa)"
                if nt == 0
                else f"{nc} pressures (Pa) then {nt} tensions (N), all finite"
            )
            raise design_error("initial", initial, f"must be a solution or {what}", InputError)
        mode = self.regularisation or ("previous" if x is not None else "least_pressure")
        reference = None
        if mode == "previous":
            if initial is None:
                raise design_error(
                    "regularisation",
                    "previous",
                    "needs initial= (the previous command)",
                    InputError,
                )
            reference = np.clip(u0, self._inputs[:, 0], self._inputs[:, 1]).tolist()
        out = self._solver.solve(
            position,
            u0[:nc].tolist(),
            u0[nc:].tolist(),
            orientation=None if rot is None else rot.tolist(),
            x=x,
            reference=reference,
            z=z,
        )
        if out["violations"]:
            import warnings

            from ..errors import ValidityWarning

            for message in out["violations"]:
                warnings.warn(ValidityWarning(message), stacklevel=2)
        if not out["stable"]:
            from ..statics import _report_stability

            kpa = ", ".join(f"{p / 1e3:.6g}" for p in out["pressures"])
            n = ", ".join(f"{t:.6g}" for t in out["tensions"])
            at = f"pressures [{kpa}] kPa" + (f", tensions [{n}] N" if nt else "")
            _report_stability(False, self.on_unstable, f"the inverse's answer at {at}")
        return InverseSolution(
            design=self.design,
            pressures=np.array(out["pressures"]),
            reached=bool(out["reached"]),
            distance=float(out["distance"]),
            angle=float(out["angle"]),
            active=np.array(out["active"][:nc], dtype=int),
            point=float(self.point),
            point_position=np.array(out["point_position"]),
            point_rotation=np.array(out["point_rotation"]),
            tip_position=np.array(out["tip_position"]),
            tip_rotation=np.array(out["tip_rotation"]),
            target_position=np.array(position),
            target_orientation=rot,
            bounds=self.bounds,
            cost=float(out["cost"]),
            iterations=int(out["iterations"]),
            passes=int(out["passes"]),
            shooting_unknowns=np.array(out["x"]),
            collocation_unknowns=out["collocation_unknowns"],
            tip_force=self.tip_force,
            tip_moment=self.tip_moment,
            stable=bool(out["stable"]),
            violations=tuple(out["violations"]),
            tensions=np.array(out["tensions"], dtype=float),
            tension_active=np.array(out["active"][nc:], dtype=int),
            tension_bounds=self.tension_bounds,
        )


def solve_inverse(
    design: DesignLike,
    target: ArrayLike | str,
    *,
    weights: dict[str, Any] | None = None,
    pressure_bounds: ArrayLike | str | None = None,
    tension_bounds: ArrayLike | str | None = None,
    initial: InverseSolution | StaticSolution | ArrayLike | None = None,
    point: Quantity | None = None,
    orientation: ArrayLike | None = None,
    regularisation: str | None = None,
    tip_force: ArrayLike | None = None,
    tip_moment: ArrayLike | None = None,
    tol: float = 1e-10,
    max_iter: int = 100,
    on_invalid: str = "raise",
    on_unstable: str = "raise",
) -> InverseSolution:
    """The chamber pressures within ``pressure_bounds`` and tendon tensions within
    ``tension_bounds`` that bring the tip (or the point at arc length ``point``) of
    ``design`` to ``target``, and to ``orientation`` when given.

    A target that cannot be reached gives the closest pose inside the bounds with
    ``reached=False`` and the ``distance`` left (a local minimum of the distance; cold
    starts begin from the best of the start, the box's centre and, up to 4 channels, its
    corners). The returned equilibrium is converged and checked against the validity
    rules. See :class:`InverseProblem` for the arguments; for many targets in a loop,
    build the problem once and call its ``solve``.
    """
    problem = InverseProblem(
        design,
        pressure_bounds=pressure_bounds,
        tension_bounds=tension_bounds,
        point=point,
        weights=weights,
        regularisation=regularisation,
        orientation=orientation is not None,
        tip_force=tip_force,
        tip_moment=tip_moment,
        tol=tol,
        max_iter=max_iter,
        on_invalid=on_invalid,
        on_unstable=on_unstable,
    )
    return problem.solve(target, orientation=orientation, initial=initial)
