"""Pinned and clamped tips and systems of rods sharing a platform (docs/model.md, "End
constraints" and "Systems of rods"): a clamped-clamped rod under a large line load and a
two-rod parallel mechanism against scipy's collocation BVP solver, reactions that balance
the loads, the design-file keys, bad inputs, the bundled system, and hypothesis on the new
entry points. (The small-load clamped-clamped beam against the linear Timoshenko solution,
the Euler loads and the exact Jacobians are in crates/softrod-core/tests/suite/end_constraints.rs.)
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import softrod
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from softrod import (
    DesignError,
    InputError,
    Platform,
    SolverOptions,
    System,
    SystemRod,
    TipConstraint,
    load_design,
    solve_statics,
    solve_system,
)

pytestmark = pytest.mark.fast

L = 0.1  # m
EA = 1e4  # N
GA = 5e3  # N
EI = 0.01  # N m^2
TIGHT = SolverOptions(tol=1e-12)


def rod(base_x: float = 0.0, q: float = 0.0, steps: int = 48) -> dict:
    """An upright rod (d3 = +z, d1 = +x) with direct stiffnesses, no gravity, and a line
    load q (N/m) along +x."""
    doc = {
        "design": {"name": "constrained_rod", "citation": "closed-form check"},
        "mounting": {
            "orientation": "upright",
            "gravity": "0 m/s^2",
            "base_position": [f"{base_x} m", "0 m", "0 m"],
        },
        "sections": [
            {
                "name": "rod",
                "length": f"{L} m",
                "mass": "10 g",
                "outer_radius": "5 mm",
                "EA": f"{EA} N",
                "GA": f"{GA} N",
                "EI": f"{EI} N*m^2",
                "GJ": f"{EI} N*m^2",
                "steps": steps,
            }
        ],
    }
    if q:
        doc["loads"] = [{"section": "rod", "force_per_length": [f"{q} N/m", "0 N/m", "0 N/m"]}]
    return doc


def ry(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def planar_rhs(q: float):
    """The planar Cosserat rod in the x-z plane (theta: angle of d3 from +z towards +x,
    R = Ry(theta), bending about d2 = +y), state (x, z, theta, n_x, n_z, m_y), linear law
    v1 = n.d1 / GA, v3 = 1 + n.d3 / EA, theta' = m_y / EI; balance n' = -f,
    m_y' = x' n_z - z' n_x. Written from the equations, independently of softrod."""

    def rhs(s, y):
        x, z, th, nx, nz, my = y
        c, sn = np.cos(th), np.sin(th)
        d1 = (c, -sn)  # (x, z) components
        d3 = (sn, c)
        v1 = (nx * d1[0] + nz * d1[1]) / GA
        v3 = 1.0 + (nx * d3[0] + nz * d3[1]) / EA
        dx = v1 * d1[0] + v3 * d3[0]
        dz = v1 * d1[1] + v3 * d3[1]
        return np.vstack([dx, dz, my / EI, -q * np.ones_like(x), 0 * x, dx * nz - dz * nx])

    return rhs


