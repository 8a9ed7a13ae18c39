"""Measurement datasets: schema, units, validation messages, atomic writes, synthetic data."""

import json

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import softrod
from softrod import (
    ConvergenceError,
    Dataset,
    InputError,
    SolverOptions,
    load_dataset,
    solve_statics,
    synthesize_dataset,
    write_dataset,
)
from softrod._examples import SPA130_EXAMPLE, _spa130_example
from softrod.datasets import (
    QUATERNION_TOLERANCE,
    _matrix_to_quat,
    _quat_to_matrix,
    example_dataset_path,
    example_datasets,
)

pytestmark = pytest.mark.fast  # the whole module runs in seconds

DESIGN = "spa_three_chamber_130mm"

# Writing a value in a unit and reading it back multiplies and divides by the unit's factor
# (1e-3 for kPa, mm, ...), each step rounding to the nearest double (relative error <= 2^-53
# ~ 1.1e-16); CSV stores the shortest decimal that reads back to the same double, so the text
# adds no error. 1e-12 leaves a wide margin over those few roundings and still catches any real
# unit or column mix-up. Components that are zero or tiny (a rotation entry of 1e-17) are
# compared on the scale of their array (atol = RTOL * max|x|).
RTOL = 1e-12


def assert_close(a, b):
    a, b = np.asarray(a), np.asarray(b)
    scale = float(np.abs(b).max()) if b.size else 0.0
    np.testing.assert_allclose(a, b, rtol=RTOL, atol=RTOL * scale)


@pytest.fixture(scope="module")
def small():
    """Eight synthetic rows with every optional column."""
    p = np.array([[0, 0, 0], [30, 0, 0], [0, 30, 0], [0, 0, 30], [60, 20, 0], [10, 10, 10]])
    p = np.vstack([p, [[70, 0, 35], [5, 60, 5]]]) * 1e3
    return synthesize_dataset(
        DESIGN,
        p,
        noise_mm=0.2,
        seed=7,
        experiment=["a", "a", "a", "b", "b", "c", "c", "c"],
        mounting="hanging",
        time=np.arange(8) * 0.5,
    )


def message(info) -> str:
    return str(info.value)


