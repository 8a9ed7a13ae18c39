"""Contact with rigid obstacles in dynamics from Python (docs/contact.md, "Dynamics"):
simulate and Simulation accept designs with obstacles and report the contact force and the
penetration per sample, which the npz and Parquet files keep; a rod dropped onto a plane
rests with the plane and the clamp carrying its weight; friction and slip_velocity take
units and hostile values are refused by name; dynamic sensitivities carry contact; and
short runs with random obstacle placements never give NaN or a panic."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from softrod import (
    DesignError,
    Simulation,
    SoftrodError,
    TipConstraint,
    Trajectory,
    load_design,
    simulate,
    solve_statics,
)

pytestmark = pytest.mark.fast  # the whole module runs in seconds

G = 9.81
MASS = 0.02  # kg over 0.2 m: 0.98 N/m


def cantilever(obstacles: list[dict], *, tau: str = "0.05 s", steps: int = 8) -> dict:
    """A 0.2 m horizontal cantilever (EI = 0.01 N m^2: it sags 20 mm free) over obstacles,
    centreline contact (stiffnesses given directly)."""
    return {
        "design": {"name": "cantilever_over_plane", "citation": "test"},
        "mounting": {"orientation": "horizontal", "gravity": f"{G} m/s^2"},
        "sections": [
            {
                "name": "beam",
                "length": "200 mm",
                "mass": f"{MASS} kg",
                "EA": "1e4 N",
                "GA": "1e4 N",
                "EI": "0.01 N*m^2",
                "GJ": "0.01 N*m^2",
                "steps": steps,
            }
        ],
        "dynamics": {"damping_time": tau},
        "obstacles": obstacles,
    }


def plane(z_mm: float, **extra) -> dict:
    return {
        "kind": "plane",
        "point": ["0 mm", "0 mm", f"{z_mm} mm"],
        "normal": [0, 0, 1],
        "stiffness": "1e4 N/m^2",
        "tolerance": "3 mm",
        **extra,
    }


def test_dropped_rod_rests_on_the_plane_and_the_trajectory_keeps_the_contact(tmp_path):
    # Released straight 10 mm above the plane, damped (tau = 0.05 s): after 1.5 s it rests
    # on the plane, which with the clamp carries the weight: n(0) = F_contact + W to 1e-9 W.
    design = load_design(cantilever([plane(-10.0)]))
    sim = Simulation(design, initial="straight", dt=2e-3)
    run = sim.run(None, 1.5, save_every=50)
    assert run.contact_force.shape == (len(run), 3)
    assert run.penetration.shape == (len(run),)
    assert run.penetration[0] < 0 < run.penetration[-1] <= 3e-3
    state = sim.state()
    w = MASS * G
    assert abs(state.base_force[2] - (run.contact_force[-1][2] - w)) < 1e-9 * w
    assert run.contact_force[-1][2] > 0.1 * w
    for name in ("run.npz", "run.parquet"):
        back = Trajectory.load(run.save(tmp_path / name))
        np.testing.assert_array_equal(back.contact_force, run.contact_force)
        np.testing.assert_array_equal(back.penetration, run.penetration)
    # Without obstacles there is nothing to report.
    free = simulate(load_design(cantilever([])), None, 0.01, dt=2e-3)
    assert free.contact_force is None and free.penetration is None


def test_a_held_tip_rests_on_the_plane_with_the_contact_and_the_reaction():
    # The cantilever's tip pinned at its base's height 0.5 mm above the plane: held there,
    # it would sag by q L^4 / (185 EI) = 0.85 mm, so it rests on the plane between its
    # held ends (docs/contact.md, "A held tip with obstacles"); at rest the base, the pin
    # and the plane carry the weight, n(0) = F_r + F_c + W.
    design = load_design(cantilever([plane(-0.5)], tau="0.02 s", steps=32))
    tip = TipConstraint.pinned(["200 mm", "0 mm", "0 mm"])
    statics = solve_statics(design, [], tip_constraint=tip)
    assert statics.contact is not None and statics.contact.max_penetration > 0
    sim = Simulation(design, dt=2e-3, tip_constraint=tip)
    run = sim.run(None, 0.02, save_every=5)
    np.testing.assert_allclose(run.tip_position[-1], [0.2, 0.0, 0.0], atol=1e-9 * 0.2)
    state = sim.state()
    w = MASS * G
    balance = state.base_force - (
        run.tip_reaction_force[-1] + run.contact_force[-1] + [0.0, 0.0, -w]
    )
    # Started at rest in the constrained static equilibrium with contact: nothing moves,
    # and the balance holds to the Newton tolerance.
    assert np.abs(balance).max() < 1e-9 * w
    assert run.contact_force[-1][2] > 0.1 * w
    # The collocation (32 intervals) and the shooting statics (32 RK4 steps) differ by their
    # discretisation errors (measured 9.6e-3 at 8, 6.8e-5 at 32).
    np.testing.assert_allclose(
        run.contact_force[-1], statics.contact.total_force.sum(axis=0), rtol=1e-3
    )


def test_friction_takes_units_and_bad_values_are_refused_by_name():
    ok = load_design(cantilever([plane(-10.0, friction=0.5, slip_velocity="2 mm/s")]))
    assert ok.spec["obstacles"][0]["slip_velocity"] == pytest.approx(2e-3)
    run = simulate(ok, None, 0.1, dt=2e-3, initial="straight", alpha=0.0)
    assert np.isfinite(run.contact_force).all()
    for key, value in (("friction", -0.1), ("slip_velocity", "0 mm/s")):
        with pytest.raises(DesignError) as info:
            load_design(cantilever([plane(-10.0, **{key: value})]))
        assert info.value.field == f"obstacles[0].{key}"


def test_dynamic_sensitivities_carry_contact():
    # The rod rests on the plane from the start (its static start touches): the tracked
    # derivatives of the resting tip with respect to the mass are those of the static
    # contact solution, against central differences of the statics (the trajectory's
    # own checks are crates/softrod-core/tests/suite/dynamics_sensitivity.rs).
    design = load_design(cantilever([plane(-10.0)]))
    sim = Simulation(design, dt=2e-3)
    sim._sim.track_sensitivities([("mass", [0])])
    first = sim._sim.snapshot()
    d = np.asarray(first["d_tip_position"])[0, :, 0]
    assert first["penetration"][0] > 0
    h = 1e-3 * MASS

    def tip(m):
        spec = cantilever([plane(-10.0)])
        spec["sections"][0]["mass"] = f"{m} kg"
        return Simulation(load_design(spec), dt=2e-3).state().tip_position

    fd = (tip(MASS + h) - tip(MASS - h)) / (2 * h)
    # Central differences of the converged static start over the step 2e-3 MASS: truncation
    # ~1e-6 of the derivative, the start's error (1e-10 of the scaled unknowns, ~2e-11 m)
    # over the step ~1e-6 m/kg, against a derivative of ~3e-2 m/kg (the tip lying on the
    # plane sinks as the weight grows) checked to 1e-3 of it.
    assert np.abs(d).max() > 1e-2
    np.testing.assert_allclose(d, fd, rtol=0, atol=1e-3 * np.abs(d).max())


def test_an_obstacle_through_the_unloaded_rod_is_refused_before_the_start():
    # A table at z = -100 mm cuts the 130 mm actuator hanging at rest: both starts begin
    # at that shape, so neither has a state to start from; the error names the obstacle
    # (before: a penetration error at t = 0 suggesting a stiffer penalty).
    arm = load_design("spa_three_chamber_130mm").with_obstacles(
        [
            {
                "kind": "plane",
                "point": ["0 mm", "0 mm", "-100 mm"],
                "normal": [0, 0, 1],
                "stiffness": "1e7 N/m^2",
                "tolerance": "0.2 mm",
            }
        ]
    )
    for initial in ("static", "straight"):
        with pytest.raises(SoftrodError) as info:
            simulate(arm, [0, 0, 0], 0.01, initial=initial)
        assert info.value.field == "obstacles[0]"
        assert "the unloaded rod" in str(info.value)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    kind=st.sampled_from(["plane", "sphere", "cylinder", "capsule"]),
    x_mm=st.floats(0.0, 250.0),
    z_mm=st.floats(-40.0, 10.0),
    radius_mm=st.floats(2.0, 80.0),
    k_exp=st.floats(3.0, 6.0),
    mu=st.floats(0.0, 1.0),
)
def test_random_obstacles_never_give_nan_or_panic(kind, x_mm, z_mm, radius_mm, k_exp, mu):
    at = [f"{x_mm} mm", "0 mm", f"{z_mm} mm"]
    pose = {
        "plane": {"point": at, "normal": [0, 0, 1]},
        "sphere": {"center": at, "radius": f"{radius_mm} mm"},
        "cylinder": {"point": at, "axis": [0, 1, 0], "radius": f"{radius_mm} mm"},
        "capsule": {
            "start": at,
            "end": [f"{x_mm} mm", "30 mm", f"{z_mm} mm"],
            "radius": f"{radius_mm} mm",
        },
    }[kind]
    ob = {
        "kind": kind,
        **pose,
        "stiffness": f"{10**k_exp} N/m^2",
        "tolerance": "5 mm",
        "friction": mu,
    }
    design = load_design(cantilever([ob], steps=4))
    try:
        run = simulate(design, None, 0.04, dt=2e-3, initial="straight")
    except SoftrodError as e:
        assert str(e)  # an error that says why (penetration, Newton, energy, ...)
        return
    assert np.isfinite(run.tip_position).all()
    assert np.isfinite(run.contact_force).all() and np.isfinite(run.penetration).all()
    assert run.penetration.max() <= 5e-3


@pytest.mark.parametrize("tension", [1e4, 3e4])
def test_an_overflowing_tendon_pull_against_an_obstacle_is_an_error_not_a_panic(tension):
    # Found by the long fuzz run: tens of kN on the finger's tendon pressed it through the
    # table so hard that the contact Jacobian's derivatives were not finite, and an entry
    # was written outside the band (a panic in the core, reported as an InternalError).
    # Now the broken Jacobian fails the factorization and the start is not converged.
    from softrod.errors import InternalError

    try:
        traj = simulate("prebent_finger_on_table", 0.0, "20 ms", tensions=[tension])
    except SoftrodError as exc:
        assert not isinstance(exc, InternalError), exc
        return
    assert np.all(np.isfinite(traj.tip_position))