def test_clamped_clamped_rod_under_a_large_load_matches_a_bvp_solver():
    """A rod clamped at both ends (the tip moved and turned by 0.6 rad) under a sideways
    line load with q L^3 / EI = 5 against scipy's collocation BVP solver on the planar
    equations: softrod converges to the BVP's solution at fourth order in the steps.
    Clamped-clamped rods under large loads have several equilibria; the BVP starts from
    softrod's shape, so it confirms that shape is an exact solution of the independent
    equations (a BVP from the straight rod finds another one)."""
    from scipy.integrate import solve_bvp

    q = 50.0  # N/m
    tip = np.array([0.03, 0.0, 0.085])
    theta_t = 0.6
    errors, reaction_errors = [], []
    for steps in (48, 96):
        sol = solve_statics(
            load_design(rod(q=q, steps=steps)),
            [],
            tip_constraint=TipConstraint.clamped(tip, [0.0, theta_t, 0.0]),
            options=TIGHT,
        )
        assert sol.tip_constraint == "clamped" and sol.stable is True

        def bc(y0, y1):
            return np.array([y0[0], y0[1], y0[2], y1[0] - tip[0], y1[1] - tip[2], y1[2] - theta_t])

        theta = np.arctan2(sol.rotation[:, 0, 2], sol.rotation[:, 2, 2])
        mine = np.vstack(
            [
                sol.position[:, 0],
                sol.position[:, 2],
                theta,
                sol.force[:, 0],
                sol.force[:, 2],
                sol.moment[:, 1],
            ]
        )
        mesh = np.linspace(0, L, 201)
        guess = np.array([np.interp(mesh, sol.s, row) for row in mine])
        ref = solve_bvp(planar_rhs(q), bc, mesh, guess, tol=1e-9, max_nodes=100_000)
        assert ref.success, ref.message
        y = ref.sol(sol.s)
        errors.append(np.abs(y[:2] - mine[:2]).max())
        # Reactions: the tip clamp applies n(L), m(L) (no tip loads here).
        reaction = np.array([*sol.tip_reaction_force[[0, 2]], sol.tip_reaction_moment[1] / L])
        reaction_errors.append(np.abs(reaction - np.array([*y[3:5, -1], y[5, -1] / L])).max())
        # Reactions balance the load to 1e-9: -n(0) + q L e_x + F_r = 0.
        total = -sol.force[0] + np.array([q * L, 0.0, 0.0]) + sol.tip_reaction_force
        assert np.abs(total).max() < 1e-9 * q * L
    # RK4: the error falls 16-fold per halving of the step (measured 2.0e-7 m at 48 steps,
    # 9.5e-9 m at 96; reactions 1.8e-3 N and 1.1e-4 N of 72 N; the BVP's own error at tol
    # 1e-9 is far below). Fourth order in both, and at 96 steps within 2e-7 of L and 5e-6
    # of the 72 N reaction: what the order predicts, with a factor of two to spare.
    for e in (errors, reaction_errors):
        assert 12 < e[0] / e[1] < 24, e
    assert errors[1] < 2e-7 * L, errors
    assert reaction_errors[1] < 5e-6 * 72.0, reaction_errors


def test_two_rod_parallel_mechanism_matches_a_bvp_solver():
    """Two upright rods 40 mm apart clamped to a platform on their tips, the platform
    pushed sideways, down and twisted in the x-z plane: the coupled planar BVP (two rods,
    the platform pose as three unknown parameters, the platform's balance as boundary
    conditions) against solve_system."""
    from scipy.integrate import solve_bvp

    half = 0.02
    force = np.array([1.5, 0.0, -2.0])
    my = 0.05
    rods = tuple(
        SystemRod(load_design(rod(base_x=bx)), attachment=np.array([bx, 0.0, 0.0]))
        for bx in (-half, half)
    )
    system = System("two_rods", rods, Platform(position=np.array([0.0, 0.0, L])))
    sol = solve_system(system, platform_force=force, platform_moment=[0.0, my, 0.0], options=TIGHT)
    assert sol.converged and sol.stable is True  # a stiff pair, pushed sideways
    rhs1 = planar_rhs(0.0)
    offsets = (-half, half)

    def rhs(s, y, p):
        return np.vstack([rhs1(s, y[:6]), rhs1(s, y[6:])])

    def bc(ya, yb, p):
        px, pz, th = p
        out = []
        for i, o in enumerate(offsets):
            a, b = ya[6 * i : 6 * i + 6], yb[6 * i : 6 * i + 6]
            out += [a[0] - o, a[1], a[2]]
            # tip = p + Ry(th) (o, 0, 0)
            out += [b[0] - (px + math.cos(th) * o), b[1] - (pz - math.sin(th) * o), b[2] - th]
        fx, fz, m = force[0], force[2], my
        for i in range(len(offsets)):
            b = yb[6 * i : 6 * i + 6]
            lx, lz = b[0] - px, b[1] - pz
            fx -= b[3]
            fz -= b[4]
            m -= b[5] + (lz * b[3] - lx * b[4])
        return np.array(out + [fx, fz, m])

    s = np.linspace(0, L, 101)
    guess = np.zeros((12, s.size))
    guess[0] = -half
    guess[6] = half
    guess[1] = guess[7] = s
    ref = solve_bvp(rhs, bc, s, guess, p=[0.0, L, 0.0], tol=1e-10, max_nodes=100_000)
    assert ref.success, ref.message
    px, pz, th = ref.p
    # As above: RK4 at 48 steps, tolerances 1e-10 and 1e-12: 1e-9 m and 1e-8 rad.
    np.testing.assert_allclose(sol.platform_position, [px, 0.0, pz], atol=1e-9)
    np.testing.assert_allclose(sol.platform_rotation, ry(th), atol=1e-8)
    for r, i in zip(sol.rods, (0, 6), strict=True):
        np.testing.assert_allclose(
            r.tip_reaction_force[[0, 2]],
            ref.sol(L)[[i + 3, i + 4]],
            atol=1e-7 * np.abs(force).max(),
        )
    # The platform's balance with the rods' tip reactions, to 1e-9 of the load.
    p = sol.platform_position
    f = force.copy()
    m = np.array([0.0, my, 0.0])
    for r in sol.rods:
        f -= r.tip_reaction_force
        m -= r.tip_reaction_moment + np.cross(r.tip_position - p, r.tip_reaction_force)
    assert np.abs(f).max() < 1e-9 * np.abs(force).max()
    assert np.abs(m).max() < 1e-9 * (my + L * np.abs(force).max())
    # A warm start from the solution converges at once.
    again = solve_system(
        system, platform_force=force, platform_moment=[0.0, my, 0.0], options=TIGHT, initial=sol
    )
    assert again.load_steps == 1
    np.testing.assert_allclose(again.platform_position, sol.platform_position, atol=1e-12)


