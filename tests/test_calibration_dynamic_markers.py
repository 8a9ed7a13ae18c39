"""Dynamic calibration from motion-capture markers along the body (paper 000 Sec. III-D
recorded markers in time series): the replay reads every marker at every sample (the core's
continuous extension between the nodes, ``Simulator::set_markers``) with its exact
trajectory derivatives, so markers alone fit tau and A_eff, and a held (clamped) tip, whose
own trajectory no parameter moves, is fitted by its markers."""

import numpy as np
import pytest
import softrod
from adapter_checks import central_difference
from softrod import PressureSchedule
from softrod.calibration import synthesize_trajectory_dataset
from softrod.calibration.adapters.rod_dynamic import RodDynamic
from softrod.calibration.params import design_changes, parse_parameters
from softrod.errors import InputError

pytestmark = pytest.mark.filterwarnings("error")

ARM = "pam_arm_220mm"
TAU, AREA = 0.12, 1.3  # truth: tau in s, area relative to the bundled design
DT = 5e-3
#: Two markers: at mid-length 15 mm off the axis (d1) and 10 mm short of the tip.
MARKERS = [("110 mm", ["15 mm", "0 mm"]), ("210 mm", ["0 mm", "0 mm"])]
NAMES = ["damping_time", "area_scale"]
#: Noise-free fits stop on the LM rule of RodDynamic (1e-3 of the standard errors the data
#: would leave with 1 mm noise) or scipy's tolerances; on data without noise the
#: Gauss-Newton steps converge quadratically to the truth, which the replays (Newton to 1e-9
#: of the unknowns' scales) reproduce to ~1e-9 relative: 1e-6 leaves three digits.
EXACT = 1e-6


def truth(design):
    d = design.replace({"dynamics.damping_time": f"{TAU} s"})
    return d.replace(design_changes(parse_parameters(["area_scale"], d), [AREA], d))


def schedule():
    """1.1 s: PAM 0 pulsed to 2.5 bar, then PAM 1 to 2 bar (bending one way, then another)."""
    return PressureSchedule.square_pulses(
        3, [(0, 2.5e5, 0.3), (1, 2.0e5, 0.3)], rest=0.2, start=0.1
    )


def clamped_arm():
    """The arm with its tip clamped where 1.5 bar on PAM 0 holds it: bent between the
    clamps, so the pulses (stretching one side) move its body while the tip stays put (the
    straight arm clamped would not move: a uniform change of its stress-free strains goes
    into the clamps)."""
    free = softrod.load_design(ARM)
    rest = softrod.solve_statics(free, [1.5e5, 0.0, 0.0])
    tip = {
        "constraint": "clamped",
        "position": [f"{float(v)!r} m" for v in rest.tip_position],
        "orientation": rest.tip_rotation.tolist(),
    }
    return free.replace({"tip": tip})


def markers_only(design, **kw):
    return synthesize_trajectory_dataset(
        truth(design), schedule(), 1.1, markers=MARKERS, tip=False, dt=DT, **kw
    )


def test_markers_alone_recover_tau_and_area():
    design = softrod.load_design(ARM)
    data = markers_only(design)
    assert data.tip_position is None and data.markers.shape[1:] == (2, 3)
    res = softrod.calibrate(design, data, NAMES, dynamic=True, dt=DT)
    assert res.success
    np.testing.assert_allclose(res.values, [TAU, AREA], rtol=EXACT)
    assert res.predicted_markers.shape == data.markers.shape
    np.testing.assert_allclose(res.predicted_markers, data.markers, rtol=0, atol=1e-8)


def test_clamped_tip_is_fitted_by_its_markers():
    design = clamped_arm()
    data = markers_only(design)
    # The tip does not move; the markers do (by about a centimetre).
    moved = np.abs(data.markers - data.markers[0]).max()
    assert moved > 5e-3, moved
    res = softrod.calibrate(design, data, NAMES, dynamic=True, dt=DT)
    assert res.success
    np.testing.assert_allclose(res.values, [TAU, AREA], rtol=EXACT)


