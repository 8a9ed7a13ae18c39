"""Calibration of a system of rods (``softrod.calibrate_system``): the adapter's exact
Jacobian (``_core.rod_system_sensitivity_batch``: the implicit function theorem on the
system's residual) against central differences of whole predictions for every kind of
system parameter; round trips that recover the body's Young's modulus, one rod's extension
factor and the platform's mass from the platform position and markers on the platform and
the rods (noise-free: to the solver's accuracy; noisy: within three standard errors);
datasets with markers on a system's bodies (``Dataset.marker_body``) through files; and the
refusals by name."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest
import softrod
from adapter_checks import central_difference
from conftest import assert_clean_error
from softrod import InputError, StiffnessMap
from softrod.calibration.system import (
    SystemStatic,
    calibrate_system,
    calibrated_system,
    parse_system_parameters,
)
from softrod.datasets import Dataset, load_dataset, write_dataset

pytestmark = pytest.mark.filterwarnings("error")

SYSTEM = "two_spa_platform"
#: One rod's bending factor would correlate with the platform's mass at |r| > 0.9 on these
#: rows (both mostly lower the platform); its extension factor does not.
NAMES = ["E[ecoflex_00_50_table1]", "rods[1].c_e", "platform_mass"]
#: The truth of the round trips, relative to the bundled system's values.
SCALE = np.array([1.15, 0.9, 1.25])
#: Noise-free fits stop on scipy's xtol/ftol of 1e-10 with solves converged to 1e-10:
#: the values agree to ~1e-9 relative; 1e-6 leaves three digits for the conditioning.
EXACT = 1e-6
MARKERS = [
    ("platform", ["20 mm", "0 mm", "5 mm"]),
    ("platform", ["-20 mm", "10 mm", "0 mm"]),
    ("rod0", "60 mm", ["21.1 mm", "0 mm"]),
    ("rod1", "90 mm", ["0 mm", "21.1 mm"]),
]


@pytest.fixture(scope="module")
def system():
    return softrod.load_system(SYSTEM)


def _pressures(m: int = 18, seed: int = 1) -> np.ndarray:
    """(m, 2 rods, 3 channels): each rod's chambers on or off at up to 30 kPa."""
    rng = np.random.default_rng(seed)
    return rng.uniform(5e3, 30e3, size=(m, 2, 3)) * (rng.random((m, 2, 3)) < 0.5)


def _truth(system):
    params = parse_system_parameters(NAMES, system)
    values = SCALE * np.array([p.value(system) for p in params])
    return calibrated_system(system, params, values), values


def test_system_jacobian_matches_central_differences(system):
    """Every parameter kind's column of the platform position and the markers: a rod
    parameter on both rods, one on one rod, a relative one (area_scale: the core's factor
    on the current areas, rescaled), and the platform's mass."""
    names = ["E", "rods[0].c_b", "area_scale", "platform_mass"]
    params = parse_system_parameters(names, system)
    ds = softrod.synthesize_system_dataset(system, _pressures(4), markers=MARKERS, seed=0)
    # Solves to 1e-13 (scaled): their error over the 2 h step stays ~1e-7 of a column.
    adapter = SystemStatic(system, ds, params, softrod.SolverOptions(tol=1e-13), 1)
    theta = np.array([p.value(system) for p in params]) * np.array([1.1, 0.95, 1.05, 1.2])
    rows = np.arange(len(ds))
    exact = adapter.predict(theta, rows, True)
    assert exact.ok.all()
    for quantity, d in (("tip", exact.d_tip), ("markers", exact.d_markers)):
        for j in range(len(params)):
            fd = central_difference(adapter, theta, rows, j, quantity)
            # Relative step 1e-5 (truncation ~1e-10 of the column), solve error over the
            # step ~1e-7: 1e-5 of the column's size is two digits above both; a missing
            # term (the 1/theta of area_scale, a rod's share) is off by percent.
            scale = np.abs(fd).max()
            err = np.abs(d[..., j] - fd).max()
            assert err < 1e-5 * scale, f"{quantity} / {names[j]}: {err:.2e} of {scale:.2e}"


