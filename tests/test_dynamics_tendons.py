"""Tendons and follower loads in dynamics (issue 17): tendon tensions as time inputs of
``simulate`` and ``Simulation`` beside the pressures, follower tip loads, their energy
books, and the input rules (docs/dynamics.md, "Tendons and follower loads"). The core's
precise checks (settling on collocation statics to 1e-9 L, exact step Jacobians, energy
balance) are in crates/softrod-core/tests/suite/dynamics_tendons.rs."""

import math

import numpy as np
import pytest
import softrod
from hypothesis import given, settings
from hypothesis import strategies as st
from softrod import InputError, Simulation, SolverOptions, load_design, solve_statics

pytestmark = pytest.mark.fast

L = 0.1  # m
EI = 0.01  # N m^2
D = 3e-3  # tendon offset, m


def rod(tendon: bool = True, **tip) -> dict:
    """A uniform upright rod (d3 = +z) with one straight tendon 3 mm along d1, no gravity,
    damped (tau = 0.02 s)."""
    sec = {
        "name": "rod",
        "length": f"{L * 1e3} mm",
        "mass": "10 g",
        "outer_radius": "10 mm",
        "EA": "100 N",
        "GA": "50 N",
        "EI": f"{EI} N*m^2",
        "GJ": "0.008 N*m^2",
        "steps": 10,
    }
    if tendon:
        sec["tendons"] = [{"channel": 0, "distance": f"{D * 1e3} mm"}]
    out = {
        "design": {"name": "tendon_rod", "citation": "closed-form check"},
        "mounting": {"orientation": "upright", "gravity": "0 m/s^2"},
        "dynamics": {"damping_time": "20 ms"},
        "sections": [sec],
    }
    if tip:
        out["tip"] = tip
    return out


def test_tendon_run_settles_on_the_statics_with_the_same_tension():
    # Slack at t = 0 (the static start), 2 N from the first step on: the damped rod settles
    # on the arc of curvature T d / EI (Rucker and Webster's straight tendon) that
    # solve_statics gives with the same tension, to the two discretisations' difference.
    traj = softrod.simulate(rod(), None, 1.5, dt=5e-3, tensions=lambda t: [0.0 if t == 0 else 2.0])
    st_ = solve_statics(rod(), [], tensions=[2.0], options=SolverOptions(tol=1e-12))
    assert np.linalg.norm(traj.tip_position[0] - [0, 0, L]) < 1e-12
    moved = np.linalg.norm(traj.tip_position[-1] - traj.tip_position[0])
    k = 2.0 * D / EI
    assert moved > 0.3 * (1 - math.cos(k * L)) / k  # the tendon bends the rod
    assert np.linalg.norm(traj.tip_position[-1] - st_.tip_position) < 1e-6 * L
    # The books balance: the elastic energy includes the tendon's potential T (|q| - |q0|)
    # (negative once the tendon is shorter than on the straight rod), W_in the work of the
    # changing tension (docs/dynamics.md). No energy appears (BDF-alpha only loses some to
    # numerical damping of the modes the jump excites).
    moved = np.max(np.abs(traj.elastic - traj.elastic[0]))
    assert traj.work_in[-1] != 0 and moved > 0
    assert np.max(traj.energy_balance) <= 0.02 * moved