def test_pinned_tip_turns_freely_and_the_reaction_holds_the_tip_load():
    d = load_design(rod())
    free = solve_statics(d, [], tip_force=[0.5, 0.0, 0.0], options=TIGHT)
    pinned = solve_statics(
        d,
        [],
        tip_force=[0.5, 0.0, 0.0],
        tip_constraint=TipConstraint.pinned(free.tip_position),
        options=TIGHT,
    )
    # Pinned where the free tip went: nothing to react.
    assert np.abs(pinned.tip_reaction_force).max() < 1e-9
    np.testing.assert_allclose(pinned.tip_position, free.tip_position, atol=1e-12)
    np.testing.assert_array_equal(pinned.tip_reaction_moment, np.zeros(3))
    # Pinned at the unloaded tip: the pin takes the whole tip load, the rod stays straight.
    held = solve_statics(
        d,
        [],
        tip_force=[0.5, 0.0, 0.0],
        tip_constraint={"type": "pinned", "position": ["0 mm", "0 mm", "100 mm"]},
        options=TIGHT,
    )
    np.testing.assert_allclose(held.tip_reaction_force, [-0.5, 0.0, 0.0], atol=1e-9)
    assert np.abs(held.position[:, 0]).max() < 1e-12


def test_design_file_keys_set_the_constraint():
    doc = rod(q=10.0)
    doc["tip"] = {
        "constraint": "clamped",
        "position": ["0 mm", "0 mm", "100 mm"],
        "orientation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
    }
    d = load_design(doc)
    assert d.tip_constraint == TipConstraint.clamped([0, 0, L], [0, 0, 0])
    sol = solve_statics(d, [], options=TIGHT)
    assert sol.tip_constraint == "clamped"
    # Symmetric clamped-clamped beam under a uniform load: each end takes half of it.
    np.testing.assert_allclose(sol.tip_reaction_force[0], -0.5, atol=1e-9)
    # An explicit argument replaces the file's.
    free = solve_statics(d, [], tip_constraint="free", options=TIGHT)
    assert free.tip_constraint == "free" and free.stable is True


@pytest.mark.parametrize(
    "tip, field, words",
    [
        ({"constraint": "welded"}, "tip.constraint", "must be one of"),
        ({"constraint": "pinned"}, "tip.position", "needs the tip position"),
        (
            {"constraint": "clamped", "position": [0, 0, "100 mm"]},
            "tip.orientation",
            "needs the tip orientation",
        ),
        (
            {
                "constraint": "clamped",
                "position": ["0 m", "0 m", "0.1 m"],
                "orientation": [[1, 0, 0], [0, 1, 0.1], [0, 0, 1]],
            },
            "tip.orientation",
            "must be a rotation matrix",
        ),
        (
            {
                "constraint": "pinned",
                "position": ["0 m", "0 m", "0.1 m"],
                "orientation": ["0 deg", "0 deg", "0 deg"],
            },
            "tip.orientation",
            "turns freely",
        ),
        ({"position": ["0 m", "0 m", "0.1 m"]}, "tip.position", "only used with"),
        (
            {
                "constraint": "clamped",
                "position": ["0 m", "0 m", "0.1 kg"],
                "orientation": ["0 deg", "0 deg", "0 deg"],
            },
            "tip.position[2]",
            "",
        ),
    ],
)
def test_bad_design_file_constraints_name_the_field(tip, field, words):
    doc = rod()
    doc["tip"] = tip
    with pytest.raises(DesignError) as exc:
        load_design(doc)
    assert exc.value.field == field
    assert words in str(exc.value)