def test_noise_free_round_trip_recovers_the_truth(system):
    truth, values = _truth(system)
    ds = softrod.synthesize_system_dataset(truth, _pressures(), markers=MARKERS, seed=0)
    res = calibrate_system(system, ds, NAMES, progress=False)
    assert res.success
    np.testing.assert_allclose(res.values, values, rtol=EXACT)
    assert res.converged.all()
    # The calibrated system predicts the data it was fitted to.
    assert np.abs(res.predicted - ds.tip_position).max() < 1e-9
    # Each rod carries its own calibrated design (rods of one file differ in mounting).
    bases = [r.design.spec["mounting"]["base_position"][0] for r in res.system.rods]
    assert bases == pytest.approx([-0.03, 0.03])
    assert res.system.rods[1].design.provenance["tool"] == "softrod.calibrate_system"
    fitted = {p["name"] for p in res.system.rods[1].design.provenance["parameters"]}
    assert fitted == {"E[ecoflex_00_50_table1]", "rods[1].c_e"}
    fitted0 = {p["name"] for p in res.system.rods[0].design.provenance["parameters"]}
    assert fitted0 == {"E[ecoflex_00_50_table1]"}
    assert res.system.platform.mass == pytest.approx(values[2], rel=EXACT)
    table = res.parameter_table()
    assert list(table["parameter"]) == NAMES
    assert list(table["unit"]) == ["Pa", "1", "kg"]
    frame = res.to_frame()
    assert frame["error_mm"].max() < 1e-6 and (frame["set"] == "train").all()


def test_noisy_round_trip_lies_within_three_standard_errors(system):
    """0.1 mm of noise on every coordinate: the estimate is Gaussian about the truth with
    the reported standard errors (linearised least squares), so each parameter lies
    within 3 of them (a fixed seed makes the check reproducible; the chance that one of
    three fails by bad luck is below 1 %)."""
    truth, values = _truth(system)
    ds = softrod.synthesize_system_dataset(
        truth, _pressures(30, seed=4), markers=MARKERS, noise_mm=0.1, seed=7
    )
    res = calibrate_system(system, ds, NAMES, progress=False)
    z = (res.values - values) / res.std_errors
    assert np.abs(z).max() < 3.0, z
    # The platform's 30 points: their RMS distance error reads the noise, sqrt(3) x 0.1 mm
    # per point (three parameters absorb little of 450 residuals). Its estimate from 90
    # coordinates has a relative standard deviation of 1/sqrt(2 x 90) = 7.5 %: 3 of them
    # allow 0.173 mm +- 22 %.
    rms = float(res.error_table.set_index("quantity")["rms_error_mm"]["platform"])
    assert 0.135 < rms < 0.211, rms


def test_split_predicts_the_test_rows(system):
    truth, values = _truth(system)
    p = _pressures(12)
    ds = softrod.synthesize_system_dataset(
        truth, p, markers=MARKERS[:2], seed=0, experiment=np.repeat([0, 1, 2], 4)
    )
    res = calibrate_system(system, ds, NAMES[:1], split="experiment", test=2, progress=False)
    assert list(res.labels) == ["train"] * 8 + ["test"] * 4
    # One parameter cannot explain the others' change: the model errs on both sets, and
    # the test rows are predicted by the calibrated system too.
    assert {"train", "test"} <= set(res.error_table["set"])
    assert np.isfinite(res.predicted).all()