def test_trajectory_records_the_tensions_and_keeps_them_in_files(tmp_path):
    # The tensions are inputs like the pressures: every sample records the ones held over
    # the step that ended there, the tables carry them as t0_N, and both file formats give
    # them back exactly (a trajectory without them, as files before them, loads with none).
    def ramp(t):
        return [min(t, 0.02) * 100.0]  # 0 at t = 0, then up to 2 N at 20 ms

    traj = softrod.simulate(rod(), None, 0.05, dt=5e-3, tensions=ramp)
    assert traj.n_tendons == 1 and traj.tension.shape == (len(traj), 1)
    np.testing.assert_allclose(traj.tension[:, 0], [ramp(t)[0] for t in traj.time], rtol=1e-15)
    frame = traj.to_frame(units="SI")
    np.testing.assert_array_equal(frame["t0_N"].to_numpy(), traj.tension[:, 0])
    for suffix in (".npz", ".parquet"):
        back = softrod.Trajectory.load(traj.save(tmp_path / f"run{suffix}"))
        np.testing.assert_array_equal(back.tension, traj.tension)
    plain = softrod.simulate(rod(tendon=False), None, 0.01, dt=5e-3)
    assert plain.tension.shape == (len(plain), 0) and "t0_N" not in plain.to_frame().columns
    with pytest.raises(InputError, match=r"tension\[0, 0\].*>= 0"):
        softrod.Trajectory(**{**_fields(traj), "tension": -traj.tension[:, :1] - 1.0})


def _fields(traj) -> dict:
    """A trajectory's constructor arguments."""
    import dataclasses

    return {f.name: getattr(traj, f.name) for f in dataclasses.fields(traj)}


def test_stepper_takes_tensions_and_restores_them():
    sim = Simulation(rod(), tensions=["1 N"], dt=5e-3)
    np.testing.assert_array_equal(sim.tensions, [1.0])
    start = sim.state()
    np.testing.assert_array_equal(start.tensions, [1.0])
    # At rest in equilibrium under the starting tension: held, nothing moves.
    sim.step()
    assert np.linalg.norm(sim.state().tip_velocity) < 1e-9
    sim.step(tensions=[2.5])
    sim.set_tensions(["0.5 N"])
    sim.step()
    state = sim.state()
    np.testing.assert_array_equal(state.tensions, [0.5])
    branch = Simulation(rod(), dt=5e-3)
    branch.restore(state)
    np.testing.assert_array_equal(branch.tensions, [0.5])
    for s in (sim, branch):
        s.step(tensions=[1.5])
        s.step()
    np.testing.assert_array_equal(sim.state().data, branch.state().data)


def test_midpoint_rule_keeps_the_books_of_a_tendon_swing():
    # Undamped, the midpoint rule: the jump of tension does work (the tendons' potential
    # changes at fixed strains), then the swing conserves energy: E - E(0) - W_in + D
    # stays within 1 % of the work in.
    d = rod()
    d["dynamics"] = {"damping_time": "0 s"}
    traj = softrod.simulate(
        d, None, 0.3, dt=2e-3, scheme="midpoint", tensions=lambda t: [0.0 if t == 0 else 2.0]
    )
    moved = np.max(np.abs(traj.elastic - traj.elastic[0]))
    assert moved > 1e-4
    assert np.max(np.abs(traj.energy_balance)) <= 1e-2 * moved
    assert np.ptp(traj.energy[1:]) <= 1e-2 * moved


def test_follower_tip_force_run_settles_on_the_statics():
    # A follower tip force (turns with the tip) on the damped rod without tendons, switched
    # on with the pressure-free schedule: from the static start under it, no motion; after a
    # change of the tip load the rod settles on the statics with the new follower load.
    d = rod(tendon=False, force=["0.05 N", "0 N", "0 N"], frame="body")
    sim = Simulation(d, dt=5e-3)
    f = [0.12, 0.0, -0.02]
    sim.set_tip_loads(f, [0.0, 0.0, 0.0])
    sim.run(None, 1.5)
    d2 = rod(tendon=False, force=[f"{x} N" for x in f], frame="body")
    st_ = solve_statics(d2, [], options=SolverOptions(tol=1e-12))
    assert st_.stable is None  # follower loads: stability not assessed
    tip = sim.state().tip_position
    assert np.linalg.norm(tip - [0, 0, L]) > 1e-3
    assert np.linalg.norm(tip - st_.tip_position) < 1e-6 * L


