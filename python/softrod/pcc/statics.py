"""Static equilibria of the PCC model, returned as the rod's ``StaticSolution``."""

from __future__ import annotations

import numpy as np

from ..errors import ConvergenceError
from ..solution import StaticSolution
from .model import pcc_model

N_PER_SECTION = 32


def solve_pcc_statics(
    design,
    pressures: list[float],
    *,
    tip_force=None,
    tip_moment=None,
    max_iter: int = 30,
    initial=None,
    check: bool = True,
):
    """PCC equilibrium under ``pressures`` (Pa, validated by the caller).

    The shape is the chain of arcs sampled at 32 intervals per section. ``v`` and ``u`` are
    the strains of the arcs (v = (0, 0, L/L0), u = (-theta_y, theta_x, 0)/L0 in the body
    frame; rigid sections v = e3, u = 0). ``force`` and ``moment`` are NaN: the PCC model
    balances generalised forces and does not resolve the internal wrench along s.
    ``shooting_unknowns`` holds the PCC coordinates (L, theta_x, theta_y) per segment, so a
    solution warm-starts the next one through ``initial``.
    """
    model = pcc_model(design, tip_force=tip_force, tip_moment=tip_moment)
    guess = None if initial is None else [float(v) for v in initial.shooting_unknowns]
    try:
        out = model.statics(list(pressures), guess=guess, max_iter=max_iter)
    except ConvergenceError as exc:
        if check:
            raise
        return StaticSolution._failed(design, pressures, exc, model.ndof)
    x = out["x"]
    s, pos, rot = model.shape(x, N_PER_SECTION)
    v, u, section = _strains(design, model, x, len(s))
    return StaticSolution(
        design=design,
        pressures=np.array(pressures),
        s=s,
        section=section,
        position=pos,
        rotation=rot,
        force=np.full((len(s), 3), np.nan),
        moment=np.full((len(s), 3), np.nan),
        v=v,
        u=u,
        converged=True,
        iterations=out["iterations"],
        residual=out["residual"],
        load_steps=0,
        shooting_unknowns=np.array(x),
    )


def _strains(design, model, x, n):
    """Per-sample strains of the arcs and section index (sample k of section j is at
    j * N + k; the last sample is the tip)."""
    sections = design.spec["sections"]
    v = np.zeros((n, 3))
    u = np.zeros((n, 3))
    section = np.zeros(n, dtype=int)
    per = 2 if model.planar else 3
    plane = design.spec.get("pcc", {}).get("plane", 0.0)
    o = 0
    for j, sec in enumerate(sections):
        rows = slice(
            j * N_PER_SECTION, (j + 1) * N_PER_SECTION + (1 if j == len(sections) - 1 else 0)
        )
        section[rows] = j
        v[rows, 2] = 1.0
        if sec.get("rigid", False):
            continue
        length, l0 = x[o], sec["length"]
        if per == 2:
            tx, ty = x[o + 1] * np.cos(plane), x[o + 1] * np.sin(plane)
        else:
            tx, ty = x[o + 1], x[o + 2]
        v[rows, 2] = length / l0
        u[rows, 0] = -ty / l0
        u[rows, 1] = tx / l0
        o += per
    return v, u, section
