"""The statics API: closed forms, batch vs single, warm starts, output shapes, units."""

import numpy as np
import pytest
from softrod import SolverOptions, load_design, solve_statics, solve_statics_batch

pytestmark = pytest.mark.fast  # the whole module runs in seconds

SPA = "spa_three_chamber_130mm"
L = 0.2  # m
EA = 100.0  # N
EI = 0.01  # N m^2


def straight_rod(**section) -> dict:
    """A uniform rod with direct stiffnesses, standing upright (d3 = +z), no gravity."""
    sec = {
        "name": "rod",
        "length": f"{L * 1e3} mm",
        "mass": "10 g",
        "EA": f"{EA} N",
        "GA": "50 N",
        "EI": f"{EI} N*m^2",
        "GJ": "0.008 N*m^2",
    }
    sec.update(section)
    return {
        "design": {"name": "uniform_rod", "citation": "closed-form check"},
        "mounting": {"orientation": "upright", "gravity": "0 m/s^2"},
        "sections": [sec],
    }


def _arc_error(angle: float, steps: int):
    """Solve the pure-bending rod; return (solution, radius, tip error in m)."""
    rod = load_design(straight_rod(steps=steps))
    moment = EI * angle / L  # N m about +y: the rod bends in the x-z plane through `angle`
    # A dead tip moment is not conservative in 3-D, and with GJ < EI the stability test
    # flags arcs beyond about 2.7 rad (lateral-torsional; docs/model.md, "Validity and
    # stability"): this test checks the shape only.
    sol = solve_statics(rod, [], tip_moment=[0.0, moment, 0.0], on_unstable="ignore")
    radius = EI / moment
    expected_tip = [radius * (1 - np.cos(angle)), 0.0, radius * np.sin(angle)]
    return sol, radius, float(np.abs(sol.tip_position - expected_tip).max())


@pytest.mark.parametrize("angle", [0.5, 1.0, 3.0])
def test_tip_moment_bends_into_circle_of_radius_ei_over_m(angle):
    steps = 16
    sol, radius, tip_error = _arc_error(angle, steps)
    assert sol.design.n_channels == 0
    # RK4's global error on this arc is C L (angle/steps)^4 with C = 0.007-0.008 (measured
    # for angles 0.25-3 rad); allow C = 0.02. That is 2e-10 m at 0.5 rad, 5e-6 m at 3 rad.
    tol = 0.02 * L * (angle / steps) ** 4
    assert tip_error < tol
    centre = np.array([radius, 0.0, 0.0])
    np.testing.assert_allclose(
        np.linalg.norm(sol.position - centre, axis=1), radius, rtol=0, atol=tol
    )
    # Pure bending: the internal moment is the tip moment everywhere, no force (1e-12:
    # round-off of quantities of order 1e-2 N m).
    moment = EI / radius
    np.testing.assert_allclose(
        sol.moment, np.tile([0.0, moment, 0.0], (len(sol.s), 1)), rtol=0, atol=1e-12
    )
    np.testing.assert_allclose(sol.force, 0.0, atol=1e-12)


def test_arc_error_is_fourth_order():
    # Halving the step divides RK4's error by 2^4 = 16; accept 12-20 (higher-order terms).
    ratio = _arc_error(2.0, 16)[2] / _arc_error(2.0, 32)[2]
    assert 12 < ratio < 20


@pytest.mark.parametrize("force", [3.0, -3.0])
def test_axial_force_stretches_by_fl_over_ea(force):
    rod = load_design(straight_rod())
    # -3 N exceeds the rod's Euler load pi^2 EI / (4 L^2) = 0.62 N: the straight solution is
    # then an unstable equilibrium (flagged); this test checks the axial stretch only.
    sol = solve_statics(rod, [], tip_force=[0.0, 0.0, force], on_unstable="ignore")
    assert sol.stable == (force > 0)
    # The stretch is uniform and the ODE linear in s, which RK4 integrates exactly: only
    # round-off remains (1e-14 m against a 6 mm change).
    np.testing.assert_allclose(sol.tip_position, [0.0, 0.0, L + force * L / EA], rtol=0, atol=1e-14)
    np.testing.assert_allclose(sol.v[:, 2], 1.0 + force / EA, rtol=1e-14)


def _grid(n: int, top: float = 70e3) -> np.ndarray:
    g = np.linspace(0.0, top, n)
    return np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)


@pytest.mark.parametrize("threads", [1, 2, 4])
def test_batch_equals_single(threads):
    d = load_design(SPA)
    pressures = _grid(4)
    batch = solve_statics_batch(d, pressures, threads=threads)
    single = [solve_statics(d, p) for p in pressures]
    assert batch.converged.all() and batch.stable.all()
    # Every row is solved cold, exactly as the single solve: bitwise equal, whatever the
    # thread count; and a sub-batch (other chunking) gives the same rows.
    np.testing.assert_array_equal(batch.tip_position, [s.tip_position for s in single])
    np.testing.assert_array_equal(batch.tip_rotation, [s.tip_rotation for s in single])
    np.testing.assert_array_equal(batch.x, [s.shooting_unknowns for s in single])
    part = solve_statics_batch(d, pressures[5:], threads=threads)
    np.testing.assert_array_equal(part.tip_position, batch.tip_position[5:])


