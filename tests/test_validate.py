"""The validated boundary (softrod/_validate.py): the unit grammar, strict numbers, limits,
the bare-number rule of design files and the CLI, and the atomic file writes."""

import math
import os

import numpy as np
import pandas as pd
import pytest
import softrod
from conftest import DELETE, assert_clean_error, with_entries
from softrod import DesignError, InputError, load_design
from softrod import _validate as V
from softrod.io import atomic_path, check_target, remove_stale_temporaries, staged_paths

pytestmark = pytest.mark.fast

SPA = "spa_three_chamber_130mm"


# --- the unit grammar ------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "kind", "si"),
    [
        ("110 mm", "length", 0.11),
        ("110mm", "length", 0.11),
        ("0.6 bar", "pressure", 6e4),
        ("82.7 kPa", "pressure", 82.7e3),
        ("1.2e-3 N*m^2", "stiffness_bending", 1.2e-3),
        ("1.2e3 N*mm^2", "stiffness_bending", 1.2e-3),
        ("1070 kg/m^3", "density", 1070.0),
        ("9.81 m/s^2", "acceleration", 9.81),
        ("3 Nmm", "moment", 3e-3),
        ("3 N m", "moment", 3.0),
        ("3 N·m", "moment", 3.0),
        ("2 N*m/rad", "moment", 2.0),
        ("1 N*s/m", "damping_linear", 1.0),
        ("83.3 mm**2", "area", 83.3e-6),
        ("-1 N", "force", -1.0),
        ("30 deg", "angle", math.radians(30)),
        ("90°", "angle", math.pi / 2),
        ("0.25 turn", "angle", math.pi / 2),
        ("5 psi", "pressure", 5 * 6894.757293168361),
        ("0", "length", 0.0),
    ],
)
def test_grammar_reads_quantities(text, kind, si):
    assert V.quantity(text, kind, "x", bare="error") == pytest.approx(si, rel=1e-12)


@pytest.mark.parametrize(
    ("text", "kind", "words"),
    [
        ("10**10**10 mm", "length", "expected a unit symbol"),
        ("9" * 400 + " mm", "length", "too long"),
        ("30 deg", "length", "no dimension"),
        ("30 deg", "pressure", "no dimension"),
        ("5 %", "length", "no dimension"),
        ("5 mm/m", "length", "no dimension"),
        ("0.5 %", "mass", "no dimension"),
        ("5 %", "angle", "angle unit"),
        ("1 degC", "length", "[temperature]"),
        ("1 m**9", "area", "exponent"),
        ("1 kPx", "pressure", "unknown unit 'kPx'"),
        ("inf mm", "length", "finite"),
        ("1e400 mm", "length", "finite"),
        ("nan kPa", "pressure", "finite"),
        ("mm", "length", "does not start with a number"),
        ("1 (mm)", "length", "expected a unit symbol"),
        ("90", "length", "bare number"),
    ],
)
def test_grammar_refuses(text, kind, words):
    with pytest.raises(InputError) as info:
        V.quantity(text, kind, "x", bare="error")
    assert words in info.value.rule
    assert info.value.field == "x" and info.value.value == text


def test_expressions_are_never_evaluated():
    # pint's expression parser would try to build 10**(10**10): the grammar stops at "**".
    import time

    t0 = time.perf_counter()
    for text in ("10**10**10 mm", "2**2**2**2**2**2 mm", "1 m**10**10"):
        with pytest.raises(InputError):
            V.quantity(text, "length", "x")
    assert time.perf_counter() - t0 < 0.5


@pytest.mark.parametrize(
    "value", [True, np.bool_(False), 1 + 2j, None, [1.0], {"a": 1}, b"1", 10**400]
)
def test_numbers_are_real(value):
    with pytest.raises(InputError):
        V.real(value, "x")


def test_numpy_scalars_are_numbers():
    assert V.real(np.float32(0.5), "x") == 0.5
    assert V.integer(np.int64(3), "x") == 3
    assert V.quantity(np.float64(2.0), "pressure", "x") == 2.0


@pytest.mark.parametrize("value", [1.5, 2.0, "2", True, 2**70])
def test_integers_are_integers(value):
    with pytest.raises(InputError):
        V.integer(value, "n", minimum=0, maximum=10**6)


def test_threads_are_bounded():
    assert V.threads(0) == 0
    with pytest.raises(InputError) as info:
        V.threads(100_000)
    assert str(V.MAX_THREADS) in info.value.rule


