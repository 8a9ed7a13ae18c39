"""Dynamics of a :class:`~softrod.System`: its rods' tips clamped to a rigid platform that
moves under gravity, its load and the rods' tip reactions (docs/dynamics.md, "Systems of
rods"). The physics is the core's (``softrod_core::dynamics::system``): every rod is the
single rod's time step with its tip clamped at its attachment, the platform a rigid body
(Newton-Euler) integrated with the same BDF-alpha formula, and one Newton per step solves
everything together.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import _core
from . import _validate as V
from .dynamics.simulate import (
    DEFAULT_ENERGY_TOL,
    _seconds,
    _solver_options,
    step_count,
)
from .errors import InputError
from .statics import _pressures, _tensions
from .system import System, _platform_args, load_system
from .system import platform_inertia as _inertia_of

__all__ = ["SystemSimulation", "SystemSimulationState", "SystemTrajectory", "simulate_system"]


@dataclass(frozen=True)
class SystemTrajectory:
    """Samples of a system's motion, the start (t = 0) first, then one per output step (SI,
    world frame). ``platform_position`` (n, 3) m, ``platform_rotation`` (n, 3, 3),
    ``platform_velocity`` (n, 3) m/s (of the platform origin), ``platform_angular_velocity``
    (n, 3) rad/s; per rod ``tip_position``, ``tip_reaction_force`` (N) and
    ``tip_reaction_moment`` (N m), each (n, rods, 3), the reaction being the wrench the
    platform applies to the rod's tip; ``shapes``: per rod its centreline (n, nodes, 3) m;
    energies (n,) J: ``kinetic``, ``elastic``, ``potential`` (rods and platform),
    ``work_in`` (the inputs' work since t = 0), ``dissipated`` and ``energy_balance``
    (E - E(0) - W_in + D, zero for the exact motion)."""

    system: System
    time: np.ndarray
    platform_position: np.ndarray
    platform_rotation: np.ndarray
    platform_velocity: np.ndarray
    platform_angular_velocity: np.ndarray
    tip_position: np.ndarray
    tip_reaction_force: np.ndarray
    tip_reaction_moment: np.ndarray
    shapes: tuple[np.ndarray, ...]
    kinetic: np.ndarray
    elastic: np.ndarray
    potential: np.ndarray
    work_in: np.ndarray
    dissipated: np.ndarray
    energy_balance: np.ndarray

    @staticmethod
    def _concat(system: System, parts: list[dict]) -> SystemTrajectory:
        n_rods = len(system.rods)
        time = np.concatenate([np.asarray(p["time"], dtype=float) for p in parts])
        k = time.size

        def cat(key, shape):
            return np.concatenate([np.asarray(p[key], dtype=float) for p in parts]).reshape(shape)

        energy = cat("energy", (k, 6))
        shapes = tuple(
            np.concatenate([np.asarray(p["shapes"][i], dtype=float) for p in parts]).reshape(
                k, -1, 3
            )
            for i in range(n_rods)
        )
        return SystemTrajectory(
            system=system,
            time=time,
            platform_position=cat("platform_position", (k, 3)),
            platform_rotation=cat("platform_rotation", (k, 3, 3)),
            platform_velocity=cat("platform_velocity", (k, 3)),
            platform_angular_velocity=cat("platform_angular_velocity", (k, 3)),
            tip_position=cat("tip_position", (k, n_rods, 3)),
            tip_reaction_force=cat("tip_reaction_force", (k, n_rods, 3)),
            tip_reaction_moment=cat("tip_reaction_moment", (k, n_rods, 3)),
            shapes=shapes,
            kinetic=energy[:, 0],
            elastic=energy[:, 1],
            potential=energy[:, 2],
            work_in=energy[:, 3],
            dissipated=energy[:, 4],
            energy_balance=energy[:, 5],
        )


@dataclass(frozen=True)
class SystemSimulationState:
    """A :class:`SystemSimulation`'s complete state at ``time`` (s): ``data`` (read-only
    numbers) for :meth:`SystemSimulation.restore`, ``system`` (its name) and
    ``fingerprint`` (a digest of the rods' designs, attachments and platform: a state only
    restores into the same system)."""

    system: str
    fingerprint: str
    time: float
    data: np.ndarray = field(repr=False)


def _system_fingerprint(system: System, inertia: np.ndarray) -> str:
    """A digest of what a saved state belongs to: every rod's design document and
    attachment, the platform's nominal pose, mass, centre of mass and inertia."""
    doc = {
        "rods": [
            [
                r.design.spec,
                np.asarray(r.attachment, dtype=float).tolist(),
                np.asarray(r.attachment_rotation, dtype=float).tolist(),
            ]
            for r in system.rods
        ],
        "platform": [
            np.asarray(v, dtype=float).tolist()
            for v in (
                system.platform.position,
                system.platform.rotation,
                system.platform.mass,
                system.platform.com_offset,
                inertia,
            )
        ],
    }
    text = json.dumps(doc, sort_keys=True)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def _per_rod(system: System, value, name: str, convert) -> list[list[float]]:
    n = len(system.rods)
    if value is None:
        return [convert(r.design, None) for r in system.rods]
    if isinstance(value, np.ndarray):
        value = list(value)
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise V.fail(name, value, f"must be a list of {n} entries, one per rod", InputError)
    return [convert(r.design, v) for r, v in zip(system.rods, value, strict=True)]


