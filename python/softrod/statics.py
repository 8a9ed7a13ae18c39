"""Static equilibria: ``solve_statics`` and ``solve_statics_batch``.

Model (``Design``), method (solver options) and result (``StaticSolution``) are separate.
All inputs and outputs are SI: pressures in Pa (gauge), one per channel.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from . import _core
from . import _validate as V
from .catalog import load_design
from .constraints import TipConstraint
from .constraints import coerce as coerce_constraint
from .design import Design
from .errors import (
    ConvergenceError,
    InputError,
    InvalidStateError,
    StabilityWarning,
    ValidityWarning,
    design_error,
)
from .solution import BatchSolution, Contact, StaticSolution
from .stiffness_map import StiffnessMap, _check_pressure_rows

if TYPE_CHECKING:
    from ._types import ArrayLike, DesignLike, Progress


@dataclass(frozen=True)
class SolverOptions:
    """Settings of the shooting solver.

    tol: convergence tolerance on the scaled tip-wrench residual (relative, see docs).
    max_iter: Newton iterations per load level.
    continuation: ramp pressures, gravity and loads from zero (the natural path) when Newton
        fails or lands on an unstable equilibrium.
    max_load_steps: most load levels continuation may take.
    stretch_range: (min, max) validity range of the fibre stretch (docs/model.md, "Validity
        and stability"); a solution outside it is refused, or warned about with
        ``on_invalid="warn"``.
    friction_steps: equal load increments of a frictional static solve (an obstacle with
        friction > 0; docs/contact.md, "Friction in the statics"), each halved while it
        fails (down to 1/1024 of it, or of 1/80 of the path when fewer are requested). The
        answer depends on the increment size to first order; 80 leaves about 1 % of the
        friction force of the bundled finger example.
    """

    tol: float = 1e-10
    max_iter: int = 25
    continuation: bool = True
    max_load_steps: int = 200
    stretch_range: tuple[float, float] = (1 / 3, 3.0)
    friction_steps: int = 80

    def __post_init__(self):
        tol = V.real(self.tol, "tol", minimum=0.0, exclusive=True)
        if not tol < 1:
            raise design_error("tol", self.tol, "must be in (0, 1)", InputError)
        for name in ("max_iter", "max_load_steps", "friction_steps"):
            V.integer(getattr(self, name), name, minimum=1, maximum=V.MAX_ITERATIONS)
        V.boolean(self.continuation, "continuation")
        r = self.stretch_range
        rule = "must be (min, max) with 0 < min < 1 < max (stretch 1 is the reference state)"
        if isinstance(r, str) or not isinstance(r, tuple | list) or len(r) != 2:
            raise design_error("stretch_range", r, rule, InputError)
        lo = V.real(r[0], "stretch_range[0]")
        hi = V.real(r[1], "stretch_range[1]")
        if not 0 < lo < 1 < hi:
            raise design_error("stretch_range", r, rule, InputError)

    def as_kwargs(self) -> dict:
        return {
            "tol": float(self.tol),
            "max_iter": int(self.max_iter),
            "continuation": bool(self.continuation),
            "max_load_steps": int(self.max_load_steps),
            "stretch_range": (float(self.stretch_range[0]), float(self.stretch_range[1])),
        }


# Frozen, so one validated instance serves every call that passes no options (validating a
# fresh one cost a fifth of a warm solve_statics).
_DEFAULT_OPTIONS = SolverOptions()
_FREE_TIP = TipConstraint()
# sigma = 1 of a design without mapped sections, shared (read-only) by the solutions.
_UNIT_SCALE = np.ones(3)
_UNIT_SCALE.flags.writeable = False

_POLICIES = ("raise", "warn", "ignore")


def _policy(name: str, value) -> str:
    if not isinstance(value, str) or value not in _POLICIES:
        raise design_error(name, value, "must be 'raise', 'warn' or 'ignore'", InputError)
    return value


def _report_stability(stable: bool | None, on_unstable: str, what: str) -> None:
    """Warn about (or raise for) an unstable equilibrium, as ``on_unstable`` says. None:
    stability was not assessed (follower loads are not conservative, docs/scope.md; friction
    has no potential, docs/contact.md)."""
    if stable is None or stable or on_unstable == "ignore":
        return
    message = (
        f"{what} is an unstable equilibrium (the second variation of the energy is not positive "
        "definite: a small disturbance moves the rod away; docs/model.md, 'Validity and "
        "stability'). Above a buckling load add the imperfection that decides the side (a "
        "small lateral force; near the buckling load a tiny one may not be enough for the "
        "load path to follow it: a larger one, or initial= a stable solution at a nearby "
        "load), or pass on_unstable='ignore'"
    )
    if on_unstable == "raise":
        raise InvalidStateError(message, rule="stability")
    warnings.warn(StabilityWarning(message), stacklevel=3)


def _pressures(design: Design, pressures) -> list[float]:
    """One gauge pressure per channel (Pa, or strings with units), checked like a batch row."""
    if V.is_real(pressures) or isinstance(pressures, str):
        pressures = [pressures]
    return _quantities(
        pressures,
        "pressure",
        "pressures",
        design.n_channels,
        f"the design has {design.n_channels} pressure channels; give one gauge "
        "pressure per channel",
    )


def _quantities(value, kind: str, name: str, count: int, rule: str) -> list[float]:
    """``count`` quantities from a list/tuple (numbers in SI or strings with units) or a 1-d
    numeric array; mappings, sets, masked arrays, bools and complex numbers are refused."""
    if isinstance(value, (list, tuple)):
        if len(value) != count:
            raise V.fail(name, value, rule)
        # Plain finite floats and safe ints are SI as they are (what V.quantity returns for
        # them); anything else (strings with units, numpy scalars, bools) takes the full path.
        plain = [_plain_float(x) for x in value]
        if None not in plain:
            return plain
        return [V.quantity(x, kind, f"{name}[{i}]") for i, x in enumerate(value)]
    arr = V.real_array(value, name, what=f"{kind}s (SI)", max_size=V.MAX_CHANNELS * 4)
    if arr.ndim != 1 or arr.size != count:
        raise V.fail(name, f"shape {arr.shape}", rule)
    return arr.tolist()


def _reaction(out: dict, key: str) -> np.ndarray:
    """A constrained tip's reaction from the core's result; zeros for a free tip."""
    return np.array(out[key]) if key in out else np.zeros(3)


def _plain_float(x) -> float | None:
    """``x`` as a float when it is a finite Python float or an int within 2^53, else None."""
    t = type(x)
    if t is float:
        return x if math.isfinite(x) else None
    if t is int and -V.MAX_ABS_INT <= x <= V.MAX_ABS_INT:
        return float(x)
    return None


def _vec3(value, kind: str, name: str, default) -> list[float]:
    if value is None:
        return list(default)
    return _quantities(value, kind, name, 3, f"must be 3 {kind} values (in the design's tip frame)")


def _tensions(design: Design, tensions) -> list[float]:
    """One tendon tension per tendon channel (N, or strings with units), each finite and
    >= 0 (a tendon pulls or is slack: it cannot push). None: every tendon slack."""
    n = design.n_tendons
    if tensions is None:
        return [0.0] * n
    if n == 0:
        raise V.fail(
            "tensions",
            tensions,
            f"design {design.name!r} has no tendons ([[sections.tendons]]); leave tensions out",
        )
    if V.is_real(tensions) or isinstance(tensions, str):
        tensions = [tensions]
    out = _quantities(
        tensions,
        "force",
        "tensions",
        n,
        f"the design has {n} tendon channel(s); give one tension per channel",
    )
    _check_tension_values(np.asarray(out), "tensions")
    return out


def _check_tension_values(arr: np.ndarray, name: str) -> None:
    bad = np.flatnonzero(~(arr.reshape(-1) >= 0.0))
    if bad.size:
        k = int(bad[0])
        if arr.ndim <= 1:
            where = f"{name}[{k}]"
        else:
            where = f"{name}[{k // arr.shape[1]}, {k % arr.shape[1]}]"
        raise V.fail(
            where,
            f"{float(arr.reshape(-1)[k])!r} N",
            "a tendon tension must be >= 0 (a tendon pulls or is slack, it cannot push)",
        )


def batch_tensions(design: Design, tensions, rows: int) -> np.ndarray | None:
    """An (m, tendon channels) float array of tensions (N, each >= 0), or None (slack)."""
    if tensions is None:
        return None
    n = design.n_tendons
    if n == 0:
        raise V.fail(
            "tensions",
            "an array",
            f"design {design.name!r} has no tendons ([[sections.tendons]]); leave tensions out",
        )
    arr = V.real_array(tensions, "tensions", unit_kind="force", max_size=V.MAX_ROWS * max(n, 1))
    if arr.ndim == 1 and n == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape != (rows, n):
        raise V.fail(
            "tensions",
            f"shape {arr.shape}",
            f"must be ({rows}, {n}): one row per pressure row, one column per tendon channel",
        )
    _check_tension_values(arr, "tensions")
    return np.ascontiguousarray(arr, dtype=float)


def _n_unknowns(design: Design, tf, tm) -> int:
    """Shooting unknowns of a solve: 6 with follower loads or obstacles (base force
    unknown), else 3."""
    spec = design.spec
    if spec.get("obstacles"):
        return 6
    tip_body = spec["tip"].get("frame") == "body" and any(v != 0 for v in [*tf, *tm])
    line_body = any(
        ld.get("frame") == "body"
        and any(v != 0 for v in [*ld["force_per_length"], *ld["moment_per_length"]])
        for ld in spec["loads"]
    )
    return 6 if tip_body or line_body else 3


def _initial(initial, model: str) -> list[float] | None:
    """The warm start of ``initial``: any result that knows its equilibrium's shooting
    unknowns (a converged StaticSolution, or an InverseSolution) through ``_warm_start``, so
    this layer needs no import of the layers above it."""
    if initial is None:
        return None
    warm_start = getattr(initial, "_warm_start", None)
    if warm_start is None:
        raise V.fail(
            "initial",
            type(initial).__name__,
            "must be a StaticSolution, an InverseSolution or None",
        )
    return warm_start(model)


def _options(options: SolverOptions | None) -> SolverOptions:
    if options is None:
        return _DEFAULT_OPTIONS
    if not isinstance(options, SolverOptions):
        raise design_error("options", options, "must be a softrod.SolverOptions", InputError)
    return options


def _stiffness_map(design: Design, stiffness_map) -> StiffnessMap | None:
    """The map to use, or None for a design without mapped sections."""
    mapped = design.mapped_sections
    if stiffness_map is None:
        if design.stiffness_map is not None:
            return design.stiffness_map  # the design file's [stiffness_map]
        if mapped:
            raise design_error(
                "stiffness_map",
                None,
                f"section(s) {', '.join(mapped)} of design {design.name!r} set [sections.law] "
                "stiffness_map = true: pass stiffness_map=, a softrod.StiffnessMap (e.g. "
                "StiffnessMap.from_table or from_csv; sigma is never assumed to be 1), or "
                'reference a map file in the design ([stiffness_map] file = "sigma.json")',
                InputError,
            )
        return None
    if not isinstance(stiffness_map, StiffnessMap):
        raise design_error(
            "stiffness_map",
            type(stiffness_map).__name__,
            "must be a softrod.StiffnessMap (build one with StiffnessMap.from_table, "
            "from_csv, from_callable or from_regressor)",
            InputError,
        )
    if not mapped:
        raise design_error(
            "stiffness_map",
            stiffness_map,
            f"design {design.name!r} has no section with [sections.law] stiffness_map = true, "
            "so the map would have no effect",
            InputError,
        )
    if stiffness_map.n_channels != design.n_channels:
        raise design_error(
            "stiffness_map",
            stiffness_map,
            f"takes {stiffness_map.n_channels} pressure channel(s), the design has "
            f"{design.n_channels}",
            InputError,
        )
    return stiffness_map


def solve_statics(
    design: DesignLike,
    pressures: ArrayLike | None = None,
    *,
    tip_force: ArrayLike | None = None,
    tip_moment: ArrayLike | None = None,
    options: SolverOptions | None = None,
    initial: StaticSolution | None = None,
    check: bool = True,
    stiffness_map: StiffnessMap | None = None,
    model: str = "cosserat",
    on_unstable: str = "warn",
    on_invalid: str = "raise",
    tensions: ArrayLike | None = None,
    tip_constraint: TipConstraint | str | dict | None = None,
    history: StaticSolution | None = None,
) -> StaticSolution:
    """Static shape of ``design`` under chamber ``pressures`` (Pa gauge, one per channel;
    None only for a design without chambers) and tendon ``tensions`` (N, one per tendon
    channel, each >= 0; None: slack).

    Friction (an obstacle with ``friction`` > 0; docs/contact.md, "Friction in the
    statics"): the equilibrium depends on the load path, so the solve follows one, in
    ``options.friction_steps`` equal load increments with elastic-slip Coulomb friction,
    from the unloaded rod, or with ``history`` (a frictional StaticSolution of the same
    design) from that solution's loads and friction state: pull, then
    ``solve_statics(design, p, history=pulled)`` to release. The answer depends on the
    increment size to first order; ``stable`` is None (friction has no potential) and
    ``friction_state`` carries the path on. A held (pinned or clamped) tip follows the
    same path, its prescribed pose moved in the same increments from where the path
    starts (the unloaded rod's tip, or ``history``'s held pose: a history continues with
    the same kind of tip) to ``tip_constraint``'s, the position on a straight line and the
    orientation on the geodesic: if the unloaded tip is not at the prescribed pose, moving
    it there is part of the loading. The rod model only (not ``model="pcc"``).

    tip_constraint: how the tip is held (a :class:`TipConstraint`, "free", or a mapping
    with ``type``, ``position``, ``orientation`` as the design file's ``[tip]`` keys);
    None: the design's (``[tip] constraint``, free by default). A pinned or clamped tip
    reports the wrench the constraint applies in ``tip_reaction_force`` and
    ``tip_reaction_moment``; its stability is assessed with the tip held (``stable``,
    ``on_unstable`` as for a free tip; None under follower line loads or a follower tip
    moment on a pin: docs/model.md, "End constraints"). With the design's obstacles the
    held tip's solution carries its ``contact`` report too, and the reaction is what the
    pose adds to the rounded end's contact force (docs/contact.md, "A held tip with
    obstacles").

    model: "cosserat" (the rod) or "pcc" (paper 003's piecewise-constant-curvature model,
    docs/pcc.md): the same design and inputs; its shape is the chain of arcs, its ``force``
    and ``moment`` are NaN (the PCC model does not resolve the internal wrench) and
    ``options.max_iter`` bounds its Newton iterations.

    tip_force / tip_moment (N, N m; in the design's tip frame: the world, or the tip's body
    frame with ``[tip] frame = "body"``, a follower load) replace the design's ``[tip]``
    force and moment when given; gravity and the tip body always act. Tendons, reference
    shapes, tapered sections and follower loads: docs/scope.md. ``initial`` warm-starts from a
    previous solution. On non-convergence raises :class:`ConvergenceError`, or with
    ``check=False`` returns a solution with ``converged=False`` and NaN arrays.
    ``stiffness_map`` (a :class:`StiffnessMap`) is needed exactly when a section sets
    ``[sections.law] stiffness_map = true``; it defaults to the map the design file
    references (``[stiffness_map] file = ...``, ``design.stiffness_map``), and one given here
    replaces it. It is evaluated once at ``pressures``.

    Every solution is checked before it is returned (docs/model.md, "Validity and
    stability"): a state that breaks a physical rule (a rotation that is not one, stretch
    <= 0, a collapsed chamber) raises :class:`InvalidStateError` naming the rule, the node
    and the value. ``on_invalid`` says what a solution outside the validity range does
    (fibre stretch beyond ``options.stretch_range``, pressures beyond the design's
    ``operating_range``): "raise" (default, :class:`InvalidStateError`), "warn"
    (:class:`ValidityWarning`, listed in ``violations``) or "ignore". ``stable`` says whether
    the equilibrium is stable; ``on_unstable`` says what an unstable one does: "warn"
    (default, :class:`StabilityWarning`), "raise" (:class:`InvalidStateError` with rule
    "stability") or "ignore". A cold start follows the natural path from zero load, so an
    upright column above its buckling load bends to the side a small lateral force pushes.
    """
    on_unstable = _policy("on_unstable", on_unstable)
    on_invalid = _policy("on_invalid", on_invalid)
    design = load_design(design)
    friction_at = design.frictional_obstacle
    state = _history(history, design, friction_at)
    if friction_at is not None and initial is not None:
        raise design_error(
            "initial",
            type(initial).__name__,
            f"obstacles[{friction_at}].friction > 0: a frictional solve follows its load "
            "path from the unloaded rod, not from a warm start; pass history= a frictional "
            "solution to continue a path from it",
            InputError,
        )
    if friction_at is not None and model == "pcc":
        raise design_error(
            f"obstacles[{friction_at}].friction",
            design.spec["obstacles"][friction_at]["friction"],
            "model='pcc' has no contact with friction (docs/contact.md); use model='cosserat'",
            InputError,
        )
    if pressures is None:
        # Only a design without chambers has nothing to state; a chambered one must say its
        # pressures (no silent zero).
        if design.n_channels:
            raise V.fail(
                "pressures",
                None,
                f"the design has {design.n_channels} pressure "
                "channels; give one gauge pressure per channel",
            )
        pressures = []
    p = _pressures(design, pressures)
    V.choice(model, ("cosserat", "pcc"), "model")
    V.boolean(check, "check")
    guess = _initial(initial, model)
    t = _tensions(design, tensions)
    constraint = (
        coerce_constraint(tip_constraint)
        if tip_constraint is not None
        else design.tip_constraint or _FREE_TIP
    )
    if model == "pcc" and constraint.kind != "free":
        raise design_error(
            "tip_constraint", constraint.kind, "model='pcc' solves a free tip only", InputError
        )
    if model == "pcc":
        if tensions is not None:
            raise design_error("tensions", tensions, "is not used by model='pcc'", InputError)
        if stiffness_map is not None:
            raise design_error(
                "stiffness_map", stiffness_map, "is not used by model='pcc'", InputError
            )
        from .pcc.statics import solve_pcc_statics

        return solve_pcc_statics(
            design,
            p,
            tip_force=tip_force,
            tip_moment=tip_moment,
            max_iter=_options(options).max_iter,
            initial=initial,
            check=check,
        )
    smap = _stiffness_map(design, stiffness_map)
    sigma = _UNIT_SCALE if smap is None else smap(np.array([p]))[0]
    tip = design.spec["tip"]
    tf = _vec3(tip_force, "force", "tip_force", tip["force"])
    tm = _vec3(tip_moment, "moment", "tip_moment", tip["moment"])
    opts = _options(options)
    try:
        if constraint.kind == "free":
            out = design._rod.solve(
                p,
                tf,
                tm,
                guess=guess,
                stiffness_scale=sigma.tolist(),
                on_invalid=on_invalid,
                tensions=t,
                friction_steps=int(opts.friction_steps),
                history=state,
                **opts.as_kwargs(),
            )
        else:
            kind, position, rotation = constraint.core_args()
            out = _core.solve_constrained_tip(
                design._rod,
                p,
                tf,
                tm,
                kind,
                position=position,
                rotation=rotation,
                guess=guess,
                stiffness_scale=sigma.tolist(),
                on_invalid=on_invalid,
                tensions=t,
                friction_steps=int(opts.friction_steps),
                history=state,
                **opts.as_kwargs(),
            )
        if out["stable"] is False:  # formatted only when there is something to report
            _report_stability(False, on_unstable, f"the solution at pressures {p} Pa")
    except ConvergenceError as exc:
        if check:
            raise
        return StaticSolution._failed(
            design,
            p,
            exc,
            _n_unknowns(design, tf, tm) if constraint.kind == "free" else 6,
            stiffness_scale=sigma,
            tensions=np.array(t),
            tip_constraint=constraint.kind,
        )
    for v in out["violations"]:
        warnings.warn(ValidityWarning(v), stacklevel=2)
    return StaticSolution(
        design=design,
        pressures=np.array(p),
        s=out["s"],
        section=out["section"],
        position=out["position"],
        rotation=out["rotation"],
        force=out["force"],
        moment=out["moment"],
        v=out["v"],
        u=out["u"],
        converged=True,
        iterations=out["iterations"],
        residual=out["residual"],
        load_steps=out["load_steps"],
        shooting_unknowns=np.array(out["x"]),
        collocation_unknowns=out["collocation_unknowns"],
        stiffness_scale=sigma,
        stiffness_map=smap,
        stable=None if out["stable"] is None else bool(out["stable"]),
        violations=tuple(out["violations"]),
        tip_loads=(tuple(tf), tuple(tm)),
        tensions=np.array(t),
        tip_constraint=constraint.kind,
        tip_reaction_force=_reaction(out, "tip_reaction_force"),
        tip_reaction_moment=_reaction(out, "tip_reaction_moment"),
        contact=Contact.from_core(out["contact"]) if "contact" in out else None,
        friction_state=out.get("friction_state"),
        tip_hold=None if constraint.kind == "free" else constraint.core_args(),
    )


def _history(history, design: Design, friction_at: int | None):
    """The friction state a frictional path continues from (``history=``), checked: a
    converged frictional StaticSolution of this design (the core checks the design and
    obstacles it was solved with again)."""
    if history is None:
        return None
    if not isinstance(history, StaticSolution):
        raise design_error(
            "history",
            type(history).__name__,
            "must be a frictional StaticSolution (from solve_statics) or None",
            InputError,
        )
    if friction_at is None:
        raise design_error(
            "history",
            history.design.name,
            f"design {design.name!r} has no obstacle with friction > 0: a frictionless "
            "equilibrium does not depend on the load path",
            InputError,
        )
    if history.friction_state is None:
        raise design_error(
            "history",
            history.design.name,
            "must be a converged frictional StaticSolution (its friction_state is None: "
            "frictionless, or failed)",
            InputError,
        )
    return history.friction_state


def solve_statics_batch(
    design: DesignLike,
    pressures: ArrayLike,
    *,
    tip_force: ArrayLike | None = None,
    tip_moment: ArrayLike | None = None,
    options: SolverOptions | None = None,
    threads: int = 0,
    stiffness_map: StiffnessMap | None = None,
    executor: Any = None,
    chunk_size: int | None = None,
    progress: Progress = None,
    on_unstable: str = "warn",
    on_invalid: str = "raise",
    tensions: ArrayLike | None = None,
    tip_constraint: TipConstraint | str | dict | None = None,
) -> BatchSolution:
    """Solve for every row of an (m, channels) pressure array (Pa) in parallel, with an
    optional (m, tendon channels) array of tendon ``tensions`` (N, >= 0; None: slack).

    tip_constraint: how the tip of every row is held, as in :func:`solve_statics` (a
    :class:`TipConstraint`, "free", or a mapping as the design file's ``[tip]`` keys); None:
    the design's (``[tip] constraint``, free by default). With a pinned or clamped tip every
    row is solved as :func:`solve_statics` solves it alone with that constraint (cold), so
    a row is bitwise equal to the single solve; ``tip_reaction_force`` (m, 3) N and
    ``tip_reaction_moment`` (m, 3) N m hold the wrench the constraint applies to each tip
    (world frame; zero moment when pinned, NaN on failed rows), ``x`` (m, 6) the unknowns,
    and ``stable`` the stability with the tip held (docs/model.md, "End constraints").

    Runs in Rust on ``threads`` cores (0 = all) with the GIL released. Every row is solved
    as :func:`solve_statics` solves it alone (cold), so a row is bitwise equal to the single
    solve whatever the thread count or chunking. Rows that fail to converge are kept with
    ``converged = False`` and NaN results.

    Friction (an obstacle with ``friction`` > 0; docs/contact.md, "Friction in the
    statics"): every row follows its own load path from the unloaded rod to its inputs in
    ``options.friction_steps`` increments, exactly as :func:`solve_statics` solves it alone
    (same increments, same halvings; no row starts from another's solution), so a row is
    bitwise equal to the single frictional solve. ``x`` is then (m, 6), ``stable`` False
    with ``stability_assessed`` False (friction has no potential), and ``contact_force``
    and ``friction_force`` (m, obstacles, 3) N hold each obstacle's resultant contact force
    and its tangential part (``StaticSolution.contact``'s ``total_force`` and
    ``friction_force``; NaN on failed rows). A row whose path fails is kept failed as any
    row. With a held tip (``tip_constraint``) every row's path also moves the held pose
    from the unloaded rod's tip to the prescribed one, as the single held frictional solve
    does, and the rows carry their tip reactions. ``stiffness_map`` as in :func:`solve_statics`,
    evaluated for every row as the single solve evaluates it (tables, constants and
    networks in one call for all rows, each row's bits its own; regressors and callables
    one row at a time, since softrod cannot know that their rows do not round differently
    in a block).

    ``stable`` (m,) says which equilibria are stable (``stability_assessed`` (m,) is False
    where it was not assessed: follower loads) and ``violation`` (m,) which validity
    rule a row broke ("" if none). ``on_invalid``: with "raise" (default) pressures beyond
    the design's operating range are refused before any work (naming the row), and rows
    outside the strain validity range are kept failed (``converged`` False, NaN, the rule in
    ``violation``); with "warn" such rows keep their values and one :class:`ValidityWarning`
    names how many; "ignore" checks neither range. ``on_unstable``: "warn" (default, one
    :class:`StabilityWarning` naming how many rows are unstable), "raise" or "ignore".

    executor: a ``distributed.Client``: the rows run on its cluster in chunks of
    ``chunk_size`` rows (default: the rule in :mod:`softrod.cluster`), each chunk one Rust
    batch on a worker with ``threads`` cores (0 = the worker's share of its machine), and
    come back in order (docs/cluster.md). ``progress(done_rows, total_rows)`` is called as
    chunks finish (with an executor only).
    """
    on_unstable = _policy("on_unstable", on_unstable)
    on_invalid = _policy("on_invalid", on_invalid)
    design = load_design(design)
    constraint = (
        coerce_constraint(tip_constraint)
        if tip_constraint is not None
        else design.tip_constraint or _FREE_TIP
    )
    arr = batch_pressures(design, pressures)
    tens = batch_tensions(design, tensions, arr.shape[0])
    threads = V.threads(threads)
    opts = _options(options)
    smap = _stiffness_map(design, stiffness_map)
    sigma = None if smap is None else np.ascontiguousarray(_sigma_rows(smap, arr), dtype=float)
    tip = design.spec["tip"]
    tf = _vec3(tip_force, "force", "tip_force", tip["force"])
    tm = _vec3(tip_moment, "moment", "tip_moment", tip["moment"])
    from .cluster import check_executor

    held = None if constraint.kind == "free" else constraint.core_args()
    # A frictional path's increments (the core ignores them on a frictionless design).
    steps = int(opts.friction_steps)
    meta = _batch_metadata(design, options, tf, tm, smap, constraint)
    if check_executor(executor) is not None:
        out = _batch_on_cluster(
            executor,
            design,
            arr,
            tf,
            tm,
            sigma,
            _options(options),
            threads,
            chunk_size,
            progress,
            on_invalid,
            tens,
            held,
            steps,
        )
        return _batch_result(arr, sigma, meta, out, on_unstable, on_invalid, tens, constraint)
    if chunk_size is not None:
        raise design_error("chunk_size", chunk_size, "applies with executor= only", InputError)
    if progress is not None:
        raise design_error("progress", progress, "applies with executor= only", InputError)
    out = _core_batch(
        design._rod,
        np.ascontiguousarray(arr),
        tf,
        tm,
        threads,
        sigma,
        on_invalid,
        tens,
        opts.as_kwargs(),
        held,
        steps,
    )
    return _batch_result(arr, sigma, meta, out, on_unstable, on_invalid, tens, constraint)


# Map kinds whose rows are computed each from its own pressures alone, bit for bit: a
# table or constant (point by point) and networks as arrays (stiffness_map._forward sums
# its matrix products in a fixed order, row by row). A whole block in one call equals
# every row evaluated alone.
_ROW_EXACT_KINDS = ("table", "constant", "mlp")


def _sigma_rows(smap: StiffnessMap, arr: np.ndarray) -> np.ndarray:
    """sigma of every row of ``arr`` as solve_statics evaluates it for that row alone (a
    batch row is bitwise the single solve of that row). Tables, constants and networks
    (``_ROW_EXACT_KINDS``) are one call for all rows. Regressors and callables are code
    softrod cannot see into: a scikit-learn model's matrix products (BLAS) round a row
    differently in a block of another size, and a callable may do anything, so those are
    evaluated one row at a time, after one call for all rows that checks them and names a
    bad one by its row."""
    whole = smap(arr)
    if smap.kind in _ROW_EXACT_KINDS or len(arr) <= 1:
        return whole
    return np.vstack([smap(arr[k : k + 1]) for k in range(len(arr))])


def _core_batch(
    rod, arr, tf, tm, threads, sigma, on_invalid, tens, options: dict, held, friction_steps
):
    """One Rust batch call: the free tip's ``Rod.solve_batch``, or with ``held`` (a
    constraint's ``core_args()``) the constrained batch; with friction either follows one
    load path of ``friction_steps`` increments per row."""
    if held is None:
        return rod.solve_batch(
            arr,
            tf,
            tm,
            threads=threads,
            stiffness_scale=sigma,
            on_invalid=on_invalid,
            tensions=tens,
            friction_steps=friction_steps,
            **options,
        )
    kind, position, rotation = held
    return _core.solve_constrained_tip_batch(
        rod,
        arr,
        tf,
        tm,
        kind,
        position=position,
        rotation=rotation,
        threads=threads,
        stiffness_scale=sigma,
        on_invalid=on_invalid,
        tensions=tens,
        friction_steps=friction_steps,
        **options,
    )


def _batch_result(
    arr, sigma, meta, out, on_unstable, on_invalid, tens=None, constraint=_FREE_TIP
) -> BatchSolution:
    """The BatchSolution of the core's columns, with the stability and validity reports."""
    out = dict(out)
    out["tip_constraint"] = constraint.kind
    out["violation"] = np.asarray(out["violation"], dtype=object)
    out["stability_assessed"] = np.asarray(out.pop("assessed"), dtype=bool)
    converged = np.asarray(out["converged"], dtype=bool)
    unstable = np.flatnonzero(
        converged & out["stability_assessed"] & ~np.asarray(out["stable"], dtype=bool)
    )
    if unstable.size:
        _report_stability(
            False,
            on_unstable,
            f"{unstable.size} of {len(converged)} rows (first: row {unstable[0]})"
            if unstable.size > 1
            else f"row {unstable[0]}",
        )
    outside = np.flatnonzero(converged & (out["violation"] != ""))
    if outside.size and on_invalid == "warn":
        warnings.warn(
            ValidityWarning(
                f"{outside.size} of {len(converged)} rows lie outside the validity range "
                f"(first: row {outside[0]}: {out['violation'][outside[0]]}); see "
                "BatchSolution.violation"
            ),
            stacklevel=3,
        )
    return BatchSolution(pressures=arr, stiffness_scale=sigma, metadata=meta, tensions=tens, **out)


def _batch_metadata(design, options, tf, tm, smap, constraint=_FREE_TIP) -> dict:
    """The metadata block of a batch's table (BatchSolution.to_frame); a held tip adds
    ``tip_constraint`` (its kind, position in m and rotation matrix)."""
    from .schema import provenance

    extra = {}
    if constraint.kind != "free":
        held = {"type": constraint.kind, "position_m": list(constraint.position)}
        if constraint.rotation is not None:
            held["rotation"] = [list(r) for r in constraint.rotation]
        extra["tip_constraint"] = held
    solver = _options(options).as_kwargs()
    if design.frictional_obstacle is not None:
        solver["friction_steps"] = int(_options(options).friction_steps)
    return provenance(
        "softrod.solve_statics_batch",
        design,
        solver=solver,
        tip_force_N=tf,
        tip_moment_Nm=tm,
        stiffness_map=None if smap is None else repr(smap),
        **extra,
    )


def _batch_chunk(
    text,
    pressures,
    tip_force,
    tip_moment,
    sigma,
    options,
    threads,
    per_host,
    on_invalid,
    tensions=None,
    held=None,
    friction_steps=_DEFAULT_OPTIONS.friction_steps,
):
    """One chunk of a batch on a worker: the design rebuilt from its TOML text, one Rust
    batch call (``held``: the tip constraint's ``core_args()``, None: free;
    ``friction_steps``: a frictional path's increments)."""
    from .cluster import design_from_text, worker_threads

    design = design_from_text(text)
    return _core_batch(
        design._rod,
        pressures,
        tip_force,
        tip_moment,
        worker_threads(per_host, threads),
        sigma,
        on_invalid,
        tensions,
        options,
        held,
        friction_steps,
    )


def _batch_on_cluster(
    executor,
    design,
    arr,
    tf,
    tm,
    sigma,
    options,
    threads,
    chunk_size,
    progress,
    on_invalid,
    tens=None,
    held=None,
    friction_steps=_DEFAULT_OPTIONS.friction_steps,
):
    from .cluster import chunk_rows, design_text, run_chunks, task_slots

    if progress is not None and not callable(progress):
        raise design_error(
            "progress", progress, "must be callable: progress(done_rows, total_rows)", InputError
        )
    m = arr.shape[0]
    slots, per_host = task_slots(executor)
    rows = chunk_rows(m, slots, chunk_size)
    text = design_text(design)
    bounds = [(lo, min(lo + rows, m)) for lo in range(0, m, rows)]
    chunks = [
        (
            text,
            np.ascontiguousarray(arr[lo:hi]),
            tf,
            tm,
            None if sigma is None else np.ascontiguousarray(sigma[lo:hi]),
            options.as_kwargs(),
            threads,
            per_host,
            on_invalid,
            None if tens is None else np.ascontiguousarray(tens[lo:hi]),
            held,
            friction_steps,
        )
        for lo, hi in bounds
    ]
    parts = run_chunks(
        executor,
        _batch_chunk,
        chunks,
        sizes=[hi - lo for lo, hi in bounds],
        progress=progress,
        name="softrod-batch",
    )
    if not parts:  # no rows: the core's empty result
        return _core_batch(
            design._rod,
            arr,
            tf,
            tm,
            1,
            sigma,
            on_invalid,
            tens,
            options.as_kwargs(),
            held,
            friction_steps,
        )
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def batch_pressures(design: Design, pressures) -> np.ndarray:
    """An (m, channels) float array of gauge pressures (Pa), checked as :func:`solve_statics`
    checks one row: numbers (Python or numpy) or strings with units, never bools, complex
    numbers, masked or text arrays; at most MAX_ROWS rows."""
    n = design.n_channels
    arr = V.real_array(
        pressures,
        "pressures",
        unit_kind="pressure",
        max_size=V.MAX_ROWS * max(n, 1),
        what="gauge pressures (Pa)",
    )
    if arr.ndim == 1 and n == 1:
        arr = arr[:, None]
    _check_pressure_rows(arr, n, f"must be an (m, {n}) array of gauge pressures (Pa)")
    if arr.shape[0] > V.MAX_ROWS:
        raise V.fail("pressures", f"{arr.shape[0]} rows", f"too many rows: at most {V.MAX_ROWS:,}")
    low = np.flatnonzero((arr < V.VACUUM_PA).any(axis=1))
    if low.size:
        r = int(low[0])
        raise V.fail(
            f"pressures[{r}]",
            arr[r].tolist(),
            f"gauge pressures must be >= {V.VACUUM_PA:g} Pa (-1 atm, a perfect vacuum)"
            + (f"; {low.size} rows are below" if low.size > 1 else ""),
        )
    return np.ascontiguousarray(arr)