@pytest.mark.parametrize(
    "make, field",
    [
        (lambda: TipConstraint("welded"), "tip_constraint.type"),
        (lambda: TipConstraint("pinned"), "tip_constraint.position"),
        (lambda: TipConstraint("clamped", position=[0, 0, 0.1]), "tip_constraint.orientation"),
        (
            lambda: TipConstraint.clamped([0, 0, 0.1], np.diag([1.0, 1.0, -1.0])),
            "tip_constraint.orientation",
        ),
        (lambda: TipConstraint.pinned([0, float("nan"), 0.1]), "tip_constraint.position[1]"),
        (lambda: TipConstraint.pinned([0, 0]), "tip_constraint.position"),
        (lambda: softrod.constraints.coerce({"type": "pinned", "where": 1}), "tip_constraint"),
    ],
)
def test_bad_constraints_name_the_field(make, field):
    with pytest.raises(InputError) as exc:
        make()
    assert exc.value.field == field


def test_pcc_model_refuses_a_constrained_tip():
    with pytest.raises(InputError) as exc:
        solve_statics(
            "stiff_flop_pcc",
            [0.0] * 6,
            model="pcc",
            tip_constraint=TipConstraint.pinned([0, 0, 0.11]),
        )
    assert exc.value.field == "tip_constraint"


FREE_TIP_ENTRIES = {
    # calibrate and synthesize_dataset take a held tip in statics
    # (tests/test_calibration_held_tip.py); the PCC fit does not.
    "calibrate(model='pcc')": lambda d, ds: softrod.calibrate(d, ds, ["k_L"], model="pcc"),
    "identify_stiffness": lambda d, ds: softrod.identify_stiffness(d, ds),
    "compare_hybrid": lambda d, ds: softrod.compare_hybrid(d, ds, None),
    "simulate(model='pcc')": lambda d, ds: softrod.simulate(d, [0.0, 0.0, 0.0], 0.01, model="pcc"),
    "solve_inverse": lambda d, ds: softrod.solve_inverse(d, "0,5,-130 mm"),
    "workspace": lambda d, ds: softrod.workspace(d),
    "model='pcc'": lambda d, ds: solve_statics(d, [0.0, 0.0, 0.0], model="pcc"),
}
# StaticSolution.jacobian takes a held tip (tests/test_jacobian_six_unknowns.py), linearise a
# clamped or pinned one (tests/test_linearise_held.py).


@pytest.mark.parametrize("entry", sorted(FREE_TIP_ENTRIES))
def test_free_tip_entries_refuse_a_constrained_design_by_name(entry):
    """Every entry point that solves a free tip only refuses a design whose file pins the
    tip, naming itself and the field, before any work: never a free-tip answer to it."""
    base = load_design("spa_three_chamber_130mm")
    pinned = base.replace(
        {"tip": {"constraint": "pinned", "position": ["0 mm", "10 mm", "-125 mm"]}}
    )
    # A valid two-row dataset of the free design (the guard must fire on the design alone).
    data = softrod.synthesize_dataset(base, [[1e4, 0, 0], [0, 1e4, 0]], seed=0)
    with pytest.raises(InputError) as exc:
        FREE_TIP_ENTRIES[entry](pinned, data)
    assert exc.value.field == "tip_constraint"
    assert exc.value.value == "pinned"
    assert f"{entry} solves a free tip only" in str(exc.value)


def test_bundled_two_rod_system_solves_and_balances():
    assert "two_spa_platform" in softrod.bundled_systems()
    system = softrod.load_system("two_spa_platform")
    assert len(system.rods) == 2 and system.platform.mass == pytest.approx(0.02)
    sol = solve_system(system, [[40e3, 0.0, 0.0], [0.0, 0.0, 0.0]])
    g = system.rods[0].design.spec["mounting"]["gravity"]
    weight = system.platform.mass * np.array(g)
    f = weight.copy()
    for r in sol.rods:
        f -= r.tip_reaction_force
    assert np.abs(f).max() < 1e-9
    # Pressurising the left actuator (which lengthens it) tilts the platform.
    tilt = math.degrees(math.acos(np.clip(sol.platform_rotation[2, 2], -1, 1)))
    assert tilt > 1.0


