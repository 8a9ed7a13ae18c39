"""Control tools (docs/control.md): inverse statics (round trip, unreachable targets against
the workspace sweep, bounds as a property), exact Jacobians against finite differences of
whole solves, linearised frequencies against the ring-down of the dynamic simulation, the
closed-loop example with an error bound from the linearised model, and the command line.

The core's own tests (crates/softrod-core/tests/suite/inverse.rs, linearise.rs) cover the
algorithms on synthetic designs: 200-sample round trip, redundant channels, orientation
targets, points along the rod, frequencies of a cantilever against closed forms.
"""

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest
import softrod
from conftest import DELETE, assert_clean_error, ring_down_frequency, with_entries
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from softrod import InputError, InverseProblem, solve_inverse, solve_statics
from softrod.control import TargetPath, workspace

SPA = "spa_three_chamber_130mm"
ARM = "pam_arm_220mm"
P_MAX = 70e3  # Pa: paper 001's pressure range
BOUNDS = (0.0, P_MAX)
ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def spa():
    return softrod.load_design(SPA)


@pytest.fixture(scope="module")
def sweep(spa):
    """The workspace of the 130 mm actuator, 21 x 21 samples per face (2646 solves)."""
    return workspace(spa, pressure_bounds=BOUNDS, samples=21)


def test_round_trip_recovers_200_random_pressures(spa):
    """The issue's round trip through the Python API: 200 random pressures inside the
    bounds, forward solve, invert the tip position from a cold start. Three chambers and a
    position target make the map injective, so the pressures come back to 1e-6 of the
    range and the tip to 1e-9 L (the solver stops at 1e-10 L per component)."""
    rng = np.random.default_rng(7)
    problem = InverseProblem(spa, pressure_bounds=BOUNDS)
    worst_p = worst_tip = 0.0
    for p in rng.uniform(0.0, P_MAX, size=(200, 3)):
        tip = solve_statics(spa, p).tip_position
        sol = problem.solve(tip)
        assert sol.reached and sol.stable
        assert np.all(sol.pressures >= 0.0) and np.all(sol.pressures <= P_MAX)
        worst_p = max(worst_p, np.max(np.abs(sol.pressures - p)) / P_MAX)
        worst_tip = max(worst_tip, sol.distance / spa.length)
    assert worst_p <= 1e-6, worst_p
    assert worst_tip <= 1e-9, worst_tip


def test_inverse_solution_reproduces_its_equilibrium(spa):
    target = solve_statics(spa, [30e3, 5e3, 45e3]).tip_position
    text = ",".join(repr(float(v) * 1e3) for v in target) + " mm"  # units at the boundary
    sol = solve_inverse(spa, text, pressure_bounds="0:70 kPa")
    assert sol.reached
    st_ = sol.statics()
    assert np.allclose(st_.tip_position, sol.tip_position, atol=1e-9 * spa.length)
    assert np.allclose(st_.tip_position, target, atol=1e-9 * spa.length)
    assert "target reached" in sol.summary()


def test_unreachable_target_closest_pose_is_on_the_workspace_boundary(spa, sweep):
    """Targets outside the workspace: the answer says not reached, lies on the boundary
    (a bound is active and the point is within the sweep's sample spacing of the sampled
    boundary) and is at least as close to the target as every sampled boundary point."""
    pts = sweep.points
    assert len(pts) == 6 * 21 * 21
    # Largest distance between neighbours on a face grid: how far a boundary point can be
    # from the nearest sample (half a diagonal of a grid cell at most).
    spacing = 0.0
    for f in range(len(sweep.faces)):
        rows = sweep.face == f
        grid = np.full((21, 21, 3), np.nan)
        grid[sweep.grid[rows, 0], sweep.grid[rows, 1]] = sweep.tip_position[rows]
        diag = np.linalg.norm(grid[1:, 1:] - grid[:-1, :-1], axis=2)
        anti = np.linalg.norm(grid[1:, :-1] - grid[:-1, 1:], axis=2)
        spacing = max(spacing, np.nanmax(diag), np.nanmax(anti))
    centre = pts.mean(axis=0)
    for direction in ([1, 0, 0], [0, -1, 0], [1, 1, 0], [0, 0, 1], [0, 0, -1], [-1, 0.3, 0.2]):
        d = np.asarray(direction, float) / np.linalg.norm(direction)
        target = centre + 0.08 * d
        sol = solve_inverse(spa, target, pressure_bounds=BOUNDS)
        assert not sol.reached
        assert np.any(sol.active != 0)
        assert np.all(sol.pressures >= 0.0) and np.all(sol.pressures <= P_MAX)
        nearest = np.min(np.linalg.norm(pts - target, axis=1))
        # At least as close as any sample (the boundary between samples can be closer).
        assert sol.distance <= nearest + 1e-9 * spa.length, (direction, sol.distance, nearest)
        assert sweep.distance_to(sol.point_position) <= 0.5 * spacing, direction


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    x=st.floats(-0.08, 0.08),
    y=st.floats(-0.08, 0.08),
    z=st.floats(-0.2, -0.05),
    lo=st.floats(0.0, 30e3),
    width=st.floats(5e3, 60e3),
)
def test_bounds_are_never_violated(x, y, z, lo, width):
    """Any target, any box: the pressures stay inside the bounds, and the answer either
    reaches the target or says it did not."""
    design = softrod.load_design(SPA)
    hi = lo + width
    # Bounds beyond the design's operating range are the caller's choice here: on_invalid
    # "ignore" lets answers above 70 kPa through (the default refuses them).
    sol = solve_inverse(design, [x, y, z], pressure_bounds=(lo, hi), on_invalid="ignore")
    assert np.all(sol.pressures >= lo) and np.all(sol.pressures <= hi)
    assert sol.reached == (sol.distance <= math.sqrt(3) * 1e-10 * design.length) or (
        not sol.reached
    )
    if sol.reached:
        assert sol.distance <= 1e-9 * design.length


