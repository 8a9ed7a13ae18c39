"""``softrod calibrate`` and ``softrod calibrate-axial``, driven through click's CliRunner.

The calibration data are made here: the coarse paper 002 model M3 (13 mm steps) solved at
15 pressure combinations without noise, three experiments. A fit that starts from a wrong
c_b must come back to the c_b that made the data.
"""

import io
import json

import numpy as np
import pytest
import softrod
import tomli_w
from conftest import assert_clean_error
from rich.console import Console
from softrod import ConvergenceError
from softrod.calibration import axial_example_paths, identify_axial, load_axial_data
from softrod.calibration.params import design_changes, parse_parameters
from softrod.cli.calibrate import _FitProgress

pytestmark = pytest.mark.fast  # the whole module runs in seconds

PRESET = "paper002_M3_vertical"
C_B_START = 1.3  # the fits start from c_b 30 % off the value that made the data
# The data are the model's own noise-free tip positions, so the fit can return the exact
# parameter: what is left is the shooting solver's tolerance and the optimiser's xtol (1e-10
# on log c_b); the fits here land within 1e-10. 1e-6 leaves a margin and still fails for
# any fit that stops early (the start is 30 % off).
RECOVERY_RTOL = 1e-6
# A noise-free fit reproduces the data to round-off (nm); 1e-6 mm is far below any real
# error and far above round-off.
EXACT_FIT_MM = 1e-6


def _write_design(design, path):
    path.write_text(tomli_w.dumps(design.document), encoding="utf-8")
    return path


def _pressures() -> np.ndarray:
    rows = []
    for level in np.linspace(12e3, 60e3, 5):
        rows += [[level, 0, 0], [0, level, 0], [0, 0, level]]
    return np.array(rows)


def _c_b(design) -> float:
    return parse_parameters("c_b", design)[0].value(design)


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    """Files of one calibration problem: the true design, a start design with a wrong c_b,
    the dataset they made (experiments 1, 2, 3) and the same for a design without gravity."""
    folder = tmp_path_factory.mktemp("calibration")
    truth = softrod.load_design(PRESET).replace({"numerics": {"step_length": "13 mm"}})
    c_b = _c_b(truth)
    start = truth.replace(design_changes(parse_parameters("c_b", truth), [C_B_START * c_b], truth))
    data = softrod.synthesize_dataset(
        truth, _pressures(), noise_mm=0.0, seed=1, experiment=np.tile([1, 2, 3], 5)
    )
    weightless = truth.replace({"mounting.gravity": "0 m/s^2"})
    weightless_data = softrod.synthesize_dataset(weightless, _pressures(), noise_mm=0.0, seed=2)
    return {
        "truth": truth,
        "c_b": c_b,
        "truth_toml": _write_design(truth, folder / "truth.toml"),
        "start_toml": _write_design(start, folder / "start.toml"),
        "data": softrod.write_dataset(data, folder / "d.csv"),
        "weightless_toml": _write_design(weightless, folder / "weightless.toml"),
        "weightless_data": softrod.write_dataset(weightless_data, folder / "weightless.csv"),
    }


def flat(text: str) -> str:
    """Text with rich's line wrapping undone (the console is 80 columns in the tests)."""
    return " ".join(text.split())


# --------------------------------------------------------------------------- calibrate


def test_calibrate_recovers_c_b_and_writes_design_and_report(run, case, tmp_path):
    assert _c_b(softrod.load_design(case["start_toml"])) != pytest.approx(case["c_b"], rel=0.1)
    out, report = tmp_path / "calibrated.toml", tmp_path / "report.html"
    result = run(
        "calibrate",
        case["start_toml"],
        case["data"],
        "--params",
        "c_b",
        "--split",
        "experiment",
        "--test",
        "3",  # a string on the command line; the dataset's ids are integers
        "--out",
        out,
        "--report",
        report,
        "--threads",
        1,
    )
    assert result.exit_code == 0, result.output
    assert result.stderr == ""  # no terminal: no progress line, and no warnings here
    text = flat(result.stdout)
    header = "calibrate c_b of paper002_M3_vertical (cosserat) on d.csv (SYNTHETIC): 15 samples"
    assert header in text
    assert "calibrated parameters" in text and "position errors" in text
    assert f"wrote {out}" in text and f"wrote {report}" in text
    assert "warning:" not in text
    # No warnings, and the rules it was judged by (docs/calibration.md).
    assert "no warnings: warnings when a relative standard error exceeds 20 %" in text
    assert "correlation |r| exceeds 0.9" in text

    fitted = softrod.load_design(out)
    assert _c_b(fitted) == pytest.approx(case["c_b"], rel=RECOVERY_RTOL)
    assert "Calibrated with softrod.calibrate" in fitted.assumptions[-1]
    # A new name and the provenance, in the file.
    assert fitted.name == "paper002_M3_vertical_calibrated"
    prov = fitted.provenance
    assert prov["tool"] == "softrod.calibrate" and prov["softrod_version"] == softrod.__version__
    assert prov["dataset"] == "d.csv" and prov["synthetic_data"] is True
    assert prov["initial_design"] == "paper002_M3_vertical" and prov["training_samples"] == 10
    (entry,) = prov["parameters"]
    assert entry["name"] == "c_b" and entry["unit"] == "1"
    assert entry["value"] == pytest.approx(case["c_b"], rel=RECOVERY_RTOL)
    assert len(prov["date"]) == 25  # ISO 8601 with seconds and UTC offset
    # The written design reproduces the data (the test experiment too).
    data = softrod.load_dataset(case["data"])
    tips = softrod.solve_statics_batch(fitted, data.pressures).tip_position
    err_mm = np.linalg.norm(tips - data.tip_position, axis=1) * 1e3
    assert err_mm.max() < EXACT_FIT_MM
    # The table: one row per set, 10 training and 5 test samples (experiment 3).
    for line in ("train 10 0 0.000", "test 5 0 0.000", "all 15 0 0.000"):
        assert line in " ".join(text.replace("│", " ").split()), line

    html = report.read_text(encoding="utf-8")
    assert html.lstrip().lower().startswith("<!doctype html") and "c_b" in html
    assert sorted(tmp_path.iterdir()) == sorted([out, report])  # no staging files left


