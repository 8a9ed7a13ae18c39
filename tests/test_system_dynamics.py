"""Dynamics of a system of rods and its platform through the Python API (the physics is
tested in crates/softrod-core/tests/dynamics_system.rs; here the wiring, units, results,
save/restore and refusals; docs/dynamics.md, "Systems of rods")."""

from __future__ import annotations

import numpy as np
import pytest
import softrod
from softrod import InputError

SYSTEM = "two_spa_platform"


@pytest.fixture(scope="module")
def system():
    return softrod.load_system(SYSTEM)


def test_a_run_starts_on_the_static_equilibrium_and_keeps_its_books(system):
    # Rod 0's channel 0 ramps to 40 kPa in 0.05 s; the platform's inertia is a 3x3 tensor.
    steps = 25
    traj = softrod.simulate_system(
        system, "50 ms", pressures=lambda t: [[min(t / 0.05, 1.0) * 40e3, 0, 0], [0, 0, 0]],
        platform_inertia=[[2e-6, 0, 0], [0, 2e-6, 0], [0, 0, 4e-6]], dt="2 ms", alpha=-0.5,
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
    a = sim.run("10 ms", [["30 kPa", 0, 0], [0, "5 kPa", 0]])
    b = plain.run(0.01, [[30e3, 0, 0], [0, 5e3, 0]])
    assert a.time.shape == (5,)
    assert np.array_equal(a.platform_position, b.platform_position)
    assert sim.time == pytest.approx(0.01, rel=1e-12)
    assert sim.stats["steps"] == 5


def test_save_restore_and_copy_continue_bit_for_bit(system):
    sim = softrod.SystemSimulation(system, dt=2e-3, platform_inertia=[2e-6, 2e-6, 4e-6])
    sim.run(0.004, [[20e3, 0, 0], [0, 0, 0]])
    saved = sim.save()
    twin = sim.copy()
    a = sim.run(0.006, [[20e3, 10e3, 0], [0, 0, 0]], platform_force=[0.0, 0.01, 0.0])
    b = twin.run(0.006, [[20e3, 10e3, 0], [0, 0, 0]], platform_force=[0.0, 0.01, 0.0])
    other = softrod.SystemSimulation(system, dt=2e-3, platform_inertia=[2e-6, 2e-6, 4e-6])
    other.restore(saved)
    c = other.run(0.006, [[20e3, 10e3, 0], [0, 0, 0]], platform_force=[0.0, 0.01, 0.0])
    for t in (b, c):
        assert np.array_equal(a.platform_position, t.platform_position)
        assert np.array_equal(a.shapes[1], t.shapes[1])
        assert np.array_equal(a.energy_balance, t.energy_balance)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"pressures": [[0, 0, 0]]}, "pressures"),
        ({"pressures": [[0, 0], [0, 0, 0]]}, "pressures"),
        ({"scheme": "midpoint"}, "scheme"),
        ({"platform_inertia": [[1e-6, 1e-7, 0], [0, 1e-6, 0], [0, 0, 1e-6]]},
         "platform_inertia"),
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


def test_bad_run_inputs_are_refused_by_name(system):
    sim = softrod.SystemSimulation(system, dt=2e-3)
    with pytest.raises(InputError) as exc:
        sim.run(0.002, [[0, 0, 0], [0, 0, float("nan")]])
    assert "pressures" in exc.value.field
    with pytest.raises(InputError) as exc:
        sim.run(0.002, platform_force=[0, 0])
    assert "platform_force" in exc.value.field
    # Nothing changed: the run goes on from t = 0.
    assert sim.time == 0.0
    sim.run(0.002)
    assert sim.time == pytest.approx(0.002)
