"""Linearisations at an equilibrium: the exact pose Jacobian of a static solution
(``StaticSolution.jacobian``) and the linearised dynamics M q'' + D q' + K q = B u with its
modes (``linearise``, ``LinearSystem.modes``). The matrices come from the Rust core
(``softrod_core::{jacobian, linearise}``, exact by dual numbers); the eigenvalue problems
are dense linear algebra (scipy) on them. docs/control.md explains the discretisation.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import os

    import pandas as pd
    from matplotlib.figure import Figure

    from .._types import ArrayLike, DesignLike, Quantity

import math
from dataclasses import dataclass, field

import numpy as np

from .. import _core
from .. import _validate as V
from .._validate import integer
from ..catalog import load_design
from ..constraints import TipConstraint
from ..design import Design
from ..errors import InputError, design_error
from ..solution import Jacobian, StaticSolution
from ..stiffness_map import StiffnessMap

__all__ = ["Jacobian", "LinearSystem", "Modes", "SystemLinearSystem", "jacobian", "linearise"]

INPUT_NAMES_LOADS = ("F_x", "F_y", "F_z", "M_x", "M_y", "M_z")


def jacobian(
    solution: StaticSolution, *, params: Sequence[str] = (), point: Quantity | None = None
) -> Jacobian:
    """The exact Jacobian of the pose at arc length ``point`` (default the tip) of a
    converged rod equilibrium: :meth:`softrod.StaticSolution.jacobian`."""
    if not isinstance(solution, StaticSolution):
        raise design_error(
            "solution", type(solution).__name__, "must be a converged StaticSolution", InputError
        )
    return solution.jacobian(params=params, point=point)


@dataclass(frozen=True)
class Modes:
    """Modes of a :class:`LinearSystem`, lowest first (k modes).

    frequency (k,) Hz and omega (k,) rad/s: undamped natural frequencies (K phi = w^2 M phi);
    damping_ratio (k,): modal damping phi^T D phi / (2 w phi^T M phi) (exact for Kelvin-Voigt
    damping without prestress, where D = tau K; first order otherwise);
    damped_frequency (k,) Hz: the imaginary part of the exact pole of each mode (NaN when it
    is overdamped; poles and modes are matched one to one); shapes (k, n, 6): node
    displacements and small rotations (a pinned tip's displacement zero), normalised to the
    largest entry 1; nodes (n,) m; poles: every eigenvalue of the first-order system, 1/s.
    """

    frequency: np.ndarray
    omega: np.ndarray
    damping_ratio: np.ndarray
    damped_frequency: np.ndarray
    shapes: np.ndarray
    nodes: np.ndarray
    poles: np.ndarray = field(repr=False)

    def to_frame(self) -> pd.DataFrame:
        import pandas as pd

        return pd.DataFrame(
            {
                "mode": np.arange(1, len(self.frequency) + 1),
                "frequency_Hz": self.frequency,
                "damping_ratio": self.damping_ratio,
                "damped_frequency_Hz": self.damped_frequency,
            }
        )


class _SecondOrder:
    """What every M q'' + D q' + K q = B u has: its first-order form and its response."""

    mass: np.ndarray
    damping: np.ndarray
    stiffness: np.ndarray
    input: np.ndarray

    def state_space(self) -> tuple[np.ndarray, np.ndarray]:
        """(A, B) of x' = A x + B u with x = (q, q')."""
        n = self.mass.shape[0]
        minv = np.linalg.inv(self.mass)
        a = np.block(
            [[np.zeros((n, n)), np.eye(n)], [-minv @ self.stiffness, -minv @ self.damping]]
        )
        b = np.vstack([np.zeros_like(self.input), minv @ self.input])
        return a, b

    def poles(self) -> np.ndarray:
        """Every eigenvalue of the first-order system x' = A x (1/s; :meth:`state_space`),
        largest real part first: a pole with a positive real part grows (divergence when
        it is real, flutter when it comes in a complex pair)."""
        a, _ = self.state_space()
        p = np.linalg.eigvals(a)
        return p[np.lexsort((-np.abs(p.imag), -p.real))]

    def _response(self, omega: float) -> np.ndarray:
        """(K - w^2 M + i w D)^-1 B: every coordinate per unit input at ``omega`` (rad/s)."""
        # 1e12 rad/s is far beyond any mode of a rod; w^2 M then stays finite.
        omega = V.real(omega, "omega", minimum=0.0, maximum=1e12)
        z = self.stiffness - omega**2 * self.mass + 1j * omega * self.damping
        return np.linalg.solve(z, self.input)


@dataclass(frozen=True)
class LinearSystem(_SecondOrder):
    """The linearised dynamics M q'' + D q' + K q = B u about a static equilibrium (SI).

    q = (dr_1, dtheta_1, ..., dr_n, dtheta_n): displacement (m) and small rotation (rad,
    world frame) of the nodes at arc lengths ``nodes`` (the last is the tip); u = changes of
    the chamber pressures (Pa), of the tip force (N) and moment (N m) and of the tendon
    tensions (N), named in ``input_names`` (p0 ..., F_x ... M_z, t0 ...). ``equilibrium``
    is the static solution it was taken at. ``tip_constraint``: "free"; "clamped" (the
    tip does not move: it is no coordinate, the nodes lie between the clamps, and the tip
    load's input columns are zero); or "pinned" (the tip, the last node, keeps only its
    rotation dtheta_n: q has 6 n - 3 rows, and the tip force's input columns are zero).
    :meth:`node_rows` reads any node's six rows out of a vector or matrix over q;
    :meth:`poles` gives the first-order system's poles (under follower loads K is not
    symmetric, and a pole may grow: flutter).
    """

    design: Design
    pressures: np.ndarray
    nodes: np.ndarray
    mass: np.ndarray
    damping: np.ndarray
    stiffness: np.ndarray
    input: np.ndarray
    input_names: tuple[str, ...]
    equilibrium: StaticSolution = field(repr=False)
    tip_constraint: str = "free"

    @property
    def tip_rows(self) -> slice:
        """Rows of q holding the tip's coordinates: its displacement and rotation (a free
        tip), its rotation only (a pinned tip: the last three rows)."""
        if self.tip_constraint == "clamped":
            raise design_error(
                "tip_constraint",
                self.tip_constraint,
                "a clamped tip does not move, so it has no rows in q; read a node's rows "
                "(6 k .. 6 k + 6 for nodes[k]; frequency_response(w, node=k))",
                InputError,
            )
        n = self.mass.shape[0]
        return slice(n - (3 if self.tip_constraint == "pinned" else 6), n)

    def node_rows(self, x: np.ndarray, node: int) -> np.ndarray:
        """The six pose rows (dr, dtheta) of ``nodes[node]`` (an index, negative from the
        end) of ``x``, a vector or matrix over q (its first axis). A pinned tip's
        displacement rows, which are not coordinates, are zeros."""
        n = len(self.nodes)
        k = V.integer(node, "node", minimum=-n, maximum=n - 1, hint=f" (the {n} nodes)") % n
        x = _over_q(self, x)
        if self.tip_constraint == "pinned" and k == n - 1:
            return np.concatenate([np.zeros((3, *x.shape[1:]), x.dtype), x[6 * k : 6 * k + 3]])
        return x[6 * k : 6 * k + 6]

    def frequency_response(self, omega: float, *, node: int | None = None) -> np.ndarray:
        """The tip pose (6 rows) per unit input at angular frequency ``omega`` (rad/s):
        T (K - w^2 M + i w D)^-1 B. ``node``: the pose of ``nodes[node]`` instead (an index,
        negative from the end); a clamped tip does not move, so there a node is needed. A
        pinned tip's displacement rows are zeros."""
        V.real(omega, "omega", minimum=0.0, maximum=1e12)
        if node is None:
            _ = self.tip_rows  # a clamped tip has none: refused before any work
            node = -1
        self.node_rows(np.zeros(self.mass.shape[0]), node)  # the index, before any work
        return self.node_rows(self._response(omega), node)

    def plot_modes(
        self,
        count: int = 3,
        path: str | os.PathLike | None = None,
        *,
        title: str | None = None,
    ) -> Figure:
        """The ``count`` lowest mode shapes (at most 8) over the equilibrium, front (x-z)
        and side (y-z) views, each labelled with its frequency
        (:func:`softrod.control.mode_plots.plot_modes`). Written to ``path`` when given;
        returns the Figure."""
        from .mode_plots import plot_modes

        return plot_modes(self, count, path, title=title)

    def modes(self, count: int | None = None) -> Modes:
        """The ``count`` lowest modes (default all)."""
        return _modes(
            self,
            count,
            [lambda x, k=k: self.node_rows(x, k) for k in range(len(self.nodes))],
            self.nodes,
        )


def _modes(system, count: int | None, rows_of: Sequence, nodes: np.ndarray) -> Modes:
    """The ``count`` lowest modes of a linear system (``mass``, ``stiffness``, ``damping``,
    ``state_space()``); ``rows_of[j](x)`` reads the six rows of point j from a matrix over
    q, the points at arc lengths ``nodes``."""
    if count is not None:
        n = system.mass.shape[0]
        count = V.integer(count, "count", minimum=1, maximum=n, hint=f" (the {n} coordinates)")
    from threadpoolctl import threadpool_limits

    # Dense eigenproblems of a few hundred unknowns: one BLAS thread is fastest (and
    # several oversubscribe a shared machine).
    with threadpool_limits(1):
        return _eigen_modes(system, count, rows_of, nodes)


def _eigen_modes(system, count: int | None, rows_of: Sequence, nodes: np.ndarray) -> Modes:
    import scipy.linalg
    import scipy.optimize

    a, _ = system.state_space()
    poles = np.linalg.eigvals(a)
    # A pole in the right half-plane grows: no modes to report. The bound sits far above
    # the round-off of the eigenvalues of a non-symmetric matrix (1e-8 relative measured on
    # Beck's column at 16 nodes) and far below the growth of an instability just past its
    # onset (Beck's column 0.1 % beyond its flutter load: 3e-2 relative).
    growing = poles.real > 1e-6 * np.abs(poles)
    if np.any(growing):
        worst = poles[growing][np.argmax(poles[growing].real)]
        kind = "flutter, a growing oscillation" if worst.imag != 0 else "divergence"
        raise design_error(
            "equilibrium",
            f"pole {worst.real:.4g} {worst.imag:+.4g}j 1/s",
            f"grows ({kind}): the equilibrium is dynamically unstable, so it has no modes "
            "(follower loads can make a statically stable equilibrium flutter, as Beck's "
            "column does above 20.05 EI/L^2); poles() lists every growth rate",
            InputError,
        )
    w2, vecs = scipy.linalg.eig(system.stiffness, system.mass)
    # Under follower loads K is not symmetric, and damping can keep a system stable whose
    # undamped modes have merged (a complex pair of omega^2): it has no undamped modes then.
    merged = np.abs(w2.imag) > 1e-6 * np.abs(w2)
    if np.any(merged):
        worst = w2[merged][np.argmin(np.abs(w2[merged]))]
        raise design_error(
            "equilibrium",
            f"omega^2 = {worst.real:.4g} {worst.imag:+.4g}j s^-2",
            "has complex undamped eigenvalues omega^2 (a follower load merged two modes; "
            "without its damping the equilibrium would flutter), so it has no undamped "
            "modes; poles() gives the damped system's",
            InputError,
        )
    w2 = w2.real
    order = np.argsort(w2)
    w2, vecs = w2[order], vecs[:, order].real
    if np.any(w2 <= 0):
        raise design_error(
            "equilibrium",
            "K",
            "has a non-positive eigenvalue: the equilibrium is not stable, so it has no modes",
            InputError,
        )
    omega = np.sqrt(w2)
    k = len(omega) if count is None else int(count)
    omega, vecs = omega[:k], vecs[:, :k]
    zeta = np.array(
        [
            (v @ system.damping @ v) / (2 * w * (v @ system.mass @ v))
            for v, w in zip(vecs.T, omega, strict=True)
        ]
    )
    # Each underdamped mode's exact pole: the poles nearest to the first-order estimates,
    # each pole given to one mode only (a nearest-pole search gave both modes of a
    # degenerate pair, e.g. a round rod's two bending planes, the same pole).
    damped = np.full(k, np.nan)
    upper = poles[poles.imag > 0]
    under = np.flatnonzero(zeta < 1)
    if len(under) and len(upper):
        expect = -zeta[under] * omega[under] + 1j * omega[under] * np.sqrt(1 - zeta[under] ** 2)
        rows, cols = scipy.optimize.linear_sum_assignment(abs(expect[:, None] - upper[None, :]))
        damped[under[rows]] = upper[cols].imag / (2 * math.pi)
    shapes = np.stack([rows(vecs) for rows in rows_of], axis=1).transpose(2, 1, 0)  # (k, n, 6)
    scale = np.abs(shapes).reshape(k, -1).max(axis=1)
    shapes = shapes / scale[:, None, None]
    # Sign: the largest entry positive.
    flat = shapes.reshape(k, -1)
    sign = np.sign(flat[np.arange(k), np.abs(flat).argmax(axis=1)])
    shapes = shapes * sign[:, None, None]
    return Modes(
        frequency=omega / (2 * math.pi),
        omega=omega,
        damping_ratio=zeta,
        damped_frequency=damped,
        shapes=shapes,
        nodes=nodes,
        poles=poles[np.argsort(abs(poles))],
    )


def linearise(
    design: DesignLike | StaticSolution,
    pressures: ArrayLike | None = None,
    *,
    nodes: int = 12,
    tip_force: ArrayLike | None = None,
    tip_moment: ArrayLike | None = None,
    initial: StaticSolution | None = None,
    tensions: ArrayLike | None = None,
    tip_constraint: TipConstraint | str | dict | None = None,
    stiffness_map: StiffnessMap | None = None,
) -> LinearSystem:
    """The linearised dynamics of ``design`` about its equilibrium under ``pressures`` (Pa;
    default zero), the tendon ``tensions`` (N; default slack) and the tip loads (default the
    design's), or about ``initial`` when it is given (a :class:`StaticSolution`; its
    pressures, tensions, loads and tip constraint are used). ``nodes``: how many nodes carry
    the coordinates (spread over the integration nodes, the tip last). ``tip_constraint``
    (as in :func:`solve_statics`; default the design's ``[tip] constraint``) linearises the
    held equilibrium: a clamped tip does not move, so it is no coordinate (the nodes spread
    between the clamps, and a tip load's input columns are zero); a pinned tip keeps its
    three small rotations as coordinates (its displacement rows are not in q, and the tip
    force's input columns are zero). ``stiffness_map``: as in :func:`solve_statics`, for a
    design with a stiffness-mapped section (default the design's map); its pressure
    columns then carry the map's part, d sigma / d p (the map must give a derivative)."""
    from ..statics import _pressures, _vec3, solve_statics

    if isinstance(design, StaticSolution):
        initial, design = design, design.design
    design = load_design(design)
    nodes = integer(nodes, "nodes", minimum=1, maximum=200)
    k = design.frictional_obstacle
    if k is not None:
        raise design_error(
            f"obstacles[{k}].friction",
            design.spec["obstacles"][k]["friction"],
            "a frictional equilibrium has no linearisation: it depends on the load path, and "
            "the stick/slip switch has no derivative (obstacles without friction have one; "
            "docs/control.md, 'Follower loads and obstacles')",
            InputError,
        )
    if initial is None:
        p = _pressures(design, np.zeros(design.n_channels) if pressures is None else pressures)
        tip = design.spec["tip"]
        tf = _vec3(tip_force, "force", "tip_force", tip["force"])
        tm = _vec3(tip_moment, "moment", "tip_moment", tip["moment"])
        initial = solve_statics(
            design,
            p,
            tip_force=tf,
            tip_moment=tm,
            tensions=tensions,
            tip_constraint=tip_constraint,
            stiffness_map=stiffness_map,
        )
        t = [float(v) for v in initial.tensions]
    else:
        if not isinstance(initial, StaticSolution):
            raise design_error(
                "initial",
                initial,
                "must be a StaticSolution (the equilibrium to linearise about) or None",
                InputError,
            )
        if initial.design is not design and initial.design.spec != design.spec:
            raise design_error(
                "initial",
                initial.design.name,
                f"is an equilibrium of another design than {design.name!r}",
                InputError,
            )
        given = {
            "pressures": pressures,
            "tensions": tensions,
            "tip_force": tip_force,
            "tip_moment": tip_moment,
            "tip_constraint": tip_constraint,
            "stiffness_map": stiffness_map,
        }
        for name, value in given.items():
            if value is not None:
                raise design_error(
                    name,
                    value,
                    f"the equilibrium `initial` fixes the {name.replace('_', ' ')}; leave "
                    f"{name} out",
                    InputError,
                )
        p = [float(v) for v in initial.pressures]
        t = [float(v) for v in initial.tensions]
        tf = [float(v) for v in initial._tip_load("force")]
        tm = [float(v) for v in initial._tip_load("moment")]
    held = initial._held_args("initial", "linearisation")
    dsigma = initial._stiffness_map_derivative()  # before any work: refused without one
    if dsigma is not None:
        held["stiffness_scale"] = [float(v) for v in initial.stiffness_scale]
    out = _core.linearise_at(
        design._rod,
        p,
        tf,
        tm,
        initial._unknowns(),
        nodes,
        tensions=t,
        **held,
    )
    names = (
        tuple(f"p{c}" for c in range(design.n_channels))
        + INPUT_NAMES_LOADS
        + tuple(f"t{k}" for k in range(design.n_tendons))
    )
    b = np.asarray(out["input"])
    if dsigma is not None:
        # sigma(p) moves with the pressures: the core's last three columns are d / d sigma
        # at fixed pressures; add them times d sigma / d p to the pressures' columns.
        nc = design.n_channels
        b[:, :nc] += b[:, len(names) :] @ dsigma
        b = b[:, : len(names)].copy()
    return LinearSystem(
        design=design,
        pressures=np.array(p),
        nodes=out["nodes"],
        mass=out["mass"],
        damping=out["damping"],
        stiffness=out["stiffness"],
        input=b,
        input_names=names,
        equilibrium=initial,
        tip_constraint=initial.tip_constraint,
    )


@dataclass(frozen=True)
class SystemLinearSystem(_SecondOrder):
    """The linearised dynamics M q'' + D q' + K q = B u of a system of rods (a parallel
    continuum robot) about its equilibrium (SI; :meth:`softrod.SystemSolution.linearise`).

    q: every rod's inner nodes, rod by rod (six rows each: displacement, m, and small
    rotation, rad, world), then the platform's origin (its displacement and its small
    rotation, the last six rows: ``platform_rows``). A rod's tip is no coordinate: it moves
    with the platform. u: changes of every rod's pressures (Pa), then of every rod's
    tendon tensions (N), then of the platform's force (N) and moment (N m), named in
    ``input_names`` (rod0_p0 ..., rod0_t0 ..., F_x ... M_z). ``nodes``: the arc lengths of
    each rod's nodes (one array per rod, m). ``equilibrium`` is the system's solution it
    was taken at.
    """

    system: Any
    nodes: tuple[np.ndarray, ...]
    mass: np.ndarray
    damping: np.ndarray
    stiffness: np.ndarray
    input: np.ndarray
    input_names: tuple[str, ...]
    equilibrium: Any = field(repr=False)

    @property
    def platform_rows(self) -> slice:
        """Rows of q holding the platform's displacement and small rotation."""
        n = self.mass.shape[0]
        return slice(n - 6, n)

    def node_rows(self, x: np.ndarray, rod: int, node: int) -> np.ndarray:
        """The six pose rows of node ``node`` of rod ``rod`` (indices, negative from the
        end) of ``x``, a vector or matrix over q (its first axis)."""
        nr = len(self.nodes)
        i = V.integer(rod, "rod", minimum=-nr, maximum=nr - 1, hint=f" (the {nr} rods)") % nr
        n = len(self.nodes[i])
        k = V.integer(node, "node", minimum=-n, maximum=n - 1, hint=f" (rod {i}'s {n} nodes)") % n
        x = _over_q(self, x)
        start = 6 * (sum(len(v) for v in self.nodes[:i]) + k)
        return x[start : start + 6]

    def frequency_response(
        self, omega: float, *, rod: int | None = None, node: int | None = None
    ) -> np.ndarray:
        """The platform's pose (6 rows) per unit input at angular frequency ``omega``
        (rad/s): T (K - w^2 M + i w D)^-1 B. ``rod`` (and ``node``, default its last): the
        pose of that rod's node instead; a ``node`` without its ``rod`` is refused."""
        V.real(omega, "omega", minimum=0.0, maximum=1e12)
        if rod is None:
            if node is not None:
                raise design_error(
                    "rod",
                    None,
                    f"node={node!r} needs the rod it is on (rod=...); without both the "
                    "response is the platform's",
                    InputError,
                )
            return self._response(omega)[self.platform_rows]
        node = -1 if node is None else node
        self.node_rows(np.zeros(self.mass.shape[0]), rod, node)  # before any work
        return self.node_rows(self._response(omega), rod, node)

    def plot_modes(
        self,
        count: int = 3,
        path: str | os.PathLike | None = None,
        *,
        title: str | None = None,
    ) -> Figure:
        """The ``count`` lowest mode shapes (at most 8) over the equilibrium, front (x-z)
        and side (y-z) views: every rod through its nodes to its tip, which moves with the
        platform, and the platform's outline
        (:func:`softrod.control.mode_plots.plot_system_modes`). Written to ``path`` when
        given; returns the Figure."""
        from .mode_plots import plot_system_modes

        return plot_system_modes(self, count, path, title=title)

    def modes(self, count: int | None = None) -> Modes:
        """The ``count`` lowest modes (default all). ``shapes`` (k, points, 6) has a row per
        node, rod by rod, then the platform's (its origin), and ``nodes`` the arc length of
        each of those rows (m), NaN for the platform's."""
        rows_of = [
            (lambda x, i=i, k=k: self.node_rows(x, i, k))
            for i, v in enumerate(self.nodes)
            for k in range(len(v))
        ]
        rows_of.append(lambda x: _over_q(self, x)[self.platform_rows])
        nodes = np.concatenate([*self.nodes, [np.nan]])
        return _modes(self, count, rows_of, nodes)


def _over_q(system: _SecondOrder, x: np.ndarray) -> np.ndarray:
    """``x`` as an array whose first axis runs over q; InputError naming ``x`` otherwise."""
    x = np.asarray(x)
    if x.shape[:1] != system.mass.shape[:1]:
        raise design_error(
            "x",
            f"shape {x.shape}",
            f"must run over the {system.mass.shape[0]} coordinates of q along its first axis",
            InputError,
        )
    return x