def test_a_system_cannot_be_changed_through_its_arrays_or_rod_list():
    system = softrod.load_system("two_spa_platform")
    for array in (
        system.platform.position,
        system.platform.rotation,
        system.platform.force,
        system.rods[0].attachment,
        system.rods[0].attachment_rotation,
    ):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 1.0
    # Arrays and lists the caller keeps are copied: editing them later changes nothing.
    position = np.array([0.0, 0.0, 0.1])
    platform = Platform(position=position)
    position[2] = 5.0
    assert platform.position[2] == 0.1
    rods = list(system.rods)
    built = System("copy", rods, platform)
    rods.pop()
    assert isinstance(built.rods, tuple) and len(built.rods) == 2


def test_system_pressures_as_an_array_of_rows_equal_the_list():
    # simulate_system takes an (n_rods, n_channels) array; solve_system refused it with
    # "must be a list of 2 entries, one per rod" although it had 2 rows.
    system = softrod.load_system("two_spa_platform")
    rows = [[30e3, 0.0, 10e3], [0.0, 20e3, 5e3]]
    a = solve_system(system, np.array(rows))
    b = solve_system(system, rows)
    assert np.array_equal(a.platform_position, b.platform_position)
    with pytest.raises(softrod.InputError, match="one per rod"):
        solve_system(system, np.zeros((3, 3)))


@pytest.mark.parametrize(
    "text, field",
    [
        ("[platform]\nmass = '1 g'\n", "platform.position"),
        (
            "[platform]\nposition = [0, 0, 0]\n[[rods]]\ndesign = 'nope_design'\n"
            "attachment = [0, 0, 0]\n",
            "design",
        ),
        ("[platform]\nposition = [0, 0, 0]\nwobble = 1\n", "platform.wobble"),
        ("[platform]\nposition = [0, 0, 0]\n", "rods"),
        (
            "[platform]\nposition = [0, 0, 0]\n[[rods]]\ndesign = 'spa_three_chamber_130mm'\n",
            "rods[0].attachment",
        ),
    ],
)
def test_bad_system_files_name_the_field(tmp_path, text, field):
    path = tmp_path / "s.toml"
    path.write_text('units = "SI"\n' + text)
    with pytest.raises(DesignError) as exc:
        softrod.load_system(path)
    assert exc.value.field == field


@pytest.mark.parametrize("value", [None, 3, 1.5, ["two_spa_platform"], b"two_spa_platform"])
def test_a_system_that_is_neither_a_system_nor_a_name_is_named(value):
    # Every entry taking a system (solve, simulate, sensitivities) goes through load_system.
    for call in (
        lambda: softrod.load_system(value),
        lambda: solve_system(value, [[0, 0, 0]] * 2),
        lambda: softrod.simulate_system(value, [[0, 0, 0]] * 2, 0.004),
    ):
        with pytest.raises(DesignError) as exc:
            call()
        assert exc.value.field == "system"


