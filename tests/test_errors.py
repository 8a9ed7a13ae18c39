"""Bad input fails loudly: DesignError / InputError naming the field; ConvergenceError."""

import math

import numpy as np
import pytest
import softrod
from conftest import DELETE, with_entries
from softrod import (
    ConvergenceError,
    DesignError,
    InputError,
    SolverOptions,
    load_design,
    solve_statics,
    solve_statics_batch,
)
from softrod.plotting import plot_shape

pytestmark = pytest.mark.fast  # the whole module runs in seconds

SPA = "spa_three_chamber_130mm"
BODY = "sections[1]"  # the chambered Ecoflex body of SPA
EF = "materials.ecoflex_00_50_table1"  # its inline material


# (id, entry to change, new value, field the error must name)
DESIGN_CASES = [
    ("unknown-key-top", "colour", "red", "colour"),
    ("unknown-key-design", "design.autor", "me", "design.autor"),
    ("unknown-key-section", f"{BODY}.lenght", "110 mm", f"{BODY}.lenght"),
    ("unknown-key-chamber", f"{BODY}.chambers[0].radus", "5 mm", f"{BODY}.chambers[0].radus"),
    ("unknown-key-material", f"{EF}.youngs", "1 kPa", f"{EF}.youngs"),
    ("missing-length", f"{BODY}.length", DELETE, f"{BODY}.length"),
    ("missing-citation", "design.citation", DELETE, "design.citation"),
    (
        "missing-chamber-distance",
        f"{BODY}.chambers[2].distance",
        DELETE,
        f"{BODY}.chambers[2].distance",
    ),
    ("missing-sections", "sections", DELETE, "sections"),
    ("wrong-unit-length", f"{BODY}.length", "110 kPa", f"{BODY}.length"),
    ("wrong-unit-modulus", f"{EF}.E", "82.7 mm", f"{EF}.E"),
    ("zero-length", f"{BODY}.length", "0 mm", f"{BODY}.length"),
    ("negative-length", f"{BODY}.length", "-110 mm", f"{BODY}.length"),
    ("zero-outer-radius", f"{BODY}.outer_radius", "0 mm", f"{BODY}.outer_radius"),
    (
        "negative-chamber-radius",
        f"{BODY}.chambers[0].radius",
        "-5.15 mm",
        f"{BODY}.chambers[0].radius",
    ),
    ("bore-equals-outer", f"{BODY}.bore_radius", "21.1 mm", f"{BODY}.bore_radius"),
    ("bore-above-outer", f"{BODY}.bore_radius", "30 mm", f"{BODY}.bore_radius"),
    (
        "chamber-outside-section",
        f"{BODY}.chambers[0].distance",
        "18 mm",
        f"{BODY}.chambers[0].distance",
    ),
    (
        "chamber-overlaps-bore",
        f"{BODY}.chambers[0].distance",
        "6 mm",
        f"{BODY}.chambers[0].distance",
    ),
    ("chambers-overlap", f"{BODY}.chambers[1].angle", "100 deg", f"{BODY}.chambers[1].angle"),
    # An inline material's errors name the [materials] entry the value came from.
    ("zero-E", f"{EF}.E", "0 kPa", f"{EF}.E"),
    ("negative-E", f"{EF}.E", "-82.7 kPa", f"{EF}.E"),
    ("poisson-0.6", f"{EF}.poisson", 0.6, f"{EF}.poisson"),
    ("poisson-minus-1", f"{EF}.poisson", -1.0, f"{EF}.poisson"),
    ("nan-length", f"{BODY}.length", float("nan"), f"{BODY}.length"),
    ("nan-correction-factor", f"{BODY}.c_b", float("nan"), f"{BODY}.c_b"),
    ("inf-mm", f"{BODY}.outer_radius", "inf mm", f"{BODY}.outer_radius"),
    ("unknown-material", f"{BODY}.material", "unobtainium", f"{BODY}.material"),
    ("unknown-orientation", "mounting.orientation", "sideways", "mounting.orientation"),
    # The design sets steps_per_section, so any step_length also breaks "not both".
    ("step-length-and-steps", "numerics.step_length", "5 mm", "numerics.step_length"),
    ("zero-steps", "numerics.steps_per_section", 0, "numerics.steps_per_section"),
]


@pytest.mark.parametrize(
    ("path", "value", "field"), [c[1:] for c in DESIGN_CASES], ids=[c[0] for c in DESIGN_CASES]
)
def test_bad_design_raises_design_error(path, value, field):
    doc = with_entries(SPA, {path: value})
    with pytest.raises(DesignError) as info:
        load_design(doc)
    exc = info.value
    assert exc.field == field
    assert field in str(exc)
    assert exc.rule  # the message says what the value must satisfy