def write(tmp_path, text, name="d.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


BASE = "p0_kPa,p1_kPa,tip_x_mm,tip_y_mm,tip_z_mm\n"


# --- round trips ------------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
@pytest.mark.parametrize(
    "units",
    [None, {"pressure": "bar", "length": "m", "force": "mN", "moment": "N*m", "time": "ms"}],
)
def test_round_trip(tmp_path, small, suffix, units):
    path = write_dataset(small, tmp_path / f"d{suffix}", units=units)
    back = load_dataset(path, design=DESIGN)
    assert len(back) == len(small) == 8 and back.n_channels == 3
    for name in ("pressures", "tip_position", "tip_rotation", "base_force", "base_moment", "time"):
        assert_close(getattr(back, name), getattr(small, name))
    assert back.experiment.tolist() == ["a", "a", "a", "b", "b", "c", "c", "c"]
    assert back.mounting.tolist() == ["hanging"] * 8
    assert back.metadata == small.metadata and back.synthetic
    assert back.source == path
    # Units are in the column names.
    names = (
        pd.read_csv(path, comment="#").columns
        if suffix == ".csv"
        else pq.read_table(path).column_names
    )
    expected = "p0_bar" if units else "p0_kPa"
    assert expected in names and ("base_mx_Nm" if units else "base_mx_Nmm") in names


def test_frame_round_trip_keeps_metadata(small):
    frame = small.to_frame()
    assert list(frame.columns[:6]) == [
        "experiment",
        "mounting",
        "time_s",
        "p0_kPa",
        "p1_kPa",
        "p2_kPa",
    ]
    back = load_dataset(frame)
    assert back.synthetic and back.metadata["seed"] == 7
    assert_close(back.tip_position, small.tip_position)
    np.testing.assert_allclose(frame["tip_z_mm"], small.tip_position[:, 2] * 1e3, rtol=1e-15)


def test_csv_header_says_synthetic(tmp_path, small):
    path = write_dataset(small, tmp_path / "s.csv")
    first = path.read_text().splitlines()[0]
    assert first.startswith("# SYNTHETIC") and DESIGN in first
    measured = Dataset(pressures=small.pressures, tip_position=small.tip_position)
    path = write_dataset(measured, tmp_path / "m.csv")
    lines = path.read_text().splitlines()
    assert lines[0] == "# softrod dataset" and lines[2] == '# metadata: {"synthetic": false}'
    assert not load_dataset(path).synthetic


# --- units: in the names or in a metadata block --------------------------------------------------

ROWS = ["10,0,1.5,-2,-130", "20,35,0,0.25,-128.5"]
EXPECTED_P = np.array([[10e3, 0.0], [20e3, 35e3]])
EXPECTED_TIP = np.array([[1.5e-3, -2e-3, -130e-3], [0.0, 0.25e-3, -128.5e-3]])


def test_units_in_names_or_block_give_the_same_si_data(tmp_path):
    named = write(tmp_path, BASE + "\n".join(ROWS) + "\n", "named.csv")
    block = write(
        tmp_path,
        '# my rig, 2024-05-02\n# units: {"p0": "kPa", "p1": "kPa", "tip_x": "mm", '
        '"tip_y": "mm", "tip_z": "mm"}\np0,p1,tip_x,tip_y,tip_z\n' + "\n".join(ROWS) + "\n",
        "block.csv",
    )
    frame = pd.read_csv(named)
    table = pa.Table.from_pandas(frame.rename(columns=lambda c: c.rsplit("_", 1)[0]))
    units = {"p0": "kPa", "p1": "kPa", "tip_x": "mm", "tip_y": "mm", "tip_z": "mm"}
    pq.write_table(
        table.replace_schema_metadata({"softrod.units": json.dumps(units)}),
        tmp_path / "block.parquet",
    )
    bare = frame.rename(columns=lambda c: c.rsplit("_", 1)[0])
    loaded = [
        load_dataset(named),
        load_dataset(block),
        load_dataset(tmp_path / "block.parquet"),
        load_dataset(frame),
        load_dataset(bare, units=units),
    ]
    for ds in loaded:
        np.testing.assert_array_equal(ds.pressures, loaded[0].pressures)
        np.testing.assert_array_equal(ds.tip_position, loaded[0].tip_position)
    assert_close(loaded[0].pressures, EXPECTED_P)
    assert_close(loaded[0].tip_position, EXPECTED_TIP)


def test_unit_spellings(tmp_path):
    path = write(
        tmp_path,
        "p0_bar,p1_psi,tip_x_m,tip_y_cm,tip_z_um,base_fx_mN,base_fy_N,base_fz_kN,"
        "base_mx_Nm,base_my_Nmm,base_mz_N*cm,time_ms\n"
        "1,1,0.1,1,1,1,1,1,1,1,1,250\n",
    )
    ds = load_dataset(path)
    assert_close(ds.pressures, [[1e5, 6894.757293168361]])
    assert_close(ds.tip_position, [[0.1, 0.01, 1e-6]])
    assert_close(ds.base_force, [[1e-3, 1.0, 1e3]])
    assert_close(ds.base_moment, [[1.0, 1e-3, 1e-2]])  # "Nm" is N*m, not pint's number-metre
    assert_close(ds.time, [0.25])


# --- validation errors ---------------------------------------------------------------------------


def test_missing_columns_lists_missing_and_found(tmp_path):
    path = write(tmp_path, "p0_kPa,tip_x_mm,tip_y_mm\n1,2,3\n")
    with pytest.raises(InputError) as info:
        load_dataset(path)
    msg = message(info)
    assert msg.startswith("d.csv: columns = ['p0_kPa', 'tip_x_mm', 'tip_y_mm']")
    assert "missing column(s) tip_z (spelled e.g. tip_z_mm)" in msg
    assert info.value.field == "columns"


def test_incomplete_optional_group(tmp_path):
    path = write(tmp_path, BASE.strip() + ",tip_qw,base_fx_N\n" + "1,2,3,4,5,1,0\n")
    with pytest.raises(InputError) as info:
        load_dataset(path)
    assert "missing column(s) tip_qx, tip_qy, tip_qz, base_fy, base_fz" in message(info)


@pytest.mark.parametrize(
    ("header", "field", "words"),
    [
        ("p0_kPx", "p0_kPx", ["unknown unit 'kPx'"]),
        ("p0_mm", "p0_mm", ["wrong unit", "pressure", "[length]"]),
        ("p0", "p0", ["needs a unit", "p0_kPa", '# units: {"p0": "kPa"}']),
        ("p0_", "p0_", ["empty unit"]),
        ("p0_degC", "p0_degC", ["wrong unit", "[temperature]"]),
    ],
)
def test_bad_units_name_the_column(tmp_path, header, field, words):
    path = write(tmp_path, f"{header},p1_kPa,tip_x_mm,tip_y_mm,tip_z_mm\n1,2,3,4,5\n")
    with pytest.raises(InputError) as info:
        load_dataset(path)
    assert info.value.field == field
    for w in words:
        assert w in message(info)


def test_unit_in_block_and_name_and_unused_block_entry(tmp_path):
    path = write(tmp_path, '# units: {"p0_kPa": "kPa"}\n' + BASE + "1,2,3,4,5\n")
    with pytest.raises(InputError, match="unit given twice"):
        load_dataset(path)
    path = write(tmp_path, '# units: {"tip_w": "mm"}\n' + BASE + "1,2,3,4,5\n")
    with pytest.raises(InputError, match=r"units.tip_w = 'mm': names no column"):
        load_dataset(path)
    path = write(tmp_path, "# units: {p0: kPa}\n" + BASE + "1,2,3,4,5\n")
    with pytest.raises(InputError, match="line 1: not valid JSON"):
        load_dataset(path)
    frame = pd.DataFrame({"tip_qw_1": [1.0]})
    with pytest.raises(InputError, match="tip_qw is dimensionless and takes no unit"):
        load_dataset(frame, extra="ignore")


def test_nan_rows_reported_with_their_line_numbers(tmp_path):
    text = (
        "# comment\n"  # line 1
        '# units: {"tip_x": "mm"}\n'  # line 2
        "p0_kPa,p1_kPa,tip_x,tip_y_mm,tip_z_mm\n"  # line 3 (header)
        "1,2,3,4,5\n"  # line 4
        "1,,3,4,5\n"  # line 5: p1 empty
        "1,2,3,4,NaN\n"  # line 6: tip_z NaN
        "\n"  # line 7: blank
        "1,2,3,4,5\n"  # line 8
        "1,2,3,4,\n"  # line 9: tip_z empty
        "\n\n"  # trailing blank lines are not rows
    )
    path = write(tmp_path, text)
    with pytest.raises(InputError) as info:
        load_dataset(path)
    msg = message(info)
    assert info.value.field == "p1_kPa, tip_z_mm"
    assert "in 4 row(s): blank line 7; p1_kPa at line 5; tip_z_mm at lines 6, 9" in msg
    # The numbers are the lines a text editor shows.
    lines = text.splitlines()
    assert lines[5 - 1] == "1,,3,4,5" and lines[7 - 1] == "" and lines[9 - 1].endswith(",")


def test_nan_rows_in_parquet_and_frames(tmp_path):
    frame = pd.DataFrame(
        {"p0_kPa": [1.0, np.nan, 3.0], "tip_x_mm": [1.0, 2, 3], "tip_y_mm": [1.0, 2, 3]},
        index=["a", "b", "c"],
    )
    frame["tip_z_mm"] = [np.nan, 1.0, np.nan]
    with pytest.raises(InputError) as info:
        load_dataset(frame)
    assert "p0_kPa at index 'b'; tip_z_mm at index labels 'a', 'c'" in message(info)
    frame.reset_index(drop=True).to_parquet(tmp_path / "d.parquet")
    with pytest.raises(InputError) as info:
        load_dataset(tmp_path / "d.parquet")
    assert message(info).startswith("d.parquet: p0_kPa, tip_z_mm = 'empty/NaN'")
    assert "p0_kPa at row 1; tip_z_mm at rows 0, 2" in message(info)


def test_text_and_non_finite_values(tmp_path):
    path = write(tmp_path, BASE + "1,2,3,4,5\n1,2,abc,4,5\n")
    with pytest.raises(InputError) as info:
        load_dataset(path)
    assert message(info) == "d.csv: tip_x_mm = 'abc': not a number at line 3"
    path = write(tmp_path, BASE + "1,2,3,4,5\n1,2,3,inf,5\n1,2,3,-inf,5\n")
    with pytest.raises(InputError) as info:
        load_dataset(path)
    assert message(info) == "d.csv: tip_y_mm = inf: must be finite, at lines 3-4"
    path = write(tmp_path, BASE + "1,2,3\n")
    with pytest.raises(InputError, match="tip_y_mm at line 2"):  # a short row has empty cells
        load_dataset(path)
    path = write(tmp_path, "# x\n" + BASE + "1,2,3,4,5\n1,2,3,4,5,6\n")
    with pytest.raises(InputError, match="line 4 = .6 values.: the header has 5 columns"):
        load_dataset(path)


def test_channel_count_and_numbering(tmp_path):
    path = write(tmp_path, BASE + "1,2,3,4,5\n")
    with pytest.raises(InputError) as info:
        load_dataset(path, design=DESIGN)
    assert "has 2 pressure channel(s) but design 'spa_three_chamber_130mm' has 3" in message(info)
    with pytest.raises(InputError, match="has 2 pressure channel.* but n_channels = 3"):
        load_dataset(path, n_channels=3)
    with pytest.raises(InputError, match="disagrees with design"):
        load_dataset(path, n_channels=2, design=DESIGN)
    ds = load_dataset(path, n_channels=2)
    assert ds.n_channels == 2 and load_dataset(ds) is ds
    with pytest.raises(InputError, match="has 2 pressure channel.* but design"):
        load_dataset(ds, design=DESIGN)
    path = write(tmp_path, "p0_kPa,p2_kPa,tip_x_mm,tip_y_mm,tip_z_mm\n1,2,3,4,5\n")
    with pytest.raises(InputError) as info:
        load_dataset(path)
    assert message(info) == (
        "d.csv: columns = ['p0_kPa', 'p2_kPa']: pressure channels must be numbered p0, p1, ... "
        "without gaps: p1 missing"
    )
    path = write(tmp_path, "p1_kPa,p2_kPa,p3_kPa,tip_x_mm,tip_y_mm,tip_z_mm\n1,2,3,4,5,6\n")
    with pytest.raises(InputError, match="without gaps: p0 missing"):
        load_dataset(path)


def test_quaternion_must_be_unit(tmp_path):
    head = BASE.strip() + ",tip_qw,tip_qx,tip_qy,tip_qz\n"
    near = 1 + 0.5 * QUATERNION_TOLERANCE  # rounding of exported data: accepted, renormalised
    ok = load_dataset(write(tmp_path, head + f"1,2,3,4,5,0,{near},0,0\n"))
    np.testing.assert_allclose(ok.tip_rotation[0], np.diag([1.0, -1.0, -1.0]), atol=1e-15)
    path = write(
        tmp_path, head + "1,2,3,4,5,0,1,0,0\n1,2,3,4,5,0.5,0.5,0.5,0.5\n1,2,3,4,5,1,1,0,0\n"
    )
    with pytest.raises(InputError) as info:
        load_dataset(path)
    msg = message(info)
    assert msg.startswith("d.csv: tip_qw, tip_qx, tip_qy, tip_qz = '|q| = 1.41421356'")
    assert "not a unit quaternion at line 4: |q| must be 1 within 1e-06" in msg
    assert "(w, x, y, z), scalar first" in msg


def test_duplicate_and_unknown_columns(tmp_path):
    path = write(tmp_path, "p0_kPa,p0_kPa,tip_x_mm,tip_y_mm,tip_z_mm\n1,2,3,4,5\n")
    with pytest.raises(InputError) as info:
        load_dataset(path)
    assert message(info) == (
        "d.csv: columns = ['p0_kPa']: duplicate column name(s): each column may appear once"
    )
    path = write(tmp_path, "p0_kPa,p0_bar,tip_x_mm,tip_y_mm,tip_z_mm\n1,2,3,4,5\n")
    with pytest.raises(InputError, match=r"\['p0_kPa', 'p0_bar'\]: both give p0"):
        load_dataset(path)
    path = write(tmp_path, "p0_kPa,tip_x_mm,tip_y_mm,tip_Z_mm,tip_z_mm,note\n1,2,3,4,5,x\n")
    with pytest.raises(InputError) as info:
        load_dataset(path)
    assert "columns = ['tip_Z_mm', 'note']: unknown column(s)" in message(info)
    assert "extra='ignore'" in message(info)
    assert len(load_dataset(path, extra="ignore")) == 1


def test_path_errors(tmp_path):
    with pytest.raises(InputError, match="must end in one of .csv, .parquet"):
        load_dataset(tmp_path / "d.xlsx")
    with pytest.raises(InputError, match="no such file"):
        load_dataset(tmp_path / "none.csv")
    with pytest.raises(InputError, match="no data rows"):
        load_dataset(write(tmp_path, BASE))


def test_labels_and_whitespace(tmp_path):
    path = write(
        tmp_path,
        "experiment, mounting, p0_kPa, tip_x_mm, tip_y_mm, tip_z_mm\n"
        "007, hanging, 1, 2, 3, 4\n3, upright , 1, 2, 3, 4\n",
    )
    ds = load_dataset(path)
    assert ds.experiment.tolist() == ["007", "3"]  # ids stay text unless all are integers
    assert ds.mounting.tolist() == ["hanging", "upright"]
    path = write(tmp_path, "experiment,p0_kPa,tip_x_mm,tip_y_mm,tip_z_mm\n2,1,2,3,4\n10,1,2,3,4\n")
    assert load_dataset(path).experiment.dtype == np.int64


def test_quaternion_convention_matches_scipy():
    """(w, x, y, z), scalar first, Hamilton, active (body -> world), as scipy's as_quat does
    scalar-last; the writer picks w >= 0."""
    from scipy.spatial.transform import Rotation

    rot = Rotation.random(200, random_state=np.random.default_rng(5))
    mats = rot.as_matrix()
    q = _matrix_to_quat(mats)
    ref = rot.as_quat()[:, [3, 0, 1, 2]]
    ref[ref[:, 0] < 0] *= -1
    np.testing.assert_allclose(q, ref, rtol=0, atol=1e-14)
    np.testing.assert_allclose(_quat_to_matrix(q), mats, rtol=0, atol=1e-14)
    # Near-180-degree turns (w ~ 0) take another branch of Shepperd's method.
    half = Rotation.from_rotvec(np.pi * np.eye(3)).as_matrix()
    np.testing.assert_allclose(_quat_to_matrix(_matrix_to_quat(half)), half, atol=1e-15)


# --- the dataset object ---------------------------------------------------------------------------


def test_split_by_experiment(small):
    train, test = small.split(test=["b"])
    assert len(train) == 6 and len(test) == 2
    assert set(test.experiment) == {"b"} and "b" not in set(train.experiment)
    np.testing.assert_array_equal(test.pressures, small.pressures[3:5])
    assert train.synthetic and test.metadata == small.metadata
    with pytest.raises(InputError) as info:
        small.split(test=["b", "z", 1])
    assert message(info) == (
        "test = ['z', 1]: unknown experiment id(s); the dataset has 'a', 'b', 'c'"
    )
    with pytest.raises(InputError, match="nothing would be left to train on"):
        small.split(test=["a", "b", "c"])
    with pytest.raises(InputError, match="no mounting column"):
        Dataset(pressures=[[0.0]], tip_position=[[0, 0, 0]]).split("mounting", test="x")


def test_subset_and_construction(small):
    assert len(small.subset([0, 7])) == 2 and len(small.subset(small.experiment == "c")) == 3
    with pytest.raises(InputError, match="must lie in"):
        small.subset([8])
    with pytest.raises(InputError, match="boolean mask needs shape"):
        small.subset([True, False])
    with pytest.raises(ValueError):
        small.pressures[0, 0] = 1.0  # read-only
    with pytest.raises(InputError, match=r"tip_position = 'shape \(1, 2\)'"):
        Dataset(pressures=[[0.0]], tip_position=[[0.0, 0.0]])
    with pytest.raises(InputError, match="must be rotation matrices"):
        Dataset(pressures=[[0.0]], tip_position=[[0, 0, 0]], tip_rotation=2 * np.eye(3)[None])
    assert "SYNTHETIC" in repr(small) and "8 rows" in repr(small)


# --- atomic writes ------------------------------------------------------------------------------


def test_write_is_atomic_csv(tmp_path, small, monkeypatch):
    path = tmp_path / "d.csv"

    def broken(self, fh, **kwargs):
        fh.write("p0_kPa,p1_kPa\n1,")  # half a file, then the disk fills up
        raise OSError("disk full")

    monkeypatch.setattr(pd.DataFrame, "to_csv", broken)
    with pytest.raises(OSError, match="disk full"):
        write_dataset(small, path)
    assert list(tmp_path.iterdir()) == []  # neither the file nor a temporary file
    monkeypatch.undo()
    write_dataset(small, path)
    before = path.read_bytes()
    monkeypatch.setattr(pd.DataFrame, "to_csv", broken)
    with pytest.raises(OSError):
        write_dataset(small.subset([0]), path)
    assert path.read_bytes() == before  # the old file is untouched
    assert [p.name for p in tmp_path.iterdir()] == ["d.csv"]


def test_write_is_atomic_parquet(tmp_path, small, monkeypatch):
    def broken(table, where, **kwargs):
        with open(where, "wb") as fh:
            fh.write(b"PAR1 partial")
        raise OSError("killed")

    monkeypatch.setattr(pq, "write_table", broken)
    with pytest.raises(OSError, match="killed"):
        write_dataset(small, tmp_path / "d.parquet")
    assert list(tmp_path.iterdir()) == []


def test_write_rejects_bad_metadata_before_writing(tmp_path, small):
    bad = Dataset(pressures=[[0.0]], tip_position=[[0, 0, 0]], metadata={"f": object()})
    with pytest.raises(InputError, match="metadata = .*must be JSON serialisable"):
        write_dataset(bad, tmp_path / "d.csv")
    assert list(tmp_path.iterdir()) == []


# --- synthetic data ---------------------------------------------------------------------------


def test_synthetic_noise_has_the_requested_deviation():
    sigma_mm, m = 0.5, 3000
    p = np.tile([[20e3, 10e3, 0.0]], (m, 1))
    clean = synthesize_dataset(DESIGN, p[:1])
    noisy = synthesize_dataset(DESIGN, p, noise_mm=sigma_mm, seed=11)
    err = (noisy.tip_position - clean.tip_position) * 1e3  # mm, n = 3 m samples
    n = err.size
    # The sample deviation of n normal samples has a relative spread of 1/sqrt(2n) (0.0075
    # here) and the mean a spread of sigma/sqrt(n); allow 5 spreads (false alarm < 1e-6).
    assert abs(err.std() / sigma_mm - 1) < 5 / np.sqrt(2 * n)
    assert abs(err.mean()) < 5 * sigma_mm / np.sqrt(n)
    for axis in range(3):  # isotropic: every axis alike
        assert abs(err[:, axis].std() / sigma_mm - 1) < 5 / np.sqrt(2 * m)
    # Only the position is noisy.
    np.testing.assert_array_equal(noisy.base_force[5], clean.base_force[0])
    np.testing.assert_array_equal(noisy.tip_rotation[5], clean.tip_rotation[0])


def test_synthetic_is_reproducible_and_labelled():
    p = np.array([[0.0, 0, 0], [40e3, 0, 20e3]])
    a = synthesize_dataset(DESIGN, p, noise_mm=0.3, seed=3)
    b = synthesize_dataset(DESIGN, p, noise_mm=0.3, seed=3)
    c = synthesize_dataset(DESIGN, p, noise_mm=0.3, seed=4)
    np.testing.assert_array_equal(a.tip_position, b.tip_position)
    assert not np.array_equal(a.tip_position, c.tip_position)
    d = synthesize_dataset(DESIGN, p, noise_mm=0.3)  # a seed is drawn and recorded
    e = synthesize_dataset(DESIGN, p, noise_mm=0.3, seed=d.metadata["seed"])
    np.testing.assert_array_equal(d.tip_position, e.tip_position)
    meta = a.metadata
    assert meta["synthetic"] is True and meta["design"] == DESIGN
    assert meta["noise_mm"] == 0.3 and meta["seed"] == 3 and "not measurements" in meta["note"]
    # Noise-free, the rows are the model's equilibria in the same frame as solve_statics.
    exact = synthesize_dataset(DESIGN, p)
    sol = solve_statics(DESIGN, p[1])
    np.testing.assert_allclose(exact.tip_position[1], sol.tip_position, rtol=0, atol=1e-12)
    np.testing.assert_allclose(exact.tip_rotation[1], sol.tip_rotation, rtol=0, atol=1e-12)
    np.testing.assert_allclose(exact.base_moment[1], sol.base_moment, rtol=0, atol=1e-12)


def test_synthetic_input_errors():
    with pytest.raises(InputError, match="noise_mm = -1"):
        synthesize_dataset(DESIGN, [[0.0, 0, 0]], noise_mm=-1)
    with pytest.raises(InputError, match=r"must be an \(m, 3\) array"):
        synthesize_dataset(DESIGN, [[0.0, 0]])
    with pytest.raises(InputError, match="experiment = 'shape"):
        synthesize_dataset(DESIGN, [[0.0, 0, 0]], experiment=[1, 2])
    # One Newton step without continuation: the unloaded hanging rod converges, 70 kPa not.
    failing = SolverOptions(max_iter=1, continuation=False)
    with pytest.raises(ConvergenceError) as info:
        synthesize_dataset(DESIGN, [[0.0, 0, 0], [70e3, 0, 0], [0, 0, 0]], options=failing)
    assert "1 of 3 rows did not converge (row 1: p = (70, 0, 0) kPa)" in str(info.value)


# --- the bundled example --------------------------------------------------------------------------


def test_bundled_example():
    path = example_dataset_path("spa130_synthetic")
    assert path.name == "spa130_synthetic.csv" and path.stat().st_size < 100_000
    assert example_datasets() == ["paper002_m3_synthetic", "spa130_synthetic"]
    assert path.read_text().startswith("# SYNTHETIC")
    ds = load_dataset(path, design=DESIGN)
    assert len(ds) == 216 and ds.synthetic and ds.experiments == (1, 2, 3)
    assert ds.metadata["noise_mm"] == SPA130_EXAMPLE["noise_mm"] == 0.3
    assert all(np.sum(ds.experiment == k) == 72 for k in (1, 2, 3))
    np.testing.assert_array_equal(np.unique(ds.pressures), np.arange(0, 71e3, 14e3))
    # The file is what the recipe makes today: the model has not drifted by more than 1 um
    # (well below the 0.3 mm noise) since it was written.
    fresh = _spa130_example()
    np.testing.assert_allclose(ds.tip_position, fresh.tip_position, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(ds.pressures, fresh.pressures)
    with pytest.raises(InputError, match="known: paper002_m3_synthetic, spa130_synthetic"):
        example_dataset_path("spa131")


def test_calibration_example_is_what_its_recipe_makes():
    """The calibration tutorial's dataset (docs/calibration.md) still matches its recipe."""
    from softrod._examples import PAPER002_EXAMPLE, _paper002_example

    ds = load_dataset(example_dataset_path("paper002_m3_synthetic"))
    assert len(ds) == 240 and ds.synthetic and ds.experiments == (1, 2, 3, 4)
    assert ds.metadata["true_parameters"] == PAPER002_EXAMPLE["truth"]
    fresh = _paper002_example()
    np.testing.assert_allclose(ds.tip_position, fresh.tip_position, rtol=0, atol=1e-6)


def test_public_names():
    for name in ("Dataset", "load_dataset", "write_dataset"):
        assert getattr(softrod, name) is getattr(softrod.datasets, name)
        assert name in softrod.__all__
    assert softrod.synthesize_dataset is softrod.synthetic.synthesize_dataset
    assert "synthesize_dataset" in softrod.__all__
