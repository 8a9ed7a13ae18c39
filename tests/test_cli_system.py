"""``softrod solve-system`` and ``softrod simulate-system`` through click's CliRunner, and the
files, tables and figures of a system's motion (docs/model.md and docs/dynamics.md,
"Systems of rods")."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest
import softrod
from conftest import assert_clean_error
from softrod import InputError, SystemTrajectory
from softrod.system_plots import plot_system, plot_system_motion

SYSTEM = "two_spa_platform"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def system():
    return softrod.load_system(SYSTEM)


@pytest.fixture(scope="module")
def motion(system):
    """10 steps of 2 ms after rod 0's channel 0 stepped to 30 kPa, from rest at 0 kPa."""
    sim = softrod.SystemSimulation(system, dt="2 ms")
    start = sim.state()
    run = sim.run([["30 kPa", 0, 0], [0, 0, 0]], "20 ms")
    return SystemTrajectory.concat([start, run])


# --- the motion's inputs, table, file and figure ------------------------------------------


def test_the_trajectory_carries_the_commanded_inputs(motion):
    assert len(motion) == 11
    assert [p.shape for p in motion.pressures] == [(11, 3), (11, 3)]
    assert [t.shape for t in motion.tensions] == [(11, 0), (11, 0)]
    # The start's pressures, then the step's (held over every step).
    assert motion.pressures[0][0].tolist() == [0.0, 0.0, 0.0]
    assert np.all(motion.pressures[0][1:, 0] == 30e3)
    assert np.all(motion.pressures[1] == 0.0)


def test_the_table_has_units_in_its_names_and_the_api_values(motion):
    frame = motion.to_frame()
    assert frame.shape[0] == 11
    for name in (
        "time_s",
        "rod0_p0_kPa",
        "rod1_p2_kPa",
        "platform_x_mm",
        "platform_qw",
        "platform_vz_mm/s",
        "platform_wy_rad/s",
        "rod1_tip_z_mm",
        "rod0_tip_reaction_fz_N",
        "rod0_tip_reaction_my_Nmm",
        "kinetic_J",
        "energy_balance_J",
    ):
        assert name in frame.columns, name
    # Display units are the SI arrays scaled exactly (mm, kPa, N mm).
    assert np.array_equal(frame["platform_z_mm"], motion.platform_position[:, 2] / 1e-3)
    assert np.array_equal(frame["rod0_p0_kPa"], motion.pressures[0][:, 0] / 1e3)
    si = motion.to_frame(units="SI")
    assert np.array_equal(si["platform_z_m"], motion.platform_position[:, 2])
    assert np.array_equal(si["rod0_tip_reaction_my_Nm"], motion.tip_reaction_moment[:, 0, 1])
    assert frame.attrs["softrod.metadata"]["system"] == SYSTEM


def test_npz_round_trip_is_exact_and_checks_its_system(motion, system, tmp_path):
    path = motion.save(tmp_path / "motion.npz")
    back = SystemTrajectory.load(path, system)
    for name in ("time", "platform_rotation", "tip_reaction_moment", "energy_balance"):
        assert np.array_equal(getattr(back, name), getattr(motion, name)), name
    for i in range(2):
        assert np.array_equal(back.shapes[i], motion.shapes[i])
        assert np.array_equal(back.pressures[i], motion.pressures[i])
    # A file of another system (here: a heavier platform) is refused by name.
    other = dataclasses.replace(system, platform=dataclasses.replace(system.platform, mass=0.05))
    with pytest.raises(InputError, match="another version of it"):
        SystemTrajectory.load(path, other)
    # Damaged or foreign files are errors, never a traceback from numpy or zipfile.
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip archive")
    with pytest.raises(InputError, match="not a readable .npz"):
        SystemTrajectory.load(bad, system)
    np.savez(tmp_path / "foreign.npz", time=np.zeros(3))
    with pytest.raises(InputError, match="not a system trajectory"):
        SystemTrajectory.load(tmp_path / "foreign.npz", system)
    with pytest.raises(InputError, match="only .npz"):
        SystemTrajectory.load(tmp_path / "motion.csv", system)


def test_tables_and_bad_paths(motion, tmp_path):
    csv = motion.save(tmp_path / "motion.csv")
    frame = pd.read_csv(csv, comment="#")
    assert frame.shape[0] == 11
    assert np.allclose(frame["platform_z_mm"], motion.platform_position[:, 2] * 1e3, rtol=1e-12)
    pq = motion.save(tmp_path / "motion.parquet")
    assert pd.read_parquet(pq).shape == frame.shape
    with pytest.raises(InputError, match="must end in"):
        motion.save(tmp_path / "motion.txt")
    with pytest.raises(InputError, match="does not exist"):
        motion.save(tmp_path / "missing" / "motion.npz")


