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
from softrod.viewer.app import place_arrow

pytest.importorskip("viser", reason="needs the viewer extra (viser)")

SPA = "spa_three_chamber_130mm"


@pytest.fixture(scope="module")
def viewer():
    v = softrod.view(SPA, pressure_range=(0, 70e3), environment_map=False)
    yield v
    v.close()


def quaternion_matrix(q) -> np.ndarray:
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def skinned_vertices(mesh) -> np.ndarray:
    """A skinned tube's vertices as the browser draws them: each vertex moved from the bind
    pose by its one bone (weight 1): v = p + R R_bind^T (v_bind - p_bind)."""
    out = np.empty(mesh.vertices.shape)
    for v, (idx, wt) in enumerate(zip(mesh.skin_indices, mesh.skin_weights, strict=True)):
        i = int(idx[np.argmax(wt)])
        assert np.isclose(wt.max(), 1.0) and np.isclose(wt.sum(), 1.0)
        r_bind = quaternion_matrix(mesh.bone_wxyzs[i])
        r_now = quaternion_matrix(mesh.bones[i].wxyz)
        local = r_bind.T @ (mesh.vertices[v] - mesh.bone_positions[i])
        out[v] = mesh.bones[i].position + r_now @ local
    return out


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
    rots = []
    for _ in range(20):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        rots.append(q * np.sign(np.linalg.det(q)))
    # Half turns about each axis: 1 + trace = 0, where only Shepperd's other branches work.
    rots += [np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]), np.diag([-1.0, -1.0, 1.0])]
    stacked = geo.wxyz(np.array(rots))
    for q, w in zip(rots, stacked, strict=True):
        np.testing.assert_allclose(quaternion_matrix(geo.wxyz(q)), q, atol=1e-12)
        np.testing.assert_array_equal(geo.wxyz(q), w)  # one rotation or a stack: the same
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


def test_cross_section_marks_the_tendons_by_their_tension():
    sec = load_design("till_tendon_robot").spec["sections"][0]
    svg = geo.cross_section_svg(
        sec, np.zeros(0), 1.0, 20e-3, tensions=np.array([20.0, 0.0, 0.0, 10.0]), t_max=20.0
    )
    assert [f"t{k}</text>" in svg for k in range(4)] == [True] * 4
    assert svg.count('fill="#1e64ff"') == 1  # full tension: blue
    assert svg.count('fill="#ffffff"') == 2  # slack
    assert svg.count('fill="#8eb1ff"') == 1  # half: (255 - 225 / 2, 255 - 155 / 2) = (142, 177)


def test_viewer_solves_like_solve_statics(viewer):
    n = viewer.solves
    sol = viewer.set_inputs(pressures=[35e3, 10e3, 0], tip_force=[0.0, 0.1, 0.0])
    assert viewer.solves == n + 1  # one solve for all the sliders moved together
    ref = solve_statics(SPA, [35e3, 10e3, 0], tip_force=[0.0, 0.1, 0.0])
    np.testing.assert_allclose(sol.pressures, [35e3, 10e3, 0])
    # Warm-started from the previous shape: the same equilibrium to the solver tolerance.
    np.testing.assert_allclose(sol.position, ref.position, atol=1e-9)
    assert viewer.timings[-1].solve_s < 0.05
    # The drawn tube of the body is the tube of the new shape: its bind-pose vertices moved
    # by the bones as the browser skins them (linear blend skinning with one bone per vertex).
    a, b = geo.node_ranges(sol.section, len(viewer.looks))[1]
    want = geo.tube_vertices(
        sol.position[a : b + 1],
        sol.rotation[a : b + 1, :, 0],
        sol.rotation[a : b + 1, :, 1],
        viewer.looks[1].radius,
    )
    # float32 vertices and bind poses (as sent to the browser) at ~0.1 m: ~1e-8 m; the bone
    # poses are skipped by viser when within 1e-5 relative of the last (np.allclose):
    # 1e-5 * 0.13 m about a rotation with a 13 mm arm, well under 1e-6 m.
    np.testing.assert_allclose(skinned_vertices(viewer._tubes.meshes[1]), want, atol=2e-6)
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
        # The trajectory's stored shapes are drawn on its own grid: the tube's last ring
        # rides on the stored tip (float32 bind pose at ~0.2 m: ~1e-8 m).
        tube = [m for m in v._tubes.meshes if m is not None and m.visible][-1]
        end = skinned_vertices(tube)[-1]  # the end centre
        np.testing.assert_allclose(end, traj.shape_position[-1][-1], atol=1e-6)
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


