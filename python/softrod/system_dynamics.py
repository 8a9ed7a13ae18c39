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
import os
import time as _time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from itertools import chain
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from . import _core
from . import _validate as V
from .dynamics.simulate import (
    DEFAULT_ENERGY_TOL,
    _seconds,
    _solver_options,
    core_sigma,
    simulated_time,
    step_count,
)
from .errors import InputError
from .io import as_path, atomic_path, check_target, write_table
from .io import is_file as _is_file
from .progress import chunks, reporter
from .statics import _pressures, _tensions
from .stiffness_map import StiffnessMap
from .system import System, _platform_args, check_rods, load_system
from .system import platform_inertia as _inertia_of

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.figure import Figure

    from ._types import Units

__all__ = [
    "SystemSimulation",
    "SystemSimulationState",
    "SystemTrajectory",
    "simulate_system",
]

# The energy books of a system's motion, in the order of the core's samples.
ENERGY_NAMES = ("kinetic", "elastic", "potential", "work_in", "dissipated", "energy_balance")
# The arrays of a system trajectory's .npz file besides the per-rod ones.
_ARRAYS = (
    "time",
    "platform_position",
    "platform_rotation",
    "platform_velocity",
    "platform_angular_velocity",
    "tip_position",
    "tip_reaction_force",
    "tip_reaction_moment",
    *ENERGY_NAMES,
)
_NPZ_FORMAT = "softrod-system-trajectory/1"
_SUFFIXES = (".npz", ".csv", ".parquet")