def test_concat_refuses_pieces_out_of_order(motion):
    with pytest.raises(InputError, match="must start after"):
        SystemTrajectory.concat([motion, motion])
    with pytest.raises(InputError, match="non-empty list"):
        SystemTrajectory.concat([])


def test_figures_of_a_motion_and_of_equilibria(motion, system, tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = motion.plot(tmp_path / "motion.png")
    assert (tmp_path / "motion.png").read_bytes()[:8] == PNG_SIGNATURE
    assert len(fig.axes) == 3
    plt.close(fig)
    sols = [softrod.solve_system(system, [[p, 0, 0], [0, 0, 0]]) for p in (0.0, 30e3)]
    fig = plot_system(sols, tmp_path / "eq.png")
    assert (tmp_path / "eq.png").read_bytes()[:8] == PNG_SIGNATURE
    plt.close(fig)
    plt.close(sols[1].plot())
    with pytest.raises(InputError, match="one label per solution"):
        plot_system(sols, labels=["only one"])
    with pytest.raises(InputError, match="unknown figure format"):
        plot_system(sols, tmp_path / "eq.xyz")
    # The figures tell the two results apart by their fields (system_plots imports neither
    # class): a motion is not an equilibrium, nor the other way round.
    for wrong in (motion, [sols[0], motion], "eq", []):
        with pytest.raises(InputError, match="must be a SystemSolution or a non-empty list"):
            plot_system(wrong)
    with pytest.raises(InputError, match="must be a SystemTrajectory"):
        plot_system_motion(sols[0])
    with pytest.raises(InputError, match="must be a SystemSolution or None"):
        plot_system_motion(motion, reference=motion)
    assert not (tmp_path / "eq.xyz").exists()


def test_restore_holds_the_restored_inputs(system):
    # run(None, ...) holds the current pressures: after restore, the saved state's, not
    # those of the run before it.
    sim = softrod.SystemSimulation(system, dt="2 ms")
    sim.run([[0, 0, 0], [0, 0, 0]], "4 ms")
    saved = sim.save()
    twin = sim.copy()
    sim.run([["40 kPa", 0, 0], [0, 0, 0]], "4 ms")
    sim.restore(saved)
    a = sim.run(None, "4 ms")
    b = twin.run(None, "4 ms")
    assert np.array_equal(a.pressures[0], b.pressures[0])
    assert np.array_equal(a.platform_position, b.platform_position)


# --- the commands -----------------------------------------------------------------------


def test_solve_system_table_json_and_plot(run, system, tmp_path):
    result = run("solve-system", SYSTEM, "-p", "30kPa,0,0", "-p", "0,0,0")
    assert result.exit_code == 0, result.output
    api = softrod.solve_system(system, [[30e3, 0, 0], [0, 0, 0]])
    out = result.stdout
    for text in ("platform position", "platform tilt", "rod 1: tip position", "stable", "mm"):
        assert text in out, text
    assert f"{api.platform_position[2] * 1e3:.3f}" in out
    png = tmp_path / "eq.png"
    result = run("solve-system", SYSTEM, "-p", "30kPa,0,0", "-p", "0,0,0", "--json", "--plot", png)
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)  # pure JSON on stdout; "wrote" went to stderr
    assert data["system"] == SYSTEM and data["stable"] is True
    assert np.allclose(data["platform_position_m"], api.platform_position, rtol=0, atol=1e-12)
    assert np.allclose(
        data["rods"][0]["tip_reaction_force_N"], api.rods[0].tip_reaction_force, atol=1e-12
    )
    assert data["rods"][0]["pressures_Pa"] == [30e3, 0.0, 0.0]
    assert png.read_bytes()[:8] == PNG_SIGNATURE


def test_solve_system_refuses_inputs_that_do_not_fit(run, tmp_path):
    result = run("solve-system", SYSTEM, "-p", "30kPa,0,0")
    assert_clean_error(result, 2, "--pressure", "2 rods", "given 1 times")
    result = run("solve-system", SYSTEM, "-p", "30kPa,0,0", "-p", "30,0,0")
    assert_clean_error(result, 2, "--pressure of rod 1[0]")
    result = run("solve-system", SYSTEM, "-p", "30kPa,0", "-p", "0,0,0")
    assert_clean_error(result, 2, "--pressure of rod 0", "3 pressure channels")
    result = run("solve-system", SYSTEM, "--platform-force", "0,0,nan N")
    assert_clean_error(result, 2, "--platform-force[2]")
    result = run("solve-system", "no_such_system")
    assert_clean_error(result, 2, "no such file or bundled system")
    result = run("solve-system", SYSTEM, "--plot", tmp_path / "eq.txt")
    assert_clean_error(result, 2, "--plot")