def test_warm_start_follows_a_path_and_regularises_to_the_previous_command(spa):
    problem = InverseProblem(spa, pressure_bounds=BOUNDS)
    centre = solve_statics(spa, [35e3] * 3).tip_position
    prev = problem.solve(centre + [0.01, 0, 0])
    passes = []
    for k in range(1, 41):
        a = k * 0.05  # 0.5 mm per call on a 10 mm circle
        target = centre + 0.01 * np.array([math.cos(a), math.sin(a), 0.0])
        prev = problem.solve(target, initial=prev)
        assert prev.reached
        passes.append(prev.passes)
    # The linearisation is kept between calls: dual passes are rare.
    assert sum(passes) <= 10, passes


def test_stacked_modules_with_split_channels():
    """Paper 004's two modules on six channels (module 2 on channels 3-5): a position target
    is redundant (6 channels, 3 dimensions), resolved by least pressure; a pose target
    (position and orientation) recovers the pressures that made it."""
    base = softrod.load_design("modular_two_module")
    design = base.replace({f"sections[3].chambers[{k}].channel": 3 + k for k in range(3)})
    assert design.n_channels == 6
    p = np.array([60e3, 10e3, 0.0, 20e3, 50e3, 5e3])
    st_ = solve_statics(design, p)
    sol = solve_inverse(design, st_.tip_position, pressure_bounds="0:100 kPa")
    assert sol.reached
    assert np.sum(sol.pressures**2) < np.sum(p**2)
    pose = solve_inverse(
        design, st_.tip_position, orientation=st_.tip_rotation, pressure_bounds="0:100 kPa"
    )
    assert pose.reached and pose.angle < 1e-9
    assert np.allclose(pose.pressures, p, atol=1e-6 * 100e3)


def test_an_unstable_answer_is_refused(spa):
    """The actuator upright under a tip mass of five times the buckling load of its softest
    section: at zero pressure the straight column is an equilibrium, but an unstable one
    (the statics flags it). Asked for the straight column's tip, the inverse reaches it and
    refuses the answer; with on_unstable="warn" it returns it marked unstable."""
    ei = min(min(s["k_bt"][0][0], s["k_bt"][1][1]) for s in spa.sections() if not s["rigid"])
    p_cr = math.pi**2 * ei / (4 * spa.length**2)  # below the true one: the softest section
    up = spa.replace(
        {"mounting.orientation": "upright", "tip.mass": f"{5 * p_cr / 9.81 * 1e3:.1f} g"}
    )
    with pytest.warns(softrod.StabilityWarning):
        column = solve_statics(up, [0, 0, 0])
    assert not column.stable
    with pytest.raises(softrod.InvalidStateError) as err:
        solve_inverse(up, column.tip_position, pressure_bounds=BOUNDS)
    assert err.value.rule == "stability"
    with pytest.warns(softrod.StabilityWarning):
        sol = solve_inverse(up, column.tip_position, pressure_bounds=BOUNDS, on_unstable="warn")
    assert sol.reached and not sol.stable


