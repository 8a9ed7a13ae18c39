"""Static calibration from a held tip's measured reaction (the blocked force): the reaction
columns of a dataset (``tip_reaction_fx_N`` ..., docs/datasets.md), their exact Jacobian
in the fit (``Rod.sensitivity_batch(..., tip_kind=...)``'s ``d_tip_reaction_*``: the
implicit function theorem on the held residual) against finite differences, round trips
that recover E and the area factor from the reactions alone, the error tables, and the
refusals by name (a free tip with reactions, a held tip with neither markers nor
reactions, bad reaction values and weights)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
import softrod
from softrod import InputError
from softrod.calibration import CalibrationWarning, calibrate
from softrod.calibration.adapters.rod_static import RodStatic
from softrod.calibration.params import design_changes, parse_parameters
from softrod.calibration.result import result_json

pytestmark = pytest.mark.filterwarnings("error")

SPA = "spa_three_chamber_130mm"
NAMES = ["E", "area_scale"]
#: The truth of the round trips: E 10 % above the design's, the area factor 1.08.
SCALE = [1.1, 1.08]
#: Noise-free fits stop on scipy's xtol/ftol of 1e-10 with solves converged to 1e-10
#: (scaled residual): the values agree to ~1e-9 relative; 1e-6 leaves three digits for the
#: conditioning of E against the area factor (tests/test_calibration_fit.py's EXACT).
EXACT = 1e-6
#: A bench load cell's noise per force component (the default weight of "reaction").
SIGMA_N = 5e-3


def _straight(design):
    """The tip pose of the straight, unloaded rod: base + L d3, the base's orientation."""
    mount = design.spec["mounting"]
    rot = np.asarray(mount["base_rotation"])
    return np.asarray(mount["base_position"]) + design.length * rot[:, 2], rot


def _held(kind: str, aside_mm: float = 5.0):
    """The SPA with its tip held at the straight pose moved ``aside_mm`` along world x
    (clamped with the straight orientation, or pinned). Held exactly at the straight pose,
    the blocked force is that of the pressure alone (linear theory: the actuation moment
    over its arm, whatever the stiffness), so E would be all but unidentifiable; held
    aside, the rod's stiffness pushes back too."""
    design = softrod.load_design(SPA)
    pos, rot = _straight(design)
    pos = pos + np.array([aside_mm * 1e-3, 0.0, 0.0])
    tip = {"constraint": kind, "position": [f"{float(v)!r} m" for v in pos]}
    if kind == "clamped":
        tip["orientation"] = rot.tolist()
    return design.replace({"tip": tip})


def _pressures() -> np.ndarray:
    ramp = 10e3 * np.arange(1, 5)
    return np.vstack([np.outer(ramp, pat) for pat in ([1, 0, 0], [0, 1, 0], [0.5, 0, 0.5])])


def _truth(held):
    params = parse_parameters(NAMES, held)
    values = [s * p.value(held) for s, p in zip(SCALE, params, strict=True)]
    return held.replace(design_changes(params, values, held)), values


def _blocked(held, sigma: float = 0.0, seed: int = 0, moment: bool = False):
    """The blocked forces (and moments) of the truth at _pressures(), with Gaussian noise
    of ``sigma`` N per component (moments: sigma times 0.1 m, in N m); no tip columns and
    no markers."""
    truth, _ = _truth(held)
    p = _pressures()
    batch = softrod.solve_statics_batch(truth, p)
    assert batch.converged.all()
    rng = np.random.default_rng(seed)
    force = batch.tip_reaction_force + sigma * rng.standard_normal((len(p), 3))
    torque = batch.tip_reaction_moment + 0.1 * sigma * rng.standard_normal((len(p), 3))
    return softrod.Dataset(
        pressures=p, tip_reaction_force=force, tip_reaction_moment=torque if moment else None
    )


@pytest.fixture(scope="module", params=["clamped", "pinned"])
def held(request):
    return _held(request.param)


@pytest.fixture(scope="module")
def clamped():
    return _held("clamped")


