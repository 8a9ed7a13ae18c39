"""The dynamic side-by-side of the PCC model and the Cosserat rod (issue 6, item 4).

stiff_flop_pcc gives the rod the PCC model's stiffnesses and damping (EA = k_L L0,
EI = k_theta L0, B = b L0), so without gravity and tip loads the two models differ only in
that the rod's shape is free while PCC's is an arc: under a uniform chamber moment the rod's
equilibrium is an arc too, and the motion between equilibria stays close to one.
"""

import numpy as np
import pytest
from conftest import assert_clean_error
from softrod import PressureSchedule, load_dataset
from softrod.pcc.compare import CASES, compare_pcc_dynamics, plot_pcc_dynamics_comparison

ARM = "stiff_flop_pcc"


@pytest.fixture(scope="module")
def frame():
    zero, on = [0.0] * 6, [1e5, 1e5, 0.0, 0.0, 0.0, 1e5]  # channels 5, 0, 1
    sched = PressureSchedule.steps([0.0, 0.1, 1.5], [zero, on, zero])
    return compare_pcc_dynamics(ARM, sched, 3.0, dt=2e-3)


def test_models_agree_without_gravity_and_part_with_it(frame):
    rod = frame[frame["model"] == "cosserat"]
    worst = rod.groupby("experiment", sort=False)["error_mm"].max()
    assert list(worst.index) == list(CASES)
    travel = np.hypot(rod["tip_x_mm"], rod["tip_y_mm"]).max()
    assert travel > 80  # the pulse bends the 110 mm arm by ~100 mm
    # Weightless: the rod's shape departs from an arc only through its own inertia during
    # the transients, 0.65 mm at the pressure switches (0.6 % of the travel), and both
    # settle on the same arc: 1 % of the travel bounds it.
    assert worst["weightless"] < 0.01 * travel
    # Near the end of the pulse both are settling on the same arc (0.045 mm at 1.2 s and
    # falling), against the 8-9 mm that gravity makes at the same time.
    late = rod[(rod["experiment"] == "weightless") & (rod["time_s"].between(1.2, 1.5))]
    assert late["error_mm"].max() < 0.1
    # Gravity bends the rod's free shape away from an arc; a tip load even more.
    assert worst["gravity"] > 10 * worst["weightless"]
    assert worst["gravity + tip load"] > worst["gravity"]


def test_plot_has_one_error_curve_per_case(frame):
    import matplotlib.pyplot as plt

    fig = plot_pcc_dynamics_comparison(frame, title="t")
    try:
        left, right = fig.axes
        assert len(left.get_lines()) == 3 and len(right.get_lines()) == 6
    finally:
        plt.close(fig)


def test_cli_compare_pcc_dynamic(run, tmp_path):
    out, table = tmp_path / "dyn.png", tmp_path / "dyn.csv"
    res = run(
        "compare-pcc", ARM, "--channels", "5,0,1", "--dynamic", "--t-end", "0.4 s",
        "--dt", "4 ms", "--out", out, "--table", table,
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "(dynamics, dt = 4 ms)" in res.output
    assert out.stat().st_size > 0 and table.stat().st_size > 0
    ds = load_dataset(table)  # the dataset schema: one row per case, time and model
    assert set(ds.extra["model"]) == {"pcc", "cosserat"} and ds.time is not None
    assert ds.metadata["design"] == ARM and ds.n_channels == 6
    res = run("compare-pcc", ARM, "--channels", "0", "--input", table, "--out", out)
    assert_clean_error(res, 2, "--input", "--dynamic")
    res = run("compare-pcc", ARM, "--channels", "0", "--dynamic", "--dt", "0 s", "--out", out)
    assert_clean_error(res, 2, "--dt")
