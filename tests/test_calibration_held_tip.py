"""Static calibration of a design whose ``[tip]`` pins or clamps the tip: synthetic marker
data of the held equilibria (``synthesize_dataset``) and round trips through ``calibrate``,
whose Jacobian is the held tip's exact sensitivities (``Rod.sensitivity_batch(...,
tip_kind=...)``: the implicit function theorem on the held residual, docs/calibration.md
"A held tip"); a held tip without markers is refused, in static and dynamic fits."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import softrod
from softrod import InputError
from softrod.calibration import CalibrationWarning, calibrate
from softrod.calibration.params import design_changes, parse_parameters

pytestmark = pytest.mark.filterwarnings("error")

#: Paper 002's M3 model with 13 mm RK4 steps, mounted horizontally: its weight makes it sag,
#: so the data see E through weight / stiffness as well as through pressure / stiffness, and
#: the area factor through the pressure response only (as the free tip's mocap test).
FAST = {
    "numerics": {"step_length": "13 mm"},
    "mounting": {"orientation": "horizontal", "gravity": "9.81 m/s^2"},
}
#: Four markers along the rod (arc length, offset in the cross-section frame (d1, d2)).
MARKERS = [
    ("30 mm", ["10 mm", "0 mm"]),
    ("70 mm", ["0 mm", "-10 mm"]),
    ("110 mm", ["-10 mm", "0 mm"]),
    ("125 mm", ["0 mm", "12 mm", "2 mm"]),
]
NAMES = ["E", "area_scale"]
TRUTH = [92e3, 1.12]
#: Noise-free fits stop on scipy's xtol/ftol of 1e-10 with solves converged to 1e-10
#: (scaled residual): the values agree to ~1e-9 relative where the parameters are well
#: conditioned; 1e-6 leaves three digits for the conditioning of E against the area factor
#: (the same bound as tests/test_calibration_fit.py's EXACT).
EXACT = 1e-6
MOCAP_NOISE_MM = 0.1  # an optical tracker's order of accuracy


def _base():
    return softrod.load_design("paper002_M3_vertical").replace(FAST)


def _held(design, kind: str):
    """The design with its tip held: pinned 6 mm above and 4 mm beside the free unloaded
    tip (so the pin carries a force), or clamped there turned 0.1 rad about the world y."""
    free = softrod.solve_statics(design, [0.0, 0.0, 0.0])
    pos = free.tip_position + np.array([4e-3, 0.0, 6e-3])
    tip = {"constraint": kind, "position": [f"{float(v)!r} m" for v in pos]}
    if kind == "clamped":
        c, s = math.cos(0.1), math.sin(0.1)
        turn = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
        tip["orientation"] = (turn @ free.tip_rotation).tolist()
    return design.replace({"tip": tip})


def _pressures(n: int = 5, top: float = 40e3) -> np.ndarray:
    ramp = top * np.arange(1, n + 1) / n
    return np.vstack([np.outer(ramp, pat) for pat in ([1, 0, 0], [0, 1, 0], [0, 0, 1])])


def _truth(held):
    return held.replace(design_changes(parse_parameters(NAMES, held), TRUTH, held))


def _data(held, noise_mm: float = 0.0, seed: int = 0, markers=MARKERS):
    return softrod.synthesize_dataset(
        _truth(held), _pressures(), markers=markers, noise_mm=noise_mm, seed=seed
    )


@pytest.fixture(scope="module", params=["pinned", "clamped"])
def held(request):
    return _held(_base(), request.param)


def test_held_dataset_is_the_held_equilibrium(held):
    data = _data(held)
    c = held.tip_constraint
    # The tip columns hold the prescribed position (to the solve's tolerance), the markers
    # the held rod's: the same as solve_statics_batch's held equilibria read at the markers.
    np.testing.assert_allclose(data.tip_position, np.tile(c.position, (len(data), 1)), atol=1e-9)
    batch = softrod.solve_statics_batch(_truth(held), data.pressures)
    np.testing.assert_array_equal(data.tip_position, batch.tip_position)
    assert data.metadata["tip_constraint"]["type"] == c.kind
    free = _data(_base())
    # Holding the tip moves the markers by millimetres (not vacuous).
    assert np.abs(free.markers - data.markers).max() > 1e-3


def test_fit_jacobian_of_a_held_tip_matches_finite_differences(held):
    """The markers' Jacobian as calibrate assembles it for a held tip (the adapter calls the
    held-tip sensitivities; area_scale's chain rule; E with G) against central differences
    of whole held solves; the held tip's own columns vanish."""
    from softrod.calibration.adapters.rod_static import RodStatic

    names = [*NAMES, "c_b", "alpha"]
    params = parse_parameters(names, held)
    data = _data(held)
    rows = np.arange(0, len(data), 4)
    theta = np.array([1.1 * 80e3, 1.07, 1.2, 8.0])
    model = RodStatic(held, data, params, softrod.SolverOptions(tol=1e-12), 1)
    pred = model.predict(theta, rows, True)
    assert pred.ok[rows].all()
    # Relative steps of 1e-4 (alpha: 1e-3 of 8): the held rod moves less than a free one
    # (theta |dy/dtheta| ~ 0.5 mm for E), so the solves' noise (~1e-13 m at tol 1e-12)
    # over the step stays below 2e-6 of a column, and the truncation (step^2) ~1e-8.
    for j, step in enumerate([80e3 * 1e-4, 1e-4, 1e-4, 8e-3]):
        e = np.zeros_like(theta)
        e[j] = step
        plus = model.predict(theta + e, rows, False).markers[rows]
        minus = model.predict(theta - e, rows, False).markers[rows]
        fd = (plus - minus) / (2 * step)
        # The exact column agrees to 1e-5 of its size (as tests/test_calibration_fit.py;
        # measured at most 1.5e-8, E of the pinned tip).
        scale = np.abs(fd).max()
        assert scale > 0, names[j]
        assert np.abs(pred.d_markers[rows, :, :, j] - fd).max() < 1e-5 * scale, names[j]
        # The held tip: zero up to round-off (the core's tests bound it at 1e-9 of the
        # largest marker derivative; measured here at most 2.2e-14).
        assert np.abs(pred.d_tip[rows, :, j]).max() < 1e-9 * scale, names[j]


