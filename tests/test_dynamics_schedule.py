"""Pressure schedules: values against hand computation, files, callables, square pulses."""

import copy
import pickle

import numpy as np
import pandas as pd
import pytest
from softrod import InputError, load_design
from softrod.dynamics import VACUUM_PA, PressureSchedule

pytestmark = pytest.mark.fast

# Linear interpolation of a few knots: exact up to the rounding of one multiply-add.
_INTERP_TOL = 1e-12
# kPa/bar text in files: a value is divided then multiplied by 1e3/1e5 on the way through.
_FILE_TOL = 1e-12


def test_piecewise_linear_matches_hand_values():
    s = PressureSchedule.piecewise_linear([0.0, 2.0, 3.0], [[0.0, 100.0], [40e3, 0.0], [10e3, 0]])
    assert (s.kind, s.n_channels, s.t_end) == ("linear", 2, 3.0)
    got = s.sample([-1.0, 0.0, 0.5, 2.0, 2.25, 3.0, 10.0])
    want = [
        [0.0, 100.0],  # before the first knot: first value
        [0.0, 100.0],
        [10e3, 75.0],  # a quarter of the way from knot 0 to knot 1
        [40e3, 0.0],
        [32.5e3, 0.0],  # 40 - 0.25 * 30 kPa
        [10e3, 0.0],
        [10e3, 0.0],  # after the last knot: last value
    ]
    np.testing.assert_allclose(got, want, rtol=_INTERP_TOL, atol=0)
    assert s.sample(2.25).shape == (1, 2)  # a number gives one row


def test_steps_hold_until_next_knot():
    s = PressureSchedule.steps([1.0, 2.0, 4.0], [[10.0], [20.0], [30.0]])
    got = s.sample([0.0, 1.0, 1.999999, 2.0, 3.9, 4.0, 99.0])[:, 0]
    np.testing.assert_array_equal(got, [10, 10, 10, 20, 20, 30, 30])


def test_constant_and_channel_check():
    s = PressureSchedule.constant([1e3, 2e3, 0.0])
    assert s.t_end == 0.0
    np.testing.assert_array_equal(s.sample([0.0, 50.0]), [[1e3, 2e3, 0], [1e3, 2e3, 0]])
    s.check_channels(3)
    s.check_channels(load_design("pam_arm_220mm"))
    with pytest.raises(InputError, match=r"pressure_schedule.n_channels = 3: .*\(2\)"):
        s.check_channels(2)
    with pytest.raises(InputError) as info:
        PressureSchedule.constant([1.0, 2.0]).check_channels(load_design("pam_arm_220mm"))
    assert "pam_arm_220mm" in str(info.value) and "has 3" in str(info.value)


def test_constant_pressures_with_units_are_read_in_their_unit():
    # As solve_statics takes them: strings with units beside numbers in Pa.
    s = PressureSchedule.constant(["1.5 bar", "20 kPa", 0.0])
    np.testing.assert_array_equal(s.sample([0.0]), [[1.5e5, 2e4, 0.0]])
    with pytest.raises(InputError, match=r"pressures\[1\] = '2 mm': wrong unit"):
        PressureSchedule.constant([1e3, "2 mm"])
    with pytest.raises(InputError, match=r"pressures\[0\] = \[-200000.0\]: .*>= -101325 Pa"):
        PressureSchedule.constant(["-2 bar"])


def test_is_immutable():
    s = PressureSchedule.steps([0.0, 1.0], [[0.0], [1.0]])
    with pytest.raises(AttributeError):
        s.kind = "linear"
    with pytest.raises(ValueError):
        s.pressures[0, 0] = 5.0
    with pytest.raises(ValueError):
        s.times[0] = 5.0
    back = pickle.loads(pickle.dumps(s))  # through the constructor: checked and frozen again
    assert back.kind == "step" and not back.pressures.flags.writeable
    np.testing.assert_array_equal(back.pressures, s.pressures)
    assert copy.deepcopy(s).t_end == 1.0


@pytest.mark.parametrize(
    ("times", "pressures", "fragments"),
    [
        ([0.0, 1.0, 1.0], [[0], [1], [2]], ("times[2] = 1.0", "strictly increasing")),
        ([0.0, -1.0], [[0], [1]], ("times[1] = -1.0", ">= 0")),
        ([0.0, np.nan], [[0], [1]], ("times[1]", "finite")),
        ([0.0, 1.0], [[0], [np.inf]], ("pressures[1]", "finite")),
        ([0.0, 1.0], [[0], [-2e5]], ("pressures[1]", "-101325")),
        ([0.0, 1.0], [0.0, 1.0], ("pressures", "shape (2,)", "(n, 1)")),
        ([0.0, 1.0], [[0.0], [1.0], [2.0]], ("pressures", "shape (3, 1)", "2 rows")),
    ],
)
def test_table_validation(times, pressures, fragments):
    with pytest.raises(InputError) as info:
        PressureSchedule.piecewise_linear(times, pressures)
    for f in fragments:
        assert f in str(info.value), (f, str(info.value))


