"""Shape plots and atomic table/figure writers."""

import os

import matplotlib
import numpy as np
import pandas as pd
import pytest
import softrod
from softrod import InputError, SolverOptions, load_design, solve_statics
from softrod.io import write_table
from softrod.plotting import plot_shape, save_figure

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

pytestmark = pytest.mark.fast  # the whole module runs in seconds


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


def test_write_table_round_trip(tmp_path):
    df = pd.DataFrame({"p1_Pa": [0.0, 1e3], "x_mm": [1.5, -2.0], "converged": [True, False]})
    for name in ("t.csv", "t.parquet"):
        path = write_table(df, tmp_path / name)
        back = pd.read_csv(path) if name.endswith(".csv") else pd.read_parquet(path)
        pd.testing.assert_frame_equal(back, df)
    # Written like an ordinary file (not the owner-only mode of a temporary file).
    umask = os.umask(0)
    os.umask(umask)
    assert (tmp_path / "t.csv").stat().st_mode & 0o777 == 0o666 & ~umask


def test_write_table_unknown_suffix(tmp_path):
    path = tmp_path / "t.xlsx"
    with pytest.raises(InputError) as info:
        write_table(pd.DataFrame({"a": [1]}), path)
    assert str(path) in str(info.value)
    assert ".csv" in str(info.value) and ".parquet" in str(info.value)
    assert not path.exists()


def test_write_table_is_all_or_nothing(tmp_path):
    path = tmp_path / "t.parquet"
    write_table(pd.DataFrame({"a": [1.0]}), path)
    before = path.read_bytes()
    bad = pd.DataFrame({"a": [object()]})  # Parquet cannot store an arbitrary object
    with pytest.raises(Exception):  # noqa: B017 - pyarrow's error type is its own business
        write_table(bad, path)
    assert path.read_bytes() == before  # the old file is untouched
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.parquet"]  # no temp file left


def test_plot_shape_many_solutions_with_frames(tmp_path):
    d = load_design("modular_two_module")  # has rigid parts, chambered and passive spans
    sols = [solve_statics(d, p) for p in ([0, 0, 0], [60e3, 0, 0], [60e3, 60e3, 0])]
    failed = solve_statics(
        "spa_three_chamber_134mm_horizontal",
        [60e3, 0, 0],
        options=SolverOptions(max_iter=1, continuation=False),
        check=False,
    )
    fig = plot_shape([*sols, failed], title="test", show_frames=True)
    ax = fig.axes[0]
    assert ax.get_xlabel() == "x (mm)" and ax.get_zlabel() == "z (mm)"
    top = fig.axes[1]  # the top view beside the 3-D one
    assert top.get_xlabel() == "x (mm)" and top.get_ylabel() == "y (mm)"
    assert top.get_aspect() == 1.0  # equal scale in the top view too
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "p = (60, 60, 0) kPa" in labels
    assert "p = (60, 0, 0) kPa (not converged)" in labels
    assert "rigid part" in labels and "base" in labels
    # Equal scale: the box aspect is proportional to the axis limits.
    spans = np.array([np.ptp(ax.get_xlim()), np.ptp(ax.get_ylim()), np.ptp(ax.get_zlim())])
    aspect = np.array(ax.get_box_aspect())
    np.testing.assert_allclose(aspect / aspect.max(), spans / spans.max(), rtol=1e-9)
    path = save_figure(fig, tmp_path / "shapes.pdf")
    assert path.read_bytes()[:5] == b"%PDF-"


def test_plot_shape_draws_the_applied_tip_force_not_reactions_or_contact():
    """The arrow is the tip load the solve was given: a held tip's reaction (4.8 N here) and
    the table's push on the finger's rounded end (46 mN) are in the tip's total force but
    are not tip forces; a follower force is drawn turned with the tip."""
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    pin = softrod.TipConstraint.pinned(["5 mm", "0 mm", "-125 mm"])
    held = solve_statics("spa_three_chamber_130mm", [0, 0, 0], tip_constraint=pin)
    pressed = solve_statics("prebent_finger_on_table", [30e3])
    assert np.linalg.norm(held.tip_reaction_force) > 1.0
    assert pressed.contact.end_force[0][2] > 0.01
    for sol in (held, pressed):
        fig = plot_shape(sol)
        ax3d = fig.axes[0]
        assert not [c for c in ax3d.collections if isinstance(c, Line3DCollection)]
        assert not any("tip force" in t.get_text() for t in fig.legends[0].get_texts())
    follower = load_design("spa_three_chamber_130mm").replace(
        {"tip.frame": "body", "tip.force": ["0.5 N", "0 N", "0 N"]}
    )
    sol = solve_statics(follower, [30e3, 0, 0])
    fig = plot_shape(sol)
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "tip force 0.5 N (arrows to scale)" in labels
    top = fig.axes[1]
    start, end = np.asarray(top.texts[0].xyann), np.asarray(top.texts[0].xy)
    # Along the tip's d1 (its horizontal part, as the top view draws it).
    d1 = sol.tip_rotation[:2, 0]
    arrow = end - start
    assert abs(arrow @ d1) / (np.linalg.norm(arrow) * np.linalg.norm(d1)) > 1 - 1e-9


