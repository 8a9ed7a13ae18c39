"""The viewer without a browser: the geometry it draws (tube at the true outer radius, section
kinds and colours, frames, the chamber cross-section), the server's re-solves against
solve_statics, trajectory playback, measured vs predicted tips, the CLI, and that `softrod
--help` does not import viser or dask."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import softrod
from softrod import load_design, solve_statics
from softrod.viewer import geometry as geo

pytest.importorskip("viser", reason="needs the viewer extra (viser)")

SPA = "spa_three_chamber_130mm"


@pytest.fixture(scope="module")
def viewer():
    v = softrod.view(SPA, pressure_range=(0, 70e3), environment_map=False)
    yield v
    v.close()


def test_tube_vertices_lie_at_the_outer_radius_around_the_centreline():
    sol = solve_statics(SPA, [40e3, 0, 0])
    r = 21.1e-3  # the design's outer radius
    verts = geo.tube_vertices(sol.position, sol.rotation[:, :, 0], sol.rotation[:, :, 1], r)
    n, ring = len(sol.s), geo.RING
    rings = verts[: n * ring].reshape(n, ring, 3) - sol.position[:, None, :].astype(np.float32)
    # float32 vertices: distances to the node exact to ~1e-7 relative.
    np.testing.assert_allclose(np.linalg.norm(rings, axis=2), r, rtol=1e-5)
    # Every ring lies in its node's cross-section plane (normal d3).
    d3 = sol.rotation[:, :, 2]
    assert np.abs(np.einsum("nkj,nj->nk", rings, d3)).max() < 1e-7
    faces = geo.tube_faces(n)
    assert faces.shape == (2 * (n - 1) * ring + 2 * ring, 3)
    assert faces.max() == len(verts) - 1


def test_sections_get_their_kind_colour_and_radius():
    looks = geo.section_looks(load_design(SPA))
    assert [lk.kind for lk in looks] == ["cap", "chambered", "cap"]
    assert all(lk.radius == pytest.approx(21.1e-3) and lk.radius_from_design for lk in looks)
    assert looks[1].colour == geo.COLOURS["chambered"]
    assert looks[-1].s1 == pytest.approx(0.130)
    # The modular design gives no outer radius: chambered modules are drawn around their
    # chambers, rigid caps like their nearest neighbour, and the panel says so.
    mod = geo.section_looks(load_design("modular_two_module"))
    assert [lk.kind for lk in mod] == ["rigid", "chambered", "rigid", "chambered", "rigid"]
    assert not any(lk.radius_from_design for lk in mod)
    reach = 11.547e-3 + np.sqrt(114.6e-6 / np.pi)
    assert mod[1].radius == pytest.approx(geo.ENVELOPE_MARGIN * reach)
    assert mod[0].radius == mod[1].radius


def test_node_ranges_join_neighbouring_sections():
    section = np.array([0, 0, 0, 1, 1, 1, 2, 2])
    assert geo.node_ranges(section, 3) == [(0, 3), (3, 6), (6, 7)]
    assert geo.node_ranges(np.array([0, 0, 2]), 3)[1] is None


def test_quaternion_and_transported_frames():
    rng = np.random.default_rng(0)
    for _ in range(20):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        q *= np.sign(np.linalg.det(q))
        w, x, y, z = geo.wxyz(q)
        back = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
            ]
        )
        np.testing.assert_allclose(back, q, atol=1e-12)
    # Frames rebuilt from a centreline alone: d3 is the tangent, and they are rotations.
    sol = solve_statics(SPA, [60e3, 20e3, 0])
    frames = geo.transport_frames(sol.position, sol.rotation[0])
    np.testing.assert_allclose(
        frames @ np.transpose(frames, (0, 2, 1)), np.eye(3)[None].repeat(len(frames), 0), atol=1e-12
    )
    # Central differences of a 16-step RK4 centreline: tangents within ~1e-2 rad of d3.
    assert np.abs(frames[:, :, 2] - sol.rotation[:, :, 2]).max() < 2e-2


def test_cross_section_marks_the_pressurised_chambers():
    sec = load_design(SPA).spec["sections"][1]
    svg = geo.cross_section_svg(sec, np.array([70e3, 0.0, 0.0]), 70e3, 21.1e-3)
    assert svg.startswith("<svg") and svg.endswith("</svg>")
    assert svg.count('fill="#ff963c"') == 1  # full pressure: orange
    assert svg.count('fill="#ffffff"') == 2  # the two others at 0


def test_viewer_solves_like_solve_statics(viewer):
    n = viewer.solves
    sol = viewer.set_inputs(pressures=[35e3, 10e3, 0], tip_force=[0.0, 0.1, 0.0])
    assert viewer.solves == n + 1  # one solve for all the sliders moved together
    ref = solve_statics(SPA, [35e3, 10e3, 0], tip_force=[0.0, 0.1, 0.0])
    np.testing.assert_allclose(sol.pressures, [35e3, 10e3, 0])
    # Warm-started from the previous shape: the same equilibrium to the solver tolerance.
    np.testing.assert_allclose(sol.position, ref.position, atol=1e-9)
    assert viewer.timings[-1].solve_s < 0.05
    # The drawn tube of the body follows the new shape.
    body = viewer._tubes[1].vertices[: geo.RING].mean(axis=0)
    a = int(np.flatnonzero(sol.section == 1)[0])
    np.testing.assert_allclose(body, sol.position[a], atol=1e-6)
    viewer.set_inputs(pressures=[0, 0, 0], tip_force=[0, 0, 0])


def test_unconverged_inputs_keep_the_last_shape_and_say_so(viewer):
    good = viewer.set_inputs(pressures=[20e3, 0, 0])
    opts = softrod.SolverOptions(max_iter=1, continuation=False)
    viewer._options = opts
    try:
        viewer.set_inputs(pressures=[70e3, 0, 70e3])
    finally:
        viewer._options = None
    assert viewer.solution is good
    assert "NO" in viewer._status.content and "no convergence" in viewer.error


def test_trajectory_playback_and_calibration_view(tmp_path):
    design = load_design("pam_arm_220mm")  # paper 000's arm, the dynamics example
    sched = softrod.PressureSchedule.steps([0.0, 0.02], [[0, 0, 0], [150e3, 0, 0]])
    traj = softrod.simulate(design, sched, 0.1, dt=5e-3, shapes="saved")
    p = np.array([[100e3, 0, 0], [200e3, 0, 0], [0, 200e3, 0]])
    data = softrod.synthesize_dataset(design, p, noise_mm=0.5, seed=1)
    v = softrod.view(design, trajectory=traj, dataset=data, environment_map=False)
    try:
        v._show_trajectory(len(traj) - 1)
        tip = v._tip_frame.position
        np.testing.assert_allclose(tip, traj.tip_position[-1], atol=1e-6)
        assert "t = " in v._t_note.content
        measured, predicted, pressures = v.calibration
        np.testing.assert_array_equal(measured, data.tip_position)
        np.testing.assert_allclose(predicted, softrod.solve_statics_batch(design, p).tip_position)
        v._show_sample(2)
        np.testing.assert_allclose(v.pressures, p[2])
    finally:
        v.close()


def test_bad_viewer_inputs_are_rejected():
    with pytest.raises(softrod.InputError, match="pressure_range"):
        softrod.view(SPA, pressure_range=(10e3, 0))
    with pytest.raises(softrod.InputError, match="force_max"):
        softrod.view(SPA, force_max=-1)
    with pytest.raises(softrod.InputError, match="pressures"):
        softrod.view(SPA, pressures=[1.0, 2.0])


def test_view_command_help_and_errors(run):
    res = run("view", "--help")
    assert res.exit_code == 0 and "Ctrl-C" in res.output
    res = run("view", SPA, "--pressure-range", "70kPa:0")
    assert res.exit_code == 2 and "--pressure-range" in res.output


def test_cli_help_does_not_import_viser_or_distributed():
    # (pint itself imports dask's core when dask is installed; distributed is ours to keep out.)
    code = (
        "import sys; from softrod.cli import main\n"
        "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
        "print(sorted(m for m in ('viser', 'distributed', 'playwright') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "[]"
