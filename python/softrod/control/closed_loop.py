"""Closed-loop simulation: a controller called at a fixed rate drives the dynamic rod
(``run_closed_loop``), and a tracking controller built from inverse statics with a PI
correction on the tip error (``TrackingController``), for target paths such as a circle
(``TargetPath``). docs/control.md shows the paper 000 arm tracing a circle.

The simulation is :class:`softrod.Simulation` (the physics in Rust); the controller is the
user's Python callable, called once per control period with a :class:`Measurement`; its
command is held until the next call (zero-order hold).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import pandas as pd

    from .._types import ArrayLike, DesignLike, PathLike, Quantity
    from ..dynamics import Trajectory

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .. import _validate as V
from .._validate import real
from ..catalog import load_design
from ..constraints import require_free_tip
from ..errors import InputError, design_error
from ..units import to_si

__all__ = [
    "ClosedLoopResult",
    "Measurement",
    "TargetPath",
    "TrackingController",
    "predicted_circle_error",
    "run_closed_loop",
    "tracking_frame",
    "tracking_plot",
]


@dataclass(frozen=True)
class Measurement:
    """What a controller sees at a sample (SI, world frame): ``time`` s, ``tip_position``
    (3,) m, ``tip_rotation`` (3, 3), ``tip_velocity`` (3,) m/s, ``pressure`` (c,) Pa (the
    chamber pressures now) and ``command`` (c,) Pa (the command held until now)."""

    time: float
    tip_position: np.ndarray
    tip_rotation: np.ndarray
    tip_velocity: np.ndarray
    pressure: np.ndarray
    command: np.ndarray


@dataclass(frozen=True)
class ClosedLoopResult:
    """A closed-loop run: ``trajectory`` (every simulation step, a
    :class:`softrod.Trajectory`), ``control_time`` (k,) s and ``commands`` (k, c) Pa: the
    controller's calls and answers; ``rate`` Hz."""

    trajectory: object
    control_time: np.ndarray
    commands: np.ndarray
    rate: float
    metadata: dict = field(default_factory=dict)


def _period(rate, dt):
    rate = real(rate, "rate", minimum=0.0, exclusive=True, what="a control rate in Hz")
    period = 1.0 / rate
    if dt is None:
        steps = max(1, math.ceil(period / 2e-3 - 1e-9))
        return float(rate), period, period / steps, steps
    step = to_si(dt, "time", "dt", InputError)
    if not step > 0:
        raise design_error("dt", dt, "must be > 0 s", InputError)
    steps = round(period / step)
    if steps < 1 or abs(steps * step - period) > 1e-9 * period:
        raise design_error(
            "dt",
            dt,
            f"the control period 1/rate = {period} s must be a whole number of time steps",
            InputError,
        )
    return float(rate), period, step, steps