def test_system_datasets_round_trip_through_files(system, tmp_path):
    ds = softrod.synthesize_system_dataset(system, _pressures(3), markers=MARKERS, seed=0)
    assert list(ds.marker_body) == [-1, -1, 0, 1]
    assert list(ds.marker_s) == [0.0, 0.0, 0.06, 0.09]
    assert "SYNTHETIC from system two_spa_platform" in repr(ds)
    for name in ("d.csv", "d.parquet"):
        write_dataset(ds, tmp_path / name)
        back = load_dataset(tmp_path / name)
        np.testing.assert_array_equal(back.marker_body, ds.marker_body)
        np.testing.assert_allclose(back.marker_offset, ds.marker_offset, rtol=1e-15)
        np.testing.assert_allclose(back.markers, ds.markers, rtol=1e-12)
        np.testing.assert_allclose(back.tip_position, ds.tip_position, rtol=1e-12)
    sub = ds.subset([0, 2])
    np.testing.assert_array_equal(sub.marker_body, ds.marker_body)


def _csv(tmp_path, markers: str) -> str:
    path = tmp_path / "bad.csv"
    path.write_text(
        "# softrod dataset\n"
        f'# metadata: {{"markers": {markers}}}\n'
        "p0_kPa,tip_x_mm,tip_y_mm,tip_z_mm,marker0_x_mm,marker0_y_mm,marker0_z_mm\n"
        "0,0,0,-130,0,0,-130\n"
    )
    return path


@pytest.mark.parametrize(
    ("markers", "field"),
    [
        ('{"marker0": {"body": "table", "offset": ["1 mm", "0 mm", "0 mm"]}}', "body"),
        (
            '{"marker0": {"body": "platform", "s": "1 mm", "offset": ["1 mm", "0 mm", "0 mm"]}}',
            ".s",
        ),
        ('{"marker0": {"body": "platform", "offset": ["1 mm", "0 mm"]}}', "offset"),
        ('{"marker0": {"body": "rod0", "offset": ["1 mm", "0 mm"]}}', "marker0"),
    ],
)
def test_bad_marker_bodies_in_files_are_refused_by_name(tmp_path, markers, field):
    with pytest.raises(InputError) as e:
        load_dataset(_csv(tmp_path, markers))
    assert "metadata.markers.marker0" in e.value.field and field in e.value.field


def test_refusals_name_the_field(system):
    ds = softrod.synthesize_system_dataset(system, _pressures(3), markers=MARKERS, seed=0)

    def field(**kw):
        args = {"system": system, "dataset": ds, "params": ["E"], "progress": False} | kw
        with pytest.raises(InputError) as e:
            calibrate_system(**args)
        return e.value.field

    assert field(params=["rods[2].E"]) == "params"
    assert field(params=["damping_time"]) == "params"
    one_rod = Dataset(pressures=ds.pressures[:, :3], tip_position=ds.tip_position)
    assert field(dataset=one_rod) == "dataset.pressures"
    far = dataclasses.replace(ds, marker_body=np.array([-1, -1, 0, 5]))
    assert field(dataset=far) == "dataset.marker_body[3]"
    no_body = Dataset(
        pressures=ds.pressures,
        tip_position=ds.tip_position,
        markers=ds.markers,
        marker_s=ds.marker_s,
        marker_offset=ds.marker_offset,
    )
    assert field(dataset=no_body) == "dataset.marker_body"
    massless = dataclasses.replace(system, platform=dataclasses.replace(system.platform, mass=0.0))
    assert field(system=massless, params=["platform_mass"]) == "params"
    # A lone design's fit refuses markers on a system's bodies.
    with pytest.raises(InputError) as e:
        softrod.calibrate(system.rods[0].design, ds.subset([0]), ["E"], progress=False)
    assert e.value.field == "dataset.marker_body"
    # Markers given in the API are checked before any solve.
    with pytest.raises(InputError) as e:
        softrod.synthesize_system_dataset(
            system, _pressures(1), markers=[("rod0", "200 mm", [0, 0])]
        )
    assert e.value.field.startswith("markers[0]")
    with pytest.raises(InputError) as e:
        softrod.synthesize_system_dataset(system, _pressures(1), markers=[("platform", [0, 0])])
    assert e.value.field == "markers[0]"