def test_calibrate_json_is_clean_and_matches_the_fit(run, case):
    result = run(
        "calibrate",
        case["start_toml"],
        case["data"],
        "--params",
        "c_b,c_e",
        "--split",
        "experiment",
        "--test",
        "1,2",
        "--json",
    )
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)  # nothing but JSON on stdout
    assert set(data) == {"model", "dynamic", "parameters", "errors", "warnings"}
    assert result.stderr == ""
    params = {p["parameter"]: p for p in data["parameters"]}
    assert params["c_b"]["value"] == pytest.approx(case["c_b"], rel=RECOVERY_RTOL)
    c_e = parse_parameters("c_e", case["truth"])[0].value(case["truth"])
    assert params["c_e"]["value"] == pytest.approx(c_e, rel=RECOVERY_RTOL)
    assert params["c_b"]["initial"] == pytest.approx(C_B_START * case["c_b"], rel=1e-12)
    sets = {row["set"]: row for row in data["errors"]}
    assert (sets["train"]["n"], sets["test"]["n"]) == (5, 10)  # experiments 1 and 2 test
    assert sets["test"]["max_error_mm"] < EXACT_FIT_MM
    assert data["warnings"] == []


def test_calibrate_bounds_take_units(run, case):
    (material,) = {
        s.get("material") for s in case["truth"].document["sections"] if s.get("chambers")
    }
    name = f"E[{material}]"
    e_true = parse_parameters(name, case["truth"])[0].value(case["truth"])
    assert e_true == pytest.approx(80e3)  # Ecoflex 00-50, paper 002 Table II
    args = ["calibrate", case["truth_toml"], case["data"], "--params", name, "--json"]
    # 40-200 kPa contains the design's E; read as bare Pa (40-200 Pa) it would not. A unit
    # on the upper bound alone applies to both.
    for bounds in (f"{name}=40kPa:200kPa", f"{name}=40:200kPa", f"{name}=0.04:0.2MPa"):
        ok = run(*args, "--bounds", bounds)
        assert ok.exit_code == 0, ok.output
        (row,) = json.loads(ok.stdout)["parameters"]
        assert row["unit"] == "Pa"
        assert row["value"] == pytest.approx(e_true, rel=RECOVERY_RTOL)
    # 400-900 kPa does not contain 80 kPa: refused before the fit, naming --bounds.
    bad = run(*args, "--bounds", f"{name}=400kPa:900kPa")
    assert_clean_error(bad, 2, "--bounds", f"{name}=400kPa:900kPa", "must contain")


def test_calibrate_unidentifiable_set_warns_once(run, case):
    # Without gravity, scaling the chamber areas and every stiffness together leaves the
    # tips where they are (pressure forces over stiffness), and nothing here twists or
    # shears measurably: the Jacobian is singular.
    args = [
        "calibrate",
        case["weightless_toml"],
        case["weightless_data"],
        "--params",
        "area_scale,c_s,c_e,c_b,c_t",
    ]
    result = run(*args)
    assert result.exit_code == 0, result.output
    text = flat(result.stdout)
    assert "warning: not identifiable" in text
    assert "area_scale" in text.split("warning:", 1)[1]
    assert "CalibrationWarning" not in result.output  # printed by the CLI, not by Python
    assert result.stderr == ""
    assert "inf" in text  # the standard errors of a singular fit

    as_json = run(*args, "--json")
    assert as_json.exit_code == 0, as_json.output
    warnings = json.loads(as_json.stdout)["warnings"]
    assert any(w.startswith("not identifiable") for w in warnings)
    # With --json the warnings go to stderr, each once.
    assert flat(as_json.stderr).count("warning: ") == len(warnings)