def run_closed_loop(
    design: DesignLike,
    controller: Callable[[Measurement], ArrayLike],
    t_end: Quantity,
    *,
    rate: float,
    dt: Quantity | None = None,
    pressures: ArrayLike | None = None,
    initial: str = "static",
    alpha: float = -0.2,
    progress: Callable[[float, float], None] | bool | None = None,
) -> ClosedLoopResult:
    """Simulate ``design`` for ``t_end`` (s) with ``controller`` in the loop.

    ``controller(measurement)`` is called at t = 0, 1/rate, 2/rate, ... (``rate`` in Hz)
    and returns the commanded chamber pressures (Pa, one per channel), held until the next
    call. ``dt``: the simulation's time step, a whole fraction of the control period
    (default: the largest one <= 2 ms). ``pressures`` and ``initial`` set the start as in
    :class:`softrod.Simulation` (default: at rest in equilibrium at zero pressure).
    ``progress(t_done, t_end)`` is called after every control period (None: a bar in
    interactive sessions; True or False: always or never a bar; softrod.progress).
    """
    from ..dynamics import Simulation, Trajectory
    from ..dynamics.simulate import step_count
    from ..progress import reporter
    from ..statics import _pressures

    design = load_design(design)
    require_free_tip(design, "run_closed_loop")
    if not callable(controller):
        raise design_error(
            "controller",
            type(controller).__name__,
            "must be callable: controller(measurement) -> pressures (Pa)",
            InputError,
        )
    rate, period, step, steps = _period(rate, dt)
    duration = to_si(t_end, "time", "t_end", InputError)
    if not duration > 0:
        raise design_error("t_end", t_end, "must be > 0 s", InputError)
    periods = max(1, math.ceil(duration / period - 1e-9))
    # The whole run's steps are bounded as simulate's are, before the first one.
    step_count(periods * period, step)
    nc = design.n_channels
    p0 = np.zeros(nc) if pressures is None else np.array(_pressures(design, pressures))
    sim = Simulation(design, p0, initial=initial, dt=step, alpha=alpha)
    state = sim.state()
    meas = Measurement(
        time=state.time,
        tip_position=np.array(state.tip_position),
        tip_rotation=np.array(state.tip_rotation),
        tip_velocity=np.array(state.tip_velocity),
        pressure=np.array(state.pressure),
        command=p0.copy(),
    )
    pieces, times, commands = [], [], []
    with reporter(progress, "closed loop", duration, _simulated) as report:
        for k in range(periods):
            meas = _period_run(controller, meas, sim, nc, steps * step, k, pieces, times, commands)
            if report is not None:
                report(min(meas.time, duration), duration)
    cat = lambda name: np.concatenate([getattr(p, name) for p in pieces])  # noqa: E731
    energy = None if pieces[0].energy is None else cat("energy")
    metadata = dict(pieces[0].metadata)
    metadata.update(
        {
            "control_rate_Hz": rate,
            "steps": int(periods * steps),
            "controller": type(controller).__name__,
        }
    )
    trajectory = Trajectory(
        time=cat("time"),
        command=cat("command"),
        pressure=cat("pressure"),
        tip_position=cat("tip_position"),
        tip_rotation=cat("tip_rotation"),
        tip_velocity=cat("tip_velocity"),
        energy=energy,
        metadata=metadata,
    )
    return ClosedLoopResult(
        trajectory=trajectory,
        control_time=np.array(times),
        commands=np.array(commands),
        rate=rate,
        metadata=metadata,
    )


def _simulated(done: float, total: float) -> tuple[float, str]:
    """A progress bar's position and text for run_closed_loop's progress(t_done, t_end)."""
    return done, f"{done:.3g} / {total:.3g} s"


def _period_run(controller, meas, sim, nc: int, span: float, k: int, pieces, times, commands):
    """One control period: the controller's command at the measurement ``meas``, held for
    ``span`` seconds of simulation; returns the next measurement."""
    from ..dynamics import PressureSchedule

    given = controller(meas)
    rule = f"must return {nc} finite pressures (Pa) at t = {meas.time:.6g} s"
    try:
        command = V.real_array(given, "controller", what="pressures (Pa)")
    except InputError as exc:
        raise design_error("controller", exc.value, f"{rule} ({exc.rule})", InputError) from None
    if command.shape != (nc,):
        raise design_error("controller", command.tolist(), rule, InputError)
    times.append(meas.time)
    commands.append(command)
    piece = sim.run(PressureSchedule.constant(command), span)
    pieces.append(piece if k == 0 else _drop_first(piece))
    return Measurement(
        time=float(piece.time[-1]),
        tip_position=piece.tip_position[-1],
        tip_rotation=piece.tip_rotation[-1],
        tip_velocity=piece.tip_velocity[-1],
        pressure=piece.pressure[-1],
        command=command,
    )


