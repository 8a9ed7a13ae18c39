"""Issue 17 part A from the design file to the answer: reference shapes (precurvature,
pre-strain), tendons, follower loads and tapered sections. Closed forms, batch = single,
input rules and property tests on the new keys (docs/scope.md)."""

import math

import numpy as np
import pytest
import softrod
from hypothesis import given, settings
from hypothesis import strategies as st
from softrod import (
    DesignError,
    InputError,
    SolverOptions,
    load_design,
    solve_statics,
    solve_statics_batch,
)

pytestmark = pytest.mark.fast  # the whole module runs in seconds

L = 0.1  # m
EA = 100.0  # N
EI = 0.01  # N m^2
GJ = 0.008  # N m^2
FINGER = "prebent_tendon_finger"


def rod(**section) -> dict:
    """A uniform upright rod (d3 = +z) with direct stiffnesses and no gravity."""
    sec = {
        "name": "rod",
        "length": f"{L * 1e3} mm",
        "mass": "10 g",
        "outer_radius": "10 mm",
        "EA": f"{EA} N",
        "GA": "50 N",
        "EI": f"{EI} N*m^2",
        "GJ": f"{GJ} N*m^2",
    }
    sec.update(section)
    return {
        "design": {"name": "scope_rod", "citation": "closed-form check"},
        "mounting": {"orientation": "upright", "gravity": "0 m/s^2"},
        "sections": [sec],
    }


def _arc_tip(k: float, length: float = L) -> np.ndarray:
    """Tip of an arc of curvature k about +y from the origin along +z (bending towards +x)."""
    return np.array([(1 - math.cos(k * length)) / k, 0.0, math.sin(k * length) / k])


def test_unloaded_precurved_rod_keeps_its_arc_at_fourth_order():
    k = 10.0  # 1/m: a 1 rad arc over L
    errors = []
    for steps in (8, 16):
        sol = solve_statics(load_design(rod(curvature=[0, f"{k} 1/m", 0], steps=steps)), [])
        # No load: no internal force or moment (round-off of the Newton tolerance).
        assert np.abs(sol.force).max() < 1e-12 and np.abs(sol.moment).max() < 1e-12
        np.testing.assert_allclose(sol.u, np.tile([0.0, k, 0.0], (len(sol.s), 1)), atol=1e-12)
        errors.append(np.abs(sol.tip_position - _arc_tip(k)).max())
    # RK4 on the rotation: global error C L (k h)^4; the arc's rotations are exact up to it.
    # C = 0.02 as for the pure-bending arc of test_statics_api (same equations): 8 steps of
    # 1/8 rad give 5e-7 m; halving h divides the error by about 16 (fourth order).
    assert errors[0] < 0.02 * L * (k * L / 8) ** 4
    assert 10 < errors[0] / errors[1] < 22


def test_bend_radius_equals_curvature_and_its_direction():
    radius, phi = 0.125, math.radians(30)
    a = load_design(rod(bend_radius=f"{radius * 1e3} mm", bend_direction="30 deg"))
    k = [-math.sin(phi) / radius, math.cos(phi) / radius, 0.0]
    b = load_design(rod(curvature=[f"{x} 1/m" for x in k]))
    sa, sb = solve_statics(a, []), solve_statics(b, [])
    np.testing.assert_array_equal(sa.position, sb.position)
    # The tip lies in the bending plane (cos phi, sin phi, *) on the arc of that radius.
    tip = sa.tip_position
    in_plane = _arc_tip(1 / radius)
    expected = np.array([in_plane[0] * math.cos(phi), in_plane[0] * math.sin(phi), in_plane[2]])
    np.testing.assert_allclose(tip, expected, atol=0.02 * L * (L / radius / 16) ** 4)