@pytest.mark.parametrize(
    ("args", "fragments"),
    [
        (["--params", "c_x"], ["--params", "c_x", "unknown parameter"]),
        (["--params", "c_b[cap_a,nope]"], ["--params", "no section named 'nope'"]),
        (["--params", "c_b", "--bounds", "c_b=1"], ["--bounds", "NAME=LO:HI"]),
        (["--params", "c_b", "--bounds", "c_b:1:3"], ["--bounds", "NAME=LO:HI"]),
        (["--params", "c_b", "--bounds", "c_e=1:3"], ["--bounds", "not one of the calibrated"]),
        (["--params", "c_b", "--bounds", "c_b=a:3"], ["--bounds c_b.lower", "a number"]),
        (["--params", "c_b", "--bounds", "c_b=2:3"], ["--bounds", "must contain"]),
        (
            ["--params", "c_b", "--bounds", "c_b=0.5:3", "--bounds", "c_b=1:2"],
            ["--bounds", "twice"],
        ),
        (["--params", "c_b", "--out", "{out}/nodir/c.toml"], ["--out", "does not exist"]),
        (["--params", "c_b", "--out", "{out}/c.txt"], ["--out", ".toml"]),
        (["--params", "c_b", "--report", "{out}/r.pdf"], ["--report", ".html"]),
        (["--params", "c_b", "--report", "{out}/nodir/r.html"], ["--report", "does not exist"]),
        (["--params", "sigma_ext", "--out", "{out}/c.toml"], ["--out", "sigma_ext"]),
        (["--params", "c_b", "--test", "3"], ["--test", "needs --split"]),
        (["--params", "c_b", "--split", "experiment", "--test", "7"], ["--test", "unknown"]),
        (["--params", "c_b", "--split", "mounting"], ["--split", "no mounting column"]),
    ],
    ids=[
        "unknown-param",
        "unknown-section",
        "bounds-no-range",
        "bounds-no-equals",
        "bounds-not-fitted",
        "bounds-not-a-number",
        "bounds-exclude-start",
        "bounds-twice",
        "out-no-folder",
        "out-suffix",
        "report-suffix",
        "report-no-folder",
        "sigma-not-a-design",
        "test-without-split",
        "unknown-test-id",
        "no-mounting-column",
    ],
)
def test_calibrate_bad_inputs(run, case, tmp_path, args, fragments):
    args = [a.replace("{out}", str(tmp_path)) for a in args]
    result = run("calibrate", case["start_toml"], case["data"], *args)
    assert_clean_error(result, 2, *fragments)
    assert result.stdout == ""  # refused before the fit started
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_calibrate_missing_data_file(run, case, tmp_path):
    result = run("calibrate", case["start_toml"], tmp_path / "nope.csv", "--params", "c_b")
    assert_clean_error(result, 2, "DATA", "no such file")


def test_calibrate_failed_write_leaves_no_file(run, case, tmp_path, monkeypatch):
    def broken(self, path):
        raise OSError(28, "No space left on device", str(path))

    monkeypatch.setattr(softrod.calibration.fit.CalibrationResult, "write_report", broken)
    out, report = tmp_path / "c.toml", tmp_path / "r.html"
    result = run(
        "calibrate", case["start_toml"], case["data"], "--params", "c_b", "--out", out,
        "--report", report,
    )  # fmt: skip
    assert result.exit_code == 2, result.output
    assert "No space left on device" in result.stderr
    assert list(tmp_path.iterdir()) == []  # the design is not written without the report


def test_calibrate_convergence_failure_exits_3(run, case, monkeypatch):
    def fail(*args, **kwargs):
        raise ConvergenceError("calibrate: the model did not converge for 3 training samples")

    monkeypatch.setattr("softrod.calibration.fit.calibrate", fail)
    result = run("calibrate", case["start_toml"], case["data"], "--params", "c_b")
    assert_clean_error(result, 3, "did not converge")


def test_fit_progress_line():
    calls = []
    buffer = io.StringIO()
    terminal = Console(file=buffer, force_terminal=True, width=100)
    with _FitProgress(lambda: calls.append(1), terminal) as progress:
        progress(1, 2.5)
        progress(2, 0.75)
        progress(3, 1.5)
    assert calls == [1] and progress.best == 0.75
    shown = buffer.getvalue()
    assert "3 evaluations" in shown and "RMS tip error 1.5 mm (best 0.75 mm)" in shown

    quiet = io.StringIO()
    with _FitProgress(None, Console(file=quiet, force_terminal=False)) as progress:
        progress(1, 2.5)
    assert quiet.getvalue() == "" and progress.evaluations == 1