def test_frictional_systems_are_refused(system):
    table = softrod.load_system("two_fingers_on_table")
    rough = dataclasses.replace(
        table,
        rods=tuple(
            dataclasses.replace(r, design=r.design.replace({"obstacles[0].friction": 0.5}))
            for r in table.rods
        ),
    )
    p = np.zeros((1, len(rough.rods), rough.rods[0].design.n_channels))
    with pytest.raises(InputError) as e:
        softrod.synthesize_system_dataset(rough, p)
    assert "friction" in e.value.field
    ds = Dataset(
        pressures=np.zeros((1, sum(r.design.n_channels for r in rough.rods))),
        tip_position=np.zeros((1, 3)),
    )
    with pytest.raises(InputError) as e:
        calibrate_system(rough, ds, ["E"], progress=False)
    assert e.value.field == "system.rods[0].design"


def test_calibrate_system_command_writes_a_system_that_loads(system, run, tmp_path):
    """``softrod calibrate-system``: the fitted values of the API, the calibrated system
    written with its rods' designs (all loadable, solving to the API's predictions), JSON,
    and errors naming the option."""
    truth, values = _truth(system)
    ds = softrod.synthesize_system_dataset(truth, _pressures(12), markers=MARKERS, seed=0)
    write_dataset(ds, tmp_path / "pcr.csv")
    out = tmp_path / "pcr_fitted.toml"
    result = run(
        "calibrate-system", SYSTEM, tmp_path / "pcr.csv", "--params", ",".join(NAMES), "--out", out
    )
    assert result.exit_code == 0, result.output
    assert "platform_mass" in result.stdout and "wrote" in result.stdout
    # The API's fit of the same file (the CSV's mm round off the last bits of ds).
    api = calibrate_system(system, tmp_path / "pcr.csv", NAMES, progress=False)
    back = softrod.load_system(out)
    assert back.platform.mass == api.system.platform.mass
    for a, b in zip(back.rods, api.system.rods, strict=True):
        assert a.design.spec == b.design.spec
        np.testing.assert_array_equal(a.attachment, b.attachment)
    p = ds.pressures[:3].reshape(3, 2, 3)
    np.testing.assert_array_equal(
        softrod.solve_system_batch(back, p).platform_position,
        softrod.solve_system_batch(api.system, p).platform_position,
    )
    result = run(
        "calibrate-system",
        SYSTEM,
        tmp_path / "pcr.csv",
        "--params",
        "E",
        "--predictions",
        tmp_path / "pred.csv",
        "--plot",
        tmp_path / "fit.png",
        "--report",
        tmp_path / "fit.html",
    )
    assert result.exit_code == 0, result.output
    assert "softrod system calibration" in (tmp_path / "fit.html").read_text(encoding="utf-8")
    pred = pd.read_csv(tmp_path / "pred.csv", comment="#")
    assert len(pred) == len(ds) and {"error_mm", "set"} <= set(pred.columns)
    assert (tmp_path / "fit.png").read_bytes().startswith(b"\x89PNG")
    result = run("calibrate-system", SYSTEM, tmp_path / "pcr.csv", "--params", "E", "--json")
    assert result.exit_code == 0, result.output
    parsed = json.loads(result.stdout)
    assert parsed["parameters"][0]["parameter"] == "E"
    assert {e["quantity"] for e in parsed["errors"]} == {"platform", "markers"}
    # Restarts from the command line: the starts table of the API (the best fit wins).
    result = run(
        "calibrate-system",
        SYSTEM,
        tmp_path / "pcr.csv",
        "--params",
        "E",
        "--restarts",
        "1",
        "--seed",
        "3",
        "--json",
    )
    assert result.exit_code == 0, result.output
    starts = calibrate_system(
        system, tmp_path / "pcr.csv", ["E"], restarts=1, seed=3, progress=False
    )
    assert json.loads(result.stdout)["parameters"][0]["value"] == starts.values[0]
    # Registration parameters through the command line (units known for --bounds).
    result = run(
        "calibrate-system",
        SYSTEM,
        tmp_path / "pcr.csv",
        "--params",
        "E,registration_x",
        "--bounds",
        "registration_x=-5mm:5mm",
    )
    assert result.exit_code == 0, result.output
    assert "registration_x" in result.stdout
    result = run(
        "calibrate-system", SYSTEM, tmp_path / "pcr.csv", "--params", "E", "--report", "r.txt"
    )
    assert_clean_error(result, 2, "--report", "r.txt")
    result = run("calibrate-system", SYSTEM, tmp_path / "pcr.csv", "--params", "rods[4].c_b")
    assert_clean_error(result, 2, "--params", "rods[4].c_b", "2 rods")
    result = run(
        "calibrate-system", SYSTEM, tmp_path / "pcr.csv", "--params", "E", "--bounds", "E=1kPa:2kPa"
    )
    assert_clean_error(result, 2, "--bounds")


