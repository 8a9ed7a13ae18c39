"""The ``softrod`` command line, driven through click's CliRunner."""

import json
import math

import numpy as np
import pandas as pd
import pytest
import softrod
from conftest import assert_clean_error
from softrod import ConvergenceError, load_dataset, solve_statics, solve_statics_batch

pytestmark = pytest.mark.fast  # the whole module runs in seconds

SPA = "spa_three_chamber_130mm"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def test_version(run):
    result = run("--version")
    assert result.exit_code == 0
    assert result.output.strip() == f"softrod {softrod.__version__}"


def test_solve_table(run):
    result = run("solve", SPA, "--pressure", "30kPa,0,0")
    assert result.exit_code == 0, result.output
    out = result.stdout
    for text in (
        "tip position",
        "tip tangent",
        "base force",
        "base moment",
        "iterations",
        "residual",
        "mm",
        "N mm",
    ):
        assert text in out
    tip_mm = solve_statics(SPA, [30e3, 0, 0]).tip_position * 1e3
    assert f"{tip_mm[1]:.3f}" in out and f"{tip_mm[2]:.3f}" in out


def test_solve_json_equals_api(run):
    result = run("solve", SPA, "--pressure", "0.3bar,0,0", "--tip-force", "0,0,-1 N", "--json")
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert set(data) == {
        "design",
        "pressures_Pa",
        "tip_position_m",
        "tip_rotation",
        "base_force_N",
        "base_moment_Nm",
        "converged",
        "stable",
        "violations",
        "iterations",
        "residual",
        "shape",
    }
    api = solve_statics(SPA, [30e3, 0, 0], tip_force=[0, 0, -1])
    assert data["design"] == SPA and data["converged"] is True
    assert data["stable"] is True and data["violations"] == []
    # 1e-9 Pa: "0.3bar" converts to 30000 Pa up to round-off.
    np.testing.assert_allclose(data["pressures_Pa"], [30e3, 0, 0], rtol=0, atol=1e-9)
    # Same inputs, same deterministic solve, and JSON floats round-trip exactly; 1e-12 m
    # only allows for the last bit of the bar -> Pa conversion.
    np.testing.assert_allclose(data["tip_position_m"], api.tip_position, rtol=0, atol=1e-12)
    np.testing.assert_allclose(data["tip_rotation"], api.tip_rotation, rtol=0, atol=1e-12)
    np.testing.assert_allclose(data["base_force_N"], api.base_force, rtol=0, atol=1e-12)
    np.testing.assert_allclose(data["base_moment_Nm"], api.base_moment, rtol=0, atol=1e-12)
    assert data["iterations"] == api.iterations
    np.testing.assert_allclose(data["shape"]["s_m"], api.s, rtol=0, atol=0)
    np.testing.assert_allclose(data["shape"]["position_m"], api.position, rtol=0, atol=1e-12)


def test_solve_plot_writes_png(run, tmp_path):
    path = tmp_path / "shape.png"
    result = run("solve", SPA, "--pressure", "50kPa,0,20kPa", "--plot", path)
    assert result.exit_code == 0, result.output
    assert path.read_bytes()[:8] == PNG_SIGNATURE
    assert list(tmp_path.iterdir()) == [path]  # the temporary file was moved, not left


def test_solve_json_with_plot_keeps_stdout_json(run, tmp_path):
    path = tmp_path / "shape.svg"
    result = run("solve", SPA, "--json", "--plot", path)
    assert result.exit_code == 0
    json.loads(result.stdout)  # the "wrote ..." note went to stderr
    assert "wrote" in result.stderr and path.read_text().lstrip().startswith("<?xml")


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_sweep_writes_table(run, tmp_path, suffix):
    out = tmp_path / f"workspace{suffix}"
    result = run("sweep", SPA, "--grid", "0:60kPa:3", "--out", out, "--threads", 1)
    assert result.exit_code == 0, result.output
    assert "27 rows" in result.stdout and "solves/s" in result.stdout
    ds = load_dataset(out, design=SPA)  # the dataset schema: softrod reads its own table
    assert ds.metadata["generator"] == "softrod sweep" and ds.metadata["design"] == SPA
    assert ds.metadata["softrod_version"] == softrod.__version__
    assert ds.metadata["grid"] == ["0:60kPa:3"]
    assert list(ds.extra) == ["converged", "iterations", "residual", "stable"]
    df = ds.to_frame()
    assert list(df.columns[:9]) == [
        "p0_kPa",
        "p1_kPa",
        "p2_kPa",
        "tip_x_mm",
        "tip_y_mm",
        "tip_z_mm",
        "tip_qw",
        "tip_qx",
        "tip_qy",
    ]
    assert len(ds) == 27
    assert ds.extra["converged"].all()
    # Channel 0 slowest, last channel fastest.
    np.testing.assert_array_equal(ds.pressures[:3, 2], [0.0, 30e3, 60e3])
    np.testing.assert_array_equal(ds.pressures[:9, 0], 0.0)
    np.testing.assert_array_equal(ds.pressures[18:, 0], 60e3)
    sol = solve_statics(SPA, ds.pressures[14])
    # 1e-9 m: sweep rows warm-start (see test_batch_equals_single); the file keeps full
    # float precision (kPa and mm to the shortest round-trip decimal).
    np.testing.assert_allclose(ds.tip_position[14], sol.tip_position, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ds.tip_rotation[14], sol.tip_rotation, rtol=0, atol=1e-8)
    np.testing.assert_allclose(ds.base_force[14], sol.base_force, rtol=0, atol=1e-8)


