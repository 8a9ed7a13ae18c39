"""Tendon tensions as data (issue 17, item 7): the ``t0_N``, ``t1_N``, ... columns of the
dataset schema (docs/datasets.md), written by synthesize_dataset and BatchSolution.to_frame,
read back by load_dataset, used by calibrate (static and dynamic fits), and refused by name
where an entry point solves with slack tendons only."""

import numpy as np
import pytest
import softrod
from hypothesis import given, settings
from hypothesis import strategies as st
from softrod import InputError, load_dataset, load_design

ROBOT = "till_tendon_robot"  # 4 tendon channels, no pressure channels


@pytest.fixture(scope="module")
def tensions() -> np.ndarray:
    return np.random.default_rng(0).uniform(0.0, 15.0, size=(24, 4))  # N, inside 0-20 N


@pytest.fixture(scope="module")
def robot_data(tensions):
    truth = load_design(ROBOT).replace({"sections[0].c_b": 1.1})
    return softrod.synthesize_dataset(
        truth, np.zeros((len(tensions), 0)), tensions=tensions, noise_mm=0.2, seed=2
    )


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_tensions_round_trip_through_files(robot_data, tensions, tmp_path, suffix):
    assert robot_data.n_tendons == 4 and robot_data.n_channels == 0
    np.testing.assert_array_equal(robot_data.tensions, tensions)
    path = tmp_path / f"robot{suffix}"
    softrod.write_dataset(robot_data, path)
    back = load_dataset(path, design=ROBOT)
    # CSV stores the N values with repr precision and N is SI: exact.
    np.testing.assert_array_equal(back.tensions, tensions)
    assert [c for c in robot_data.to_frame().columns if c.startswith("t")][:4] == [
        "t0_N",
        "t1_N",
        "t2_N",
        "t3_N",
    ]


def test_batch_table_carries_its_tensions(tensions):
    batch = softrod.solve_statics_batch(ROBOT, np.zeros((len(tensions), 0)), tensions=tensions)
    back = load_dataset(batch.to_frame())
    np.testing.assert_array_equal(back.tensions, tensions)
    np.testing.assert_allclose(back.tip_position, batch.tip_position, rtol=0, atol=1e-12)


def test_calibrate_uses_the_measured_tensions(robot_data):
    """Bending correction c_b = 1.1 on the tendon robot recovered from tip positions under
    24 tension combinations (0.2 mm noise): within 3 standard errors (a 0.3 % two-sided
    chance to fail for a correct estimator and standard error)."""
    fit = softrod.calibrate(ROBOT, robot_data, ["c_b"])
    value, se = float(fit.values[0]), float(fit.std_errors[0])
    assert abs(value - 1.1) < 3 * se, (value, se)
    # The tensions matter: the same tips read as slack-tendon data give no such fit.
    slack = softrod.Dataset(
        pressures=robot_data.pressures,
        tensions=np.zeros_like(robot_data.tensions),
        tip_position=robot_data.tip_position,
    )
    with pytest.warns(softrod.calibration.CalibrationWarning, match="poorly determined"):
        blind = softrod.calibrate(ROBOT, slack, ["c_b"])
    assert blind.rms_error_mm > 50.0


@pytest.mark.parametrize(
    "columns, field, words",
    [
        ({"t0_N": [-1.0]}, "t0_N", ">= 0"),
        ({"t0_N": [1.0], "t2_N": [1.0]}, "columns", "t1 missing"),
        ({"t0_kPa": [1.0]}, "t0_kPa", ""),
        ({"t0": [1.0]}, "t0", "needs a unit"),
        ({"t999_N": [1.0]}, "t999_N", "tension channels"),
    ],
)
def test_bad_tension_columns_name_the_column(columns, field, words):
    import pandas as pd

    frame = pd.DataFrame({**columns, "tip_x_mm": [1.0], "tip_y_mm": [0.0], "tip_z_mm": [0.0]})
    with pytest.raises(InputError) as err:
        load_dataset(frame)
    assert err.value.field == field and words in str(err.value)


def test_tension_channels_must_match_the_design(robot_data):
    frame = robot_data.to_frame().drop(columns=["t3_N"])
    with pytest.raises(InputError, match="3 tendon tension channel"):
        load_dataset(frame, design=ROBOT)


def test_slack_only_entries_refuse_measured_tensions():
    """The per-sample identification and the PCC fits solve with slack tendons (dynamic
    fits replay the tensions: tests/test_calibration_dynamic.py): a dataset that records
    tensions is refused by name, never solved without them."""
    finger = "prebent_tendon_finger"  # one chamber and one tendon
    data = softrod.synthesize_dataset(finger, [[1e4], [2e4]], tensions=[[1.0], [0.5]], seed=0)
    assert data.n_tendons == 1
    with pytest.raises(InputError) as err:
        softrod.identify_stiffness(finger, data)
    assert err.value.field == "tensions" and "slack tendons" in str(err.value)
    # Zero tensions are the slack case: accepted.
    slack = softrod.synthesize_dataset(finger, [[1e4], [2e4]], tensions=[[0.0], [0.0]], seed=0)
    slack.require_slack("a test")


@settings(max_examples=60, deadline=None)
@given(
    values=st.lists(
        st.one_of(
            st.floats(allow_nan=True, allow_infinity=True),
            st.integers(min_value=-(10**30), max_value=10**30),
            st.text(max_size=6),
            st.none(),
        ),
        min_size=1,
        max_size=4,
    ),
    unit=st.sampled_from(["N", "kN", "mN", "kPa", "mm", "", "Nm"]),
)
def test_any_tension_column_is_read_or_refused_by_name(values, unit):
    """Hostile tension cells and units: either every value comes back finite, >= 0 and in
    N, or an InputError names the column (or the rows); never a raw exception or a NaN."""
    import pandas as pd

    name = f"t0_{unit}" if unit else "t0"
    n = len(values)
    frame = pd.DataFrame(
        {name: values, "tip_x_mm": [1.0] * n, "tip_y_mm": [0.0] * n, "tip_z_mm": [0.0] * n}
    )
    try:
        data = load_dataset(frame)
    except InputError as exc:
        assert exc.field, exc
        return
    assert np.isfinite(data.tensions).all() and (data.tensions >= 0).all()
    assert unit in ("N", "kN", "mN")  # a force unit was required to read them