def test_noise_free_round_trip_recovers_E_and_the_area_factor(held):
    data = _data(held)
    # From the design's values (E as designed, area factor 1).
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CalibrationWarning)  # correlation is reported below
        res = calibrate(held, data, NAMES)
    assert res.success
    for name, v, t in zip(res.names, res.values, TRUTH, strict=True):
        assert v == pytest.approx(t, rel=EXACT), name
    assert res.rms_error_mm < 1e-5


#: Noise seeds of the noisy round trips.
SEEDS = 6


def test_noisy_round_trips_have_honest_standard_errors(held):
    """Over SEEDS noise draws the z-scores (fit - truth) / std_error of E and the area
    factor are those of honest standard errors: each within 4 (p = 6e-5 per value, so a
    wrong error would show while a 3-sigma draw, expected about once in 12 runs of these
    2 x 6 correlated values, does not fail the test) and, per parameter, a mean square
    inside the central 99.8 % of chi^2 with SEEDS degrees of freedom over SEEDS."""
    from scipy.stats import chi2

    zs = []
    for seed in range(SEEDS):
        data = _data(held, noise_mm=MOCAP_NOISE_MM, seed=seed)
        with warnings.catch_warnings():
            # E and the area factor correlate (|r| ~ 0.9): both scale the pressure response
            # (reported as a CalibrationWarning; the weight separates them).
            warnings.simplefilter("ignore", CalibrationWarning)
            res = calibrate(held, data, NAMES)
        zs.append([(v - t) / s for v, t, s in zip(res.values, TRUTH, res.std_errors, strict=True)])
        # The noise, read back from the residual (0.1 mm per axis, 3 axes; the tip columns
        # are the prescribed position plus the same noise).
        assert res.rms_error_mm == pytest.approx(MOCAP_NOISE_MM * math.sqrt(3), rel=0.2)
    z = np.array(zs)
    assert np.all(np.abs(z) < 4), z
    lo, hi = chi2.ppf([0.001, 0.999], SEEDS) / SEEDS
    msq = (z**2).mean(axis=0)
    assert np.all((lo < msq) & (msq < hi)), (msq, lo, hi)


def test_held_tip_without_markers_is_refused(held):
    """A held tip does not move with any parameter: its tip columns carry no information,
    so a dataset without markers is refused naming dataset.markers (not fitted to a
    silent answer)."""
    data = _data(held, markers=None)
    with pytest.raises(InputError) as exc:
        calibrate(held, data, NAMES)
    assert exc.value.field == "dataset.markers"
    assert "needs markers" in str(exc.value)


def test_dynamic_fit_of_a_held_tip_without_markers_is_refused_with_its_reason(held):
    """The dynamic fit reads a held tip's markers (tests/test_calibration_dynamic_markers.py);
    without them it is refused by name, before any replay."""
    data = _data(held, markers=None)
    with pytest.raises(InputError) as exc:
        calibrate(held, data, ["damping_time"], dynamic=True, dt=1e-3)
    assert exc.value.field == "dataset.markers"
    assert "calibrate(dynamic=True) of a held tip needs markers" in str(exc.value)


def test_held_sensitivity_batch_refuses_bad_constraints_naming_the_field(held):
    rod = held._rod
    p = np.array([[1e4, 0.0, 0.0], [0.0, 1e4, 0.0]])
    zero = [0.0, 0.0, 0.0]
    for kw, field in [
        ({"tip_kind": "glued"}, "tip_constraint.type"),
        ({"tip_kind": "pinned"}, "tip_constraint.position"),
        ({"tip_kind": "clamped", "tip_position": zero}, "tip_constraint.orientation"),
        ({"tip_kind": "pinned", "tip_position": [0.0, np.nan, 0.0]}, "tip_constraint.position[1]"),
        # A held tip has 6 unknowns per row: a free tip's (m, 3) warm starts are refused.
        ({"tip_kind": "pinned", "tip_position": zero, "x0": np.zeros((2, 3))}, "x0"),
    ]:
        with pytest.raises(InputError) as exc:
            rod.sensitivity_batch(p, zero, zero, [("E", [1])], **kw)
        assert exc.value.field == field, kw
