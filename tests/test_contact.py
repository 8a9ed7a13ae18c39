"""Contact with rigid obstacles from the design file to the answer (docs/contact.md):
the [[obstacles]] keys with units, the contact report of solve_statics (forces, points,
gaps, resultants), global equilibrium, the penetration rule, the finger pressed onto a table,
bad input, and a property test on the entry point."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from softrod import (
    ConvergenceError,
    DesignError,
    InputError,
    InvalidStateError,
    TipConstraint,
    linearise,
    load_design,
    solve_statics,
)

pytestmark = pytest.mark.fast  # the whole module runs in seconds

FINGER = "prebent_finger_on_table"
EI = 1.0  # N m^2
Q = 1.0  # N/m: the beam's weight per length
G = 9.81


def beam_over(obstacle: dict, *, length="500 mm", steps=200, gravity=True) -> dict:
    """A horizontal cantilever (EI = 1 N m^2, nearly inextensible, centreline contact:
    stiffnesses given directly) above an obstacle."""
    return {
        "design": {"name": "beam_over_obstacle", "citation": "closed-form check"},
        "mounting": {
            "orientation": "horizontal",
            "gravity": "9.81 m/s^2" if gravity else "0 m/s^2",
        },
        "sections": [
            {
                "name": "beam",
                "length": length,
                "mass": f"{Q / G * 0.5} kg",
                "EA": "1e8 N",
                "GA": "1e8 N",
                "EI": f"{EI} N*m^2",
                "GJ": f"{EI} N*m^2",
                "steps": steps,
            }
        ],
        "obstacles": [obstacle],
    }


def plane(z_mm: float, **extra) -> dict:
    ob = {
        "kind": "plane",
        "point": ["0 mm", "0 mm", f"{z_mm} mm"],
        "normal": [0, 0, 1],
        "stiffness": "1e6 N/m^2",
        "tolerance": "0.05 mm",
        "smoothing": "0.2 um",
    }
    ob.update(extra)
    return ob


def balance_error(sol) -> float:
    """|n(0) - (weight + contact)| for a rod without tip loads: the global force balance."""
    weight = np.array([0.0, 0.0, -sol.design.mass * G])
    return float(np.abs(sol.base_force - (weight + sol.contact.total)).max())


def test_cantilever_on_a_plane_matches_the_beam_on_a_rigid_support():
    # Clamp 0.11 mm above the support: the beam on a rigid support lies flat from
    # a = (72 EI c / q)^(1/4) = 0.3 m, the clamp taking 2 q a / 3 and q a^2 / 6.
    c = Q * 0.3**4 / (72 * EI)
    sol = solve_statics(load_design(beam_over(plane(-c * 1e3))), [])
    a = (72 * EI * c / Q) ** 0.25
    # The penalty (k = 1e6 N/m^2) is a Winkler foundation with 1/beta = (4 EI/k)^(1/4) =
    # 45 mm, which smears the point reaction; the clamp's reactions err by
    # < (1/(beta a))^2 (second order, measured in the Rust test), here 0.022.
    bound = ((4 * EI / 1e6) ** 0.25 / a) ** 2
    assert abs(-sol.base_force[2] - 2 * Q * a / 3) < bound * 2 * Q * a / 3
    assert abs(abs(sol.base_moment[1]) - Q * a * a / 6) < bound * Q * a * a / 6
    assert balance_error(sol) < 1e-9
    ct = sol.contact
    assert ct.force.shape == sol.position.shape and ct.gap.shape == sol.s.shape
    assert ct.in_contact[-1] and not ct.in_contact[0]
    # Contact points lie on the plane; the force pushes up.
    assert np.allclose(ct.point[ct.in_contact, 2], -c, atol=1e-15)
    assert np.all(ct.force[:, 2] >= 0) and np.all(ct.force[:, :2] == 0)
    assert 0 < ct.max_penetration <= 0.05e-3


def test_rod_on_a_sphere_cylinder_and_capsule_balance_and_point_through_the_centre():
    centre = np.array([0.5, 0.0, -0.052])
    shapes = [
        {"kind": "sphere", "center": [f"{v * 1e3} mm" for v in centre], "radius": "50 mm"},
        # A cylinder across the beam (axis y) and a capsule along y through the same
        # centre touch it the same way.
        {
            "kind": "cylinder",
            "point": [f"{v * 1e3} mm" for v in centre],
            "axis": [0, 1, 0],
            "radius": "50 mm",
        },
        {
            "kind": "capsule",
            "start": ["500 mm", "-30 mm", "-52 mm"],
            "end": ["500 mm", "30 mm", "-52 mm"],
            "radius": "50 mm",
        },
    ]
    totals = []
    for shape in shapes:
        ob = {**shape, "stiffness": "1e7 N/m^2", "tolerance": "0.1 mm"}
        doc = beam_over(ob, gravity=False) | {"tip": {"force": ["0 N", "0 N", "-0.1 N"]}}
        design = load_design(doc)
        sol = solve_statics(design, [])
        ct = sol.contact
        f = ct.total_force[0]
        # Global balance: n(0) = F_tip + contact.
        assert np.abs(sol.base_force - (np.array([0, 0, -0.1]) + f)).max() < 1e-9
        # Every contact force points through the centre (sphere) or axis: the contact
        # moment about the base is (c - r0) x F.
        assert np.abs(ct.total_moment[0] - np.cross(centre, f)).max() < 1e-12
        assert 0 < ct.max_penetration <= 1e-4
        totals.append(f[2])
    # Small deflection: the obstacle takes R = P - 3 EI d0 / L^3 at the tip (d0 = 2 mm);
    # the penalty spreads it over ~(EI/k)^(1/4) = 18 mm: < 1.5 ell / L = 5 % (Rust test).
    r = 0.1 - 3 * EI * 2e-3 / 0.5**3
    for t in totals:
        assert abs(t - r) < 0.054 * r
    # The three shapes are the same circle in the beam's plane: the same answer.
    assert max(totals) - min(totals) < 1e-9


def test_finger_pressed_onto_the_table():
    design = load_design(FINGER)
    forces = []
    for p_kpa in (0, 10, 20, 30, 40, 50):
        sol = solve_statics(design, [p_kpa * 1e3])
        ct = sol.contact
        assert ct.max_penetration <= 0.2e-3
        assert balance_error(sol) < 1e-9 * max(1.0, design.mass * G)
        forces.append(ct.total[2])
    forces = np.array(forces)
    # Free above the table at zero pressure, then pressed harder as pressure opens it.
    assert forces[0] == 0.0
    assert forces[-1] > 0.0 and np.all(np.diff(forces) >= 0)
    # The tip's contact is carried by the rounded end, so the answer does not hang on the
    # steps: 40 (the design's) and 160 steps agree to 1e-4 (measured 4e-5; RK4's error
    # falls as h^4, the contact's as the step's share of the penalty's decay length).
    fine = design.replace({"sections[0].steps": 160})
    f_fine = solve_statics(fine, [50e3]).contact.total[2]
    assert abs(forces[-1] - f_fine) < 1e-4 * f_fine


@pytest.mark.parametrize(
    ("change", "field", "words"),
    [
        ({"radius": "-5 mm"}, "obstacles[0].radius", "> 0"),
        ({"kind": "cone"}, "obstacles[0].kind", "plane"),
        ({"stiffness": "1e6"}, "obstacles[0].stiffness", "unit"),
        ({"stiffness": "1e6 N/m"}, "obstacles[0].stiffness", "N/m^2"),
        ({"tolerance": "nan mm"}, "obstacles[0].tolerance", "finite"),
        ({"center": ["0 mm", "nan mm", "0 mm"]}, "obstacles[0].center[1]", "finite"),
        ({"normal": [0, 0, 1]}, "obstacles[0].normal", "sphere obstacle has no normal"),
        ({"colour": "red"}, "obstacles[0].colour", "unknown key"),
        ({"smoothing": "1 m"}, "obstacles[0].smoothing", "at most the tolerance"),
    ],
)
def test_bad_obstacles_name_field_value_and_rule(change, field, words):
    ob = {
        "kind": "sphere",
        "center": ["0 mm", "0 mm", "-60 mm"],
        "radius": "50 mm",
        "stiffness": "1e6 N/m^2",
        "tolerance": "0.1 mm",
    }
    ob.update(change)
    with pytest.raises(DesignError) as info:
        load_design(beam_over(ob))
    assert info.value.field == field, str(info.value)
    assert words in str(info.value)


def test_missing_obstacle_keys_and_friction_in_statics():
    ob = {
        "kind": "sphere",
        "center": ["0 mm", "0 mm", "-60 mm"],
        "radius": "50 mm",
        "tolerance": "0.1 mm",
    }
    with pytest.raises(DesignError, match=r"obstacles\[0\]\.stiffness"):
        load_design(beam_over(ob))
    ob["stiffness"] = "1e6 N/m^2"
    del ob["radius"]
    with pytest.raises(DesignError, match=r"obstacles\[0\]\.radius"):
        load_design(beam_over(ob))
    # Friction: solve_statics follows a load path with it, for a free or a held tip
    # (tests/test_friction_statics.py); the batch still refuses it, naming the friction.
    design = load_design(beam_over(plane(-1.0, friction=0.4)))
    assert solve_statics(design, []).friction_state is not None
    held = {"type": "pinned", "position": ["500 mm", "0 mm", "0 mm"]}
    sol = solve_statics(design, [], tip_constraint=held)
    assert sol.friction_state.tip_constraint == "pinned" and sol.stable is None


def test_penetration_beyond_the_tolerance_is_an_error():
    soft = plane(-0.01, stiffness="1e3 N/m^2", tolerance="0.01 mm", smoothing="1 um")
    with pytest.raises(InvalidStateError) as info:
        solve_statics(load_design(beam_over(soft)), [])
    assert info.value.rule == "penetration"


def test_an_obstacle_through_the_unloaded_rod_is_refused_before_any_solve():
    # The 130 mm actuator hangs to z = -131 mm: a table at -100 mm cuts it, a pin 20 mm off
    # its axis lies inside its 21.1 mm radius. Named, with the depth and the fix (before:
    # a singular Jacobian, or a failed load step blamed on snap-through).
    arm = load_design("spa_three_chamber_130mm")
    table = {"kind": "plane", "point": ["0 mm", "0 mm", "-100 mm"], "normal": [0, 0, 1]}
    pin = {"kind": "capsule", "start": ["-30 mm", "20 mm", "-90 mm"], "radius": "4 mm"}
    pin["end"] = ["30 mm", "20 mm", "-90 mm"]
    for ob in (table, pin):
        design = arm.with_obstacles([{**ob, "stiffness": "1e7 N/m^2", "tolerance": "0.2 mm"}])
        for p in ([0, 0, 0], [40e3, 0, 0]):
            with pytest.raises(InputError) as info:
                solve_statics(design, p)
            assert info.value.field == "obstacles[0]"
            assert "the unloaded rod" in str(info.value) and "move the obstacle" in str(info.value)


def test_linearisation_carries_contact():
    """An obstacle out of reach changes nothing: the linearisation (six shooting unknowns,
    the free tip's balance) equals the obstacle-free beam's (three) to the round-off of the
    two condensations. Resting on the plane 1 mm below, the beam's lowest vertical mode is
    held by the penalty and rises above the free one (docs/control.md, "Follower loads and
    obstacles")."""
    bare = beam_over(plane(-100.0), steps=40)
    bare.pop("obstacles")
    free = linearise(load_design(bare), [], nodes=8)
    far = linearise(load_design(beam_over(plane(-100.0), steps=40)), [], nodes=8)
    for name in ("stiffness", "damping", "input"):
        a, b = getattr(far, name), getattr(free, name)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-8 * np.abs(b).max(), err_msg=name)
    # M = K^T G K carries the product's cancellation between the axial (EA = 1e8 N) and
    # bending parts in its small entries (docs/control.md, "The discretisation"), so it is
    # compared where it acts: the lowest frequencies, to the same 1e-8.
    np.testing.assert_allclose(far.modes(8).omega, free.modes(8).omega, rtol=1e-8, atol=0)
    resting = linearise(load_design(beam_over(plane(-1.0), steps=40)), [], nodes=8)
    lowest = [s.modes(4) for s in (free, resting)]
    # The vertical (z) bending modes: the tip moves along z more than along y.
    vertical = [
        m.frequency[np.abs(m.shapes[:, -1, 2]) > np.abs(m.shapes[:, -1, 1])][0] for m in lowest
    ]
    assert vertical[1] > 2 * vertical[0], vertical


def test_held_tip_with_obstacles_solves_with_contact():
    # Pinned where the free finger's tip rests on the table at 50 kPa, the held solve finds
    # the free equilibrium again: the pin carries nothing, the contacts are the free
    # solve's, and the solution carries its contact report and stability verdict
    # (docs/contact.md, "A held tip with obstacles").
    design = load_design(FINGER)
    free = solve_statics(design, [50e3])
    held = solve_statics(design, [50e3], tip_constraint=TipConstraint.pinned(free.tip_position))
    assert held.contact is not None
    pressed = float(np.abs(free.contact.total).max())
    assert pressed > 0.0
    # Both solves converge to 1e-10 of the scaled residual: the pin's force is round-off
    # against the contact force.
    assert np.abs(held.tip_reaction_force).max() < 1e-6 * pressed
    np.testing.assert_allclose(held.contact.total, free.contact.total, rtol=1e-6, atol=1e-9)
    assert held.contact.max_penetration <= 0.2e-3
    assert held.stable is free.stable is True


def test_design_with_obstacles_saves_and_reloads(tmp_path):
    design = load_design(FINGER)
    path = design.save(tmp_path / "finger.toml")
    again = load_design(path)
    assert again.spec["obstacles"] == design.spec["obstacles"]


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    height_mm=st.floats(-30.0, 5.0),
    k_exp=st.floats(4.0, 7.0),
    radius_mm=st.floats(5.0, 200.0),
    x_mm=st.floats(0.0, 600.0),
    kind=st.sampled_from(["plane", "sphere"]),
)
def test_property_contact_answers_are_balanced_or_errors(height_mm, k_exp, radius_mm, x_mm, kind):
    """Any obstacle below the beam: a solution balances (base force = weight + contact to
    1e-9) and sinks no deeper than the tolerance, or the solve raises a SoftrodError that
    says why (never NaN, never a silent penetration)."""
    tol_mm = 0.5
    if kind == "plane":
        ob = plane(
            height_mm,
            stiffness=f"{10**k_exp} N/m^2",
            tolerance=f"{tol_mm} mm",
            smoothing=f"{tol_mm / 10} mm",
        )
    else:
        ob = {
            "kind": "sphere",
            "center": [f"{x_mm} mm", "0 mm", f"{height_mm - radius_mm} mm"],
            "radius": f"{radius_mm} mm",
            "stiffness": f"{10**k_exp} N/m^2",
            "tolerance": f"{tol_mm} mm",
        }
    design = load_design(beam_over(ob, steps=100))
    # The unloaded beam (straight along +x at z = 0, centreline contact) at its 101 nodes:
    # an obstacle it already sinks into beyond the tolerance has no load path and is
    # refused by name before any solve.
    x = np.linspace(0.0, 0.5, 101)
    if kind == "plane":
        depth = height_mm * 1e-3
    else:
        centre = np.array([x_mm, 0.0, height_mm - radius_mm]) * 1e-3
        gaps = np.hypot(x - centre[0], centre[2])
        depth = float(np.max(radius_mm * 1e-3 - gaps))
    if abs(depth - tol_mm * 1e-3) < 1e-12:
        return  # on the rule's edge to round-off: either answer is right
    if depth > tol_mm * 1e-3:
        with pytest.raises(InputError) as info:
            solve_statics(design, [])
        assert info.value.field == "obstacles[0]" and "unloaded rod" in str(info.value)
        return
    try:
        # A beam resting on a small stiff sphere can be an unstable equilibrium (it rolls
        # off sideways; e.g. a 5 mm sphere at x = 365 mm): an honest answer, reported in
        # `stable`, and it balances like any other.
        sol = solve_statics(design, [], on_unstable="ignore")
    except (ConvergenceError, InvalidStateError) as exc:
        assert str(exc)
        if isinstance(exc, InvalidStateError):
            assert exc.rule in ("penetration", "strain_range", "stretch_limit")
        return
    assert sol.stable in (True, False)
    assert np.all(np.isfinite(sol.position)) and np.all(np.isfinite(sol.contact.force))
    assert sol.contact.max_penetration <= tol_mm * 1e-3
    assert balance_error(sol) < 1e-9 * max(1.0, math.fabs(sol.base_force[2]))