def test_warm_start_same_answer_in_no_more_iterations():
    d = load_design(SPA)
    for p in ([35e3, 0.0, 0.0], [70e3, 70e3, 0.0], [10e3, 50e3, 20e3]):
        cold = solve_statics(d, p)
        near = solve_statics(d, [0.9 * x for x in p])
        warm = solve_statics(d, p, initial=near)
        assert warm.iterations <= cold.iterations
        # 1e-9 m: same tolerance argument as batch vs single.
        np.testing.assert_allclose(warm.position, cold.position, rtol=0, atol=1e-9)
        again = solve_statics(d, p, initial=cold)  # starting at the answer
        assert again.iterations <= 1
        np.testing.assert_allclose(again.position, cold.position, rtol=0, atol=1e-9)


def test_output_shapes_and_orthonormal_rotations():
    d = load_design(SPA)
    sol = solve_statics(d, [40e3, 0.0, 20e3])
    n = sum(sec["steps"] for sec in d.sections()) + 1  # nodes of every RK4 step plus the base
    assert sol.s.shape == (n,) and sol.section.shape == (n,)
    for name in ("position", "force", "moment", "v", "u"):
        assert getattr(sol, name).shape == (n, 3), name
    assert sol.rotation.shape == (n, 3, 3)
    assert sol.tip_position.shape == (3,) and sol.tip_rotation.shape == (3, 3)
    assert sol.pressures.shape == (3,)
    assert sol.s[0] == 0.0 and np.all(np.diff(sol.s) > 0)
    assert sol.s[-1] == pytest.approx(d.length, rel=1e-12)  # 1e-12: sums of step lengths
    assert np.array_equal(np.unique(sol.section), np.arange(len(d.sections())))
    np.testing.assert_array_equal(sol.tip_position, sol.position[-1])
    np.testing.assert_array_equal(sol.position[0], [0.0, 0.0, 0.0])  # base at the origin

    m = 5
    batch = solve_statics_batch(d, _grid(2)[:m])
    assert batch.pressures.shape == (m, 3)
    assert batch.tip_position.shape == (m, 3) and batch.tip_rotation.shape == (m, 3, 3)
    assert batch.base_force.shape == (m, 3) and batch.base_moment.shape == (m, 3)
    assert batch.converged.shape == (m,) and batch.converged.dtype == bool
    assert batch.iterations.shape == (m,) and batch.residual.shape == (m,)


def _orthonormality_error(rotations: np.ndarray) -> float:
    rtr = np.einsum("...ji,...jk->...ik", rotations, rotations)
    return float(np.abs(rtr - np.eye(3)).max())


def test_rotations_orthonormal_at_rest():
    # A straight hanging rod has u = 0: every RK4 stage is exact and R stays exactly
    # orthonormal (1e-12: round-off only).
    sol = solve_statics(SPA, [0.0, 0.0, 0.0])
    assert _orthonormality_error(sol.rotation) < 1e-12


def test_rotations_orthonormal_to_1e9():
    # 1e-9: the documented accuracy of the rotation output; with a rotation-preserving
    # integrator only round-off (~1e-15 per step) would remain.
    d = load_design(SPA)
    sol = solve_statics(d, [40e3, 0.0, 20e3])
    assert _orthonormality_error(sol.rotation) < 1e-9
    np.testing.assert_allclose(np.linalg.det(sol.rotation), 1.0, rtol=0, atol=1e-9)
    batch = solve_statics_batch(d, _grid(3))
    assert _orthonormality_error(batch.tip_rotation) < 1e-9
    horizontal = solve_statics("spa_three_chamber_134mm_horizontal", [0.0, 0.0, 0.0])
    assert _orthonormality_error(horizontal.rotation) < 1e-9


def test_pressures_and_tip_force_as_strings_with_units():
    d = load_design(SPA)
    ref = solve_statics(d, [30e3, 0.0, 0.0], tip_force=[0.0, 0.0, -1.0])
    for pressures, force in (
        (["30 kPa", 0, 0], ["0 N", "0 N", "-1 N"]),
        (["0.3 bar", "0 Pa", 0.0], [0, "0 mN", "-1000 mN"]),
    ):
        sol = solve_statics(d, pressures, tip_force=force)
        # 1e-12 m: "0.3 bar" and "-1000 mN" convert to SI with at most an ulp of error.
        np.testing.assert_allclose(sol.position, ref.position, rtol=0, atol=1e-12)
    unloaded = solve_statics(d, [30e3, 0.0, 0.0])
    assert ref.tip_position[2] < unloaded.tip_position[2]  # a downward force pulls it down


def test_tip_force_replaces_the_designs_force():
    d = load_design("modular_two_module_1N_tip")  # the design carries a (0, 0, -1 N) force
    default = solve_statics(d, [0.0, 0.0, 0.0])
    explicit = solve_statics(d, [0.0, 0.0, 0.0], tip_force="0 N,0 N,-1 N".split(","))
    np.testing.assert_array_equal(default.position, explicit.position)
    none = solve_statics(d, [0.0, 0.0, 0.0], tip_force=[0, 0, 0])
    # A 1 N pull on EA = 200 N over ~90 mm of elastic length stretches ~0.45 mm.
    assert default.tip_position[2] - none.tip_position[2] == pytest.approx(-0.448e-3, rel=0.02)


def test_solver_options_are_respected():
    d = load_design(SPA)
    loose = solve_statics(d, [70e3, 0.0, 0.0], options=SolverOptions(tol=1e-6))
    tight = solve_statics(d, [70e3, 0.0, 0.0], options=SolverOptions(tol=1e-12))
    assert loose.residual <= 1e-6 and tight.residual <= 1e-12
    assert loose.iterations <= tight.iterations