@pytest.mark.parametrize("held", [False, True])
def test_marker_jacobian_matches_central_differences(held):
    """The adapter's exact d markers / d theta (the core's sensitivities of the continuous
    extension, the area factor's chain rule, interpolation at the sample times) against
    central differences of whole replays."""
    design = clamped_arm() if held else softrod.load_design(ARM)
    data = markers_only(design)
    params = parse_parameters(["damping_time", "area_scale", "c_b"], design)
    adapter = RodDynamic(design, data, params, DT, 1)
    theta = np.array([0.15, 1.2, 0.9])
    rows = np.arange(len(data))
    exact = adapter.predict(theta, rows, True)
    assert exact.ok.all()
    for j in range(len(params)):
        # Relative step 1e-5: truncation ~1e-10 of the derivative; the Newton tolerance
        # (1e-9 of the unknowns' scales, ~1e-10 m on the body) over the step 2e-5 theta
        # adds ~1e-5 m per unit. 1e-3 of the largest derivative (>= 1e-3 m per unit here)
        # plus 1e-5 leaves an order of magnitude above both (the tip's test's bound).
        fd = central_difference(adapter, theta, rows, j, "markers")
        d = exact.d_markers[..., j]
        largest = np.abs(d).max()
        assert largest > 1e-3, params[j].name
        np.testing.assert_allclose(d, fd, rtol=0, atol=1e-3 * largest + 1e-5)


def test_held_tip_without_markers_is_refused_by_name():
    design = clamped_arm()
    data = synthesize_trajectory_dataset(truth(design), schedule(), 0.2, dt=DT)
    with pytest.raises(InputError) as exc:
        softrod.calibrate(design, data, NAMES, dynamic=True, dt=DT)
    assert exc.value.field == "dataset.markers"
    assert "needs markers" in str(exc.value)


def test_held_tip_reaction_columns_are_refused_in_dynamic_fits():
    design = clamped_arm()
    data = markers_only(design)
    with_reaction = softrod.Dataset(
        pressures=data.pressures,
        markers=data.markers,
        marker_s=data.marker_s,
        marker_offset=data.marker_offset,
        time=data.time,
        tip_reaction_force=np.zeros((len(data), 3)),
    )
    with pytest.raises(InputError) as exc:
        softrod.calibrate(design, with_reaction, NAMES, dynamic=True, dt=DT)
    assert exc.value.field == "dataset.tip_reaction_force"


@pytest.mark.parametrize(
    ("s", "offset", "field"),
    [(0.23, [0.0, 0.0, 0.0], "markers[1].s"), (0.1, [0.0, np.inf, 0.0], "marker_offset")],
)
def test_bad_marker_definitions_are_refused_before_any_replay(s, offset, field):
    """As in static fits: an arc length beyond the rod (the core's check, naming the
    marker) or an offset that is not finite (the dataset's check)."""
    design = softrod.load_design(ARM)
    data = markers_only(design)
    with pytest.raises(InputError) as exc:
        bad = softrod.Dataset(
            pressures=data.pressures,
            markers=data.markers,
            marker_s=[data.marker_s[0], s],
            marker_offset=[data.marker_offset[0], offset],
            time=data.time,
        )
        softrod.calibrate(design, bad, NAMES, dynamic=True, dt=DT, max_evaluations=1)
    assert exc.value.field.startswith(field)


def test_synthetic_markers_need_a_list_of_pairs():
    with pytest.raises(InputError) as exc:
        synthesize_trajectory_dataset(ARM, schedule(), 0.2, markers=[("10 mm",)], dt=DT)
    assert exc.value.field == "markers[0]"
    with pytest.raises(InputError) as exc:
        synthesize_trajectory_dataset(ARM, schedule(), 0.2, tip=False, dt=DT)
    assert exc.value.field == "tip"


def test_registration_is_fitted_with_the_markers():
    """The measurement frame's offset (registration_x, _y) fitted jointly with tau and A_eff
    from markers seen 2 mm and -1 mm away (the Registered wrapper moves the markers and
    their derivatives as in static fits)."""
    design = softrod.load_design(ARM)
    data = markers_only(design)
    seen = softrod.Dataset(
        pressures=data.pressures,
        markers=data.markers + [2e-3, -1e-3, 0.0],
        marker_s=data.marker_s,
        marker_offset=data.marker_offset,
        time=data.time,
    )
    names = [*NAMES, "registration_x", "registration_y"]
    res = softrod.calibrate(design, seen, names, dynamic=True, dt=DT)
    np.testing.assert_allclose(res.values[:2], [TAU, AREA], rtol=EXACT)
    # The offsets to the same relative accuracy of their 1-2 mm.
    np.testing.assert_allclose(res.values[2:], [2e-3, -1e-3], rtol=0, atol=EXACT * 1e-3)