def _rod_pressures(design, p) -> list[float]:
    return [0.0] * design.n_channels if p is None else _pressures(design, p)


class SystemSimulation:
    """A running simulation of a :class:`~softrod.System`, started at rest in its static
    equilibrium (:func:`~softrod.solve_system`'s, refined on the dynamics' grids).

    ``pressures``/``tensions``: at t = 0, one list per rod as :func:`~softrod.solve_system`
    takes them (None: zero, slack). ``platform_force``/``platform_moment``: the platform's
    load at t = 0 (N and N m, world; None: the system's). ``platform_inertia``: the
    platform's inertia tensor about its centre of mass in the platform frame (kg m^2; a
    3x3 tensor or three principal values; None: the system's ``[platform] inertia``, zero
    unless given, so that a platform with mass is a point mass at its centre of mass).
    ``dt``, ``alpha``, ``tol``, ``max_iter``, ``error_tol``, ``energy_tol`` as for
    :class:`~softrod.Simulation`; the scheme is BDF-alpha (the midpoint rule is refused: it
    does not carry held tips). Refused by name before any work: obstacles, follower tip
    loads on a rod, inputs that do not match a rod, a rod design with its own ``[tip]
    constraint``.
    """

    def __init__(
        self,
        system: System | str,
        pressures: Any = None,
        *,
        tensions: Any = None,
        platform_force: Any = None,
        platform_moment: Any = None,
        platform_inertia: Any = None,
        dt: Any = 2e-3,
        scheme: str = "bdf-alpha",
        alpha: float = -0.2,
        tol: float = 1e-9,
        max_iter: int = 25,
        error_tol: Any = None,
        energy_tol: float = DEFAULT_ENERGY_TOL,
    ) -> None:
        if not isinstance(system, System):
            system = load_system(system)
        self.system = system
        for i, rod in enumerate(system.rods):
            if rod.design.tip_constraint is not None:
                raise V.fail(
                    f"rods[{i}].design",
                    rod.design.name,
                    "its [tip] constraint is set; a system's rod tips hold the platform",
                    InputError,
                )
        ps = _per_rod(system, pressures, "pressures", _rod_pressures)
        ts = _per_rod(system, tensions, "tensions", _tensions)
        opts = _solver_options(scheme, alpha, tol, max_iter, error_tol, energy_tol)
        self.dt = _seconds(dt, "dt")
        entries = [
            (
                r.design._rod,
                p,
                t,
                [float(v) for v in r.attachment],
                np.asarray(r.attachment_rotation, dtype=float).tolist(),
            )
            for r, p, t in zip(system.rods, ps, ts, strict=True)
        ]
        inertia = (
            system.platform.inertia
            if platform_inertia is None
            else _inertia_of(platform_inertia, "platform_inertia", InputError)
        )
        platform = _platform_args(system, platform_force, platform_moment)
        self._force, self._moment = platform[2], platform[3]
        self._sim = _core.SystemSimulator(entries, platform, inertia.tolist(), self.dt, **opts)
        self._pressures = ps
        self._fingerprint = _system_fingerprint(system, inertia)

    @property
    def time(self) -> float:
        """Time now, s."""
        return self._sim.time()

    @property
    def stats(self) -> dict:
        """Counters of the run so far (steps, internal steps, rejected, Newton iterations,
        Jacobians)."""
        return self._sim.stats()

    def state(self) -> SystemTrajectory:
        """The state now as a one-sample :class:`SystemTrajectory`."""
        return SystemTrajectory._concat(self.system, [self._sim.snapshot()])

    def save(self) -> SystemSimulationState:
        """The complete state; :meth:`restore` continues from it bit for bit."""
        data = np.array(self._sim.save(), dtype=float)
        data.setflags(write=False)
        return SystemSimulationState(self.system.name, self._fingerprint, self.time, data)

    def restore(self, state: SystemSimulationState) -> None:
        """Continue from a state saved by :meth:`save` of a simulation of the same system
        (its rods' designs, attachments and platform, inertia included)."""
        if not isinstance(state, SystemSimulationState):
            raise V.fail(
                "state", type(state).__name__, "must be a SystemSimulationState", InputError
            )
        if state.fingerprint != self._fingerprint:
            raise V.fail(
                "state",
                repr(state),
                f"was saved from system {state.system!r}, not from this simulation's "
                f"{self.system.name!r} (or from another version of it: rods, attachments or "
                "platform differ)",
                InputError,
            )
        self._sim.restore(np.ascontiguousarray(state.data, dtype=float))

    def copy(self) -> SystemSimulation:
        """An independent simulation starting from this one's current state (exact)."""
        obj = SystemSimulation.__new__(SystemSimulation)
        obj.__dict__.update(self.__dict__)
        obj._sim = self._sim.copy()
        return obj

    def run(
        self,
        pressures: Any,
        duration: Any,
        *,
        tensions: Any = None,
        platform_force: Any = None,
        platform_moment: Any = None,
    ) -> SystemTrajectory:
        """Advance by ``duration`` (s or a string with units) in output steps of dt and
        return the samples after each step (without the current state).

        ``pressures``: one list per rod (held), or a function of t (s) returning them,
        sampled at each step's end; None: the last ones. ``tensions``, ``platform_force``,
        ``platform_moment`` likewise (None: unchanged)."""
        out = self._run(duration, pressures, tensions, platform_force, platform_moment)
        return SystemTrajectory._concat(self.system, [out])

    def _run(
        self,
        duration,
        pressures,
        tensions,
        platform_force,
        platform_moment,
        field: str = "duration",
    ) -> dict:
        steps = step_count(_seconds(duration, field), self.dt, field)
        t0 = self.time
        times = [t0 + (k + 1) * self.dt for k in range(steps)]

        def series(value, name, convert):
            if value is None:
                return None
            if callable(value):
                return [convert(value(t), name) for t in times]
            once = convert(value, name)
            return [once] * steps

        def per_rod_p(v, name):
            return _per_rod(self.system, v, name, _rod_pressures)

        def per_rod_t(v, name):
            return _per_rod(self.system, v, name, _tensions)

        commands = series(pressures, "pressures", per_rod_p)
        if commands is None:
            commands = [self._pressures] * steps
        tens = series(tensions, "tensions", per_rod_t)
        loads = None
        if platform_force is not None or platform_moment is not None:
            fs = series(
                platform_force,
                "platform_force",
                lambda v, n: _platform_args(self.system, v, None)[2],
            )
            ms = series(
                platform_moment,
                "platform_moment",
                lambda v, n: _platform_args(self.system, None, v)[3],
            )
            fs = fs or [self._force] * steps
            ms = ms or [self._moment] * steps
            loads = list(zip(fs, ms, strict=True))
        out = self._sim.run(commands, tensions=tens, platform_loads=loads)
        self._pressures = commands[-1]
        if loads is not None:
            self._force, self._moment = loads[-1]
        return out


