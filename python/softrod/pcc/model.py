"""The PCC model of paper 003 on a softrod design: statics, dynamics and shape.

Thin wrappers around ``softrod._core.PccModel`` (the physics is in the Rust core,
``crates/softrod-core/src/pcc``). Coordinates q = (L, theta, phi) per segment as in paper 003
(theta >= 0, phi in (-pi, pi]; a planar model keeps a signed theta and phi = its plane);
every deformable section of the design is one constant-curvature segment, rigid sections are
straight links. Everything is SI.
"""

from __future__ import annotations

import copy
import json
from collections.abc import Sequence

import numpy as np

from .. import _core
from ..catalog import load_design
from ..constraints import require_free_tip
from ..errors import InputError, design_error
from ..units import to_si

__all__ = ["pcc_model", "pcc_parameters", "pcc_shape", "run_pcc"]


_CACHED_LOADS = 8  # compiled models kept per design (sweeps reuse a few tip loads)


def pcc_model(design, *, tip_force=None, tip_moment=None) -> _core.PccModel:
    """The compiled core model of ``design`` (tip loads optionally replaced, world frame).

    Kept on the design for the next call with the same tip loads: compiling costs more than
    a PCC static solve (the spec's JSON text and the core's checks)."""
    design = load_design(design)
    require_free_tip(design, "the PCC model")
    spec = design.spec
    force = None if tip_force is None else _vec3(tip_force, "force", "tip_force")
    moment = None if tip_moment is None else _vec3(tip_moment, "moment", "tip_moment")
    key = (None if force is None else tuple(force), None if moment is None else tuple(moment))
    cache = design._pcc
    if key in cache:
        return cache[key]
    if force is not None or moment is not None:
        spec = copy.deepcopy(spec)
        if force is not None:
            spec["tip"]["force"] = force
        if moment is not None:
            spec["tip"]["moment"] = moment
    model = _core.PccModel(json.dumps(spec))
    if len(cache) >= _CACHED_LOADS:
        cache.pop(next(iter(cache)))
    cache[key] = model
    return model


def _vec3(value, kind: str, name: str) -> list[float]:
    arr = list(value) if not isinstance(value, str) else value
    if isinstance(arr, str) or len(arr) != 3:
        raise design_error(name, value, f"must be 3 {kind} values (world frame)", InputError)
    return [to_si(x, kind, f"{name}[{i}]", InputError) for i, x in enumerate(arr)]


def pcc_parameters(design) -> list[dict]:
    """The parameters the PCC model uses for each segment, after the defaults of
    docs/pcc.md: dicts with name, length (m), mass (kg), k_L (N/m), b_L (N s/m), k_theta
    (N m/rad, or a pair (angles, stiffnesses)), b_theta (N m s/rad), k_phi, b_phi."""
    return pcc_model(design).segments()


def _pressure_array(model, pressures) -> np.ndarray:
    arr = np.asarray(pressures, dtype=float)
    nc = model.n_channels
    if arr.ndim == 1 and nc == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[1] != nc or arr.shape[0] < 1:
        raise design_error(
            "pressures",
            f"array of shape {arr.shape}",
            f"must be (n_steps + 1, {nc}): the chamber pressures (Pa) at every step time",
            InputError,
        )
    return np.ascontiguousarray(arr)


def run_pcc(
    design,
    dt: float,
    pressures,
    *,
    save_every: int = 1,
    initial: str | tuple = "rest",
    tol: float = 1e-11,
    max_iter: int = 30,
) -> dict[str, np.ndarray]:
    """Simulate the PCC model with time step ``dt`` (s).

    pressures: (n_steps + 1, n_channels) chamber pressures in Pa at the step times
    0, dt, ..., n_steps dt. initial: "rest" (at rest in the equilibrium under zero
    pressure), "static" (at rest in the equilibrium under the first row of pressures) or a
    pair (q, q_dot) of paper coordinates (L, theta, phi) per segment and their rates.
    Implicit midpoint rule with Newton (exact Jacobian); a step that does not converge
    raises ConvergenceError.

    Returns arrays at the saved steps (every ``save_every``-th, from step 0): ``time`` (n,) s,
    ``q``, ``q_dot`` (n, 3 * segments) paper coordinates, ``x``, ``x_dot`` (n, ndof) the
    regular coordinates (L, theta cos phi, theta sin phi) integrated, ``tip_position``
    (n, 3) m, ``tip_rotation`` (n, 3, 3), ``energy`` (n,) J (kinetic + gravitational +
    elastic), ``newton_iterations``.
    """
    model = pcc_model(design)
    dt = to_si(dt, "time", "dt", InputError)
    if not dt > 0:
        raise design_error("dt", dt, "must be a time step > 0 s", InputError)
    if isinstance(save_every, bool) or not isinstance(save_every, int) or save_every < 1:
        raise design_error("save_every", save_every, "must be an integer >= 1", InputError)
    arr = _pressure_array(model, pressures)
    kw = {"save_every": save_every, "tol": float(tol), "max_iter": int(max_iter)}
    if isinstance(initial, str):
        if initial not in ("rest", "static"):
            raise design_error(
                "initial", initial, "must be 'rest', 'static' or a pair (q, q_dot)", InputError
            )
        out = model.simulate(dt, arr, initial, **kw)
    else:
        try:
            q0, qd0 = initial
            q0 = [float(v) for v in np.ravel(q0)]
            qd0 = [float(v) for v in np.ravel(qd0)]
        except (TypeError, ValueError, OverflowError):
            raise design_error(
                "initial", initial, "must be 'rest', 'static' or a pair (q, q_dot)", InputError
            ) from None
        out = model.simulate(dt, arr, "given", q0=q0, q_dot0=qd0, **kw)
    return dict(out)


def pcc_shape(
    design, q: Sequence[float] | np.ndarray, *, n_points: int = 32
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The arc(s) of configuration ``q`` = (L, theta, phi) per segment, sampled at
    ``n_points`` intervals per section: (s (p,) reference arc length m, position (p, 3) m,
    rotation (p, 3, 3) [d1 d2 d3] in the world frame)."""
    model = pcc_model(design)
    if isinstance(n_points, bool) or not isinstance(n_points, int) or n_points < 1:
        raise design_error("n_points", n_points, "must be an integer >= 1", InputError)
    q = [float(v) for v in np.ravel(q)]
    x, _ = model.to_model(q, [0.0] * len(q))
    s, pos, rot = model.shape(x, n_points)
    return s, pos, rot