def test_sweep_grid_per_channel(run, tmp_path):
    out = tmp_path / "w.csv"
    result = run(
        "sweep",
        SPA,
        "--grid",
        "0:20kPa:3",
        "--grid",
        "0.1:0.2bar:2",
        "--grid",
        "5kPa:5kPa:1",
        "--out",
        out,
    )
    assert result.exit_code == 0, result.output
    ds = load_dataset(out)
    assert len(ds) == 6
    # 1e-9 Pa: bar -> Pa round-off.
    np.testing.assert_allclose(sorted(set(ds.pressures[:, 1])), [10e3, 20e3], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(ds.pressures[:, 2], 5e3)
    batch = solve_statics_batch(SPA, ds.pressures)
    np.testing.assert_allclose(
        ds.tip_position, batch.tip_position, rtol=0, atol=1e-9
    )  # 1e-9 m: chunking changes warm starts


@pytest.mark.parametrize(
    ("args", "fragments"),
    [
        (["--grid", "0:70kPa:1000"], ["--grid", "10,000,000"]),  # 1e9 rows, refused at once
        (["--grid", "0:70kPa"], ["--grid", "START:STOP:COUNT"]),
        (["--grid", "0:70kPa:0"], ["--grid.count"]),
        (["--grid", "0:1m:3"], ["--grid.stop"]),
        (["--grid", "0:1:3", "--grid", "0:1:3"], ["--grid", "one per channel"]),
    ],
    ids=["too-big", "no-count", "zero-count", "wrong-unit", "two-grids-three-channels"],
)
def test_sweep_bad_grid(run, tmp_path, args, fragments):
    out = tmp_path / "w.csv"
    result = run("sweep", SPA, *args, "--out", out)
    assert_clean_error(result, 2, *fragments)
    assert not out.exists()


def test_sweep_unknown_suffix(run, tmp_path):
    result = run("sweep", SPA, "--grid", "0:1kPa:2", "--out", tmp_path / "w.xlsx")
    assert_clean_error(result, 2, "--out", ".csv", ".parquet")


@pytest.mark.parametrize(
    ("pressure", "fragments"),
    [
        ("30kPa,abc,0", ["--pressure[1]", "abc"]),
        ("30kPa,0", ["--pressure", "3 pressure channels"]),
        ("30kPa,5,0", ["--pressure[1]", "ambiguous"]),
        ("-2bar,0,0", ["--pressure[0]", "-1 atm"]),
        ("30mm,0,0", ["--pressure[0]", "pressure"]),
    ],
    ids=["unreadable", "count", "ambiguous", "below-vacuum", "wrong-unit"],
)
def test_solve_bad_pressure_exits_2(run, pressure, fragments):
    assert_clean_error(run("solve", SPA, "--pressure", pressure), 2, *fragments)


def test_unit_on_last_item_applies_to_all(run):
    a = json.loads(run("solve", SPA, "-p", "10,20,30kPa", "--json").stdout)
    b = json.loads(run("solve", SPA, "-p", "10kPa,20kPa,30kPa", "--json").stdout)
    assert a["pressures_Pa"] == b["pressures_Pa"] == [10e3, 20e3, 30e3]


def test_bad_design_exits_2(run, tmp_path):
    assert_clean_error(run("solve", "no_such_design"), 2, "design", SPA)
    bad = tmp_path / "bad.toml"
    bad.write_text("[design\n")
    assert_clean_error(run("solve", bad), 2, "not valid TOML")


def test_convergence_failure_exits_3(run, monkeypatch):
    def fail(*args, **kwargs):
        raise ConvergenceError(
            "static solve did not converge after 25 iterations", iterations=25, residual=1e-3
        )

    monkeypatch.setattr("softrod.statics.solve_statics", fail)
    assert_clean_error(run("solve", SPA, "-p", "70kPa,0,0"), 3, "did not converge")


def test_demo_writes_files(run, tmp_path):
    out_dir = tmp_path / "demo"
    result = run("demo", "--out-dir", out_dir)
    assert result.exit_code == 0, result.output
    shapes, tips = out_dir / "shapes.png", out_dir / "tips.csv"
    assert shapes.read_bytes()[:8] == PNG_SIGNATURE
    ds = load_dataset(tips, design=SPA)
    assert len(ds) == 5
    assert {"lateral_mm", "iterations", "solve_time_us"} == set(ds.extra)
    assert ds.metadata["generator"] == "softrod demo"
    np.testing.assert_array_equal(ds.pressures[1], [35e3, 0, 0])  # channel 0 first
    # Pressurising channel 0 bends the actuator sideways, more at 70 than at 35 kPa;
    # equal pressure on all three only stretches it (1e-6 mm: round-off of a symmetric case).
    lateral = ds.extra["lateral_mm"]
    assert lateral[0] == pytest.approx(0.0, abs=1e-6)
    assert 0 < lateral[1] < lateral[2]
    assert lateral[4] == pytest.approx(0.0, abs=1e-6)
    df = ds.to_frame()
    assert df["tip_z_mm"][4] < df["tip_z_mm"][0] < 0  # hangs down and stretches
    assert str(shapes) in result.stdout and str(tips) in result.stdout
    assert "solves/s" in result.stdout


def test_designs_lists_all(run):
    result = run("designs")
    assert result.exit_code == 0
    for name in softrod.bundled_designs():
        assert name in result.stdout
    assert "3 channels" in result.stdout
    for name in softrod.bundled_systems():
        assert f"{name}  2 rods" in result.stdout


# --------------------------------------------------------------------------- presets, compare


def test_designs_lists_presets(run):
    result = run("designs")
    assert result.exit_code == 0
    assert "presets" in result.stdout
    for p in softrod.list_presets():
        assert p.name in result.stdout


def test_solve_accepts_a_preset_name(run):
    result = run("solve", "paper002_M3_vertical", "-p", "0.3bar,0,0", "--json")
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["design"] == "paper002_M3_vertical"
    api = solve_statics("paper002_M3_vertical", [30e3, 0, 0])
    np.testing.assert_allclose(data["tip_position_m"], api.tip_position, rtol=0, atol=1e-12)


def test_compare_writes_table_and_figure(run, tmp_path):
    out, fig = tmp_path / "compare.parquet", tmp_path / "compare.png"
    result = run(
        "compare",
        "paper002",
        "--models",
        "M0,M3",
        "--experiments",
        "iii,a",
        "--pressure-ramp",
        "0:0.6bar:2",
        "--out",
        out,
        "--figure",
        fig,
        "--threads",
        1,
    )
    assert result.exit_code == 0, result.output
    assert "2 models x 2 experiments x 3 levels" in result.stdout
    assert "12 solves, 12 converged" in result.stdout
    assert str(out) in result.stdout and str(fig) in result.stdout
    df = pd.read_parquet(out)
    assert tuple(df.columns) == softrod.compare.COLUMNS + softrod.compare.RESULT_COLUMNS
    assert len(df) == 12 and df["converged"].all()
    np.testing.assert_allclose(sorted(set(df["ramp_kPa"])), [0.0, 30.0, 60.0], rtol=0, atol=1e-9)
    ds = load_dataset(out)
    assert ds.metadata["generator"] == "softrod.compare_models" and len(ds) == 12
    api = softrod.compare_models(["M0", "M3"], experiments="iii,a", pressures=[0, 30e3, 60e3])
    np.testing.assert_allclose(df["paper_z_mm"], api["paper_z_mm"], rtol=0, atol=1e-9)
    # The printed table shows the tip at the top of the ramp in the paper's frame.
    last = api[(api["model"] == "M3") & (api["experiment"] == "iii")].iloc[-1]
    assert f"{last['paper_z_mm']:.2f}" in result.stdout
    assert fig.read_bytes()[:8] == PNG_SIGNATURE
    assert sorted(tmp_path.iterdir()) == sorted([fig, out])  # no temporary files left


def test_compare_defaults_are_paper_002(run):
    result = run("compare", "--models", "M1", "--experiments", "i-1")
    assert result.exit_code == 0, result.output
    assert "1 model x 1 experiment x 31 levels (0 to 60 kPa) = 31 solves" in result.stdout


@pytest.mark.parametrize(
    ("args", "fragments"),
    [
        (["--models", "M0,M4"], ["--models", "M4", "M0, M1, M2, M3"]),
        (["--models", "M0,M0"], ["--models", "twice"]),
        (["--experiments", "i,iv"], ["--experiments", "iv", "unknown experiment"]),
        (["--pressure-ramp", "0:0.6bar"], ["--pressure-ramp", "START:STOP:STEPS"]),
        (["--pressure-ramp", "0:0.6bar:0"], ["--pressure-ramp.steps"]),
        (["--pressure-ramp", "0:1m:3"], ["--pressure-ramp.stop", "pressure"]),
        (["--pressure-ramp", "-2bar:0:3"], ["--pressure-ramp.start", "-1 atm"]),
        (["--out", "{tmp}/c.xlsx"], ["--out", ".csv", ".parquet"]),
        (["--figure", "{tmp}/c.foo"], ["--figure", ".png"]),
        (["--out", "{tmp}/nodir/c.csv"], ["--out", "does not exist"]),
        # M3 swells its chambers (eq. 22) into the bore at 1.5 bar
        (["--models", "M3", "--pressure-ramp", "0:3bar:2"], ["model M3", "lower c_p"]),
    ],
    ids=[
        "unknown-model",
        "model-twice",
        "unknown-experiment",
        "ramp-no-steps",
        "ramp-zero-steps",
        "ramp-wrong-unit",
        "ramp-below-vacuum",
        "table-suffix",
        "figure-suffix",
        "no-folder",
        "swelling-too-far",
    ],
)
def test_compare_bad_options(run, tmp_path, args, fragments):
    args = [a.replace("{tmp}", str(tmp_path)) for a in args]
    result = run("compare", *args)
    assert_clean_error(result, 2, *fragments)
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_compare_unknown_protocol(run):
    result = run("compare", "paper001")
    assert result.exit_code == 2
    assert "paper002" in result.stderr


def test_modes_lists_the_linearisations_modes(run, tmp_path):
    """``softrod modes``: the table, the JSON (the same numbers as softrod.linearise's modes)
    and the written table; a pinned design file is linearised pinned."""
    result = run("modes", SPA, "-p", "30kPa,5kPa,45kPa", "--count", 4)
    assert result.exit_code == 0, result.output
    assert "frequency (Hz)" in result.stdout and "tip free; 12 nodes" in result.stdout
    result = run("modes", SPA, "-p", "30kPa,5kPa,45kPa", "--count", 4, "--nodes", 8, "--json")
    out = json.loads(result.stdout)
    want = softrod.linearise(SPA, [30e3, 5e3, 45e3], nodes=8).modes(4)
    np.testing.assert_array_equal(out["frequency_Hz"], want.frequency)
    assert out["tip_constraint"] == "free" and out["nodes"] == 8
    path, picture = tmp_path / "modes.csv", tmp_path / "modes.png"
    assert run("modes", SPA, "--count", 3, "--output", path, "--figure", picture).exit_code == 0
    assert picture.read_bytes()[:8] == PNG_SIGNATURE
    frame = pd.read_csv(path)
    assert list(frame.columns) == ["mode", "frequency_Hz", "damping_ratio", "damped_frequency_Hz"]
    assert len(frame) == 3
    design = softrod.load_design(SPA)
    tip = solve_statics(design, [0, 0, 0]).tip_position * 1e3
    pinned = design.replace(
        {"tip": {"constraint": "pinned", "position": [f"{float(v)!r} mm" for v in tip]}}
    )
    file = pinned.save(tmp_path / "pinned.toml")
    result = run("modes", file, "--count", 2, "--json")
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["tip_constraint"] == "pinned"


def test_modes_of_a_fluttering_design_show_what_grows(run, tmp_path):
    """Beck's column (tests/test_linearise_loads.py) above its flutter load: the command
    exits 2 with the refusal naming the equilibrium, after a line with the growing pole's
    rate and frequency (the same as LinearSystem.poles()); below it, the table, whose
    header says the tip load follows the tip."""
    from test_linearise_loads import beck

    for p, code in ((19.5, 0), (20.5, 2)):
        file = beck(p).save(tmp_path / f"beck_{p}.toml")
        result = run("modes", file, "--count", 2)
        assert result.exit_code == code, result.output
    assert (
        "tip free (follower tip load); 12 nodes" in run("modes", tmp_path / "beck_19.5.toml").stdout
    )
    top = softrod.linearise(beck(20.5)).poles()[0]
    assert f"{top.real:.4g} 1/s at {abs(top.imag) / (2 * math.pi):.4g} Hz" in result.stderr
    assert "equilibrium" in result.stderr and "flutter" in result.stderr


def test_modes_refusals_name_the_option(run):
    assert_clean_error(run("modes", SPA, "--count", 500), 2, "--count")
    assert_clean_error(run("modes", SPA, "-p", "30kPa,0"), 2, "--pressure")
    assert_clean_error(run("modes", SPA, "--nodes", 0), 2, "--nodes")
    assert_clean_error(run("modes", SPA, "--figure", "modes.txt"), 2, "--figure")