def test_reaction_jacobian_of_the_fit_matches_finite_differences(held):
    """The reaction's Jacobian as calibrate assembles it (the adapter reads the core's
    d_tip_reaction_*; area_scale's chain rule; E with G) against central differences of
    whole held solves."""
    names = [*NAMES, "c_b"]
    params = parse_parameters(names, held)
    data = _blocked(held, moment=True)
    rows = np.arange(0, len(data), 3)
    theta = np.array([1.05 * params[0].value(held), 1.04, 1.1])
    model = RodStatic(held, data, params, softrod.SolverOptions(tol=1e-12), 1)
    pred = model.predict(theta, rows, True)
    assert pred.ok[rows].all()
    # Relative steps of 1e-4: the solves' noise (~1e-12 of the 4 N reaction) over the step
    # stays below 1e-7 of a column of ~0.1 N, the truncation (step^2) ~1e-8.
    for j in range(len(names)):
        e = np.zeros_like(theta)
        e[j] = 1e-4 * theta[j]
        plus = model.predict(theta + e, rows, False)
        minus = model.predict(theta - e, rows, False)
        for what, d in (("reaction", pred.d_reaction), ("reaction_moment", pred.d_reaction_moment)):
            fd = (getattr(plus, what)[rows] - getattr(minus, what)[rows]) / (2 * e[j])
            scale = np.abs(fd).max()
            if what == "reaction_moment" and held.tip_constraint.kind == "pinned":
                # A pin carries no moment, whatever the parameters.
                assert scale == 0.0 and np.all(d[rows, :, j] == 0.0)
                continue
            assert scale > 0, (names[j], what)
            # The exact column agrees to 1e-5 of its size (as the markers' check in
            # tests/test_calibration_held_tip.py; measured at most 3.5e-8, E of the pin).
            err = np.abs(d[rows, :, j] - fd).max() / scale
            assert err < 1e-5, (names[j], what, err)


def test_noise_free_blocked_forces_recover_E_and_the_area_factor(clamped):
    data = _blocked(clamped)
    _, truth = _truth(clamped)
    # Held 5 mm aside, E and the area factor are separated: no CalibrationWarning (the
    # module turns warnings into errors).
    res = calibrate(clamped, data, NAMES)
    assert res.success
    for name, v, t in zip(res.names, res.values, truth, strict=True):
        assert v == pytest.approx(t, rel=EXACT), name
    # Reactions only: no position rows; the reaction table reads in mN.
    assert len(res.error_table) == 0 and math.isnan(res.rms_error_mm)
    table = res.reaction_error_table
    assert table["quantity"].tolist() == ["reaction"] and table["unit"].item() == "mN"
    assert table["n"].item() == len(data) and table["failed"].item() == 0
    assert table["max_error"].item() < 1e-5  # mN: the solves' tolerance
    assert "mN" in res.summary()
    np.testing.assert_allclose(res.predicted_reaction, data.tip_reaction_force, atol=1e-8)


def test_noisy_blocked_forces_lie_within_three_standard_errors(clamped):
    """With SIGMA_N noise per component and the matching weight (the default), every
    estimate lies within 3 standard errors of the truth, and the residual reads the noise
    back."""
    _, truth = _truth(clamped)
    for seed in range(3):
        data = _blocked(clamped, sigma=SIGMA_N, seed=seed)
        res = calibrate(clamped, data, NAMES, weights={"reaction": "5 mN"})
        z = (res.values - truth) / res.std_errors
        assert np.all(np.abs(z) < 3), (seed, z)
        # 36 residuals, 2 parameters: the RMS per component estimates sigma within ~12 %
        # (one standard deviation of a chi with 34 dof); 35 % is three of them.
        rms_mN = res.reaction_error_table["rms_error"].item() / math.sqrt(3)
        assert rms_mN == pytest.approx(1e3 * SIGMA_N, rel=0.35), seed


def test_at_the_straight_pose_the_blocked_force_hardly_sees_E():
    """Held exactly at its straight pose the blocked force is the pressure's alone (linear
    theory: the actuation moment over its arm, whatever the stiffness), so the same data
    pin the area factor but not E: reported, not fitted silently (docs/calibration.md)."""
    straight = _held("clamped", aside_mm=0.0)
    with pytest.warns(CalibrationWarning) as record:
        res = calibrate(straight, _blocked(straight, sigma=SIGMA_N), NAMES)
    found = [str(w.message) for w in record]
    assert any("E is poorly determined" in w for w in found), found
    assert any("strongly correlated" in w for w in found), found
    # Measured: 430 % for E, 17 % for the area factor (5 % aside: 0.4 % and 0.06 %).
    assert res.std_errors[0] / res.values[0] > 1.0


