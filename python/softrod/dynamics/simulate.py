"""``simulate``: the motion of a design under a pressure schedule (docs/dynamics.md).

The physics and the time stepping live in the Rust core (``softrod_core::dynamics``:
paper 000's Kelvin-Voigt Cosserat rod; BDF-alpha or the implicit midpoint rule in time as in
Till, Aloi and Rucker, IJRR 2019; Gauss collocation in space with an exact block-banded
Newton). This module turns user input into SI arrays, drives the core in chunks so that long
runs can show progress, and packs the result into a :class:`~softrod.dynamics.Trajectory`.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import math
import os
import re
import time as _time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .. import _core
from .. import _validate as V
from ..catalog import load_design
from ..constraints import TipConstraint, require_free_tip
from ..constraints import coerce as coerce_constraint
from ..datasets import parse_marker_sites
from ..design import Design
from ..errors import InputError, design_error
from ..progress import chunks, reporter
from .schedule import PressureSchedule
from .trajectory import ENERGY_PARTS, Trajectory

if TYPE_CHECKING:
    from .._types import ArrayLike, DesignLike, Quantity
    from ..stiffness_map import StiffnessMap
    from .schedule import ScheduleLike

    # Held (force, moment) in N and N m, or a function of t returning them.
    TipLoad = tuple[ArrayLike, ArrayLike] | Callable[[float], tuple[ArrayLike, ArrayLike]]
    # Tendon tensions (N, one per tendon channel): held constant, or a function of t.
    Tensions = ArrayLike | Callable[[float], ArrayLike]
    # How the tip is held: a TipConstraint, "free" or a mapping (fixed), or a function of
    # t (s) returning one (a moving pose).
    TipHold = TipConstraint | str | dict | Callable[[float], TipConstraint | str | dict]

__all__ = ["METHOD", "SCHEMES", "Simulation", "SimulationState", "simulate"]

METHOD = (
    "{scheme} in time (Till, Aloi, Rucker, IJRR 2019), Gauss collocation in space "
    "(4th order, block-banded Newton)"
)
SCHEMES = ("bdf-alpha", "midpoint")
DEFAULT_ENERGY_TOL = 0.02  # softrod_core::dynamics::DEFAULT_ENERGY_TOL

logger = logging.getLogger(__name__)


def _no_stiffness_map(design: Design) -> None:
    """Dynamics have no pressure-dependent stiffness scaling (yet): a design that needs one
    is refused rather than simulated with sigma = 1."""
    mapped = [
        s["name"]
        for s in design.spec["sections"]
        if (s.get("law") or {}).get("stiffness_map", False)
    ]
    if mapped:
        raise design_error(
            "design",
            design.name,
            f"section(s) {', '.join(mapped)} set [sections.law] stiffness_map = true: the "
            "dynamics do not support a stiffness map sigma(p) (paper 001's static model); "
            "simulate a design without mapped sections",
            InputError,
        )


def _fingerprint(design: Design, sigma: dict | None = None) -> str:
    """A digest of the design's SI document and of the stiffness map's numbers the core
    evaluates (``sigma``, :func:`core_sigma`'s arguments; none: the design alone): a saved
    state only restores into the same model."""
    doc = design.spec if not sigma else {"design": design.spec, "sigma": sigma}
    text = json.dumps(doc, sort_keys=True)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


#: BDF-alpha's parameter when ``alpha`` is not given.
DEFAULT_ALPHA = -0.2


def _solver_options(scheme, alpha, tol, max_iter, error_tol, energy_tol) -> dict:
    """The integrator's keyword options, checked here (the core checks them again).
    ``alpha`` None: :data:`DEFAULT_ALPHA`; given with the midpoint rule, which has no
    parameter, it is refused rather than ignored."""
    V.choice(scheme, SCHEMES, "scheme")
    if alpha is not None and scheme == "midpoint":
        raise design_error(
            "alpha",
            alpha,
            "is BDF-alpha's parameter; the midpoint rule (scheme='midpoint') has none: leave "
            "alpha out",
            InputError,
        )
    alpha = V.real(DEFAULT_ALPHA if alpha is None else alpha, "alpha", minimum=-0.5, maximum=0.0)
    tol = V.real(tol, "tol", minimum=0.0, exclusive=True, maximum=1.0)
    max_iter = V.integer(max_iter, "max_iter", minimum=1, maximum=V.MAX_ITERATIONS)
    if error_tol is not None:
        error_tol = V.quantity(error_tol, "length", "error_tol")
        if not error_tol > 0:
            raise design_error(
                "error_tol",
                error_tol,
                "must be a length > 0 (the local error of the node positions per step, "
                "e.g. '0.1 mm')",
                InputError,
            )
    energy_tol = V.real(
        energy_tol, "energy_tol", minimum=0.0, exclusive=True, what="a fraction of the energy moved"
    )
    return {
        "scheme": scheme,
        "alpha": alpha,
        "tol": tol,
        "max_iter": max_iter,
        "error_tol": error_tol,
        "energy_tol": energy_tol,
    }


def _sigma_args(design: Design, stiffness_map) -> dict:
    """The core's stiffness-map arguments (the map given, else the design file's): sigma is
    evaluated in the core at every step's pressures, so only maps the core can evaluate
    (constant, PCHIP table) run in dynamics."""
    from ..statics import _stiffness_map

    return core_sigma(_stiffness_map(design, stiffness_map), design.n_channels)


def core_sigma(smap, n_channels: int, field: str = "stiffness_map") -> dict:
    """The core's arguments (``sigma_const`` or ``sigma_grid``) of a checked stiffness map
    (None: none) of a design with ``n_channels``; a map the core cannot evaluate at every
    step (a network, a regressor, a callable, a non-PCHIP table) is refused naming
    ``field``."""
    if smap is None:
        return {}
    if smap.kind == "constant":
        sigma = smap(np.zeros((1, n_channels)))[0]
        return {"sigma_const": [float(x) for x in sigma]}
    axes = smap.axes
    two_point = axes is not None and all(len(a) == 2 for a in axes)
    if smap.kind == "table" and (smap._method == "pchip" or two_point):
        values = np.asarray(smap.values, dtype=float)
        return {
            "sigma_grid": (
                [np.asarray(a, dtype=float).tolist() for a in axes],
                values.ravel().tolist(),
                smap._outside == "clamp",
            )
        }
    raise design_error(
        field,
        repr(smap),
        "dynamics evaluates sigma in the core at every step: use StiffnessMap.constant or "
        "StiffnessMap.from_table(..., method='pchip') (tabulate a trained regressor over "
        "your pressure range first)",
        InputError,
    )


@dataclass(frozen=True, eq=False)
class SimulationState:
    """A :class:`Simulation`'s state at one time (SI). The named fields are what a
    controller reads; ``data`` holds everything the core needs to continue exactly
    (:meth:`Simulation.restore` reproduces the run from here bit for bit).

    ``time`` s; ``pressure`` (c,) Pa (actual chamber pressures); ``tensions`` (k,) N
    (tendon tensions now); ``tip_force``, ``tip_moment`` (3,) N, N m (tip loads now, in the
    design's tip frame: world for dead loads, body for follower loads); ``tip_position`` (3,) m,
    ``tip_rotation`` (3, 3) [d1 d2 d3], ``tip_velocity`` (3,) m/s; ``base_force``,
    ``base_moment`` (3,) N, N m; ``shape_s`` (p,) m and ``shape_position`` (p, 3) m (the
    centreline at the nodes); ``energy`` J (kinetic + elastic + potential) and its books
    ``kinetic``, ``elastic``, ``potential``, ``work_in``, ``dissipated`` J;
    ``energy_balance`` J (zero for the exact motion); ``tip_reaction_force``,
    ``tip_reaction_moment`` (3,) N, N m (the wrench a held tip's constraint applies, world;
    zero for a free tip); ``marker_position`` (K, 3) m (the simulation's markers, world;
    None without markers); ``design`` and
    ``fingerprint`` (the design and stiffness map it belongs to); ``data`` (read-only float
    array).
    """

    design: str
    fingerprint: str
    time: float
    pressure: np.ndarray
    tip_force: np.ndarray
    tip_moment: np.ndarray
    tip_position: np.ndarray
    tip_rotation: np.ndarray
    tip_velocity: np.ndarray
    base_force: np.ndarray
    base_moment: np.ndarray
    shape_s: np.ndarray
    shape_position: np.ndarray
    energy: float
    kinetic: float
    elastic: float
    potential: float
    work_in: float
    dissipated: float
    energy_balance: float
    data: np.ndarray
    tensions: np.ndarray = dataclasses.field(default_factory=lambda: _ro(np.zeros(0)))
    tip_reaction_force: np.ndarray = dataclasses.field(default_factory=lambda: _ro(np.zeros(3)))
    tip_reaction_moment: np.ndarray = dataclasses.field(default_factory=lambda: _ro(np.zeros(3)))
    marker_position: np.ndarray | None = None

    def __repr__(self) -> str:
        tip = ", ".join(f"{x * 1e3:.2f}" for x in self.tip_position)
        return (
            f"SimulationState({self.design!r}, t = {self.time:g} s, tip ({tip}) mm, "
            f"E = {self.energy:.6g} J)"
        )


def simulated_time(done: float, total: float, wall: float) -> tuple[float, str]:
    """A progress bar's position and text for simulate's progress(t_done, t_end, wall_s)."""
    rtf = f"{done / wall:,.0f}x real time" if wall > 0 else ""
    return done, f"{done:.2f} / {total:g} s {rtf}"


def _seconds(value, field: str, *, positive: bool = True) -> float:
    x = V.quantity(value, "time", field)
    if positive and x <= 0:
        raise design_error(field, value, "must be > 0 s", InputError)
    return x


def step_count(duration: float, dt: float, field: str = "t_end") -> int:
    """ceil(duration / dt) time steps, refused beyond MAX_DYNAMIC_STEPS before anything is
    allocated (a 1e-9 s step over 1 s would otherwise build a 1e9-row command table)."""
    ratio = duration / dt * (1.0 - 1e-12)
    if not ratio <= V.MAX_DYNAMIC_STEPS:
        raise design_error(
            field,
            f"{duration:g} s at dt = {dt:g} s",
            f"needs {ratio:.3g} time steps; the limit is {V.MAX_DYNAMIC_STEPS:,} per run "
            "(use a larger dt, a shorter run, or several runs continued with initial=)",
            InputError,
        )
    return max(1, math.ceil(ratio))


def _save_every(save_every) -> int:
    return V.integer(save_every, "save_every", minimum=1, maximum=V.MAX_DYNAMIC_STEPS)


def _check_saved(n: int, save_every: int, shape_rows: int, nodes: int) -> None:
    """Refuse runs whose trajectory would not fit the documented limits."""
    saved = n // save_every + 2
    if saved > V.MAX_SAVED_SAMPLES:
        raise design_error(
            "save_every",
            save_every,
            f"keeps {saved:,} samples of {n:,} steps; the limit is {V.MAX_SAVED_SAMPLES:,} "
            "(keep every n-th step with a larger save_every)",
            InputError,
        )
    if shape_rows * nodes > V.MAX_SHAPE_POINTS:
        raise design_error(
            "shapes",
            f"{shape_rows:,} shapes of {nodes} nodes",
            f"would keep {shape_rows * nodes:,} centreline points; the limit is "
            f"{V.MAX_SHAPE_POINTS:,} (keep fewer shapes)",
            InputError,
        )


_NUMBER_FIRST = re.compile(r"\s*[-+]?(\d|\.\d)")


def _pressure_text(value) -> bool:
    """Whether ``value`` is a string that reads as one pressure ("30 kPa") and names no file:
    a schedule's text is a file path otherwise."""
    if not isinstance(value, str) or os.path.exists(value):
        return False
    if os.path.splitext(value)[1].lower() in (".csv", ".parquet"):
        return False
    if not _NUMBER_FIRST.match(value):
        return False
    V.quantity(value, "pressure", "pressure_schedule")  # '30 m' is refused: not a pressure
    return True


def _schedule(schedule, n_channels: int) -> PressureSchedule:
    """A PressureSchedule from a schedule, a file path, a callable, constant pressures or (for
    a one-channel design) one constant pressure."""
    if isinstance(schedule, PressureSchedule):
        out = schedule
    elif V.is_real(schedule) or _pressure_text(schedule):
        # One constant pressure, as solve_statics and Simulation take it for a one-channel
        # design; with more channels check_channels says how many are needed.
        out = PressureSchedule.constant([schedule])
    elif isinstance(schedule, str | os.PathLike):
        out = PressureSchedule.from_file(schedule)
    elif callable(schedule):
        out = PressureSchedule.from_callable(schedule, n_channels)
    elif isinstance(schedule, Sequence | np.ndarray):
        out = PressureSchedule.constant(schedule)
    else:
        raise design_error(
            "pressure_schedule",
            type(schedule).__name__,
            "must be a PressureSchedule, a CSV/Parquet path, a function of t (s) returning "
            "pressures (Pa), or constant pressures (Pa)",
            InputError,
        )
    out.check_channels(n_channels)
    return out


class Simulation:
    """A running simulation of a design: the state (shape, velocities, chamber pressures and
    the integrator's history) advanced step by step. Use it for control loops; use
    :func:`simulate` for a whole schedule.

    ``pressures``: chamber pressures at t = 0 in Pa (default zero). ``initial``: ``"static"`` (at
    rest in equilibrium under those pressures, gravity and the design's tip loads), ``"straight"``
    (at rest in the straight shape, released at t = 0: a rod whose reference shape is straight) or
    ``"reference"`` (at rest in the reference shape with no internal force, released at t = 0: a
    pre-bent finger let go; for a straight reference the same as ``"straight"``). ``dt``: time step
    (s or a string with units). ``scheme``: ``"bdf-alpha"`` (default; ``alpha`` in [-0.5, 0],
    default -0.2: -0.5 is paper 000's trapezoidal rule, 0 BDF2; below -0.45 unresolved modes are not
    damped) or ``"midpoint"`` (the implicit midpoint rule: conserves the energy of undamped runs;
    docs/dynamics.md). ``tol``: Newton tolerance on the scaled collocation unknowns at each step.
    ``error_tol``: adaptive time stepping, the largest estimated local error of the node positions
    per step (m or a string such as "0.1 mm"); each ``dt`` is then split into as many steps as that
    needs. ``energy_tol``: the energy check's tolerance (fraction of the energy moved).
    ``stiffness_map``: the StiffnessMap of a design with mapped sections (constant or PCHIP table).
    ``tensions``: tendon tensions at t = 0 (N or strings with units, one per tendon channel, each >=
    0; None: slack); the static start balances them, and :meth:`set_tensions` or the ``tensions`` of
    :meth:`step` and :meth:`run` change them. ``tip_constraint``: how the tip is held at t = 0 (a
    :class:`~softrod.TipConstraint`, "free" or a mapping as :func:`~softrod.solve_statics` takes;
    None: the design's ``[tip] constraint``); a pinned or clamped tip starts "static" in the
    constrained equilibrium, "straight" (or "reference" of a straight rod) only at the straight
    rod's tip pose, and moves with :meth:`set_tip_pose` or the ``tip_constraint`` of :meth:`run`
    (docs/dynamics.md, "Held tip"). ``markers``: motion-capture markers on the body, read at every
    recorded sample into the trajectory's ``marker_position``: a list of ``(s, offset)`` (arc length
    from the base in [0, L], offset (d1, d2[, d3]) in the cross-section frame) or ``s`` alone, SI
    numbers or strings with units, checked before the start is solved; :meth:`set_markers` changes
    them later (docs/dynamics.md, "Markers on the moving rod"). ``on_unstable``: what a "static"
    start at an unstable equilibrium does, as :func:`simulate` says ("warn", "raise" or "ignore");
    :attr:`start_stable` keeps the verdict."""

    def __init__(
        self,
        design: DesignLike,
        pressures: ArrayLike | None = None,
        *,
        initial: str = "static",
        dt: Quantity = 2e-3,
        scheme: str = "bdf-alpha",
        alpha: float | None = None,
        tol: float = 1e-9,
        max_iter: int = 25,
        error_tol: Quantity | None = None,
        energy_tol: float = DEFAULT_ENERGY_TOL,
        stiffness_map: StiffnessMap | None = None,
        tensions: ArrayLike | None = None,
        tip_constraint: TipConstraint | str | dict | None = None,
        markers: Sequence | None = None,
        on_unstable: str = "warn",
        _tip_loads0: Sequence[float] | None = None,
    ) -> None:
        from ..statics import _policy, _pressures, _report_stability, _tensions

        self.design: Design = load_design(design)
        held = _held(self.design, tip_constraint)
        sites = parse_marker_sites(markers, self.design.length)
        n = self.design.n_channels
        p = [0.0] * n if pressures is None else _pressures(self.design, pressures)
        t0 = _tensions(self.design, tensions)
        V.choice(initial, ("static", "straight", "reference"), "initial")
        on_unstable = _policy("on_unstable", on_unstable)
        opts = _solver_options(scheme, alpha, tol, max_iter, error_tol, energy_tol)
        sigma = _sigma_args(self.design, stiffness_map)
        self._sim = _core.Simulator(
            json.dumps(self.design.spec, allow_nan=False),
            p,
            initial,
            _seconds(dt, "dt"),
            **opts,
            **sigma,
            **(
                {}
                if _tip_loads0 is None
                else {"tip_force": list(_tip_loads0[:3]), "tip_moment": list(_tip_loads0[3:])}
            ),
            tensions=t0,
            **_hold_args(held),
        )
        self.initial = initial
        self._fingerprint = _fingerprint(self.design, sigma)
        self.options = opts
        self._markers = None
        self._set_sites(sites)
        if initial == "static":
            # An unstable start is still a start, but a coarse step can hold it there for
            # ever (implicit steps damp the growing mode): say so, as solve_statics does.
            _report_stability(
                self._sim.start_stable, on_unstable, f"the initial static state at pressures {p} Pa"
            )

    @property
    def start_stable(self) -> bool | None:
        """The 'static' start's stability (False: the run started from an unstable
        equilibrium, which a small disturbance leaves, though a coarse time step may hold
        it); None for a 'straight' start or where it is not assessed (follower loads)."""
        return self._sim.start_stable

    @classmethod
    def _wrap(
        cls, design: Design, sim, initial: str, options: dict, markers, fingerprint: str
    ) -> Simulation:
        obj = cls.__new__(cls)
        obj.design, obj._sim, obj.initial, obj.options = design, sim, initial, options
        obj._markers, obj._fingerprint = markers, fingerprint
        return obj

    def copy(self) -> Simulation:
        """An independent simulation starting from this one's current state (exact), with
        the same markers."""
        return Simulation._wrap(
            self.design,
            self._sim.copy(),
            self.initial,
            dict(self.options),
            self._markers,
            self._fingerprint,
        )

    @property
    def markers(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The markers read at every sample: (s (K,), offset (K, 3)) in m, or None."""
        return self._markers

    def set_markers(self, markers: Sequence | None) -> None:
        """Read these motion-capture markers from now on (None: none): as the constructor's
        ``markers``, checked in full before anything changes. The next :meth:`run`'s
        trajectory records their positions at every sample, and :meth:`state` reads them."""
        self._set_sites(parse_marker_sites(markers, self.design.length))

    def _set_sites(self, sites) -> None:
        if sites is None and self._markers is None:
            return
        pairs = (
            [] if sites is None else [(float(a), b.tolist()) for a, b in zip(*sites, strict=True)]
        )
        self._sim.set_markers(pairs)
        self._markers = None if sites is None else (_ro(sites[0]), _ro(sites[1]))

    def __repr__(self) -> str:
        return (
            f"Simulation({self.design.name!r}, t = {self.time:g} s, dt = {self.dt * 1e3:g} ms, "
            f"{self.options['scheme']})"
        )

    @property
    def alpha(self) -> float:
        """The BDF-alpha parameter."""
        return self.options["alpha"]

    @property
    def time(self) -> float:
        """Simulated time now, s."""
        return self._sim.time

    @property
    def dt(self) -> float:
        """Time step, s."""
        return self._sim.dt

    @property
    def pressures(self) -> np.ndarray:
        """Chamber pressures now, Pa (after the design's supply lag and rate limit)."""
        return np.asarray(self._sim.pressures)

    @property
    def tensions(self) -> np.ndarray:
        """Tendon tensions now (those of the next step), N."""
        return np.asarray(self._sim.tensions, dtype=float)

    def set_tensions(self, tensions: ArrayLike | None) -> None:
        """Tendon tensions (N or strings with units, one per tendon channel, each >= 0;
        None: slack) from the next step on, held until changed. The energy books count
        their work (docs/dynamics.md)."""
        from ..statics import _tensions

        self._sim.set_tensions(_tensions(self.design, tensions))

    @property
    def tip_constraint(self) -> TipConstraint:
        """How the tip is held (its kind is fixed for the run)."""
        d = self._sim.snapshot()
        kind = str(d["tip_kind"])
        if kind == "free":
            return TipConstraint.free()
        pos = list(d["tip_pose_position"])
        if kind == "pinned":
            return TipConstraint.pinned(pos)
        return TipConstraint.clamped(pos, np.asarray(d["tip_pose_rotation"]))

    def set_tip_pose(self, pose: TipConstraint | str | dict) -> None:
        """Move a held tip: its pose (a :class:`~softrod.TipConstraint` or mapping of the
        run's kind; units accepted) at the end of the next step, reached linearly in
        position and along the geodesic in rotation by the steps in between."""
        self._sim.set_tip_pose(*coerce_constraint(pose).core_args())

    @property
    def stats(self) -> dict:
        """Steps (calls), internal (time) steps, rejected steps, Newton iterations and exact
        Jacobians so far."""
        return dict(self._sim.stats)

    def state(self) -> SimulationState:
        """The state now: a :class:`SimulationState`, which :meth:`restore` continues
        from exactly."""
        d = self._sim.snapshot()
        ro = lambda a: _ro(np.asarray(a, dtype=float))  # noqa: E731
        return SimulationState(
            design=self.design.name,
            fingerprint=self._fingerprint,
            time=float(d["time"][0]),
            pressure=ro(d["pressure"][0]),
            tip_force=ro(d["tip_force"]),
            tip_moment=ro(d["tip_moment"]),
            tip_position=ro(d["tip_position"][0]),
            tip_rotation=ro(d["tip_rotation"][0]),
            tip_velocity=ro(d["tip_velocity"][0]),
            base_force=ro(d["base_force"]),
            base_moment=ro(d["base_moment"]),
            shape_s=ro(d["shape_s"]),
            shape_position=ro(d["shape_position"][0]),
            energy=float(d["energy"][0]),
            **{k: float(d[k][0]) for k in ENERGY_PARTS},
            energy_balance=float(d["energy_balance"]),
            data=ro(self._sim.save()),
            tensions=ro(d["tensions"]),
            tip_reaction_force=ro(d["tip_reaction_force"][0]),
            tip_reaction_moment=ro(d["tip_reaction_moment"][0]),
            marker_position=ro(d["marker_position"][0]) if "marker_position" in d else None,
        )

    def restore(self, state: SimulationState) -> None:
        """Continue from ``state`` (taken from a simulation of the same design): the next
        steps are bit for bit those the original simulation would take. The motion is the
        state's; the markers read are this simulation's own (:meth:`set_markers`), whichever
        the state was taken with."""
        if not isinstance(state, SimulationState):
            raise design_error(
                "state", type(state).__name__, "must be a SimulationState", InputError
            )
        if state.fingerprint != self._fingerprint:
            raise design_error(
                "state",
                repr(state),
                f"was taken from design {state.design!r}, not from this simulation's "
                f"{self.design.name!r} (or from another version of it, or with another "
                "stiffness map)",
                InputError,
            )
        self._sim.restore(np.ascontiguousarray(state.data, dtype=float))

    def set_tip_loads(
        self, force: ArrayLike = (0.0, 0.0, 0.0), moment: ArrayLike = (0.0, 0.0, 0.0)
    ) -> None:
        """Tip force (N) and moment (N m) from the next step on, in the design's tip frame
        (``[tip] frame``: world for dead loads, body for follower loads)."""
        from ..statics import _vec3

        for name, value in (("force", force), ("moment", moment)):
            if value is None:
                raise V.fail(name, None, f"must be 3 {name} values; [0, 0, 0] for none")
        f = _vec3(force, "force", "force", None)
        m = _vec3(moment, "moment", "moment", None)
        self._sim.set_tip_loads(f, m)

    def step(self, command: ArrayLike | None = None, *, tensions: ArrayLike | None = None) -> None:
        """One time step towards the commanded pressures ``command`` (Pa; None for a design
        without chambers), with the tendon ``tensions`` (N, one per tendon channel) from
        this step on when given (None keeps the current ones; see :meth:`set_tensions`)."""
        from ..statics import _pressures, _tensions

        if command is None and self.design.n_channels == 0:
            c = np.zeros((1, 0))
        else:
            c = np.asarray([_pressures(self.design, command)], dtype=float)
        if tensions is not None:
            # Checked (with the pressures) before anything changes.
            self._sim.set_tensions(_tensions(self.design, tensions))
        self._sim.run(c, np.zeros(1, dtype=np.uint8), False)

    def run(
        self,
        pressure_schedule: ScheduleLike,
        duration: Quantity,
        *,
        save_every: int = 1,
        shapes: str | float | Sequence[float] | None = None,
        energy: bool = True,
        tip_load: TipLoad | None = None,
        tensions: Tensions | None = None,
        tip_constraint: TipHold | None = None,
        progress: Callable[[float, float, float], None] | None = None,
    ) -> Trajectory:
        """Advance by ``duration`` (s) under ``pressure_schedule`` (evaluated on this
        simulation's clock; None for a design without chambers) and return the trajectory
        from the current time on; see :func:`simulate` for the arguments (``tensions``:
        None keeps the current tensions; ``tip_constraint``: None holds the tip where it
        is, a pose of the run's kind moves it there, a function of t moves it along)."""
        dt = self.dt
        duration = _seconds(duration, "t_end")
        n = step_count(duration, dt)
        save_every = _save_every(save_every)
        V.boolean(energy, "energy")
        nc = self.design.n_channels
        schedule = (
            None if pressure_schedule is None and nc == 0 else _schedule(pressure_schedule, nc)
        )
        t0 = self.time
        shape_steps, want_shape0 = _shape_steps(shapes, n, dt, save_every)
        nodes = len(self._sim.snapshot()["shape_s"])
        _check_saved(n, save_every, len(shape_steps) + int(want_shape0), nodes)
        keep = np.zeros(n, dtype=np.uint8)
        keep[save_every - 1 :: save_every] = 1
        keep[-1] = 1
        keep[shape_steps] = 2
        first = self._sim.snapshot()
        parts = [first]

        def commands_at(t: np.ndarray) -> np.ndarray:
            return np.zeros((t.size, 0)) if schedule is None else schedule.sample(t)

        kept_commands = [commands_at(np.array([t0]))]
        # Steps inside an interval (substeps, adaptive steps) read a table schedule at their
        # own times; a callable's is sampled at the intervals' ends only.
        table = None
        if schedule is not None and schedule.kind in ("linear", "step"):
            table = (
                schedule.times.tolist(),
                schedule.pressures.tolist(),
                schedule.kind == "step",
            )
        wall0 = _time.perf_counter()
        # The run takes n whole steps: it ends at n dt >= duration, and its reports rise
        # to that.
        span = n * dt
        with reporter(progress, "simulate", span, simulated_time) as report:
            for start, stop in chunks(n):
                # Commands and loads are sampled chunk by chunk: memory stays bounded.
                times = t0 + dt * np.arange(start + 1, stop + 1)
                commands = commands_at(times)
                loads = _tip_loads(tip_load, times)
                tens = _tension_rows(self.design, tensions, times)
                poses = _pose_rows(tip_constraint, times, str(first["tip_kind"]))
                kept_commands.append(commands[keep[start:stop] >= 1])
                parts.append(
                    self._sim.run(
                        np.ascontiguousarray(commands),
                        keep[start:stop],
                        bool(energy),
                        None if loads is None else np.ascontiguousarray(loads),
                        table,
                        None if tens is None else np.ascontiguousarray(tens),
                        None if poses is None else np.ascontiguousarray(poses),
                    )
                )
                if report is not None:
                    report(self.time - t0, span, _time.perf_counter() - wall0)
        wall = _time.perf_counter() - wall0
        logger.info(
            "simulate %s: %d steps of %g s in %.3g s (%.3g x real time)",
            self.design.name,
            n,
            dt,
            wall,
            (n * dt) / wall if wall > 0 else math.inf,
        )
        cat = lambda key: np.concatenate([p[key] for p in parts])  # noqa: E731
        shape_parts = [p for p in (parts if want_shape0 else parts[1:]) if len(p["shape_time"])]
        opts = self.options
        metadata = {
            "design": self.design.name,
            "model": "cosserat",
            "method": METHOD.format(
                scheme="the implicit midpoint rule"
                if opts["scheme"] == "midpoint"
                else f"BDF-alpha (alpha = {opts['alpha']:g})"
            ),
            "scheme": opts["scheme"],
            "dt_s": dt,
            "alpha": opts["alpha"],
            "tol": opts["tol"],
            "error_tol_m": opts["error_tol"],
            "energy_tol": opts["energy_tol"],
            "initial": self.initial,
            "tip_constraint": str(first["tip_kind"]),
            "damping_time_s": self.design.spec["dynamics"]["damping_time"],
            "steps": n,
            "wall_time_s": wall,
            "real_time_factor": (n * dt) / wall if wall > 0 else math.inf,
            **{k: int(v) for k, v in self._sim.stats.items()},
        }
        return Trajectory(
            time=cat("time"),
            command=np.concatenate(kept_commands),
            pressure=cat("pressure"),
            tension=cat("tension"),
            # (A chunk that keeps no sample has no contact arrays.)
            **(
                {
                    k: np.concatenate([p[k] for p in parts if k in p])
                    for k in ("contact_force", "penetration")
                }
                if "penetration" in first
                else {}
            ),
            tip_position=cat("tip_position"),
            tip_rotation=cat("tip_rotation"),
            tip_velocity=cat("tip_velocity"),
            **(
                {k: cat(k) for k in ("tip_reaction_force", "tip_reaction_moment")}
                if str(first["tip_kind"]) != "free"
                else {}
            ),
            energy=cat("energy") if energy else None,
            **({k: cat(k) for k in ENERGY_PARTS} if energy else {}),
            shape_time=np.concatenate([p["shape_time"] for p in shape_parts])
            if shape_parts
            else None,
            shape_s=first["shape_s"] if shape_parts else None,
            shape_position=np.concatenate([p["shape_position"] for p in shape_parts])
            if shape_parts
            else None,
            **(
                {
                    "marker_position": cat("marker_position"),
                    "marker_s": self._markers[0],
                    "marker_offset": self._markers[1],
                }
                if self._markers is not None
                else {}
            ),
            metadata=metadata,
        )


def _held(design: Design, value) -> TipConstraint:
    """The tip constraint of a run: ``value`` (a TipConstraint, "free" or a mapping), or
    the design's ``[tip] constraint`` when None."""
    if value is not None:
        return coerce_constraint(value)
    return getattr(design, "tip_constraint", None) or TipConstraint.free()


def _hold_args(held: TipConstraint) -> dict:
    kind, position, rotation = held.core_args()
    return {"tip_kind": kind, "tip_position": position, "tip_rotation": rotation}


def _pose_rows(tip_constraint, times: np.ndarray, kind: str) -> np.ndarray | None:
    """(n, 12) poses (position m, rotation row-major) of a held tip at the step times, or
    None (hold the tip where it is). ``tip_constraint``: None, a pose held from the next
    step on, or a function of t (s) returning one (sampled at the step times); each of the
    run's ``kind``."""
    if tip_constraint is None:
        return None

    def row(value, field: str) -> list[float]:
        try:
            c = coerce_constraint(value)
        except InputError as exc:
            # tip_constraint.position -> tip_constraint(t = 0.1 s).position
            at = exc.field.replace("tip_constraint", field, 1) if exc.field else field
            raise design_error(at, exc.value, exc.rule or str(exc), InputError) from None
        if c.kind != kind:
            raise design_error(
                field,
                c.kind,
                f"this run's tip is {kind}: give a {kind} pose (the kind is fixed for a run)",
                InputError,
            )
        if c.kind == "free":
            return [0.0] * 12
        rot = np.eye(3) if c.rotation is None else np.asarray(c.rotation, dtype=float)
        return [*c.position, *rot.reshape(9).tolist()]

    if callable(tip_constraint):
        rows = [row(tip_constraint(float(t)), f"tip_constraint(t = {t:g} s)") for t in times]
    else:
        rows = [row(tip_constraint, "tip_constraint")] * len(times)
    return np.array(rows, dtype=float).reshape(len(times), 12)


def coerce_constraint_at0(value) -> str:
    """The kind of a moving pose's value at t = 0 (errors name ``tip_constraint(t = 0 s)``)."""
    try:
        return coerce_constraint(value).kind
    except InputError as exc:
        at = (exc.field or "tip_constraint").replace("tip_constraint", "tip_constraint(t = 0 s)", 1)
        raise design_error(at, exc.value, exc.rule or str(exc), InputError) from None


def _ro(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


def _vector(value, field: str, kind: str) -> list[float]:
    """Three finite numbers (SI), or strings with units of ``kind``."""
    from ..statics import _vec3

    if value is None:
        raise design_error(
            field, value, f"must be 3 {kind} values (in the design's tip frame)", InputError
        )
    return _vec3(value, kind, field, None)


def _tip_loads(tip_load, times: np.ndarray) -> np.ndarray | None:
    """(n, 6) dead tip force (N) and moment (N m) at the step times, or None (the design's
    own tip loads). ``tip_load``: None, a pair (force, moment) held constant, or a
    function of t (s) returning such a pair."""
    if tip_load is None:
        return None
    if callable(tip_load):
        rows = []
        for t in times:
            raw = tip_load(float(t))
            if not (isinstance(raw, tuple | list) and len(raw) == 2):
                raise design_error(
                    f"tip_load(t = {t:g} s)",
                    raw,
                    "must return a pair (force (3,) in N, moment (3,) in N m)",
                    InputError,
                )
            f = _vector(raw[0], f"tip_load(t = {t:g} s)[0]", "force")
            m = _vector(raw[1], f"tip_load(t = {t:g} s)[1]", "moment")
            rows.append(f + m)
        return np.array(rows, dtype=float).reshape(len(times), 6)
    if isinstance(tip_load, tuple | list) and len(tip_load) == 2:
        f = _vector(tip_load[0], "tip_load[0]", "force")
        m = _vector(tip_load[1], "tip_load[1]", "moment")
        return np.tile(np.array(f + m, dtype=float), (len(times), 1))
    raise design_error(
        "tip_load",
        type(tip_load).__name__,
        "must be None, a pair (force in N, moment in N m) or a function of t (s) returning one",
        InputError,
    )


def _tension_rows(design: Design, tensions, times: np.ndarray) -> np.ndarray | None:
    """(n, tendon channels) tendon tensions (N) at the step times, or None (keep the
    current ones). ``tensions``: None, tensions held constant (N or strings with units, one
    per tendon channel), or a function of t (s) returning them; every value finite and
    >= 0, checked before any step."""
    from ..statics import _check_tension_values, _tensions

    if tensions is None:
        return None
    k = design.n_tendons
    if callable(tensions):
        rows = []
        for t in times:
            field = f"tensions(t = {t:g} s)"
            raw = tensions(float(t))
            if k == 0:
                raise design_error(
                    "tensions",
                    "a function",
                    f"design {design.name!r} has no tendons ([[sections.tendons]]); leave "
                    "tensions out",
                    InputError,
                )
            arr = V.real_array(raw, field, ndim=1, unit_kind="force", what="tendon tensions (N)")
            if arr.shape != (k,):
                raise design_error(
                    field,
                    f"{arr.size} values",
                    f"the design has {k} tendon channel(s); return one tension (N) per channel",
                    InputError,
                )
            _check_tension_values(arr, field)
            rows.append(arr)
        return np.array(rows, dtype=float).reshape(len(times), k)
    row = _tensions(design, tensions)
    return np.tile(np.array(row, dtype=float), (len(times), 1)).reshape(len(times), k)


def _shape_steps(shapes, n: int, dt: float, save_every: int) -> tuple[np.ndarray, bool]:
    """Indices of the steps after which the shape is kept, and whether the start's is."""
    if shapes is None:
        return np.zeros(0, dtype=int), False
    if isinstance(shapes, str):
        if shapes != "saved":
            raise design_error(
                "shapes", shapes, "must be None, 'saved', an interval (s) or times", InputError
            )
        idx = np.arange(save_every - 1, n, save_every)
        return np.unique(np.append(idx, n - 1)), True
    if V.is_real(shapes):
        interval = V.real(shapes, "shapes", minimum=0.0, exclusive=True, what="an interval (s)")
        # At most one shape per step: a tiny interval means every step, not 1e12 indices.
        every = max(1, round(min(interval / dt, n + 1)))
        return np.arange(every - 1, n, every), True
    # Chosen instants, relative to the start of the run: the nearest step.
    arr = V.real_array(shapes, "shapes", ndim=1, max_size=V.MAX_SAVED_SAMPLES, what="times (s)")
    if np.any(arr < 0):
        raise design_error("shapes", "negative times", "times must be >= 0 s", InputError)
    # The nearest step, so an instant up to half a step past the last one is that step's;
    # a later one is not in the run (it is refused, not moved to the end).
    late = np.flatnonzero(arr > (n + 0.5) * dt)
    if late.size:
        i = late[0]
        raise design_error(
            f"shapes[{i}]",
            f"{arr[i]:g} s",
            f"is after the run's end ({n} steps of {dt:g} s = {n * dt:g} s)",
            InputError,
        )
    steps = np.rint(np.minimum(arr / dt, n + 1)).astype(int)
    return np.unique(np.clip(steps[steps > 0] - 1, 0, n - 1)), bool(np.any(steps == 0))


def simulate(
    design: DesignLike,
    pressure_schedule: ScheduleLike,
    t_end: Quantity,
    *,
    dt: Quantity = 2e-3,
    save_every: int = 1,
    shapes: str | float | Sequence[float] | None = None,
    initial: str | Simulation = "static",
    model: str = "cosserat",
    scheme: str = "bdf-alpha",
    alpha: float | None = None,
    tol: float | None = None,
    max_iter: int | None = None,
    error_tol: Quantity | None = None,
    energy_tol: float = DEFAULT_ENERGY_TOL,
    stiffness_map: StiffnessMap | None = None,
    tip_load: TipLoad | None = None,
    tensions: Tensions | None = None,
    tip_constraint: TipHold | None = None,
    markers: Sequence | None = None,
    energy: bool = True,
    progress: Callable[[float, float, float], None] | None = None,
    on_unstable: str = "warn",
) -> Trajectory:
    """Simulate the motion of ``design`` under ``pressure_schedule`` from t = 0 to ``t_end``.

    - ``design``: a Design, a bundled name or a TOML path. Its ``[dynamics]`` table gives the
      Kelvin-Voigt damping time tau (B = tau K, paper 000 eq. 8) and the pressure supply's
      lag and rate limit; sections may give damping matrices and rotary inertia instead.
    - ``pressure_schedule``: a :class:`PressureSchedule`, a CSV/Parquet file of commands
      (``time_s``, ``p0_kPa``, ...), a function of t (s) returning one pressure per channel
      (Pa), or constant pressures (Pa; a single number or ``"30 kPa"`` for a one-channel
      design); None for a design without chambers.
    - ``t_end`` (s or a string with units) and ``dt`` (default 2 ms): the run takes
      ceil(t_end / dt) steps.
    - ``save_every``: keep every n-th step (the last step is always kept).
    - ``shapes``: None (tip only), ``"saved"`` (the centreline at every kept sample), an
      interval in s, or a list of instants (s, relative to the run's start; each gives the
      nearest step's shape, and an instant after the run's end is refused).
    - ``initial``: ``"static"`` (at rest in equilibrium under the first commanded pressures),
      ``"straight"`` (at rest in the straight shape), ``"reference"`` (at rest in the
      reference shape, a pre-bent finger let go), or a :class:`Simulation`
      to continue from its state (it is not changed; the schedule is read on its clock).
    - ``model``: ``"cosserat"`` (paper 000's viscoelastic rod) or ``"pcc"`` (paper 003's
      piecewise-constant-curvature Lagrangian model, one arc per deformable section, with
      the design's ``[pcc]`` parameters; docs/pcc.md). Both take the same schedule through
      the same pressure supply and return the same :class:`Trajectory`; a PCC run's shapes
      are its arcs sampled along s, and ``initial`` may not be a :class:`Simulation`.
    - ``scheme``, ``alpha``, ``tol``, ``max_iter``, ``error_tol``, ``energy_tol``,
      ``stiffness_map``: the rod's integrator settings, see :class:`Simulation` (the PCC
      model uses the implicit midpoint rule; its ``tol`` default is 1e-11 on the Newton
      update per coordinate scale, and it takes none of the others).
    - ``tip_load``: tip force (N) and moment (N m) over time, in the design's tip frame
      (``[tip] frame``: world for dead loads, ``"body"`` for follower loads): None (the
      design's ``[tip]`` loads), a pair ``(force, moment)``, or a function of t (s)
      returning one (sampled at the step times, like the schedule). With it, designs
      without chambers simulate.
    - ``tensions``: tendon tensions (N, one per tendon channel, each >= 0; Rucker and
      Webster's frictionless tendons, docs/dynamics.md) over time: None (slack), tensions
      held constant (numbers in N or strings with units), or a function of t (s)
      returning them (sampled at the step times and held over each step). The static start
      balances the tensions at t = 0; every value is checked before the first step. With
      them, designs without chambers simulate.
    - ``tip_constraint``: how the tip is held (docs/dynamics.md, "Held tip"): None (the
      design's ``[tip] constraint``), a :class:`~softrod.TipConstraint`, "free" or a mapping
      as :func:`~softrod.solve_statics` takes (a fixed pose), or a function of t (s)
      returning one (a moving pose: its value at t = 0 is the start's, then it is sampled
      at the step times, the steps in between interpolating linearly in position and along
      the geodesic in rotation). A held tip's reaction is recorded as the trajectory's
      ``tip_reaction_force`` and ``tip_reaction_moment``, and its work enters the energy
      books. Not with the midpoint scheme (obstacles are carried: docs/contact.md).
    - ``markers``: motion-capture markers on the body whose world positions are recorded at
      every sample as the trajectory's ``marker_position`` (n, K, 3) m: a list of
      ``(s, offset)`` (arc length from the base in [0, L], offset (d1, d2[, d3]) in the
      cross-section frame) or ``s`` alone, SI numbers or strings with units, e.g.
      ``["100 mm", ("220 mm", ["5 mm", "0 mm"])]`` (docs/dynamics.md, "Markers on the moving
      rod"). Checked before any work; with a :class:`Simulation` as ``initial`` they replace
      its markers (None keeps them). Rod model only.
    - ``energy``: also record the energy and its books (J).
    - ``progress``: None (a bar in interactive sessions), True, False, or a callable called
      after each chunk of steps as progress(t_done, t_run, wall_s), t_run the run's length
      (its ceil(t_end / dt) steps: t_end itself when dt divides it); see
      :mod:`softrod.progress`.
    - ``on_unstable``: what a 'static' start at an unstable equilibrium does (the static
      solver's stability test, as :func:`~softrod.solve_statics`): "warn" (default,
      :class:`~softrod.StabilityWarning`), "raise" (:class:`~softrod.InvalidStateError`,
      rule "stability") or "ignore". Such a run starts at rest there and leaves only when
      disturbed, and a coarse fixed step (implicit steps damp the growing mode) may hold it
      there: a wrong answer that the energy check cannot see.

    Returns a :class:`Trajectory`; its metadata records the method, the wall time and the
    real-time factor. A step that does not converge raises ``ConvergenceError`` with the
    time it failed at; a state that breaks a physical rule (stretch <= 0, energy growth
    beyond ``energy_tol``) raises ``InvalidStateError`` naming the time, the step, the
    rule and what to change.
    """
    V.choice(model, ("cosserat", "pcc"), "model")
    if model == "pcc":
        rod_only = {
            "scheme": (scheme, "bdf-alpha"),
            "error_tol": (error_tol, None),
            "energy_tol": (energy_tol, DEFAULT_ENERGY_TOL),
            "stiffness_map": (stiffness_map, None),
            "tip_load": (tip_load, None),
            "tensions": (tensions, None),
            "tip_constraint": (tip_constraint, None),
            "markers": (None if markers is None else "given", None),
        }
        for name, (value, default) in rod_only.items():
            if value is not default and value != default:
                raise design_error(
                    name, value, "is a setting of the rod model (model='cosserat')", InputError
                )
        return _simulate_pcc(
            design,
            pressure_schedule,
            t_end,
            dt=dt,
            save_every=save_every,
            shapes=shapes,
            initial=initial,
            alpha=alpha,
            tol=1e-11 if tol is None else tol,
            max_iter=30 if max_iter is None else max_iter,
            energy=energy,
            progress=progress,
        )
    tol = 1e-9 if tol is None else tol
    max_iter = 25 if max_iter is None else max_iter
    if isinstance(initial, Simulation):
        sim = initial.copy()
        if markers is not None:
            sim.set_markers(markers)
    else:
        d = load_design(design)
        if pressure_schedule is None and d.n_channels == 0:
            schedule, p0 = None, np.zeros(0)
        else:
            schedule = _schedule(pressure_schedule, d.n_channels)
            p0 = schedule.sample([0.0])[0]
        if not isinstance(initial, str):
            raise design_error(
                "initial",
                type(initial).__name__,
                "must be 'static', 'straight', 'reference' or a Simulation",
                InputError,
            )
        first = None if tip_load is None else _tip_loads(tip_load, np.zeros(1))[0]
        tens0 = _tension_rows(d, tensions, np.zeros(1))
        held0 = tip_constraint(0.0) if callable(tip_constraint) else tip_constraint
        if callable(tip_constraint):
            _pose_rows(tip_constraint, np.zeros(1), coerce_constraint_at0(held0))
        sim = Simulation(
            d,
            p0,
            initial=initial,
            dt=dt,
            scheme=scheme,
            alpha=alpha,
            tol=tol,
            max_iter=max_iter,
            error_tol=error_tol,
            energy_tol=energy_tol,
            stiffness_map=stiffness_map,
            tensions=None if tens0 is None else tens0[0],
            tip_constraint=held0,
            markers=markers,
            on_unstable=on_unstable,
            _tip_loads0=first,
        )
        pressure_schedule = schedule
    return sim.run(
        pressure_schedule,
        t_end,
        save_every=save_every,
        shapes=shapes,
        energy=energy,
        tip_load=tip_load,
        tensions=tensions,
        # (A fixed pose is the start's; a Simulation continued is moved to it.)
        tip_constraint=tip_constraint
        if callable(tip_constraint) or isinstance(initial, Simulation)
        else None,
        progress=progress,
    )


def _simulate_pcc(
    design, pressure_schedule, t_end, *, dt, save_every, shapes, initial, alpha, **kw
) -> Trajectory:
    """``simulate(model="pcc")``: check the shared arguments, then run the PCC model."""
    from ..pcc.simulate import simulate_pcc

    if isinstance(initial, Simulation) or initial not in ("static", "straight"):
        what = "a Simulation" if isinstance(initial, Simulation) else initial
        raise design_error(
            "initial", what, "with model='pcc' must be 'static' or 'straight'", InputError
        )
    if alpha is not None:
        raise design_error(
            "alpha",
            alpha,
            "is the rod's BDF-alpha parameter; the PCC model uses the implicit midpoint rule",
            InputError,
        )
    d = load_design(design)
    require_free_tip(d, "simulate(model='pcc')")
    _no_stiffness_map(d)
    schedule = _schedule(pressure_schedule, d.n_channels)
    step = _seconds(dt, "dt")
    duration = _seconds(t_end, "t_end")
    save_every = _save_every(save_every)
    n = step_count(duration, step)
    shape_steps, shape0 = _shape_steps(shapes, n, step, save_every)
    _check_saved(n, save_every, len(shape_steps) + int(shape0), 33 * len(d.spec["sections"]) + 1)
    kw["tol"] = V.real(kw["tol"], "tol", minimum=0.0, exclusive=True, maximum=1.0)
    kw["max_iter"] = V.integer(kw["max_iter"], "max_iter", minimum=1, maximum=V.MAX_ITERATIONS)
    with reporter(kw.pop("progress"), "simulate (PCC)", duration, simulated_time) as report:
        return simulate_pcc(
            d,
            schedule,
            duration,
            dt=step,
            save_every=save_every,
            shape_steps=shape_steps,
            shape_at_start=shape0,
            initial=initial,
            progress=report,
            **kw,
        )


def tracked_trajectory(
    design: Design,
    schedule: PressureSchedule | None,
    t_end: float,
    dt: float,
    params: Sequence[tuple[str, list[int]]],
    tensions: np.ndarray | None = None,
    markers: Sequence[tuple[float, list[float]]] = (),
    tol: float = 1e-9,
    max_iter: int = 25,
    progress: Callable[[float, float, float], None] | bool | None = False,
) -> dict[str, np.ndarray]:
    """The tip trajectory of ``design`` under ``schedule`` from rest in equilibrium (BDF-alpha,
    fixed steps ``dt``) and its exact derivatives with respect to ``params`` ((kind,
    sections) pairs of the core, as :meth:`Parameter.core
    <softrod.calibration.params.Parameter.core>` gives them), carried through every step by
    the core's forward sensitivities (``softrod_core::dynamics::sensitivity``; the public
    form with names: :func:`softrod.trajectory_sensitivities`). ``tensions``: None (slack
    tendons) or the tendon tensions (N) at the start and after every step, (steps + 1,
    tendon channels), checked by the core (finite, >= 0). With markers on the body:
    ``markers`` ((s, offset) pairs in m, the core's checks: s in [0, L], a finite offset in
    the cross-section frame) are read at every step (at a node the node's pose, between
    nodes the collocation's continuous extension, docs/dynamics.md "Markers on the moving
    rod"), with their exact derivatives. ``params`` may be empty: the run without
    sensitivities. ``tol``, ``max_iter``: each step's Newton settings (:class:`Simulation`);
    ``progress`` as :func:`simulate`'s (default False: none; the steps run in chunks of about
    0.2 s of work either way).

    Returns {"time" (k,), "tip_position" (k, 3), and with markers "marker_position" (k, K,
    3); with params "d_tip_position" (k, 3, P) and with markers "d_marker_position" (k, K,
    3, P)}."""
    n = step_count(t_end, dt)
    if tensions is not None and tensions.shape != (n + 1, design.n_tendons):
        raise design_error(
            "tensions",
            f"shape {tensions.shape}",
            f"needs one row per step and the start ({n + 1}) and one column per tendon "
            f"channel ({design.n_tendons})",
            InputError,
        )
    # A design without chambers has no schedule (None): no pressures to command.
    p0 = np.zeros(0) if schedule is None else schedule.sample([0.0])[0]
    sim = Simulation(
        design,
        p0,
        dt=dt,
        tol=tol,
        max_iter=max_iter,
        tensions=None if tensions is None else tensions[0],
    )
    if markers:
        sim._sim.set_markers([(s, list(o)) for s, o in markers])
    if params:
        sim._sim.track_sensitivities([(k, list(s)) for k, s in params])
    first = sim._sim.snapshot()
    table = None
    if schedule is not None and schedule.kind in ("linear", "step"):
        table = (schedule.times.tolist(), schedule.pressures.tolist(), schedule.kind == "step")
    parts = [first]
    wall0 = _time.perf_counter()
    span = n * dt  # the run's length: n whole steps, n dt >= t_end
    with reporter(progress, "trajectory sensitivities", span, simulated_time) as report:
        for start, stop in chunks(n):
            times = dt * np.arange(start + 1, stop + 1)
            commands = np.zeros((times.size, 0)) if schedule is None else schedule.sample(times)
            rows = None if tensions is None else tensions[start + 1 : stop + 1]
            parts.append(
                sim._sim.run(
                    np.ascontiguousarray(commands),
                    np.ones(stop - start, dtype=np.uint8),
                    False,
                    None,
                    table,
                    None if rows is None else np.ascontiguousarray(rows, dtype=float),
                )
            )
            if report is not None:
                report(stop * dt, span, _time.perf_counter() - wall0)
    keys = ["time", "tip_position", "marker_position", "d_tip_position", "d_marker_position"]
    return {key: np.concatenate([p[key] for p in parts]) for key in keys if key in parts[-1]}
