"""What is derived from an equilibrium that statics solved by collocation (a long, soft rod
whose single shooting cannot be resolved: docs/model.md, "Collocation"): motion-capture
markers are read from the solution's own nodes; the Jacobian, the parameter sensitivities
(so calibration), the linearisation and the inverse differentiate the collocation equations
(crates/softrod-core/tests/suite/collocation.rs, collocation_derivatives.rs,
linearise_collocation.rs and inverse_collocation.rs check the core's side)."""

from __future__ import annotations

import numpy as np
import pytest
import softrod
from conftest import ring_down_frequency
from softrod import (
    InverseProblem,
    linearise,
    load_design,
    solve_inverse,
    solve_statics,
    synthesize_dataset,
)
from softrod.calibration import calibrate

#: The bundled 1 m arm hanging under its own weight, soft in bending (EI = 1e-3 N m^2):
#: single shooting's growth exponent int sqrt(|n| / EI) ds is about 20, beyond the limit of
#: 12, so statics solves it by collocation.
ARM = "long_soft_arm_1m"


def test_markers_are_read_from_the_collocation_nodes():
    """A marker at the tip is the tip (before, markers were shot from the base unknowns and
    landed centimetres away on such a rod); one at mid-length lies on the solution's
    centreline at its node."""
    design = load_design(ARM)
    p = [[0.0], [3e3]]
    data = synthesize_dataset(design, p, markers=[("1 m", [0, 0]), ("0.5 m", [0, 0])], seed=1)
    np.testing.assert_allclose(data.markers[:, 0], data.tip_position, rtol=0, atol=1e-12)
    for row, pressure in enumerate(p):
        sol = solve_statics(design, pressure)
        mid = sol.position[np.argmin(np.abs(sol.s - 0.5))]
        np.testing.assert_allclose(data.markers[row, 1], mid, rtol=0, atol=1e-12)


def test_the_inverse_of_a_collocation_rod_finds_the_pressure():
    """Before, refused. The tip where the arm hangs at 3 kPa: the inverse from 0 Pa (one
    chamber, a position target a forward solve put there) returns 3 kPa, to 1e-6 of the
    range (the tip is reached to 1e-10 L; 1e-6 of the range moves it by about 1e-7 L, so
    a looser answer could not pass). An InverseProblem then follows the tip along the
    pressure path to 4 kPa with warm starts from each answer's equilibrium: a few
    iterations per call, and each answer is its pressure's forward solve; and from a
    static solution."""
    design = load_design(ARM)
    target = solve_statics(design, [3e3]).tip_position
    inv = solve_inverse(design, target, pressure_bounds=[(0, 2e4)])
    assert inv.reached
    assert inv.pressures[0] == pytest.approx(3e3, abs=1e-6 * 2e4)
    np.testing.assert_allclose(inv.tip_position, target, rtol=0, atol=1e-9)

    problem = InverseProblem(design, pressure_bounds=[(0, 2e4)])
    prev = inv
    for p in np.linspace(3.1e3, 4e3, 10):
        goal = solve_statics(design, [p]).tip_position
        prev = problem.solve(goal, initial=prev)
        assert prev.reached
        assert prev.pressures[0] == pytest.approx(p, abs=1e-6 * 2e4)
        assert prev.iterations <= 4
    np.testing.assert_allclose(
        solve_statics(design, prev.pressures).tip_position, prev.tip_position, atol=1e-9
    )
    # From a static solution: its collocation unknowns start the equilibrium (the core's
    # test checks that they are taken as they are).
    start = solve_statics(design, [3e3])
    goal = solve_statics(design, [3.2e3]).tip_position
    from_static = problem.solve(goal, initial=start)
    assert from_static.reached and from_static.iterations <= 4
    assert from_static.pressures[0] == pytest.approx(3.2e3, abs=1e-6 * 2e4)


def test_a_long_soft_arm_rings_as_its_linearisation_says():
    """Before, refused. The hanging arm with Kelvin-Voigt damping (tau = 0.2 s), stepped
    from 3 to 4 kPa: the ring-down of the nonlinear simulation (dt = 5 ms, BDF-alpha;
    fitted from 8 s on, when the next modes, 25x more damped, have died out) against the
    lowest pole of the linearisation (32 nodes; its modal damping ratio is a first-order
    estimate, the pole is exact). The time step's period error falls as dt^2 (measured
    3.3e-4 at 10 ms, 6.7e-5 at 5 ms): 3e-4 bounds it; the decay rate to 1 % (measured
    4e-4)."""
    design = load_design(ARM).replace({"dynamics.damping_time": "0.2 s"})
    sim = softrod.Simulation(design, [3e3], dt=5e-3, alpha=-0.2)
    traj = sim.run([4e3], 24.0, progress=False)
    f_sim, sigma_sim = ring_down_frequency(traj, 8.0, axis=0)
    poles = linearise(solve_statics(design, [4e3]), nodes=32).poles()
    pole = poles[np.argmin(abs(poles - complex(-sigma_sim, 2 * np.pi * f_sim)))]
    assert abs(pole.imag / (2 * np.pi * f_sim) - 1) < 3e-4, (pole, f_sim)
    assert abs(-pole.real / sigma_sim - 1) < 1e-2, (pole, sigma_sim)