def _trajectory_path(path) -> Path:
    """``path`` checked: a known suffix and a writable folder, before any work."""
    path = as_path(path)
    if path.suffix.lower() not in _SUFFIXES:
        raise V.fail(
            "path",
            str(path),
            f"unknown format {path.suffix or '(no suffix)'!r}: the file name must end in "
            f"{', '.join(_SUFFIXES)}",
            InputError,
        )
    return check_target(path)


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
    (E - E(0) - W_in + D, zero for the exact motion); per rod its commanded ``pressures``
    (n, channels) Pa and ``tensions`` (n, tendon channels) N, those of the step that ended
    at the sample (at t = 0: the start's); per rod with obstacles (None for a rod without)
    ``contact_force`` (n, 3) N, the obstacles' total force on the rod (world frame), and
    ``penetration`` (n,) m, its surface's deepest penetration (<= 0: no contact;
    docs/contact.md).

    Tables and files: :meth:`to_frame`, :meth:`save` (``.npz`` exact and read back by
    :meth:`load`; ``.csv``/``.parquet`` the table), :meth:`plot`."""

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
    pressures: tuple[np.ndarray, ...] = ()
    tensions: tuple[np.ndarray, ...] = ()
    contact_force: tuple[np.ndarray | None, ...] = ()
    penetration: tuple[np.ndarray | None, ...] = ()

    @staticmethod
    def _concat(system: System, parts: list[dict]) -> SystemTrajectory:
        n_rods = len(system.rods)
        time = np.concatenate([np.asarray(p["time"], dtype=float) for p in parts])
        k = time.size

        def cat(key, shape):
            return np.concatenate([np.asarray(p[key], dtype=float) for p in parts]).reshape(shape)

        energy = cat("energy", (k, 6))

        def per_rod(key, widths):
            return tuple(
                np.concatenate([np.asarray(p[key][i], dtype=float) for p in parts]).reshape(k, w)
                for i, w in enumerate(widths)
            )

        designs = [r.design for r in system.rods]
        shapes = tuple(a.reshape(k, -1, 3) for a in per_rod("shapes", [-1] * n_rods))
        pressures = per_rod("pressures", [d.n_channels for d in designs])
        tensions = per_rod("tensions", [d.n_tendons for d in designs])
        touching = [_has_obstacles(d) for d in designs]
        force = per_rod("contact_force", [3 if t else 0 for t in touching])
        depth = per_rod("penetration", [1 if t else 0 for t in touching])
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
            pressures=pressures,
            tensions=tensions,
            contact_force=tuple(f if t else None for f, t in zip(force, touching, strict=True)),
            penetration=tuple(d[:, 0] if t else None for d, t in zip(depth, touching, strict=True)),
        )

    @staticmethod
    def concat(parts: list[SystemTrajectory]) -> SystemTrajectory:
        """One trajectory from consecutive pieces of the same system's motion (e.g. the
        start's :meth:`SystemSimulation.state` and the runs after it), in order."""
        parts = list(parts) if isinstance(parts, (list, tuple)) else []
        if not parts or not all(isinstance(p, SystemTrajectory) for p in parts):
            raise V.fail(
                "parts",
                type(parts).__name__,
                "must be a non-empty list of SystemTrajectory",
                InputError,
            )
        first = parts[0]
        for i, p in enumerate(parts[1:], 1):
            if p.system is not first.system:
                raise V.fail(
                    f"parts[{i}]", p.system.name, "is a motion of another system", InputError
                )
            if not p.time[0] > parts[i - 1].time[-1]:
                raise V.fail(
                    f"parts[{i}]",
                    float(p.time[0]),
                    f"must start after parts[{i - 1}] ends ({parts[i - 1].time[-1]:g} s)",
                    InputError,
                )

        def cat(name):
            return np.concatenate([getattr(p, name) for p in parts])

        def per_rod(name):
            return tuple(
                None
                if getattr(first, name)[i] is None
                else np.concatenate([getattr(p, name)[i] for p in parts])
                for i in range(len(first.system.rods))
            )

        return SystemTrajectory(
            system=first.system,
            **{name: cat(name) for name in _ARRAYS},
            shapes=per_rod("shapes"),
            pressures=per_rod("pressures"),
            tensions=per_rod("tensions"),
            contact_force=per_rod("contact_force"),
            penetration=per_rod("penetration"),
        )

    # --- tables, files and figures -----------------------------------------------------------

    def __len__(self) -> int:
        return int(self.time.size)

    def __repr__(self) -> str:
        return (
            f"SystemTrajectory({self.system.name!r}, {len(self)} samples, "
            f"t = {self.time[0]:g} ... {self.time[-1]:g} s, {len(self.system.rods)} rods)"
        )

    def to_frame(self, units: Units = None) -> pd.DataFrame:
        """The motion as a table, one row per sample, units in the column names as in the
        dataset schema (docs/datasets.md; ``units`` as there, also "velocity" and "energy";
        "SI" for Pa, m, m/s): ``time_s``; the columns of
        :meth:`softrod.SystemBatchSolution.to_frame` (per rod its inputs ``rod<i>_p<k>_kPa``
        and ``rod<i>_t<k>_N``, the platform pose ``platform_x_mm`` ... ``platform_qz``, per
        rod its tip ``rod<i>_tip_x_mm`` ... and the platform's reaction on it
        ``rod<i>_tip_reaction_fx_N`` ...); the platform's velocity ``platform_vx_mm/s`` ...
        and angular velocity ``platform_wx_rad/s`` ... (world frame); the energies
        ``kinetic_J``, ``elastic_J``, ``potential_J``, ``work_in_J``, ``dissipated_J``,
        ``energy_balance_J``; per rod with obstacles its contact force
        ``rod<i>_contact_fx_N`` ... and penetration ``rod<i>_penetration_mm``. The metadata
        block (``frame.attrs["softrod.metadata"]``) names the system and the softrod
        version."""
        import pandas as pd

        from . import __version__
        from .schema import table_units
        from .system import system_columns

        chosen, factor = table_units(units)
        cols: dict[str, Any] = {f"time_{chosen['time']}": self.time / factor["time"]}
        cols.update(system_columns(self, chosen, factor))
        for k, a in enumerate("xyz"):
            cols[f"platform_v{a}_{chosen['velocity']}"] = (
                self.platform_velocity[:, k] / factor["velocity"]
            )
        for k, a in enumerate("xyz"):
            # Angular velocity has no unit choice in the schema: always rad/s.
            cols[f"platform_w{a}_rad/s"] = self.platform_angular_velocity[:, k]
        for name in ENERGY_NAMES:
            cols[f"{name}_{chosen['energy']}"] = getattr(self, name) / factor["energy"]
        for i, (f, d) in enumerate(zip(self.contact_force, self.penetration, strict=True)):
            if f is None:
                continue
            for k, a in enumerate("xyz"):
                cols[f"rod{i}_contact_f{a}_{chosen['force']}"] = f[:, k] / factor["force"]
            cols[f"rod{i}_penetration_{chosen['length']}"] = d / factor["length"]
        frame = pd.DataFrame(cols)
        frame.attrs["softrod.metadata"] = {
            "system": self.system.name,
            "synthetic": True,
            "softrod_version": __version__,
        }
        return frame

    def save(self, path: str | os.PathLike) -> Path:
        """Write the motion to ``path``, atomically (whole or not at all); returns the path.

        ``.npz``: every array exactly (SI), the shapes and inputs per rod, the system's name
        and a fingerprint of it; :meth:`load` reads it back. ``.csv`` or ``.parquet``: the
        table of :meth:`to_frame` (without the shapes), for pandas or a spreadsheet."""
        path = _trajectory_path(path)
        if path.suffix.lower() != ".npz":
            return write_table(self.to_frame(), path)
        arrays: dict[str, Any] = {name: getattr(self, name) for name in _ARRAYS}
        for i in range(len(self.system.rods)):
            arrays[f"shapes_{i}"] = self.shapes[i]
            arrays[f"pressures_{i}"] = self.pressures[i]
            arrays[f"tensions_{i}"] = self.tensions[i]
            if self.contact_force[i] is not None:
                arrays[f"contact_force_{i}"] = self.contact_force[i]
                arrays[f"penetration_{i}"] = self.penetration[i]
        with atomic_path(path) as tmp, open(tmp, "wb") as fh:  # numpy would append ".npz"
            np.savez_compressed(
                fh,
                **arrays,
                format=np.array(_NPZ_FORMAT),
                system_name=np.array(self.system.name),
                fingerprint=np.array(_system_fingerprint(self.system)),
            )
        return path

    @classmethod
    def load(cls, path: str | os.PathLike, system: System | str | os.PathLike) -> SystemTrajectory:
        """Read a ``.npz`` file written by :meth:`save` of a motion of ``system`` (a
        :class:`~softrod.System`, a system file or a bundled name), exactly. A file of
        another system (or of another version of it: rods, attachments, platform) is
        refused, as is a damaged file."""
        path = as_path(path)
        if path.suffix.lower() != ".npz":
            raise V.fail(
                "path",
                str(path),
                "only .npz files are read back (.csv and .parquet are tables for pandas)",
                InputError,
            )
        if not _is_file(path):
            raise V.fail("path", str(path), "no such file", InputError)
        if not isinstance(system, System):
            system = load_system(system)
        try:
            data = np.load(path, allow_pickle=False)
        except Exception as exc:  # zipfile / numpy raise several types for broken files
            raise V.fail(
                "path", str(path), f"is not a readable .npz file: {exc}", InputError
            ) from None
        n = len(system.rods)
        touching = [_has_obstacles(r.design) for r in system.rods]
        per_rod = [f"{key}_{i}" for i in range(n) for key in ("shapes", "pressures", "tensions")]
        per_rod += [
            f"{key}_{i}"
            for i in range(n)
            if touching[i]
            for key in ("contact_force", "penetration")
        ]
        with data:
            try:
                fmt = str(data["format"]) if "format" in data.files else None
                if fmt != _NPZ_FORMAT:
                    raise V.fail(
                        "format", fmt, f"not a system trajectory file ({_NPZ_FORMAT})", InputError
                    )
                missing = [
                    k
                    for k in (*_ARRAYS, *per_rod, "system_name", "fingerprint")
                    if k not in data.files
                ]
                if missing:
                    raise V.fail(
                        "arrays",
                        sorted(data.files),
                        f"missing {', '.join(missing)} (a file of a system with {n} rods?)",
                        InputError,
                    )
                name, print_ = str(data["system_name"]), str(data["fingerprint"])
                values = {k: np.array(data[k], dtype=float) for k in (*_ARRAYS, *per_rod)}
            except InputError:
                raise
            except Exception as exc:  # a damaged archive: zipfile, zlib and numpy errors
                raise V.fail(
                    "path", str(path), f"is a damaged .npz file: {exc}", InputError
                ) from None
        if print_ != _system_fingerprint(system):
            raise V.fail(
                "system",
                system.name,
                f"{path.name} holds a motion of system {name!r}, not of this one (or of "
                "another version of it: rods, attachments or platform differ)",
                InputError,
            )
        k = values["time"].shape[0] if values["time"].ndim == 1 else -1
        expected = {
            "time": (k,),
            "platform_position": (k, 3),
            "platform_rotation": (k, 3, 3),
            "platform_velocity": (k, 3),
            "platform_angular_velocity": (k, 3),
            "tip_position": (k, n, 3),
            "tip_reaction_force": (k, n, 3),
            "tip_reaction_moment": (k, n, 3),
            **{e: (k,) for e in ENERGY_NAMES},
        }
        for i, r in enumerate(system.rods):
            expected[f"pressures_{i}"] = (k, r.design.n_channels)
            expected[f"tensions_{i}"] = (k, r.design.n_tendons)
            if touching[i]:
                expected[f"contact_force_{i}"] = (k, 3)
                expected[f"penetration_{i}"] = (k,)
        for key, shape in expected.items():
            if k < 1 or values[key].shape != shape:
                raise V.fail(
                    key, values[key].shape, f"must have shape {shape} (a damaged file)", InputError
                )
        for i in range(n):
            sh = values[f"shapes_{i}"]
            if sh.ndim != 3 or sh.shape[0] != k or sh.shape[2] != 3:
                raise V.fail(f"shapes_{i}", sh.shape, f"must be ({k}, nodes, 3)", InputError)
        return cls(
            system=system,
            **{key: values[key] for key in _ARRAYS},
            shapes=tuple(values[f"shapes_{i}"] for i in range(n)),
            pressures=tuple(values[f"pressures_{i}"] for i in range(n)),
            tensions=tuple(values[f"tensions_{i}"] for i in range(n)),
            contact_force=tuple(
                values[f"contact_force_{i}"] if touching[i] else None for i in range(n)
            ),
            penetration=tuple(
                values[f"penetration_{i}"] if touching[i] else None for i in range(n)
            ),
        )

    def plot(
        self,
        path: str | os.PathLike | None = None,
        *,
        reference: Any = None,
        title: str | None = None,
    ) -> Figure:
        """The platform's displacement and tilt and the rods' pressures against time
        (:func:`softrod.plot_system_motion`; ``reference``: an equilibrium
        drawn dashed). Written to ``path`` when given; returns the Figure."""
        from .system_plots import plot_system_motion

        return plot_system_motion(self, path, reference=reference, title=title)


