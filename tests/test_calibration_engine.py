"""The calibration engine (issue 19): the static fits give the values and standard errors
they gave before the engine; identifiability read off the Jacobian's near-null space for
any parameter set; motion-capture markers anywhere on the body with a registration of the
measurement frame (issue 17 item 7); the PCC model through the same engine."""

from __future__ import annotations

import json
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
import softrod
from softrod import InputError
from softrod.calibration import CalibrationWarning, calibrate
from softrod.calibration.adapters.rod_static import RodStatic
from softrod.calibration.params import design_changes, parse_parameters
from softrod.calibration.problem import Registered, RegistrationParameter
from static_fit_cases import CASES, run_case

HERE = Path(__file__).resolve().parent

#: The engine must reproduce the former fits to this (issue 19). The optimiser takes the
#: same steps on the same residuals, so values agreed bitwise and standard errors to
#: round-off (measured: at most 6e-16); since the core's integrator was restructured
#: (tapered sections, reference shapes) the residuals differ at round-off (1e-14 measured).
SAME = 1e-9
#: Nelder-Mead stops once its simplex spans xatol = 1e-8 in log theta: a round-off change
#: of the cost moves where it stops anywhere within that (measured after the integrator's
#: restructuring: 1.1e-8 on the values, 2.1e-8 on the standard errors taken there, 121
#: instead of 127 evaluations). Its values are compared at 5 x xatol; the cost, flat at the
#: optimum, still to SAME.
SIMPLEX = 5e-8


@pytest.mark.parametrize("case", CASES)
def test_static_fits_match_the_former_engine(case):
    ref = json.loads((HERE / "data" / "static_fit_reference.json").read_text())[case]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CalibrationWarning)
        res = run_case(case)
    assert res.names == ref["names"]
    rtol = SIMPLEX if case == "nelder_mead" else SAME
    np.testing.assert_allclose(res.values, ref["values"], rtol=rtol, atol=0)
    np.testing.assert_allclose(res.std_errors, ref["std_errors"], rtol=rtol, atol=0)
    assert res.cost_m2 == pytest.approx(ref["cost_m2"], rel=SAME)
    if case != "nelder_mead":  # the simplex's path follows the round-off
        assert res.evaluations == ref["evaluations"]


# --- identifiability without a pair list ----------------------------------------------------


FAST = {"numerics": {"step_length": "13 mm"}}


@pytest.fixture(scope="module")
def m3():
    return softrod.load_design("paper002_M3_vertical").replace(FAST)


def _ramps(n=4, top=50e3):
    ramp = top * np.arange(1, n + 1) / n
    return np.vstack([np.outer(ramp, q) for q in ([1, 0, 0], [0, 1, 0], [0, 0, 1], [0.6, 0.4, 0])])


def _null_vector(message: str) -> dict[str, float]:
    """{name: coefficient} of a 'not identifiable' warning's combination."""
    import re

    return {m[1]: float(m[2]) for m in re.finditer(r"([\w\[\]]+) \(([+-][0-9.]+)\)", message)}


def test_area_and_stiffness_gauge_is_found_in_a_weightless_statics(m3):
    """Without weight, scaling the chamber areas and E of the body together leaves every
    strain unchanged (paper 000 Sec. II-G's A_eff against the stiffness): the near-null
    direction of the scaled Jacobian is (+1, +1)/sqrt(2) in relative changes."""
    weightless = m3.replace({"mounting.gravity": "0 m/s^2", "tip": {"mass": "0 g"}})
    data = softrod.synthesize_dataset(weightless, _ramps(), noise_mm=0.05, seed=1)
    with pytest.warns(CalibrationWarning, match="not identifiable"):
        res = calibrate(weightless, data, ["area_scale", "E[ecoflex_00_50_table2]"])
    (msg,) = [w for w in res.warnings if "not identifiable" in w]
    v = _null_vector(msg)
    assert set(v) == {"area_scale", "E[ecoflex_00_50_table2]"}
    # Same sign, equal size: a common scale factor (to the printed digits).
    assert v["area_scale"] == pytest.approx(v["E[ecoflex_00_50_table2]"], abs=0.01)
    assert abs(v["area_scale"]) == pytest.approx(math.sqrt(0.5), abs=0.01)
    assert np.all(np.isinf(res.std_errors))