def test_bad_system_figure_arguments_are_named(tmp_path):
    sol = solve_system("two_spa_platform", [[10e3, 0, 0], [0, 0, 0]])
    for kwargs, field in (
        ({"path": True}, "path"),
        ({"path": 3}, "path"),
        ({"labels": 3}, "labels"),
        ({"labels": ["a", "b"]}, "labels"),
        ({"labels": {"a": 1}}, "labels"),
    ):
        with pytest.raises(softrod.InputError) as exc:
            softrod.plot_system(sol, **kwargs)
        assert exc.value.field == field


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    dx=st.floats(-0.01, 0.01),
    # Not much stretch: a tension T makes single shooting's sensitivity grow like
    # exp(L sqrt(T / EI)) (docs/model.md, "Collocation"); 0.5 mm is T ~ 50 N, exp(7).
    dz=st.floats(-0.01, 0.0005),
    angle=st.floats(-0.4, 0.4),
    kind=st.sampled_from(["pinned", "clamped"]),
)
def test_constrained_solves_hold_the_pose_and_balance(dx, dz, angle, kind):
    """Any reachable pose near the unloaded tip: the tip is where it was told, and the
    reactions balance the line load to 1e-9 (the load is constant, so n' = -f is integrated
    exactly). Shortening the rod by up to 10 % is far beyond its Euler load (0.4 mm of
    clamped-clamped shortening), so the far corners buckle into S shapes whose curvature the
    steps may not resolve: there the answer must be the documented error, never a shape."""
    q = 20.0
    d = load_design(rod(q=q, steps=48))
    pos = [dx, 0.0, L + dz]
    c = (
        TipConstraint.pinned(pos)
        if kind == "pinned"
        else TipConstraint.clamped(pos, [0.0, angle, 0.0])
    )
    try:
        sol = solve_statics(d, [], tip_constraint=c, options=TIGHT, on_unstable="ignore")
    except softrod.InvalidStateError as exc:
        assert exc.rule == "rotation" and "steps are too coarse" in str(exc), exc
        return
    # The residual tolerance 1e-12 is relative to the unknowns (base force / (EI / L^2),
    # up to ~400 here): 1e-9 of L and 1e-9 rad leave a factor of two.
    np.testing.assert_allclose(sol.tip_position, pos, atol=1e-9 * L)
    if kind == "clamped":
        np.testing.assert_allclose(sol.tip_rotation, ry(angle), atol=1e-9)
    total = -sol.force[0] + np.array([q * L, 0.0, 0.0]) + sol.tip_reaction_force
    assert np.abs(total).max() < 1e-9 * q * L
    # Dead loads: the stability of a held tip is assessed (shortened far enough, the rod may
    # be on an unstable branch, which on_unstable="ignore" lets through).
    assert sol.stable in (True, False)


@pytest.mark.parametrize("kind, kl", [("clamped", 2 * math.pi), ("pinned", 4.493409457909064)])
def test_column_held_at_both_ends_is_flagged_beyond_its_euler_load(kind, kl):
    """An upright column held at both ends and pressed along its axis (the tip prescribed at
    z = L (1 - P/EA), the stretch of the linear law under P) stays straight by symmetry. Its
    Euler load is P_E = (kL)^2 EI / L^2 with kL = 2 pi clamped-clamped and tan kL = kL
    (4.4934) clamped-pinned; shear lowers it by about P/GA (0.8 % here). At 0.8 P_E the
    straight column is stable; at 1.5 P_E it is unstable, and the policies apply as for a
    free tip: a StabilityWarning by default, InvalidStateError (rule "stability") with
    on_unstable="raise"."""
    d = load_design(rod(steps=48))
    pe = kl**2 * EI / L**2

    def held(ratio):
        pos = [0.0, 0.0, L * (1.0 - ratio * pe / EA)]
        if kind == "pinned":
            return TipConstraint.pinned(pos)
        return TipConstraint.clamped(pos, [0.0, 0.0, 0.0])

    below = solve_statics(d, [], tip_constraint=held(0.8), options=TIGHT)
    assert below.stable is True
    with pytest.warns(softrod.StabilityWarning):
        above = solve_statics(d, [], tip_constraint=held(1.5), options=TIGHT)
    assert above.stable is False
    assert np.abs(above.position[:, :2]).max() < 1e-9 * L
    np.testing.assert_allclose(-above.force[0, 2], 1.5 * pe, rtol=1e-6)
    with pytest.raises(softrod.InvalidStateError) as exc:
        solve_statics(d, [], tip_constraint=held(1.5), options=TIGHT, on_unstable="raise")
    assert exc.value.rule == "stability"


@settings(max_examples=25, deadline=None)
@given(
    st.one_of(
        st.text(max_size=8),
        st.lists(st.one_of(st.floats(allow_nan=True), st.text(max_size=5)), max_size=4),
        st.dictionaries(
            st.sampled_from(["type", "position", "orientation", "x"]),
            st.one_of(st.text(max_size=6), st.lists(st.floats(), max_size=4)),
        ),
    )
)
def test_any_tip_constraint_value_is_accepted_or_refused_clearly(value):
    try:
        c = softrod.constraints.coerce(value)
    except InputError as exc:
        assert exc.field.startswith("tip_constraint")
    else:
        assert c.kind in ("free", "pinned", "clamped")


