"""Dynamics of a system of rods and its platform through the Python API (the physics is
tested in crates/softrod-core/tests/suite/dynamics_system.rs; here the wiring, units, results,
save/restore and refusals; docs/dynamics.md, "Systems of rods")."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import softrod
import system_cases
from softrod import DesignError, InputError

SYSTEM = "two_spa_platform"


@pytest.fixture(scope="module")
def system():
    return softrod.load_system(SYSTEM)


def test_a_run_starts_on_the_static_equilibrium_and_keeps_its_books(system):
    # Rod 0's channel 0 ramps to 40 kPa in 0.05 s; the platform's inertia is a 3x3 tensor.
    steps = 25
    traj = softrod.simulate_system(
        system,
        lambda t: [[min(t / 0.05, 1.0) * 40e3, 0, 0], [0, 0, 0]],
        "50 ms",
        platform_inertia=[[2e-6, 0, 0], [0, 2e-6, 0], [0, 0, 4e-6]],
        dt="2 ms",
        alpha=-0.5,
    )
    n = steps + 1
    assert traj.time.shape == (n,)
    assert traj.time[0] == 0.0
    assert traj.time[-1] == pytest.approx(0.05, rel=1e-12)
    assert traj.platform_position.shape == (n, 3)
    assert traj.platform_rotation.shape == (n, 3, 3)
    assert traj.tip_position.shape == (n, 2, 3)
    assert traj.tip_reaction_force.shape == (n, 2, 3)
    assert len(traj.shapes) == 2 and traj.shapes[0].shape[0] == n
    # t = 0: solve_system's equilibrium refined on the collocation grids; the two
    # discretisations agree to ~1e-7 of the 130 mm rods (measured 1e-9 m in Rust's test
    # systems; 1e-6 m leaves the grids' O(h^4) error room).
    rest = softrod.solve_system(system)
    assert np.abs(traj.platform_position[0] - rest.platform_position).max() < 1e-6
    # Each rod's tip is where the platform holds it (Newton tolerance 1e-9 of L in
    # position, 1e-12 m is round-off of the rotation's product).
    for k in (0, n - 1):
        p, r = traj.platform_position[k], traj.platform_rotation[k]
        for i, rod in enumerate(system.rods):
            want = p + r @ rod.attachment
            assert np.abs(traj.tip_position[k, i] - want).max() < 1e-9
            assert np.abs(traj.shapes[i][k, -1] - traj.tip_position[k, i]).max() < 1e-15
    # The pressure moved the platform; undamped (the design has no damping) and with the
    # trapezoidal rule (alpha = -0.5, no numerical damping) the books balance to the
    # scheme's second-order error, ~(omega dt)^2 / 12 of the energy moved for the resolved
    # motion (measured 2e-5): 1e-3. (At alpha = -0.2 BDF-alpha's numerical damping removes
    # ~5 % here, as it does from the single actuator.)
    assert np.linalg.norm(traj.platform_position[-1] - traj.platform_position[0]) > 1e-4
    assert traj.work_in[-1] > 0
    assert traj.dissipated[-1] == 0.0
    moved = traj.kinetic.max() + traj.work_in.max()
    assert np.abs(traj.energy_balance).max() <= 1e-3 * moved


def test_units_and_the_stepping_object(system):
    sim = softrod.SystemSimulation(system, [["10 kPa", 0, 0], [0, 0, 0]], dt="2 ms")
    s0 = sim.state()
    assert s0.time.tolist() == [0.0]
    plain = softrod.SystemSimulation(system, [[10e3, 0, 0], [0, 0, 0]], dt=2e-3)
    assert np.array_equal(plain.state().platform_position, s0.platform_position)
    a = sim.run([["30 kPa", 0, 0], [0, "5 kPa", 0]], "10 ms")
    b = plain.run([[30e3, 0, 0], [0, 5e3, 0]], 0.01)
    assert a.time.shape == (5,)
    assert np.array_equal(a.platform_position, b.platform_position)
    assert sim.time == pytest.approx(0.01, rel=1e-12)
    assert sim.stats["steps"] == 5


def test_save_restore_and_copy_continue_bit_for_bit(system):
    sim = softrod.SystemSimulation(system, dt=2e-3, platform_inertia=[2e-6, 2e-6, 4e-6])
    sim.run([[20e3, 0, 0], [0, 0, 0]], 0.004)
    saved = sim.save()
    twin = sim.copy()
    a = sim.run([[20e3, 10e3, 0], [0, 0, 0]], 0.006, platform_force=[0.0, 0.01, 0.0])
    b = twin.run([[20e3, 10e3, 0], [0, 0, 0]], 0.006, platform_force=[0.0, 0.01, 0.0])
    other = softrod.SystemSimulation(system, dt=2e-3, platform_inertia=[2e-6, 2e-6, 4e-6])
    other.restore(saved)
    c = other.run([[20e3, 10e3, 0], [0, 0, 0]], 0.006, platform_force=[0.0, 0.01, 0.0])
    for t in (b, c):
        assert np.array_equal(a.platform_position, t.platform_position)
        assert np.array_equal(a.shapes[1], t.shapes[1])
        assert np.array_equal(a.energy_balance, t.energy_balance)
    assert saved.system == SYSTEM and saved.time == pytest.approx(0.004)
    # A state restores only into the same system: not into one whose platform has another
    # inertia or mass (the state would continue under other physics), nor from bare numbers.
    for changed in (
        softrod.SystemSimulation(system, dt=2e-3, platform_inertia=[3e-6, 2e-6, 4e-6]),
        softrod.SystemSimulation(
            dataclasses.replace(system, platform=dataclasses.replace(system.platform, mass=0.03)),
            dt=2e-3,
            platform_inertia=[2e-6, 2e-6, 4e-6],
        ),
    ):
        with pytest.raises(InputError, match="not from this simulation's") as exc:
            changed.restore(saved)
        assert exc.value.field == "state"
        assert changed.time == 0.0
    with pytest.raises(InputError, match="must be a SystemSimulationState"):
        other.restore(np.asarray(saved.data))


def test_a_rod_pressed_on_a_wall_moves_with_its_contact(system, tmp_path):
    """A rod's obstacles act in the system's motion (docs/dynamics.md "Systems of rods"; the
    physics against the free rod by a wall: Rust's dynamics_system.rs). The run starts on the
    walled equilibrium, a pressure step presses the rod harder on the wall, the books
    balance with the penalty's potential, and the trajectory reports, files and tables
    the left rod's contact (the right rod has no obstacles: None)."""
    walled = system_cases.walled(system)
    p40 = system_cases.LEFT_AT_40_KPA
    rest = softrod.solve_system(walled, p40)
    sim = softrod.SystemSimulation(walled, p40, dt="2 ms", alpha=-0.5)
    start = sim.state()
    # Shooting and collocation equilibria agree to the grids' O(h^4) (as the test above).
    assert np.abs(start.platform_position[0] - rest.platform_position).max() < 1e-6
    assert start.contact_force[1] is None and start.penetration[1] is None
    f0 = start.contact_force[0][0]
    assert f0[1] < 0  # the wall pushes back towards -y
    assert f0 == pytest.approx(rest.rods[0].contact.total, rel=1e-4, abs=1e-6)
    traj = sim.run([[55e3, 0.0, 0.0], [0.0, 0.0, 0.0]], "40 ms")
    force, depth = traj.contact_force[0], traj.penetration[0]
    assert force.shape == (20, 3) and depth.shape == (20,)
    # Pressed harder: the wall pushes back harder; the surface stays within the tolerance
    # (every step checks it).
    assert force[-1, 1] < f0[1] - 1e-3
    assert depth.max() <= 0.5e-3
    # Undamped, trapezoidal rule: the books (the penalty's potential in `potential`)
    # balance to the scheme's second-order error, as the free run above (1e-3 of the
    # energy moved).
    moved = traj.kinetic.max() + traj.work_in.max()
    assert np.abs(traj.energy_balance).max() <= 1e-3 * moved
    frame = traj.to_frame()
    assert {"rod0_contact_fy_N", "rod0_penetration_mm"} <= set(frame.columns)
    assert not any(c.startswith("rod1_contact") for c in frame.columns)
    assert np.array_equal(frame["rod0_contact_fy_N"].to_numpy(), force[:, 1])
    whole = softrod.SystemTrajectory.concat([start, traj])
    back = softrod.SystemTrajectory.load(whole.save(tmp_path / "walled.npz"), walled)
    assert np.array_equal(back.contact_force[0], whole.contact_force[0])
    assert np.array_equal(back.penetration[0], whole.penetration[0])
    assert back.contact_force[1] is None
    # The file of the walled system is not one of the system without the wall.
    with pytest.raises(InputError):
        softrod.SystemTrajectory.load(tmp_path / "walled.npz", system)


def test_a_follower_tip_load_on_a_rod_starts_at_rest_and_moves_with_a_pressure_step(system):
    """A follower tip load on a rod (``[tip] frame = "body"``) acts in the system's motion
    (docs/dynamics.md "Systems of rods"; the physics against the free rod with the same
    follower load: Rust's dynamics_system.rs). The run starts at rest on the equilibrium
    under the follower load, stays there while the inputs are held, and a pressure step
    moves it with the books balanced (the follower's work in ``work_in``)."""
    loaded = system_cases.follower(system)
    rest = softrod.solve_system(loaded)
    # The load acts: the equilibrium is not the unloaded system's.
    unloaded = softrod.solve_system(system)
    assert np.abs(rest.platform_position - unloaded.platform_position).max() > 1e-4
    tol = 1e-12
    sim = softrod.SystemSimulation(loaded, dt="2 ms", alpha=-0.5, tol=tol)
    start = sim.state()
    # Shooting and collocation equilibria agree to the grids' O(h^4) (as the tests above).
    assert np.abs(start.platform_position[0] - rest.platform_position).max() < 1e-6
    assert np.abs(start.platform_velocity[0]).max() == 0.0
    held = sim.run(None, "10 ms")
    # At rest under held inputs: each step may move it by its Newton error only, 2 tol of
    # the scaled unknowns (max(1, |z|) <= 2, positions in units of L = 130 mm), after the
    # start's tol: (1 + 2 steps) tol 2 L = 2.9e-12 m over 5 steps.
    length = 0.13
    bound = (1 + 2 * 5) * tol * 2 * length
    assert np.abs(held.platform_position - start.platform_position[0]).max() <= bound
    for i, shape in enumerate(held.shapes):
        assert np.abs(shape - start.shapes[i][0]).max() <= bound
    traj = sim.run(system_cases.LEFT_AT_40_KPA, "40 ms")
    assert np.linalg.norm(traj.platform_position[-1] - start.platform_position[0]) > 1e-4
    # Undamped, trapezoidal rule: the books balance to the scheme's second-order error, as
    # the first test's (1e-3 of the energy moved).
    moved = traj.kinetic.max() + np.abs(traj.work_in).max()
    assert np.abs(traj.energy_balance).max() <= 1e-3 * moved


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"pressures": [[0, 0, 0]]}, "pressures"),
        ({"pressures": [[0, 0], [0, 0, 0]]}, "pressures"),
        ({"scheme": "midpoint"}, "scheme"),
        ({"platform_inertia": [[1e-6, 1e-7, 0], [0, 1e-6, 0], [0, 0, 1e-6]]}, "platform_inertia"),
        ({"platform_inertia": [1e-6, -1e-6, 1e-6]}, "platform_inertia"),
        ({"platform_inertia": [[1e-6, 0], [0, 1e-6]]}, "platform_inertia"),
        ({"dt": -1.0}, "dt"),
        ({"alpha": 0.5}, "alpha"),
    ],
)
def test_bad_inputs_are_refused_by_name(system, kwargs, field):
    with pytest.raises(InputError) as exc:
        softrod.SystemSimulation(system, **kwargs)
    assert field in exc.value.field
    # simulate_system takes the same settings and refuses them the same way.
    args = {"pressures": None, **kwargs}
    with pytest.raises(InputError) as exc:
        softrod.simulate_system(system, args.pop("pressures"), "4 ms", **args)
    assert field in exc.value.field


