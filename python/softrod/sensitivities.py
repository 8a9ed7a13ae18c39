"""Exact forward sensitivities of motion: a rod's tip and markers
(:func:`trajectory_sensitivities`) and a system's platform pose and markers
(:func:`system_trajectory_sensitivities`), with their derivatives with respect to named
model parameters, carried through every step by the core (the implicit function theorem on
each step's equations; docs/dynamics.md, "Parameter sensitivities of the motion").

Above both the dynamics (the runs: ``tracked_trajectory``, ``tracked_run``) and the
calibration (the parameters' names: ``parse_parameters``, ``parse_system_parameters``),
which the dynamic calibrations share with it."""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from . import _validate as V
from .calibration.params import parse_parameters
from .calibration.problem import REGISTRATION
from .calibration.system import parse_system_parameters
from .catalog import load_design
from .datasets import parse_marker_sites
from .dynamics.simulate import (
    DEFAULT_ENERGY_TOL,
    _schedule,
    _seconds,
    _tension_rows,
    step_count,
    tracked_trajectory,
)
from .errors import InputError
from .system import System, load_system
from .system_dynamics import started, tracked_run

if TYPE_CHECKING:
    from ._types import DesignLike

__all__ = ["system_trajectory_sensitivities", "trajectory_sensitivities"]


def _names(params: Sequence[str] | str) -> list[str] | Any:
    """``params`` as a list of names (a comma-separated string split outside brackets),
    with the registration parameters of a fit refused: they turn the measurement frame,
    not the model's motion."""
    names = params
    if isinstance(names, str):
        names = [n for n in re.split(r",(?![^\[]*\])", names) if n.strip()]
    if isinstance(names, (list, tuple)):
        for name in names:
            if isinstance(name, str) and name.strip() in REGISTRATION:
                raise V.fail(
                    "params",
                    name,
                    "is a fit's measurement frame, not a parameter of the model's motion: "
                    "name the model's parameters",
                    InputError,
                )
    return names


def trajectory_sensitivities(
    design: DesignLike,
    pressure_schedule: Any,
    t_end: Any,
    params: Sequence[str] | str,
    *,
    markers: Sequence | None = None,
    tensions: Any = None,
    dt: Any = 2e-3,
    tol: float = 1e-9,
    max_iter: int = 25,
    progress: Callable[[float, float, float], None] | bool | None = None,
) -> dict[str, Any]:
    """The motion of a rod's tip and of markers on its body, run as :func:`~softrod.simulate` runs
    it (from rest in equilibrium under the inputs at t = 0, BDF-alpha with fixed steps
    ``dt``, the design's integrator defaults), with the exact derivatives with respect to
    the model parameters ``params``, carried through every step by the core's forward
    sensitivities (``softrod_core::dynamics::sensitivity``, docs/dynamics.md).

    ``params``: names as :func:`~softrod.calibrate` takes them with ``dynamic=True`` (a list
    or a comma-separated string): ``"E"``, ``"c_b[body]"``, ``"area_scale"``,
    ``"damping_time"``, ...; an empty list: the run without derivatives.
    ``pressure_schedule`` (None for a design without chambers), ``t_end``, ``dt``,
    ``tensions`` (held or a function of t), ``markers`` (``(s, offset)`` or ``s``, SI or
    strings with units), ``tol`` and ``max_iter`` (each step's Newton settings) and
    ``progress`` (None: a bar in interactive sessions): as
    :func:`~softrod.simulate` takes them (the inputs are inputs, not parameters; adaptive
    steps are not offered: the step sizes would depend on the parameters).

    Returns a dict of arrays, k = steps + 1 samples (the start included), P parameters, K
    markers, derivatives per SI unit of each parameter (area_scale: per unit of the factor
    on the design's areas): "time" (k,) s, "tip_position" (k, 3) m, with parameters
    "d_tip_position" (k, 3, P), with markers "marker_position" (k, K, 3) m (and with both
    "d_marker_position" (k, K, 3, P)); "params" and "units", the parameters' names and SI
    units in the order of the last axis. Bad input raises
    :class:`~softrod.errors.InputError` naming the field before any step; a run that fails
    raises as :func:`~softrod.simulate` does."""
    d = load_design(design)
    names = _names(params)
    parsed = (
        parse_parameters(names, d) if not (isinstance(params, (list, tuple)) and not params) else []
    )
    sites = parse_marker_sites(markers, d.length)
    pairs = [] if sites is None else [(float(a), b.tolist()) for a, b in zip(*sites, strict=True)]
    schedule = (
        None
        if pressure_schedule is None and d.n_channels == 0
        else _schedule(pressure_schedule, d.n_channels)
    )
    step = _seconds(dt, "dt")
    duration = _seconds(t_end, "t_end")
    n = step_count(duration, step)
    rows = _tension_rows(d, tensions, step * np.arange(n + 1))
    out = tracked_trajectory(
        d,
        schedule,
        duration,
        step,
        [p.core() for p in parsed],
        rows,
        pairs,
        tol,
        max_iter,
        progress,
    )
    out["params"] = tuple(p.name for p in parsed)
    out["units"] = tuple(p.unit for p in parsed)
    return out