def test_tendon_sliders_solve_like_solve_statics():
    """A tendon design gets one tension slider per tendon channel, 0 (slack) to the design's
    [operating_range] tension top (Till's robot: 20 N), and the re-solve takes them."""
    v = softrod.view("till_tendon_robot", environment_map=False)
    try:
        assert v.tension_max == 20.0 and len(v._t_sliders) == 4
        assert all(s.min == 0.0 and s.max == 20.0 for s in v._t_sliders)
        sol = v.set_inputs(tensions=[5.0, 0.0, 0.0, 0.0])
        ref = solve_statics("till_tendon_robot", [], tensions=[5.0, 0.0, 0.0, 0.0])
        np.testing.assert_array_equal(v.tensions, [5.0, 0.0, 0.0, 0.0])
        np.testing.assert_array_equal(sol.tensions, [5.0, 0.0, 0.0, 0.0])
        # Warm-started from the straight rod: the same equilibrium to the solver tolerance.
        np.testing.assert_allclose(sol.position, ref.position, atol=1e-9)
        assert sol.tip_position[0] > 0.1  # 5 N on tendon 0 bends the 0.5 m rod strongly
    finally:
        v.close()


def test_default_tension_range_bends_the_softest_tendon_section_half_a_turn():
    # The finger on the table has a tendon and no [operating_range] tension: T = pi EI / (d L)
    # rounded up to 1, 1.5, 2, 3, 5 or 7 times a power of ten.
    from softrod.viewer.app import _nice_ceiling, default_tension_max

    d = load_design("prebent_finger_on_table")
    sec, spec = d.sections()[0], d.spec["sections"][0]
    ei = min(sec["k_bt"][0][0], sec["k_bt"][1][1])
    t = np.pi * ei / (spec["tendons"][0]["distance"] * spec["length"])
    assert default_tension_max(d) == _nice_ceiling(t)
    assert t <= default_tension_max(d) < 1.5 * t


def test_obstacles_are_drawn_and_the_contact_force_is_shown():
    """The finger pressed on its table: the table is drawn with its surface at the plane,
    the contact force arrow starts on the table and is the solution's total contact force
    at the loads' common scale, and the panel gives it in mN."""
    v = softrod.view("prebent_finger_on_table", environment_map=False)
    try:
        sol = v.set_inputs(pressures=[30e3])
        total = sol.contact.total_force[0]
        assert total[2] > 0.01  # the table pushes the finger up
        arrow = v._contact_arrows[0]
        assert arrow.visible
        # The arrow is drawn by its two bones: at its start and its end (docs/viewer.md).
        start, end = (np.asarray(b.position) for b in arrow.bones)
        np.testing.assert_allclose(end - start, total * v._force_scale, rtol=0, atol=1e-15)
        assert start[2] == pytest.approx(-0.082, abs=1e-7)  # on the table's surface
        assert f"contact with plane 0: {np.linalg.norm(total) * 1e3:.1f} mN" in v._status.content
        assert "deepest penetration" in v._status.content
    finally:
        v.close()


