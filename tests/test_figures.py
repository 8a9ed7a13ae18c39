"""Every kind of figure softrod draws stays readable: no text runs into other text.

Each figure is rendered (Agg) and the window extents of its visible texts are compared pairwise:
tick labels (only those inside the view limits, which are the ones drawn), axis labels, offset
texts, titles, text artists and legends, of every axes (secondary axes and colour bars
included) and of the figure (suptitle, figure legends). Two boxes that overlap by more than a
pixel both ways fail, and so does a text that leaves the canvas (a clipped label). Tick marks
and data are not text and are not checked.
"""

from __future__ import annotations

import itertools

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import softrod  # noqa: E402
from softrod.plotting import plot_shape  # noqa: E402

TOLERANCE_PX = 1.0  # anti-aliased glyph edges may touch; a real collision is several pixels


def _all_axes(fig):
    out = []

    def walk(ax):
        out.append(ax)
        for child in getattr(ax, "child_axes", []):  # secondary axes
            walk(child)

    for ax in fig.axes:
        walk(ax)
    return out


def text_boxes(fig) -> list[tuple[str, object]]:
    """(name, display-space Bbox) of every visible, non-empty text of a drawn figure."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    boxes = []

    def add(name, artist):
        if artist is None or not artist.get_visible():
            return
        if hasattr(artist, "get_text") and not artist.get_text().strip():
            return
        box = artist.get_window_extent(renderer)
        if box.width > 0 and box.height > 0:
            boxes.append((name, box))

    for i, ax in enumerate(_all_axes(fig)):
        if not ax.get_visible():
            continue
        axes = [("x", ax.xaxis), ("y", ax.yaxis)]
        if hasattr(ax, "zaxis"):
            axes.append(("z", ax.zaxis))
        for a, axis in axes:
            # Only ticks inside the view interval are drawn (3-D axes place their labels while
            # drawing, so the positions are read as the draw left them).
            lo, hi = sorted(axis.get_view_interval())
            eps = 1e-9 * max(abs(lo), abs(hi), 1.0)
            for tick in axis.get_major_ticks():
                loc = tick.get_loc()
                if loc is None or not lo - eps <= loc <= hi + eps:
                    continue
                for label in (tick.label1, tick.label2):
                    add(f"axes {i} {a} tick {label.get_text()!r}", label)
            add(f"axes {i} {a} label", axis.label)
            add(f"axes {i} {a} offset text", axis.get_offset_text())
        for attr in ("title", "_left_title", "_right_title"):
            add(f"axes {i} title", getattr(ax, attr, None))
        for t in ax.texts:
            add(f"axes {i} text {t.get_text()!r}", t)
        add(f"axes {i} legend", ax.get_legend())
    add("suptitle", fig._suptitle)
    for legend in fig.legends:
        add("figure legend", legend)
    return boxes


def text_collisions(fig) -> list[str]:
    boxes = text_boxes(fig)
    bad = []
    for (n1, b1), (n2, b2) in itertools.combinations(boxes, 2):
        w = min(b1.x1, b2.x1) - max(b1.x0, b2.x0)
        h = min(b1.y1, b2.y1) - max(b1.y0, b2.y0)
        if w > TOLERANCE_PX and h > TOLERANCE_PX:
            bad.append(f"{n1} overlaps {n2}")
    width, height = fig.canvas.get_width_height()
    for name, b in boxes:
        if b.x0 < -TOLERANCE_PX or b.y0 < -TOLERANCE_PX or b.x1 > width + 1 or b.y1 > height + 1:
            bad.append(f"{name} is cut off at the edge of the figure")
    return bad


def assert_readable(fig):
    try:
        bad = text_collisions(fig)
        assert not bad, "\n".join(bad)
    finally:
        plt.close(fig)


# --------------------------------------------------------------------------- the checker


def test_checker_finds_colliding_and_cut_off_text():
    fig, ax = plt.subplots(figsize=(4, 3))
    ax.text(0.4, 0.5, "one text", transform=ax.transAxes)
    ax.text(0.45, 0.5, "another", transform=ax.transAxes)
    ax.text(1.3, 0.5, "beyond the right edge", transform=ax.transAxes)
    bad = text_collisions(fig)
    plt.close(fig)
    assert "axes 0 text 'one text' overlaps axes 0 text 'another'" in bad, bad
    assert "axes 0 text 'beyond the right edge' is cut off at the edge of the figure" in bad, bad
    assert len(bad) == 2, bad  # ticks and labels of a plain axes are fine


def test_checker_passes_a_plain_figure_and_sees_every_text():
    fig, ax = plt.subplots(figsize=(4, 3), layout="constrained")
    ax.plot([0, 1], [0, 1], label="line")
    ax.set(xlabel="x (mm)", ylabel="y (mm)", title="title")
    ax.legend()
    names = [n for n, _ in text_boxes(fig)]
    assert {"axes 0 x label", "axes 0 y label", "axes 0 title", "axes 0 legend"} <= set(names)
    assert any("tick" in n for n in names)
    assert_readable(fig)


# --------------------------------------------------------------------------- shapes


@pytest.fixture(scope="module")
def demo_solutions():
    d = softrod.load_design("spa_three_chamber_130mm")
    grid = ([0, 0, 0], [35e3, 0, 0], [70e3, 0, 0], [70e3, 70e3, 0], [70e3, 70e3, 70e3])
    return [softrod.solve_statics(d, p) for p in grid]


def test_shape_figure_of_the_demo(demo_solutions):
    # softrod demo's shapes.png and `softrod solve --plot` are this figure.
    assert_readable(plot_shape(demo_solutions, title="spa_three_chamber_130mm: static shapes"))


def test_shape_figure_with_tip_loads_frames_and_rigid_parts():
    m = softrod.load_design("paper004_1N_tip")  # a dead 1 N tip force, rigid connectors
    sols = [softrod.solve_statics(m, p) for p in ([0, 0, 0], [95e3, 0, 0], [95e3, 95e3, 0])]
    fig = plot_shape(sols, show_frames=True)
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "tip force 1 N (arrows to scale)" in labels
    assert_readable(fig)


def test_shape_figure_of_one_shape_and_into_given_axes():
    sol = softrod.solve_statics("spa_three_chamber_130mm", [30e3, 0, 0], tip_force=[0.3, 0, 0])
    assert_readable(plot_shape(sol))
    assert_readable(plot_shape(sol, top_view=False))
    # Into an Axes the caller made: the caller's layout decides the margins (a tall 3-D box
    # that fills the figure puts its x and y labels past the canvas edge; save_figure crops
    # to the drawn content and keeps them), so only collisions are checked.
    fig = plt.figure(figsize=(6, 6), layout="constrained")
    plot_shape(sol, ax=fig.add_subplot(projection="3d"))
    bad = [m for m in text_collisions(fig) if "cut off" not in m]
    plt.close(fig)
    assert not bad, bad


def test_shape_figure_of_a_horizontal_actuator():
    d = softrod.load_design("spa_three_chamber_134mm_horizontal")
    sols = [softrod.solve_statics(d, p) for p in ([0, 0, 0], [60e3, 0, 0], [0, 60e3, 60e3])]
    assert_readable(plot_shape(sols))


# --------------------------------------------------------------------------- trajectories


@pytest.fixture(scope="module")
def trajectory():
    schedule = softrod.PressureSchedule.square_pulses(
        3, [(0, 1.8e5, 0.6), (1, 1.8e5, 0.6)], rest=0.3, start=0.1
    )
    return softrod.simulate("pam_arm_220mm", schedule, 1.8, dt=1e-2, shapes=0.1)


def test_trajectory_tip_plot_with_a_reference(trajectory):
    ref = (trajectory.time, trajectory.tip_position + 2e-3)
    assert_readable(trajectory.plot_tip(reference=ref))


def _first_frame(trajectory):
    """The animation's figure with its first frame drawn (Trajectory.animate's defaults)."""
    fig, _canvas, draw = trajectory._animation_scene(
        trail=True, elev=20.0, azim=-60.0, dpi=80, figsize=(5.0, 5.0)
    )
    draw(0)
    return fig


def test_animation_first_frame(trajectory):
    fig = _first_frame(trajectory)
    assert [t.get_text() for t in fig.axes[0].texts] == ["t = 0.00 s"]
    assert_readable(fig)


def test_animation_first_frame_of_the_slender_pcc_arm():
    # The PCC GIF of the issue: a 110 mm arm bending by 100 mm, a tall narrow 3-D box.
    schedule = softrod.PressureSchedule.steps([0.0, 0.1], [np.zeros(6), [1e5, 0, 0, 0, 0, 1e5]])
    tr = softrod.simulate("stiff_flop_pcc", schedule, 0.6, dt=5e-3, model="pcc", shapes=0.1)
    assert_readable(_first_frame(tr))


def test_trajectory_tip_plot_of_the_pcc_model():
    schedule = softrod.PressureSchedule.steps([0.0, 0.1], [np.zeros(6), [1e5, 0, 0, 0, 0, 1e5]])
    tr = softrod.simulate("stiff_flop_pcc", schedule, 0.6, dt=5e-3, model="pcc")
    assert_readable(tr.plot_tip())


# --------------------------------------------------------------------------- calibration


@pytest.fixture(scope="module")
def report_inputs():
    ds = softrod.load_dataset(softrod.datasets.example_dataset_path("spa130_synthetic"))
    rng = np.random.default_rng(3)
    predicted = ds.tip_position + rng.normal(0.0, 0.4e-3, ds.tip_position.shape)
    factors = np.exp(rng.normal(0.0, 0.2, (len(ds), 3)))
    factors[::7, 2] = np.nan  # some factors not identified
    return {
        "measured": ds.tip_position,
        "predicted": predicted,
        "labels": np.where(ds.experiment == 3, "test", "train"),
        "pressures": ds.pressures,
        "factors": factors,
        "factor_names": ["sigma_ext", "sigma_bend_x", "sigma_bend_y"],
        "length": 0.13,
        "axis": [0.0, 0.0, -1.0],
        "base_position": [0.0, 0.0, 0.0],
    }


def test_calibration_report_figures(report_inputs):
    from softrod.calibration.report import _figures

    figures = _figures(**report_inputs)
    assert [stem for stem, _, _ in figures] == [
        "tip_positions",
        "tip_error_boxes",
        "tip_error_map",
        "factors",
        "error_vs_pressure",
    ]
    for _, _, fig in figures:
        assert_readable(fig)


def test_report_box_plots_with_many_long_set_names(report_inputs):
    from softrod.calibration.report import _figures

    names = np.array(["identified", "not identified", "experiment 3", "held out", "rest"])
    labels = names[np.arange(len(report_inputs["labels"])) % len(names)]
    inputs = {**report_inputs, "labels": labels, "factors": None, "pressures": None}
    for _, _, fig in _figures(**inputs):
        assert_readable(fig)


# --------------------------------------------------------------------------- comparisons


def test_compare_figure():
    from softrod.compare import plot_comparison, pressure_ramp

    df = softrod.compare_models(
        ["M0", "M3"], experiments="i-1,iii,a", pressures=pressure_ramp("0 bar", "0.6 bar", 6)
    )
    assert_readable(plot_comparison(df, title="M0 vs M3"))


def test_pcc_figures():
    from softrod.pcc import run_pcc
    from softrod.pcc.compare import (
        compare_pcc,
        compare_pcc_dynamics,
        plot_pcc_comparison,
        plot_pcc_dynamics_comparison,
        plot_pcc_step_response,
    )

    design = softrod.load_design("stiff_flop_pcc")
    df = compare_pcc(design, [5, 0, 1], 1.5e5, steps=3)
    assert_readable(plot_pcc_comparison(df, title="stiff_flop_pcc: PCC vs Cosserat rod"))
    pulse = np.zeros(6)
    pulse[[5, 0, 1]] = 1e5
    schedule = softrod.PressureSchedule.steps([0.0, 0.05, 0.3], [np.zeros(6), pulse, np.zeros(6)])
    dyn = compare_pcc_dynamics(design, schedule, 0.5, dt=1e-2)
    assert_readable(plot_pcc_dynamics_comparison(dyn, title="a pulse on chambers 5, 0, 1"))
    runs = {}
    for chambers, label in (([0, 2, 4], "chambers 0, 2, 4"), ([5, 0, 1], "chambers 5, 0, 1")):
        p = np.zeros((101, 6))
        p[10:, chambers] = 1e5
        runs[f"1 bar step on {label}"] = run_pcc(design, 5e-3, p, save_every=2)
    fig = plot_pcc_step_response(runs, rest_length=design.length, title="step responses")
    ylabels = {ax.get_ylabel() for ax in fig.axes}
    assert ylabels == {"elongation L - L0 (mm)", "bending angle theta (deg)"}  # one per quantity
    assert_readable(fig)


def test_system_calibration_figure():
    """SystemCalibrationResult.plot: front view and per-row errors, with an initial model
    and test rows marked."""
    import numpy as np
    from softrod.calibration.system import calibrate_system

    pcr = softrod.load_system("two_spa_platform")
    rng = np.random.default_rng(4)
    p = rng.uniform(5e3, 30e3, size=(12, 2, 3)) * (rng.random((12, 2, 3)) < 0.5)
    data = softrod.synthesize_system_dataset(
        pcr, p, noise_mm=0.1, seed=1, experiment=np.repeat([0, 1, 2], 4)
    )
    fit = calibrate_system(pcr, data, ["E"], split="experiment", test=2, progress=False)
    initial = data.tip_position + 1e-3
    assert_readable(fit.plot(initial=initial))