def test_malformed_toml(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text('[design]\nname = "unterminated\n')
    with pytest.raises(DesignError) as info:
        load_design(path)
    assert info.value.field == str(path)
    assert "not valid TOML" in str(info.value) and str(path) in str(info.value)


def test_error_from_file_names_file_and_field(tmp_path):
    text = (softrod.designs_dir() / f"{SPA}.toml").read_text()
    path = tmp_path / "typo.toml"
    path.write_text(text.replace('bore_radius = "2.9 mm"', 'bore_radus = "2.9 mm"', 1))
    with pytest.raises(DesignError) as info:
        load_design(path)
    assert info.value.field == "sections[0].bore_radus"
    assert str(info.value).startswith("typo.toml: sections[0].bore_radus")


def test_unknown_design_name():
    with pytest.raises(DesignError) as info:
        load_design("no_such_design")
    assert info.value.field == "design"
    assert SPA in str(info.value)  # the message lists what exists


# Per-call inputs: InputError (a DesignError subclass) naming the argument.
def _spa():
    return load_design(SPA)


INPUT_CASES = [
    ("too-few-pressures", lambda d: solve_statics(d, [0.0, 0.0]), "pressures"),
    ("too-many-pressures", lambda d: solve_statics(d, [0.0] * 4), "pressures"),
    ("below-vacuum", lambda d: solve_statics(d, ["-1.5 bar", 0, 0]), "pressures[0]"),
    ("pressure-wrong-unit", lambda d: solve_statics(d, [0, "30 mm", 0]), "pressures[1]"),
    ("pressure-nan", lambda d: solve_statics(d, [0, 0, float("nan")]), "pressures[2]"),
    ("pressure-inf", lambda d: solve_statics(d, [0, 0, "inf kPa"]), "pressures[2]"),
    ("tip-force-length", lambda d: solve_statics(d, [0, 0, 0], tip_force=[0, 1]), "tip_force"),
    (
        "tip-force-unit",
        lambda d: solve_statics(d, [0, 0, 0], tip_force=["1 m", 0, 0]),
        "tip_force[0]",
    ),
    ("options-type", lambda d: solve_statics(d, [0, 0, 0], options={"tol": 1e-8}), "options"),
    ("options-max-iter", lambda d: SolverOptions(max_iter=0), "max_iter"),
    ("options-tol", lambda d: SolverOptions(tol=2.0), "tol"),
    ("batch-shape", lambda d: solve_statics_batch(d, np.zeros((4, 2))), "pressures"),
    ("batch-threads", lambda d: solve_statics_batch(d, np.zeros((4, 3)), threads=-1), "threads"),
    # Methods of results and designs (values of the wrong type once escaped as TypeError,
    # ValueError or OverflowError from inside numpy or pathlib).
    ("jacobian-params", lambda d: _sol(d).jacobian(params=np.zeros((2, 2))), "params"),
    ("modes-count-zero", lambda d: _lin(d).modes(0), "count"),
    ("modes-count-text", lambda d: _lin(d).modes("2"), "count"),
    ("modes-count-inf", lambda d: _lin(d).modes(math.inf), "count"),
    ("response-omega-text", lambda d: _lin(d).frequency_response("x"), "omega"),
    ("response-omega-huge", lambda d: _lin(d).frequency_response(1e300), "omega"),
    ("save-path-none", lambda d: d.save(None), "path"),
    ("save-path-bytes", lambda d: d.save(b"x.toml"), "path"),
    ("toml-path-number", lambda d: d.toml_text(3), "path"),
    ("map-path-number", lambda d: d.with_stiffness_map(3), "path"),
    ("obstacles-number", lambda d: d.with_obstacles(3), "obstacles"),
    ("shape-title", lambda d: plot_shape(_sol(d), title=np.zeros((2, 2))), "title"),
    ("table-path", lambda d: softrod.io.check_table_path(3), "path"),
    # Counts and springs that once allocated or overflowed (found by the function fuzz).
    (
        "restarts-huge",
        lambda d: softrod.calibrate(d, _synthetic(d), "c_b", restarts=10**12),
        "restarts",
    ),
    (
        "restarts-over",
        lambda d: softrod.calibrate(d, _synthetic(d), "c_b", restarts=10_001),
        "restarts",
    ),
    ("restarts-seed", lambda d: softrod.calibrate(d, _synthetic(d), "c_b", seed=-1), "seed"),
    ("experiment-huge", lambda d: _synthetic(d, experiment=2**70), "experiment"),
    ("experiment-text", lambda d: _synthetic(d, experiment="9" * 30), "experiment"),
    ("experiment-float", lambda d: _synthetic(d, experiment=[0.0, 1e300]), "experiment"),
    (
        "spring-huge",
        lambda d: softrod.identify_stiffness(d, _synthetic(d), n_high=1e300),
        "n_high / r_high",
    ),
    (
        "spring-tiny",
        lambda d: softrod.identify_stiffness(d, _synthetic(d), m_high=1e-300),
        "m_high / R_high",
    ),
]


def _synthetic(design, **kwargs):
    return softrod.synthesize_dataset(design, [[0.0] * 3, [2e4, 0.0, 0.0]], **kwargs)


def _sol(design):
    return solve_statics(design, [20e3, 0.0, 0.0])


def _lin(design):
    return softrod.linearise(design, [20e3, 0.0, 0.0], nodes=3)


@pytest.mark.parametrize(
    ("call", "field"), [c[1:] for c in INPUT_CASES], ids=[c[0] for c in INPUT_CASES]
)
def test_bad_call_input_raises_input_error(call, field):
    with pytest.raises(InputError) as info:
        call(_spa())
    assert info.value.field == field
    assert field in str(info.value)


# A case Newton cannot finish in one iteration: the horizontal actuator at 60 kPa needs
# several from the straight initial guess, and continuation is switched off.
HARD = ("spa_three_chamber_134mm_horizontal", [60e3, 0.0, 0.0])
ONE_STEP = SolverOptions(max_iter=1, continuation=False)


def test_convergence_error_has_diagnostics():
    name, p = HARD
    with pytest.raises(ConvergenceError) as info:
        solve_statics(name, p, options=ONE_STEP)
    exc = info.value
    assert exc.iterations == 1
    assert math.isfinite(exc.residual) and exc.residual > ONE_STEP.tol
    assert "converge" in str(exc)
    # With the defaults the same problem converges: the failure came from the options.
    assert solve_statics(name, p).converged


def test_convergence_failure_without_check_returns_nan_solution():
    name, p = HARD
    sol = solve_statics(name, p, options=ONE_STEP, check=False)
    assert sol.converged is False
    assert sol.iterations == 1 and sol.residual > ONE_STEP.tol
    for arr in (sol.position, sol.rotation, sol.force, sol.moment, sol.v, sol.u):
        assert np.all(np.isnan(arr))
    assert np.all(np.isnan(sol.tip_position))


# Methods of datasets, schedules, maps and system runs: an argument of the wrong type is an
# InputError naming it (these once escaped as TypeError or ValueError).
METHOD_CASES = [
    ("rows-text-number", lambda: _data().rows_text(3), "rows"),
    ("rows-text-names", lambda: _data().rows_text(["a"]), "rows[0]"),
    ("rows-text-beyond", lambda: _data().rows_text([0, 10**6]), "rows[1]"),
    ("split-test-float", lambda: _data().split(test=1.5), "test"),
    (
        "schedule-times-text",
        lambda: softrod.PressureSchedule.constant([0.0]).to_frame("x"),
        "times",
    ),
    ("map-networks-number", lambda: softrod.StiffnessMap.from_networks(3), "networks"),
    ("system-concat-number", lambda: softrod.SystemTrajectory.concat(3), "parts"),
    ("reference-time-text", lambda: _tracker().reference("x"), "t"),
    ("errors-not-a-trajectory", lambda: _tracker().errors(3), "trajectory"),
    ("distance-text", lambda: _workspace().distance_to("x"), "point"),
    ("workspace-figure-name", lambda: _workspace().plot(path=""), "path"),
    ("compare-models-number", lambda: softrod.compare_models(models=0), "models"),
    ("mesh-field-number", lambda: softrod.read_mesh("m.stl", field=3), "field"),
    ("stl-faces-number", lambda: softrod.write_stl("m.stl", [[0, 0, 0]] * 3, 5), "faces"),
    ("tip-loads-none", lambda: softrod.Simulation(SPA).set_tip_loads(force=None), "force"),
]


def _tracker():
    tip = solve_statics(SPA, [20e3, 0.0, 0.0]).tip_position
    return softrod.TrackingController(SPA, softrod.TargetPath([0.0, 1.0], [tip, tip]), rate=100.0)


def _workspace():
    return softrod.workspace(SPA, samples=3)


def _data():
    return softrod.load_dataset("spa130_synthetic").subset(range(4))


@pytest.mark.parametrize(
    ("call", "field"), [c[1:] for c in METHOD_CASES], ids=[c[0] for c in METHOD_CASES]
)
def test_bad_method_arguments_raise_input_error(call, field):
    with pytest.raises(InputError) as info:
        call()
    assert info.value.field == field
