"""One data convention (issue 15, item 2): every table softrod writes is in the dataset schema
of docs/datasets.md (units in the names, channels from 0, the metadata block) and
load_dataset reads it back. The per-command tests (test_cli, test_compare, test_pcc,
test_pcc_compare, test_cli_calibration, test_keep, test_dynamics_trajectory) load each
command's file; this module checks what they share."""

import numpy as np
import pytest
import softrod
from conftest import assert_clean_error
from softrod import BatchSolution, InputError, load_dataset, simulate, solve_statics_batch
from softrod.io import write_table

SPA = "spa_three_chamber_130mm"
P = np.array([[0.0, 0.0, 0.0], [30e3, 0.0, 0.0], [30e3, 30e3, 0.0]])
# kPa and mm in a table: x / 1e3 and back rounds twice, at most 2 ulp (4.4e-16 relative).
UNIT_ROUND_TRIP = 4.5e-16


@pytest.fixture(scope="module")
def batch():
    return solve_statics_batch(SPA, P, threads=1)


def test_batch_and_trajectory_use_the_same_names(batch):
    traj = simulate("pam_arm_220mm", [0.0, 0.0, 0.0], 0.02, dt=0.01, progress=False)
    b, t = batch.to_frame(), traj.to_frame()
    shared = ["p0_kPa", "p1_kPa", "p2_kPa", "tip_x_mm", "tip_y_mm", "tip_z_mm"]
    shared += ["tip_qw", "tip_qx", "tip_qy", "tip_qz"]
    assert list(b.columns[:10]) == shared
    assert list(t.columns[1:11]) == shared and t.columns[0] == "time_s"
    # Other units for both, the same way.
    si = {"pressure": "Pa", "length": "m"}
    assert list(batch.to_frame(si).columns[:4]) == ["p0_Pa", "p1_Pa", "p2_Pa", "tip_x_m"]
    assert list(traj.to_frame(si).columns[1:5]) == ["p0_Pa", "p1_Pa", "p2_Pa", "tip_x_m"]


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_batch_frame_loads_back(batch, tmp_path, suffix):
    path = write_table(batch.to_frame(), tmp_path / f"batch{suffix}")
    ds = load_dataset(path, design=SPA)
    assert ds.synthetic and ds.metadata["design"] == SPA
    assert ds.metadata["generator"] == "softrod.solve_statics_batch"
    assert ds.metadata["softrod_version"] == softrod.__version__
    assert ds.metadata["solver"]["tol"] == 1e-10
    np.testing.assert_allclose(ds.tip_position, batch.tip_position, rtol=UNIT_ROUND_TRIP)
    np.testing.assert_allclose(ds.pressures, batch.pressures, rtol=UNIT_ROUND_TRIP)
    # Rotation through the quaternion: a few ulp of a unit-size matrix.
    np.testing.assert_allclose(ds.tip_rotation, batch.tip_rotation, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(ds.extra["iterations"], batch.iterations)
    assert ds.extra["converged"].dtype == bool and ds.extra["converged"].all()
    # Written again, the result columns stay declared: the file loads a second time.
    again = load_dataset(write_table(ds.to_frame(), tmp_path / f"again{suffix}"))
    assert list(again.extra) == list(ds.extra)


def _with_a_failed_row(batch) -> BatchSolution:
    def failed(a):
        a = np.array(a, dtype=float)
        a[1] = np.nan
        return a

    return BatchSolution(
        pressures=batch.pressures,
        tip_position=failed(batch.tip_position),
        tip_rotation=failed(batch.tip_rotation),
        base_force=failed(batch.base_force),
        base_moment=failed(batch.base_moment),
        converged=np.array([True, False, True]),
        iterations=batch.iterations,
        residual=failed(batch.residual),
        metadata=batch.metadata,
    )


def test_rows_that_did_not_converge(batch, tmp_path):
    path = write_table(_with_a_failed_row(batch).to_frame(), tmp_path / "sweep.csv")
    lines = path.read_text().splitlines()
    assert lines[0].startswith("# metadata: ") and ",,," in lines[3]  # empty cells, not NaN text
    with pytest.raises(InputError, match=r"did not converge at line 4 \(1 of 3 rows\)"):
        load_dataset(path)
    ds = load_dataset(path, unconverged="drop")
    assert len(ds) == 2
    np.testing.assert_allclose(ds.pressures, P[[0, 2]], rtol=UNIT_ROUND_TRIP)


def test_undeclared_columns_stay_errors(batch, tmp_path):
    frame = batch.to_frame()
    frame["tip_Z_mm"] = 0.0  # a typo, not declared in the metadata
    with pytest.raises(InputError, match=r"tip_Z_mm.*unknown column"):
        load_dataset(frame)


def test_bundled_datasets_by_name():
    by_name = load_dataset("spa130_synthetic")
    assert len(by_name) == 216 and by_name.source.name == "spa130_synthetic.csv"
    with pytest.raises(InputError, match="no such file or bundled example dataset.*spa130"):
        load_dataset("spa131_synthetic")
    assert softrod.example_datasets() == ["paper002_m3_synthetic", "spa130_synthetic"]


def test_commands_take_bundled_names(run):
    res = run("designs")
    assert res.exit_code == 0 and "spa130_synthetic" in res.stdout
    res = run("calibrate", SPA, "no_such_dataset", "--params", "c_b")
    assert_clean_error(res, 2, "DATA", "no_such_dataset", "spa130_synthetic")


def test_channels_count_from_zero_in_messages(run, tmp_path):
    res = run("solve", SPA, "--pressure", "30kPa,0,0")
    assert "pressures p0..p2" in res.stdout
    res = run("solve", SPA, "--pressure", "30kPa,0")
    assert_clean_error(res, 2, "--pressure", "3 pressure channels")
    from softrod.calibration.metrics import per_sample_errors
    from softrod.calibration.report import _pressure_figure

    samples = per_sample_errors(np.zeros((3, 3)), np.ones((3, 3)) * 1e-3)
    fig = _pressure_figure(samples, P)
    try:
        assert [ax.get_xlabel() for ax in fig.axes] == ["p0 (kPa)", "p1 (kPa)", "p2 (kPa)"]
    finally:
        import matplotlib.pyplot as plt

        plt.close(fig)


def test_compare_pcc_figure_names_channels_as_given(run, tmp_path):
    out = tmp_path / "c.png"
    res = run("compare-pcc", "stiff_flop_pcc", "--channels", "5,0,1", "--steps", "2", "--out", out)
    assert res.exit_code == 0, res.output
    import matplotlib.pyplot as plt
    from softrod.pcc.compare import compare_pcc, plot_pcc_comparison

    df = compare_pcc("stiff_flop_pcc", [5, 0, 1], 1e5, steps=2)
    fig = plot_pcc_comparison(df, title="t")
    try:
        assert fig.axes[0].get_xlabel() == "pressure (kPa)"
    finally:
        plt.close(fig)
    assert df.attrs["softrod.metadata"]["channels"] == [5, 0, 1]


def test_known_unit_factors_are_pints():
    """Tables are written without building pint's registry: the shortcut factors must be
    exactly the ones pint gives (the same doubles)."""
    from softrod.schema import _KNOWN_FACTORS, TABLE_SI, UNIT_ALIASES
    from softrod.units import registry

    ureg = registry()
    for (kind, unit), factor in _KNOWN_FACTORS.items():
        parsed = ureg.parse_units(UNIT_ALIASES.get(unit, unit))
        assert float(ureg.Quantity(1.0, parsed).to(TABLE_SI[kind]).magnitude) == factor, unit