def test_default_bounds_are_the_operating_range(spa):
    sol = solve_inverse(spa, [0.0, 0.0, -0.2])  # below the reach: the closest pose
    assert np.allclose(sol.bounds, [[0.0, 70e3]] * 3)  # the design's [operating_range]
    assert not sol.reached and np.all(sol.pressures == 70e3)
    bare = softrod.load_design(with_entries(SPA, {"operating_range": DELETE}))
    with pytest.raises(InputError, match="pressure_bounds"):
        solve_inverse(bare, [0, 0, -0.13])  # no range known: the caller must say


def test_bad_inputs_are_named(spa):
    with pytest.raises(InputError, match="lo must be <= hi"):
        solve_inverse(spa, [0, 0, -0.13], pressure_bounds=(70e3, 0))
    with pytest.raises(InputError, match="target"):
        solve_inverse(spa, [0, 0], pressure_bounds=BOUNDS)
    with pytest.raises(InputError, match="point"):
        solve_inverse(spa, [0, 0, -0.13], pressure_bounds=BOUNDS, point="1 m")
    with pytest.raises(InputError, match="weights"):
        solve_inverse(spa, [0, 0, -0.13], pressure_bounds=BOUNDS, weights={"pos": 1})
    with pytest.raises(softrod.DesignError, match="rotation"):
        solve_inverse(spa, [0, 0, -0.13], pressure_bounds=BOUNDS, orientation=np.ones((3, 3)))
    with pytest.raises(InputError, match="-1 atm"):
        solve_inverse(spa, [0, 0, -0.13], pressure_bounds=(-2e5, 0))
    # Values of the wrong type are named too (they once escaped as ValueError or TypeError).
    target = [0, 0, -0.13]
    wrong = [
        ({"initial": "x"}, "initial"),
        ({"initial": {"a": 1}}, "initial"),
        ({"orientation": "x"}, "orientation"),
        ({"orientation": 1j}, "orientation"),
        ({"regularisation": np.zeros((2, 2))}, "regularisation"),
    ]
    for kwargs, field in wrong:
        with pytest.raises(InputError) as err:
            solve_inverse(spa, target, pressure_bounds=BOUNDS, **kwargs)
        assert err.value.field == field, kwargs
    with pytest.raises(InputError) as err:
        softrod.InverseProblem(spa, pressure_bounds=BOUNDS, orientation=np.zeros((2, 2)))
    assert err.value.field == "orientation"


def test_bad_linearisation_starts_and_paths_are_named(spa):
    sol = solve_statics(spa, [20e3, 0, 0])
    with pytest.raises(InputError) as err:
        softrod.linearise(spa, initial=3)
    assert err.value.field == "initial"
    # An equilibrium of another design would linearise the wrong rod.
    with pytest.raises(InputError, match="another design") as err:
        softrod.linearise("pam_arm_220mm", initial=sol)
    assert err.value.field == "initial"
    # What the equilibrium fixes is not given again (it would be ignored).
    for key, value in (("pressures", [0, 0, 0]), ("tip_force", [0, 0, 0.1])):
        with pytest.raises(InputError, match="fixes") as err:
            softrod.linearise(spa, initial=sol, **{key: value})
        assert err.value.field == key
    assert softrod.linearise(sol, nodes=3).stiffness.shape[0] > 0
    for time, position, field in (
        ("x", [[0, 0, 0]], "path.time"),
        ([0.0], "y", "path.position"),
        ([0.0, 1j], [[0, 0, 0]] * 2, "path.time"),
    ):
        with pytest.raises(InputError) as err:
            softrod.TargetPath(time, position)
        assert err.value.field == field


def test_orientation_target_and_point_along_the_rod(spa):
    p = np.array([40e3, 12e3, 3e3])
    st_ = solve_statics(spa, p)
    sol = solve_inverse(spa, st_.tip_position, orientation=st_.tip_rotation, pressure_bounds=BOUNDS)
    assert sol.reached and sol.angle < 1e-9
    assert np.allclose(sol.pressures, p, atol=1e-6 * P_MAX)
    s = 0.07  # inside the chambered body
    k = int(np.argmin(np.abs(st_.s - s)))
    node = st_.s[k]
    sol = solve_inverse(spa, st_.position[k], point=node, pressure_bounds=BOUNDS)
    assert sol.reached and np.allclose(sol.pressures, p, atol=1e-6 * P_MAX)