@dataclass(frozen=True)
class SystemSimulationState:
    """A :class:`SystemSimulation`'s complete state at ``time`` (s): ``data`` (read-only
    numbers) for :meth:`SystemSimulation.restore`, ``system`` (its name) and
    ``fingerprint`` (a digest of the rods' designs, attachments, stiffness maps and platform:
    a state only restores into the same system)."""

    system: str
    fingerprint: str
    time: float
    data: np.ndarray = field(repr=False)


def _system_fingerprint(
    system: System, inertia: np.ndarray | None = None, sigma: list | None = None
) -> str:
    """A digest of what a saved state or file belongs to: every rod's design document and
    attachment, the platform's nominal pose, mass, centre of mass and inertia (default: the
    system's), and the stiffness maps' numbers the core evaluates (``sigma``, per rod, of
    :func:`_sigma_maps`; None: no maps)."""
    if inertia is None:
        inertia = system.platform.inertia
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
    if sigma is not None:
        doc["sigma"] = sigma
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


def _has_obstacles(design) -> bool:
    """Whether a rod's design has obstacles (its motion then reports its contact)."""
    return bool(design.spec.get("obstacles"))


def _sigma_maps(system: System, maps: list, given: Any) -> list[tuple] | None:
    """The binding's per-rod (sigma_const, sigma_grid) of the rods' checked maps
    (:func:`~softrod.system.check_rods`); None when no rod has one. A map the core cannot
    evaluate at every step is refused naming ``stiffness_maps[i]`` (given) or the rod's
    design map."""
    if all(m is None for m in maps):
        return None
    out = []
    for i, (rod, smap) in enumerate(zip(system.rods, maps, strict=True)):
        field = (
            f"stiffness_maps[{i}]"
            if given is not None and given[i] is not None
            else f"rods[{i}].design.stiffness_map"
        )
        args = core_sigma(smap, rod.design.n_channels, field)
        out.append((args.get("sigma_const"), args.get("sigma_grid")))
    return out


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
    ``dt``, ``alpha``, ``tol``, ``max_iter``, ``error_tol``, ``energy_tol`` and
    ``on_unstable`` (an unstable start: "warn", "raise" or "ignore"; :attr:`start_stable`
    keeps the verdict) as for :class:`~softrod.Simulation`; the scheme is BDF-alpha (the
    midpoint rule is refused: it does not carry held tips). A rod's obstacles act on it as
    on a free rod in motion
    (docs/contact.md); the trajectory reports each such rod's contact. A rod design's tip
    loads, dead or follower (``[tip] frame = "body"``: they turn with the tip the platform
    holds), act on its tip as in :func:`~softrod.solve_system`.

    ``stiffness_maps``: as :func:`~softrod.solve_system` takes it (one
    :class:`~softrod.StiffnessMap` or None per rod, a map replacing the design's): a rod
    with stiffness-mapped sections runs with its map (its design's ``[stiffness_map]`` or
    the one given), sigma evaluated in the core at every step's chamber pressures (those
    after the design's pressure supply), as :class:`~softrod.Simulation` evaluates it; the
    map must be one the core evaluates (``StiffnessMap.constant`` or a PCHIP
    ``from_table``). :attr:`stiffness_maps` keeps each rod's map.

    Refused by name before any work: inputs that do not match a rod, a rod design with its
    own ``[tip] constraint``, a mapped rod without a map (``rods[i].design.stiffness_map``:
    sigma is never assumed to be 1), a map for a rod without mapped sections or of another
    channel count, or one the core cannot evaluate at every step (``stiffness_maps[i]``).
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
        alpha: float | None = None,
        tol: float = 1e-9,
        max_iter: int = 25,
        error_tol: Any = None,
        energy_tol: float = DEFAULT_ENERGY_TOL,
        on_unstable: str = "warn",
        stiffness_maps: Any = None,
    ) -> None:
        from .statics import _policy, _report_stability

        if not isinstance(system, System):
            system = load_system(system)
        self.system = system
        on_unstable = _policy("on_unstable", on_unstable)
        # What the statics refuse, named as there: a rod holding its own tip, a mapped rod
        # without a map, a map that does not fit its rod.
        maps = check_rods(system, stiffness_maps, argument=True)
        sigma = _sigma_maps(system, maps, stiffness_maps)
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
        self._sim = _core.SystemSimulator(
            entries, platform, inertia.tolist(), self.dt, **opts, sigma_maps=sigma
        )
        self.stiffness_maps: tuple[StiffnessMap | None, ...] = tuple(maps)
        self._pressures = ps
        self._fingerprint = _system_fingerprint(system, inertia, sigma)
        # As a single rod's static start: a coarse step may hold an unstable start.
        _report_stability(self._sim.start_stable, on_unstable, "the system's initial static state")

    @property
    def start_stable(self) -> bool | None:
        """The start's stability (False: the system started from an unstable equilibrium,
        which a small disturbance leaves, though a coarse step may hold it); None where it is
        not assessed (a follower load on some rod)."""
        return self._sim.start_stable

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
        (its rods' designs, attachments, stiffness maps and platform, inertia included)."""
        if not isinstance(state, SystemSimulationState):
            raise V.fail(
                "state", type(state).__name__, "must be a SystemSimulationState", InputError
            )
        if state.fingerprint != self._fingerprint:
            raise V.fail(
                "state",
                repr(state),
                f"was saved from system {state.system!r}, not from this simulation's "
                f"{self.system.name!r} (or from another version of it: rods, attachments, "
                "stiffness maps or platform differ)",
                InputError,
            )
        self._sim.restore(np.ascontiguousarray(state.data, dtype=float))
        # The inputs held when a run gives none are the restored state's, not the last run's.
        self._pressures = [list(p) for p in self._sim.snapshot()["pressures"]]
        force, moment = self._sim.platform_loads()
        self._force, self._moment = list(force), list(moment)

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
        progress: Callable[[float, float, float], None] | bool | None = None,
    ) -> SystemTrajectory:
        """Advance by ``duration`` (s or a string with units) in output steps of dt and
        return the samples after each step (without the current state).

        ``pressures``: one list per rod (held), or a function of t (s) returning them,
        sampled at each step's end; None: the last ones. ``tensions``, ``platform_force``,
        ``platform_moment`` likewise (None: unchanged). ``progress``: None (a bar in
        interactive sessions), True, False, or a callable called after each chunk of steps
        as progress(t_done, duration, wall_s) (:mod:`softrod.progress`)."""
        out = self._run(
            duration, pressures, tensions, platform_force, platform_moment, progress=progress
        )
        return SystemTrajectory._concat(self.system, [out])

    def _run(
        self,
        duration,
        pressures,
        tensions,
        platform_force,
        platform_moment,
        field: str = "duration",
        progress: Callable[[float, float, float], None] | bool | None = False,
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
        # In chunks of about CHUNK_WALL_S of work (progress.chunks), as a lone rod's run, so
        # that a long run shows its progress; the core carries its state across calls exactly.
        parts = []
        wall0 = _time.perf_counter()
        with reporter(progress, "simulate_system", steps * self.dt, simulated_time) as report:
            for start, stop in chunks(steps, first=8, smallest=4):
                parts.append(
                    self._sim.run(
                        commands[start:stop],
                        tensions=None if tens is None else tens[start:stop],
                        platform_loads=None if loads is None else loads[start:stop],
                    )
                )
                if report is not None:
                    report(stop * self.dt, steps * self.dt, _time.perf_counter() - wall0)
        self._pressures = commands[-1]
        if loads is not None:
            self._force, self._moment = loads[-1]
        return _joined(parts)


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
    scheme: str = "bdf-alpha",
    alpha: float | None = None,
    tol: float = 1e-9,
    max_iter: int = 25,
    error_tol: Any = None,
    energy_tol: float = DEFAULT_ENERGY_TOL,
    on_unstable: str = "warn",
    stiffness_maps: Any = None,
    progress: Callable[[float, float, float], None] | bool | None = None,
) -> SystemTrajectory:
    """Simulate a :class:`~softrod.System` until ``t_end`` (s or a string with units; the
    run takes ceil(t_end / dt) output steps, as :func:`~softrod.simulate`),
    starting at rest in its static equilibrium under the inputs at t = 0.

    ``pressures``/``tensions``: one list per rod (Pa / N or strings with units, as
    :func:`~softrod.solve_system` takes them), held, or a function of t (s) returning them
    (its value at t = 0 is the start's; then sampled at each output step's end).
    ``platform_force``/``platform_moment`` (N, N m, world) likewise (None: the system's).
    ``platform_inertia``, ``dt``, ``scheme``, ``alpha``, ``tol``, ``max_iter``,
    ``error_tol``, ``energy_tol``, ``on_unstable``, ``stiffness_maps`` (one
    :class:`~softrod.StiffnessMap` or None per rod, as :func:`~softrod.solve_system` takes
    it; sigma evaluated at every step's pressures): as :class:`SystemSimulation` (whose
    only scheme is BDF-alpha: the midpoint rule is refused by name, as for a held tip).
    ``progress``: None (a bar in interactive sessions), True, False, or a callable called
    after each chunk of steps as progress(t_done, t_end, wall_s) (:mod:`softrod.progress`).
    Returns a :class:`SystemTrajectory` from t = 0 (docs/dynamics.md, "Systems of
    rods")."""

    sim = started(
        system,
        pressures,
        tensions,
        platform_force,
        platform_moment,
        platform_inertia=platform_inertia,
        dt=dt,
        scheme=scheme,
        alpha=alpha,
        tol=tol,
        max_iter=max_iter,
        error_tol=error_tol,
        energy_tol=energy_tol,
        on_unstable=on_unstable,
        stiffness_maps=stiffness_maps,
    )
    start = sim._sim.snapshot()
    out = sim._run(t_end, pressures, tensions, platform_force, platform_moment, "t_end", progress)
    return SystemTrajectory._concat(sim.system, [start, out])