def test_precurved_and_twisted_rod_is_a_helix():
    kappa, tau = 20.0, 10.0  # 1/m
    sol = solve_statics(load_design(rod(curvature=[0, f"{kappa} 1/m", f"{tau} 1/m"], steps=32)), [])
    w = np.array([0.0, kappa, tau])  # the Darboux vector: constant, and R(0) = I
    norm2 = w @ w
    axis = w / math.sqrt(norm2)
    centre = np.cross(w, [0.0, 0.0, 1.0]) / norm2  # a point of the screw axis
    rel = sol.position - centre
    dist = np.linalg.norm(rel - np.outer(rel @ axis, axis), axis=1)
    # Helix radius kappa / (kappa^2 + tau^2), rise tau / |w| per unit length, both exact up to
    # RK4's error C L (|w| h)^4 (|w| h = 0.07 rad: 5e-8 m with C = 0.02).
    tol = 0.02 * L * (math.sqrt(norm2) * L / 32) ** 4
    np.testing.assert_allclose(dist, kappa / norm2, atol=tol)
    np.testing.assert_allclose(rel @ axis - rel[0] @ axis, sol.s * tau / math.sqrt(norm2), atol=tol)


def test_tendon_gives_the_constant_curvature_arc():
    d, t = 4e-3, 2.0  # m, N
    tendon = {"channel": 0, "distance": f"{d * 1e3} mm", "angle": "0 deg"}
    design = load_design(rod(tendons=[tendon]))
    assert design.n_tendons == 1
    sol = solve_statics(design, [], tensions=[f"{t} N"])
    # Rucker-Webster, straight tendon at (d, 0): the tension's moment T d bends the rod
    # towards the tendon (u2 = T d / EI) and its force compresses it (v3 = 1 - T / EA),
    # uniform along s. Exact up to the Newton tolerance of the tendon law (1e-13 on strains).
    n = len(sol.s)
    u_exact = np.tile([0.0, t * d / EI, 0.0], (n, 1))
    np.testing.assert_allclose(sol.u, u_exact, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(sol.v, np.tile([0.0, 0.0, 1 - t / EA], (n, 1)), rtol=0, atol=1e-10)
    # The tip: an arc of curvature u2 / v3 per deformed length over v3 L.
    k, stretch = t * d / EI, 1 - t / EA
    np.testing.assert_allclose(
        sol.tip_position, _arc_tip(k / stretch, stretch * L), atol=0.02 * L * (k * L / 16) ** 4
    )
    # Total-force formulation: no external load, so the total internal wrench is zero.
    assert np.abs(sol.force).max() < 1e-9 and np.abs(sol.moment).max() < 1e-9
    np.testing.assert_array_equal(sol.tensions, [t])


def test_slack_tendon_is_the_plain_rod():
    with_tendon = load_design(rod(tendons=[{"channel": 0, "distance": "4 mm"}], chambers=[]))
    plain = load_design(rod())
    a = solve_statics(with_tendon, [], tensions=[0.0])
    b = solve_statics(with_tendon, [])
    c = solve_statics(plain, [])
    np.testing.assert_array_equal(a.position, c.position)
    np.testing.assert_array_equal(b.position, c.position)


def test_follower_tip_moment_rolls_the_rod_into_a_circle():
    design = rod(steps=32)
    design["tip"] = {"moment": [0, f"{2 * math.pi * EI / L} N*m", 0], "frame": "body"}
    sol = solve_statics(load_design(design), [])
    # A body-frame moment 2 pi EI / L keeps u2 = 2 pi / L: the tip comes back to the base,
    # up to RK4's error C L (angle / steps)^4 with C = 0.02 as for the arcs above (1.2e-6 m).
    assert np.abs(sol.tip_position).max() < 0.02 * L * (2 * math.pi / 32) ** 4
    assert sol.stable is None  # follower loads are not conservative: not assessed
    assert sol.shooting_unknowns.shape == (6,)


def test_follower_tip_force_differs_from_the_dead_one():
    base = rod(steps=16)
    base["tip"] = {"force": ["0.5 N", 0, 0]}
    dead = solve_statics(load_design(base), [])
    base["tip"]["frame"] = "body"
    follower = solve_statics(load_design(base), [])
    # A follower force turns with the tip (here towards -z as the rod bends), a dead one does
    # not: same start, different answers; both balance the base wrench.
    assert np.linalg.norm(dead.tip_position - follower.tip_position) > 1e-4
    np.testing.assert_allclose(dead.base_force, [0.5, 0, 0], atol=1e-12)
    d3 = follower.tip_rotation @ [0.5, 0.0, 0.0]
    np.testing.assert_allclose(follower.base_force, d3, atol=1e-9)


def test_tapered_section_keeps_the_geometry_rules():
    design = rod(outer_radius_end="5 mm")
    design["sections"][0].pop("EI")
    design["sections"][0].pop("EA")
    design["sections"][0].pop("GA")
    design["sections"][0].pop("GJ")
    design["sections"][0]["material"] = "dragon_skin_20"
    design["sections"][0].pop("mass")
    design["mounting"]["gravity"] = "9.81 m/s^2"
    design["mounting"]["orientation"] = "horizontal"
    sol = solve_statics(load_design(design), [])
    assert sol.converged and sol.tip_position[2] < 0
    design["sections"][0]["outer_radius_end"] = "-1 mm"
    with pytest.raises(DesignError, match="outer_radius_end"):
        load_design(design)


CHAMBER = {"radius": "1 mm", "distance": "3 mm", "angle": "0 deg", "channel": 0}


def _tapered_arm() -> dict:
    """Dragon Skin rod tapering from 10 to 5 mm, horizontal under gravity, damped."""
    design = rod(outer_radius_end="5 mm", steps=6, chambers=[CHAMBER])
    for key in ("EI", "EA", "GA", "GJ", "mass"):
        design["sections"][0].pop(key)
    design["sections"][0]["material"] = "dragon_skin_20"
    design["mounting"]["gravity"] = "9.81 m/s^2"
    design["mounting"]["orientation"] = "horizontal"
    design["dynamics"] = {"damping_time": "0.01 s"}
    return design


def test_dynamics_carries_a_tapered_section():
    # Released straight, the damped tapered rod sags and settles on its static shape (the
    # dynamics evaluates stiffness, mass and inertia at every stage point's radius), which
    # differs from the uniform rod's by millimetres.
    design = load_design(_tapered_arm())
    traj = softrod.simulate(
        design, softrod.PressureSchedule.constant([0.0]), 1.5, dt=5e-3, initial="straight"
    )
    assert np.all(np.isfinite(traj.tip_position))
    st_ = solve_statics(design, [0.0], options=SolverOptions(tol=1e-12))
    # tau = 10 ms and the slowest mode is well damped: after 1.5 s only round-off of the
    # solvers and the two discretisations' O(h^4) difference are left (1e-5 L).
    assert np.linalg.norm(traj.tip_position[-1] - st_.tip_position) < 1e-5 * L
    assert st_.tip_position[2] < -1e-3  # it sags
    uniform = _tapered_arm()
    uniform["sections"][0].pop("outer_radius_end")
    su = solve_statics(load_design(uniform), [0.0])
    assert np.linalg.norm(su.tip_position - st_.tip_position) > 1e-3
    # Undamped, the midpoint rule keeps the energy balance.
    undamped = _tapered_arm()
    undamped["dynamics"] = {"damping_time": "0 s"}
    tr = softrod.simulate(
        load_design(undamped),
        softrod.PressureSchedule.constant([0.0]),
        0.2,
        dt=1e-3,
        initial="straight",
        scheme="midpoint",
    )
    # The swing under gravity trades potential for kinetic energy; the books (at every stage
    # point's mass and stiffness) balance to well within 1 % of it.
    moved = np.max(tr.kinetic)
    assert moved > 0 and np.max(np.abs(tr.energy_balance)) < 1e-2 * moved


def test_dynamics_carries_a_tabulated_reference_shape():
    table = {
        "s": ["0 mm", "50 mm", "100 mm"],
        "curvature": [[0, "5 1/m", 0], [0, "10 1/m", 0], [0, "5 1/m", 0]],
    }
    design = rod(reference_table=table, steps=8, chambers=[CHAMBER])
    design["dynamics"] = {"damping_time": "0.01 s"}
    d = load_design(design)
    # At rest in its tabulated arc, then 20 kPa: the damped rod swings and settles on the
    # static shape under the pressure: the two discretisations' O(h^4) difference is left
    # (8 steps: 1.2e-6 L measured; 1e-5 L). (A 'straight' start is refused: with a
    # reference shape zero internal force is not straight.)
    traj = softrod.simulate(
        d, softrod.PressureSchedule.steps([0.0, 5e-3], [[0.0], [20e3]]), 0.6, dt=5e-3
    )
    st_ = solve_statics(d, [20e3])
    # The pressure moves the tip by 0.12 mm, over 100 times the tolerance below.
    assert np.linalg.norm(traj.tip_position[-1] - traj.tip_position[0]) > 100 * 1e-5 * L
    with pytest.raises(softrod.InputError) as exc:
        softrod.simulate(d, [0.0], 0.01, dt=5e-3, initial="straight")
    assert exc.value.field == "initial"
    np.testing.assert_allclose(traj.tip_position[-1], st_.tip_position, atol=1e-5 * L)


def test_bundled_finger_runs_end_to_end():
    d = load_design(FINGER)
    assert d.n_channels == 1 and d.n_tendons == 1
    rest = solve_statics(d, [0.0])
    pulled = solve_statics(d, [0.0], tensions=["1 N"])
    opened = solve_statics(d, ["30 kPa"])
    # The tendon curls the finger further; pressure lengthens the chamber's side and opens it.
    assert pulled.tip_position[0] > rest.tip_position[0] > opened.tip_position[0]
    assert pulled.stable and rest.stable and opened.stable


def test_batch_equals_single_with_tensions():
    d = load_design(FINGER)
    p = np.array([[0.0], [10e3], [20e3], [0.0]])
    t = np.array([[0.0], [0.5], [1.0], [2.0]])
    batch = solve_statics_batch(d, p, tensions=t)
    assert batch.converged.all() and batch.stability_assessed.all()
    np.testing.assert_array_equal(batch.tensions, t)
    for row in range(len(p)):
        single = solve_statics(d, p[row], tensions=t[row])
        np.testing.assert_array_equal(batch.tip_position[row], single.tip_position)
        np.testing.assert_array_equal(batch.x[row], single.shooting_unknowns)


def test_batch_with_follower_loads_reports_stability_not_assessed():
    design = rod(chambers=[{"radius": "2 mm", "distance": "4 mm", "angle": "0 deg", "channel": 0}])
    design["tip"] = {"force": ["0.02 N", 0, 0], "frame": "body"}
    batch = solve_statics_batch(load_design(design), [[0.0], [10e3]])
    assert batch.converged.all()
    assert not batch.stability_assessed.any()
    assert batch.x.shape == (2, 6)


@pytest.mark.parametrize(
    "tensions, field, rule",
    [
        ([-1.0], r"tensions\[0\]", ">= 0"),
        ([float("nan")], r"tensions", "finite|>= 0"),
        ([1.0, 2.0], "tensions", "1 tendon channel"),
        (["1 kPa"], r"tensions\[0\]", "force"),
    ],
)
def test_bad_tensions_are_refused(tensions, field, rule):
    d = load_design(FINGER)
    with pytest.raises(InputError, match=field) as err:
        solve_statics(d, [0.0], tensions=tensions)
    assert re_search(rule, str(err.value))


def re_search(pattern: str, text: str) -> bool:
    import re

    return re.search(pattern, text) is not None


def test_batch_tension_rules():
    d = load_design(FINGER)
    with pytest.raises(InputError, match=r"tensions\[1, 0\].*>= 0"):
        solve_statics_batch(d, np.zeros((2, 1)), tensions=[[0.0], [-0.1]])
    with pytest.raises(InputError, match=r"shape"):
        solve_statics_batch(d, np.zeros((2, 1)), tensions=np.zeros((3, 1)))
    with pytest.raises(InputError, match="no tendons"):
        solve_statics_batch(load_design(rod()), np.zeros((1, 0)), tensions=np.zeros((1, 1)))


@pytest.mark.parametrize(
    "change, field",
    [
        ({"bend_radius": "0 mm"}, "bend_radius"),
        ({"bend_radius": "10 mm", "curvature": [0, 0, 0]}, "bend_radius|curvature"),
        ({"bend_direction": "10 deg"}, "bend_direction"),
        ({"curvature": ["1 mm", 0, 0]}, r"curvature\[0\]"),
        ({"curvature": [1, 2]}, "curvature"),
        ({"v_star": [0, 0]}, "v_star"),
        ({"tendons": [{"channel": 0}]}, "distance"),
        ({"tendons": [{"channel": 1, "distance": "1 mm"}]}, r"tendons\[0\]\.channel"),
        ({"tendons": [{"channel": 0, "distance": "1 mm", "pitch": 3}]}, "pitch"),
        ({"reference_table": {"s": ["0 mm"], "curvature": [[0, 0, 0]]}}, "reference_table.s"),
    ],
)
def test_bad_keys_name_the_field(change, field):
    with pytest.raises(DesignError, match=field):
        load_design(rod(**change))


def test_bad_frame_names_the_field():
    design = rod()
    design["tip"] = {"frame": "sideways"}
    with pytest.raises(DesignError, match=r"tip\.frame"):
        load_design(design)


def test_reference_table_round_trips_through_save(tmp_path):
    table = {
        "s": ["0 mm", "50 mm", "100 mm"],
        "curvature": [[0, "5 1/m", 0], [0, "10 1/m", 0], [0, "5 1/m", 0]],
    }
    d = load_design(rod(reference_table=table))
    path = d.save(tmp_path / "tabled.toml")
    again = load_design(path)
    assert again.spec == d.spec
    a, b = solve_statics(d, []), solve_statics(again, [])
    np.testing.assert_array_equal(a.position, b.position)
    # The spline passes through the table: u2 at s = 50 mm is 10 1/m (no load: u = u*).
    mid = int(np.argmin(np.abs(a.s - 0.05)))
    assert abs(a.s[mid] - 0.05) < 1e-12
    np.testing.assert_allclose(a.u[mid], [0, 10, 0], atol=1e-12)


def test_dynamics_carries_the_finger_and_pcc_refuses_it():
    d = load_design(FINGER)
    # The finger's constant precurvature and its tendon are carried by the dynamics
    # (tests/test_dynamics_tendons.py); the PCC model refuses them.
    traj = softrod.simulate(d, softrod.PressureSchedule.constant([0.0]), 0.01, tensions=[0.5])
    assert np.all(np.isfinite(traj.tip_position))
    with pytest.raises((InputError, DesignError), match="PCC model"):
        solve_statics(d, [0.0], model="pcc")


@settings(max_examples=15, deadline=None)
@given(
    radius=st.floats(0.05, 2.0),
    direction=st.floats(-180.0, 180.0),
)
def test_any_bend_radius_gives_its_unloaded_arc(radius, direction):
    d = load_design(rod(bend_radius=f"{radius} m", bend_direction=f"{direction} deg"))
    sol = solve_statics(d, [])
    phi = math.radians(direction)
    expected_u = [-math.sin(phi) / radius, math.cos(phi) / radius, 0.0]
    np.testing.assert_allclose(sol.u, np.tile(expected_u, (len(sol.s), 1)), atol=1e-9 / radius)
    # Chord of the arc: 2 R sin(L / 2R), up to RK4's error (see the arc test).
    chord = np.linalg.norm(sol.tip_position - sol.position[0])
    tol = 0.02 * L * (L / radius / 16) ** 4 + 1e-14
    assert abs(chord - 2 * radius * math.sin(L / (2 * radius))) < tol


@settings(max_examples=15, deadline=None)
@given(tension=st.floats(0.0, 3.0), angle=st.floats(0.0, 360.0))
def test_any_straight_tendon_bends_towards_itself(tension, angle):
    d = load_design(rod(tendons=[{"channel": 0, "distance": "3 mm", "angle": f"{angle} deg"}]))
    sol = solve_statics(d, [], tensions=[tension], options=SolverOptions(tol=1e-12))
    a = math.radians(angle)
    # The tip load -T d3 at the offset (x, y) = d (cos a, sin a) has the moment
    # T (-y, x, 0): u = (T d / EI) (-sin a, cos a, 0) bends the rod towards the tendon.
    k = tension * 3e-3 / EI
    expected = np.tile([-k * math.sin(a), k * math.cos(a), 0.0], (len(sol.s), 1))
    np.testing.assert_allclose(sol.u, expected, rtol=0, atol=1e-9 * max(k, 1.0))


def test_cli_solve_takes_tensions(run):
    import json

    from conftest import assert_clean_error

    result = run("solve", FINGER, "--pressure", "30kPa", "--tension", "2N", "--json")
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["tensions_N"] == [2.0] and data["stable"] is True
    api = solve_statics(FINGER, [30e3], tensions=[2.0])
    # Same inputs and deterministic solve; JSON floats round-trip exactly.
    np.testing.assert_array_equal(data["tip_position_m"], api.tip_position)
    assert_clean_error(run("solve", FINGER, "--tension", "-1N"), 2, "--tension[0]", ">= 0")
    assert_clean_error(run("solve", FINGER, "--tension", "1N,2N"), 2, "--tension", "1 tendon")
    assert_clean_error(
        run("solve", "spa_three_chamber_130mm", "--tension", "1N"), 2, "0 tendon channels"
    )


def test_jacobian_is_taken_at_the_solved_tensions():
    d = load_design(FINGER)
    opts = SolverOptions(tol=1e-13)
    sol = solve_statics(d, [20e3], tensions=[1.5], options=opts)
    jac = sol.jacobian()
    h = 50.0  # Pa: central differences, truncation O(h^2) ~ 1e-12 of the derivative
    hi = solve_statics(d, [20e3 + h], tensions=[1.5], options=opts).tip_position
    lo = solve_statics(d, [20e3 - h], tensions=[1.5], options=opts).tip_position
    fd = (hi - lo) / (2 * h)
    # Tolerance: the solves' 1e-13 residual over 2h gives ~1e-13 * 0.1 m / 100 Pa.
    np.testing.assert_allclose(jac.pressures[:3, 0], fd, rtol=1e-5, atol=1e-12)
    # At zero tension the derivative differs: the tensions were not dropped.
    slack = solve_statics(d, [20e3], options=opts).jacobian()
    assert np.abs(slack.pressures[:3, 0] - jac.pressures[:3, 0]).max() > 1e-3 * np.abs(fd).max()


def test_follower_force_cantilever_against_the_elastica():
    """A tip force that follows the body (F along the tip's d1) on a nearly inextensible,
    unshearable cantilever against the planar elastica solved independently by scipy's
    collocation BVP solver: n = F R(L) e1 is constant along the rod, so
    EI theta'' = -(cos(theta) n_x - sin(theta) n_z), theta(0) = 0, theta'(L) = 0, with the
    tip angle theta(L) an unknown parameter (it sets the force's direction)."""
    from scipy.integrate import solve_bvp

    force = 2.0  # N: F L^2 / EI = 2, a large deflection
    design = rod(steps=64, EA="1e7 N", GA="1e7 N")
    design["tip"] = {"force": [f"{force} N", 0, 0], "frame": "body"}
    sol = solve_statics(load_design(design), [], options=SolverOptions(tol=1e-12))

    def rhs(s, y, p):
        theta, dtheta = y[0], y[1]
        nx, nz = force * math.cos(p[0]), -force * math.sin(p[0])
        return np.vstack(
            [dtheta, -(np.cos(theta) * nx - np.sin(theta) * nz) / EI, np.sin(theta), np.cos(theta)]
        )

    def bc(y0, y1, p):
        return np.array([y0[0], y1[1], y0[2], y0[3], y1[0] - p[0]])

    s = np.linspace(0, L, 201)
    guess = np.vstack([s / L, np.ones_like(s), 0.5 * s, s])
    ref = solve_bvp(rhs, bc, s, guess, p=[1.0], tol=1e-10, max_nodes=100_000)
    assert ref.success
    tip_ref = np.array([ref.sol(L)[2], 0.0, ref.sol(L)[3]])
    # Differences: extension and shear F / EA ~ 2e-7 of the length, RK4's error
    # C L (theta h)^4 ~ 1e-11 m, the BVP's tolerance 1e-10: 1e-7 m is 1e-6 of L.
    np.testing.assert_allclose(sol.tip_position, tip_ref, rtol=0, atol=1e-7)
    assert abs(math.atan2(sol.tip_rotation[0, 2], sol.tip_rotation[2, 2]) - ref.p[0]) < 1e-6


@pytest.mark.parametrize(
    "law",
    [None, {"axial": "ogden", "alpha": 8.89, "stretch_bending": True}],
    ids=["linear", "ogden-stretch-bending"],
)
def test_precurved_rod_in_dynamics_settles_on_its_statics(law):
    """Every law acts on the strains relative to the reference, in the dynamics as in the
    statics (docs/dynamics.md): an Ogden body with stretch-dependent bending too."""
    chamber = {"radius": "2 mm", "distance": "4 mm", "angle": "90 deg", "channel": 0}
    design = rod(curvature=[0, "10 1/m", 0], chambers=[chamber], **({"law": law} if law else {}))
    design["mounting"]["gravity"] = "9.81 m/s^2"
    design["dynamics"] = {"damping_time": "20 ms"}
    d = load_design(design)
    p = 20e3
    traj = softrod.simulate(d, softrod.PressureSchedule.constant([p]), 1.0, dt=5e-3)
    static = solve_statics(d, [p])
    # Starting at rest under p it stays there (the run starts from its own statics): the tip
    # stays on the shooting statics up to the two discretisations' O(h^4) difference,
    # 1e-6 of the length (crates/softrod-core/tests/suite/dynamics_scope.rs checks the moving
    # case to 1e-9 L against the collocation statics).
    assert np.abs(traj.tip_position - static.tip_position).max() < 1e-6 * L
    # and that statics is the precurved one, not the straight rod's.
    straight = solve_statics(load_design(rod(chambers=[chamber])), [p])
    assert np.linalg.norm(static.tip_position - straight.tip_position) > 1e-3


def test_linearisation_carries_a_tapered_section():
    """The tapered arm lightly damped (tau = 1 ms), loaded at t = 0 by a 1 mN tip force:
    the first bending mode's frequency from the linearisation (inertia and damping taken
    at every quadrature point's radius) against a fit of the simulated ring-down (dt = 1 ms,
    after 0.2 s). The two discretisations differ by the time step (BDF-alpha's period error
    ~(w dt)^2 < 1e-3 here) and in space by O(h^4) on the same 6 steps; 1 % bounds both with
    the fit's noise, while the uniform rod's frequency differs by far more (checked)."""
    from conftest import ring_down_frequency

    design = _tapered_arm()
    design["dynamics"] = {"damping_time": "1 ms"}
    d = load_design(design)
    force = [0.0, 1e-3, 0.0]
    sim = softrod.Simulation(d, [0.0], dt=1e-3, alpha=-0.2)
    sim.set_tip_loads(force, [0, 0, 0])
    traj = sim.run([0.0], 1.5)
    f_sim, _ = ring_down_frequency(traj, 0.2, axis=1)
    modes = softrod.linearise(d, [0.0], tip_force=force, nodes=6).modes(2)
    f_lin = modes.damped_frequency[0]
    assert abs(f_lin / f_sim - 1) < 1e-2, (f_lin, f_sim)
    uniform = _tapered_arm()
    uniform["sections"][0].pop("outer_radius_end")
    uniform["dynamics"] = design["dynamics"]
    f_uniform = softrod.linearise(load_design(uniform), [0.0], nodes=6).modes(1)
    assert abs(f_uniform.damped_frequency[0] / f_lin - 1) > 0.1


def test_linearisation_carries_tendons():
    """Till's robot with one tendon pulled: the static response K^-1 B of the tension columns
    is the Jacobian of the equilibrium (both exact: agreement to the solves' tolerance), and
    the first bending frequency matches the simulated ring-down of the undamped robot after
    a 5 mN tip force at t = 0 (dt = 1 ms: BDF-alpha's period error (w dt)^2 ~ 1e-3; 0.5 %)."""
    from conftest import ring_down_frequency

    till = load_design("till_tendon_robot")
    t = [6.0, 0.0, 0.0, 0.0]
    sys_ = softrod.linearise(till, [], tensions=t, nodes=8)
    assert sys_.input_names[-4:] == ("t0", "t1", "t2", "t3")
    response = np.linalg.solve(sys_.stiffness, sys_.input)[sys_.tip_rows]
    jac = solve_statics(till, [], tensions=t).jacobian()
    assert np.allclose(response[:, -4:], jac.tensions, rtol=1e-7, atol=1e-12)
    force = [0.0, 5e-3, 0.0]
    sim = softrod.Simulation(till, dt=1e-3, alpha=-0.2, tensions=t)
    sim.set_tip_loads(force, [0, 0, 0])
    traj = sim.run(None, 1.5)
    f_sim, _ = ring_down_frequency(traj, 0.1, axis=1)
    modes = softrod.linearise(till, [], tensions=t, tip_force=force, nodes=8).modes(4)
    # The first two modes bend in the two planes (the pulled tendon's prestress makes them
    # differ slightly); the y force excites the sideways one.
    f_lin = min(modes.damped_frequency[:2], key=lambda f: abs(f / f_sim - 1))
    assert abs(f_lin / f_sim - 1) < 5e-3, (f_lin, f_sim, modes.damped_frequency)
    with pytest.raises(InputError, match="tensions"):
        softrod.linearise(solve_statics(till, [], tensions=t), tensions=t)