def test_obstacle_solids_sit_where_the_obstacles_are():
    centre, size = np.array([0.0, 0.0, -0.05]), 0.1
    ((kind, box),) = geo.obstacle_solids(
        {"kind": "plane", "point": [0, 0, -0.08], "normal": [0, 0, 2.0]}, centre, size
    )
    assert kind == "box"
    top = box["position"] + 0.5 * box["dimensions"][2] * np.array([0, 0, 1.0])
    np.testing.assert_allclose(top, [0, 0, -0.08], atol=1e-15)  # surface at the plane
    tilted = {"kind": "plane", "point": [0, 0, 0], "normal": [1.0, 0, 1.0]}
    ((_, slab),) = geo.obstacle_solids(tilted, centre, size)
    rot = np.array(slab["wxyz"])
    # The slab's local z (the quaternion's third column) is the unit normal.
    w, x, y, z = rot
    zcol = [2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)]
    np.testing.assert_allclose(zcol, np.array([1, 0, 1]) / np.sqrt(2), atol=1e-12)
    ((kind, ball),) = geo.obstacle_solids(
        {"kind": "sphere", "center": [0.01, 0, -0.1], "radius": 0.004}, centre, size
    )
    assert kind == "sphere" and ball["radius"] == 0.004
    cyl = {"kind": "cylinder", "point": [0, 0.02, 0], "axis": [1, 0, 0], "radius": 0.003}
    ((kind, c),) = geo.obstacle_solids(cyl, centre, size)
    np.testing.assert_allclose(c["position"], [0, 0.02, 0])  # the centre's foot on the axis
    assert kind == "cylinder" and c["height"] == pytest.approx(3 * size)
    cap = {"kind": "capsule", "start": [0, 0, 0], "end": [0, 0.03, 0.04], "radius": 0.002}
    parts = geo.obstacle_solids(cap, centre, size)
    assert [k for k, _ in parts] == ["cylinder", "sphere", "sphere"]
    assert parts[0][1]["height"] == pytest.approx(0.05)
    np.testing.assert_allclose(parts[0][1]["position"], [0, 0.015, 0.02])


def test_bad_viewer_inputs_are_rejected():
    with pytest.raises(softrod.InputError, match="pressure_range"):
        softrod.view(SPA, pressure_range=(10e3, 0))
    with pytest.raises(softrod.InputError, match="force_max"):
        softrod.view(SPA, force_max=-1)
    with pytest.raises(softrod.InputError, match="pressures"):
        softrod.view(SPA, pressures=[1.0, 2.0])
    for bad in ([-1.0, 0, 0, 0], [1.0], [float("nan")] * 4):
        with pytest.raises(softrod.InputError, match="tensions"):
            softrod.view("till_tendon_robot", tensions=bad)
    with pytest.raises(softrod.InputError, match="tension_max"):
        softrod.view("till_tendon_robot", tension_max=0)


def test_view_command_help_and_errors(run):
    res = run("view", "--help")
    assert res.exit_code == 0 and "Ctrl-C" in res.output
    res = run("view", SPA, "--pressure-range", "70kPa:0")
    assert res.exit_code == 2 and "--pressure-range" in res.output
    res = run("view", SPA, "--tension", "2N")
    assert res.exit_code == 2 and "--tension" in res.output and "0 tendon channels" in res.output
    res = run("view", "till_tendon_robot", "--max-tension", "-1N")
    assert res.exit_code == 2 and "--max-tension" in res.output