def test_area_stiffness_and_mass_gauge_is_found_under_gravity(m3):
    """Under gravity the weight breaks (area_scale, E) but not (area_scale, E, density):
    scaling all three leaves n' + rho A g = 0 with n = K (v - v*(p A / K)) unchanged. For an
    exact gauge every weight and every stiffness must scale: the caps are made of the
    body's material here and the tip body is massless."""
    material = "ecoflex_00_50_table2"
    light = m3.replace(
        {
            "mounting": {"orientation": "horizontal", "gravity": "9.81 m/s^2"},
            "sections[0].material": material,
            "sections[2].material": material,
            "tip": {"mass": "0 g"},
        }
    )
    data = softrod.synthesize_dataset(light, _ramps(), noise_mm=0.05, seed=2)
    names = ["area_scale", "E[ecoflex_00_50_table2]", "density[ecoflex_00_50_table2]"]
    with pytest.warns(CalibrationWarning, match="not identifiable"):
        res = calibrate(light, data, names)
    (msg,) = [w for w in res.warnings if "not identifiable" in w]
    v = _null_vector(msg)
    assert set(v) == set(names)
    assert np.allclose(list(v.values()), v["area_scale"], atol=0.01)  # (1, 1, 1)/sqrt(3)
    # Any two of the three are identifiable: the gravity sag pins density / E, the
    # pressure response area / E.
    with warnings.catch_warnings():
        warnings.simplefilter("error", CalibrationWarning)
        two = calibrate(light, data, names[1:])
    assert np.all(np.isfinite(two.std_errors))


# --- markers and registration -----------------------------------------------------------------


def _mocap_design():
    """Paper 002's M3 actuator mounted horizontally: its weight makes it sag, so the data
    see the density as well as E (the pressure response pins E, the sag density / E)."""
    return softrod.load_design("paper002_M3_vertical").replace(
        {**FAST, "mounting": {"orientation": "horizontal", "gravity": "9.81 m/s^2"}}
    )


#: Four markers along the rod (arc length, offset in the cross-section frame (d1, d2)).
MARKERS = [
    ("30 mm", ["10 mm", "0 mm"]),
    ("70 mm", ["0 mm", "-10 mm"]),
    ("110 mm", ["-10 mm", "0 mm"]),
    ("134 mm", ["0 mm", "12 mm", "2 mm"]),
]
E_NAME, RHO_NAME = "E[ecoflex_00_50_table2]", "density[ecoflex_00_50_table2]"
TRUTH_E, TRUTH_RHO = 92e3, 1250.0
#: The measurement frame: 3 degrees about the base axis, 2 mm offset (issue 17 item 7).
ANGLE = math.radians(3.0)
OFFSET = np.array([2e-3, -1e-3, 0.5e-3])
MOCAP_NOISE_MM = 0.1  # an optical tracker's order of accuracy


def _measured(design, seed: int, tip: bool = False):
    """Synthetic mocap data: the truth's markers, seen in the rotated and offset frame."""
    params = parse_parameters([E_NAME, RHO_NAME], design)
    truth = design.replace(design_changes(params, [TRUTH_E, TRUTH_RHO], design))
    data = softrod.synthesize_dataset(
        truth,
        _ramps(n=5, top=40e3),
        markers=MARKERS,
        tip=tip,
        noise_mm=MOCAP_NOISE_MM,
        seed=seed,
    )
    base = np.asarray(design.spec["mounting"]["base_position"])
    axis = np.asarray(design.spec["mounting"]["base_rotation"])[:, 2]
    from scipy.spatial.transform import Rotation

    q = Rotation.from_rotvec(ANGLE * axis).as_matrix()

    def frame(x):
        return (x - base) @ q.T + base + OFFSET

    return softrod.Dataset(
        pressures=data.pressures,
        tip_position=None if data.tip_position is None else frame(data.tip_position),
        markers=frame(data.markers),
        marker_s=data.marker_s,
        marker_offset=data.marker_offset,
        metadata={"synthetic": True},
    )


