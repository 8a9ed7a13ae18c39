"""SystemSolution.jacobian(): the exact derivatives of a parallel continuum robot's
platform pose and of its rods' base wrenches with respect to every rod's pressures and
tensions and the platform's load (docs/control.md, "Jacobians of a system"). Every block is
checked against central differences of whole system solves; the core's tests add a one-rod
system against the lone rod's Jacobian (crates/softrod-core/tests/suite/system_sensitivity.rs)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from softrod import InputError, SolverOptions, load_system, solve_system
from system_cases import table_map, two_mapped_rods, walled

OPTS = SolverOptions(tol=1e-13)
P = [[20e3, 5e3, 3e3], [2e3, 15e3, 10e3]]  # inside the operating range by > 1 step
TENSION = [None, [0.4]]


def _vee(a: np.ndarray) -> np.ndarray:
    return 0.5 * np.array([a[2, 1] - a[1, 2], a[0, 2] - a[2, 0], a[1, 0] - a[0, 1]])


def _fd(solve, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Central differences of the platform pose (6,) and of every rod's base wrench
    (n, 6) for solve(+-1), the system solved with the input moved by +-h."""
    hi, lo = solve(+1), solve(-1)
    dp = (hi.platform_position - lo.platform_position) / (2 * h)
    r0 = 0.5 * (hi.platform_rotation + lo.platform_rotation)
    dth = _vee((hi.platform_rotation - lo.platform_rotation) / (2 * h) @ r0.T)
    base = np.array(
        [
            np.concatenate([a.base_force - b.base_force, a.base_moment - b.base_moment])
            for a, b in zip(hi.rods, lo.rods, strict=True)
        ]
    ) / (2 * h)
    return np.concatenate([dp, dth]), base


def _hybrid():
    """The bundled two-rod platform, its right actuator with a tendon in its cap and body
    (Paper 002's actuator as a hybrid pneumatic-tendon rod)."""
    system = load_system("two_spa_platform")
    route = [{"channel": 0, "distance": "6 mm", "angle": "60 deg"}]
    right = system.rods[1].design.replace(
        {"sections[0].tendons": route, "sections[1].tendons": route}
    )
    rods = (system.rods[0], dataclasses.replace(system.rods[1], design=right))
    return dataclasses.replace(system, rods=rods)


# Central differences of solves converged to 1e-13 (scaled residual): truncation
# O((h / scale)^2) with scales of 1e4 Pa, 1 N, 0.05 N m: below 1e-8 of a column at the
# steps below; round-off about 1e-13 * 0.1 m / h: 1e-14 m/Pa at h = 1 Pa against
# derivatives of ~1e-7 m/Pa (1e-7 relative). rtol 1e-5 leaves room for both; atol covers
# entries that vanish (1e-9 of the largest entry of the block).
STEPS = {"pressures": 1.0, "tensions": 1e-4, "platform_force": 1e-5, "platform_moment": 1e-7}


def _check_block(jac_pose, jac_base, fd_pose, fd_base):
    atol = 1e-9 * np.abs(jac_pose).max()
    np.testing.assert_allclose(jac_pose, fd_pose, rtol=1e-5, atol=atol)
    atol = 1e-9 * np.abs(jac_base).max()
    np.testing.assert_allclose(jac_base, fd_base, rtol=1e-5, atol=atol)