def _drop_first(piece):
    """A trajectory piece without its first sample (the previous piece's last)."""
    from ..dynamics import Trajectory

    return Trajectory(
        time=piece.time[1:],
        command=piece.command[1:],
        pressure=piece.pressure[1:],
        tip_position=piece.tip_position[1:],
        tip_rotation=piece.tip_rotation[1:],
        tip_velocity=piece.tip_velocity[1:],
        energy=None if piece.energy is None else piece.energy[1:],
        metadata=piece.metadata,
    )


@dataclass(frozen=True)
class TargetPath:
    """A target position as a function of time: samples (time (k,) s, position (k, 3) m)
    interpolated linearly, held before the first and after the last."""

    time: np.ndarray
    position: np.ndarray

    def __post_init__(self):
        t = V.real_array(self.time, "path.time", what="times (s)")
        p = V.real_array(self.position, "path.position", what="positions (m)")
        if t.ndim != 1 or t.size < 1 or p.shape != (t.size, 3):
            raise design_error(
                "path",
                f"time {t.shape}, position {p.shape}",
                "needs k times (s) and (k, 3) positions (m)",
                InputError,
            )
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(p))):
            raise design_error("path", "values", "must be finite", InputError)
        if np.any(np.diff(t) <= 0):
            raise design_error("path.time", "values", "must increase strictly", InputError)
        object.__setattr__(self, "time", t)
        object.__setattr__(self, "position", p)

    def at(self, t: float) -> np.ndarray:
        """The target position (m) at time ``t`` (s)."""
        t = V.real(t, "t", what="a time (s)")
        return np.array([np.interp(t, self.time, self.position[:, k]) for k in range(3)])

    @classmethod
    def circle(
        cls,
        center: ArrayLike,
        radius: Quantity,
        period: Quantity,
        *,
        duration: Quantity | None = None,
        samples_per_period: int = 400,
        start_angle: float = 0.0,
    ) -> TargetPath:
        """A circle in the horizontal (x-y) plane around ``center`` (3 values, m), run
        counter-clockwise seen from +z once per ``period`` (s) for ``duration`` (default one
        period)."""
        c = np.asarray(
            [to_si(v, "length", f"center[{i}]", InputError) for i, v in enumerate(center)]
        )
        r = to_si(radius, "length", "radius", InputError)
        per = to_si(period, "time", "period", InputError)
        dur = per if duration is None else to_si(duration, "time", "duration", InputError)
        if not (r > 0 and per > 0 and dur > 0):
            raise design_error(
                "circle",
                (radius, period, duration),
                "radius, period and duration must be > 0",
                InputError,
            )
        n = max(2, math.ceil(samples_per_period * dur / per) + 1)
        t = np.linspace(0.0, dur, n)
        a = start_angle + 2 * math.pi * t / per
        pos = c + r * np.column_stack([np.cos(a), np.sin(a), np.zeros_like(a)])
        return cls(t, pos)

    @classmethod
    def from_file(cls, path: PathLike) -> TargetPath:
        """Read a CSV with columns ``time_s`` and ``x_<unit>``, ``y_<unit>``, ``z_<unit>``
        (unit m or mm), e.g. ``time_s,x_mm,y_mm,z_mm``."""
        import pandas as pd

        frame = pd.read_csv(path)
        if "time_s" not in frame:
            raise design_error("path", str(path), "needs a column time_s", InputError)
        cols = []
        for axis in "xyz":
            for unit, scale in (("m", 1.0), ("mm", 1e-3)):
                name = f"{axis}_{unit}"
                if name in frame:
                    cols.append(frame[name].to_numpy(float) * scale)
                    break
            else:
                raise design_error(
                    "path", str(path), f"needs a column {axis}_m or {axis}_mm", InputError
                )
        return cls(frame["time_s"].to_numpy(float), np.column_stack(cols))

    def to_frame(self) -> pd.DataFrame:
        import pandas as pd

        return pd.DataFrame(
            {
                "time_s": self.time,
                "x_mm": self.position[:, 0] * 1e3,
                "y_mm": self.position[:, 1] * 1e3,
                "z_mm": self.position[:, 2] * 1e3,
            }
        )