def test_bad_run_inputs_are_refused_by_name(system):
    sim = softrod.SystemSimulation(system, dt=2e-3)
    with pytest.raises(InputError) as exc:
        sim.run([[0, 0, 0], [0, 0, float("nan")]], 0.002)
    assert "pressures" in exc.value.field
    with pytest.raises(InputError) as exc:
        sim.run(None, 0.002, platform_force=[0, 0])
    assert "platform_force" in exc.value.field
    # Nothing changed: the run goes on from t = 0.
    assert sim.time == 0.0
    sim.run(None, 0.002)
    assert sim.time == pytest.approx(0.002)


def test_the_platform_inertia_of_a_system_file_is_the_runs_default(system, tmp_path):
    text = (softrod.system.systems_dir() / f"{SYSTEM}.toml").read_text()
    assert 'mass = "20 g"' in text
    given = text.replace(
        'mass = "20 g"', 'mass = "20 g"\ninertia = ["2e-6 kg*m^2", "2e-6 kg*m^2", "4e-6 kg*m^2"]'
    )
    (tmp_path / "with_inertia.toml").write_text(given)
    from_file = softrod.load_system(tmp_path / "with_inertia.toml")
    np.testing.assert_array_equal(from_file.platform.inertia, np.diag([2e-6, 2e-6, 4e-6]))
    np.testing.assert_array_equal(system.platform.inertia, np.zeros((3, 3)))
    push = [[20e3, 0, 0], [0, 0, 0]]
    a = softrod.simulate_system(from_file, push, 0.006, dt=2e-3)
    b = softrod.simulate_system(system, push, 0.006, dt=2e-3, platform_inertia=[2e-6, 2e-6, 4e-6])
    c = softrod.simulate_system(system, push, 0.006, dt=2e-3)
    np.testing.assert_array_equal(a.platform_rotation, b.platform_rotation)
    # The inertia does act: without it the platform turns differently.
    assert np.abs(a.platform_rotation - c.platform_rotation).max() > 0
    for bad, rule in [
        ('["1e-6 kg*m^2", "-1e-6 kg*m^2", "1e-6 kg*m^2"]', "semi-definite"),
        ("[[1e-6, 1e-7, 0], [0, 1e-6, 0], [0, 0, 1e-6]]", "symmetric"),
        ('["1 kg", "1 kg", "1 kg"]', "wrong unit"),
        ("[1e-6, 1e-6]", "3 principal values"),
    ]:
        (tmp_path / "bad.toml").write_text(
            text.replace('mass = "20 g"', f'mass = "20 g"\ninertia = {bad}')
        )
        with pytest.raises(DesignError, match=rule) as exc:
            softrod.load_system(tmp_path / "bad.toml")
        assert exc.value.field.startswith("platform.inertia")