def test_vacuum_is_allowed():
    s = PressureSchedule.steps([0.0], [[VACUUM_PA]])
    assert s.sample(1.0)[0, 0] == -101325.0


# --- files ---------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["linear", "step"])
@pytest.mark.parametrize("name", ["s.csv", "s.parquet"])
def test_write_and_read_back(tmp_path, kind, name):
    times = [0.0, 0.5, 2.0, 7.25]
    p = [[0.0, 1e3], [12.5e3, 2e3], [360e3, 0.0], [0.0, 0.0]]
    s = PressureSchedule.piecewise_linear(times, p)
    if kind == "step":
        s = PressureSchedule.steps(times, p)
    path = s.write(tmp_path / name)
    assert sorted(x.name for x in tmp_path.iterdir()) == [name]  # no temporary file left
    back = PressureSchedule.from_file(path)  # the kind comes from the file's metadata
    assert back.kind == kind
    np.testing.assert_array_equal(back.times, times)
    np.testing.assert_allclose(back.pressures, p, rtol=_FILE_TOL, atol=1e-9)
    assert PressureSchedule.from_file(path, kind="linear").kind == "linear"  # caller wins


def test_from_file_bar_and_ms_columns(tmp_path):
    path = tmp_path / "bar.csv"
    path.write_text("time_ms,p1_bar,p0_kPa\n0,0,0\n500,1.5,20\n1500,3.6,0\n")
    s = PressureSchedule.from_file(path, kind="step")
    assert s.kind == "step" and s.n_channels == 2
    np.testing.assert_allclose(s.times, [0.0, 0.5, 1.5], rtol=_FILE_TOL)
    np.testing.assert_allclose(
        s.pressures, [[0, 0], [20e3, 1.5e5], [0, 3.6e5]], rtol=_FILE_TOL, atol=0
    )
    np.testing.assert_allclose(s.sample(1.0), [[20e3, 1.5e5]], rtol=_FILE_TOL)


def test_from_file_parquet_pa_columns(tmp_path):
    path = tmp_path / "pa.parquet"
    pd.DataFrame({"time_s": [0.0, 1.0], "p0_Pa": [0.0, 1234.5]}).to_parquet(path)
    s = PressureSchedule.from_file(path)
    assert s.kind == "linear"
    np.testing.assert_array_equal(s.pressures, [[0.0], [1234.5]])


def test_from_file_units_block_and_extra_columns(tmp_path):
    path = tmp_path / "u.csv"
    path.write_text('# units: {"p0": "kPa"}\ntime_s,p0,tip_x_mm\n0,1,5\n1,2,6\n')
    with pytest.raises(InputError, match="tip_x_mm.*extra='ignore'"):
        PressureSchedule.from_file(path)
    s = PressureSchedule.from_file(path, extra="ignore")
    np.testing.assert_array_equal(s.pressures[:, 0], [1e3, 2e3])


@pytest.mark.parametrize(
    ("text", "fragments"),
    [
        ("time_s,p0_kPa\n0,1\n2,NaN\n3,1\n", ("p0_kPa", "NaN", "line 3")),
        ("time_s,p0_kPa\n0,1\n2,\n", ("p0_kPa", "line 3")),
        ("time_s,p0_kPa\n0,1\n2,1\n1,1\n", ("time_s = 1:", "strictly increasing", "line 4")),
        ("time_s,p0_kPa\n0,1\n0,1\n", ("strictly increasing", "line 3")),
        ("time_s,p0_kPa\n0,1\n1,-200\n", ("-101325", "line 3")),
        ("time_s,p0_kPa\n-1,1\n", (">= 0", "line 2")),
        ("time_s,p0_kPa\n0,abc\n", ("p0_kPa", "'abc'", "not a number", "line 2")),
        ("time,p0_kPa\n0,1\n", ("time", "needs a unit", "time_s")),
        ("time_s,p0_kg\n0,1\n", ("p0_kg", "wrong unit", "pressure")),
        ("time_s,p0_Pa,p2_Pa\n0,1,1\n", ("p1 missing",)),
        ("t_s,p0_Pa\n0,1\n", ("t_s", "unknown column")),
        ("time_s\n0\n", ("missing column(s) p0",)),
        ("p0_Pa\n0\n", ("missing column(s) time",)),
        ("time_s,p0_Pa,p0_kPa\n0,1,1\n", ("both give p0",)),
        ("time_s,p0_Pa\n", ("no data rows",)),
    ],
)
def test_from_file_errors_name_column_and_line(tmp_path, text, fragments):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(InputError) as info:
        PressureSchedule.from_file(path)
    msg = str(info.value)
    assert msg.startswith("bad.csv: "), msg
    for f in fragments:
        assert f in msg, (f, msg)


