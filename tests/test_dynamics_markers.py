"""Motion-capture markers on the moving rod from the public API (docs/dynamics.md, "Markers
on the moving rod"): ``simulate(..., markers=)``, ``Simulation(markers=)`` and
``set_markers`` record them in ``Trajectory.marker_position``; they are the tip and the
shape's nodes where they sit there, survive the tables and files, work with a held tip and
with obstacles, and bad markers are refused by name before any work. (The continuous
extension between nodes, its third order and the exact derivatives are Rust tests in
crates/softrod-core/tests/suite/dynamics_markers.rs and dynamics_sensitivity.rs.)
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pandas as pd
import pytest
import softrod
from conftest import assert_clean_error
from softrod import PressureSchedule, Simulation, TipConstraint, Trajectory, load_design, simulate
from softrod.errors import InputError

ARM = "pam_arm_220mm"
L = 0.22
D = 5e-3  # a marker's offset, m
# 0.1 bar on PAM 0 from 10 ms on: the arm swings, so every sample is a different pose.
STEP = PressureSchedule.steps([0.0, 0.01], [[0, 0, 0], [1e4, 0, 0]])


@pytest.fixture(scope="module")
def swing():
    """A short swing with markers at the tip (bare, offset along d1 and d2), at a node and
    between nodes, and the shapes at every sample."""
    markers = [L, (L, [D, 0.0]), ("220 mm", ["0 mm", "5 mm"]), 0.11, ("100 mm", [D, 0, 0]), 0.1]
    return simulate(ARM, STEP, 0.06, dt=5e-3, shapes="saved", markers=markers)


def test_a_marker_at_the_tip_is_the_tip_bitwise(swing):
    tr = swing
    assert tr.marker_position.shape == (len(tr), 6, 3)
    assert np.ptp(tr.tip_position[:, 0]) > 1e-4  # it moves
    # Bitwise: the core reads a marker within 1e-9 of an interval of a node at that node's
    # own pose, and the node at s = L is the tip (Simulator::marker_positions).
    np.testing.assert_array_equal(tr.marker_position[:, 0], tr.tip_position)
    # r + R o with o = (d, 0, 0) or (0, d, 0): the zero terms add exactly, so the offset
    # markers are tip + d R[:, 0] and tip + d R[:, 1] bit for bit as well.
    r = tr.tip_rotation
    np.testing.assert_array_equal(tr.marker_position[:, 1], tr.tip_position + D * r[:, :, 0])
    np.testing.assert_array_equal(tr.marker_position[:, 2], tr.tip_position + D * r[:, :, 1])
    np.testing.assert_array_equal(tr.marker_s, [L, L, L, 0.11, 0.1, 0.1])
    np.testing.assert_array_equal(tr.marker_offset[:3], [[0, 0, 0], [D, 0, 0], [0, D, 0]])
    assert "6 markers" in repr(tr)


def test_the_animation_draws_the_markers_of_the_shape_shown(swing):
    # shapes="saved": every shape has its tip sample, so frame i's dots are that sample's
    # markers exactly (in mm, as the axes); a trajectory without markers draws no dots.
    fig, _canvas, draw = swing._animation_scene(
        trail=True, elev=20.0, azim=-60.0, dpi=30, figsize=(2.0, 2.0)
    )
    ax = fig.axes[0]
    dots = [line for line in ax.lines if line.get_color() == "C3"]
    assert len(dots) == 1
    for i in (0, len(swing.shape_time) - 1):
        draw(i)
        row = int(np.flatnonzero(swing.time == swing.shape_time[i])[0])
        x, y, z = dots[0].get_data_3d()
        np.testing.assert_array_equal(np.column_stack([x, y, z]), swing.marker_position[row] * 1e3)
    bare = dataclasses.replace(swing, marker_position=None, marker_s=None, marker_offset=None)
    fig, _canvas, _draw = bare._animation_scene(
        trail=True, elev=20.0, azim=-60.0, dpi=30, figsize=(2.0, 2.0)
    )
    assert not [line for line in fig.axes[0].lines if line.get_color() == "C3"]


def test_a_marker_at_a_node_is_the_shape_node_bitwise(swing):
    tr = swing
    j = int(np.flatnonzero(tr.shape_s == 0.11)[0])  # 0.11 m is node 8 of 16 intervals
    rows = np.searchsorted(tr.time, tr.shape_time)
    np.testing.assert_array_equal(tr.marker_position[rows, 3], tr.shape_position[:, j])
    # Between nodes (0.1 m lies inside [0.09625, 0.11]) a marker is the collocation's
    # continuous extension r(s) + R(s) o, R orthonormal: the offset marker is D from the
    # bare one at the same s to round-off, and the bare one lies near the chord between
    # the nodes (measured 1.8e-6 m off it: the chord's own error, curvature h^2 / 8).
    offset, bare = tr.marker_position[:, 4], tr.marker_position[:, 5]
    np.testing.assert_allclose(np.linalg.norm(offset - bare, axis=1), D, rtol=1e-12)
    theta = (0.1 - tr.shape_s[j - 1]) / (tr.shape_s[j] - tr.shape_s[j - 1])
    a, b = tr.shape_position[:, j - 1], tr.shape_position[:, j]
    chord = np.linalg.norm(bare[rows] - (a + theta * (b - a)), axis=1)
    assert chord.max() < 1e-5
    # Interpolated at the samples, marker_position_at gives the samples back.
    np.testing.assert_allclose(tr.marker_position_at(tr.time), tr.marker_position, atol=0.0)


def test_marker_error_against_measured_markers(swing):
    tr = swing
    t = np.array([0.0125, 0.03, 0.06])  # between samples and at the end
    measured = tr.marker_position_at(t) + [0.0, 0.003, 0.004]  # 5 mm off everywhere
    measured[1, 2] = np.nan  # marker 2 not seen at 30 ms
    err = tr.marker_error(t, measured)
    assert err.shape == (3, 6)
    assert np.isnan(err[1, 2]) and np.isfinite(np.delete(err.ravel(), 1 * 6 + 2)).all()
    # 3-4-5: the distance is 5 mm to round-off of the subtraction (1e-15 m on 0.2 m).
    np.testing.assert_allclose(np.delete(err.ravel(), 8), 5e-3, rtol=0, atol=1e-15)
    half = measured.copy()
    half[0, 1, 0] = np.nan  # a marker half seen
    with pytest.raises(InputError) as info:
        tr.marker_error(t, half)
    assert info.value.field == "measured_position[0, 1]"
    with pytest.raises(InputError, match="measured_time"):
        tr.marker_error([0.1], measured[:1])  # after the run's end
    with pytest.raises(InputError) as info:
        tr.marker_error(t, measured[:, :5])
    assert info.value.field == "measured_position"


def test_simulation_markers_state_copy_and_continuation():
    sim = Simulation(ARM, dt=5e-3, markers=["220 mm"])
    s, o = sim.markers
    np.testing.assert_array_equal(s, [L])
    np.testing.assert_array_equal(o, [[0.0, 0.0, 0.0]])
    first = sim.run(STEP, 0.02)
    np.testing.assert_array_equal(first.marker_position[:, 0], first.tip_position)
    state = sim.state()
    np.testing.assert_array_equal(state.marker_position, [state.tip_position])
    # A copy carries the markers; simulate(initial=sim) keeps them or replaces them.
    np.testing.assert_array_equal(sim.copy().markers[0], [L])
    kept = simulate(ARM, STEP, 0.01, dt=5e-3, initial=sim)
    np.testing.assert_array_equal(kept.marker_position[:, 0], kept.tip_position)
    other = simulate(ARM, STEP, 0.01, dt=5e-3, initial=sim, markers=[0.0])
    base = other.marker_position[:, 0]
    np.testing.assert_array_equal(base, np.zeros_like(base) + base[0])  # the base stays
    assert sim.markers[0][0] == L  # simulate worked on a copy
    # set_markers changes them from now on; None removes them.
    sim.set_markers([("110 mm", ["0 mm", "0 mm"]), L])
    second = sim.run(STEP, 0.01)
    assert second.marker_position.shape == (len(second), 2, 3)
    np.testing.assert_array_equal(second.marker_position[:, 1], second.tip_position)
    sim.set_markers(None)
    assert sim.markers is None and sim.state().marker_position is None
    third = sim.run(STEP, 0.01)
    assert third.marker_position is None and third.marker_s is None and third.n_markers == 0
    with pytest.raises(InputError) as info:
        third.marker_position_at([third.time[0]])
    assert info.value.field == "marker_position"


def test_markers_survive_the_tables_and_every_file_format(swing, tmp_path):
    tr = swing
    for name in ("t.npz", "t.parquet"):
        back = Trajectory.load(tr.save(tmp_path / name))
        for field in ("marker_position", "marker_s", "marker_offset", "tip_position"):
            np.testing.assert_array_equal(getattr(back, field), getattr(tr, field), err_msg=name)
        assert "markers" not in back.metadata  # the table's block is taken out again
    frame = tr.to_frame()
    cols = [c for c in frame.columns if c.startswith("marker")]
    assert cols == [f"marker{k}_{a}_mm" for k in range(6) for a in "xyz"]
    np.testing.assert_allclose(frame["marker1_y_mm"], tr.marker_position[:, 1, 1] * 1e3, rtol=1e-15)
    si = tr.to_frame(units="SI")
    np.testing.assert_array_equal(si["marker4_z_m"], tr.marker_position[:, 4, 2])
    # The table is a dataset with markers: the sites come back from its metadata block.
    ds = softrod.load_dataset(si)
    np.testing.assert_array_equal(ds.markers, tr.marker_position)
    np.testing.assert_array_equal(ds.marker_s, tr.marker_s)
    np.testing.assert_array_equal(ds.marker_offset, tr.marker_offset)


def test_files_of_format_2_still_load_and_newer_ones_are_refused(tmp_path):
    tr = simulate(ARM, STEP, 0.01, dt=5e-3)
    path = tr.save(tmp_path / "old.npz")
    with np.load(path) as data:
        arrays = dict(data)
    assert str(arrays["format"]) == "softrod.trajectory/3"
    for version, ok in (("2", True), ("4", False)):
        arrays["format"] = np.array(f"softrod.trajectory/{version}")
        with open(path, "wb") as fh:
            np.savez(fh, **arrays)
        if ok:
            np.testing.assert_array_equal(Trajectory.load(path).tip_position, tr.tip_position)
            assert Trajectory.load(path).marker_position is None
        else:
            with pytest.raises(InputError, match="newer softrod"):
                Trajectory.load(path)


def test_markers_with_a_held_tip():
    # A horizontal 0.1 m beam released straight under gravity with its tip pinned where the
    # straight rod's is: the tip marker stays on the pin while the middle sags.
    doc = {
        "design": {"name": "pinned_beam", "citation": "test"},
        "mounting": {"orientation": "horizontal", "gravity": "9.81 m/s^2"},
        "sections": [
            {
                "name": "beam",
                "length": "100 mm",
                "mass": "5 g",
                "outer_radius": "5 mm",
                "EA": "1e3 N",
                "GA": "5e2 N",
                "EI": "1e-4 N*m^2",
                "GJ": "1e-4 N*m^2",
                "steps": 8,
            }
        ],
        "dynamics": {"damping_time": "0.01 s"},
    }
    pin = TipConstraint.pinned([0.1, 0.0, 0.0])
    tr = simulate(
        load_design(doc), None, 0.05, dt=2e-3, initial="straight", tip_constraint=pin,
        markers=[0.1, 0.05, (0.1, [D, 0.0])],
    )  # fmt: skip
    np.testing.assert_array_equal(tr.marker_position[:, 0], tr.tip_position)
    np.testing.assert_allclose(tr.marker_position[:, 0], [[0.1, 0.0, 0.0]] * len(tr), atol=1e-12)
    # Straight at the start (its rotations composed in floating point: 1e-17 m), sagging
    # by the end.
    assert abs(tr.marker_position[0, 1, 2]) < 1e-15 and tr.marker_position[-1, 1, 2] < -1e-4
    # The pin holds the position, not the rotation: the offset marker turns with the tip.
    r = tr.tip_rotation
    np.testing.assert_array_equal(tr.marker_position[:, 2], tr.tip_position + D * r[:, :, 0])
    assert np.ptp(tr.marker_position[:, 2, 0]) > 1e-4


def test_markers_with_obstacles(tmp_path):
    # The contact suite's cantilever dropped onto a plane 10 mm below: the markers fall with
    # it, the tip marker is the tip, and the files keep both the contact and the markers.
    from test_dynamics_contact import cantilever, plane

    design = load_design(cantilever([plane(-10.0)]))
    sim = Simulation(design, initial="straight", dt=2e-3, markers=[0.2, 0.1])
    tr = sim.run(None, 0.3, save_every=10)
    assert tr.penetration[-1] > tr.penetration[0]
    np.testing.assert_array_equal(tr.marker_position[:, 0], tr.tip_position)
    assert tr.marker_position[-1, 1, 2] < -1e-3
    back = Trajectory.load(tr.save(tmp_path / "c.parquet"))
    np.testing.assert_array_equal(back.marker_position, tr.marker_position)
    np.testing.assert_array_equal(back.contact_force, tr.contact_force)


@pytest.mark.parametrize(
    ("markers", "field", "fragment"),
    [
        ([0.3], "markers[0].s", "[0, L] = [0, 0.22] m"),
        ([0.1, "221 mm"], "markers[1].s", "[0, L]"),
        ([-1e-3], "markers[0].s", "[0, L]"),
        ([math.nan], "markers[0].s", "finite"),
        (["5 kPa"], "markers[0].s", "length"),
        ([(0.1, [0.0, math.inf])], "markers[0].offset[1]", "finite"),
        ([(0.1, [0.0])], "markers[0].offset", "2 or 3 lengths"),
        # A bare number is metres: a 50 mm marker offset written as 50 is 50 m off the rod.
        ([("50 mm", [50, 0])], "markers[0].offset", "within the rod's length L = 0.22 m"),
        ([(0.1, [0.2, 0.2])], "markers[0].offset", "0.282843 m away"),
        ([(0.1, 0.0)], "markers[0].offset", "2 or 3 lengths"),
        ([(0.1, [0, 0], 0)], "markers[0]", "pair (s, offset)"),
        ([{"s": 0.1}], "markers[0]", "pair (s, offset)"),
        ([True], "markers[0]", "pair (s, offset)"),
        ([], "markers", "list of 1 to 256"),
        ("100 mm", "markers", "list of 1 to 256"),
        ([0.1] * 257, "markers", "list of 1 to 256"),
    ],
)
def test_bad_markers_are_refused_by_name_before_any_work(markers, field, fragment, monkeypatch):
    import importlib

    module = importlib.import_module("softrod.dynamics.simulate")

    def no_work(*args, **kwargs):
        raise AssertionError("the core was started before the markers were checked")

    monkeypatch.setattr(module._core, "Simulator", no_work)
    for make in (
        lambda: simulate(ARM, [0.0] * 3, 0.01, markers=markers),
        lambda: Simulation(ARM, markers=markers),
    ):
        with pytest.raises(InputError) as info:
            make()
        assert info.value.field == field, str(info.value)
        assert fragment in str(info.value)


def test_markers_are_a_setting_of_the_rod_model():
    with pytest.raises(InputError) as info:
        simulate("stiff_flop_pcc", [0.0] * 6, 0.01, model="pcc", markers=[0.01])
    assert info.value.field == "markers" and "rod model" in str(info.value)


def test_set_markers_checks_everything_before_changing_anything():
    sim = Simulation(ARM, dt=5e-3, markers=[L])
    with pytest.raises(InputError) as info:
        sim.set_markers([0.1, 0.5])
    assert info.value.field == "markers[1].s"
    np.testing.assert_array_equal(sim.markers[0], [L])
    np.testing.assert_array_equal(sim.state().marker_position, [sim.state().tip_position])


# A trajectory of two samples without chambers, for the constructor's checks.
_BASE = {
    "time": [0.0, 1.0],
    "command": np.zeros((2, 0)),
    "pressure": np.zeros((2, 0)),
    "tip_position": np.zeros((2, 3)),
    "tip_rotation": np.tile(np.eye(3), (2, 1, 1)),
    "tip_velocity": np.zeros((2, 3)),
}


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"marker_s": [0.1], "marker_offset": [[0, 0, 0]]}, "marker_position"),
        ({"marker_position": np.zeros((2, 1, 3)), "marker_offset": [[0, 0, 0]]}, "marker_s"),
        (
            {"marker_position": np.zeros((2, 2, 3)), "marker_s": [0.1], "marker_offset": [[0] * 3]},
            "marker_position",
        ),
        (
            {
                "marker_position": np.zeros((2, 1, 3)),
                "marker_s": [-0.1],
                "marker_offset": [[0] * 3],
            },
            "marker_s[0]",
        ),
        (
            {
                "marker_position": np.full((2, 1, 3), np.nan),
                "marker_s": [0.1],
                "marker_offset": [[0] * 3],
            },
            "marker_position",
        ),  # fmt: skip
    ],
)
def test_trajectory_checks_its_markers(kwargs, field):
    with pytest.raises(InputError) as info:
        Trajectory(**_BASE, **kwargs)
    assert info.value.field == field, str(info.value)


def test_a_metadata_key_markers_is_kept_or_refused(tmp_path):
    # Without markers a "markers" entry of the metadata is the user's, kept by the files;
    # with markers that is where the tables put the sites, so it is refused, not overwritten.
    mine = Trajectory(**_BASE, metadata={"markers": "glued by hand"})
    for name in ("m.npz", "m.parquet"):
        assert Trajectory.load(mine.save(tmp_path / name)).metadata["markers"] == "glued by hand"
    sites = {"marker_position": np.zeros((2, 1, 3)), "marker_s": [0.1], "marker_offset": [[0] * 3]}
    with pytest.raises(InputError) as info:
        Trajectory(**_BASE, **sites, metadata={"markers": "glued by hand"})
    assert info.value.field == "metadata.markers"


def test_cli_simulate_records_markers(run, tmp_path):
    inp = STEP.write(tmp_path / "p.csv")
    out = tmp_path / "t.parquet"
    res = run(
        "simulate", ARM, "--input", inp, "--t-end", "20 ms", "--dt", "5 ms", "--out", out,
        "--marker", "220 mm", "--marker", "110 mm,5 mm,0", "--marker", "100,0,5 mm",
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    tr = Trajectory.load(out)
    np.testing.assert_array_equal(tr.marker_s, [L, 0.11, 0.1])
    np.testing.assert_array_equal(tr.marker_offset, [[0, 0, 0], [D, 0, 0], [0, D, 0]])
    np.testing.assert_array_equal(tr.marker_position[:, 0], tr.tip_position)
    frame = pd.read_parquet(out)
    assert "marker2_z_m" in frame.columns
    out.unlink()
    for marker, field in (
        ("300 mm", "--marker[0].s"),
        ("100", "--marker[0].s"),
        ("100 mm,5 mm", "--marker[0]"),
        ("100 mm,x,0", "--marker[0].offset[0]"),
    ):
        res = run("simulate", ARM, "--input", inp, "--out", out, "--marker", marker)
        assert_clean_error(res, 2, field)
    res = run("simulate", "stiff_flop_pcc", "--pulses", "paper000", "--model", "pcc",
              "--out", out, "--marker", "10 mm")  # fmt: skip
    assert_clean_error(res, 2, "--marker")
    assert not out.exists()


def test_parquet_marker_sites_come_from_the_metadata_block(swing, tmp_path):
    # A file whose block lacks a marker's site is refused by the dataset reader's rule.
    import pyarrow.parquet as pq

    path = swing.save(tmp_path / "t.parquet")
    table = pq.read_table(path)
    kv = dict(table.schema.metadata)
    meta = json.loads(kv[b"softrod.metadata"])
    del meta["markers"]["marker4"]
    kv[b"softrod.metadata"] = json.dumps(meta).encode()
    pq.write_table(table.replace_schema_metadata(kv), path)
    with pytest.raises(InputError) as info:
        Trajectory.load(path)
    assert info.value.field == "metadata.markers.marker4"