def test_system_jacobian_matches_central_differences_of_solves():
    system = _hybrid()
    sol = solve_system(system, P, tensions=TENSION, options=OPTS)
    jac = sol.jacobian()
    assert jac.pressures.shape == (6, 6) and jac.tensions.shape == (6, 1)
    assert jac.pressure_columns == (
        "rod0_p0",
        "rod0_p1",
        "rod0_p2",
        "rod1_p0",
        "rod1_p1",
        "rod1_p2",
    )
    assert jac.tension_columns == ("rod1_t0",)
    assert jac.base["pressures"].shape == (2, 6, 6)
    np.testing.assert_allclose(jac.position, sol.platform_position, atol=1e-12)
    for c in range(6):
        rod, k = divmod(c, 3)

        def solve(sign, rod=rod, k=k):
            p = [list(row) for row in P]
            p[rod][k] += sign * STEPS["pressures"]
            return solve_system(system, p, tensions=TENSION, initial=sol, options=OPTS)

        pose, base = _fd(solve, STEPS["pressures"])
        _check_block(jac.pressures[:, c], jac.base["pressures"][:, :, c], pose, base)

    def pull(sign):
        t = [None, [TENSION[1][0] + sign * STEPS["tensions"]]]
        return solve_system(system, P, tensions=t, initial=sol, options=OPTS)

    pose, base = _fd(pull, STEPS["tensions"])
    _check_block(jac.tensions[:, 0], jac.base["tensions"][:, :, 0], pose, base)
    load = np.asarray(system.platform.force, dtype=float)
    turn = np.asarray(system.platform.moment, dtype=float)
    for j in range(3):
        e = np.eye(3)[j]

        def push(sign, e=e):
            f = load + sign * STEPS["platform_force"] * e
            return solve_system(
                system, P, tensions=TENSION, platform_force=f, initial=sol, options=OPTS
            )

        def twist(sign, e=e):
            m = turn + sign * STEPS["platform_moment"] * e
            return solve_system(
                system, P, tensions=TENSION, platform_moment=m, initial=sol, options=OPTS
            )

        pose, base = _fd(push, STEPS["platform_force"])
        _check_block(jac.platform_force[:, j], jac.base["platform_force"][:, :, j], pose, base)
        pose, base = _fd(twist, STEPS["platform_moment"])
        _check_block(jac.platform_moment[:, j], jac.base["platform_moment"][:, :, j], pose, base)


def test_platform_load_balances_the_base_wrenches():
    """A force on the platform goes to the bases whole: the derivatives of the rods' base
    forces with respect to it sum to the identity (the rods' weights and the platform's do
    not change), to round-off."""
    sol = solve_system("two_spa_platform", P, options=OPTS)
    jac = sol.jacobian()
    np.testing.assert_allclose(
        jac.base["platform_force"][:, :3, :].sum(axis=0), np.eye(3), atol=1e-9
    )


def test_mapped_rods_include_the_maps_part():
    """Both rods stiffness-mapped by a PCHIP table: the pressures' blocks (with d sigma /
    d p) against central differences of mapped solves."""
    system = two_mapped_rods()
    smap = table_map()
    maps = [smap, smap]
    sol = solve_system(system, P, stiffness_maps=maps, options=OPTS)
    jac = sol.jacobian()
    assert all(s.shape == (6, 3) for s in jac.stiffness_scale)
    # Channels off the table's nodes (15 kPa is one: C1 there, not C2, so a central
    # difference across it is first order only).
    for c in (0, 5):
        rod, k = divmod(c, 3)

        def solve(sign, rod=rod, k=k):
            p = [list(row) for row in P]
            p[rod][k] += sign * STEPS["pressures"]
            return solve_system(system, p, stiffness_maps=maps, initial=sol, options=OPTS)

        pose, base = _fd(solve, STEPS["pressures"])
        _check_block(jac.pressures[:, c], jac.base["pressures"][:, :, c], pose, base)


def test_frictionless_obstacles_are_taken_and_refusals_name_the_field():
    system = walled(load_system("two_spa_platform"))
    sol = solve_system(system, [[40e3, 0.0, 0.0], [0.0, 0.0, 0.0]], options=OPTS)
    assert sol.rods[0].contact.max_penetration > 0  # the wall carries load
    jac = sol.jacobian()
    assert np.isfinite(jac.pressures).all()

    rough = dataclasses.replace(
        system,
        rods=(
            dataclasses.replace(
                system.rods[0], design=system.rods[0].design.replace({"obstacles[0].friction": 0.3})
            ),
            system.rods[1],
        ),
    )
    frictional = solve_system(rough, [[40e3, 0.0, 0.0], [0.0, 0.0, 0.0]])
    with pytest.raises(InputError) as info:
        frictional.jacobian()
    assert info.value.field == "rods[0].design.obstacles[0].friction"

    failed = dataclasses.replace(sol, converged=False, solved_with=None)
    with pytest.raises(InputError) as info:
        failed.jacobian()
    assert info.value.field == "solution"
    bare = dataclasses.replace(sol, solved_with=None)
    with pytest.raises(InputError) as info:
        bare.jacobian()
    assert info.value.field == "solution.solved_with"
