"""softrod's statics against an independent reference: the same model solved by scipy's
solve_bvp (benchmarks/baseline_bvp.py: numpy right-hand side, collocation, no Rust solver).

Tolerance TIP_TOL = 1e-6 L (0.13 um on 130 mm), the accuracy target of the statics issue:
- softrod integrates with classical RK4 at the designs' 16 steps per section; its global error
  is O(h^4) and, measured against a 64x finer softrod solution, at most 7.8e-8 L for the 130 mm
  design at 70 kPa and 3.1e-7 L for the horizontal 134 mm design;
- solve_bvp at tol = 1e-6 (relative collocation residual, 4th-order Lobatto IIIA) on 20 initial
  nodes per section is within 5e-9 L of that fine solution in every case below;
so the two must agree to about 3.2e-7 L, a factor of three inside TIP_TOL. A modelling
difference is four or more orders larger: dropping the tip body's centre-of-mass offset moves
the 134 mm tip by 6e-3 L. Tip rotations: same budget (measured at most 3.3e-7), ROT_TOL = 1e-6.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import softrod

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import baseline_bvp  # noqa: E402

pytestmark = pytest.mark.fast

TIP_TOL = 1e-6  # fraction of the length
ROT_TOL = 1e-6  # max entry of R_softrod - R_bvp
BVP_TOL = 1e-6
BVP_NODES = 20

CASES = [
    ("spa_three_chamber_130mm", (0.0, 0.0, 0.0)),
    ("spa_three_chamber_130mm", (70e3, 0.0, 0.0)),
    ("spa_three_chamber_130mm", (70e3, 70e3, 0.0)),
    ("spa_three_chamber_130mm", (20e3, 45e3, 70e3)),
    ("spa_three_chamber_130mm", (35e3, 0.0, 10e3)),
    # horizontal mounting, 17.25 g tip body with a centre-of-mass offset
    ("spa_three_chamber_134mm_horizontal", (30e3, 10e3, 50e3)),
]


@pytest.fixture(scope="module")
def designs():
    return {name: softrod.load_design(name) for name in {c[0] for c in CASES}}


@pytest.mark.parametrize(("name", "pressures"), CASES, ids=[f"{n}-{p}" for n, p in CASES])
def test_tip_matches_solve_bvp(designs, name, pressures):
    design = designs[name]
    sol = softrod.solve_statics(design, pressures)
    ref = baseline_bvp.solve_bvp_full(design, pressures, nodes=BVP_NODES, tol=BVP_TOL)
    assert ref.success, ref.message
    err = np.linalg.norm(sol.tip_position - ref.tip_position) / design.length
    assert err <= TIP_TOL, f"tip differs by {err:.2e} L (tolerance {TIP_TOL:.0e} L)"
    rot_err = np.abs(sol.tip_rotation - ref.tip_rotation).max()
    assert rot_err <= ROT_TOL, f"tip rotation differs by {rot_err:.2e}"


def test_reference_sees_the_com_offset(designs):
    """The reference is not blind to the tip body's moment: without the centre-of-mass
    offset its tip moves by far more than TIP_TOL."""
    design = designs["spa_three_chamber_134mm_horizontal"]
    plain = design.replace({"tip.com_offset": ["0 mm", "0 mm", "0 mm"]})
    p = (30e3, 10e3, 50e3)
    a = baseline_bvp.solve_bvp_tip(design, p, nodes=BVP_NODES, tol=BVP_TOL)[0]
    b = baseline_bvp.solve_bvp_tip(plain, p, nodes=BVP_NODES, tol=BVP_TOL)[0]
    assert np.linalg.norm(a - b) / design.length > 1e3 * TIP_TOL
