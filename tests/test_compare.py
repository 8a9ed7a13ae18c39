"""compare_models: paper 002's experiments (Sec. V) for several models, tables and figure."""

import copy

import numpy as np
import pandas as pd
import pytest
import softrod
from softrod import InputError, compare_models, load_dataset, load_design, solve_statics_batch
from softrod.compare import (
    COLUMNS,
    EXPERIMENTS,
    RESULT_COLUMNS,
    clamp_frame,
    plot_comparison,
    pressure_ramp,
    resolve_experiments,
)
from softrod.io import write_table
from softrod.plotting import save_figure

pytestmark = pytest.mark.fast  # the whole module runs in a few seconds

SHORT = pressure_ramp(0.0, 0.6e5, 3)  # 4 levels: enough for shape checks, quick
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def table():
    return compare_models(["M0", "M2"], experiments="ii-0,iii,a", pressures=SHORT, threads=1)


def test_paper_ramp():
    """Sec. V: 0 to 0.6 bar in 30 equal steps, i.e. 31 levels."""
    ramp = pressure_ramp()
    assert len(ramp) == 31 and ramp[0] == 0.0 and ramp[-1] == pytest.approx(0.6e5)
    np.testing.assert_allclose(np.diff(ramp), 2e3)
    np.testing.assert_allclose(pressure_ramp("0 bar", "60 kPa", 30), ramp, rtol=0, atol=1e-9)


@pytest.mark.parametrize("steps", [0, -1, 1.5, True])
def test_bad_ramp_steps(steps):
    with pytest.raises(InputError, match="ramp.steps"):
        pressure_ramp(0.0, 1e4, steps)


def test_experiments_and_groups():
    assert list(EXPERIMENTS) == ["i-0", "i-1", "i-2", "ii-0", "ii-1", "ii-2", "iii", "a"]
    assert resolve_experiments(None) == list(EXPERIMENTS)
    assert resolve_experiments("a, i") == ["i-0", "i-1", "i-2", "a"]  # canonical order
    assert resolve_experiments(["iii", "iii"]) == ["iii"]
    assert EXPERIMENTS["ii-1"].weights == (1.0, 0.0, 1.0)  # p1 = 0, the others p
    assert EXPERIMENTS["a"].mounting == "horizontal"
    assert EXPERIMENTS["i-2"].title == "(i-2) vertical: p2 = p, p0 = p1 = 0"
    with pytest.raises(InputError, match="experiments = 'iv'.*unknown"):
        resolve_experiments("i,iv")


def test_table_columns_and_rows(table):
    assert tuple(table.columns) == COLUMNS + RESULT_COLUMNS
    assert len(table) == 2 * 3 * len(SHORT)
    assert table["converged"].all()
    assert list(table["model"].unique()) == ["M0", "M2"]
    assert set(table["design"]) == {
        "paper002_M0_vertical",
        "paper002_M0_horizontal",
        "paper002_M2_vertical",
        "paper002_M2_horizontal",
    }
    rows = table[(table["model"] == "M2") & (table["experiment"] == "ii-0")]
    np.testing.assert_array_equal(rows["step"], np.arange(len(SHORT)))
    np.testing.assert_allclose(rows["ramp_kPa"], SHORT / 1e3)
    np.testing.assert_array_equal(rows["p0_kPa"], 0.0)
    np.testing.assert_allclose(rows[["p1_kPa", "p2_kPa"]], np.c_[SHORT, SHORT] / 1e3)
    assert (rows["mounting"] == "vertical").all()


def test_rows_equal_a_direct_batch_solve(table):
    rows = table[(table["model"] == "M2") & (table["experiment"] == "iii")]
    direct = solve_statics_batch("paper002_M2_vertical", np.c_[SHORT, SHORT, SHORT], threads=1)
    # Same inputs, same ordered batch: identical up to the mm scaling.
    np.testing.assert_allclose(
        rows[["tip_x_mm", "tip_y_mm", "tip_z_mm"]], direct.tip_position * 1e3, rtol=1e-15
    )