REGISTRATION = ["registration_angle", "registration_x", "registration_y", "registration_z"]


def test_markers_and_registration_recover_material_and_frame():
    design = _mocap_design()
    truth = {E_NAME: TRUTH_E, RHO_NAME: TRUTH_RHO, "registration_angle": ANGLE}
    truth.update(zip(REGISTRATION[1:], OFFSET, strict=True))
    inside_2 = 0
    for seed in range(3):
        data = _measured(design, seed)
        with warnings.catch_warnings():
            warnings.simplefilter("error", CalibrationWarning)  # all identifiable
            res = calibrate(design, data, [E_NAME, RHO_NAME, *REGISTRATION])
        fitted = zip(res.names, res.values, res.std_errors, strict=True)
        z = {n: (v - truth[n]) / s for n, v, s in fitted}
        # Within 3 standard errors (p = 0.3 % per value for honest errors).
        assert all(abs(x) < 3 for x in z.values()), z
        inside_2 += sum(abs(x) < 2 for x in z.values())
        # The noise of the markers, read back from the residual (0.1 mm per axis).
        assert res.rms_error_mm == pytest.approx(MOCAP_NOISE_MM * math.sqrt(3), rel=0.2)
        assert res.registration["angle"] == pytest.approx(res.values[2])
        assert res.error_table.quantity.unique().tolist() == ["markers"]
        # 3 deg and 2 mm are resolved to a few per cent and some 10 micrometres: 0.1 mm of
        # noise over 80 marker positions averages to 11 um per axis, and each offset shares
        # its direction with the rotation's lever (correlated, so up to twice that).
        assert res.std_errors[2] < 0.05 * ANGLE
        assert np.all(res.std_errors[3:] < 0.05e-3)
        # E and the density both come out, to about a per cent.
        assert np.all(res.std_errors[:2] < 0.02 * res.values[:2])
    # 18 values: at most a few outside 2 standard errors (5 % each).
    assert inside_2 >= 15


def test_without_registration_the_frame_error_shows():
    design = _mocap_design()
    data = _measured(design, 0)
    res = calibrate(design, data, [E_NAME, RHO_NAME])
    # The 3 deg / 2 mm the model cannot express stay in the residual.
    assert res.rms_error_mm > 5 * MOCAP_NOISE_MM * math.sqrt(3)


def test_registration_jacobian_matches_finite_differences():
    design = _mocap_design()
    data = _measured(design, 4, tip=True)
    params = parse_parameters([E_NAME, "c_b"], design)
    reg = [
        RegistrationParameter(n, "angle" if n.endswith("angle") else n[-1]) for n in REGISTRATION
    ]
    adapter = Registered(RodStatic(design, data, params, softrod.SolverOptions(tol=1e-12), 1), reg)
    theta = np.array([85e3, 1.2, 0.05, 1e-3, -2e-3, 0.5e-3])
    rows = np.arange(len(data))
    pred = adapter.predict(theta, rows, True)
    for j, step in enumerate([85e3 * 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6]):
        e = np.zeros_like(theta)
        e[j] = step
        plus = adapter.predict(theta + e, rows, False)
        minus = adapter.predict(theta - e, rows, False)
        pairs = ((pred.d_tip, plus.tip, minus.tip), (pred.d_markers, plus.markers, minus.markers))
        for exact, a, b in pairs:
            fd = (a - b) / (2 * step)
            # Central differences of converged solves: truncation ~step^2, solve noise
            # 1e-14 m / step; the exact column agrees to 1e-6 of its size.
            assert np.abs(exact[..., j] - fd).max() < 1e-6 * np.abs(fd).max(), j


