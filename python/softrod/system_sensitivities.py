"""Exact forward sensitivities of a system's motion (``softrod.system_trajectory_
sensitivities``): the platform pose and markers on the platform and the rods, with their
derivatives with respect to named model parameters, from the core's tracked run.

Above both :mod:`softrod.system_dynamics` (the run, ``tracked_run``) and
:mod:`softrod.calibration.system` (the parameters' names, ``parse_system_parameters``),
which calibrate_system(dynamic=True) shares with it."""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from typing import Any

from . import _validate as V
from .calibration.problem import REGISTRATION
from .calibration.system import parse_system_parameters
from .dynamics.simulate import DEFAULT_ENERGY_TOL
from .errors import InputError
from .system import System, load_system
from .system_dynamics import SystemSimulation, tracked_run

__all__ = ["system_trajectory_sensitivities"]


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
    ``on_unstable`` and ``stiffness_maps``: as :func:`simulate_system` (the inputs are
    inputs, not parameters; adaptive steps are not offered: the step sizes would depend on
    the parameters).

    Returns a dict of arrays, k = steps + 1 samples (the start included), P parameters, K
    markers, derivatives per SI unit of each parameter: "time" (k,) s,
    "platform_position" (k, 3) m, "platform_rotation" (k, 3, 3), "marker_position"
    (k, K, 3) m, "d_platform_position" (k, 3, P), "d_platform_rotation" (k, 3, 3, P),
    "d_marker_position" (k, K, 3, P), and "params" and "units": the parameters' names and
    SI units, in the order of the last axis. Bad input raises
    :class:`~softrod.errors.InputError` naming the field (``params``, ``markers[k]``, ...)
    before any step; a run that fails raises as :func:`simulate_system` does."""

    def at0(value):
        return value(0.0) if callable(value) else value

    if not isinstance(system, System):
        system = load_system(system)
    names = params
    if isinstance(names, str):
        names = re.split(r",(?![^\[]*\])", names)
    if isinstance(names, (list, tuple)):
        for name in names:
            if isinstance(name, str) and name.strip() in REGISTRATION:
                raise V.fail(
                    "params",
                    name,
                    "is a fit's measurement frame, not a parameter of the model's motion: "
                    "name the rods' parameters, damping_time and platform_mass",
                    InputError,
                )
    parsed = (
        parse_system_parameters(params, system, dynamic=True)
        if not (isinstance(params, (list, tuple)) and len(params) == 0)
        else []
    )
    core_markers = _system_markers(system, markers)
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
        energy_tol=energy_tol,
        on_unstable=on_unstable,
        stiffness_maps=stiffness_maps,
    )
    out = tracked_run(
        sim, parsed, core_markers, t_end, pressures, tensions, platform_force, platform_moment
    )
    out["params"] = tuple(p.name for p in parsed)
    out["units"] = tuple(p.unit for p in parsed)
    return out