def test_an_unstable_start_warns_raises_or_is_ignored(system):
    """Pushed up by 10 N, the two actuators holding the platform are compressed past
    buckling and solve_system flags the straight equilibrium unstable (from 5 N on): a
    run started there would stay until disturbed, so the start says so, as a single rod's
    does (softrod.Simulation)."""
    from softrod import InvalidStateError, StabilityWarning

    up = [0.0, 0.0, 10.0]
    with pytest.warns(StabilityWarning, match="system's initial static state"):
        sim = softrod.SystemSimulation(system, platform_force=up)
    assert sim.start_stable is False
    with pytest.raises(InvalidStateError) as info:
        softrod.simulate_system(system, None, "4 ms", platform_force=up, on_unstable="raise")
    assert info.value.rule == "stability"
    assert (
        softrod.SystemSimulation(system, platform_force=up, on_unstable="ignore").start_stable
        is False
    )
    assert softrod.SystemSimulation(system).start_stable is True  # hanging: stable, quiet


def test_long_runs_report_progress_and_their_chunks_change_nothing(system):
    """A run goes through the core in chunks of about 0.2 s of work, reporting
    progress(t_done, t_end, wall_s) after each; where the chunks end changes nothing: the
    same run as three SystemSimulation.run calls is the same to the last bit."""

    def ramp(t):
        return [[min(t / 0.02, 1.0) * 30e3, 0.0, 0.0], [0.0, 0.0, 0.0]]

    seen = []
    whole = softrod.simulate_system(
        system, ramp, 0.06, progress=lambda done, total, wall: seen.append((done, total))
    )
    assert seen and all(total == pytest.approx(0.06) for _, total in seen)
    assert np.all(np.diff([d for d, _ in seen]) > 0) and seen[-1][0] == pytest.approx(0.06)
    sim = softrod.SystemSimulation(system, ramp(0.0))
    pieces = [sim.run(ramp, 0.02, progress=False) for _ in range(3)]
    np.testing.assert_array_equal(
        np.concatenate([p.platform_position for p in pieces]), whole.platform_position[1:]
    )
    np.testing.assert_array_equal(
        np.concatenate([p.shapes[0] for p in pieces]), whole.shapes[0][1:]
    )