def test_moments_and_one_axis_load_cells_enter_the_fit(clamped):
    """A clamp's moment enters with its own weight; a one-axis load cell (fx and fy not
    measured: NaN) still recovers both parameters from fz alone plus the moments."""
    full = _blocked(clamped, moment=True)
    force = np.array(full.tip_reaction_force)
    force[:, :2] = np.nan
    data = softrod.Dataset(
        pressures=full.pressures,
        tip_reaction_force=force,
        tip_reaction_moment=full.tip_reaction_moment,
    )
    _, truth = _truth(clamped)
    res = calibrate(clamped, data, NAMES, weights={"reaction_moment": "0.2 N*mm"})
    assert res.scales == {"reaction": SIGMA_N, "reaction_moment": 2e-4}
    np.testing.assert_allclose(res.values, truth, rtol=EXACT)
    assert res.reaction_error_table["quantity"].tolist() == ["reaction", "reaction_moment"]
    assert res.reaction_error_table["unit"].tolist() == ["mN", "N mm"]


def test_result_table_and_report_carry_the_reactions(clamped, tmp_path):
    data = _blocked(clamped, sigma=SIGMA_N)
    res = calibrate(clamped, data, NAMES, split=np.arange(len(data)) % 4 == 3)
    sets = res.reaction_error_table["set"].tolist()
    assert sets == ["train", "test", "all"]
    frame = res.to_frame()
    names = [f"tip_reaction_f{a}_N" for a in "xyz"] + [f"model_tip_reaction_f{a}_N" for a in "xyz"]
    assert set(names) <= set(frame.columns) and "reaction_error_N" in frame.columns
    back = softrod.load_dataset(frame)
    np.testing.assert_allclose(back.tip_reaction_force, data.tip_reaction_force, rtol=1e-15)
    html = res.write_report(tmp_path / "report.html").read_text()
    assert "Reaction errors" in html
    assert '"reaction_errors"' in result_json(res)


def test_a_sweep_table_of_a_held_tip_is_a_blocked_force_dataset(clamped):
    """The held sweep's reaction columns (result columns of solve_statics_batch's table)
    are read back as the measured reaction, same names, same units."""
    truth, _ = _truth(clamped)
    batch = softrod.solve_statics_batch(truth, _pressures())
    data = softrod.load_dataset(batch.to_frame())
    np.testing.assert_array_equal(data.tip_reaction_force, batch.tip_reaction_force)
    np.testing.assert_allclose(data.tip_reaction_moment, batch.tip_reaction_moment, rtol=1e-15)
    assert "tip_reaction_fx_N" not in data.extra


def test_reaction_columns_with_empty_cells_read_as_not_measured(tmp_path):
    path = tmp_path / "blocked.csv"
    path.write_text(
        "p0_kPa,p1_kPa,p2_kPa,tip_reaction_fx_mN,tip_reaction_fy_mN,tip_reaction_fz_N\n"
        "10,0,0,,,1.5\n"
        "20,0,0,12,-3,2.5\n"
    )
    data = softrod.load_dataset(path)
    assert data.tip_position is None and data.markers is None
    np.testing.assert_array_equal(
        data.tip_reaction_force, [[np.nan, np.nan, 1.5], [12e-3, -3e-3, 2.5]]
    )
    assert data.tip_reaction_moment is None


def test_a_free_tip_with_reactions_is_refused_by_name():
    free = softrod.load_design(SPA)
    data = _blocked(_held("clamped"))
    with pytest.raises(InputError) as exc:
        calibrate(free, data, NAMES)
    assert exc.value.field == "dataset.tip_reaction_force"
    assert "free tip" in str(exc.value)


def test_a_held_tip_with_neither_markers_nor_reactions_is_refused(clamped):
    truth, _ = _truth(clamped)
    data = softrod.synthesize_dataset(truth, _pressures())
    with pytest.raises(InputError) as exc:
        calibrate(clamped, data, NAMES)
    assert exc.value.field == "dataset.markers"
    assert "tip_reaction_fx_N" in str(exc.value)


@pytest.mark.parametrize(
    ("force", "field", "rule"),
    [
        (np.full((12, 3), np.inf), "tip_reaction_force[0][0]", "must be finite"),
        (np.zeros((12, 2)), "tip_reaction_force", "(m, 3)"),
        (np.full((12, 3), np.nan), "tip_reaction_force", "nothing measured"),
        ([["1 N", 0, 0]] * 12, "tip_reaction_force", "not text"),
    ],
)
def test_bad_reaction_values_are_refused_naming_the_field(force, field, rule):
    with pytest.raises(InputError) as exc:
        softrod.Dataset(pressures=_pressures(), tip_reaction_force=force)
    assert exc.value.field == field
    assert rule in str(exc.value)


