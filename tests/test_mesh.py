"""Triangle-mesh obstacles (docs/contact.md, "Triangle meshes"): STL (ASCII, binary) and OBJ
files and inline vertices with their units, the pose, every refusal naming its field, the
save/load round trip, the same answers as the plane obstacle in every static solve (free,
frictional, held tip), and hostile meshes that must always give a DesignError."""

import math
import struct

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from softrod import DesignError, TipConstraint, load_design, solve_statics
from softrod.mesh_io import MAX_MESH_TRIANGLES, read_mesh, write_stl
from test_contact import FINGER, balance_error, beam_over, plane

pytestmark = pytest.mark.fast


def cube(size=1.0):
    """The cube [0, size]^3 as 12 outward triangles."""
    v = np.array([[i & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)], float) * size
    quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    f = [t for q in quads for t in ([q[0], q[1], q[2]], [q[0], q[2], q[3]])]
    return v, np.array(f)


def patch(z, half=2000.0):
    """The square [-half, half]^2 at height z as two triangles, normal +z."""
    v = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]])
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def write_obj(path, v, f, *, quads=False):
    lines = ["# softrod test", "o cube"] + [f"v {x!r} {y!r} {z!r}" for x, y, z in v.tolist()]
    lines.append("vn 0 0 1")
    if quads:  # pairs of triangles written back as quads: the reader fans them again
        for a, b in zip(f[::2].tolist(), f[1::2].tolist(), strict=True):
            lines.append(f"f {a[0] + 1}//1 {a[1] + 1}//1 {a[2] + 1}//1 {b[2] + 1}//1")
    else:
        n = len(v)
        lines += [f"f {a - n} {b - n} {c - n}" for a, b, c in f.tolist()]  # negative indices
    path.write_text("\n".join(lines) + "\n")
    return path


def mesh_ob(**keys):
    return {"kind": "mesh", "stiffness": "1e6 N/m^2", "tolerance": "0.05 mm", **keys}


def test_stl_ascii_binary_and_obj_read_the_same_cube(tmp_path):
    v, f = cube(20.0)
    meshes = [
        read_mesh(write_stl(tmp_path / "a.stl", v, f, binary=False)),
        read_mesh(write_stl(tmp_path / "b.stl", v, f, binary=True)),
        read_mesh(write_obj(tmp_path / "c.obj", v, f)),
        read_mesh(write_obj(tmp_path / "d.obj", v, f, quads=True)),
    ]
    for vertices, faces in meshes:
        # STL repeats the corners per triangle: welded back to the cube's 8 vertices.
        assert vertices.shape == (8, 3) and faces.shape == (12, 3)
        tri = vertices[faces]
        normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        # Outward winding kept: each normal points away from the cube's centre.
        assert np.all(np.einsum("ij,ij->i", normals, tri.mean(axis=1) - 10.0) > 0)
        assert sorted(map(tuple, np.round(tri.reshape(-1, 3), 9))) == sorted(
            map(tuple, v[f].reshape(-1, 3))
        )


def test_units_and_pose_place_the_mesh_in_metres(tmp_path):
    v, f = cube(20.0)
    write_stl(tmp_path / "cube.stl", v, f)
    base = beam_over(plane(-1.0))
    rot = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]  # 90 degrees about z
    ob = mesh_ob(file="cube.stl", units="mm", position=["0.1 m", "0 m", "-200 mm"])
    ob["rotation"] = rot
    doc = base | {"obstacles": [ob]}
    path = tmp_path / "d.toml"
    import tomli_w

    path.write_text(tomli_w.dumps(doc))
    design = load_design(path)
    got = np.array(design.spec["obstacles"][0]["vertices"])
    want = (np.array(read_mesh(tmp_path / "cube.stl")[0]) * 1e-3) @ np.array(rot).T
    want += [0.1, 0.0, -0.2]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)
    # Inline vertices: lengths with units, or plain numbers in the obstacle's units.
    inline = mesh_ob(vertices=[[f"{x} mm" for x in p] for p in v.tolist()], faces=f.tolist())
    a = load_design(base | {"obstacles": [inline]}).spec["obstacles"][0]["vertices"]
    b = mesh_ob(vertices=(v / 10).tolist(), faces=f.tolist(), units="cm")
    b = load_design(base | {"obstacles": [b]}).spec["obstacles"][0]["vertices"]
    np.testing.assert_allclose(a, v * 1e-3, rtol=1e-15)
    np.testing.assert_allclose(b, v * 1e-3, rtol=1e-15)