def test_plot_shape_draws_the_obstacles_near_the_rod():
    """The finger's table is in the 3-D view at its height (the view reaches down to it),
    a floor two metres below the 130 mm arm is not (it would shrink the arm to a dot), and
    a pin beside the arm is drawn as a surface."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    fig = plot_shape(solve_statics("prebent_finger_on_table", [30e3]))
    ax3d = fig.axes[0]
    planes = [c for c in ax3d.collections if type(c) is Poly3DCollection]
    assert planes, "the table is drawn"
    assert ax3d.get_zlim()[0] <= -82.0  # the view holds the table (z = -82 mm)
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "obstacle (3-D view; rods as centrelines)" in labels
    plt.close(fig)

    common = {"stiffness": "1e7 N/m^2", "tolerance": "0.2 mm"}
    floor = {"kind": "plane", "point": ["0 mm", "0 mm", "-2 m"], "normal": [0, 0, 1], **common}
    pin = {"kind": "cylinder", "point": ["0 mm", "0 mm", "-160 mm"], "axis": [1, 0, 0]}
    arm = load_design("spa_three_chamber_130mm")
    fig = plot_shape(solve_statics(arm.with_obstacles([floor]), [40e3, 0, 0]))
    assert fig.axes[0].get_zlim()[0] > -300.0  # the floor is far: not in the view
    assert not [c for c in fig.axes[0].collections if type(c) is Poly3DCollection]
    plt.close(fig)
    fig = plot_shape(
        solve_statics(arm.with_obstacles([{**pin, "radius": "5 mm", **common}]), [0, 0, 0])
    )
    assert fig.axes[0].get_zlim()[0] <= -165.0  # the pin's axis and radius are in the view
    assert [c for c in fig.axes[0].collections if type(c) is Poly3DCollection]
    plt.close(fig)
    # A metre-long capsule across the arm, 10 mm beside its surface: drawn, and the view
    # widened by its radius, not its length.
    rail = {"kind": "capsule", "start": ["-500 mm", "35 mm", "-90 mm"], "radius": "4 mm"}
    rail["end"] = ["500 mm", "35 mm", "-90 mm"]
    fig = plot_shape(solve_statics(arm.with_obstacles([{**rail, **common}]), [0, 0, 0]))
    assert [c for c in fig.axes[0].collections if type(c) is Poly3DCollection]
    assert np.ptp(fig.axes[0].get_xlim()) < 300.0  # mm: the arm's view, not the rail's 1 m
    plt.close(fig)


def test_plot_shape_draws_tip_forces_to_scale():
    d = load_design("spa_three_chamber_130mm")
    pushed = solve_statics(d, [30e3, 0, 0], tip_force=[0.3, 0, -0.4])  # 0.5 N
    free = solve_statics(d, [30e3, 0, 0])  # only the tip body's weight: no arrow
    fig = plot_shape([pushed, free])
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "tip force 0.5 N (arrows to scale)" in labels
    ax3d, top = fig.axes
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    quivers = [c for c in ax3d.collections if isinstance(c, Line3DCollection)]
    assert len(quivers) == 1  # one arrow: the pushed shape's
    assert len(top.texts) == 1  # the top view draws its horizontal part
    # The arrow starts at the tip and points along the applied force (not the tip weight).
    start = np.asarray(top.texts[0].xyann)
    end = np.asarray(top.texts[0].xy)
    np.testing.assert_allclose(start, 1e3 * pushed.tip_position[:2])
    direction = (end - start) / np.linalg.norm(end - start)
    np.testing.assert_allclose(direction, [1.0, 0.0], atol=1e-9)


def test_plot_shape_into_given_axes_and_errors(tmp_path):
    sol = solve_statics("spa_three_chamber_130mm", [30e3, 0, 0])
    fig = plt.figure()
    ax = fig.add_subplot(projection="3d")
    assert plot_shape(sol, ax=ax) is fig
    with pytest.raises(InputError):
        plot_shape(sol, ax=plt.figure().add_subplot())  # a 2-D Axes
    with pytest.raises(InputError):
        plot_shape([])
    with pytest.raises(InputError) as info:
        save_figure(fig, tmp_path / "shape.unknown")
    assert info.value.field == "path"
