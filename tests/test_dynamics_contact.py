"""Contact with rigid obstacles in dynamics from Python (docs/contact.md, "Dynamics"):
simulate and Simulation accept designs with obstacles and report the contact force and the
penetration per sample, which the npz and Parquet files keep; a rod dropped onto a plane
rests with the plane and the clamp carrying its weight; friction and slip_velocity take
units and hostile values are refused by name; dynamic sensitivities refuse obstacles; and
short runs with random obstacle placements never give NaN or a panic."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from softrod import DesignError, Simulation, SoftrodError, Trajectory, load_design, simulate

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


def test_friction_takes_units_and_bad_values_are_refused_by_name():
    ok = load_design(cantilever([plane(-10.0, friction=0.5, slip_velocity="2 mm/s")]))
    assert ok.spec["obstacles"][0]["slip_velocity"] == pytest.approx(2e-3)
    run = simulate(ok, None, 0.1, dt=2e-3, initial="straight", alpha=0.0)
    assert np.isfinite(run.contact_force).all()
    for key, value in (("friction", -0.1), ("slip_velocity", "0 mm/s")):
        with pytest.raises(DesignError) as info:
            load_design(cantilever([plane(-10.0, **{key: value})]))
        assert info.value.field == f"obstacles[0].{key}"


def test_dynamic_sensitivities_refuse_obstacles():
    design = load_design(cantilever([plane(-30.0)]))
    sim = Simulation(design)
    with pytest.raises(SoftrodError) as info:
        sim._sim.track_sensitivities([("damping_time", [])])
    assert info.value.field == "obstacles"


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