def test_a_mesh_plane_solves_as_the_plane_in_every_static_solve():
    # The finger's table (a plane 82 mm below the base) as two triangles: the same
    # distance and normal, so the same answers to round-off, free, held and frictional.
    finger = load_design(FINGER)
    v, f = patch(-82.0)
    table = mesh_ob(vertices=v.tolist(), faces=f.tolist(), units="mm")
    table.update(stiffness="1e7 N/m^2", tolerance="0.2 mm")
    mesh = finger.with_obstacles([table])
    free_p, free_m = solve_statics(finger, [50e3]), solve_statics(mesh, [50e3])
    np.testing.assert_allclose(free_m.position, free_p.position, rtol=0, atol=1e-13)
    np.testing.assert_allclose(free_m.contact.total, free_p.contact.total, rtol=0, atol=1e-12)
    assert balance_error(free_m) < 1e-9 and 0 < free_m.contact.max_penetration <= 0.2e-3
    pin = TipConstraint.pinned(free_p.tip_position)
    held_p = solve_statics(finger, [50e3], tip_constraint=pin)
    held_m = solve_statics(mesh, [50e3], tip_constraint=pin)
    np.testing.assert_allclose(held_m.position, held_p.position, rtol=0, atol=1e-13)
    rough_p = finger.replace({"obstacles[0].friction": 0.5})
    rough_m = mesh.replace({"obstacles[0].friction": 0.5})
    a, b = solve_statics(rough_p, [50e3]), solve_statics(rough_m, [50e3])
    np.testing.assert_allclose(b.position, a.position, rtol=0, atol=1e-13)
    np.testing.assert_allclose(b.contact.friction_force, a.contact.friction_force, atol=1e-12)


def test_save_and_reload_keep_the_file_reference_and_inline_meshes(tmp_path):
    v, f = cube(20.0)
    (tmp_path / "meshes").mkdir()
    write_stl(tmp_path / "meshes" / "block.stl", v, f)
    doc = beam_over(plane(-1.0)) | {
        "obstacles": [
            mesh_ob(file="meshes/block.stl", units="mm", position=["0 mm", "0 mm", "-100 mm"]),
            mesh_ob(vertices=(v * 1e-3 - [0, 0, 0.2]).tolist(), faces=f.tolist(), units="m"),
        ]
    }
    import tomli_w

    (tmp_path / "d.toml").write_text(tomli_w.dumps(doc))
    design = load_design(tmp_path / "d.toml")
    assert design.mesh_sources == ((0, (tmp_path / "meshes" / "block.stl").resolve()),)
    (tmp_path / "elsewhere").mkdir()
    saved = design.save(tmp_path / "elsewhere" / "copy.toml")
    text = saved.read_text()
    assert 'file = "../meshes/block.stl"' in text
    again = load_design(saved)
    assert again == design
    assert again.spec["obstacles"] == design.spec["obstacles"]
    # What travels to a cluster's workers names the mesh file by its absolute path.
    from softrod.cluster import design_text

    block = str((tmp_path / "meshes" / "block.stl").resolve())
    assert f"file = {block!r}".replace("'", '"') in design_text(design)
    # A units = "SI" document's inline vertices are written with their unit.
    si = {"units": "SI", **beam_over(plane(-1.0))}
    si["obstacles"] = [mesh_ob(vertices=(v * 1e-3).tolist(), faces=f.tolist())]
    si["obstacles"][0].update(stiffness=1e6, tolerance=5e-5)
    si["sections"] = [dict(si["sections"][0])]
    first = load_design(si)
    assert load_design(first.save(tmp_path / "si.toml")) == first


