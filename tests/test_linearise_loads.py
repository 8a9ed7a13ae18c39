"""The linearisation under follower loads and on obstacles (docs/control.md, "Follower loads
and obstacles"): Beck's column flutters above its critical load and ``modes()`` says so;
K^-1 B is the follower equilibrium's Jacobian, follower tip load components in the tip
frame; the finger pressed onto its table rings as its linearisation with the contact
stiffness says; a frictional equilibrium is refused by name before any work. The core's
tests (crates/softrod-core/tests/suite/linearise_loads.rs) check Beck's frequencies and
flutter load against the characteristic equation and a rod on a plane against the beam on a
Winkler foundation."""

from __future__ import annotations

import numpy as np
import pytest
import softrod
from conftest import ring_down_frequency
from friction_designs import FINGER, MU
from softrod import InputError, linearise, load_design, solve_statics

L, EI, MASS = 0.5, 0.02, 0.1


def beck(p: float, damping_time: float = 0.0) -> softrod.Design:
    """Beck's column: an upright cantilever nearly rigid in extension and shear under a
    follower compressive tip force p EI / L^2 along its tangent; undamped unless
    ``damping_time`` (s, Kelvin-Voigt) is given."""
    return load_design(
        {
            "design": {"name": "beck_column", "citation": "Beck, ZAMP 3, 1952"},
            "mounting": {"orientation": "upright", "gravity": "0 m/s^2"},
            "sections": [
                {
                    "name": "rod",
                    "length": f"{L} m",
                    "mass": f"{MASS} kg",
                    "EA": "4e7 N",
                    "GA": "1e8 N",
                    "EI": f"{EI} N*m^2",
                    "GJ": "0.015 N*m^2",
                    "steps": 48,
                }
            ],
            "tip": {"force": [0, 0, f"{-p * EI / L**2} N"], "frame": "body"},
            "dynamics": {"damping_time": f"{damping_time} s"},
        }
    )


def test_beck_column_flutters_above_its_critical_load():
    """Below 20.05 EI/L^2 the column has modes (K not symmetric: the follower force has no
    potential); above it the lowest two have merged and grow, so modes() refuses, naming the
    growing pole, and poles() shows it (a complex pair with a positive real part)."""
    below = linearise(beck(19.5), nodes=12)
    k = below.stiffness
    assert np.abs(k - k.T).max() > 0.5 * 19.5 * EI / L**2  # order P: the follower's term
    assert below.modes(4).frequency[0] > 0
    # Undamped and stable: every pole on the imaginary axis (round-off of a 144 x 144
    # non-symmetric eigenproblem).
    assert np.abs(below.poles().real).max() < 1e-6 * np.abs(below.poles()).max()
    above = linearise(beck(20.5), nodes=12)
    with pytest.raises(InputError, match="flutter") as info:
        above.modes()
    assert info.value.field == "equilibrium"
    top = above.poles()[0]
    assert top.real > 0 and top.imag != 0
    # The static solve cannot see it: the straight column is its equilibrium.
    assert np.abs(above.equilibrium.tip_position[:2]).max() < 1e-12


def test_kelvin_voigt_damping_lowers_becks_flutter_load():
    """Ziegler's destabilisation paradox, seen in poles(): a little Kelvin-Voigt damping
    makes the column flutter far below the undamped 20.05, at a load that does not depend on
    how small the damping is (tau = 1e-4 and 1e-3 s agree to 1e-3: the vanishing-damping
    limit; measured 10.939 and 10.939). Undamped, the column at p = 12 stays on the
    imaginary axis (as below 20.05 above)."""

    def growth(p: float, tau: float) -> float:
        poles = linearise(beck(p, tau), nodes=8).poles()
        return poles[np.abs(poles) < 100].real.max()  # the two lowest bending pairs

    def onset(tau: float) -> float:
        lo, hi = 10.0, 12.0
        assert growth(lo, tau) < 0 < growth(hi, tau)
        for _ in range(12):
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if growth(mid, tau) > 0 else (mid, hi)
        return 0.5 * (lo + hi)

    assert abs(growth(12.0, 0.0)) < 1e-6 * 20  # undamped: |Re| at round-off of |pole| ~ 20
    light, lighter = onset(1e-3), onset(1e-4)
    assert abs(light / lighter - 1) < 1e-3, (light, lighter)
    assert light < 0.6 * 20.05


