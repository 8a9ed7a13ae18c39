"""``softrod.system_trajectory_sensitivities``: the exact forward sensitivities of a
system's motion (platform pose and markers) with respect to model parameters, against
central differences of whole ``simulate_system`` runs (docs/dynamics.md, "Systems of
rods"; the core's own checks are crates/softrod-core/tests/suite/dynamics_system_sensitivity.rs)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import softrod
from softrod import InputError, StiffnessMap
from softrod.calibration.system import calibrated_system, parse_system_parameters
from system_cases import table_map, two_mapped_rods

pytestmark = pytest.mark.filterwarnings("error")

DT = 2e-3
T_END = 0.04  # s: 20 steps
#: Newton to 1e-12 of the unknowns in every run, so that the differences see the
#: parameters and not the solver's stopping point.
TOL = 1e-12
#: Central differences with a relative step H: truncation ~H^2 = 1e-8 of a derivative;
#: each run's Newton error (~TOL * L = 1.3e-13 m) divided by the step 2 H theta gives
#: ~1e-13 / (2e-4 * 4e-3 m) ~ 1.3e-7 of the largest derivative (theta * d(platform)/d theta
#: ~ 4 mm for E here), and the core's refinement stops at 1e-9: 1e-6 of the largest
#: derivative bounds the three with a margin (measured 2e-8).
H = 1e-4
RTOL = 1e-6
PARAMS = ["rods[0].E", "platform_mass"]
#: One marker on the platform, one on rod 0's body section (80 mm from its base).
MARKERS = [("platform", 0.0, [0.01, -0.005, 0.0]), (0, 0.08, [0.0, 0.02, 0.0])]


def ramp(t):
    """Rod 0's channel 0 and rod 1's channel 1 ramped to 40 and 20 kPa in 20 ms."""
    a = min(t / 0.02, 1.0)
    return [[a * 40e3, 0.0, 10e3], [0.0, a * 20e3, 0.0]]


@pytest.fixture(scope="module")
def system():
    """The bundled two-actuator platform (20 g) with rod 0's body section stiffness-mapped:
    the derivatives hold sigma of the pressures fixed (it does not depend on them)."""
    bundled = softrod.load_system("two_spa_platform")
    mapped = two_mapped_rods(bundled)
    return dataclasses.replace(bundled, rods=(mapped.rods[0], bundled.rods[1]))


MAPS = [table_map(), None]


def run(system, params=PARAMS, **kw):
    return softrod.system_trajectory_sensitivities(
        system,
        ramp,
        T_END,
        params,
        markers=MARKERS,
        dt=DT,
        tol=TOL,
        stiffness_maps=MAPS,
        **kw,
    )


def test_derivatives_match_central_differences_of_simulate_system(system):
    out = run(system)
    k = round(T_END / DT) + 1
    assert out["params"] == ("rods[0].E", "platform_mass")
    assert out["units"] == ("Pa", "kg")
    assert out["time"].shape == (k,)
    assert out["d_platform_position"].shape == (k, 3, 2)
    assert out["d_platform_rotation"].shape == (k, 3, 3, 2)
    assert out["marker_position"].shape == (k, 2, 3)
    assert out["d_marker_position"].shape == (k, 2, 3, 2)
    params = parse_system_parameters(PARAMS, system, dynamic=True)
    theta = np.array([p.value(system) for p in params])

    def motion(values):
        sysm = calibrated_system(system, params, values)
        traj = softrod.simulate_system(sysm, ramp, T_END, dt=DT, tol=TOL, stiffness_maps=MAPS)
        plain = softrod.system_trajectory_sensitivities(
            sysm, ramp, T_END, [], markers=MARKERS, dt=DT, tol=TOL, stiffness_maps=MAPS
        )
        # The run without derivatives is simulate_system's, bit for bit.
        assert np.array_equal(plain["platform_position"], traj.platform_position)
        return traj.platform_position, traj.platform_rotation, plain["marker_position"]

    for j in range(len(params)):
        step = H * theta[j]
        up, down = theta.copy(), theta.copy()
        up[j] += step
        down[j] -= step
        a, b = motion(up), motion(down)
        for key, plus, minus in zip(
            ("d_platform_position", "d_platform_rotation", "d_marker_position"), a, b, strict=True
        ):
            exact = out[key][..., j]
            central = (plus - minus) / (2 * step)
            scale = np.abs(exact).max()
            assert scale > 0, key
            assert np.abs(exact - central).max() <= RTOL * scale, (params[j].name, key)
    # The platform moved, so the derivatives are of a motion (the start's are static).
    assert np.linalg.norm(out["platform_position"][-1] - out["platform_position"][0]) > 1e-3
    assert np.abs(out["d_platform_position"][-1] - out["d_platform_position"][0]).max() > 0


def test_the_run_is_simulate_systems_and_tracking_does_not_change_it(system):
    out = run(system)
    traj = softrod.simulate_system(system, ramp, T_END, dt=DT, tol=TOL, stiffness_maps=MAPS)
    assert np.array_equal(out["time"], traj.time)
    assert np.array_equal(out["platform_position"], traj.platform_position)
    assert np.array_equal(out["platform_rotation"], traj.platform_rotation)
    # The platform marker is the platform's point p + R o.
    o = np.array(MARKERS[0][2])
    want = traj.platform_position + traj.platform_rotation @ o
    np.testing.assert_allclose(out["marker_position"][:, 0], want, rtol=0, atol=1e-15)
    # One name a string, as calibrate_system takes it; no parameters: no derivatives.
    one = run(system, "rods[0].E")
    assert np.array_equal(one["d_platform_position"][..., 0], out["d_platform_position"][..., 0])
    none = run(system, [])
    assert none["d_platform_position"].shape == (len(traj), 3, 0)
    assert none["params"] == () and none["units"] == ()


@pytest.mark.parametrize(
    "params, words",
    [
        (["Q"], "unknown parameter"),
        (["rods[5].E"], "has 2 rods"),
        (["registration_x"], "measurement frame"),
        (["sigma_ext"], "stiffness scaling"),
        (["E", "rods[0].E"], "same thing"),
        ("", "at least one"),
        ([3], "each parameter must be a name"),
    ],
)
def test_bad_params_are_refused_naming_the_field(system, params, words):
    with pytest.raises(InputError, match=words) as e:
        run(system, params)
    assert e.value.field == "params"


def test_a_massless_platform_and_bad_markers_are_refused(system):
    massless = dataclasses.replace(system, platform=dataclasses.replace(system.platform, mass=0.0))
    with pytest.raises(InputError, match="massless platform") as e:
        run(massless, ["platform_mass"])
    assert e.value.field == "params"
    for markers, field in [
        ([("base", 0.0, [0, 0, 0])], "markers[0].body"),
        ([(2, 0.0, [0, 0, 0])], "markers[0].body"),
        ([(0, 0.05, [0, 0])], "markers[0].offset"),
        ([(0, 0.05)], "markers[0]"),
        ("platform", "markers"),
        ([("platform", 0.01, [0, 0, 0])], "markers[0].s"),
        ([(1, 0.5, [0, 0, 0])], "markers[0].s"),
    ]:
        with pytest.raises(InputError) as e:
            softrod.system_trajectory_sensitivities(
                system, ramp, T_END, PARAMS, markers=markers, stiffness_maps=MAPS
            )
        assert e.value.field == field, markers


def test_a_mapped_rod_keeps_the_statics_refusals(system):
    with pytest.raises(InputError, match="never assumed to be 1") as e:
        softrod.system_trajectory_sensitivities(system, ramp, T_END, PARAMS)
    assert e.value.field == "rods[0].design.stiffness_map"
    with pytest.raises(InputError) as e:
        softrod.system_trajectory_sensitivities(
            system, ramp, T_END, PARAMS, stiffness_maps=[StiffnessMap.constant((1, 1, 1), 3)]
        )
    assert e.value.field == "stiffness_maps"