def test_jacobian_matches_finite_differences_of_whole_solves(spa):
    """StaticSolution.jacobian(): pressures, tip force, tip moment and a parameter, against
    central differences of solve_statics (steps 1 Pa, 0.1 mN, 0.01 mN m, 1e-4 relative:
    truncation ~h^2 and solve noise 1e-13 / h both far below the 1e-5 tolerance)."""
    p = np.array([30e3, 5e3, 45e3])
    tf, tm = np.array([0.01, -0.02, 0.0]), np.array([0.0, 1e-3, 0.0])
    opts = softrod.SolverOptions(tol=1e-13)
    base = solve_statics(spa, p, tip_force=tf, tip_moment=tm, options=opts)
    jac = base.jacobian(params=["c_b"])

    def pose(sol):
        return sol.tip_position, sol.tip_rotation

    def column(fd_plus, fd_minus, h):
        (rp, Rp), (rm, Rm) = pose(fd_plus), pose(fd_minus)
        dr = (rp - rm) / (2 * h)
        dR = (Rp - Rm) / (2 * h)
        w = dR @ base.tip_rotation.T
        return np.concatenate(
            [dr, 0.5 * np.array([w[2, 1] - w[1, 2], w[0, 2] - w[2, 0], w[1, 0] - w[0, 1]])]
        )

    def check(fd, exact):
        assert np.linalg.norm(fd - exact) <= 1e-5 * np.linalg.norm(fd), (fd, exact)

    for c in range(3):
        dp = np.eye(3)[c]
        fd = column(
            solve_statics(spa, p + dp, tip_force=tf, tip_moment=tm, options=opts),
            solve_statics(spa, p - dp, tip_force=tf, tip_moment=tm, options=opts),
            1.0,
        )
        check(fd, jac.pressures[:, c])
    for j in range(3):
        e = np.eye(3)[j]
        fd = column(
            solve_statics(spa, p, tip_force=tf + 1e-4 * e, tip_moment=tm, options=opts),
            solve_statics(spa, p, tip_force=tf - 1e-4 * e, tip_moment=tm, options=opts),
            1e-4,
        )
        check(fd, jac.tip_force[:, j])
        fd = column(
            solve_statics(spa, p, tip_force=tf, tip_moment=tm + 1e-5 * e, options=opts),
            solve_statics(spa, p, tip_force=tf, tip_moment=tm - 1e-5 * e, options=opts),
            1e-5,
        )
        check(fd, jac.tip_moment[:, j])
    cb = spa.spec["sections"][1].get("c_b", 1.0)
    h = 1e-4 * cb
    plus = spa.replace({"sections[1].c_b": cb + h})
    minus = spa.replace({"sections[1].c_b": cb - h})
    fd = column(
        solve_statics(plus, p, tip_force=tf, tip_moment=tm, options=opts),
        solve_statics(minus, p, tip_force=tf, tip_moment=tm, options=opts),
        h,
    )
    check(fd, jac.params[:, 0])


def test_linearised_frequency_matches_the_ring_down_of_the_simulation(spa):
    """The 130 mm actuator, lightly damped (tau = 2 ms), released from rest by a 2 mN tip
    force applied at t = 0: the first bending mode's damped frequency and decay rate from
    the linearisation (12 nodes) against a fit of the simulated ring-down (dt = 1 ms, 2 s,
    after 0.3 s when the higher modes, damped 3-10 times faster, have gone). The issue
    asks 0.5 %; the two discretisations differ by less than 0.1 % here (time step: BDF-alpha
    period error ~(w dt)^2 = 5e-4 relative at most; space: both on the design's nodes)."""
    design = spa.replace({"dynamics.damping_time": "2 ms"})
    force = [2e-3, 0.0, 0.0]
    sim = softrod.Simulation(design, [0, 0, 0], dt=1e-3, alpha=-0.2)
    sim.set_tip_loads(force, [0, 0, 0])
    traj = sim.run([0, 0, 0], 2.0)
    f_sim, sigma_sim = ring_down_frequency(traj, 0.3)
    modes = softrod.linearise(design, [0, 0, 0], tip_force=force, nodes=12).modes(4)
    f_lin = modes.damped_frequency[0]
    sigma_lin = modes.damping_ratio[0] * modes.omega[0]
    assert abs(f_lin / f_sim - 1) < 5e-3, (f_lin, f_sim)
    # The decay rate too (BDF-alpha's own damping at w dt = 0.02 is ~1e-4 of it).
    assert abs(sigma_lin / sigma_sim - 1) < 2e-2, (sigma_lin, sigma_sim)
    # Bending pairs: EI1 = EI2 for this symmetric section.
    assert modes.frequency[1] == pytest.approx(modes.frequency[0], rel=1e-6)