def _refusal(ob, tmp_path=None):
    with pytest.raises(DesignError) as info:
        load_design(beam_over(ob))
    return info.value


V, F = cube(20.0)


@pytest.mark.parametrize(
    ("change", "field", "words"),
    [
        ({"faces": [[0, 1, 8]]}, "obstacles[0].faces[0][2]", "must be"),
        ({"faces": [[0, 1, 1]]}, "obstacles[0].faces[0]", "degenerate"),
        ({"faces": [[0, 1, 3], [0, 1, 2]]}, "obstacles[0].faces[1]", "winding"),
        ({"faces": F.tolist() + [F[0].tolist()]}, "obstacles[0].faces[12]", "three or more"),
        ({"faces": []}, "obstacles[0].faces", "non-empty"),
        ({"faces": [[0, 1]]}, "obstacles[0].faces[0]", "3 vertex indices"),
        ({"faces": [[0, 1, 2.5]]}, "obstacles[0].faces[0][2]", "integer"),
        (
            {"vertices": [[0, 0, float("nan")]] + V[1:].tolist()},
            "obstacles[0].vertices[0][2]",
            "finite",
        ),
        ({"vertices": [[0, 0, 1e300]] + V[1:].tolist()}, "obstacles[0].vertices[0][2]", "within"),
        # Entries the fast path of plain numbers does not take: checked one by one, named.
        ({"vertices": [[0, 0, True]] + V[1:].tolist()}, "obstacles[0].vertices[0][2]", "number"),
        ({"vertices": [[0, 0, "1"]] + V[1:].tolist()}, "obstacles[0].vertices[0][2]", "number"),
        ({"vertices": [[0, 0, 2**60]] + V[1:].tolist()}, "obstacles[0].vertices[0][2]", "2^53"),
        ({"vertices": [[0, 0]] + V[1:].tolist()}, "obstacles[0].vertices[0]", "3 numbers"),
        ({"faces": [[0, 1, True]]}, "obstacles[0].faces[0][2]", "integer"),
        ({"faces": [[-1, 1, 2]]}, "obstacles[0].faces[0][0]", ">= 0"),
        ({"faces": [[0, 1, 2**70]]}, "obstacles[0].faces[0][2]", "must be"),
        ({"units": "kg"}, "obstacles[0].units", "length"),
        ({"units": "2 mm"}, "obstacles[0].units", "length unit"),
        ({"rotation": [[1, 0, 0], [0, 1, 0], [0, 0, -1]]}, "obstacles[0].rotation", "rotation"),
        ({"file": "x.stl"}, "obstacles[0]", "either file"),
        ({"faces": [[0, 1, 2]] * (MAX_MESH_TRIANGLES + 1)}, "obstacles[0].faces", "at most"),
    ],
)
def test_bad_inline_meshes_name_field_value_and_rule(change, field, words):
    ob = mesh_ob(vertices=V.tolist(), faces=F.tolist(), units="mm")
    ob.update(change)
    err = _refusal(ob)
    assert err.field == field, str(err)
    assert words in str(err)


