"""StaticSolution.jacobian() where the base force is unknown too (six shooting unknowns): a
pinned or clamped tip (with the derivatives of the tip's reaction), a follower tip force, and
a finger pressed on a table. Every derivative is checked against central differences of whole
solves (docs/control.md, "Jacobians of a static solution")."""

from __future__ import annotations

import numpy as np
import pytest
from softrod import InputError, SolverOptions, TipConstraint, load_design, solve_statics

OPTS = SolverOptions(tol=1e-13)
SPA = "spa_three_chamber_130mm"
P = [30e3, 5e3, 45e3]
# Central differences of solves converged to 1e-13 (scaled residual): the truncation error is
# O(h^2) (below 1e-8 of a derivative at these steps) and the round-off about
# 1e-13 * scale / h. With h = 50 Pa and shapes of 0.1 m that is ~2e-16 m/Pa against
# derivatives of ~1e-7 m/Pa: rtol 1e-5 leaves room for both; atol covers entries that vanish.
H_P = 50.0


def _vee(a: np.ndarray) -> np.ndarray:
    """vee of the skew part of a 3x3 matrix."""
    return 0.5 * np.array([a[2, 1] - a[1, 2], a[0, 2] - a[2, 0], a[1, 0] - a[0, 1]])


def _node(sol, s: float) -> int:
    """Index of the solution node at arc length s (the tests probe at nodes)."""
    k = int(np.argmin(np.abs(sol.s - s)))
    assert abs(sol.s[k] - s) < 1e-12
    return k


def _pose_fd(solve, k: int, h: float) -> np.ndarray:
    """Central differences of node k's position and small rotation (6,), and of the tip's
    reaction wrench (6,), for a solve(+-1) of the perturbed problem."""
    hi, lo = solve(+1), solve(-1)
    dp = (hi.position[k] - lo.position[k]) / (2 * h)
    # dR R^T at the centre: (R_hi - R_lo) / 2h times the unperturbed R^T, whose skew part
    # is [dtheta]x to O(h^2).
    r0 = 0.5 * (hi.rotation[k] + lo.rotation[k])
    dth = _vee((hi.rotation[k] - lo.rotation[k]) / (2 * h) @ r0.T)
    df = (hi.tip_reaction_force - lo.tip_reaction_force) / (2 * h)
    dm = (hi.tip_reaction_moment - lo.tip_reaction_moment) / (2 * h)
    return np.concatenate([dp, dth]), np.concatenate([df, dm])


@pytest.fixture(scope="module")
def spa():
    return load_design(SPA)


def _held(spa, kind: str):
    """The SPA's free equilibrium at P, then its tip held 8 mm aside of it (pinned: the
    position; clamped: also the free tip's orientation), so the constraint carries load."""
    free = solve_statics(spa, P, options=OPTS)
    pos = free.tip_position + np.array([0.008, 0.0, 0.0])
    if kind == "pinned":
        return TipConstraint.pinned(pos)
    return TipConstraint.clamped(pos, free.tip_rotation)


@pytest.mark.parametrize("kind", ["pinned", "clamped"])
def test_held_tip_jacobian_matches_central_differences(spa, kind):
    held = _held(spa, kind)
    sol = solve_statics(spa, P, tip_constraint=held, options=OPTS)
    assert sol.tip_constraint == kind
    mid = 0.065  # m: a node of the body section (the tests probe at nodes)
    k = _node(sol, mid)
    jac = sol.jacobian(point=mid)
    tip = sol.jacobian()
    assert jac.reaction is not None and set(jac.reaction) == {
        "pressures",
        "tip_force",
        "tip_moment",
        "tensions",
    }
    for c in range(3):

        def solve(sign, c=c):
            p = list(P)
            p[c] += sign * H_P
            return solve_statics(spa, p, tip_constraint=held, options=OPTS)

        pose, wrench = _pose_fd(solve, k, H_P)
        np.testing.assert_allclose(jac.pressures[:, c], pose, rtol=1e-5, atol=1e-12)
        np.testing.assert_allclose(jac.reaction["pressures"][:, c], wrench, rtol=1e-5, atol=1e-9)
        # The held tip does not move: its position derivative vanishes (clamped: its
        # rotation too), to the round-off of the held residual.
        assert np.abs(tip.pressures[:3, c]).max() < 1e-12
        if kind == "clamped":
            assert np.abs(tip.pressures[3:, c]).max() < 1e-10
    # The reaction moved with the pressure: these are not zeros by construction.
    assert np.abs(jac.reaction["pressures"][:3]).max() > 1e-7  # N/Pa
    # Tip loads: the constraint takes a tip force whole (the shape does not move, the
    # reaction falls by it); a tip moment bends a pinned rod, a clamped one not at all.
    np.testing.assert_allclose(jac.tip_force, 0.0, atol=1e-12)
    np.testing.assert_allclose(jac.reaction["tip_force"][:3], -np.eye(3), atol=1e-9)
    hm = 1e-4  # N m
    for j in range(3):

        def solve_m(sign, j=j):
            m = np.zeros(3)
            m[j] = sign * hm
            return solve_statics(spa, P, tip_moment=m, tip_constraint=held, options=OPTS)

        pose, wrench = _pose_fd(solve_m, k, hm)
        np.testing.assert_allclose(jac.tip_moment[:, j], pose, rtol=1e-5, atol=1e-9)
        np.testing.assert_allclose(jac.reaction["tip_moment"][:, j], wrench, rtol=1e-5, atol=1e-7)
    if kind == "clamped":
        np.testing.assert_allclose(jac.tip_moment, 0.0, atol=1e-12)
    else:
        assert np.abs(jac.tip_moment[:3]).max() > 1e-3  # m per N m