def test_paper_frame_mapping(table):
    """Documented maps (design descriptions): vertical paper (x, y, z) = world (x, -y, -z);
    horizontal paper (x, y, z) = world (z, -y, x)."""
    w = table[["tip_x_mm", "tip_y_mm", "tip_z_mm"]].to_numpy()
    p = table[["paper_x_mm", "paper_y_mm", "paper_z_mm"]].to_numpy()
    vertical = (table["mounting"] == "vertical").to_numpy()
    # 1e-12 mm: a matrix of 0 and +-1 applied in floating point
    np.testing.assert_allclose(p[vertical], w[vertical] * [1, -1, -1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(p[~vertical], w[~vertical][:, [2, 1, 0]] * [1, -1, 1], atol=1e-12)


def test_horizontal_zero_pressure_tip_is_the_measured_one(table):
    """Eq. 24: at zero pressure the end point was at (-34.5, 2.8, 130.8) mm in the paper's
    frame. 10 mm as in test_designs (M0's mean error in Table V is 9-11 mm); the frame map
    matters: a sign error in x would miss by about 69 mm."""
    start = table[(table["experiment"] == "a") & (table["step"] == 0)]
    for _, row in start.iterrows():
        tip = row[["paper_x_mm", "paper_y_mm", "paper_z_mm"]].to_numpy(dtype=float)
        assert np.linalg.norm(tip - [-34.5, 2.8, 130.8]) < 10.0


def test_equal_pressures_drift_sideways_only_with_the_offset(table):
    """Experiment (iii) (Fig. 5 bottom, Sec. VII): M0 only elongates, M2 drifts sideways."""
    iii = table[table["experiment"] == "iii"]
    for model, low, high in (("M0", 0.0, 0.1), ("M2", 5.0, np.inf)):  # mm
        r = iii[iii["model"] == model][["paper_x_mm", "paper_y_mm"]].to_numpy()
        drift = np.linalg.norm(r[-1] - r[0])
        assert low <= drift < high, (model, drift)


def test_clamp_frame_of_the_base_is_zero():
    d = load_design("paper002_M3_horizontal")
    np.testing.assert_array_equal(clamp_frame(d, d.spec["mounting"]["base_position"]), 0.0)


def test_own_designs_as_models():
    m3 = load_design("paper002_M3_vertical")
    stiffer = m3.replace({"sections[1].c_b": 1.5})
    df = compare_models(
        {"M3": {"vertical": m3}, "stiff": {"vertical": stiffer}},
        experiments="i-0",
        pressures=SHORT,
    )
    end = df[df["step"] == len(SHORT) - 1].set_index("model")["paper_x_mm"]
    assert 0 < end["stiff"] < end["M3"]  # a stiffer body bends less


@pytest.mark.parametrize(
    ("models", "experiments", "match"),
    [
        (["M7"], "iii", "models = 'M7'.*unknown model"),
        ([], "iii", "at least one model"),
        ({"x": {"vertical": "paper002_M0_vertical"}}, "a", "needs a design for the horizontal"),
        ({"x": {"sideways": "paper002_M0_vertical"}}, "iii", "unknown mounting"),
        ({"x": {"vertical": "pam_arm_220mm"}}, "iii", None),  # 3 channels: accepted
    ],
    ids=["unknown", "empty", "missing-mounting", "bad-mounting", "other-design"],
)
def test_model_errors(models, experiments, match):
    if match is None:
        compare_models(models, experiments=experiments, pressures=[0.0])
        return
    with pytest.raises(InputError, match=match):
        compare_models(models, experiments=experiments, pressures=SHORT)


def test_bad_pressures_and_failing_ramp():
    with pytest.raises(InputError, match="pressures"):
        compare_models(["M0"], pressures=[[0.0, 1.0]])
    # M3 swells its chambers (eq. 22); at 3 bar chamber 1 breaks through the wall. The error
    # says which model and experiment.
    with pytest.raises(InputError, match="model M3, experiment i-0: .*outer wall"):
        compare_models(["M3"], experiments="i-0", pressures=[0.0, 3e5])


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_table_round_trip(table, tmp_path, suffix):
    path = write_table(table, tmp_path / f"compare{suffix}")
    assert sorted(tmp_path.iterdir()) == [path]  # written atomically: no temporary left
    back = pd.read_csv(path, comment="#") if suffix == ".csv" else pd.read_parquet(path)
    assert tuple(back.columns) == COLUMNS + RESULT_COLUMNS
    # The CSV text is the shortest decimal that reads back to the same double: exact.
    pd.testing.assert_frame_equal(back, table, check_exact=True, check_dtype=False)
    ds = load_dataset(path)  # the dataset schema, result columns declared in the metadata
    # mm -> m (load) -> mm (here): two roundings, at most 2 ulp = 4.4e-16 relative.
    tips = table[["tip_x_mm", "tip_y_mm", "tip_z_mm"]]
    np.testing.assert_allclose(ds.tip_position * 1e3, tips, rtol=1e-15)
    assert ds.metadata["generator"] == "softrod.compare_models"
    assert ds.metadata["softrod_version"] == softrod.__version__
    assert list(ds.extra["model"][:2]) == ["M0", "M0"] and ds.extra["converged"].all()
    assert list(ds.experiments) == ["ii-0", "iii", "a"]


def test_figure(table, tmp_path):
    import matplotlib.pyplot as plt

    fig = plot_comparison(table, experiments="iii,a", title="test")
    try:
        axes = fig.get_axes()
        assert len(axes) == 2 * 3  # (x, y, z) per experiment
        assert [a.get_ylabel() for a in axes[:3]] == ["x (mm)", "y (mm)", "z (mm)"]
        assert all(a.get_xlabel() == "p (kPa)" for a in axes)
        assert [len(a.get_lines()) for a in axes] == [2] * 6  # one line per model
        # SubFigure.get_suptitle needs matplotlib 3.8; softrod supports 3.7.
        titles = [s._suptitle.get_text() for s in fig.subfigs]  # header, then experiments
        assert titles == ["test", EXPERIMENTS["iii"].title, EXPERIMENTS["a"].title]
        assert [t.get_text() for t in fig.subfigs[0].legends[0].get_texts()] == ["M0", "M2"]
        # x axis in kPa: the last point of the ramp is at 60 kPa (0.6 bar)
        assert axes[0].get_lines()[0].get_xdata()[-1] == pytest.approx(60.0)
        path = save_figure(fig, tmp_path / "compare.png")
        assert path.read_bytes()[:8] == PNG_SIGNATURE
        assert sorted(tmp_path.iterdir()) == [path]
    finally:
        plt.close(fig)
    with pytest.raises(InputError, match="none of them"):
        plot_comparison(table, experiments="i-0")
    with pytest.raises(InputError, match="missing column"):
        plot_comparison(table.drop(columns="paper_x_mm"))


def test_public_names():
    assert softrod.compare_models is compare_models


# --------------------------------------------------------------------------- friction

#: Few increments keep the frictional tests short; the count changes the answer (first
#: order), never whether a row equals its single solve.
STEPS = softrod.SolverOptions(friction_steps=10)
#: Off the wall, touching (from about 18 kPa on channel 0), pressed, pressed harder.
WALL_RAMP = [0.0, 20e3, 40e3, 60e3]


@pytest.fixture(scope="module")
def walled():
    from friction_designs import spa_beside_rough_wall

    return spa_beside_rough_wall()


def _spy_batches(monkeypatch, module):
    """Every solve_statics_batch call made through ``module``: (design, pressures, kwargs,
    out)."""
    calls = []
    real = module.solve_statics_batch

    def spy(design, pressures, **kwargs):
        out = real(design, pressures, **kwargs)
        calls.append((design, pressures, kwargs, out))
        return out

    monkeypatch.setattr(module, "solve_statics_batch", spy)
    return calls


def assert_rows_are_single_solves(calls) -> int:
    """Each row of each batch bitwise the single frictional solve of that row (same
    increments, same stiffness map); returns how many rows rub (friction force > 0.1 mN,
    far above the solver's resolution of it: a pressed row carries tens of mN)."""
    rubbing = 0
    for design, pressures, kwargs, out in calls:
        assert out.friction_force is not None  # the frictional batch ran
        for k, p in enumerate(pressures):
            single = softrod.solve_statics(
                design, p, stiffness_map=kwargs.get("stiffness_map"), options=STEPS
            )
            for name in ("tip_position", "tip_rotation", "base_force", "base_moment"):
                np.testing.assert_array_equal(getattr(out, name)[k], getattr(single, name))
            np.testing.assert_array_equal(out.friction_force[k], single.contact.friction_force)
            rubbing += np.abs(single.contact.friction_force).max() > 1e-4
    return rubbing


def test_frictional_rows_are_the_single_frictional_solves(walled, monkeypatch):
    """A design whose obstacle has friction: every (experiment, level) row is its own load
    path from rest, so it is bitwise solve_statics of that row alone."""
    from softrod import compare as module

    calls = _spy_batches(monkeypatch, module)
    df = compare_models(
        {"rough": {"vertical": walled}},
        experiments="i-0,ii-1",
        pressures=WALL_RAMP,
        options=STEPS,
        threads=2,
        progress=False,
    )
    assert df["converged"].all() and len(df) == 2 * len(WALL_RAMP) and len(calls) == 2
    assert assert_rows_are_single_solves(calls) >= 3  # not vacuous: pressed rows rub
    # The table holds those batches (up to the mm scaling, as for any design).
    tips = np.vstack([out.tip_position for _, _, _, out in calls])
    np.testing.assert_allclose(df[["tip_x_mm", "tip_y_mm", "tip_z_mm"]], tips * 1e3, rtol=1e-15)


def test_frictional_compare_errors_name_the_field(walled):
    # A negative friction coefficient in a model's design document is named by its field.
    doc = copy.deepcopy(walled.document)
    doc["obstacles"][0]["friction"] = -0.5
    with pytest.raises(softrod.DesignError) as err:
        compare_models({"rough": {"vertical": doc}}, experiments="i-0", pressures=[0.0])
    assert err.value.field == "obstacles[0].friction"
    # Hostile increments are refused by SolverOptions, before compare_models runs.
    for steps in (0, 2.5, "80"):
        with pytest.raises(InputError, match="friction_steps"):
            softrod.SolverOptions(friction_steps=steps)
    # options must be SolverOptions (named before any solve, not an AttributeError after).
    with pytest.raises(InputError) as err:
        compare_models({"rough": {"vertical": walled}}, experiments="i-0", options=80)
    assert err.value.field == "options"


@pytest.fixture(scope="module")
def hybrid():
    """A small hybrid model of the frictionless SPA (as tests/test_keep.py fits it)."""
    data = load_dataset("spa130_synthetic").subset(np.arange(72))
    ident = softrod.identify_stiffness("spa_three_chamber_130mm", data)
    return softrod.fit_stiffness_map(ident, hidden=(12, 10), seed=3)


def test_compare_hybrid_on_a_frictional_design_solves_each_row_from_rest(
    walled, hybrid, monkeypatch
):
    """compare_hybrid of the SPA beside its rough wall: the hybrid's and the literature's
    rows are each the single frictional solve of that row (with its stiffness map)."""
    from softrod.calibration import hybrid as module

    calls = _spy_batches(monkeypatch, module)
    data = hybrid.identification.dataset
    table = softrod.compare_hybrid(walled, data, hybrid, constant=None, options=STEPS)
    assert len(calls) == 2 and (table["failed"] == 0).all()
    # Not vacuous: the held-out rows with 70 kPa on channel 0 press on the wall.
    assert assert_rows_are_single_solves(calls) >= 2


def test_compare_hybrid_refuses_the_constant_fit_on_a_frictional_design_first(
    walled, hybrid, monkeypatch
):
    """The constant-sigma fit is a calibration (frictionless): refused by the obstacle's
    friction before any batch runs."""
    from softrod.calibration import hybrid as module

    calls = _spy_batches(monkeypatch, module)
    with pytest.raises(InputError) as err:
        softrod.compare_hybrid(walled, hybrid.identification.dataset, hybrid, options=STEPS)
    assert err.value.field == "obstacles[0].friction" and "constant=None" in str(err.value)
    assert calls == []
