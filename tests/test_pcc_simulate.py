"""softrod.simulate(model="pcc"): the PCC model of paper 003 through the rod's entry point.

The PCC physics (energy conservation, the linearised elongation as a second-order system,
mass matrix and Jacobian vs finite differences) is checked in
crates/softrod-core/tests/suite/pcc.rs; these tests check that ``simulate`` drives the same
core correctly and returns a Trajectory consistent with itself, with ``run_pcc``, with
statics and with the rod's pressure supply.
"""

import numpy as np
import pytest
import softrod
from conftest import assert_clean_error
from softrod import PressureSchedule, Simulation, Trajectory, simulate
from softrod.errors import InputError
from softrod.pcc import run_pcc

ARM = "stiff_flop_pcc"
L0 = 0.11
NEWTON = 1e-9  # m: a PCC step converges to 1e-11 L0 per coordinate; runs that differ only
# in the Newton starting guess (chunking) agree to a few times that over hundreds of steps.


def _pulse(p=1.0e5):
    """A 0.4 s pulse on the chamber pair 1-2 (channels 0, 1), then rest."""
    zero, on = [0.0] * 6, [p, p, 0.0, 0.0, 0.0, 0.0]
    return PressureSchedule.steps([0.0, 0.05, 0.45], [zero, on, zero])


@pytest.fixture(scope="module")
def pulse_run():
    return simulate(ARM, _pulse(), 1.0, dt=1e-3, save_every=5, shapes="saved", model="pcc")


