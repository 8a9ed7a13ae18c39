"""Results of static solves: ``StaticSolution`` (one equilibrium, any model, with its exact
Jacobian ``Jacobian``) and
``BatchSolution`` (many). Kept apart from the solvers so that every model's solver (the rod's,
the PCC model's) returns the same types without importing each other."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from . import _core
from . import _validate as V
from .design import Design
from .errors import InputError, design_error

if TYPE_CHECKING:
    from collections.abc import Sequence

    import pandas as pd

    from ._types import ArrayLike, Units


@dataclass(frozen=True)
class Jacobian:
    """Exact derivatives of a point's pose at an equilibrium (SI). Rows: position x, y, z
    (m) then the small rotation theta_x, theta_y, theta_z (rad, world frame:
    dR = [dtheta]x R).

    pressures (6, c) per Pa; tip_force (6, 3) per N; tip_moment (6, 3) per N m;
    tensions (6, t) per N of each tendon channel (at a slack tendon the derivative of
    pulling it); params (6, k) per unit of each named parameter (tip only),
    ``param_names`` their names.

    reaction: for an equilibrium whose tip is pinned or clamped, the derivatives of the
    wrench the constraint applies to the tip (world frame; rows force x, y, z in N, then
    moment in N m, zero rows for a pin) with respect to the same inputs, a dict with the
    keys "pressures", "tip_force", "tip_moment", "tensions" (and "params" when asked,
    "stiffness_scale" for a mapped design); None for a free tip.

    stiffness_scale: for a design with a stiffness-mapped section (docs/stiffness-map.md),
    (6, 3) per unit of each factor sigma = (sigma_ext, sigma_bend_x, sigma_bend_y) at
    fixed pressures; None otherwise. The pressures' block is then the total derivative:
    the partial one plus ``stiffness_scale @ d sigma / d p`` (the map's
    :meth:`~softrod.StiffnessMap.derivative`).
    """

    point: float
    position: np.ndarray
    rotation: np.ndarray
    pressures: np.ndarray
    tip_force: np.ndarray
    tip_moment: np.ndarray
    params: np.ndarray | None = None
    param_names: tuple[str, ...] = ()
    tensions: np.ndarray = field(default_factory=lambda: np.zeros((6, 0)))
    reaction: dict[str, np.ndarray] | None = None
    stiffness_scale: np.ndarray | None = None


@dataclass(frozen=True)
class SystemJacobian:
    """Exact derivatives of a system's equilibrium (:meth:`SystemSolution.jacobian`, SI).
    Rows of the pose blocks: the platform origin's position x, y, z (m), then the platform's
    small rotation theta_x, theta_y, theta_z (rad, world frame: dR = [dtheta]x R).

    pressures (6, sum of the rods' channels) per Pa: rod 0's channels, then rod 1's, ...
    (``pressure_columns`` names them: "rod0_p0", ...); tensions (6, sum of the rods' tendon
    channels) per N ("rod0_t0", ...); platform_force (6, 3) per N and platform_moment
    (6, 3) per N m of the external load on the platform (world frame, the moment about the
    platform origin): together the platform's compliance.

    base: the derivatives of every rod's base force (N) and moment (N m) (world frame, the
    rods' ``base_force`` and ``base_moment``), (n_rods, 6, k) per block, keyed
    "pressures", "tensions", "platform_force" and "platform_moment": what force sensing
    from loads measured at the bases needs.

    stiffness_scale: per rod, for a rod with a stiffness-mapped section, the (6, 3)
    derivatives with respect to its factors sigma at fixed pressures (None for other rods);
    ``base["stiffness_scale"]`` likewise (n_rods, 6, 3). The pressures' blocks already hold
    the part through each map (docs/stiffness-map.md).
    """

    position: np.ndarray
    rotation: np.ndarray
    pressures: np.ndarray
    tensions: np.ndarray
    platform_force: np.ndarray
    platform_moment: np.ndarray
    base: dict[str, Any]
    pressure_columns: tuple[str, ...] = ()
    tension_columns: tuple[str, ...] = ()
    stiffness_scale: tuple[np.ndarray | None, ...] = ()


@dataclass(frozen=True)
class Contact:
    """The contacts of a static solution with the design's obstacles (docs/contact.md),
    per node of the solution (n nodes) and per obstacle (k obstacles), SI, world frame.

    force: (n, 3) contact force per unit reference length on the rod at each node, N/m
    (all obstacles together).
    gap: (n,) gap between the rod's surface and the nearest obstacle, m; negative where
    the surface sinks into it (the penalty's compliance, at most the obstacle's tolerance).
    point: (n, 3) nearest point of that obstacle's surface (the contact point where the
    node touches), m.
    obstacle: (n,) index of that obstacle.
    total_force: (k, 3) resultant contact force of each obstacle on the rod, N (the
    integral the solver applied, so base force + contact + loads balance to the solver's
    tolerance).
    total_moment: (k, 3) its moment about the base position, N m.
    end_force: (k, 3) the part of total_force on the rod's rounded end (a point contact at
    the tip, docs/contact.md), N.
    max_penetration: the deepest penetration at a node, m (<= 0: nothing touches).
    friction_force: (k, 3) the tangential (Coulomb friction) part of total_force, N; zero
    without friction (docs/contact.md, "Friction in the statics"). With friction, force
    and total_force include it.
    """

    force: np.ndarray
    gap: np.ndarray
    point: np.ndarray
    obstacle: np.ndarray
    total_force: np.ndarray
    total_moment: np.ndarray
    end_force: np.ndarray
    max_penetration: float
    friction_force: np.ndarray | None = None

    def __post_init__(self):
        if self.friction_force is None:
            object.__setattr__(self, "friction_force", np.zeros_like(self.total_force))

    @classmethod
    def from_core(cls, d: dict) -> Contact:
        return cls(
            force=d["force"],
            gap=d["gap"],
            point=d["point"],
            obstacle=d["obstacle"],
            total_force=d["total_force"],
            total_moment=d["total_moment"],
            end_force=d["end_force"],
            max_penetration=float(d["max_penetration"]),
            friction_force=d.get("friction_force"),
        )

    @property
    def in_contact(self) -> np.ndarray:
        """(n,) True where the rod's surface touches an obstacle (gap < 0)."""
        return self.gap < 0

    @property
    def total(self) -> np.ndarray:
        """(3,) resultant contact force of all obstacles on the rod, N."""
        return self.total_force.sum(axis=0)

    def __repr__(self) -> str:
        k = len(self.total_force)
        forces = ", ".join(f"{np.linalg.norm(f) * 1e3:.4g}" for f in self.total_force)
        touching = int(self.in_contact.sum())
        depth = max(self.max_penetration, 0.0) * 1e3
        return (
            f"Contact({k} obstacle{'s' if k != 1 else ''}, force [{forces}] mN, "
            f"{touching} node{'s' if touching != 1 else ''} touching, deepest {depth:.3g} mm)"
        )