def test_marker_datasets_round_trip_through_files(tmp_path):
    data = _measured(_mocap_design(), 5, tip=True)
    seen = data.markers.copy()
    seen[2, 1] = np.nan  # an occluded marker
    data = softrod.Dataset(
        pressures=data.pressures,
        tip_position=data.tip_position,
        markers=seen,
        marker_s=data.marker_s,
        marker_offset=data.marker_offset,
        metadata={"synthetic": True},
    )
    for suffix in (".csv", ".parquet"):
        path = softrod.write_dataset(data, tmp_path / f"mocap{suffix}")
        back = softrod.load_dataset(path)
        np.testing.assert_allclose(back.markers, data.markers, rtol=4.5e-16, atol=0)
        assert np.isnan(back.markers[2, 1]).all() and back.n_markers == 4
        np.testing.assert_array_equal(back.marker_s, data.marker_s)
        np.testing.assert_array_equal(back.marker_offset, data.marker_offset)
    # The occluded marker leaves that row's other observations in the fit.
    res = calibrate(_mocap_design(), back, [E_NAME, *REGISTRATION])
    assert res.error_table.set_index("quantity").loc["markers", "n"].item() == 4 * len(data) - 1


@pytest.mark.parametrize(
    ("kwargs", "field", "rule"),
    [
        ({"markers": np.zeros((2, 1, 3))}, "marker_s", "where each marker sits"),
        (
            {"markers": np.full((2, 1, 3), np.nan), "marker_s": [0.0], "marker_offset": [[0, 0]]},
            "markers",
            "at least one seen marker",
        ),
        (
            {
                "markers": np.array([[[0.0, np.nan, 0.0]], [[0.0, 0.0, 0.0]]]),
                "marker_s": [0.0],
                "marker_offset": [[0, 0]],
            },
            "markers[0, 0]",
            "seen (x, y, z all given)",
        ),
        (
            {"markers": np.zeros((2, 1, 3)), "marker_s": [-1.0], "marker_offset": [[0, 0]]},
            "marker_s",
            ">= 0",
        ),
        ({"tip_position": np.zeros((2, 3)), "marker_s": [0.1]}, "marker_s", "needs markers"),
    ],
)
def test_bad_marker_data_is_refused(kwargs, field, rule):
    with pytest.raises(InputError) as err:
        softrod.Dataset(pressures=np.zeros((2, 3)), **kwargs)
    assert err.value.field == field and rule in str(err.value)


def test_markers_beyond_the_rod_and_bad_weights_are_refused():
    design = _mocap_design()
    data = _measured(design, 0)
    far = softrod.Dataset(
        pressures=data.pressures,
        markers=data.markers,
        marker_s=np.array([0.03, 0.07, 0.11, 0.5]),
        marker_offset=data.marker_offset,
    )
    with pytest.raises(InputError, match=r"markers\[3\]\.s.*\[0, L\]"):
        calibrate(design, far, [E_NAME])
    with pytest.raises(InputError, match="no tip columns"):
        calibrate(design, data, [E_NAME], weights={"tip": "0.1 mm"})
    with pytest.raises(InputError, match="length > 0"):
        calibrate(design, data, [E_NAME], weights={"markers": "0 mm"})
    with pytest.raises(InputError, match="needs the tip position"):
        softrod.calibration.identify_stiffness(design, data)


def test_weights_scale_each_quantity():
    """Tip and markers with different noise: weighting each by its own standard deviation
    gives standard errors that describe the scatter (the residual in units of each scale
    is N(0, 1))."""
    design = _mocap_design()
    data = _measured(design, 7, tip=True)
    res = calibrate(
        design,
        data,
        [E_NAME, RHO_NAME, *REGISTRATION],
        weights={"tip": f"{MOCAP_NOISE_MM} mm", "markers": f"{MOCAP_NOISE_MM} mm"},
    )
    n = 3 * (len(data) + data.markers.shape[0] * data.markers.shape[1])
    assert res.cost / (n - 6) == pytest.approx(1.0, rel=0.25)
    assert res.scales == {"tip": 1e-4, "markers": 1e-4}


def test_one_report_for_markers_and_registration(tmp_path):
    """The one report format holds a marker fit with its registration: the parameters with
    their units, the per-quantity error table, the warnings' rules."""
    design = _mocap_design()
    res = calibrate(design, _measured(design, 5), [E_NAME, *REGISTRATION])
    html = res.write_report(tmp_path / "mocap.html").read_text(encoding="utf-8")
    for text in ("registration_angle", "registration_z", E_NAME, "markers", "Rules:"):
        assert text in html, text
    text = " ".join(re.sub("<[^>]+>", " ", html).split())
    assert "model cosserat dataset" in text  # equilibria: no "(time series replayed)"