def test_bad_mesh_files_and_keys_are_refused(tmp_path):
    def load(ob):
        import tomli_w

        path = tmp_path / "d.toml"
        path.write_text(tomli_w.dumps(beam_over(plane(-1.0)) | {"obstacles": [ob]}))
        with pytest.raises(DesignError) as info:
            load_design(path)
        return info.value

    err = load(mesh_ob(file="nowhere.stl", units="mm"))
    assert err.field == "obstacles[0].file" and "no such file" in str(err)
    write_stl(tmp_path / "ok.stl", V, F)
    err = load(mesh_ob(file="ok.stl"))
    assert err.field == "obstacles[0].units" and "carry no unit" in str(err)
    err = load(mesh_ob(file="ok.stl", units="mm", faces=[[0, 1, 2]]))
    assert err.field == "obstacles[0].faces"
    (tmp_path / "bad.stl").write_bytes(b"\x00\xff" * 100)
    err = load(mesh_ob(file="bad.stl", units="mm"))
    assert err.field == "obstacles[0].file" and "STL" in str(err)
    (tmp_path / "short.stl").write_text("solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n")
    err = load(mesh_ob(file="short.stl", units="mm"))
    assert err.field == "obstacles[0].file" and "three" in str(err)
    # A binary header that promises more triangles than the cap (and the file's size).
    big = b"x" * 80 + struct.pack("<I", MAX_MESH_TRIANGLES + 1)
    (tmp_path / "big.stl").write_bytes(big + b"\x00" * 50 * (MAX_MESH_TRIANGLES + 1))
    err = load(mesh_ob(file="big.stl", units="mm"))
    assert err.field == "obstacles[0].file" and "at most" in str(err)
    (tmp_path / "m.ply").write_text("ply\n")
    err = load(mesh_ob(file="m.ply", units="mm"))
    assert err.field == "obstacles[0].file" and "OBJ" in str(err)
    (tmp_path / "bad.obj").write_text("v 0 0 0\nv 1 0 0\nf 1 2 3\n")
    err = load(mesh_ob(file="bad.obj", units="mm"))
    assert err.field == "obstacles[0].file" and "line 3" in str(err)
    # The core's rules on a file's mesh name the file key, and the mesh entry.
    flipped = F.copy()
    flipped[3] = flipped[3][::-1]
    write_stl(tmp_path / "flipped.stl", V, flipped)
    err = load(mesh_ob(file="flipped.stl", units="mm"))
    assert err.field == "obstacles[0].file" and "winding" in str(err), str(err)
    # Mesh keys on another kind.
    err = _refusal({**plane(-1.0), "file": "ok.stl"})
    assert err.field == "obstacles[0].file" and "only a mesh" in str(err)


def test_a_rod_on_an_icosphere_file_balances_and_approaches_the_sphere(tmp_path):
    # A beam pushed at its tip onto a ball (tests/test_contact.py), the ball as an STL
    # icosphere of 1280 triangles: within the facets' error of the sphere's reaction
    # (crates/softrod-core/tests/suite/mesh_contact.rs derives and checks the convergence).
    import tomli_w

    v, f = icosphere(3)
    centre = np.array([500.0, 0.0, -52.0])
    write_stl(tmp_path / "ball.stl", v * 50.0 + centre, f)
    common = {"stiffness": "1e7 N/m^2", "tolerance": "0.1 mm"}
    ball = {"kind": "sphere", "center": [f"{c} mm" for c in centre], "radius": "50 mm"}
    results = []
    for ob in (ball, {"kind": "mesh", "file": "ball.stl", "units": "mm"}):
        doc = beam_over(ob | common, gravity=False) | {"tip": {"force": ["0 N", "0 N", "-0.1 N"]}}
        (tmp_path / "d.toml").write_text(tomli_w.dumps(doc))
        sol = solve_statics(load_design(tmp_path / "d.toml"), [])
        f_c = sol.contact.total_force[0]
        assert np.abs(sol.base_force - (np.array([0, 0, -0.1]) + f_c)).max() < 1e-9
        assert 0 < sol.contact.max_penetration <= 1e-4
        results.append(f_c[2])
    # Level 3: measured 1.8e-4 relative (9.1e-6 N of 0.0516 N in
    # crates/softrod-core/tests/suite/mesh_contact.rs).
    assert abs(results[1] - results[0]) < 1e-3 * results[0]


