"""``simulate``: the motion of a design under a pressure schedule (docs/dynamics.md).

The physics and the time stepping live in the Rust core (``softrod_core::dynamics``:
paper 000's Kelvin-Voigt Cosserat rod, BDF-alpha in time and shooting in space as in Till,
Aloi and Rucker, IJRR 2019). This module turns user input into SI arrays, drives the core in
chunks so that long runs can show progress, and packs the result into a
:class:`~softrod.dynamics.Trajectory`.
"""

from __future__ import annotations

import json
import logging
import math
import os
import time as _time
from collections.abc import Callable, Sequence

import numpy as np

from .. import _core
from ..catalog import load_design
from ..design import Design
from ..errors import InputError, design_error
from ..progress import reporter
from ..units import to_si
from .schedule import PressureSchedule
from .trajectory import Trajectory

__all__ = ["METHOD", "Simulation", "simulate"]

METHOD = "BDF-alpha in time, shooting in space with RK4 (Till, Aloi, Rucker, IJRR 2019)"
_CHUNK_WALL_S = 0.2  # wall time per chunk between progress reports

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


def simulated_time(done: float, total: float, wall: float) -> tuple[float, str]:
    """A progress bar's position and text for simulate's progress(t_done, t_end, wall_s)."""
    rtf = f"{done / wall:,.0f}x real time" if wall > 0 else ""
    return done, f"{done:.2f} / {total:g} s {rtf}"


def _seconds(value, field: str, *, positive: bool = True) -> float:
    x = to_si(value, "time", field, InputError)
    if positive and x <= 0:
        raise design_error(field, value, "must be > 0 s", InputError)
    return x


