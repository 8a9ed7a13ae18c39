"""Chamber layouts of the PCC model through the public API, on the bundled six-chamber arm
(``stiff_flop_pcc``): three chamber pairs (two chambers on one channel) against six channels,
weightless statics against closed forms, and the six-fold symmetry.

Closed forms (derived in crates/softrod-core/tests/suite/pcc_chambers.rs and docs/pcc.md): with
F_k = p_k A_k at c_k = r (cos phi_k, sin phi_k) and the resultant b = sum F_k c_k,
- chamber model (virtual work p A delta l): L = L0 + sum F / k_L and theta = |b| / k_theta
  exactly, bending towards phi = angle(-b), away from the chambers;
- tip-force model (paper 003 eqs. 9-13): L = L0 + B(theta) sum F / k_L and
  k_theta theta = |b| + L N(theta) sum F, B = sin(theta)/theta,
  N = (theta - sin theta)/theta^2, same phi.
A pair at 0 and 60 deg acts like one chamber of area 2 A at 30 deg and radius r cos(30 deg),
so it bends the arm towards 210 deg.
"""

import numpy as np
import pytest
import softrod
from softrod.pcc import chamber_moment, run_pcc

# The bundled design's geometry and parameters, as written in designs/stiff_flop_pcc.toml.
AREA = np.pi * 4e-3**2  # chamber radius 4 mm
RC = 9e-3  # chamber centroid distance
ANGLES = np.radians(60.0 * np.arange(6))
L0, K_L, K_THETA = 0.11, 246.0, 0.06
PAIRS = [0, 0, 1, 1, 2, 2]  # chamber k on channel PAIRS[k]

# Newton stops when its last update is below 1e-11 of L0 (lengths) or of 1 rad, and
# converges quadratically: the equilibria are exact to round-off. 1e-10 is 10x that.
STATICS_TOL = 1e-10
# Two designs that are the same model: the core evaluates the same sums in the same order;
# 1e-13 of the scale allows only for a different summation order.
SAME_TOL = 1e-13
# Six-fold symmetry: the chamber angles k 60 deg are rounded (cos 60 deg is
# 0.5000000000000001), so turned patterns and equal pressures are symmetric to ~1e-16
# relative; Newton carries that to ~1e-14. 1e-12 rad stands for "exactly".
SYM_TOL = 1e-12
# Cosserat rod vs PCC, weightless: the same arc; the rod's RK4 error with the design's 16
# steps is ~1e-9 m at these bends, 1e-7 m as in tests/test_pcc.py.
ROD_TOL = 1e-7


def six(**changes):
    d = softrod.load_design("stiff_flop_pcc")
    return d.replace(changes) if changes else d


def paired(design):
    """The same arm with chambers 1+2, 3+4, 5+6 on channels 0, 1, 2."""
    return design.replace({f"sections[0].chambers[{k}].channel": c for k, c in enumerate(PAIRS)})


def weightless(**changes):
    return six(**{"mounting.gravity": "0 m/s^2", **changes})


def resultant(p6):
    """(b, sum F): b = sum p_k A c_k (N m, section frame) of six chamber pressures (Pa)."""
    f = np.asarray(p6, dtype=float) * AREA
    return np.array([f @ (RC * np.cos(ANGLES)), f @ (RC * np.sin(ANGLES))]), f.sum()


def lthetaphi(sol):
    length, tx, ty = sol.shooting_unknowns
    return length, np.hypot(tx, ty), np.arctan2(ty, tx)


def angle_gap(a, b):
    d = (a - b) % (2 * np.pi)
    return min(d, 2 * np.pi - d)


def b_n(theta):
    """B = sin(theta)/theta, N = (theta - sin theta)/theta^2 (no cancellation for theta > 0.1)."""
    return np.sin(theta) / theta, (theta - np.sin(theta)) / theta**2


@pytest.mark.parametrize("model", ["chamber", "tip_force"])
def test_pair_design_equals_six_channels_with_duplicated_pressures(model):
    d6 = six(**{"pcc.pressure_force": model})
    d3 = paired(d6)
    assert (d3.n_channels, d6.n_channels) == (3, 6)
    # tip_force: its follower forces act as a negative bending stiffness (~ L sum F / 6) that
    # exceeds this soft arm's k_theta above ~0.3 bar on a pair; stay below.
    level = 1e5 if model == "chamber" else 0.15e5
    for p in ([1.0, 0.0, 0.0], [1.0, 0.5, 0.0], [0.2, 0.7, 1.0]):
        p3 = level * np.array(p)
        a = softrod.solve_statics(d3, p3, model="pcc")
        b = softrod.solve_statics(d6, p3[PAIRS], model="pcc")
        assert np.abs(a.shooting_unknowns - b.shooting_unknowns).max() <= SAME_TOL
        assert np.abs(a.tip_position - b.tip_position).max() <= SAME_TOL * L0
        assert lthetaphi(a)[1] > 0.05  # it bends
    # Dynamics: 0.4 s of ramped, oscillating pressures from rest, gravity on.
    t = np.arange(401) * 1e-3
    ramp = (t / (t + 0.05))[:, None]
    p3 = level * ramp * np.array([1.0, 0.6, 0.3]) * (1 + 0.3 * np.sin(2 * np.pi * t))[:, None]
    a = run_pcc(d3, 1e-3, p3)
    b = run_pcc(d6, 1e-3, p3[:, PAIRS])
    assert np.abs(a["x"] - b["x"]).max() <= SAME_TOL
    assert np.abs(a["x_dot"] - b["x_dot"]).max() <= 10 * SAME_TOL  # rates: scale / 0.1 s
    assert np.abs(a["tip_position"] - b["tip_position"]).max() <= SAME_TOL * L0
    assert np.hypot(*a["x"][-1, 1:]) > 0.05