@pytest.mark.parametrize(
    ("value", "words"),
    [
        (np.ma.masked_array([1.0, 2.0], mask=[True, False]), "masked"),
        (np.array([1 + 1j]), "complex"),
        (np.array([True]), "booleans"),
        ({"a": 1.0}, "mapping"),
        ("1,2", "text"),
        (np.zeros(2, dtype="datetime64[ns]"), "datetime64"),
        ([1.0, [2.0]], "regular array"),
        (np.array([1.0, np.inf]), "finite"),
    ],
)
def test_arrays_refuse_surprises(value, words):
    with pytest.raises(InputError) as info:
        V.real_array(value, "p")
    assert words in str(info.value)


def test_arrays_accept_unit_strings_element_by_element():
    got = V.real_array(["30 kPa", np.float32(1.0), 0], "p", unit_kind="pressure")
    assert got.tolist() == [30e3, 1.0, 0.0]


def test_depth_is_checked_without_recursion():
    deep: list = []
    for _ in range(100_000):
        deep = [deep]
    with pytest.raises(InputError, match="deeper than"):
        V.check_depth(deep, "metadata")


# --- design documents -------------------------------------------------------------------------


def test_bare_number_names_field_and_fix():
    with pytest.raises(DesignError) as info:
        load_design(with_entries(SPA, {"sections[0].length": 90}))
    exc = info.value
    assert exc.field == "sections[0].length" and exc.value == 90
    assert '"90 mm"' in exc.rule and 'units = "SI"' in exc.rule


def test_units_si_reads_bare_numbers_as_si():
    doc = with_entries(SPA, {"sections[0].length": 0.01, "tip.mass": 0.006})
    doc["units"] = "SI"
    si = load_design(doc)
    assert si.spec == load_design(SPA).spec


def test_units_must_be_si():
    doc = with_entries(SPA, {})
    doc["units"] = "mm"
    with pytest.raises(DesignError) as info:
        load_design(doc)
    assert info.value.field == "units"


def test_zero_needs_no_unit_but_angles_do():
    d = load_design(with_entries(SPA, {"mounting.base_position": [0, 0, 0]}))
    assert d.spec["mounting"]["base_position"] == [0.0, 0.0, 0.0]
    with pytest.raises(DesignError) as info:
        load_design(with_entries(SPA, {"sections[1].chambers[0].angle": 90}))
    assert info.value.field == "sections[1].chambers[0].angle"


def test_replace_follows_the_file_rule():
    d = load_design(SPA)
    assert d.replace({"tip.mass": "10 g"}).tip_mass == pytest.approx(0.01)
    with pytest.raises(DesignError, match="bare number"):
        d.replace({"tip.mass": 0.01})
    assert d.replace({"sections[1].c_b": 1.2}).spec["sections"][1]["c_b"] == 1.2


def test_mounting_orientation_is_required():
    with pytest.raises(DesignError) as info:
        load_design(with_entries(SPA, {"mounting.orientation": DELETE}))
    assert info.value.field == "mounting.orientation"
    assert "hanging" in info.value.rule and "base_rotation" in info.value.rule


@pytest.mark.parametrize(
    ("path", "value", "field"),
    [
        ("sections[1].chambers[0].channel", 64, "sections[1].chambers[0].channel"),
        ("sections[1].chambers[2].channel", 5, "sections[1].chambers[2].channel"),
        ("mounting.orientation", ["hanging"], "mounting.orientation"),
        ("sections[1].law", {"axial": ["ogden"]}, "sections[1].law.axial"),
        ("numerics.steps_per_section", 10**6, "numerics.steps_per_section"),
        ("sections[1].name", "", "sections[1].name"),
        ("design.citation", "x" * 200_000, "design.citation"),
    ],
)
def test_design_limits_and_types(path, value, field):
    with pytest.raises(DesignError) as info:
        load_design(with_entries(SPA, {path: value}))
    assert info.value.field == field


def test_many_sections_refused_before_work():
    doc = with_entries(SPA, {})
    doc["sections"] = doc["sections"] * 400
    with pytest.raises(DesignError) as info:
        load_design(doc)
    assert info.value.field == "sections" and "1000" in info.value.rule


def test_binary_and_utf16_design_files(tmp_path):
    for data in (b"\xff\xfe\x00\x01", "[design]\n".encode("utf-16")):
        path = tmp_path / "d.toml"
        path.write_bytes(data)
        with pytest.raises(DesignError, match="not valid TOML"):
            load_design(path)


# --- per-call inputs ----------------------------------------------------------------------------


def test_single_and_batch_accept_the_same_types():
    row = [np.float32(1e3), np.int64(0), "0 kPa"]
    single = softrod.solve_statics(SPA, row)
    batch = softrod.solve_statics_batch(SPA, [row])
    assert batch.converged[0]
    assert np.allclose(batch.tip_position[0], single.tip_position, rtol=0, atol=1e-12)
    for bad in ([True, 0, 0], [1j, 0, 0]):
        with pytest.raises(InputError):
            softrod.solve_statics(SPA, bad)
        with pytest.raises(InputError):
            softrod.solve_statics_batch(SPA, [bad])