def _mm(point) -> str:
    """'(x, y, z) mm' of a point in m, for reprs."""
    # + 0.0 turns a rounded -0.0 into 0.0 (no "-0.00" for a coordinate on an axis).
    return "(" + ", ".join(f"{round(x * 1e3, 2) + 0.0:.2f}" for x in point) + ") mm"


def _values(values, scale: float, unit: str) -> str:
    """'[10, 0, 0] kPa' of inputs in SI, for reprs."""
    return "[" + ", ".join(f"{x * scale:g}" for x in values) + f"] {unit}"


def _inputs(name: str, pressures, tensions) -> list[str]:
    """The start of a solution's repr: the design's name, its pressures and tensions."""
    parts = [repr(name)]
    if len(pressures):
        parts.append(f"p = {_values(pressures, 1e-3, 'kPa')}")
    if len(tensions):
        parts.append(f"T = {_values(tensions, 1.0, 'N')}")
    return parts


@dataclass(frozen=True)
class StaticSolution:
    """A static equilibrium, sampled at every integration node (n nodes).

    s: (n,) reference arc length, m.            section: (n,) section index of each node.
    position: (n, 3) centreline r, m (world).   rotation: (n, 3, 3) [d1 d2 d3] (world).
    force: (n, 3) total internal force n, N.    moment: (n, 3) total internal moment m, N m.
    v: (n, 3) shear/stretch strain (body).      u: (n, 3) curvature/twist, 1/m (body).
    Forces and moments are the totals of the balance laws (material plus pressure part).
    stiffness_scale: (3,) sigma = (sigma_ext, sigma_bend_x, sigma_bend_y) applied to the
    mapped sections (docs/stiffness-map.md); ones when the design has none.
    stable: the equilibrium is stable (docs/model.md, "Validity and stability"); None where
    it is not assessed (the PCC model, follower loads: docs/scope.md; friction, which has
    no potential: docs/contact.md) or the solve failed. A pinned or clamped tip is
    assessed with the tip held (docs/model.md, "End constraints").
    violations: the validity ranges the solution lies outside (only with
    ``on_invalid="warn"``; otherwise such a solution is refused).
    friction_state: where a frictional load path stands (a ``softrod._core.FrictionState``:
    its loads, every contact's friction memory and how the tip was held, its
    ``tip_constraint``), for ``solve_statics(..., history=solution)`` to continue the path
    with the same kind of tip; None without friction (docs/contact.md, "Friction in the
    statics").
    """

    design: Design
    pressures: np.ndarray
    s: np.ndarray
    section: np.ndarray
    position: np.ndarray
    rotation: np.ndarray
    force: np.ndarray
    moment: np.ndarray
    v: np.ndarray
    u: np.ndarray
    converged: bool
    iterations: int
    residual: float
    load_steps: int
    shooting_unknowns: np.ndarray = field(repr=False)
    stiffness_scale: np.ndarray = field(default_factory=lambda: np.ones(3))
    stable: bool | None = None
    violations: tuple[str, ...] = ()
    #: (tip force, tip moment) the equilibrium was solved under (the design's tip frame,
    #: N and N m).
    tip_loads: tuple | None = field(default=None, repr=False)
    #: Tendon tensions (N, one per tendon channel) it was solved under; empty without tendons.
    tensions: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    #: How the tip was held: "free", "pinned" or "clamped" (docs/model.md, "End
    #: constraints").
    tip_constraint: str = "free"
    #: The force (N) and moment (N m) the tip constraint applies to the tip (world frame);
    #: zeros for a free tip, a zero moment for a pinned one.
    tip_reaction_force: np.ndarray = field(default_factory=lambda: np.zeros(3), repr=False)
    tip_reaction_moment: np.ndarray = field(default_factory=lambda: np.zeros(3), repr=False)
    #: Contacts with the design's obstacles (:class:`Contact`); None without obstacles.
    contact: Contact | None = field(default=None, repr=False)
    friction_state: Any = field(default=None, repr=False)
    #: The held tip's prescribed pose, (kind, position m, rotation) as the binding takes
    #: it; None for a free tip (its Jacobian differentiates the held equilibrium).
    tip_hold: tuple | None = field(default=None, repr=False)
    #: The :class:`~softrod.StiffnessMap` that gave ``stiffness_scale`` (None when the design
    #: has no mapped section): its derivative enters the pressures' Jacobian.
    stiffness_map: Any = field(default=None, repr=False, compare=False)
    #: The scaled collocation unknowns z of an equilibrium that statics solved by
    #: collocation (docs/model.md, "Collocation"), None otherwise: the warm start of
    #: ``initial=``, :meth:`jacobian` and ``linearise`` (``shooting_unknowns`` holds only
    #: its base moment there, which does not determine z).
    collocation_unknowns: np.ndarray | None = field(default=None, repr=False, compare=False)

    def __repr__(self) -> str:
        parts = _inputs(self.design.name, self.pressures, self.tensions)
        if self.tip_constraint != "free":
            parts.append(f"tip {self.tip_constraint}")
        if self.converged:
            parts += [f"tip {_mm(self.tip_position)}", f"stable {self.stable}"]
        else:
            parts.append("not converged")
        parts.append(f"{self.iterations} iteration" + ("" if self.iterations == 1 else "s"))
        return f"StaticSolution({', '.join(parts)})"

    @classmethod
    def _failed(
        cls,
        design: Design,
        pressures: ArrayLike,
        exc: Exception,
        n_unknowns: int,
        **extra: Any,
    ) -> StaticSolution:
        """The result of a solve that did not converge (``check=False``): NaN shape and
        wrench, ``converged`` False, the iterations and residual of ``exc``."""
        nan3 = np.full((1, 3), np.nan)
        return cls(
            design=design,
            pressures=np.array(pressures),
            s=np.array([np.nan]),
            section=np.array([-1]),
            position=nan3,
            rotation=np.full((1, 3, 3), np.nan),
            force=nan3,
            moment=nan3,
            v=nan3,
            u=nan3,
            converged=False,
            iterations=exc.iterations,
            residual=exc.residual,
            load_steps=0,
            shooting_unknowns=np.full(n_unknowns, np.nan),
            **extra,
        )

    def _warm_start(self, model: str) -> list[float]:
        """The unknowns that warm-start another solve (statics' ``initial``): the
        collocation unknowns of a collocation solution, else the shooting unknowns."""
        x = np.asarray(self.shooting_unknowns, dtype=float)
        if not self.converged or not np.all(np.isfinite(x)):
            raise V.fail(
                "initial",
                "a solution with converged = False",
                "cannot warm-start a solve: pass a converged solution (or none)",
            )
        return self._unknowns()

    def _unknowns(self) -> list[float]:
        """The unknowns the binding takes this equilibrium from (for its derivatives): a
        collocation solution's z, taken as it is where the solver's convergence test passes
        there (its shooting unknowns alone would start a cold collocation solve), else the
        shooting unknowns (a warm solve)."""
        if self.collocation_unknowns is not None:
            return [float(v) for v in self.collocation_unknowns]
        return [float(v) for v in self.shooting_unknowns]

    @property
    def tip_position(self) -> np.ndarray:
        """Tip position (end of the last section), m."""
        return self.position[-1]

    @property
    def tip_rotation(self) -> np.ndarray:
        """Tip rotation [d1 d2 d3], world frame."""
        return self.rotation[-1]

    @property
    def base_force(self) -> np.ndarray:
        """Total internal force at the base (the wrench the mount takes), N."""
        return self.force[0]

    @property
    def base_moment(self) -> np.ndarray:
        return self.moment[0]

    @property
    def strains(self) -> dict[str, np.ndarray]:
        return {"v": self.v, "u": self.u}

    def jacobian(self, *, params: Sequence[str] = (), point: float | str | None = None) -> Jacobian:
        """The exact Jacobian of the pose at arc length ``point`` (default the tip) with
        respect to the pressures, the tip force and moment, the tendon tensions and, at the
        tip, the named calibration parameters (``params``: names such as "E" or
        "c_b[body]", as in :func:`softrod.calibrate`); docs/control.md. Implicit
        differentiation of the shooting residual: no finite differences. Also for a pinned
        or clamped tip (the held equilibrium's derivatives, with those of the tip's reaction
        in ``reaction``), follower loads and obstacles without friction."""
        from .units import to_si

        if not self.converged:
            raise design_error(
                "solution", "converged = False", "must be a converged StaticSolution", InputError
            )
        if not np.all(np.isfinite(self.force)):
            raise design_error(
                "solution",
                "model='pcc'",
                "the Jacobian is available for the rod model only",
                InputError,
            )
        if self.friction_state is not None:
            k = self.design.frictional_obstacle or 0
            raise design_error(
                f"obstacles[{k}].friction",
                self.design.spec["obstacles"][k]["friction"],
                "StaticSolution.jacobian is not available for a frictional equilibrium: it "
                "depends on the load path, and the return map's stick/slip switch has no "
                "derivative there (docs/contact.md, 'Friction in the statics')",
                InputError,
            )
        held = self._held_args("solution", "Jacobian")
        design = self.design
        s = design.length if point is None else to_si(point, "length", "point", InputError)
        pairs, names = _param_pairs(design, params)
        dsigma = self._stiffness_map_derivative()
        out = _core.point_jacobian_of(
            design._rod,
            [float(p) for p in self.pressures],
            [float(v) for v in self._tip_load("force")],
            [float(v) for v in self._tip_load("moment")],
            [float(v) for v in self.stiffness_scale],
            self._unknowns(),
            float(s),
            pairs,
            tensions=[float(t) for t in self.tensions],
            **held,
        )
        reaction = out.get("reaction")
        reaction = None if reaction is None else {k: np.array(v) for k, v in reaction.items()}
        pressures = np.array(out["pressures"])
        if dsigma is not None:
            # sigma(p) moves with the pressures: d/dp = partial at fixed sigma + d/dsigma
            # dsigma/dp (the core's blocks are partial derivatives).
            pressures = pressures + out["stiffness_scale"] @ dsigma
            if reaction is not None:
                reaction["pressures"] = reaction["pressures"] + reaction["stiffness_scale"] @ dsigma
        return Jacobian(
            point=float(s),
            position=np.array(out["position"]),
            rotation=np.array(out["rotation"]),
            pressures=pressures,
            tip_force=out["tip_force"],
            tip_moment=out["tip_moment"],
            params=out.get("params"),
            param_names=tuple(names),
            tensions=out["tensions"],
            reaction=reaction,
            stiffness_scale=out.get("stiffness_scale"),
        )

    def _held_args(self, field: str, what: str) -> dict[str, Any]:
        """The binding's keyword arguments of a held tip's prescribed pose (``tip_kind``,
        ``tip_position``, ``tip_rotation``; none for a free tip). InputError naming
        ``{field}.tip_hold`` when a held solution has lost it."""
        if self.tip_constraint == "free":
            return {}
        if self.tip_hold is None:
            raise design_error(
                f"{field}.tip_hold",
                None,
                f"a {self.tip_constraint} tip's {what} needs the held pose the equilibrium "
                "was solved at (solve_statics keeps it)",
                InputError,
            )
        kind, position, rotation = self.tip_hold
        return {"tip_kind": kind, "tip_position": position, "tip_rotation": rotation}

    def _stiffness_map_derivative(self) -> np.ndarray | None:
        """d sigma / d p (3, channels) of a mapped design's solution, None without a mapped
        section; InputError when the map is unknown or gives no derivative."""
        if not self.design.mapped_sections:
            return None
        if self.stiffness_map is None:
            raise design_error(
                "solution.stiffness_map",
                None,
                "a mapped design's pressure Jacobian needs the stiffness map the solution was "
                "solved with (solve_statics and solve_system keep it): sigma(p) moves with the "
                "pressures",
                InputError,
            )
        return self.stiffness_map.derivative(np.asarray(self.pressures, dtype=float))

    def _tip_load(self, kind: str):
        """The tip force or moment the solution was solved under: from the base wrench
        balance it is not recoverable in general, so solutions carry it (``tip_loads``)."""
        if self.tip_loads is not None:
            return self.tip_loads[0] if kind == "force" else self.tip_loads[1]
        return self.design.spec["tip"][kind]