class TrackingController:
    """Make the tip follow ``path`` (a :class:`TargetPath` or a function t -> (3,) m):
    inverse statics as feed-forward, and a PI correction on the tip error fed through the
    same inverse:

        e = r(t) - r_tip,   I += e / rate,   p = inverse(r(t) + kp e + ki I).

    ``kp`` (1) and ``ki`` (1/s) are gains on the position error; the inverse is warm-started
    from the previous call (:class:`InverseProblem`, ``pressure_bounds`` and the other
    keywords as there). When the corrected target is out of reach the inverse returns the
    closest pose and the integral is frozen (anti-windup). ``history`` keeps (t, r, r_tip,
    p) of every call.
    """

    def __init__(
        self,
        design: DesignLike,
        path: TargetPath | Callable[[float], ArrayLike],
        *,
        rate: float,
        kp: float = 0.0,
        ki: float = 0.0,
        pressure_bounds: ArrayLike | str | None = None,
        **problem: Any,
    ):
        from .inverse import InverseProblem

        self.design = load_design(design)
        require_free_tip(self.design, "TrackingController")
        self.path = path
        self.rate = real(rate, "rate", minimum=0.0, exclusive=True, what="a control rate in Hz")
        self.kp = real(kp, "kp", minimum=0.0)
        self.ki = real(ki, "ki", minimum=0.0)
        if self.design.n_channels == 0:
            raise design_error(
                "design",
                self.design.name,
                "has no pressure channels: the tracking controller commands pressures",
                InputError,
            )
        if "tension_bounds" in problem:
            raise design_error(
                "tension_bounds",
                problem["tension_bounds"],
                "the tracking controller commands pressures only; its "
                "inverse holds the tendons slack",
                InputError,
            )
        # The loop applies pressures only, so its inverse must not count on tensions.
        slack = (0.0, 0.0) if self.design.n_tendons else None
        self.problem = InverseProblem(
            self.design, pressure_bounds=pressure_bounds, tension_bounds=slack, **problem
        )
        self.integral = np.zeros(3)
        self.last = None
        self.history: list[tuple] = []

    def reference(self, t: float) -> np.ndarray:
        """The target position (m) at time ``t`` (s): the path's, or the callable's value."""
        if hasattr(self.path, "at"):
            return self.path.at(t)
        r = V.real_array(self.path(V.real(t, "t", what="a time (s)")), "path", what="positions (m)")
        if r.shape != (3,):
            raise design_error("path", r.tolist(), "must return 3 positions (m)", InputError)
        return r

    def __call__(self, m: Measurement) -> np.ndarray:
        r = self.reference(m.time)
        e = r - m.tip_position
        if self.last is None or self.last.reached:
            self.integral = self.integral + e / self.rate
        goal = r + self.kp * e + self.ki * self.integral
        self.last = self.problem.solve(goal, initial=self.last)
        self.history.append((m.time, r, np.asarray(m.tip_position), self.last.pressures))
        return self.last.pressures

    def errors(self, trajectory: Trajectory) -> np.ndarray:
        """Tip error |r(t) - r_tip(t)| (m) at every sample of a trajectory."""
        from ..dynamics import Trajectory

        if not isinstance(trajectory, Trajectory):
            raise design_error(
                "trajectory", type(trajectory).__name__, "must be a Trajectory", InputError
            )
        ref = np.array([self.reference(t) for t in trajectory.time])
        return np.linalg.norm(ref - trajectory.tip_position, axis=1)


def tracking_frame(controller: TrackingController, result: ClosedLoopResult):
    """One row per simulation step: time, reference, tip and error (mm), pressures (kPa)."""
    import pandas as pd

    traj = result.trajectory
    ref = np.array([controller.reference(t) for t in traj.time])
    err = np.linalg.norm(ref - traj.tip_position, axis=1)
    cols = {"time_s": traj.time}
    for k, axis in enumerate("xyz"):
        cols[f"target_{axis}_mm"] = ref[:, k] * 1e3
    for k, axis in enumerate("xyz"):
        cols[f"tip_{axis}_mm"] = traj.tip_position[:, k] * 1e3
    cols["error_mm"] = err * 1e3
    for c in range(traj.pressure.shape[1]):
        cols[f"p{c}_kPa"] = traj.pressure[:, c] / 1e3
    return pd.DataFrame(cols)


