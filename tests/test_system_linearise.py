"""SystemSolution.linearise(): the linearised dynamics of a parallel continuum robot
(docs/control.md, "Modes of a system"). Its static response K^-1 B against the system's
Jacobian (SystemSolution.jacobian, another code path), mapped rods included; the platform's
inertia in M; its first mode against the ring-down of the nonlinear simulation; the
refusals by name. The core's tests add a one-rod system against the lone rod's
linearisation and two rods holding a platform against closed forms
(crates/softrod-core/tests/suite/linearise_system.rs)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import softrod
from conftest import ring_down_frequency
from softrod import InputError, SolverOptions, load_system, solve_system
from system_cases import LEFT_AT_40_KPA, follower, table_map, two_mapped_rods, walled

OPTS = SolverOptions(tol=1e-13)
P = [[20e3, 5e3, 3e3], [2e3, 15e3, 10e3]]


@pytest.fixture(scope="module")
def platform():
    system = load_system("two_spa_platform")
    return system, solve_system(system, P, options=OPTS)


def _static_response_is_the_jacobian(sol, lin):
    """The platform's rows of K^-1 B are the system Jacobian's pose columns: two exact
    derivatives of one equilibrium, agreeing to the solves' tolerance relative to the
    column (1e-6; both are converged to 1e-13 and go through inverses of ~1e3 condition)."""
    jac = sol.jacobian()
    response = np.linalg.solve(lin.stiffness, lin.input)[lin.platform_rows]
    want = np.hstack([jac.pressures, jac.tensions, jac.platform_force, jac.platform_moment])
    assert response.shape == want.shape
    for c in range(want.shape[1]):
        scale = np.linalg.norm(want[:, c])
        assert np.linalg.norm(response[:, c] - want[:, c]) <= 1e-6 * scale, lin.input_names[c]


def test_static_response_is_the_system_jacobian(platform):
    system, sol = platform
    lin = sol.linearise(nodes=4)
    assert isinstance(lin, softrod.SystemLinearSystem)
    n_nodes = [len(v) for v in lin.nodes]
    assert n_nodes == [4, 4]
    for rod, v in zip(system.rods, lin.nodes, strict=True):
        assert np.all((v > 0) & (v < rod.design.length))
    assert lin.mass.shape == (6 * 8 + 6, 6 * 8 + 6)
    assert lin.input_names[:3] == ("rod0_p0", "rod0_p1", "rod0_p2")
    assert lin.input_names[-6:] == ("F_x", "F_y", "F_z", "M_x", "M_y", "M_z")
    _static_response_is_the_jacobian(sol, lin)
    # The frequency response at w = 0 is the static response, at the platform and at a
    # rod's node: a complex and a real solve of one system, equal to round-off times K's
    # condition number.
    response = np.linalg.solve(lin.stiffness, lin.input)
    rtol = 10 * np.finfo(float).eps * np.linalg.cond(lin.stiffness)
    np.testing.assert_allclose(
        lin.frequency_response(0.0).real, response[lin.platform_rows], rtol=rtol, atol=1e-18
    )
    np.testing.assert_allclose(
        lin.frequency_response(0.0, rod=1, node=2).real,
        response[6 * (4 + 2) : 6 * (4 + 2) + 6],
        rtol=1e-10,
        atol=1e-18,
    )
    modes = lin.modes(5)
    assert modes.shapes.shape == (5, 9, 6)
    assert np.isnan(modes.nodes[-1]) and np.all(np.isfinite(modes.nodes[:-1]))
    assert np.all(np.diff(modes.frequency) >= 0) and modes.frequency[0] > 0
    np.testing.assert_allclose(lin.mass, lin.mass.T, rtol=0, atol=1e-12 * np.abs(lin.mass).max())


def test_mapped_rods_add_their_maps_part():
    """Stiffness-mapped rods: the pressure columns carry d sigma / d p (without it the
    static response would be the Jacobian at fixed sigma, far off)."""
    smap = table_map()
    sol = solve_system(two_mapped_rods(), P, stiffness_maps=[smap, smap], options=OPTS)
    _static_response_is_the_jacobian(sol, sol.linearise(nodes=3))


def test_platform_inertia_enters_the_mass_matrix(platform):
    """M with a platform inertia J minus M without is R J R^T in the platform's rotational
    block and zero elsewhere (J about the centre of mass; the rest of M is unchanged)."""
    _, sol = platform
    j = np.array([[2e-6, 1e-7, 0.0], [1e-7, 3e-6, 0.0], [0.0, 0.0, 1e-6]])
    diff = sol.linearise(nodes=3, platform_inertia=j).mass - sol.linearise(nodes=3).mass
    r = sol.platform_rotation
    want = np.zeros_like(diff)
    want[-3:, -3:] = r @ j @ r.T
    np.testing.assert_allclose(diff, want, rtol=0, atol=1e-12 * np.abs(want).max())
    # Units and principal values are taken as simulate_system takes them.
    principal = sol.linearise(nodes=3, platform_inertia=["2 g*m^2", "3 g*m^2", "1 g*m^2"])
    base = sol.linearise(nodes=3, platform_inertia=np.diag([2e-3, 3e-3, 1e-3]))
    np.testing.assert_allclose(principal.mass, base.mass, rtol=1e-15, atol=0)


def test_first_mode_matches_the_ring_down_of_the_simulation():
    """The platform on its two actuators, lightly damped (tau = 2 ms), released by a 2 mN
    side force on the platform at t = 0: the first mode's damped frequency and decay rate
    from the linearisation at the loaded equilibrium against a fit of the simulated
    ring-down of the platform (dt = 1 ms, 1.5 s, after 0.3 s). As for the lone rod
    (tests/test_control.py): time-step error ~(w dt)^2 ~ 5e-4, both on the designs' nodes;
    0.5 % for the frequency, 2 % for the decay rate."""
    base = load_system("two_spa_platform")
    rods = tuple(
        dataclasses.replace(r, design=r.design.replace({"dynamics.damping_time": "2 ms"}))
        for r in base.rods
    )
    system = dataclasses.replace(base, rods=rods)
    zero = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
    force = [2e-3, 0.0, 0.0]
    sim = softrod.SystemSimulation(system, zero, dt=1e-3, alpha=-0.2)
    traj = sim.run(zero, 1.5, platform_force=force, progress=False)
    ring = dataclasses.make_dataclass("Ring", ["time", "tip_position"])(
        traj.time, traj.platform_position
    )
    f_sim, sigma_sim = ring_down_frequency(ring, 0.3)
    loaded = solve_system(system, zero, platform_force=force, options=OPTS)
    modes = loaded.linearise(nodes=8).modes(3)
    # The mode the side force excites: the lowest with the platform moving along x.
    k = next(i for i in range(3) if abs(modes.shapes[i, -1, 0]) > 0.1)
    f_lin = modes.damped_frequency[k]
    sigma_lin = modes.damping_ratio[k] * modes.omega[k]
    assert abs(f_lin / f_sim - 1) < 5e-3, (f_lin, f_sim)
    assert abs(sigma_lin / sigma_sim - 1) < 2e-2, (sigma_lin, sigma_sim)


def test_refusals_name_the_field(platform):
    _, sol = platform
    for bad in (0, 201, 1.5, "4"):
        with pytest.raises(InputError) as info:
            sol.linearise(nodes=bad)
        assert info.value.field == "nodes"
    for bad in ([[1.0, 2.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], [-1.0, 1.0, 1.0], [1, 2]):
        with pytest.raises(InputError) as info:
            sol.linearise(platform_inertia=bad)
        assert info.value.field.startswith("platform_inertia")
    with pytest.raises(InputError) as info:  # more nodes than a rod has steps
        sol.linearise(nodes=199)
    assert info.value.field == "rods[0].nodes"
    lin = sol.linearise(nodes=3)
    for kwargs, field in (
        ({"rod": 2}, "rod"),
        ({"rod": 0, "node": 3}, "node"),
        ({"rod": 0, "node": 1.0}, "node"),
        ({"node": 2}, "rod"),
    ):
        with pytest.raises(InputError) as info:
            lin.frequency_response(1.0, **kwargs)
        assert info.value.field == field
    with pytest.raises(InputError) as info:
        lin.node_rows(np.zeros(5), 0, 0)
    assert info.value.field == "x"
    with pytest.raises(InputError) as info:
        dataclasses.replace(sol, solved_with=None).linearise()
    assert info.value.field == "solution.solved_with"
    with pytest.raises(InputError) as info:
        dataclasses.replace(sol, converged=False).linearise()
    assert info.value.field == "solution"


def test_obstacles_and_follower_tip_loads_enter_k():
    """A rod pressed on a wall (the penalty's stiffness in K) and a rod with a follower tip
    load (K not symmetric): the platform's rows of K^-1 B are still the system Jacobian
    (docs/control.md, "Follower loads and obstacles")."""
    base = load_system("two_spa_platform")
    walled_sol = solve_system(walled(base), LEFT_AT_40_KPA, options=OPTS)
    assert walled_sol.rods[0].contact.in_contact.any()
    _static_response_is_the_jacobian(walled_sol, walled_sol.linearise(nodes=4))
    turning = solve_system(follower(base), P, options=OPTS)
    lin = turning.linearise(nodes=4)
    _static_response_is_the_jacobian(turning, lin)
    # The follower load turns with the tip: a non-symmetric part of the order of its 0.05 N
    # (per radian), far above the dead system's (the world-frame rotations' terms of its
    # prestress moments; measured 0.05 against 5e-5).
    dead = solve_system(base, P, options=OPTS).linearise(nodes=4).stiffness
    asym = [np.abs(k - k.T).max() for k in (lin.stiffness, dead)]
    assert asym[0] > 10 * asym[1], asym


def test_plot_modes_moves_the_rods_tips_with_the_platform(platform, tmp_path):
    """SystemLinearSystem.plot_modes: per mode and view, each rod's line from its base
    through its nodes ends on the platform's outline (its tip moves with the platform); the
    largest drawn displacement is 15 % of the rods' mean length; refusals by name."""
    import matplotlib.pyplot as plt

    system, sol = platform
    lin = sol.linearise(nodes=4)
    modes = lin.modes(3)
    path = tmp_path / "modes.svg"
    fig = lin.plot_modes(3, path)
    try:
        assert path.read_text().lstrip().startswith("<?xml")
        labels = [t.get_text() for t in fig.legends[0].get_texts()]
        assert labels == ["equilibrium"] + [
            f"mode {k + 1}: {modes.frequency[k]:.3g} Hz" for k in range(3)
        ]
        length = np.mean([r.design.length for r in system.rods]) * 1e3
        # Each rod at rest: its nodes, then its tip (mm).
        rest = [
            np.vstack(
                [
                    np.array([np.interp(v, r.s, r.position[:, c]) for c in range(3)]).T,
                    r.position[-1],
                ]
            )
            * 1e3
            for r, v in zip(sol.rods, lin.nodes, strict=True)
        ]
        moved = np.zeros(3)
        for ax, (a, b) in zip(fig.axes, ((0, 2), (1, 2)), strict=True):
            drawn = [ln for ln in ax.lines if ln.get_marker() == "o"]
            assert len(drawn) == 3 * 3  # two rods and the platform per mode
            for k in range(3):
                lines = [np.column_stack(ln.get_data()) for ln in drawn[3 * k : 3 * k + 3]]
                left, right, outline = lines
                assert len(left) == len(right) == 4 + 2  # base, 4 nodes, tip
                np.testing.assert_allclose(outline, [left[-1], right[-1]], atol=1e-9)
                for line, at_rest in zip((left, right), rest, strict=True):
                    shift = np.abs(line[1:] - at_rest[:, (a, b)]).max()
                    moved[k] = max(moved[k], shift)
        # The largest displacement of each mode is drawn at 15 % of the mean length.
        np.testing.assert_allclose(moved, 0.15 * length, rtol=1e-9)
    finally:
        plt.close(fig)
    with pytest.raises(InputError) as info:
        lin.plot_modes(0)
    assert info.value.field == "count"
    with pytest.raises(InputError) as info:
        lin.plot_modes(2, tmp_path / "modes.nope")
    assert info.value.field == "path"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["modes.svg"]