# --------------------------------------------------------------------------- calibrate-axial


def test_calibrate_axial_writes_a_design_that_loads(run, tmp_path):
    force, length = axial_example_paths()
    out = tmp_path / "axial.toml"
    result = run("calibrate-axial", force, length, "--design", "modular_two_module", "--out", out)
    assert result.exit_code == 0, result.output
    api = identify_axial(load_axial_data(force, length, n_chambers=3))
    text = result.stdout
    assert "SYNTHETIC" in text
    assert f"A_eff        {api.A_eff * 1e6:.5g} mm^2" in text
    assert f"E (constant) {api.E:.5g} N" in text
    assert f"wrote {out}" in flat(text)
    design = softrod.load_design(out)
    assert design.name == "modular_two_module_axial"
    assert f"E = {api.E:.5g}" in design.assumptions[-1]
    sol = softrod.solve_statics(design, [95e3, 0, 0])
    assert sol.converged
    assert list(tmp_path.iterdir()) == [out]


def test_calibrate_axial_table_with_given_L0(run):
    force, length = axial_example_paths()
    result = run(
        "calibrate-axial", force, length, "--design", "modular_two_module", "--stiffness",
        "table", "--force-law", "affine", "--L0", "44.8 mm", "--name", "mine",
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    text = result.stdout
    assert "(given)" in text and "E(F) table" in text and "b (offset)" in text
    assert "design mine" in text and "not written" in text


@pytest.mark.parametrize(
    ("args", "fragments"),
    [
        (["--L0", "44.8 kPa"], ["--L0", "length"]),
        (["--rigid-length", "abc"], ["--rigid-length"]),
        (["--out", "{out}/a.csv"], ["--out", ".toml"]),
        (["--out", "{out}/nodir/a.toml"], ["--out", "does not exist"]),
        (["--chambers", "4"], ["n_chambers = 4"]),
    ],
    ids=["L0-unit", "rigid-length", "out-suffix", "out-no-folder", "chambers"],
)
def test_calibrate_axial_bad_inputs(run, tmp_path, args, fragments):
    force, length = axial_example_paths()
    args = [a.replace("{out}", str(tmp_path)) for a in args]
    result = run("calibrate-axial", force, length, "--design", "modular_two_module", *args)
    assert_clean_error(result, 2, *fragments)
    assert list(tmp_path.iterdir()) == []


def test_calibrate_axial_missing_file(run, tmp_path):
    force, _ = axial_example_paths()
    result = run("calibrate-axial", force, tmp_path / "l.csv", "--design", "modular_two_module")
    assert_clean_error(result, 2, "LENGTH_CSV", "no such file")


# --- softrod identify (paper 001 per-sample identification) ---------------------------------


def test_identify_writes_the_factors_and_the_report(run, tmp_path):
    from softrod.datasets import example_dataset_path

    data = example_dataset_path("spa130_synthetic")
    out, report = tmp_path / "sigma.csv", tmp_path / "ident.html"
    # DATA by the bundled name (the path works the same).
    res = run(
        "identify", "spa_three_chamber_130mm", "spa130_synthetic", "--out", out, "--report", report
    )
    assert res.exit_code == 0, res.output
    assert "sigma_ext identified" in res.output
    ds = softrod.load_dataset(out)  # the dataset schema, read back
    assert ds.metadata["generator"] == "softrod.identify_stiffness"
    # The tip columns are the example's, which is synthetic: so is the table.
    assert ds.metadata["dataset"] == data.name and ds.synthetic is True
    measured = softrod.load_dataset(data)
    # The measured columns are the dataset's (kPa/mm and back: 2 ulp).
    np.testing.assert_allclose(ds.tip_position, measured.tip_position, rtol=1e-15)
    np.testing.assert_array_equal(ds.experiment, measured.experiment)
    frame = ds.to_frame()
    assert len(frame) == 216 and {"sigma_ext", "sigma_bend_x", "sigma_bend_y"} <= set(frame)
    # The example was made with sigma = 1 everywhere plus 0.3 mm noise: identified factors
    # scatter around 1 (median within 5 %).
    assert abs(frame["sigma_ext"].median() - 1) < 0.05
    assert report.read_text().count("data:image/png") >= 3


def test_identify_rejects_bad_outputs_before_working(run, tmp_path):
    from softrod.datasets import example_dataset_path

    data = example_dataset_path("spa130_synthetic")
    res = run("identify", "spa_three_chamber_130mm", data, "--out", tmp_path / "s.txt")
    assert_clean_error(res, 2, "--out")
    res = run("identify", "spa_three_chamber_130mm", data, "--sections", "nose")
    assert_clean_error(res, 2, "nose")
    assert list(tmp_path.iterdir()) == []