def test_the_jacobian_of_a_collocation_solution_matches_finite_differences():
    """Before, refused. The pressure column and the tip-force columns against central
    differences of full solves (relative step 1e-4: truncation ~1e-8 and the solves'
    tolerance over the step ~1e-6 of a column; 1e-4 leaves a margin of 100, while a
    derivative taken by a shooting pass was off by 90 %)."""
    design = load_design(ARM)
    p0 = 3e3
    sol = solve_statics(design, [p0])
    jac = sol.jacobian()
    np.testing.assert_allclose(jac.position, sol.tip_position, rtol=0, atol=1e-12)
    dp = 1e-4 * p0
    fd = (
        solve_statics(design, [p0 + dp]).tip_position
        - solve_statics(design, [p0 - dp]).tip_position
    ) / (2 * dp)
    col = jac.pressures[:3, 0]
    assert np.linalg.norm(col - fd) < 1e-4 * np.linalg.norm(fd), (col, fd)
    df = 1e-4  # N, against a weight of 0.98 N
    for k in range(3):
        f = np.zeros(3)
        f[k] = df
        fd = (
            solve_statics(design, [p0], tip_force=f).tip_position
            - solve_statics(design, [p0], tip_force=-f).tip_position
        ) / (2 * df)
        col = jac.tip_force[:3, k]
        assert np.linalg.norm(col - fd) < 1e-4 * np.linalg.norm(fd), (k, col, fd)


def test_a_collocation_solution_warm_starts_from_its_own_unknowns():
    """A collocation solution keeps its unknowns z (a shooting solution has none). A solve
    warm-started from it is one Newton step (a cold solve from the straight rod takes
    several) and lands on the same equilibrium: both converge to 1e-10 of the scaled
    unknowns, so the tips agree to a few 1e-10 m (2e-9 m bounds it). Its Jacobian and
    linearisation take z as it is (no step: the Jacobian's point is the solution's tip),
    and equal those of the same solution without z (whose re-solve is cold, so it differs
    within the tolerance: 1e-8 relative bounds its effect on a derivative)."""
    import dataclasses

    design = load_design(ARM)
    sol = solve_statics(design, [3e3])
    assert sol.collocation_unknowns is not None and sol.collocation_unknowns.size > 64
    assert solve_statics("spa_three_chamber_130mm", [1e4] * 3).collocation_unknowns is None
    again = solve_statics(design, [3e3], initial=sol)
    assert again.iterations == 1 < sol.iterations, (again.iterations, sol.iterations)
    np.testing.assert_allclose(again.tip_position, sol.tip_position, rtol=0, atol=2e-9)
    jac = sol.jacobian()
    # (The point is read in dual numbers: equal to the f64 tip up to their rounding.)
    np.testing.assert_allclose(jac.position, sol.tip_position, rtol=0, atol=1e-12)
    cold = dataclasses.replace(sol, collocation_unknowns=None)
    np.testing.assert_allclose(jac.pressures, cold.jacobian().pressures, rtol=1e-8, atol=1e-12)
    warm_sys, cold_sys = linearise(sol, nodes=8), linearise(cold, nodes=8)
    np.testing.assert_allclose(warm_sys.stiffness, cold_sys.stiffness, rtol=1e-8, atol=1e-9)


def test_a_long_soft_arm_calibrates():
    """Before, the fit stopped at its first solve with the collocation refusal. Markers at
    mid-length and at the tip of the hanging arm with c_b = 1.25 (its bending under
    pressure) and c_e = 1.1 (its stretch under its weight), at 0-30 kPa: from c_b = c_e = 1
    the noise-free fit recovers both to the fit's tolerance (1e-6 relative: the data are
    the model's own predictions), and with 10 um of noise within 4 standard errors (a
    seeded draw; |z| > 4 has probability 6e-5)."""
    base = load_design(ARM)
    truth = base.replace({"sections[0].c_b": 1.25, "sections[0].c_e": 1.1})
    pressures = [[0.0], [1e4], [2e4], [3e4]]
    markers = [("0.5 m", [0, 0]), ("1 m", [0, 0])]
    fit = calibrate(base, synthesize_dataset(truth, pressures, markers=markers), ["c_b", "c_e"])
    assert fit.success
    np.testing.assert_allclose(fit.values, [1.25, 1.1], rtol=1e-6)
    noisy = synthesize_dataset(truth, pressures, markers=markers, noise_mm=0.01, seed=2)
    fit = calibrate(base, noisy, ["c_b", "c_e"])
    z = (fit.values - [1.25, 1.1]) / fit.std_errors
    assert np.all(np.abs(z) < 4), z


def test_each_mode_of_a_degenerate_pair_gets_its_own_pole():
    """The arm's two bending planes have nearly equal frequencies: each mode's damped
    frequency is the imaginary part of its own pole (before, both took the nearer one)."""
    design = load_design(ARM).replace({"dynamics.damping_time": "0.2 s"})
    modes = linearise(solve_statics(design, [4e3]), nodes=16).modes(4)
    upper = modes.poles[modes.poles.imag > 0]
    lowest = np.sort(upper[np.argsort(abs(upper))][:4].imag) / (2 * np.pi)
    np.testing.assert_allclose(np.sort(modes.damped_frequency), lowest, rtol=1e-12)