@pytest.mark.parametrize(
    "tensions, field, rule",
    [
        ([-1.0], r"tensions\[0\]", ">= 0"),
        ([float("nan")], r"tensions", "finite"),
        ([1.0, 2.0], "tensions", "1 tendon channel"),
        (["1 kPa"], r"tensions\[0\]", "force"),
        (lambda t: [-0.1], r"tensions\(t = .* s\)\[0\]", ">= 0"),
        (lambda t: [1.0, 1.0], r"tensions\(t = .* s\)", "1 tendon channel"),
        (lambda t: [float("inf")], r"tensions\(t = .* s\)", "finite"),
    ],
)
def test_bad_tensions_name_the_field(tensions, field, rule):
    with pytest.raises(InputError, match=f"{field}.*{rule}"):
        softrod.simulate(rod(), None, 0.01, tensions=tensions)


def test_bad_tensions_in_the_stepper_change_nothing():
    sim = Simulation(rod(), tensions=[1.0])
    with pytest.raises(InputError, match=r"tensions\[0\].*>= 0"):
        sim.set_tensions([-2.0])
    with pytest.raises(InputError, match=r"tensions\[0\].*>= 0"):
        sim.step(tensions=[-2.0])
    with pytest.raises(InputError, match=r"tensions\[0\].*>= 0"):
        Simulation(rod(), tensions=[-2.0])
    np.testing.assert_array_equal(sim.tensions, [1.0])
    assert sim.time == 0.0
    with pytest.raises(InputError, match="has no tendons"):
        softrod.simulate(rod(tendon=False), None, 0.01, tensions=[1.0])
    with pytest.raises(InputError, match="tensions.*model='cosserat'"):
        softrod.simulate("stiff_flop_pcc", [0.0] * 6, 0.01, model="pcc", tensions=[1.0])


@settings(max_examples=25, deadline=None)
@given(
    value=st.one_of(
        st.floats(-5.0, 5.0),
        st.sampled_from(
            [float("nan"), float("inf"), -float("inf"), -0.0, 1e-300, -1e-300]
            + ["1 N", "200 mN", "-1 N", "1 m", "abc", "", None, True, [1.0]]
        ),
    )
)
def test_any_tension_runs_or_is_refused_with_the_field(value):
    # Every held tension (within the rod's range: 5 N bends it by half a turn) is a finite,
    # non-negative force that runs, or an InputError that names tensions; never a crash.
    ok = (isinstance(value, float) and math.isfinite(value) and 0 <= value <= 5) or value == "1 N"
    try:
        traj = softrod.simulate(rod(), None, 0.01, dt=5e-3, tensions=[value])
    except InputError as e:
        assert "tensions" in str(e)
        assert not ok, e
    else:
        assert np.all(np.isfinite(traj.tip_position))


def test_bundled_finger_simulates_with_its_tendon():
    d = load_design("prebent_tendon_finger")
    traj = softrod.simulate(d, [0.0], 0.02, dt=5e-3, tensions=lambda t: [0.0 if t == 0 else 0.5])
    assert np.all(np.isfinite(traj.tip_position))
    assert np.linalg.norm(traj.tip_position[-1] - traj.tip_position[0]) > 0


def test_cli_simulate_takes_held_tensions(run, tmp_path):
    from conftest import assert_clean_error

    out = tmp_path / "traj.npz"
    finger = "prebent_tendon_finger"
    args = ("simulate", finger, "--pulses", "paper000", "--t-end", "20 ms", "--dt", "5 ms")
    result = run(*args, "--tension", "0.5N", "--out", str(out))
    assert result.exit_code == 0, result.output
    assert out.exists()
    bad = tmp_path / "bad.npz"
    assert_clean_error(run(*args, "--tension", "-1N", "--out", str(bad)), 2, "--tension[0]", ">= 0")
    assert_clean_error(run(*args, "--tension", "1N,2N", "--out", str(bad)), 2, "1 tendon")
    assert not bad.exists()