def test_batch_names_the_row_below_vacuum():
    with pytest.raises(InputError) as info:
        softrod.solve_statics_batch(SPA, [[0, 0, 0], [-2e5, 0, 0]])
    assert info.value.field == "pressures[1]"


def test_simulation_steps_are_bounded_before_allocation():
    with pytest.raises(InputError) as info:
        softrod.simulate(SPA, [0, 0, 0], 1.0, dt=1e-9)
    assert info.value.field == "t_end" and "10,000,000" in info.value.rule


def test_dataset_timestamps_are_not_pressures():
    frame = pd.DataFrame(
        {
            "p0_kPa": pd.to_datetime(["2020-01-01"]),
            "p1_kPa": [0.0],
            "p2_kPa": [0.0],
            "tip_x_mm": [0.0],
            "tip_y_mm": [0.0],
            "tip_z_mm": [0.0],
        }
    )
    with pytest.raises(InputError) as info:
        softrod.load_dataset(frame)
    assert info.value.field == "p0_kPa" and "dates" in info.value.rule


# --- the command line ---------------------------------------------------------------------------


def test_cli_bare_numbers_need_units(run):
    assert_clean_error(
        run("solve", SPA, "--pressure", "30000,0,0"), 2, "--pressure[0]", "bare number"
    )
    assert run("solve", SPA, "--pressure", "0,0,0").exit_code == 0
    assert run("solve", SPA, "--pressure", "30,0,0kPa").exit_code == 0
    assert_clean_error(
        run("simulate", SPA, "--pulses", "paper000", "--t-end", "10", "--out", "t.npz"),
        2,
        "--t-end",
        '"10 s"',
    )


def test_cli_usage_errors_are_one_line(run):
    assert_clean_error(
        run("sweep", SPA, "--grid", "0:1kPa:2", "--out", "o.csv", "--threads", "100000"),
        2,
        "--threads",
    )
    assert_clean_error(run("solve"), 2, "DESIGN")


# --- files --------------------------------------------------------------------------------------


def test_temporaries_are_named_for_cleanup(tmp_path):
    target = tmp_path / "out.csv"
    with atomic_path(target) as tmp:
        assert tmp.parent == tmp_path
        assert tmp.name.startswith(f".softrod-tmp-{os.getpid()}-")
        assert tmp.name.endswith("-out.csv")  # the writers see the target's suffix
        tmp.write_text("x")
    assert target.read_text() == "x" and len(list(tmp_path.iterdir())) == 1


def test_stale_temporaries_of_dead_processes_go(tmp_path):
    dead = tmp_path / ".softrod-tmp-999999999-0123abcd-a.csv"  # no such pid
    dead.write_text("half")
    other = tmp_path / ".a.csv.x.tmp"  # not softrod's: kept
    other.write_text("keep")
    assert remove_stale_temporaries(tmp_path) == [dead]
    assert other.exists()


def test_targets_are_checked(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        check_target(tmp_path / "missing" / "x.csv")
    with pytest.raises(InputError, match="folder, not a file"):
        check_target(tmp_path)
    with pytest.raises(InputError, match="too long"):
        check_target(tmp_path / ("x" * 240 + ".csv"))


def test_staged_outputs_are_all_or_none(tmp_path):
    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    a.write_text("old")
    with pytest.raises(RuntimeError), staged_paths([a, b]) as (ta, tb):
        ta.write_text("new")
        raise RuntimeError("the second output failed")
    assert a.read_text() == "old" and not b.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]


def test_integers_beyond_the_float_range_are_refused_by_name():
    """An int too large for a float (10**400) makes numpy and float() raise OverflowError,
    which the array readers take as 'not a number' like any other bad value (found by the
    long fuzz run: Trajectory.marker_error(measured_time=10**400) raised it raw)."""
    from softrod.pcc import fit_longitudinal_stiffness

    huge = 10**400
    traj = softrod.simulate(
        "spa_three_chamber_130mm", [2e4, 0, 0], "4 ms", dt="2 ms", markers=[(0.065, [0, 0, 0])]
    )
    with pytest.raises(InputError) as info:
        traj.marker_error([huge], [[[0.0, 0.0, 0.0]]])
    assert info.value.field == "measured_time"
    with pytest.raises(InputError) as info:
        fit_longitudinal_stiffness([huge, 1.0, 2.0], [0.0, 1e-3, 2e-3], area=1e-4)
    assert info.value.field == "pressure"