def icosphere(level):
    """A unit icosphere (20 * 4^level triangles, outward)."""
    t = (1 + 5**0.5) / 2
    v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t]]
    v += [[0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    v = [list(np.array(p) / np.linalg.norm(p)) for p in v]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4]]
    f += [[11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8]]
    f += [[3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    for _ in range(level):
        mid: dict = {}

        def m(a, b, mid=mid):
            key = (min(a, b), max(a, b))
            if key not in mid:
                p = (np.array(v[a]) + np.array(v[b])) / 2
                v.append(list(p / np.linalg.norm(p)))
                mid[key] = len(v) - 1
            return mid[key]

        nxt = []
        for a, b, c in f:
            ab, bc, ca = m(a, b), m(b, c), m(c, a)
            nxt += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        f = nxt
    return np.array(v), np.array(f)


_number = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, 1.0, -1.0, 1e-300, 1e300, 5e-13]),
    st.text(max_size=6),
    st.none(),
)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    vertices=st.one_of(
        st.lists(st.lists(_number, min_size=0, max_size=4), max_size=6),
        st.lists(
            st.lists(st.floats(-1e4, 1e4, allow_nan=False), min_size=3, max_size=3),
            min_size=3,
            max_size=6,
        ),
        st.just("nan"),
    ),
    faces=st.one_of(
        st.lists(st.lists(st.integers(-3, 8), min_size=0, max_size=4), max_size=6),
        st.lists(st.lists(st.sampled_from([0, 1, 2, 2**70, True, 1.5]), min_size=3, max_size=3)),
        st.just({}),
    ),
    units=st.sampled_from(["mm", "m", "kg", "", None]),
)
def test_property_hostile_meshes_are_design_errors(vertices, faces, units):
    """Whatever the vertices, faces and units, loading either succeeds with finite metres
    or raises DesignError: never another exception, never a crash."""
    ob = mesh_ob(vertices=vertices, faces=faces)
    if units is not None:
        ob["units"] = units
    try:
        design = load_design(beam_over(ob))
    except DesignError:
        return
    got = np.array(design.spec["obstacles"][0]["vertices"], dtype=float)
    assert np.all(np.isfinite(got)) and np.abs(got).max() <= 1e3


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.binary(max_size=400), suffix=st.sampled_from([".stl", ".obj"]))
def test_property_hostile_mesh_files_are_design_errors(tmp_path_factory, data, suffix):
    path = tmp_path_factory.mktemp("m") / f"m{suffix}"
    path.write_bytes(data)
    try:
        v, f = read_mesh(path)
    except DesignError:
        return
    assert v.ndim == 2 and v.shape[1] == 3 and f.shape[1] == 3 and np.all(np.isfinite(v))
    assert math.isfinite(float(np.abs(v).sum()))


def _finger_on_mesh_table(**extra):
    v, f = patch(-82.0)
    table = mesh_ob(vertices=v.tolist(), faces=f.tolist(), units="mm")
    table.update(stiffness="1e7 N/m^2", tolerance="0.2 mm", **extra)
    return load_design(FINGER).with_obstacles([table])


def test_a_mesh_table_moves_the_finger_as_the_plane_does():
    # The dynamics with the table as two triangles: the same penalty and friction, so the
    # same motion to round-off (pressure ramped onto the table, with friction).
    from softrod import simulate

    def schedule(t):
        return [20e3 + 30e3 * min(t / 0.05, 1.0)]

    plane_run = simulate(
        load_design(FINGER).replace({"obstacles[0].friction": 0.3}), schedule, 0.05
    )
    mesh_run = simulate(_finger_on_mesh_table(friction=0.3), schedule, 0.05)
    np.testing.assert_allclose(mesh_run.tip_position, plane_run.tip_position, rtol=0, atol=1e-12)
    np.testing.assert_allclose(mesh_run.contact_force, plane_run.contact_force, atol=1e-10)
    assert mesh_run.contact_force[-1, 2] > 0 and mesh_run.penetration.max() <= 0.2e-3