def tracking_plot(
    controller: TrackingController, result: ClosedLoopResult, path=None, *, title: str | None = None
):
    """Top view of the target and the tip, the tip error over time, and the chamber
    pressures; saved to ``path`` when given. Returns the figure."""
    title = V.figure_title(title)
    import matplotlib.pyplot as plt

    traj = result.trajectory
    ref = np.array([controller.reference(t) for t in traj.time]) * 1e3
    tip = traj.tip_position * 1e3
    err = np.linalg.norm(ref - tip, axis=1)
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2), constrained_layout=True)
    ax = axes[0]
    ax.plot(ref[:, 0], ref[:, 1], "k--", lw=1.2, label="target")
    ax.plot(tip[:, 0], tip[:, 1], lw=1.2, label="tip")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title("top view")
    ax.legend(fontsize=8)
    ax = axes[1]
    ax.plot(traj.time, err, lw=1.2)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("tip error (mm)")
    rms = float(np.sqrt(np.mean(err**2)))
    ax.set_title(f"tracking error (RMS {rms:.2f} mm)")
    ax.grid(True, alpha=0.3)
    ax = axes[2]
    for c in range(traj.pressure.shape[1]):
        ax.plot(traj.time, traj.pressure[:, c] / 1e3, lw=1.1, label=f"p{c}")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("chamber pressure (kPa)")
    ax.set_title("pressures")
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    fig.suptitle(
        title
        or f"{controller.design.name}: closed-loop tracking at "
        f"{result.rate:g} Hz (kp {controller.kp:g}, ki {controller.ki:g} 1/s)"
    )
    if path is not None:
        from pathlib import Path

        from ..io import atomic_path

        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=130, format=Path(path).suffix[1:])
    return fig


def predicted_circle_error(
    system, radius: float, period: float, *, kp: float, ki: float, rate: float
) -> float:
    """The steady-state RMS tip error (m) that the linearised model ``system`` (a
    :class:`~softrod.control.LinearSystem` at the circle's centre) predicts for a
    :class:`TrackingController` on a horizontal circle of ``radius`` run once per
    ``period``.

    Plant from the corrected target to the tip: G(s) = H(s) H(0)^-1 e^(-s / (2 rate)) with
    H(s) = T (M s^2 + D s + K)^-1 B_p (the tip's response to the pressures; inverse statics
    is H(0)^-1 to first order; the zero-order hold delays by half a control period).
    Controller C(s) = kp + ki / s on e = r - r_tip, so e = (I + G C)^-1 (I - G) r. For
    r = c + radius (cos w t, sin w t, 0), w = 2 pi / period, the error is the phasor
    e^ = E(i w) radius (1, -i, 0) and its RMS over a period |e^| / sqrt(2). Terms of second
    order in the radius over the arm's length (the Jacobian's change around the circle)
    and in w / rate are neglected.
    """
    nc = system.design.n_channels
    w = 2 * math.pi / period

    def tip_response(omega):
        # The tip position's rows (a held tip's are zeros or refused, by name).
        return system.frequency_response(omega)[:3, :nc]

    h0 = tip_response(0.0).real
    plant = tip_response(w) @ np.linalg.pinv(h0) * np.exp(-1j * w / (2 * rate))
    c = kp + ki / (1j * w)
    err = np.linalg.solve(np.eye(3) + plant * c, np.eye(3) - plant)
    phasor = err @ (radius * np.array([1.0, -1j, 0.0]))
    return float(np.linalg.norm(phasor) / math.sqrt(2))