def test_a_system_is_saved_whole_or_not_at_all(system, tmp_path):
    with pytest.raises(InputError) as e:
        system.save(tmp_path / "missing" / "pcr.toml")
    assert e.value.field == "path"
    with pytest.raises(InputError) as e:
        system.save(tmp_path / "pcr.json")
    assert e.value.field == "path"
    assert list(tmp_path.iterdir()) == []
    path = system.save(tmp_path / "pcr.toml")
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "pcr.toml",
        "pcr_rod0.toml",
        "pcr_rod1.toml",
    ]
    back = softrod.load_system(path)
    assert back.name == system.name and back.platform.mass == system.platform.mass
    np.testing.assert_array_equal(back.platform.rotation, system.platform.rotation)
    for a, b in zip(back.rods, system.rods, strict=True):
        assert a.design.spec == b.design.spec
        np.testing.assert_array_equal(a.attachment_rotation, b.attachment_rotation)


def test_stiffness_mapped_rods_are_refused_in_systems(system, tmp_path):
    """sigma is never assumed to be 1: a mapped rod whose design names no stiffness map is
    refused by name in every system entry point (it once solved with sigma = 1 silently).
    With a map file the rod takes its sigma from it: synthetic data and a noise-free fit
    of the system recover the truth, and the sigma_* parameters stay refused."""
    mapped = system.rods[0].design.replace({"sections[1].law": {"stiffness_map": True}})

    def with_rod0(design):
        rod0 = dataclasses.replace(system.rods[0], design=design)
        return dataclasses.replace(system, rods=(rod0, system.rods[1]))

    sysm = with_rod0(mapped)
    field = "rods[0].design.stiffness_map"
    p = np.zeros((2, 2, 3))
    for call in (
        lambda: softrod.solve_system(sysm, p[0]),
        lambda: softrod.solve_system_batch(sysm, p),
        lambda: softrod.synthesize_system_dataset(sysm, p),
        lambda: calibrate_system(
            sysm, Dataset(pressures=np.zeros((1, 6)), tip_position=np.zeros((1, 3))), ["E"]
        ),
    ):
        with pytest.raises(InputError, match="never assumed to be 1") as e:
            call()
        assert e.value.field == field
    # A table over the rows' pressures (0..30 kPa per channel), saved and named by the
    # rod's design.
    axes = [np.array([0.0, 15e3, 30e3])] * 3
    table = np.random.default_rng(2).uniform(0.5, 1.6, (3, 3, 3, 3))
    sysm = with_rod0(
        mapped.with_stiffness_map(StiffnessMap.from_table(axes, table).save(tmp_path / "s.json"))
    )
    names = ["E[ecoflex_00_50_table1]", "platform_mass"]
    params = parse_system_parameters(names, sysm)
    values = np.array([1.15, 1.25]) * np.array([q.value(sysm) for q in params])
    truth = calibrated_system(sysm, params, values)
    rows = _pressures(8)
    ds = softrod.synthesize_system_dataset(truth, rows, seed=0)
    # sigma acts: rod 0 with sigma = 1 would hold the platform up to ~1 mm away, five
    # orders above the 1e-9 m the fit reproduces the data to below.
    ones = softrod.StiffnessMap.constant((1.0, 1.0, 1.0), 3)
    unit = softrod.solve_system_batch(truth, rows, stiffness_maps=[ones, None])
    assert np.abs(unit.platform_position - ds.tip_position).max() > 1e-4
    res = calibrate_system(sysm, ds, names, progress=False)
    assert res.success and res.converged.all()
    np.testing.assert_allclose(res.values, values, rtol=EXACT)
    assert np.abs(res.predicted - ds.tip_position).max() < 1e-9
    with pytest.raises(InputError, match="not fitted on systems"):
        calibrate_system(sysm, ds, ["sigma_ext"], progress=False)