def _schedule(schedule, n_channels: int) -> PressureSchedule:
    """A PressureSchedule from a schedule, a file path, a callable or constant pressures."""
    if isinstance(schedule, PressureSchedule):
        out = schedule
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

    ``pressures``: chamber pressures at t = 0 in Pa (default zero). ``initial``:
    ``"static"`` (at rest in equilibrium under those pressures, gravity and the design's tip
    loads) or ``"straight"`` (at rest in the straight reference shape, released at t = 0).
    ``dt``: time step (s or a string with units). ``alpha``: BDF-alpha parameter in
    [-0.5, 0] (-0.5 is paper 000's trapezoidal rule; 0 is BDF2). ``tol``: tolerance on the
    scaled shooting residual at each step.
    """

    def __init__(
        self,
        design,
        pressures=None,
        *,
        initial: str = "static",
        dt=2e-3,
        alpha: float = -0.2,
        tol: float = 1e-9,
        max_iter: int = 25,
    ):
        self.design: Design = load_design(design)
        _no_stiffness_map(self.design)
        n = self.design.n_channels
        p = np.zeros(n) if pressures is None else np.asarray(pressures, dtype=float)
        if p.shape != (n,):
            raise design_error(
                "pressures",
                list(np.ravel(p)),
                f"the design has {n} pressure channels; give one gauge pressure (Pa) each",
                InputError,
            )
        if initial not in ("static", "straight"):
            raise design_error("initial", initial, "must be 'static' or 'straight'", InputError)
        self._sim = _core.Simulator(
            json.dumps(self.design.spec),
            p.tolist(),
            initial,
            _seconds(dt, "dt"),
            float(alpha),
            float(tol),
            int(max_iter),
        )
        self.initial = initial
        self.alpha = float(alpha)

    @classmethod
    def _wrap(cls, design: Design, sim, initial: str, alpha: float) -> Simulation:
        obj = cls.__new__(cls)
        obj.design, obj._sim, obj.initial, obj.alpha = design, sim, initial, alpha
        return obj

    def copy(self) -> Simulation:
        """An independent simulation starting from this one's current state."""
        return Simulation._wrap(self.design, self._sim.copy(), self.initial, self.alpha)

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
    def stats(self) -> dict:
        """Steps, Newton iterations and exact Jacobians so far."""
        return dict(self._sim.stats)

    def state(self) -> dict:
        """The state now: ``time`` (s), ``pressure`` (Pa), ``tip_position`` (m),
        ``tip_rotation``, ``tip_velocity`` (m/s), ``energy`` (J), ``base_force`` (N),
        ``base_moment`` (N m), ``shape_s`` (m) and ``shape_position`` (p, 3) m."""
        d = self._sim.snapshot()
        return {
            "time": float(d["time"][0]),
            "pressure": d["pressure"][0],
            "tip_position": d["tip_position"][0],
            "tip_rotation": d["tip_rotation"][0],
            "tip_velocity": d["tip_velocity"][0],
            "energy": float(d["energy"][0]),
            "base_force": np.asarray(d["base_force"]),
            "base_moment": np.asarray(d["base_moment"]),
            "shape_s": d["shape_s"],
            "shape_position": d["shape_position"][0],
        }

    def set_tip_loads(self, force=(0.0, 0.0, 0.0), moment=(0.0, 0.0, 0.0)) -> None:
        """Dead tip force (N) and moment (N m), world frame, from the next step on."""
        self._sim.set_tip_loads([float(x) for x in force], [float(x) for x in moment])

    def step(self, command) -> None:
        """One time step towards the commanded pressures ``command`` (Pa)."""
        c = np.asarray(command, dtype=float).reshape(1, -1)
        self._sim.run(c, np.zeros(1, dtype=np.uint8), False)

    def run(
        self,
        pressure_schedule,
        duration,
        *,
        save_every: int = 1,
        shapes=None,
        energy: bool = True,
        progress: Callable[[float, float, float], None] | None = None,
    ) -> Trajectory:
        """Advance by ``duration`` (s) under ``pressure_schedule`` (evaluated on this
        simulation's clock) and return the trajectory from the current time on; see
        :func:`simulate` for the arguments."""
        dt = self.dt
        duration = _seconds(duration, "t_end")
        n = max(1, math.ceil(duration / dt * (1.0 - 1e-12)))
        if isinstance(save_every, bool) or not isinstance(save_every, int | np.integer):
            raise design_error("save_every", save_every, "must be an integer >= 1", InputError)
        if save_every < 1:
            raise design_error("save_every", save_every, "must be an integer >= 1", InputError)
        schedule = _schedule(pressure_schedule, self.design.n_channels)
        t0 = self.time
        keep = np.zeros(n, dtype=np.uint8)
        keep[save_every - 1 :: save_every] = 1
        keep[-1] = 1
        shape_steps, want_shape0 = _shape_steps(shapes, n, dt, save_every)
        keep[shape_steps] = 2
        times = t0 + dt * np.arange(1, n + 1)
        commands = schedule.sample(times)
        first = self._sim.snapshot()
        parts = [first]
        wall0 = _time.perf_counter()
        start, chunk = 0, 32
        with reporter(progress, "simulate", duration, simulated_time) as report:
            while start < n:
                stop = min(n, start + chunk)
                t_chunk = _time.perf_counter()
                parts.append(
                    self._sim.run(
                        np.ascontiguousarray(commands[start:stop]), keep[start:stop], bool(energy)
                    )
                )
                spent = _time.perf_counter() - t_chunk
                # Size the next chunk for about _CHUNK_WALL_S of work.
                chunk = int(np.clip(chunk * _CHUNK_WALL_S / max(spent, 1e-6), 8, 100_000))
                start = stop
                if report is not None:
                    report(self.time - t0, duration, _time.perf_counter() - wall0)
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
        command0 = schedule.sample([t0])
        shape_parts = [p for p in (parts if want_shape0 else parts[1:]) if len(p["shape_time"])]
        metadata = {
            "design": self.design.name,
            "model": "cosserat",
            "method": METHOD,
            "dt_s": dt,
            "alpha": self.alpha,
            "initial": self.initial,
            "damping_time_s": self.design.spec["dynamics"]["damping_time"],
            "steps": n,
            "wall_time_s": wall,
            "real_time_factor": (n * dt) / wall if wall > 0 else math.inf,
            **{k: int(v) for k, v in self._sim.stats.items()},
        }
        return Trajectory(
            time=cat("time"),
            command=np.concatenate([command0, commands[keep >= 1]]),
            pressure=cat("pressure"),
            tip_position=cat("tip_position"),
            tip_rotation=cat("tip_rotation"),
            tip_velocity=cat("tip_velocity"),
            energy=cat("energy") if energy else None,
            shape_time=np.concatenate([p["shape_time"] for p in shape_parts])
            if shape_parts
            else None,
            shape_s=first["shape_s"] if shape_parts else None,
            shape_position=np.concatenate([p["shape_position"] for p in shape_parts])
            if shape_parts
            else None,
            metadata=metadata,
        )


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
    arr = np.atleast_1d(np.asarray(shapes, dtype=float))
    if arr.ndim == 1 and arr.size == 1 and not isinstance(shapes, Sequence | np.ndarray):
        every = max(1, round(float(arr[0]) / dt))
        if not (math.isfinite(arr[0]) and arr[0] > 0):
            raise design_error("shapes", shapes, "an interval must be > 0 s", InputError)
        return np.arange(every - 1, n, every), True
    # Chosen instants, relative to the start of the run: the nearest step.
    if not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise design_error("shapes", list(arr), "times must be finite and >= 0 s", InputError)
    steps = np.rint(arr / dt).astype(int)
    return np.unique(np.clip(steps[steps > 0] - 1, 0, n - 1)), bool(np.any(steps == 0))


def simulate(
    design,
    pressure_schedule,
    t_end,
    *,
    dt=2e-3,
    save_every: int = 1,
    shapes=None,
    initial="static",
    model: str = "cosserat",
    alpha: float = -0.2,
    tol: float | None = None,
    max_iter: int | None = None,
    energy: bool = True,
    progress: Callable[[float, float, float], None] | None = None,
) -> Trajectory:
    """Simulate the motion of ``design`` under ``pressure_schedule`` from t = 0 to ``t_end``.

    - ``design``: a Design, a bundled name or a TOML path. Its ``[dynamics]`` table gives the
      Kelvin-Voigt damping time tau (B = tau K, paper 000 eq. 8) and the pressure supply's
      lag and rate limit; sections may give damping matrices and rotary inertia instead.
    - ``pressure_schedule``: a :class:`PressureSchedule`, a CSV/Parquet file of commands
      (``time_s``, ``p0_kPa``, ...), a function of t (s) returning one pressure per channel
      (Pa), or constant pressures (Pa).
    - ``t_end`` (s or a string with units) and ``dt`` (default 2 ms): the run takes
      ceil(t_end / dt) steps.
    - ``save_every``: keep every n-th step (the last step is always kept).
    - ``shapes``: None (tip only), ``"saved"`` (the centreline at every kept sample), an
      interval in s, or a list of instants (s, nearest step).
    - ``initial``: ``"static"`` (at rest in equilibrium under the first commanded pressures),
      ``"straight"`` (at rest in the straight reference shape), or a :class:`Simulation`
      to continue from its state (it is not changed; the schedule is read on its clock).
    - ``model``: ``"cosserat"`` (paper 000's viscoelastic rod) or ``"pcc"`` (paper 003's
      piecewise-constant-curvature Lagrangian model, one arc per deformable section, with
      the design's ``[pcc]`` parameters; docs/pcc.md). Both take the same schedule through
      the same pressure supply and return the same :class:`Trajectory`; a PCC run's shapes
      are its arcs sampled along s, and ``initial`` may not be a :class:`Simulation`.
    - ``alpha``, ``tol``, ``max_iter``: integrator settings (see :class:`Simulation`;
      ``alpha`` is the rod's BDF-alpha parameter; the PCC model uses the implicit midpoint
      rule, its ``tol`` default is 1e-11 on the Newton update per coordinate scale).
    - ``energy``: also record the total mechanical energy (J).
    - ``progress``: None (a bar in interactive sessions), True, False, or a callable called
      after each chunk of steps as progress(t_done, t_end, wall_s); see
      :mod:`softrod.progress`.

    Returns a :class:`Trajectory`; its metadata records the method, the wall time and the
    real-time factor. A step that does not converge raises ``ConvergenceError`` with the
    time it failed at.
    """
    if model not in ("cosserat", "pcc"):
        raise design_error("model", model, "must be 'cosserat' or 'pcc'", InputError)
    if model == "pcc":
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
    else:
        d = load_design(design)
        schedule = _schedule(pressure_schedule, d.n_channels)
        p0 = schedule.sample([0.0])[0]
        if not isinstance(initial, str):
            raise design_error(
                "initial",
                type(initial).__name__,
                "must be 'static', 'straight' or a Simulation",
                InputError,
            )
        sim = Simulation(d, p0, initial=initial, dt=dt, alpha=alpha, tol=tol, max_iter=max_iter)
        pressure_schedule = schedule
    return sim.run(
        pressure_schedule,
        t_end,
        save_every=save_every,
        shapes=shapes,
        energy=energy,
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
    if alpha != -0.2:
        raise design_error(
            "alpha",
            alpha,
            "is the rod's BDF-alpha parameter; the PCC model uses the implicit midpoint rule",
            InputError,
        )
    d = load_design(design)
    _no_stiffness_map(d)
    schedule = _schedule(pressure_schedule, d.n_channels)
    step = _seconds(dt, "dt")
    duration = _seconds(t_end, "t_end")
    if isinstance(save_every, bool) or not isinstance(save_every, int | np.integer):
        raise design_error("save_every", save_every, "must be an integer >= 1", InputError)
    if save_every < 1:
        raise design_error("save_every", save_every, "must be an integer >= 1", InputError)
    n = max(1, math.ceil(duration / step * (1.0 - 1e-12)))
    shape_steps, shape0 = _shape_steps(shapes, n, step, int(save_every))
    with reporter(kw.pop("progress"), "simulate (PCC)", duration, simulated_time) as report:
        return simulate_pcc(
            d,
            schedule,
            duration,
            dt=step,
            save_every=int(save_every),
            shape_steps=shape_steps,
            shape_at_start=shape0,
            initial=initial,
            progress=report,
            **kw,
        )