def _param_pairs(design: Design, params) -> tuple[list, list[str]]:
    """The core's (parameter, section) pairs and the names of calibration parameters."""
    if params is None or (isinstance(params, (str, list, tuple)) and len(params) == 0):
        return [], []
    from .calibration.params import parse_parameters

    resolved = parse_parameters(params, design)
    return [p.core() for p in resolved], [p.name for p in resolved]


@dataclass(frozen=True)
class BatchSolution:
    """Results of ``solve_statics_batch``: one row per input row, failed rows kept.

    tip_position (m, 3) m; tip_rotation (m, 3, 3); base_force (m, 3) N; base_moment (m, 3) N m;
    converged (m,) bool (rows that failed hold NaN); iterations (m,); residual (m,).
    stiffness_scale (m, 3): sigma of every row when the design has mapped sections
    (docs/stiffness-map.md), else None. x (m, 3): the solver's scaled unknowns (warm starts).
    stable (m,) bool: the row's equilibrium is stable (False on failed rows and where not
    assessed: see stability_assessed (m,) bool, False with follower loads and friction;
    :meth:`to_frame` leaves such cells empty). tensions (m, k):
    the tendon tensions of every row, N (None: slack tendons). violation (m,)
    str: the validity rule a row broke ("" if none; docs/model.md, "Validity and stability").
    metadata: design, softrod version and solver settings (the metadata block of
    :meth:`to_frame`). tip_constraint: how the tips were held ("free", "pinned",
    "clamped"); with a pinned or clamped tip, tip_reaction_force (m, 3) N and
    tip_reaction_moment (m, 3) N m: the wrench the constraint applies to each tip (world
    frame; zero moment when pinned; NaN on failed rows), None for a free tip; x is then
    (m, 6). With an obstacle's friction > 0 (every row its own load path, docs/contact.md,
    "Friction in the statics"): contact_force (m, obstacles, 3) N, each obstacle's resultant
    contact force on the rod (world frame), and friction_force (m, obstacles, 3) N, its
    tangential part (NaN on failed rows; None without friction); x is then (m, 6) and
    stability is not assessed.
    """

    pressures: np.ndarray
    tip_position: np.ndarray
    tip_rotation: np.ndarray
    base_force: np.ndarray
    base_moment: np.ndarray
    converged: np.ndarray
    iterations: np.ndarray
    residual: np.ndarray
    stiffness_scale: np.ndarray | None = None
    x: np.ndarray | None = None
    stable: np.ndarray | None = None
    violation: np.ndarray | None = None
    metadata: dict = field(default_factory=dict, compare=False)
    stability_assessed: np.ndarray | None = None
    tensions: np.ndarray | None = None
    tip_constraint: str = "free"
    tip_reaction_force: np.ndarray | None = None
    tip_reaction_moment: np.ndarray | None = None
    contact_force: np.ndarray | None = None
    friction_force: np.ndarray | None = None

    def __len__(self) -> int:
        return self.pressures.shape[0]

    def __repr__(self) -> str:
        name = self.metadata.get("design")
        what = f"{name!r}, " if name else ""
        held = f", tip {self.tip_constraint}" if self.tip_constraint != "free" else ""
        return (
            f"BatchSolution({what}{len(self)} rows, {int(np.sum(self.converged))} converged{held})"
        )

    def to_frame(self, units: Units = None) -> pd.DataFrame:
        """The results as a DataFrame in the dataset schema (docs/datasets.md), one row per
        solve: ``p0_kPa`` ..., ``t0_N`` ... (with tensions), ``tip_x_mm`` ..., ``tip_qw``
        ... ``tip_qz``, ``base_fx_N`` ..., ``base_mx_Nmm`` ..., then the result columns
        ``converged``, ``iterations``, ``residual``, ``stable`` (empty where stability was
        not assessed: friction, follower loads), with a pinned or clamped
        tip ``tip_reaction_fx_N`` ... ``tip_reaction_fz_N`` and ``tip_reaction_mx_Nmm`` ...
        ``tip_reaction_mz_Nmm`` (the wrench the constraint applies to the tip, world frame)
        and, with a stiffness map, ``sigma_ext``, ``sigma_bend_x``, ``sigma_bend_y``; with
        friction ``contact0_fx_N`` ... ``contact0_fz_N`` and ``friction0_fx_N`` ...
        ``friction0_fz_N`` per obstacle (0, 1, ...: :attr:`contact_force` and
        :attr:`friction_force`). Rows that did not converge keep NaN (empty cells in a
        file).
        ``units`` as in :meth:`softrod.Dataset.to_frame`. The metadata block
        (``frame.attrs["softrod.metadata"]``) is :attr:`metadata`: design, softrod version,
        solver settings. The same quantities get the same names as in
        :meth:`softrod.Trajectory.to_frame`; ``load_dataset(frame)`` reads it back.
        """
        from .schema import Extra, schema_frame

        extras = [
            Extra("converged", np.asarray(self.converged, dtype=bool), "the solve converged"),
            Extra("iterations", np.asarray(self.iterations), "Newton iterations"),
            Extra("residual", np.asarray(self.residual, dtype=float), "scaled final residual"),
        ]
        if self.stable is not None:
            stable = np.asarray(self.stable, dtype=bool)
            what = "the equilibrium is stable"
            assessed = self.stability_assessed
            if assessed is not None and not np.all(assessed):
                import pandas as pd

                # Not assessed (friction, follower loads) is no verdict: an empty cell, never
                # a False that a reader would take for "unstable".
                stable = pd.array(np.where(assessed, stable, None), dtype="boolean")
                what += " (empty: not assessed)"
            extras.append(Extra("stable", stable, what))
        for arr, kind, what in (
            (self.tip_reaction_force, "force", "force"),
            (self.tip_reaction_moment, "moment", "moment"),
        ):
            if arr is not None:
                a = np.asarray(arr, dtype=float)
                extras += [
                    Extra(
                        f"tip_reaction_{'f' if kind == 'force' else 'm'}{axis}",
                        a[:, k],
                        f"{axis} component of the {what} the {self.tip_constraint} tip's "
                        "constraint applies to the tip (world frame)",
                        kind,
                    )
                    for k, axis in enumerate("xyz")
                ]
        for arr, name, what in (
            (self.contact_force, "contact", "contact force (normal and friction)"),
            (self.friction_force, "friction", "friction force (tangential contact force)"),
        ):
            if arr is not None:
                a = np.asarray(arr, dtype=float)
                extras += [
                    Extra(
                        f"{name}{k}_f{axis}",
                        a[:, k, i],
                        f"{axis} component of obstacle {k}'s {what} on the rod (world frame)",
                        "force",
                    )
                    for k in range(a.shape[1])
                    for i, axis in enumerate("xyz")
                ]
        if self.stiffness_scale is not None:
            from .stiffness_map import SIGMA_NAMES

            extras += [
                Extra(name, self.stiffness_scale[:, k], f"stiffness factor {name} (paper 001)")
                for k, name in enumerate(SIGMA_NAMES)
            ]
        return schema_frame(
            pressures=self.pressures,
            tensions=self.tensions,
            tip_position=self.tip_position,
            tip_rotation=self.tip_rotation,
            base_force=self.base_force,
            base_moment=self.base_moment,
            extras=extras,
            units=units,
            metadata=self.metadata,
        )