@pytest.mark.parametrize(
    ("header", "row", "field", "rule"),
    [
        (
            "tip_reaction_fx_mm,tip_reaction_fy_N,tip_reaction_fz_N",
            "1,0,0",
            "tip_reaction_fx_mm",
            "force",
        ),
        ("tip_reaction_fx_N,tip_reaction_fy_N", "1,0", "columns", "tip_reaction_fz"),
        (
            "tip_reaction_fx_N,tip_reaction_fy_N,tip_reaction_fz_N",
            "1,inf,0",
            "tip_reaction_fy_N",
            "finite",
        ),
        (
            "tip_reaction_fx_N,tip_reaction_fy_N,tip_reaction_fz_N",
            "1,one,0",
            "tip_reaction_fy_N",
            "not a number",
        ),
    ],
)
def test_bad_reaction_columns_are_refused_naming_the_column(tmp_path, header, row, field, rule):
    path = tmp_path / "bad.csv"
    path.write_text(f"p0_kPa,{header}\n10,{row}\n")
    with pytest.raises(InputError) as exc:
        softrod.load_dataset(path)
    assert exc.value.field == field
    assert rule in str(exc.value)


def test_reaction_weights_are_forces_and_moments(clamped):
    data = _blocked(clamped)
    for weights, key, rule in [
        ({"reaction": "5 mm"}, "reaction", "force"),
        ({"reaction": "-5 mN"}, "reaction", "a force > 0"),
        ({"reaction_moment": "1 N*mm"}, "reaction_moment", "no reaction_moment columns"),
        ({"markers": "1 mm"}, "markers", "no markers columns"),
    ]:
        with pytest.raises(InputError) as exc:
            calibrate(clamped, data, NAMES, weights=weights)
        assert exc.value.field == f"weights[{key!r}]", weights
        assert rule in str(exc.value), (weights, str(exc.value))


def test_dataframe_round_trip_keeps_unmeasured_components():
    force = np.array([[np.nan, 0.1, 1.0], [0.2, np.nan, 2.0]])
    data = softrod.Dataset(pressures=[[1e4, 0, 0], [2e4, 0, 0]], tip_reaction_force=force)
    frame = data.to_frame()
    assert list(frame.columns[-3:]) == [f"tip_reaction_f{a}_N" for a in "xyz"]
    back = softrod.load_dataset(frame)
    np.testing.assert_array_equal(back.tip_reaction_force, force)
    assert "tip_reaction_force" in repr(back)
    assert isinstance(frame, pd.DataFrame)


def test_cli_fits_blocked_forces_and_prints_the_reaction_errors(clamped, tmp_path, run):
    design = tmp_path / "held.toml"
    clamped.save(design)
    data = tmp_path / "blocked.csv"
    softrod.write_dataset(_blocked(clamped), data)
    out = run("calibrate", design, data, "--params", "E,area_scale", "--weights", "reaction=5mN")
    assert out.exit_code == 0, out.output
    assert "tip reaction errors" in out.output and "mN" in out.output
    assert "position errors" not in out.output  # no measured positions


def test_a_load_cell_turned_about_the_base_axis_is_registered(clamped):
    """A load cell's frame turned by 3 degrees about the base axis: the reactions rotate
    with it (no offset), and registration_angle recovers the turn with E and the area
    factor (noise-free)."""
    data = _blocked(clamped)
    axis = np.asarray(clamped.spec["mounting"]["base_rotation"])[:, 2]
    angle = math.radians(3.0)
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    turn = np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)
    seen = softrod.Dataset(
        pressures=data.pressures, tip_reaction_force=data.tip_reaction_force @ turn.T
    )
    res = calibrate(clamped, seen, [*NAMES, "registration_angle"])
    _, truth = _truth(clamped)
    np.testing.assert_allclose(res.values[:2], truth, rtol=EXACT)
    assert res.registration["angle"] == pytest.approx(angle, rel=EXACT)


def test_markers_and_reactions_fit_together(clamped):
    """Markers and blocked forces in one dataset: one residual, both tables."""
    truth, values = _truth(clamped)
    mocap = softrod.synthesize_dataset(
        truth, _pressures(), markers=[("60 mm", ["10 mm", "0 mm"])], tip=False
    )
    both = softrod.Dataset(
        pressures=mocap.pressures,
        markers=mocap.markers,
        marker_s=mocap.marker_s,
        marker_offset=mocap.marker_offset,
        tip_reaction_force=_blocked(clamped).tip_reaction_force,
    )
    res = calibrate(clamped, both, NAMES)
    np.testing.assert_allclose(res.values, values, rtol=EXACT)
    assert res.error_table["quantity"].tolist() == ["markers"]
    assert res.reaction_error_table["quantity"].tolist() == ["reaction"]