def test_follower_static_response_is_the_jacobian():
    """The 130 mm actuator with a follower tip force and moment: the tip rows of K^-1 B are
    StaticSolution.jacobian's columns, the tip load's in the tip frame (both exact: to the
    round-off of inverting the flexibility)."""
    design = load_design("spa_three_chamber_130mm").replace(
        {"tip.frame": "body", "tip.force": ["20 mN", "-10 mN", "-30 mN"]}
    )
    design = design.replace({"tip.moment": [0, "1 mN*m", 0]})
    sol = solve_statics(design, [30e3, 5e3, 45e3])
    system = linearise(sol, nodes=9)
    response = np.linalg.solve(system.stiffness, system.input)[system.tip_rows]
    jac = sol.jacobian()
    want = np.hstack([jac.pressures, jac.tip_force, jac.tip_moment])
    scale = np.abs(want).max(axis=0)
    np.testing.assert_allclose(response / scale, want / scale, rtol=0, atol=1e-8)
    # In the tip frame: the tip force's columns are the tip rotation's columns.
    rot = sol.tip_rotation
    np.testing.assert_allclose(system.input[-6:-3, 3:6], rot, rtol=0, atol=1e-15)


def test_finger_on_its_table_rings_as_its_linearisation_says():
    """The pre-curved finger pressed onto its table (20 kPa), lightly damped (tau = 0.5 ms),
    stepped to 21 kPa: the ring-down of the nonlinear simulation with contact (dt = 1 ms,
    BDF-alpha) against the in-plane mode of the linearisation, which holds the table's
    penalty stiffness. The time step's period error is about (w dt)^2 / 4 ~ 2e-3 here
    (measured 2.3e-3, and 8e-4 at dt = 0.5 ms): 0.5 % bounds it; the decay rate to 2 %.
    Without the table that mode is far lower (checked), so the contact is what is tested."""
    design = load_design(FINGER).replace({"dynamics.damping_time": "0.5 ms"})
    sim = softrod.Simulation(design, [20e3], dt=1e-3, alpha=-0.2)
    traj = sim.run([21e3], 1.0, progress=False)
    f_sim, sigma_sim = ring_down_frequency(traj, 0.2, axis=0)
    modes = linearise(design, [21e3], nodes=10).modes(4)

    # The mode the step excites: the lowest that moves the tip along x more than along y
    # (in the bend's plane; shapes are normalised to their largest entry, a rotation).
    def in_plane(m: softrod.control.Modes) -> int:
        return next(i for i in range(4) if abs(m.shapes[i, -1, 0]) > abs(m.shapes[i, -1, 1]))

    k = in_plane(modes)
    f_lin, sigma_lin = modes.damped_frequency[k], modes.damping_ratio[k] * modes.omega[k]
    assert abs(f_lin / f_sim - 1) < 5e-3, (f_lin, f_sim)
    assert abs(sigma_lin / sigma_sim - 1) < 2e-2, (sigma_lin, sigma_sim)
    lifted = design.with_obstacles([])
    free = linearise(lifted, [21e3], nodes=10).modes(4)
    assert free.frequency[in_plane(free)] < 0.8 * modes.frequency[k]


def test_frictional_equilibrium_is_refused_before_any_work(rough):
    """Friction makes the equilibrium depend on its load path and its stick/slip switch has
    no derivative: refused naming the obstacle's friction, before a solve (a design) or
    from a frictional solution."""
    with pytest.raises(InputError) as info:
        linearise(rough, [20e3], nodes=6)
    assert info.value.field == "obstacles[0].friction"
    assert str(MU) in str(info.value) and "load path" in str(info.value)
    sol = solve_statics(rough, [20e3])
    with pytest.raises(InputError) as info:
        linearise(sol, nodes=6)
    assert info.value.field == "obstacles[0].friction"


def test_system_on_obstacles_linearises_with_contact():
    """Two pre-curved fingers holding a clip, each pressed onto its table (frictionless):
    the platform's rows of K^-1 B are the system's Jacobian (both exact; 1e-6 bounds the
    round-off of the dense condensation, as for the system without contact); with friction
    the linearisation is refused, naming the solution."""
    from friction_designs import two_fingers

    system = two_fingers()
    sol = softrod.solve_system(system, [[30e3], [30e3]], options=softrod.SolverOptions(tol=1e-13))
    assert all(r.contact.in_contact.any() for r in sol.rods)
    lin = sol.linearise(nodes=6)
    response = np.linalg.solve(lin.stiffness, lin.input)[lin.platform_rows]
    jac = sol.jacobian()
    want = np.hstack([jac.pressures, jac.tensions, jac.platform_force, jac.platform_moment])
    for c in range(want.shape[1]):
        scale = np.linalg.norm(want[:, c])
        assert np.linalg.norm(response[:, c] - want[:, c]) <= 1e-6 * scale, lin.input_names[c]
    assert lin.modes(3).frequency[0] > 0
    rough = softrod.solve_system(two_fingers(MU), [[30e3], [30e3]])
    with pytest.raises(InputError, match="frictional"):
        rough.linearise(nodes=6)