def test_linear_system_static_response_is_the_jacobian(spa):
    p = [20e3, 40e3, 5e3]
    sys_ = softrod.linearise(spa, p, nodes=6)
    response = np.linalg.solve(sys_.stiffness, sys_.input)[sys_.tip_rows]
    jac = solve_statics(spa, p).jacobian()
    assert np.allclose(response[:, :3], jac.pressures, rtol=1e-7, atol=1e-14)
    assert np.allclose(response[:, 3:6], jac.tip_force, rtol=1e-7, atol=1e-12)
    assert np.allclose(sys_.mass, sys_.mass.T)
    a, b = sys_.state_space()
    assert a.shape == (72, 72) and b.shape == (72, 9)
    # No damping in this design: the poles sit on the imaginary axis (none grows).
    poles = np.linalg.eigvals(a)
    assert np.all(poles.real <= 1e-9 * np.abs(poles))


def _example():
    spec = importlib.util.spec_from_file_location(
        "closed_loop_circle", ROOT / "examples" / "closed_loop_circle.py"
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_closed_loop_example_tracks_within_the_predicted_error():
    """The example at reduced duration (two periods of a 2 s circle). Bound from the model:
    the steady-state RMS error the linearised arm predicts for this controller
    (predicted_circle_error: plant H(s) H(0)^-1 with a half-sample delay, PI on the tip
    error). The prediction neglects terms of second order in the radius over the arm's
    length (15 mm / 263 mm: the Jacobian's change around the circle, a few percent) and in
    w / rate (0.03): the simulated RMS over the last period must lie within 10 % of it
    (measured: 0.3 %)."""
    mod = _example()
    controller, result, rms, predicted, _ = mod.run(period=2.0, periods=2)
    assert rms <= 1.1 * predicted, (rms, predicted)
    assert rms >= 0.9 * predicted, (rms, predicted)
    p = result.commands
    assert np.all(p >= 0.0) and np.all(p <= 3.6e5)
    assert len(result.control_time) == 400
    # The PI loop helps: feed-forward alone predicts a larger error at this speed.
    design = softrod.load_design(ARM)
    system = softrod.linearise(design, [1.5e5] * 3, nodes=8)
    ff = softrod.control.predicted_circle_error(system, mod.RADIUS, 2.0, kp=0, ki=0, rate=mod.RATE)
    assert predicted < 0.8 * ff


def test_run_closed_loop_checks_its_arguments(spa):
    with pytest.raises(InputError, match="rate"):
        softrod.run_closed_loop(spa, lambda m: [0, 0, 0], 0.1, rate=0)
    with pytest.raises(InputError, match="whole number"):
        softrod.run_closed_loop(spa, lambda m: [0, 0, 0], 0.1, rate=100, dt=3e-3)
    with pytest.raises(InputError, match="controller"):
        softrod.run_closed_loop(spa, lambda m: [0, 0], 0.02, rate=100)
    zero = lambda m: [0, 0, 0]  # noqa: E731
    for kwargs, field in (
        # 1e300 s would run for ever: refused by its step count before the first step.
        ({"t_end": 1e300}, "t_end"),
        ({"pressures": "x"}, "pressures"),
        ({"progress": 3}, "progress"),
        ({"progress": lambda t: None}, "progress"),  # it is called with (t_done, t_end)
    ):
        args = {"t_end": 0.02, **kwargs}
        with pytest.raises(InputError) as err:
            softrod.run_closed_loop(spa, zero, args.pop("t_end"), rate=100, **args)
        assert err.value.field == field, kwargs
    with pytest.raises(InputError, match="3 finite pressures") as err:
        softrod.run_closed_loop(spa, lambda m: "x", 0.02, rate=100)
    assert err.value.field == "controller"
    # A controller sees the state at each sample.
    seen = []

    def hold(m):
        seen.append(m.time)
        return [10e3, 0.0, 0.0]

    res = softrod.run_closed_loop(ARM, hold, 0.05, rate=100, dt=2e-3)
    assert np.allclose(seen, [0.0, 0.01, 0.02, 0.03, 0.04])
    assert res.trajectory.time[-1] == pytest.approx(0.05)
    assert len(res.trajectory.time) == 26
    assert np.all(res.trajectory.command[1:] == [10e3, 0.0, 0.0])


def test_cli_inverse_json_and_table(run):
    result = run("inverse", SPA, "--target", "10,5,-134 mm", "--bounds", "0:70kPa", "--json")
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    sol = solve_inverse(SPA, [0.010, 0.005, -0.134], pressure_bounds=BOUNDS)
    assert np.allclose(out["pressures_kPa"], sol.pressures / 1e3)
    assert out["reached"] == sol.reached
    result = run("inverse", SPA, "--target", "10,5,-130 mm", "--bounds", "0:70kPa")
    assert result.exit_code == 0
    assert "NOT reached" in result.stdout
    assert_clean_error(
        run("inverse", SPA, "--target", "10,5 mm", "--bounds", "0:70kPa"), 2, "--target"
    )
    assert_clean_error(
        run("inverse", SPA, "--target", "1,2,3 mm", "--bounds", "70:0kPa"), 2, "--bounds"
    )


def test_cli_workspace_writes_table_and_figure(run, tmp_path):
    table, fig = tmp_path / "ws.csv", tmp_path / "ws.png"
    result = run(
        "workspace",
        SPA,
        "--bounds",
        "0:70kPa",
        "--samples",
        "5",
        "--output",
        table,
        "--figure",
        fig,
        "--json",
    )
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    assert out["solves"] == 6 * 25 and out["converged"] == 150
    import pandas as pd

    df = pd.read_csv(table)
    assert len(df) == 150 and {"p0_kPa", "tip_x_mm", "face"} <= set(df.columns)
    assert fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_track_a_short_path(run, tmp_path):
    centre = solve_statics(ARM, [1.5e5] * 3).tip_position
    path = TargetPath.circle(centre, 0.01, 1.0, duration=0.5)
    csv = tmp_path / "circle.csv"
    path.to_frame().to_csv(csv, index=False)
    out = tmp_path / "track.csv"
    result = run("track", ARM, "--path", csv, "--bounds", "0:3.6bar", "--output", out, "--json")
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert summary["rms_error_mm"] > 0 and summary["max_error_mm"] < 10
    import pandas as pd

    df = pd.read_csv(out)
    assert {"time_s", "error_mm", "tip_x_mm", "target_x_mm"} <= set(df.columns)


def test_plot_modes_draws_each_mode_and_marks_a_twist(spa, tmp_path):
    """LinearSystem.plot_modes: one polyline per mode from the base through every node in
    both views, labelled with its frequency; the straight actuator's torsion (its nodes do
    not translate) is marked a twist and drawn on the shape; refusals by name, no file."""
    import matplotlib.pyplot as plt

    lin = softrod.linearise(spa, [0, 0, 0], nodes=12)
    modes = lin.modes(4)
    path = tmp_path / "modes.png"
    fig = lin.plot_modes(4, path)
    try:
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        labels = [t.get_text() for t in fig.legends[0].get_texts()]
        assert labels[0] == "equilibrium"
        assert labels[1] == f"mode 1: {modes.frequency[0]:.3g} Hz"
        twists = [k for k in range(4) if np.abs(modes.shapes[k, :, :3]).max() == 0.0]
        assert twists and all(labels[k + 1].endswith("(twist)") for k in twists)
        front, side = (
            [ln for ln in ax.lines if len(ln.get_xdata()) == 13]  # base + 12 nodes
            for ax in fig.axes
        )
        assert len(front) == len(side) == 4
        eq = lin.equilibrium
        rest = np.array([np.interp(lin.nodes, eq.s, eq.position[:, c]) for c in range(3)]).T
        for k in range(4):
            drawn = np.column_stack(
                [front[k].get_xdata(), side[k].get_xdata(), front[k].get_ydata()]
            )[1:]
            moved = np.abs(drawn - rest * 1e3).max()
            # The largest node displacement is drawn at 15 % of the length (mm); a twist not
            # at all.
            want = 0.0 if k in twists else 0.15 * spa.length * 1e3
            assert moved == pytest.approx(want, abs=1e-9)
    finally:
        plt.close(fig)
    for bad, field in ((0, "count"), (9, "count"), (1.5, "count"), ("3", "count")):
        with pytest.raises(InputError) as info:
            lin.plot_modes(bad)
        assert info.value.field == field
    with pytest.raises(InputError) as info:
        lin.plot_modes(2, title=3)
    assert info.value.field == "title"
    with pytest.raises(InputError) as info:
        lin.plot_modes(2, tmp_path / "modes.unknown")
    assert info.value.field == "path"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["modes.png"]