def test_held_tip_parameter_derivatives_include_the_reaction(spa):
    held = _held(spa, "clamped")
    sol = solve_statics(spa, P, tip_constraint=held, options=OPTS)
    jac = sol.jacobian(params=["c_b[body]"])
    h = 1e-4  # of c_b = 1 (the body's bending correction factor, paper 002 eq. 19)

    def solve(sign):
        d = spa.replace({"sections[1].c_b": 1.0 + sign * h})
        return solve_statics(d, P, tip_constraint=held, options=OPTS)

    _, wrench = _pose_fd(solve, -1, h)
    np.testing.assert_allclose(jac.reaction["params"][:, 0], wrench, rtol=1e-5, atol=1e-12)
    np.testing.assert_allclose(jac.params[:, 0], 0.0, atol=1e-12)  # the clamped tip stays


def test_follower_tip_force_jacobian_matches_central_differences():
    d = load_design(SPA)
    d = d.replace({"tip": {"force": ["0.05 N", "0 N", "0 N"], "frame": "body"}})
    sol = solve_statics(d, P, options=OPTS)
    assert sol.shooting_unknowns.size == 6  # the base force is unknown too
    jac = sol.jacobian()
    assert jac.reaction is None
    k = len(sol.s) - 1
    for c in range(3):

        def solve(sign, c=c):
            p = list(P)
            p[c] += sign * H_P
            return solve_statics(d, p, options=OPTS)

        pose, _ = _pose_fd(solve, k, H_P)
        np.testing.assert_allclose(jac.pressures[:, c], pose, rtol=1e-5, atol=1e-12)
    hf = 1e-4  # N
    for j in range(3):

        def solve_f(sign, j=j):
            f = np.array([0.05, 0.0, 0.0])
            f[j] += sign * hf
            return solve_statics(d, P, tip_force=f, options=OPTS)

        pose, _ = _pose_fd(solve_f, k, hf)
        np.testing.assert_allclose(jac.tip_force[:, j], pose, rtol=1e-5, atol=1e-9)


def test_finger_on_the_table_jacobian_matches_central_differences():
    d = load_design("prebent_finger_on_table")
    p = [30e3]
    sol = solve_statics(d, p, options=OPTS)
    assert sol.contact is not None and sol.contact.max_penetration > 0  # it touches
    jac = sol.jacobian()
    k = len(sol.s) - 1

    def solve(sign):
        return solve_statics(d, [p[0] + sign * H_P], options=OPTS)

    pose, _ = _pose_fd(solve, k, H_P)
    np.testing.assert_allclose(jac.pressures[:, 0], pose, rtol=1e-5, atol=1e-12)
    assert np.abs(jac.pressures[:3, 0]).max() > 1e-8  # m/Pa: the tip still moves


def test_held_solution_without_its_pose_is_refused(spa):
    held = _held(spa, "pinned")
    sol = solve_statics(spa, P, tip_constraint=held, options=OPTS)
    import dataclasses

    bare = dataclasses.replace(sol, tip_hold=None)
    with pytest.raises(InputError) as exc:
        bare.jacobian()
    assert exc.value.field == "solution.tip_hold"