def test_plots_and_viewer_draw_a_mesh():
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection
    from softrod.plotting import plot_shape
    from softrod.viewer import geometry as geo

    design = _finger_on_mesh_table()
    fig = plot_shape(solve_statics(design, [30e3]))
    ax3d = fig.axes[0]
    (tris,) = [c for c in ax3d.collections if type(c) is Poly3DCollection]
    assert ax3d.get_zlim()[0] <= -82.0  # the view holds the mesh table
    # The table's 4 m square is held in the view only near the finger.
    assert np.ptp(ax3d.get_xlim()) < 500.0
    plt.close(fig)
    ((kind, args),) = geo.obstacle_solids(design.spec["obstacles"][0], np.zeros(3), 0.1)
    assert kind == "mesh" and args["vertices"].shape == (6, 3) and args["faces"].shape == (2, 3)
    np.testing.assert_allclose(args["vertices"][:, 2], -0.082, rtol=1e-7)
    # A big mesh is drawn by an evenly spread subset of at most MAX_DRAWN_TRIANGLES.
    v, f = icosphere(7)  # 327,680 triangles (only drawn here, never solved)
    big = geo.drawn_triangles({"vertices": v, "faces": f})
    assert len(big) <= geo.MAX_DRAWN_TRIANGLES and len(big) > geo.MAX_DRAWN_TRIANGLES // 2
    view = __import__("softrod").view(design, environment_map=False)
    try:
        sol = view.set_inputs(pressures=[30e3])
        assert sol.contact.total_force[0][2] > 0
    finally:
        view.close()


def test_a_system_on_a_mesh_table_solves_and_draws_as_on_the_plane():
    """The bundled two fingers holding a clip, their table as two triangles: the same
    equilibrium as on the plane to round-off (same distance and normal), and the system's
    figure draws the mesh projected in both views with the contact points on it."""
    import dataclasses

    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection
    from softrod import load_system, solve_system
    from softrod.system_plots import plot_system

    pair = load_system("two_fingers_on_table")
    z_mm = pair.rods[0].design.spec["obstacles"][0]["point"][2] * 1e3
    v, f = patch(z_mm)
    table = mesh_ob(vertices=v.tolist(), faces=f.tolist(), units="mm")
    table.update(stiffness="1e7 N/m^2", tolerance="0.2 mm")
    on_mesh = dataclasses.replace(
        pair,
        rods=tuple(
            dataclasses.replace(r, design=r.design.with_obstacles([table])) for r in pair.rods
        ),
    )
    inputs = [[35e3], [35e3]]
    plane, mesh = solve_system(pair, inputs), solve_system(on_mesh, inputs)
    np.testing.assert_allclose(mesh.platform_position, plane.platform_position, rtol=0, atol=1e-12)
    assert all(r.contact.in_contact.any() for r in mesh.rods)
    fig = plot_system(mesh)
    try:
        for ax in fig.axes[:2]:
            shadows = [c for c in ax.collections if type(c) is PolyCollection]
            assert shadows and ax.get_ylim()[0] < z_mm  # the table in the view
            dots = [ln for ln in ax.get_lines() if ln.get_marker() == "o"]
            assert dots and all(np.allclose(d.get_ydata(), z_mm, atol=0.3) for d in dots)
    finally:
        plt.close(fig)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    vertices=st.one_of(
        st.just([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
        st.lists(st.lists(st.floats(), min_size=3, max_size=3), min_size=3, max_size=4),
        st.one_of(st.integers(), st.floats(), st.text(max_size=3), st.none()),
    ),
    faces=st.one_of(
        st.just([[0, 1, 2]]),
        st.lists(st.lists(st.one_of(st.integers(-2, 4), st.floats()), min_size=3, max_size=3)),
        st.one_of(st.integers(), st.floats(), st.text(max_size=3), st.none()),
    ),
)
def test_write_stl_writes_or_names_the_bad_argument(tmp_path_factory, vertices, faces):
    """Whatever it is given, write_stl writes a file that reads back to its triangles or
    raises an error naming vertices or faces (never IndexError, never a numpy warning)."""
    path = tmp_path_factory.mktemp("w") / "m.stl"
    try:
        write_stl(path, vertices, faces)
    except DesignError as exc:
        assert exc.field.split("[")[0] in ("vertices", "faces")
        assert not path.exists()
        return
    v, f = read_mesh(path)
    assert len(f) == len(faces) and np.all(np.isfinite(v))