def test_pair_moment_and_bending_plane_closed_form():
    # One pair (chambers at 0 and 60 deg) at 1 bar: M = 2 p A r cos(30 deg), the arm bends
    # towards 210 deg (away from the pair's middle at 30 deg), L = L0 + 2 p A / k_L.
    d3 = paired(weightless())
    p = 1e5
    m = 2 * p * AREA * RC * np.cos(np.pi / 6)
    assert chamber_moment(d3, [p, 0, 0])[0] == pytest.approx(m, rel=1e-14)
    length, theta, phi = lthetaphi(softrod.solve_statics(d3, [p, 0, 0], model="pcc"))
    assert abs(length - L0 - 2 * p * AREA / K_L) <= STATICS_TOL * L0
    assert abs(theta - m / K_THETA) <= STATICS_TOL
    assert angle_gap(phi, np.radians(210)) <= STATICS_TOL
    # Each pair in turn: 120 deg further per channel.
    for ch in (1, 2):
        pp = np.zeros(3)
        pp[ch] = p
        _, th, ph = lthetaphi(softrod.solve_statics(d3, pp, model="pcc"))
        assert abs(th - theta) <= STATICS_TOL
        assert angle_gap(ph, np.radians(210 + 120 * ch)) <= STATICS_TOL


@pytest.mark.parametrize(
    "p6",
    [
        [1e5, 0, 0, 0, 0, 0],  # one chamber: M = p A r
        [1e5, 1e5, 0, 0, 0, 1e5],  # three adjacent (paper Sec. V-C): M = 2 p A r
        [1.5e5, 1.5e5, 0, 0, 0, 1.5e5],  # 130 deg of bending: still exact
        [3e4, 1e4, 5e4, 0, 2e4, 7e4],  # mixed
        [1e5] * 6,  # equal: pure elongation
    ],
)
def test_weightless_chamber_model_closed_form(p6):
    d = weightless()
    b, ftot = resultant(p6)
    length, theta, phi = lthetaphi(softrod.solve_statics(d, p6, model="pcc"))
    assert abs(length - L0 - ftot / K_L) <= STATICS_TOL * L0
    assert abs(theta - np.hypot(*b) / K_THETA) <= STATICS_TOL
    if np.hypot(*b) > 1e-9:
        assert angle_gap(phi, np.arctan2(-b[1], -b[0])) <= STATICS_TOL
    assert chamber_moment(d, p6)[0] == pytest.approx(np.hypot(*b), rel=1e-12, abs=1e-15)


@pytest.mark.parametrize(
    "p6", [[2e4, 0, 0, 0, 0, 0], [1e4, 1e4, 0, 0, 0, 0], [1e4, 0, 5e3, 0, 0, 3e3]]
)
def test_weightless_tip_force_model_closed_form(p6):
    # Root of k theta = M + (L0 + B sum F / k_L) N sum F by bisection; unique at these
    # pressures (sum F <= 1 N, so L sum F / 6 < k_theta / 3).
    d = weightless(**{"pcc.pressure_force": "tip_force"})
    b, ftot = resultant(p6)
    moment = np.hypot(*b)

    def g(th):
        bb, n = b_n(th)
        return K_THETA * th - moment - (L0 + bb * ftot / K_L) * n * ftot

    lo, hi = 1e-3, np.pi
    assert g(lo) < 0 < g(hi)
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if g(mid) > 0 else (mid, hi)
    want = 0.5 * (lo + hi)
    length, theta, phi = lthetaphi(softrod.solve_statics(d, p6, model="pcc"))
    assert abs(theta - want) <= STATICS_TOL
    assert abs(length - L0 - b_n(want)[0] * ftot / K_L) <= STATICS_TOL * L0
    assert angle_gap(phi, np.arctan2(-b[1], -b[0])) <= STATICS_TOL
    # theta = M / k_theta is only the first-order answer: the follower forces bend further.
    assert theta > 1.02 * moment / K_THETA


@pytest.mark.parametrize("model", ["chamber", "tip_force"])
def test_six_fold_symmetry(model):
    d = six(**{"pcc.pressure_force": model})  # upright, gravity along the axis
    for p in (2e4, 1e5):
        s = softrod.solve_statics(d, [p] * 6, model="pcc")
        assert lthetaphi(s)[1] <= SYM_TOL
        assert abs(s.tip_position[:2]).max() <= SYM_TOL * L0
    scale = 1.0 if model == "chamber" else 0.2
    base = scale * np.array([0.9e5, 0.4e5, 0.0, 0.1e5, 0.0, 0.3e5])
    l0, th0, ph0 = lthetaphi(softrod.solve_statics(d, base, model="pcc"))
    assert th0 > 0.05
    for j in range(1, 6):
        length, theta, phi = lthetaphi(softrod.solve_statics(d, np.roll(base, j), model="pcc"))
        assert abs(length - l0) <= SYM_TOL * L0
        assert abs(theta - th0) <= SYM_TOL
        assert angle_gap(phi, ph0 + np.radians(60 * j)) <= SYM_TOL


@pytest.mark.parametrize("p3", [[0.5e5, 0, 0], [0.6e5, 0.3e5, 0.1e5]])
def test_pair_design_rod_and_pcc_give_the_same_weightless_arc(p3):
    # Independent of the PCC code: the Cosserat rod's exact weightless solution under
    # chamber pressures is the same arc (docs/pcc.md), also when two chambers share a channel.
    d3 = paired(weightless())
    a = softrod.solve_statics(d3, p3, model="pcc")
    c = softrod.solve_statics(d3, p3)
    assert np.abs(a.tip_position - c.tip_position).max() < ROD_TOL