def test_pcc_simulate_equals_run_pcc(pulse_run):
    tr = pulse_run
    n = 1000
    commands = _pulse().sample(1e-3 * np.arange(n + 1))
    ref = run_pcc(ARM, 1e-3, commands, save_every=5, initial="static")
    assert tr.metadata["model"] == "pcc" and tr.metadata["steps"] == n
    np.testing.assert_allclose(tr.time, ref["time"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(tr.tip_position, ref["tip_position"], rtol=0, atol=NEWTON)
    np.testing.assert_allclose(tr.pressure, commands[::5], rtol=0, atol=0)
    np.testing.assert_allclose(tr.command, commands[::5], rtol=0, atol=0)
    # The pulse bends the arm away from the pair: tens of mm, so the check is not vacuous.
    assert np.ptp(tr.tip_position[:, 0]) > 0.02


def test_pcc_shapes_are_arcs_ending_at_the_tip(pulse_run):
    tr = pulse_run
    assert len(tr.shape_time) == len(tr.time)
    assert tr.shape_s[0] == 0.0 and tr.shape_s[-1] == pytest.approx(L0, rel=1e-15)
    np.testing.assert_allclose(tr.shape_position[:, -1], tr.tip_position, rtol=0, atol=1e-15)
    # Every stored shape is a circular arc: equal chords between equally spaced points.
    chords = np.linalg.norm(np.diff(tr.shape_position, axis=1), axis=2)
    assert np.ptp(chords, axis=1).max() < 1e-12


def test_pcc_tip_velocity_is_the_derivative_of_the_tip_position():
    tr = simulate(ARM, _pulse(), 0.3, dt=5e-4, model="pcc")
    # Central differences over 2 dt have error dt^2/6 |p'''|: with |p'''| of order
    # 1e2 m/s^3 once the motion is smooth, i.e. ~4e-6 m/s against speeds of ~0.2 m/s. At the
    # pressure step (t = 0.05 s) the acceleration jumps, and the axial mode's fast pole
    # (b_L / m = 2,000 1/s) makes |p'''| far larger for the next few ms: the samples of
    # the 20 ms after the step are left out.
    fd = (tr.tip_position[2:] - tr.tip_position[:-2]) / (2 * 5e-4)
    t = tr.time[1:-1]
    smooth = (t < 0.05 - 3 * 5e-4) | (t > 0.07)
    speed = np.abs(tr.tip_velocity).max()
    assert speed > 0.1
    assert np.abs(fd - tr.tip_velocity[1:-1])[smooth].max() < 1e-4 * speed


def test_pcc_settles_on_its_static_equilibrium():
    # The slowest poles are k_L / b_L = 2.1 1/s and k_theta / b_theta = 3 1/s: after 10 s
    # (e^-21 of a ~30 mm excursion, ~1e-11 m) under constant pressure the arm rests on the
    # equilibrium of solve_statics(model="pcc"), to Newton's tolerance.
    p = [1.2e5, 0.6e5, 0.0, 0.0, 0.0, 0.0]
    sched = PressureSchedule.steps([0.0, 0.01], [[0.0] * 6, p])
    tr = simulate(ARM, sched, 10.0, dt=5e-3, save_every=50, model="pcc")
    st = softrod.solve_statics(ARM, p, model="pcc")
    assert np.linalg.norm(tr.tip_position[-1] - st.tip_position) < 1e-9  # m; 4e-11 seen
    assert np.abs(tr.tip_velocity[-1]).max() < 1e-9  # m/s


def test_both_models_see_the_same_supplied_pressures():
    d = softrod.load_design(ARM).replace(
        {"dynamics.pressure_time_constant": "0.1 s", "dynamics.pressure_rate_limit": "2 bar/s"}
    )
    sched = PressureSchedule.steps([0.0, 0.001], [[0.0] * 6, [1.5e5] + [0.0] * 5])
    pcc = simulate(d, sched, 0.5, dt=5e-3, model="pcc")
    rod = simulate(d, sched, 0.5, dt=5e-3)
    np.testing.assert_array_equal(pcc.pressure, rod.pressure)
    assert np.diff(pcc.pressure[:, 0]).max() <= 2e5 * 5e-3 * (1 + 1e-12)  # rate limit binds
    assert pcc.pressure[-1, 0] < 1.5e5  # and the lag: not there yet after 0.5 s


def test_chunked_progress_and_straight_start():
    seen = []
    tr = simulate(
        ARM,
        [0.0] * 6,
        0.5,
        dt=1e-3,
        initial="straight",
        model="pcc",
        progress=lambda done, total, wall: seen.append((done, total)),
    )
    assert seen and seen[-1][0] == pytest.approx(0.5) and seen[-1][1] == 0.5
    # Released straight, the upright arm first sits at its reference length and then
    # shortens under its weight (59 g on k_L = 246 N/m: ~1.2 mm static).
    assert tr.tip_position[0] == pytest.approx([0.0, 0.0, L0], abs=1e-15)
    assert tr.tip_position[-1, 2] < L0 - 5e-4


def test_pcc_trajectory_round_trips_through_a_file(pulse_run, tmp_path):
    path = pulse_run.save(tmp_path / "pcc.parquet")
    back = Trajectory.load(path)
    assert back.metadata["model"] == "pcc"
    np.testing.assert_array_equal(back.tip_position, pulse_run.tip_position)
    np.testing.assert_array_equal(back.shape_position, pulse_run.shape_position)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"model": "fem"}, "model"),
        ({"model": "pcc", "alpha": -0.5}, "alpha"),
        ({"model": "pcc", "initial": "moving"}, "initial"),
        ({"model": "pcc", "dt": -1.0}, "dt"),
        ({"model": "pcc", "save_every": 0}, "save_every"),
        ({"model": "pcc", "shapes": "all"}, "shapes"),
    ],
)
def test_bad_settings_name_the_field(kwargs, field):
    with pytest.raises(InputError) as e:
        simulate(ARM, [0.0] * 6, 0.1, **kwargs)
    assert e.value.field == field


def test_pcc_cannot_continue_a_rod_simulation():
    with pytest.raises(InputError) as e:
        simulate(ARM, [0.0] * 6, 0.1, model="pcc", initial=Simulation(ARM))
    assert e.value.field == "initial"


def test_cli_simulate_model_pcc(run, tmp_path):
    inp = _pulse().write(tmp_path / "p.csv")
    out, png = tmp_path / "t.npz", tmp_path / "tip.png"
    res = run(
        "simulate", ARM, "--input", inp, "--t-end", "0.5 s", "--dt", "1ms", "--model", "pcc",
        "--out", out, "--plot", png,
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "PCC model" in res.output and "x real time" in res.output
    tr = Trajectory.load(out)
    assert tr.metadata["model"] == "pcc" and tr.time[-1] == pytest.approx(0.5)
    assert png.stat().st_size > 0
    res = run("simulate", ARM, "--input", inp, "--model", "fem", "--out", tmp_path / "x.npz")
    assert res.exit_code == 2 and not (tmp_path / "x.npz").exists()
    assert_clean_error(
        run("simulate", ARM, "--input", inp, "--model", "pcc", "--dt", "0 s", "--out", out),
        2,
        "--dt",
    )