def test_cli_solve_reports_the_contacts(run):
    """`softrod solve` on a design with obstacles shows each obstacle's contact force, the
    nodes in contact and the deepest penetration (table and JSON), the API's numbers."""
    import json

    result = run("solve", "prebent_finger_on_table", "--pressure", "30kPa", "--json")
    assert result.exit_code == 0, result.output
    contact = json.loads(result.stdout)["contact"]
    api = solve_statics("prebent_finger_on_table", [30e3]).contact
    np.testing.assert_array_equal(contact["total_force_N"], api.total_force)
    assert contact["max_penetration_m"] == api.max_penetration
    assert contact["nodes_in_contact"] == int(api.in_contact.sum()) >= 1
    table = run("solve", "prebent_finger_on_table", "--pressure", "30kPa").output
    assert "contact force, obstacle 0" in table and "nodes in contact" in table
    assert "deepest penetration" in table and "not assessed" not in table


def test_static_calibration_through_contact_recovers_the_material():
    """Static parameter sensitivities carry contact (the penalty is a line load of the
    shooting ODE, the rounded end's force a term of the tip balance; checked against
    central differences in crates/softrod-core/tests/suite/sensitivity.rs): a noise-free round
    trip on the finger pressed onto the table recovers E and the chamber area factor,
    with tip and two markers observed. Pressures from 0 to 40 kPa: the softened finger
    hangs free at 0 kPa and rests on the table from 5 kPa on (asserted), so the fit must see
    through the contact."""
    from softrod import calibrate, synthesize_dataset
    from softrod.calibration.params import design_changes, parse_parameters

    design = load_design(FINGER)
    pressures = np.linspace(0.0, 40e3, 7)[:, None]
    names = ["E[dragon_skin_20]", "area_scale"]
    truth = [0.8 * parse_parameters(names[:1], design)[0].value(design), 1.1]
    made = design.replace(design_changes(parse_parameters(names, design), truth, design))
    touching = [solve_statics(made, p).contact.in_contact.any() for p in pressures]
    assert 0 < sum(touching) < len(touching)
    markers = [("40 mm", ["8 mm", "0 mm"]), ("80 mm", ["0 mm", "8 mm"])]
    data = synthesize_dataset(made, pressures, markers=markers)
    res = calibrate(design, data, names)
    assert res.success
    # Noise-free: solves to 1e-10 and scipy's xtol 1e-10 leave ~1e-9 relative; 1e-6
    # leaves room for the conditioning of the two parameters.
    np.testing.assert_allclose(res.values, truth, rtol=1e-6)
