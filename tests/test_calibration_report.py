"""Tip-error tables (softrod.calibration.metrics) and the HTML report (.report)."""

import base64
import re

import numpy as np
import pandas as pd
import pytest
from softrod import InputError
from softrod.calibration import report
from softrod.calibration.metrics import (
    SAMPLE_COLUMNS,
    TABLE_COLUMNS,
    per_sample_errors,
    tip_error_table,
)

pytestmark = pytest.mark.fast  # the whole module runs in seconds

# Differences of m-sized coordinates carry rounding of ~1e-17 m, i.e. ~1e-14 mm; a wrong
# formula is off by far more than this.
ROUNDING_MM = 1e-9
ROUNDING_PCT = 1e-9  # the same rounding, in % (of L or of the deflection)
L = 0.13  # m: the reference length of paper 001's actuator

_IMG = re.compile(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"')


def _tips(m=12, seed=0):
    """m tip positions of a hanging actuator, around 130 mm below the base (m)."""
    rng = np.random.default_rng(seed)
    return rng.normal(scale=0.03, size=(m, 3)) + [0.0, 0.0, -L]


def _rotation(seed=1):
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    return q


# --------------------------------------------------------------------------- metrics


def test_shift_gives_the_shift_length():
    meas = _tips()
    shift = np.array([3e-3, 4e-3, 0.0])  # 5 mm long
    table = tip_error_table(meas, meas + shift, length=L)
    assert list(table.columns) == list(TABLE_COLUMNS)
    assert table["set"].tolist() == ["all"]
    row = table.iloc[0]
    assert row["n"] == len(meas) and row["failed"] == 0
    for col in ("mean_error_mm", "median_error_mm", "max_error_mm", "rms_error_mm"):
        assert row[col] == pytest.approx(5.0, abs=ROUNDING_MM), col
    for col in ("mean_error_pct_L", "median_error_pct_L", "max_error_pct_L"):
        assert row[col] == pytest.approx(100 * 5e-3 / L, abs=ROUNDING_PCT), col
    # Without reference, base and axis those columns are empty, not made up.
    assert row["n_deflection"] == 0
    for col in ("mean_error_pct_deflection", "mean_abs_radial_error_mm"):
        assert np.isnan(row[col]), col
    # The length may carry units.
    same = tip_error_table(meas, meas + shift, length="130 mm")
    pd.testing.assert_frame_equal(same, table)


def test_rms_differs_from_mean_when_errors_differ():
    meas = _tips(m=2)
    pred = meas + np.array([[1e-3, 0, 0], [0, 7e-3, 0]])  # errors 1 mm and 7 mm
    row = tip_error_table(meas, pred, length=L).iloc[0]
    assert row["mean_error_mm"] == pytest.approx(4.0, abs=ROUNDING_MM)
    assert row["rms_error_mm"] == pytest.approx(5.0, abs=ROUNDING_MM)  # sqrt((1 + 49) / 2)
    assert row["max_error_mm"] == pytest.approx(7.0, abs=ROUNDING_MM)


@pytest.mark.parametrize("tilted", [False, True])
def test_radial_and_height_split(tilted):
    # Tips on a circle of radius 20 mm around the axis (z up from the base) at several
    # heights; each prediction lies 2 mm further out and 3 mm higher.
    angle = np.linspace(0.0, 2 * np.pi, 8, endpoint=False)
    outward = np.stack([np.cos(angle), np.sin(angle), np.zeros_like(angle)], axis=1)
    up = np.array([0.0, 0.0, 1.0])
    height = np.linspace(0.08, 0.12, 8)
    meas = 0.02 * outward + height[:, None] * up
    pred = meas + 2e-3 * outward + 3e-3 * up
    base, axis = np.zeros(3), up
    if tilted:  # the same geometry turned and moved: the split must not change
        rot, base = _rotation(), np.array([0.1, -0.2, 0.3])
        meas, pred = meas @ rot.T + base, pred @ rot.T + base
        axis = 2.5 * rot @ up  # any length: only the direction counts
    samples = per_sample_errors(meas, pred, base_position=base, axis=axis)
    assert list(samples.columns) == list(SAMPLE_COLUMNS)
    # Measured minus predicted (paper 001 Fig. 7): the model overshoots both.
    np.testing.assert_allclose(samples["radial_error_mm"], -2.0, atol=ROUNDING_MM)
    np.testing.assert_allclose(samples["height_error_mm"], -3.0, atol=ROUNDING_MM)
    np.testing.assert_allclose(samples["error_mm"], np.sqrt(13.0), atol=ROUNDING_MM)
    row = tip_error_table(meas, pred, length=L, base_position=base, axis=axis).iloc[0]
    assert row["mean_abs_radial_error_mm"] == pytest.approx(2.0, abs=ROUNDING_MM)
    assert row["max_abs_radial_error_mm"] == pytest.approx(2.0, abs=ROUNDING_MM)
    assert row["mean_abs_height_error_mm"] == pytest.approx(3.0, abs=ROUNDING_MM)
    assert row["max_abs_height_error_mm"] == pytest.approx(3.0, abs=ROUNDING_MM)


def test_error_in_percent_of_deflection():
    ref = np.array([0.0, 0.0, -L])
    direction = np.array([[1.0, 0, 0], [0, 1.0, 0], [0.6, 0.8, 0]])
    deflection = np.array([10e-3, 20e-3, 0.5e-3])  # the last is below MIN_DEFLECTION (1 mm)
    meas = ref + deflection[:, None] * direction
    pred = meas + [0.0, 0.0, 1e-3]  # 1 mm error each
    samples = per_sample_errors(meas, pred, reference=ref)
    np.testing.assert_allclose(samples["deflection_mm"], [10.0, 20.0, 0.5], atol=ROUNDING_MM)
    np.testing.assert_allclose(samples["error_pct_deflection"][:2], [10.0, 5.0])
    assert np.isnan(samples["error_pct_deflection"][2])
    row = tip_error_table(meas, pred, length=L, reference=ref).iloc[0]
    assert row["n_deflection"] == 2
    assert row["mean_error_pct_deflection"] == pytest.approx(7.5, abs=ROUNDING_PCT)
    assert row["median_error_pct_deflection"] == pytest.approx(7.5, abs=ROUNDING_PCT)
    # One reference per sample gives the same; a lower threshold takes the third in (200 %).
    per_row = tip_error_table(meas, pred, length=L, reference=np.tile(ref, (3, 1)))
    pd.testing.assert_frame_equal(per_row, tip_error_table(meas, pred, length=L, reference=ref))
    low = tip_error_table(meas, pred, length=L, reference=ref, min_deflection="0.4 mm")
    assert low["n_deflection"].iloc[0] == 3
    assert low["mean_error_pct_deflection"].iloc[0] == pytest.approx(215.0 / 3, abs=ROUNDING_PCT)


def test_train_and_test_rows():
    meas = _tips(m=3)
    labels = np.array(["train", "test", "train"])
    pred = meas + np.array([[1e-3, 0, 0], [0, 2e-3, 0], [0, 0, -1e-3]])  # 1, 2, 1 mm
    table = tip_error_table(meas, pred, length=L, labels=labels)
    assert table["set"].tolist() == ["train", "test", "all"]  # first appearance, then all
    assert table["n"].tolist() == [2, 1, 3]
    np.testing.assert_allclose(table["mean_error_mm"], [1.0, 2.0, 4.0 / 3.0], atol=ROUNDING_MM)
    np.testing.assert_allclose(table["median_error_mm"], [1.0, 2.0, 1.0], atol=ROUNDING_MM)
    np.testing.assert_allclose(table["max_error_mm"], [1.0, 2.0, 2.0], atol=ROUNDING_MM)
    assert per_sample_errors(meas, pred, labels=labels)["set"].tolist() == labels.tolist()


def test_failed_predictions_are_counted_not_dropped():
    meas = _tips(m=5)
    pred = meas + [0.0, 2e-3, 0.0]
    pred[1] = np.nan  # a solve that did not converge
    pred[3, 2] = np.nan  # one NaN coordinate is a failure too
    labels = ["train", "train", "test", "test", "train"]
    samples = per_sample_errors(meas, pred, labels=labels)
    assert len(samples) == 5
    assert samples["failed"].tolist() == [False, True, False, True, False]
    table = tip_error_table(meas, pred, length=L, labels=labels)
    assert table["n"].tolist() == [3, 2, 5]
    assert table["failed"].tolist() == [1, 1, 2]
    np.testing.assert_allclose(table["mean_error_mm"], 2.0, atol=ROUNDING_MM)
    # A set with no successful prediction has NaN statistics (and no numpy warning).
    pred[[2, 3]] = np.nan
    table = tip_error_table(meas, pred, length=L, labels=labels, reference=meas[0])
    test = table[table["set"] == "test"].iloc[0]
    assert test["failed"] == 2 and test["n_deflection"] == 0
    assert np.isnan(test["mean_error_mm"]) and np.isnan(test["max_error_pct_L"])


def _bad(**change):
    meas = _tips(m=4)
    args = {"measured": meas, "predicted": meas + 1e-3, "length": L}
    args.update(change)
    return args


@pytest.mark.parametrize(
    ("args", "field"),
    [
        (_bad(predicted=np.zeros((3, 3))), "predicted"),
        (_bad(predicted=np.zeros((4, 2))), "predicted"),
        (_bad(measured=np.zeros(3)), "measured"),
        (_bad(measured=np.zeros((0, 3)), predicted=np.zeros((0, 3))), "measured"),
        (_bad(measured=np.where(np.eye(4, 3) > 0, np.nan, _tips(m=4))), "measured"),
        (_bad(predicted=np.full((4, 3), np.inf)), "predicted"),
        (_bad(measured="tips"), "measured"),
        (_bad(length=0.0), "length"),
        (_bad(length=-0.13), "length"),
        (_bad(length=float("nan")), "length"),
        (_bad(length=None), "length"),
        (_bad(length="130 kPa"), "length"),
        (_bad(labels=["train"] * 3), "labels"),
        (_bad(labels=["train", "test", "all", "test"]), "labels"),
        (_bad(labels=["train", None, "test", "test"]), "labels"),
        (_bad(reference=np.zeros((2, 3))), "reference"),
        (_bad(reference=[0.0, np.nan, 0.0]), "reference"),
        (_bad(axis=[0.0, 0.0, 0.0], base_position=[0, 0, 0]), "axis"),
        (_bad(axis=[0.0, 0.0, 1.0]), "base_position"),
        (_bad(base_position=[0.0, 0.0, 0.0]), "axis"),
        (_bad(min_deflection=-1e-3), "min_deflection"),
    ],
)
def test_bad_input_is_refused(args, field):
    with pytest.raises(InputError) as info:
        tip_error_table(**args)
    assert info.value.field == field
    assert info.value.rule and info.value.rule in str(info.value)


# --------------------------------------------------------------------------- report


def _report_inputs(m=24):
    meas = _tips(m=m, seed=3)
    rng = np.random.default_rng(4)
    pred = meas + rng.normal(scale=2e-3, size=(m, 3))
    pred[5] = np.nan
    labels = np.where(np.arange(m) < 18, "train", "test")
    error_table = tip_error_table(meas, pred, length=L, labels=labels)
    params = pd.DataFrame(
        {"parameter": ["E_Pa", "c_b", "c_p"], "value": [1.2e5, 0.87, 0.3], "unit": ["Pa", "-", "-"]}
    )
    return {
        "title": "Calibration of <spa130>",
        "summary": {"design": "spa130", "method": "Levenberg-Marquardt", "cost": 2.8e-3},
        "parameter_table": params,
        "error_table": error_table,
        "measured": meas,
        "predicted": pred,
        "labels": labels,
    }


def _images(text: str) -> list[bytes]:
    return [base64.b64decode(b) for b in _IMG.findall(text)]


def test_report_holds_tables_figures_and_warnings(tmp_path):
    args = _report_inputs()
    m = len(args["measured"])
    rng = np.random.default_rng(5)
    correlation = np.array([[1.0, 0.97, 0.5], [0.97, 1.0, -0.2], [0.5, -0.2, 1.0]])
    path = report.write_report(
        tmp_path / "calibration.html",
        **args,
        pressures=rng.uniform(0.0, 60e3, size=(m, 3)),
        factors=rng.uniform(0.5, 1.5, size=(m, 2)),
        factor_names=["sigma_ext", "sigma_bend_x"],
        warnings=["E_Pa and c_b are strongly correlated (r = 0.97)"],
        correlation=correlation,
        param_names=["E_Pa", "c_b", "c_p"],
        length=L,
        axis=[0.0, 0.0, -1.0],
        base_position=[0.0, 0.0, 0.0],
    )
    assert path == tmp_path / "calibration.html"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["calibration.html"]  # no temp left
    text = path.read_text(encoding="utf-8")
    # Five figures (positions, error boxes, error map, factors, pressures), each a PNG.
    images = _images(text)
    assert len(images) == 5
    assert all(img.startswith(b"\x89PNG\r\n\x1a\n") for img in images)
    # Self-contained: nothing is fetched from elsewhere.
    assert "http" not in text and "<link" not in text and "<script" not in text
    # The title is escaped, never markup.
    assert "<h1>Calibration of &lt;spa130&gt;</h1>" in text
    assert "Levenberg-Marquardt" in text
    assert '<ul class="warnings"><li>E_Pa and c_b are strongly correlated' in text
    for name in ("E_Pa", "c_p", "mean_error_mm", "max_error_pct_L", "failed"):
        assert f"<th>{name}</th>" in text, name
    train_mean = args["error_table"]["mean_error_mm"].iloc[0]
    assert f"<td>{train_mean:.4g}</td>" in text
    # Only the off-diagonal pair with |r| > 0.95 is highlighted, twice (symmetric).
    assert text.count('<td class="strong">0.970</td>') == 2
    assert text.count('class="strong"') == 2
    assert "<td>0.500</td>" in text


def test_report_minimal_inputs(tmp_path):
    path = report.write_report(tmp_path / "r.htm", **_report_inputs())
    text = path.read_text(encoding="utf-8")
    assert len(_images(text)) == 3  # positions, error boxes, error map
    assert "No warnings." in text
    assert "Parameter correlation" not in text


def test_report_missing_folder_raises_and_writes_nothing(tmp_path):
    path = tmp_path / "missing" / "r.html"
    with pytest.raises(InputError) as info:
        report.write_report(path, **_report_inputs())
    assert info.value.field == "path"
    assert not path.parent.exists()
    assert list(tmp_path.iterdir()) == []


def test_report_must_be_html(tmp_path):
    with pytest.raises(InputError) as info:
        report.write_report(tmp_path / "r.png", **_report_inputs())
    assert ".html" in str(info.value)
    assert list(tmp_path.iterdir()) == []


def _broken_figure(*args, **kwargs):
    raise RuntimeError("figure failed")


def test_report_figure_failure_leaves_no_file(tmp_path, monkeypatch):
    monkeypatch.setattr(report, "_residual_figure", _broken_figure)
    path = tmp_path / "r.html"
    with pytest.raises(RuntimeError, match="figure failed"):
        report.write_report(path, **_report_inputs())
    assert list(tmp_path.iterdir()) == []  # neither the report nor a temporary file
    # An earlier report stays as it was.
    path.write_text("old report", encoding="utf-8")
    with pytest.raises(RuntimeError, match="figure failed"):
        report.write_report(path, **_report_inputs())
    assert path.read_text(encoding="utf-8") == "old report"
    assert [p.name for p in tmp_path.iterdir()] == ["r.html"]


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"predicted": np.zeros((3, 3))}, "predicted"),
        ({"factors": np.ones((5, 2))}, "factors"),
        ({"factors": np.ones((24, 2)), "factor_names": ["one"]}, "factor_names"),
        ({"pressures": np.full((24, 3), np.nan)}, "pressures"),
        ({"correlation": np.array([[4.0, 2.0], [2.0, 9.0]])}, "correlation"),  # a covariance
        ({"correlation": np.eye(3)[:2]}, "correlation"),
        ({"correlation": np.eye(2), "param_names": ["a"]}, "param_names"),
        ({"parameter_table": {"E": 1.0}}, "parameter_table"),
    ],
)
def test_report_bad_input_leaves_no_file(tmp_path, change, field):
    args = {**_report_inputs(), **change}
    with pytest.raises(InputError) as info:
        report.write_report(tmp_path / "r.html", **args)
    assert info.value.field == field
    assert list(tmp_path.iterdir()) == []


def test_save_figures(tmp_path):
    args = _report_inputs()
    paths = report.save_figures(
        tmp_path, args["measured"], args["predicted"], labels=args["labels"], length=L
    )
    assert [p.name for p in paths] == [
        "tip_positions.png",
        "tip_error_boxes.png",
        "tip_error_map.png",
    ]
    assert all(p.read_bytes().startswith(b"\x89PNG") for p in paths)
    with pytest.raises(InputError):
        report.save_figures(tmp_path / "missing", args["measured"], args["predicted"])