def test_from_file_parquet_nan_names_row(tmp_path):
    path = tmp_path / "nan.parquet"
    pd.DataFrame({"time_s": [0.0, 1.0, 2.0], "p0_kPa": [0.0, np.nan, 1.0]}).to_parquet(path)
    with pytest.raises(InputError, match="p0_kPa.*row 1"):
        PressureSchedule.from_file(path)


def test_from_file_bad_path_and_kind(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        PressureSchedule.from_file(tmp_path / "missing.csv")
    with pytest.raises(InputError, match=r"\.csv, \.parquet"):
        PressureSchedule.from_file(tmp_path / "s.xlsx")
    with pytest.raises(InputError, match="kind = 'cubic'"):
        PressureSchedule.from_file(tmp_path / "s.csv", kind="cubic")


def test_write_is_all_or_nothing(tmp_path):
    s = PressureSchedule.from_callable(lambda t: [t], 1)
    with pytest.raises(InputError, match="needs times"):
        s.write(tmp_path / "s.csv")
    with pytest.raises(InputError):
        PressureSchedule.from_callable(lambda t: [np.nan], 1).write(tmp_path / "s.csv", times=[0])
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(InputError, match="unknown table format"):
        PressureSchedule.constant([0.0]).write(tmp_path / "s.txt")
    assert list(tmp_path.iterdir()) == []


def test_to_frame_columns():
    s = PressureSchedule.steps([0.0, 1.0], [[0.0, 1e3], [2e3, 3e3]])
    f = s.to_frame()
    assert list(f.columns) == ["time_s", "p0_kPa", "p1_kPa"]
    np.testing.assert_array_equal(f.to_numpy(), [[0, 0, 1], [1, 2, 3]])
    f2 = s.to_frame(times=[0.5, 2.0])
    np.testing.assert_array_equal(f2["p1_kPa"], [1.0, 3.0])


# --- callables -----------------------------------------------------------------------------


def test_callable_values_and_validation():
    s = PressureSchedule.from_callable(lambda t: (1e3 * t, 2e3), 2)
    assert s.kind == "callable" and s.t_end is None and s.n_channels == 2
    np.testing.assert_array_equal(s.sample([0.0, 1.5]), [[0.0, 2e3], [1.5e3, 2e3]])
    one = PressureSchedule.from_callable(lambda t: 5.0 * t, 1)  # a number for one channel
    np.testing.assert_array_equal(one.sample([2.0]), [[10.0]])

    cases = [
        (lambda t: [1.0, 2.0, 3.0], "t = 0 s", "shape (3,)"),
        (lambda t: [1.0, np.nan if t > 0.2 else 0.0], "t = 0.25 s", "finite"),
        (lambda t: [1.0, -2e5], "t = 0 s", "-101325"),
        (lambda t: ["a", 1.0], "t = 0 s", "numbers"),
    ]
    for fn, where, rule in cases:
        with pytest.raises(InputError) as info:
            PressureSchedule.from_callable(fn, 2).sample([0.0, 0.25])
        assert f"fn({where})" in str(info.value) and rule in str(info.value), str(info.value)
    with pytest.raises(InputError, match="n_channels = 0"):
        PressureSchedule.from_callable(lambda t: [], 0)
    with pytest.raises(InputError, match="callable"):
        PressureSchedule.from_callable(3.0, 1)
    with pytest.raises(InputError, match=r"times\[1\]"):
        s.sample([0.0, np.inf])


# --- square pulses -------------------------------------------------------------------------


def test_square_pulses_timeline():
    s = PressureSchedule.square_pulses(
        3,
        [(0, 100e3, 5.0), ([1, 2], [20e3, 30e3], 2.0), (2, 50e3, 1.0)],
        rest=4.0,
        start=1.0,
        base=1e3,
    )
    assert s.kind == "step"
    assert s.t_end == 1.0 + 5.0 + 4.0 + 2.0 + 4.0 + 1.0  # pulses and rests between them
    np.testing.assert_array_equal(s.times, [0.0, 1.0, 6.0, 10.0, 12.0, 16.0, 17.0])
    want = {
        0.5: [1e3, 1e3, 1e3],  # lead-in at base
        1.0: [100e3, 1e3, 1e3],
        5.999: [100e3, 1e3, 1e3],
        6.0: [1e3, 1e3, 1e3],  # rest
        10.0: [1e3, 20e3, 30e3],  # two channels, one level each
        12.5: [1e3, 1e3, 1e3],
        16.5: [1e3, 1e3, 50e3],  # absolute level, not base + 50 kPa
        17.0: [1e3, 1e3, 1e3],  # back to base after the last pulse
        100.0: [1e3, 1e3, 1e3],
    }
    np.testing.assert_array_equal(s.sample(list(want)), list(want.values()))


def test_square_pulses_without_rest_or_start():
    s = PressureSchedule.square_pulses(2, [(0, 1e3, 1.0), (1, 2e3, 2.0)], rest=0.0)
    np.testing.assert_array_equal(s.times, [0.0, 1.0, 3.0])
    np.testing.assert_array_equal(s.pressures, [[1e3, 0], [0, 2e3], [0, 0]])


@pytest.mark.parametrize(
    ("pulses", "kwargs", "fragment"),
    [
        ([(3, 1e3, 1.0)], {}, "pulses[0].channels = 3"),
        ([(0, 1e3, 0.0)], {}, "pulses[0].duration = 0.0"),
        ([(0, 1e3, 1.0), (0, -3e5, 1.0)], {}, "pulses[1].pressure"),
        ([([0, 1], [1e3, 2e3, 3e3], 1.0)], {}, "one per listed channel"),
        ([([0, 0], 1e3, 1.0)], {}, "twice"),
        ([(0, 1e3)], {}, "pulses[0]"),
        ([], {}, "non-empty"),
        ([(0, 1e3, 1.0)], {"rest": -1.0}, "rest = -1.0"),
        ([(0, 1e3, 1.0)], {"base": [0.0, 1.0]}, "base"),
    ],
)
def test_square_pulses_errors(pulses, kwargs, fragment):
    with pytest.raises(InputError) as info:
        PressureSchedule.square_pulses(3, pulses, **kwargs)
    assert fragment in str(info.value), str(info.value)


def test_paper000_sequence():
    s = PressureSchedule.paper000_square_pulses()
    assert s.n_channels == 3 and s.t_end == 116.0
    s.check_channels(load_design("pam_arm_220mm"))
    t = np.arange(0.0, 116.0, 0.05)
    p = s.sample(t)
    assert np.all(p[t < 1.0] == 0.0)  # at rest at zero pressure before the first pulse
    active = (p > 0).sum(axis=1)
    assert active.max() == 1  # one PAM at a time
    # Pulses: rising edges every 10 s from 1 s, each lasting 5 s (t grid step 0.05 s).
    on = active > 0
    rises = t[1:][on[1:] & ~on[:-1]]
    falls = t[1:][~on[1:] & on[:-1]]
    np.testing.assert_allclose(rises, 1.0 + 10.0 * np.arange(12), atol=1e-9)
    np.testing.assert_allclose(falls, 6.0 + 10.0 * np.arange(11), atol=1e-9)
    levels = p[on].max(axis=1)
    assert set(np.round(levels / 1e5, 6)) == {0.9, 1.8, 2.7, 3.6}
    np.testing.assert_array_equal(s.sample(115.0), [[0.0, 0.0, 3.6e5]])  # paper: 3.6 bar at 115 s
    assert s.sample(116.0).max() == 0.0


def test_one_pressure_is_a_schedule_for_a_one_channel_design_only():
    """simulate takes one pressure for a one-channel design as solve_statics and Simulation
    do (a number in Pa or a string with units), and says how many channels otherwise; a
    string is a pressure only when it names no file and starts with a number."""
    from softrod import simulate

    finger = load_design("prebent_finger_on_table")  # one channel
    ref = simulate(finger, [3e4], 0.004)
    for one in (3e4, 30000, "30 kPa", "0.3 bar"):
        # The same constant pressure gives the same run bit for bit (one code path after
        # parsing; 0.3 bar is exactly 3e4 Pa in binary64: 0.3 * 1e5 rounds to 30000.0).
        got = simulate(finger, one, 0.004)
        np.testing.assert_array_equal(got.tip_position, ref.tip_position)
    arm = load_design("spa_three_chamber_130mm")  # three channels
    for one, field in ((3e4, "pressure_schedule.n_channels"), ("30 m", "pressure_schedule")):
        with pytest.raises(InputError) as info:
            simulate(arm, one, 0.004)
        assert info.value.field == field
    with pytest.raises(InputError, match="must be a pressure"):
        simulate(finger, "30 m", 0.004)  # a length is not read as a file name
    with pytest.raises(InputError, match="no such file"):
        simulate(finger, "30kPa.csv", 0.004)  # a table's name stays a file name