def test_cli_solve_reports_the_tip_reaction(run, tmp_path):
    """`softrod solve` on a design file with a clamped tip shows the constraint's reaction
    force and moment (table and JSON, the API's numbers) and no empty pressure row."""
    import json

    doc = rod(q=10.0)
    doc["tip"] = {
        "constraint": "clamped",
        "position": ["2 mm", "0 mm", "100 mm"],  # sideways, not shortened: stable
        "orientation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
    }
    path = tmp_path / "clamped.toml"
    load_design(doc).save(path)
    result = run("solve", path, "--json")
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    api = solve_statics(load_design(path), [])
    assert data["tip_constraint"] == "clamped"
    np.testing.assert_array_equal(data["tip_reaction_force_N"], api.tip_reaction_force)
    np.testing.assert_array_equal(data["tip_reaction_moment_Nm"], api.tip_reaction_moment)
    table = run("solve", path).output
    assert "tip reaction force (clamped)" in table and "tip reaction moment" in table
    assert "pressures" not in table  # a rod without chambers has no pressure row


def test_platform_on_three_columns_sways_at_the_guided_euler_load():
    """Three upright rods at the corners of a triangle hold a platform pressed down by W.
    Their axial stiffness keeps the platform from tilting, so it sways as three guided
    columns (clamped at the base, at the tip free to translate but not to turn), each
    buckling at pi^2 EI / L^2: W_cr = 3 pi^2 EI / L^2 (shear lowers it by about P/GA, 0.2 %;
    the tilt's compliance by less). The system's stability says so (docs/model.md, "Systems
    of rods"), with the policies of a single rod (the batch's ``stable`` column:
    tests/test_batch_ends.py)."""
    corners = [
        (0.03 * math.cos(a), 0.03 * math.sin(a)) for a in (0.0, 2 * math.pi / 3, 4 * math.pi / 3)
    ]
    rods = []
    for x, y in corners:
        doc = rod(base_x=x)
        doc["mounting"]["base_position"][1] = f"{y} m"
        rods.append(SystemRod(load_design(doc), attachment=np.array([x, y, 0.0])))
    system = System("tripod", tuple(rods), Platform(position=np.array([0.0, 0.0, L])))
    w_cr = 3 * math.pi**2 * EI / L**2

    def solve(ratio, **kwargs):
        return solve_system(
            system, platform_force=[0.0, 0.0, -ratio * w_cr], options=TIGHT, **kwargs
        )

    below = solve(0.9)
    assert below.stable is True and all(r.stable is True for r in below.rods)
    with pytest.warns(softrod.StabilityWarning):
        above = solve(1.1)
    assert above.stable is False and all(r.stable is False for r in above.rods)
    assert np.abs(above.platform_position[:2]).max() < 1e-9 * L  # straight by symmetry
    with pytest.raises(softrod.InvalidStateError) as exc:
        solve(1.1, on_unstable="raise")
    assert exc.value.rule == "stability"
    # Rods without inputs have nothing to vary per row: a batch is refused by name.
    with pytest.raises(InputError) as exc:
        softrod.solve_system_batch(system, np.zeros((2, 3, 0)))
    assert exc.value.field == "pressures" and "solve_system" in str(exc.value)


def test_a_rod_of_a_system_presses_on_its_own_obstacle():
    """A rod's obstacles go with it into a system (docs/contact.md): the left actuator of
    the bundled system, pressurised, swings towards +y and meets a wall its free swing
    would cross by 4 mm. The wall holds the platform back, the left rod reports its
    contact (the right one has none), the platform's balance still holds to 1e-9 N, and
    the surface sinks no deeper than the stated tolerance (the motion by the same wall:
    tests/test_system_dynamics.py)."""
    from system_cases import LEFT_AT_40_KPA as p
    from system_cases import walled as with_wall

    system = softrod.load_system("two_spa_platform")
    free = solve_system(system, p)
    walled = with_wall(system)
    sol = solve_system(walled, p)
    assert sol.rods[1].contact is None
    contact = sol.rods[0].contact
    assert contact is not None and contact.in_contact.any()
    assert contact.total[1] < 0  # the wall pushes the rod back towards -y
    assert contact.max_penetration <= 0.5e-3
    assert sol.platform_position[1] < free.platform_position[1] - 1e-3
    weight = system.platform.mass * np.array(system.rods[0].design.spec["mounting"]["gravity"])
    f = weight - sum(r.tip_reaction_force for r in sol.rods)
    assert np.abs(f).max() < 1e-9
    # The batch solves every row as solve_system does, the wall included (bitwise).
    batch = softrod.solve_system_batch(walled, [p, [[20e3, 0.0, 0.0], [0.0, 0.0, 0.0]]])
    assert batch.converged.all()
    assert np.array_equal(batch.platform_position[0], sol.platform_position)