def test_registration_of_the_measurement_frame_is_recovered(system, tmp_path):
    """Noise-free data seen in a tracker frame turned 3 degrees about the rods' mean base
    axis (through the centroid of their bases) and offset by (2, -1, 0.5) mm: the fit
    recovers the frame with E and the platform's mass."""
    truth, values = _truth(system)
    ds = softrod.synthesize_system_dataset(truth, _pressures(), markers=MARKERS, seed=0)
    base = np.mean([r.design.spec["mounting"]["base_position"] for r in system.rods], axis=0)
    axis = np.array([0.0, 0.0, -1.0])  # both rods hang: their base axes point down
    angle, offset = np.radians(3.0), np.array([2e-3, -1e-3, 0.5e-3])
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    q = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)

    def seen(x):
        return (x - base) @ q.T + base + offset

    tracked = dataclasses.replace(ds, tip_position=seen(ds.tip_position), markers=seen(ds.markers))
    names = [*NAMES, "registration_angle", "registration_x", "registration_y", "registration_z"]
    res = calibrate_system(system, tracked, names, progress=False)
    np.testing.assert_allclose(res.values[:3], values, rtol=EXACT)
    assert res.registration["angle"] == pytest.approx(angle, rel=EXACT)
    np.testing.assert_allclose(res.registration["offset"], offset, rtol=EXACT, atol=1e-12)
    assert [p.name for p in res.parameters][3:] == names[3:]
    # The calibrated system itself carries no frame: its designs hold the rods' values.
    assert res.system.platform.mass == pytest.approx(values[2], rel=EXACT)
    # The HTML report says what was fitted, the frame included, in one file.
    text = res.write_report(tmp_path / "pcr.html").read_text(encoding="utf-8")
    assert f"softrod system calibration: {SYSTEM}" in text
    assert "registration (measurement frame)" in text and "3 deg about the base axis" in text
    assert "Platform and marker errors" in text and "registration_angle" in text
    assert "Parameter correlation" in text
    assert text.count("data:image/png;base64,") >= 2  # positions and errors per set


def test_system_report_of_markers_only_and_its_refusals(system, tmp_path):
    """A dataset without the platform's position: the report's figures draw the markers;
    a report into a missing folder or not .html is refused by name, leaving no file."""
    truth, _ = _truth(system)
    ds = softrod.synthesize_system_dataset(truth, _pressures(6), markers=MARKERS, seed=0)
    res = calibrate_system(
        system, dataclasses.replace(ds, tip_position=None), ["E"], progress=False
    )
    text = res.write_report(tmp_path / "markers.html").read_text(encoding="utf-8")
    assert "(equilibria)" in text and "markers" in text
    assert text.count("data:image/png;base64,") >= 2
    for bad in (tmp_path / "missing" / "r.html", tmp_path / "r.txt"):
        with pytest.raises(InputError) as e:
            res.write_report(bad)
        assert e.value.field == "path"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["markers.html"]