def _system_markers(system: System, markers: Any) -> list[tuple[int | None, float, list[float]]]:
    """The binding's markers ((rod or None for the platform, s, offset), m) of
    ``markers``: (body, s, offset) triples, body "platform" (s = 0) or a rod's index. The
    core checks s and the offset, naming ``markers[k]``."""
    if markers is None:
        return []
    if isinstance(markers, (str, bytes)) or not isinstance(markers, (list, tuple)):
        raise V.fail(
            "markers",
            markers,
            "must be a list of (body, s, offset): body 'platform' or a rod's index, s (m) "
            "and an offset (3,) in m",
            InputError,
        )
    n = len(system.rods)
    out: list[tuple[int | None, float, list[float]]] = []
    for k, m in enumerate(markers):
        if not isinstance(m, (list, tuple)) or len(m) != 3:
            raise V.fail(
                f"markers[{k}]",
                m,
                "must be (body, s, offset): body 'platform' or a rod's index, s (m) and an "
                "offset (3,) in m",
                InputError,
            )
        body, s, offset = m
        if isinstance(body, str) and body == "platform":
            rod = None
        elif V.is_real(body) and float(body).is_integer() and 0 <= int(body) < n:
            rod = int(body)
        else:
            raise V.fail(
                f"markers[{k}].body",
                body,
                f"must be 'platform' or a rod's index (0 ... {n - 1})",
                InputError,
            )
        s = V.real(s, f"markers[{k}].s")
        off = V.real_array(offset, f"markers[{k}].offset", ndim=1, unit_kind="length")
        if off.shape != (3,):
            raise V.fail(f"markers[{k}].offset", offset, "must be 3 numbers (m)", InputError)
        out.append((rod, float(s), [float(v) for v in off]))
    return out


def system_trajectory_sensitivities(
    system: System | str,
    pressures: Any | Callable[[float], Any],
    t_end: Any,
    params: Sequence[str] | str,
    *,
    markers: Sequence[tuple[Any, float, Any]] = (),
    tensions: Any | Callable[[float], Any] = None,
    platform_force: Any = None,
    platform_moment: Any = None,
    platform_inertia: Any = None,
    dt: Any = 2e-3,
    alpha: float | None = None,
    tol: float = 1e-9,
    max_iter: int = 25,
    energy_tol: float = DEFAULT_ENERGY_TOL,
    on_unstable: str = "warn",
    stiffness_maps: Any = None,
    progress: Callable[[float, float, float], None] | bool | None = None,
) -> dict[str, Any]:
    """The motion of a :class:`~softrod.System`'s platform and of markers on it or on its
    rods, run as :func:`simulate_system` runs it (from rest in equilibrium under the inputs
    at t = 0, BDF-alpha with fixed steps ``dt``), with its exact derivatives with respect to
    the model parameters ``params``, carried through every step by the core's forward
    sensitivities (``SystemSimulator::track_sensitivities``: the implicit function theorem
    on each step's coupled equations, docs/dynamics.md "Systems of rods").

    ``params``: names as :func:`~softrod.calibrate_system` takes them with
    ``dynamic=True`` (a list or a comma-separated string): a rod parameter acting on every
    rod (``"E"``, ``"c_b[body]"``, the rods must share its value) or on one
    (``"rods[1].c_b"``), the damping time (``"damping_time"``) and ``"platform_mass"``;
    an empty list: the run without derivatives. ``markers``: (body, s, offset) triples,
    body ``"platform"`` (s = 0, offset in the platform frame) or a rod's index (s in
    [0, L] of that rod, offset in its cross-section frame), m. ``pressures``,
    ``tensions``, ``platform_force``, ``platform_moment`` (held or functions of t),
    ``platform_inertia``, ``alpha``, ``tol``, ``max_iter``, ``energy_tol``,
    ``on_unstable``, ``stiffness_maps`` and ``progress``: as :func:`simulate_system` (the
    inputs are inputs, not parameters; adaptive steps are not offered: the step sizes would
    depend on the parameters).

    Returns a dict of arrays, k = steps + 1 samples (the start included), P parameters, K
    markers, derivatives per SI unit of each parameter: "time" (k,) s,
    "platform_position" (k, 3) m, "platform_rotation" (k, 3, 3), "marker_position"
    (k, K, 3) m, "d_platform_position" (k, 3, P), "d_platform_rotation" (k, 3, 3, P),
    "d_marker_position" (k, K, 3, P), and "params" and "units": the parameters' names and
    SI units, in the order of the last axis. Bad input raises
    :class:`~softrod.errors.InputError` naming the field (``params``, ``markers[k]``, ...)
    before any step; a run that fails raises as :func:`simulate_system` does."""

    if not isinstance(system, System):
        system = load_system(system)
    names = _names(params)
    parsed = (
        parse_system_parameters(names, system, dynamic=True)
        if not (isinstance(params, (list, tuple)) and len(params) == 0)
        else []
    )
    core_markers = _system_markers(system, markers)
    sim = started(
        system,
        pressures,
        tensions,
        platform_force,
        platform_moment,
        platform_inertia=platform_inertia,
        dt=dt,
        alpha=alpha,
        tol=tol,
        max_iter=max_iter,
        energy_tol=energy_tol,
        on_unstable=on_unstable,
        stiffness_maps=stiffness_maps,
    )
    out = tracked_run(
        sim,
        parsed,
        core_markers,
        t_end,
        pressures,
        tensions,
        platform_force,
        platform_moment,
        progress=progress,
    )
    out["params"] = tuple(p.name for p in parsed)
    out["units"] = tuple(p.unit for p in parsed)
    return out