def test_cli_help_does_not_import_viser_or_distributed():
    # (pint itself imports dask's core when dask is installed; distributed is ours to keep out.)
    code = (
        "import sys; from softrod.cli import main\n"
        "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
        "print(sorted(m for m in ('viser', 'distributed', 'playwright') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "[]"


def test_arrows_are_drawn_by_posing_two_bones():
    """An arrow of any length and direction: its skinned mesh's foot on bone 0 at the start,
    its shaft top and head on bone 1 at the end, the head of fixed size, all along the
    vector."""
    size = dict(shaft_radius=0.001, head_radius=0.003, head_length=0.006)
    vertices, faces, weights = geo.arrow_mesh(**size)

    class Mesh:  # what the browser draws: the bind vertices moved by their bones
        def __init__(self):
            self.vertices = vertices
            self.skin_indices = np.stack([np.argmax(weights, 1)] + [np.zeros(len(weights))] * 3, 1)
            self.skin_weights = np.pad(weights.max(1, keepdims=True), ((0, 0), (0, 3)))
            self.bone_wxyzs = np.array([[1.0, 0, 0, 0], [1.0, 0, 0, 0]])
            self.bone_positions = np.array([[0.0, 0, 0], [0, 0, geo.ARROW_BIND_LENGTH]])
            self.bones = [type("Bone", (), {})() for _ in range(2)]

    mesh = Mesh()
    for at, vec in [([0.1, 0.2, 0.3], [0.0, 0.0, -0.05]), ([0, 0, 0], [0.02, -0.03, 0.01])]:
        place_arrow(mesh, at, vec)
        drawn = skinned_vertices(mesh)
        at, vec = np.asarray(at), np.asarray(vec)
        unit = vec / np.linalg.norm(vec)
        along = (drawn - at) @ unit
        across = np.linalg.norm((drawn - at) - np.outer(along, unit), axis=1)
        # float32 bind vertices: ~1e-7 relative of 1 m bind length
        assert along.min() == pytest.approx(0.0, abs=1e-7)  # the foot at the start
        assert along.max() == pytest.approx(np.linalg.norm(vec), abs=1e-7)  # the apex at the end
        assert across.max() == pytest.approx(size["head_radius"], abs=1e-7)
        head = drawn[2 * geo.ARROW_RING : 3 * geo.ARROW_RING]  # the head's base ring
        np.testing.assert_allclose(head @ unit - at @ unit, np.linalg.norm(vec) - 0.006, atol=1e-7)
    assert len(faces) == 5 * geo.ARROW_RING


def test_a_tapered_section_is_drawn_with_its_radius_along_s():
    """A section tapering from 10 to 5 mm (outer_radius_end) is drawn with the radius of
    every node's arc length, linear between the two, and the panel gives both."""
    design = {
        "design": {"name": "tapered", "citation": "viewer check"},
        "mounting": {"orientation": "upright", "gravity": "0 m/s^2"},
        "sections": [
            {
                "name": "cone",
                "length": "100 mm",
                "outer_radius": "10 mm",
                "outer_radius_end": "5 mm",
                "material": "dragon_skin_20",
            }
        ],
    }
    (look,) = geo.section_looks(load_design(design))
    np.testing.assert_allclose(look.radius_at([0.0, 0.05, 0.1]), [0.010, 0.0075, 0.005])
    v = softrod.view(design, environment_map=False)
    try:
        sol = v.solution
        verts = skinned_vertices(v._tubes.meshes[0])
        ring = geo.RING
        for i in (0, len(sol.s) - 1):
            r = np.linalg.norm(verts[i * ring : (i + 1) * ring] - sol.position[i], axis=1)
            # float32 vertices at ~0.1 m: radii good to ~1e-8 m.
            np.testing.assert_allclose(r, 0.010 - 0.05 * sol.s[i], atol=1e-7)
        assert "10.0 to 5.0 mm" in v._sections_note.content
    finally:
        v.close()


def test_a_frictional_design_continues_its_load_path_from_the_shape_shown():
    """With friction every slider move loads the rod from the shape on screen (history=):
    pressing to 30 kPa via 50 kPa leaves the tip where solve_statics' same path leaves it,
    not where a direct load to 30 kPa does (path dependence, docs/contact.md)."""
    rough = load_design("prebent_finger_on_table").replace({"obstacles[0].friction": 0.5})
    v = softrod.view(rough, environment_map=False)
    try:
        v.set_inputs(pressures=[50e3])
        sol = v.set_inputs(pressures=[30e3])
        assert sol.converged and v.error is None
        # The viewer's path: its first shape (0 kPa: the weight loaded onto the table),
        # then 50 kPa, then 30 kPa, each from the last.
        path = None
        for p in (0.0, 50e3, 30e3):
            path = solve_statics(rough, [p], tensions=[0.0], tip_force=[0, 0, 0], history=path)
        via = path
        direct = solve_statics(rough, [30e3])
        # The same path in the same increments: the same numbers.
        np.testing.assert_array_equal(sol.tip_position, via.tip_position)
        assert np.abs(sol.tip_position - direct.tip_position).max() > 1e-5
        assert "friction:" in v._status.content
    finally:
        v.close()


def test_bad_values_are_refused_before_the_server_starts(monkeypatch):
    """Every start value is checked as solve_statics checks it before viser starts: an
    options that is not SolverOptions, a bool as a force, text and NaN pressures are named
    (no server is started for them; options=5 used to fail at the first solve)."""
    import viser

    def no_server(*args, **kwargs):
        raise AssertionError("a server was started for a refused value")

    monkeypatch.setattr(viser, "ViserServer", no_server)
    for kwargs, field in (
        ({"options": 5}, "options"),
        ({"force_max": True}, "force_max"),
        ({"pressures": ["x", 0, 0]}, "pressures[0]"),
        ({"pressures": [float("nan"), 0, 0]}, "pressures[0]"),
        ({"pressure_range": ("0 kPa", "70 m")}, "pressure_range[1]"),
    ):
        with pytest.raises(softrod.InputError) as err:
            softrod.view(SPA, environment_map=False, **kwargs)
        assert err.value.field == field, kwargs


def test_a_failing_first_solve_stops_the_server(monkeypatch):
    """An error out of the first solve (after the server started) stops the server before
    it goes up: no server is left running behind the error."""
    from softrod.viewer import app

    closed = []
    real_close = app.Viewer.close

    def close(self):
        closed.append(self)
        real_close(self)

    def broken_solve(*args, **kwargs):
        raise RuntimeError("the solver broke")

    monkeypatch.setattr(app.Viewer, "close", close)
    monkeypatch.setattr(app, "solve_statics", broken_solve)
    with pytest.raises(RuntimeError, match="the solver broke"):
        softrod.view(SPA, environment_map=False)
    assert len(closed) == 1 and closed[0]._closed


def test_inputs_beyond_the_operating_range_say_so():
    """Pressures on the sliders but beyond the finger's operating range (0-50 kPa) are
    refused by the solve: the panel gives that reason (it said "no convergence (0
    iterations, residual nan)"), and the next move inside the range solves."""
    v = softrod.view(
        "prebent_finger_on_table",
        pressures=[100e3],
        pressure_range=(0.0, 200e3),
        environment_map=False,
    )
    try:
        assert v.solution is None
        assert v.error.startswith("refused at these inputs") and "operating" in v.error
        assert "operating" in v._status.content and "NO" in v._status.content
        sol = v.set_inputs(pressures=[30e3])
        assert sol is not None and sol.converged and v.error is None
    finally:
        v.close()


def test_values_beyond_the_sliders_are_refused_not_clipped():
    """A slider cannot hold a value beyond its ends: viser clipped it silently (1 GPa
    became the 50 kPa of the slider's top); now the entry and the range to widen are named,
    at the start and from set_inputs, and nothing moves."""
    with pytest.raises(softrod.InputError, match="pressure_range") as err:
        softrod.view("prebent_finger_on_table", pressures=[1e9], environment_map=False)
    assert err.value.field == "pressures[0]"
    # The design's own tip force (0.5 N down) beyond sliders of +-1 mN.
    loaded = load_design(SPA).replace({"tip.force": ["0 N", "0 N", "-0.5 N"]})
    with pytest.raises(softrod.InputError, match=r"\[tip\] force") as err:
        softrod.view(loaded, force_max="1 mN", environment_map=False)
    assert err.value.field == "force_max"
    v = softrod.view("till_tendon_robot", environment_map=False)
    try:
        before = v.solves
        for kwargs, field in (
            ({"tensions": [25.0, 0, 0, 0]}, "tensions[0]"),  # the sliders end at 20 N
            ({"tip_force": [0, 0, -2 * v.force_max]}, "tip_force[2]"),
        ):
            with pytest.raises(softrod.InputError) as err:
                v.set_inputs(**kwargs)
            assert err.value.field == field
        assert v.solves == before
        np.testing.assert_array_equal(v.tensions, 0.0)
    finally:
        v.close()