def test_tendon_driven_system_round_trip():
    """Tendon tensions as the rows' inputs (two of Till's tendon robots side by side
    holding a 10 g platform; 0 pressure channels, 8 tendon channels): the bending factor
    and the platform's mass are recovered noise-free."""
    from softrod.system import Platform, System, SystemRod

    till = softrod.load_design("till_tendon_robot")
    turn = np.asarray(till.spec["mounting"]["base_rotation"])
    rods = tuple(
        SystemRod(
            design=till.replace({"mounting.base_position": ["0 m", f"{y} m", "0 m"]}),
            attachment=np.array([0.0, y, 0.0]),
            attachment_rotation=turn,
        )
        for y in (-0.05, 0.05)
    )
    pair = System("two_tills", rods, Platform(position=np.array([0.5, 0.0, 0.0]), mass=0.01))
    rng = np.random.default_rng(0)
    tensions = rng.uniform(0, 3, size=(12, 2, 4)) * (rng.random((12, 2, 4)) < 0.5)
    names = ["c_b", "platform_mass"]
    params = parse_system_parameters(names, pair)
    values = np.array([p.value(pair) for p in params]) * [1.2, 1.3]
    truth = calibrated_system(pair, params, values)
    markers = [("platform", ["0 m", "0.05 m", "0 m"]), ("rod0", "0.25 m", [0, 0])]
    ds = softrod.synthesize_system_dataset(truth, tensions=tensions, markers=markers, seed=0)
    assert ds.n_channels == 0 and ds.n_tendons == 8
    res = calibrate_system(pair, ds, names, progress=False)
    np.testing.assert_allclose(res.values, values, rtol=EXACT)


def test_system_jacobian_with_contact_matches_central_differences():
    """Two fingers pressed onto their (frictionless) table holding one clip: the contact
    penalty is a line load of each rod's shooting ODE and its rounded end's force a term of
    its tip balance, both carried by the dual passes. E's column of the clip's position
    and of markers against central differences (C1 penalty, no contact switch within the
    step): the same bound as the contact-free test."""
    pair = softrod.load_system("two_fingers_on_table")
    params = parse_system_parameters(["E"], pair)
    p = np.array([[[30e3], [30e3]], [[40e3], [35e3]], [[45e3], [20e3]]])
    ds = softrod.synthesize_system_dataset(
        pair, p, markers=[("platform", [0.01, 0, 0]), ("rod0", 0.04, [0, 0])], seed=0
    )
    assert all(r.contact.total_force[0][2] > 0 for r in softrod.solve_system(pair, p[0]).rods)
    adapter = SystemStatic(pair, ds, params, softrod.SolverOptions(tol=1e-13), 1)
    theta = np.array([params[0].value(pair)])
    rows = np.arange(len(ds))
    exact = adapter.predict(theta, rows, True)
    assert exact.ok.all()
    for quantity, d in (("tip", exact.d_tip), ("markers", exact.d_markers)):
        fd = central_difference(adapter, theta, rows, 0, quantity)
        scale = np.abs(fd).max()
        assert np.abs(d[..., 0] - fd).max() < 1e-5 * scale, quantity


def test_a_shared_parameter_on_rods_that_differ_is_refused_before_any_solve(system):
    """A parameter named on every rod is one value; where the rods' values differ the
    name is refused at parsing, naming both values and the per-rod names, for the static
    and dynamic fits and the system's motion sensitivities alike."""
    r1 = system.rods[1]
    other = dataclasses.replace(r1, design=r1.design.replace({"sections[1].c_b": 1.2}))
    mixed = dataclasses.replace(system, rods=(system.rods[0], other))
    for dynamic in (False, True):
        with pytest.raises(InputError, match=r"rods\[1\] has 1\.2.*rods\[1\]\.c_b") as e:
            parse_system_parameters(["c_b[body]"], mixed, dynamic=dynamic)
        assert e.value.field == "params"
    with pytest.raises(InputError, match="the rods differ"):
        softrod.system_trajectory_sensitivities(mixed, [[0, 0, 0], [0, 0, 0]], 0.004, "c_b[body]")
    # One per rod is fine.
    assert len(parse_system_parameters(["rods[0].c_b[body]", "rods[1].c_b[body]"], mixed)) == 2
