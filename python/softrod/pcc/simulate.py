"""``simulate(design, schedule, t_end, model="pcc")``: the PCC model's motion as a
:class:`~softrod.dynamics.Trajectory`, the same result type as the Cosserat rod's.

The time stepping lives in the Rust core (``softrod_core::pcc``: implicit midpoint rule with
Newton on the exact Jacobian). This module samples the schedule at the step times, drives the
core in chunks so that long runs can show progress, and packs the saved steps. The commanded
pressures pass through the design's pressure supply (``[dynamics]`` lag and rate limit) in
the core, exactly as for the rod, so both models see the same chamber pressures.
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Callable

import numpy as np

from ..catalog import load_design
from ..errors import InputError, design_error
from ..progress import chunks
from .model import pcc_model

__all__ = ["PCC_METHOD", "simulate_pcc"]

PCC_METHOD = "implicit midpoint rule with Newton on the exact Jacobian (paper 003 Lagrangian)"
SHAPE_POINTS = 24  # centreline samples per section of a stored shape (an arc: smooth)


def simulate_pcc(
    design,
    schedule,
    t_end: float,
    *,
    dt: float,
    save_every: int,
    shape_steps: np.ndarray,
    shape_at_start: bool,
    initial: str,
    tol: float,
    max_iter: int,
    energy: bool,
    progress: Callable[[float, float, float], None] | None,
):
    """Run the PCC model; the arguments are already checked by ``softrod.simulate``
    (``schedule`` is a PressureSchedule, ``shape_steps`` the 0-based steps after which the
    shape is kept)."""
    from ..dynamics.trajectory import Trajectory

    design = load_design(design)
    model = pcc_model(design)
    n = max(1, math.ceil(t_end / dt * (1.0 - 1e-12)))
    if initial == "static":
        state = ("static", None, None)
    elif initial == "straight":
        q0 = [v for seg in model.segments() for v in (seg["length"], 0.0, 0.0)]
        state = ("given", q0, [0.0] * len(q0))
    else:
        raise design_error("initial", initial, "must be 'static' or 'straight'", InputError)
    keep = np.zeros(n + 1, dtype=bool)  # step index 0..n
    keep[::save_every] = True
    keep[n] = True
    shape_keep = np.zeros(n + 1, dtype=bool)
    shape_keep[np.asarray(shape_steps, dtype=int) + 1] = True
    shape_keep[0] = shape_at_start
    # The core saves every `every`-th step of a chunk and its last; chunks are multiples of
    # `every`, so the saved steps line up with the global pattern.
    every = save_every if not shape_keep.any() or np.all(keep[shape_keep]) else 1
    parts: list[dict] = []
    wall0 = _time.perf_counter()
    pressure_now = schedule.sample([0.0])[0]
    first = max(every, 256 - 256 % every)
    for start, stop in chunks(n, first=first, smallest=64, largest=1_000_000, multiple=every):
        # Commands sampled chunk by chunk: memory stays bounded by the chunk size.
        rows = np.ascontiguousarray(schedule.sample(dt * np.arange(start, stop + 1)))
        rows[0] = pressure_now  # the supply continues from the pressures reached
        kind, a, b = state
        out = model.simulate(
            dt, rows, kind, q0=a, q_dot0=b, save_every=every, tol=tol, max_iter=max_iter
        )
        step_of_row = start + np.rint(out["time"] / dt).astype(int)
        if parts:  # row 0 repeats the previous chunk's last step
            out = {k: v[1:] if isinstance(v, np.ndarray) else v for k, v in out.items()}
            step_of_row = step_of_row[1:]
        out["step"] = step_of_row
        parts.append(out)
        state = ("model", list(out["x"][-1]), list(out["x_dot"][-1]))
        pressure_now = out["pressure"][-1]
        if progress is not None:
            progress(stop * dt, t_end, _time.perf_counter() - wall0)
    wall = _time.perf_counter() - wall0

    def cat(key):
        return np.concatenate([p[key] for p in parts])

    steps = cat("step")
    sel = keep[steps]
    shape_sel = shape_keep[steps]
    shape_s = shape_position = shape_time = None
    if shape_sel.any():
        shape_s, shape_position = model.shapes(
            np.ascontiguousarray(cat("x")[shape_sel]), SHAPE_POINTS
        )
        shape_time = steps[shape_sel] * dt
    segments = model.segments()
    metadata = {
        "design": design.name,
        "model": "pcc",
        "method": PCC_METHOD,
        "dt_s": dt,
        "initial": initial,
        "steps": n,
        "wall_time_s": wall,
        "real_time_factor": (n * dt) / wall if wall > 0 else math.inf,
        "newton_iterations": int(sum(p["newton_iterations"] for p in parts)),
        "jacobians": int(sum(p["jacobian_evaluations"] for p in parts)),
        "pcc_segments": [
            {k: (np.asarray(v).tolist() if k == "k_theta" else v) for k, v in s.items()}
            for s in segments
        ],
    }
    return Trajectory(
        time=steps[sel] * dt,
        command=schedule.sample(dt * steps[sel]),
        pressure=cat("pressure")[sel],
        tip_position=cat("tip_position")[sel],
        tip_rotation=cat("tip_rotation")[sel],
        tip_velocity=cat("tip_velocity")[sel],
        energy=cat("energy")[sel] if energy else None,
        shape_time=shape_time,
        shape_s=shape_s,
        shape_position=shape_position,
        metadata=metadata,
    )