def _joined(parts: list[dict]) -> dict:
    """The binding's samples of consecutive chunks as one: flat lists joined, per-rod lists
    (lists of lists) joined rod by rod."""
    if len(parts) == 1:
        return parts[0]
    out = {}
    for key, first in parts[0].items():
        if first and isinstance(first[0], list):
            out[key] = [
                list(chain.from_iterable(p[key][i] for p in parts)) for i in range(len(first))
            ]
        else:
            out[key] = list(chain.from_iterable(p[key] for p in parts))
    return out


def started(
    system: System | str,
    pressures: Any,
    tensions: Any = None,
    platform_force: Any = None,
    platform_moment: Any = None,
    **options: Any,
) -> SystemSimulation:
    """A :class:`SystemSimulation` at rest in equilibrium under the inputs at t = 0 (each
    held or a function of t, read there), with ``options`` as it takes them: the start of
    :func:`simulate_system` and of :func:`~softrod.system_trajectory_sensitivities`."""

    def at0(value):
        return value(0.0) if callable(value) else value

    return SystemSimulation(
        system,
        at0(pressures),
        tensions=at0(tensions),
        platform_force=at0(platform_force),
        platform_moment=at0(platform_moment),
        **options,
    )


def tracked_run(
    sim: SystemSimulation,
    params: Sequence[Any],
    markers: list[tuple[int | None, float, list[float]]],
    t_end: Any,
    pressures: Any,
    tensions: Any = None,
    platform_force: Any = None,
    platform_moment: Any = None,
    field: str = "t_end",
    progress: Callable[[float, float, float], None] | bool | None = False,
) -> dict[str, np.ndarray]:
    """Run a fresh ``sim`` (before its first step) until ``t_end`` as
    :meth:`SystemSimulation.run` runs it, with the binding's ``markers`` and the
    derivatives with respect to ``params`` (parsed :class:`~softrod.calibration.system.
    SystemParameter`; empty: none), from the start on: the arrays of
    :func:`~softrod.system_trajectory_sensitivities` (without the names). Shared with
    ``calibrate_system(dynamic=True)``'s replays."""
    if markers:
        sim._sim.set_markers(markers)
    if params:
        sim._sim.track_sensitivities([p.core() for p in params])
    start = sim._sim.snapshot()
    run = sim._run(t_end, pressures, tensions, platform_force, platform_moment, field, progress)
    n_par, n_mk = len(params), len(markers)
    time = np.concatenate([np.asarray(start["time"]), np.asarray(run["time"])], dtype=float)
    k = time.size

    def series(key, shape):
        a = np.concatenate([np.asarray(start[key]), np.asarray(run[key])], dtype=float)
        return a.reshape((k, *shape))

    def derivative(key, shape):
        if not n_par:
            return np.zeros((k, *shape, 0))
        return series(key, (*shape, n_par))

    return {
        "time": time,
        "platform_position": series("platform_position", (3,)),
        "platform_rotation": series("platform_rotation", (3, 3)),
        "marker_position": series("marker_position", (n_mk, 3)),
        "d_platform_position": derivative("d_platform_position", (3,)),
        "d_platform_rotation": derivative("d_platform_rotation", (3, 3)),
        "d_marker_position": derivative("d_marker_position", (n_mk, 3)),
    }