def test_simulate_system_step_writes_the_motion_and_the_figure(run, system, tmp_path):
    out, png = tmp_path / "motion.npz", tmp_path / "motion.png"
    result = run(
        "simulate-system",
        SYSTEM,
        "-p",
        "30kPa,0,0",
        "-p",
        "0,0,0",
        "--t-end",
        "20 ms",
        "--out",
        out,
        "--plot",
        png,
    )
    assert result.exit_code == 0, result.output
    assert "10 steps" in result.stdout and "platform excursion" in result.stdout
    traj = SystemTrajectory.load(out, system)
    # The command's motion is the API's: the same start, step and time grid.
    sim = softrod.SystemSimulation(system, dt="2 ms")
    api = SystemTrajectory.concat([sim.state(), sim.run([[30e3, 0, 0], [0, 0, 0]], 0.02)])
    assert np.array_equal(traj.time, api.time)
    assert np.array_equal(traj.platform_position, api.platform_position)
    assert png.read_bytes()[:8] == PNG_SIGNATURE


def test_simulate_system_from_a_schedule_file(run, system, tmp_path):
    # Six columns: rod 0's three channels, then rod 1's; a 10 ms ramp of rod 1's p1.
    sched = tmp_path / "ramp.csv"
    sched.write_text(
        "time_s,p0_kPa,p1_kPa,p2_kPa,p3_kPa,p4_kPa,p5_kPa\n0,0,0,0,0,0,0\n0.01,0,0,0,0,20,0\n"
    )
    out = tmp_path / "ramp.csv.parquet"
    result = run("simulate-system", SYSTEM, "--input", sched, "--out", out)
    assert result.exit_code == 0, result.output
    frame = pd.read_parquet(out)
    assert frame.shape[0] == 6  # the start and 5 steps of 2 ms
    assert frame["rod1_p1_kPa"].tolist() == pytest.approx([0, 4, 8, 12, 16, 20], abs=1e-9)
    assert (frame["rod0_p0_kPa"] == 0).all()
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,p0_kPa,p1_kPa,p2_kPa\n0,0,0,0\n0.01,10,0,0\n")
    result = run("simulate-system", SYSTEM, "--input", bad, "--out", tmp_path / "x.npz")
    assert_clean_error(result, 2, "--input", "6")


def test_simulate_system_refuses_bad_options_before_any_work(run, tmp_path):
    out = tmp_path / "m.npz"
    result = run("simulate-system", SYSTEM, "--out", out)
    assert_clean_error(result, 2, "--t-end")
    result = run("simulate-system", SYSTEM, "--t-end", "10 ms", "--out", tmp_path / "m.txt")
    assert_clean_error(result, 2, "--out", ".npz")
    result = run("simulate-system", SYSTEM, "--t-end", "10 ms", "--dt", "0 s", "--out", out)
    assert_clean_error(result, 2, "--dt")
    result = run("simulate-system", SYSTEM, "--t-end", "-1 s", "--out", out)
    assert_clean_error(result, 2, "--t-end")
    result = run(
        "simulate-system", SYSTEM, "--t-end", "10 ms", "--out", out, "--plot", tmp_path / "m.npz"
    )
    assert_clean_error(result, 2, "--plot", ".png")
    result = run(
        "simulate-system", SYSTEM, "--input", tmp_path / "s.csv", "-p", "0,0,0", "--out", out
    )
    assert_clean_error(result, 2, "not both")
    assert not out.exists()


def test_hostile_system_files_are_design_errors(run, tmp_path):
    # Found by the fuzz suite: a deeply nested file raised RecursionError from the TOML
    # parser (an internal error at the command line); system files are now read as design
    # files are (size, encoding, syntax, depth).
    deep = tmp_path / "deep.toml"
    deep.write_text("a = " + "[" * 5000 + "]" * 5000 + "\n")
    with pytest.raises(softrod.DesignError, match="nested too deeply"):
        softrod.load_system(deep)
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\xff\xfe\x00name")
    with pytest.raises(softrod.DesignError, match="not UTF-8"):
        softrod.load_system(binary)
    result = run("solve-system", deep)
    assert_clean_error(result, 2, "nested too deeply")