def simulate_system(
    system: System | str,
    pressures: Any | Callable[[float], Any],
    t_end: Any,
    *,
    tensions: Any | Callable[[float], Any] = None,
    platform_force: Any = None,
    platform_moment: Any = None,
    platform_inertia: Any = None,
    dt: Any = 2e-3,
    alpha: float = -0.2,
    tol: float = 1e-9,
    max_iter: int = 25,
    error_tol: Any = None,
    energy_tol: float = DEFAULT_ENERGY_TOL,
) -> SystemTrajectory:
    """Simulate a :class:`~softrod.System` until ``t_end`` (s or a string with units; the
    run takes ceil(t_end / dt) output steps, as :func:`~softrod.simulate`),
    starting at rest in its static equilibrium under the inputs at t = 0.

    ``pressures``/``tensions``: one list per rod (Pa / N or strings with units, as
    :func:`~softrod.solve_system` takes them), held, or a function of t (s) returning them
    (its value at t = 0 is the start's; then sampled at each output step's end).
    ``platform_force``/``platform_moment`` (N, N m, world) likewise (None: the system's).
    ``platform_inertia``, ``dt``, ``alpha``, ``tol``, ``max_iter``, ``error_tol``,
    ``energy_tol``: as :class:`SystemSimulation`. Returns a :class:`SystemTrajectory` from
    t = 0 (docs/dynamics.md, "Systems of rods")."""

    def at0(value):
        return value(0.0) if callable(value) else value

    sim = SystemSimulation(
        system,
        at0(pressures),
        tensions=at0(tensions),
        platform_force=at0(platform_force),
        platform_moment=at0(platform_moment),
        platform_inertia=platform_inertia,
        dt=dt,
        alpha=alpha,
        tol=tol,
        max_iter=max_iter,
        error_tol=error_tol,
        energy_tol=energy_tol,
    )
    start = sim._sim.snapshot()
    out = sim._run(t_end, pressures, tensions, platform_force, platform_moment, "t_end")
    return SystemTrajectory._concat(sim.system, [start, out])
