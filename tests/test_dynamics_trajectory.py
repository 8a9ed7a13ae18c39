"""Trajectories: validation, exact file round trips, atomic writes, tip errors, plots, GIFs."""

import json
import math

import matplotlib
import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from PIL import Image
from softrod import InputError, load_dataset
from softrod.dynamics import Trajectory

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

pytestmark = pytest.mark.fast

_L = 0.2  # m, rod length of the synthetic arc
_TIP_TOL = 1e-12  # m: linear interpolation of exactly linear data, rounding only


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


def _rz(phi):
    c, s = math.cos(phi), math.sin(phi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _ry(theta):
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def arc_trajectory(n=21, t_end=1.0, save_every=2, p=9, channels=3) -> Trajectory:
    """A hanging circular arc whose curvature grows and whose bending plane turns about z.

    Curvature kappa(t) = 8 t 1/m, bending plane at angle phi(t) = 2 t rad. The centreline of
    an arc bending in the x-z plane, hanging along -z: x = (1 - cos ks)/k, z = -sin(ks)/k.
    """
    time = np.linspace(0.0, t_end, n)
    s = np.linspace(0.0, _L, p)

    def centreline(t):
        k, phi = 8.0 * t, 2.0 * t
        if k == 0:
            local = np.column_stack([0 * s, 0 * s, -s])
        else:
            local = np.column_stack([(1 - np.cos(k * s)) / k, 0 * s, -np.sin(k * s) / k])
        return local @ _rz(phi).T

    shapes = np.array([centreline(t) for t in time])
    rot = np.array([_rz(2.0 * t) @ _ry(-8.0 * t * _L) @ np.diag([1.0, -1.0, -1.0]) for t in time])
    cmd = np.column_stack([50e3 * time * (k + 1) for k in range(channels)])
    energy = 0.01 * time**2
    energy[0] = np.nan  # allowed: not defined at the first sample
    return Trajectory(
        time=time,
        command=cmd,
        pressure=0.9 * cmd,
        tip_position=shapes[:, -1],
        tip_rotation=rot,
        tip_velocity=np.gradient(shapes[:, -1], time, axis=0),
        energy=energy,
        shape_time=time[::save_every],
        shape_s=s,
        shape_position=shapes[::save_every],
        metadata={"design": "synthetic_arc", "dt": 0.05, "method": "none", "tags": [1, "a"]},
    )


def assert_same(a: Trajectory, b: Trajectory):
    for name in (
        "time",
        "command",
        "pressure",
        "tip_position",
        "tip_rotation",
        "tip_velocity",
        "energy",
        "kinetic",
        "elastic",
        "potential",
        "work_in",
        "dissipated",
        "shape_time",
        "shape_s",
        "shape_position",
    ):
        x, y = getattr(a, name), getattr(b, name)
        assert x.shape == y.shape, name
        np.testing.assert_array_equal(x, y, err_msg=name)  # NaN == NaN here; bits exact
    assert a.metadata == b.metadata


def test_synthetic_trajectory_is_valid():
    tr = arc_trajectory()
    assert len(tr) == 21 and tr.n_channels == 3 and tr.duration == 1.0
    assert tr.shape_position.shape == (11, 9, 3)
    assert "11 shapes of 9 nodes" in repr(tr)
    with pytest.raises(ValueError):
        tr.time[0] = 1.0  # read-only


@pytest.mark.parametrize("suffix", [".parquet", ".npz"])
def test_round_trip_is_exact(tmp_path, suffix):
    tr = arc_trajectory()
    path = tr.save(tmp_path / f"run{suffix}")
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"run{suffix}"]
    assert_same(Trajectory.load(path), tr)


@pytest.mark.parametrize("suffix", [".parquet", ".npz"])
def test_round_trip_without_shapes(tmp_path, suffix):
    tr = arc_trajectory(n=3, channels=1)
    bare = Trajectory(
        time=tr.time,
        command=tr.command,
        pressure=tr.pressure,
        tip_position=tr.tip_position,
        tip_rotation=tr.tip_rotation,
        tip_velocity=tr.tip_velocity,
    )
    assert bare.shape_position.shape == (0, 0, 3) and np.isnan(bare.energy).all()
    assert_same(Trajectory.load(bare.save(tmp_path / f"b{suffix}")), bare)


def test_zero_channels_round_trip(tmp_path):
    # A design without chambers (driven by tip loads) has no pressure columns.
    tr = arc_trajectory(channels=1)
    fields = {**_fields(tr), "command": np.zeros((len(tr), 0)), "pressure": np.zeros((len(tr), 0))}
    bare = Trajectory(**fields)
    assert bare.n_channels == 0
    for suffix in (".parquet", ".npz"):
        assert_same(Trajectory.load(bare.save(tmp_path / f"z{suffix}")), bare)


def test_parquet_layout(tmp_path):
    tr = arc_trajectory(channels=2)
    path = tr.save(tmp_path / "run.parquet")
    table = pq.read_table(path)
    assert table.column_names == [
        "time_s",
        "p0_Pa",
        "p1_Pa",
        "tip_x_m",
        "tip_y_m",
        "tip_z_m",
        "tip_qw",
        "tip_qx",
        "tip_qy",
        "tip_qz",
        "cmd0_Pa",
        "cmd1_Pa",
        "tip_vx_m/s",
        "tip_vy_m/s",
        "tip_vz_m/s",
        "energy_J",
        "kinetic_J",
        "elastic_J",
        "potential_J",
        "work_in_J",
        "dissipated_J",
        *[f"tip_R{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3)],
        "shape_m",
    ]
    shapes = table.column("shape_m").to_pylist()
    assert [x is not None for x in shapes] == [i % 2 == 0 for i in range(21)]
    np.testing.assert_array_equal(shapes[4], tr.shape_position[2].reshape(-1))  # node-major
    kv = table.schema.metadata
    meta = json.loads(kv[b"softrod.metadata"])
    declared = meta.pop("columns")
    assert meta == {"synthetic": True, **tr.metadata}  # made by the model, not measured
    books = {f"{p}_J" for p in ("kinetic", "elastic", "potential", "work_in", "dissipated")}
    assert set(declared) == {"cmd0_Pa", "cmd1_Pa", "energy_J", "shape_m"} | books | {
        f"tip_v{a}_m/s" for a in "xyz"
    } | {f"tip_R{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3)}
    layout = json.loads(kv[b"softrod.trajectory"])
    assert layout["format"] == 3 and layout["n_channels"] == 2 and layout["n_nodes"] == 9
    assert layout["shape_s_m"] == tr.shape_s.tolist()
    np.testing.assert_array_equal(table.column("tip_R23").to_numpy(), tr.tip_rotation[:, 1, 2])


# to_frame writes kPa and mm: x / 1e3 and back * 1e3 round twice, at most 2 ulp (4.4e-16 rel).
_UNIT_ROUND_TRIP = 1e-15


def test_to_frame_reads_as_dataset():
    tr = arc_trajectory()
    frame = tr.to_frame()
    assert "shape_m" not in frame.columns
    meta = frame.attrs["softrod.metadata"]
    assert {k: v for k, v in meta.items() if k != "columns"} == {"synthetic": True, **tr.metadata}
    assert list(frame.columns[:4]) == ["time_s", "p0_kPa", "p1_kPa", "p2_kPa"]
    ds = load_dataset(frame)  # the result columns are declared: no extra="ignore" needed
    np.testing.assert_allclose(ds.tip_position, tr.tip_position, rtol=_UNIT_ROUND_TRIP)
    np.testing.assert_allclose(ds.pressures, tr.pressure, rtol=_UNIT_ROUND_TRIP)
    np.testing.assert_array_equal(ds.time, tr.time)
    np.testing.assert_allclose(ds.extra["cmd0_kPa"] * 1e3, tr.command[:, 0], rtol=1e-15)
    np.testing.assert_allclose(ds.extra["tip_vx_mm/s"] / 1e3, tr.tip_velocity[:, 0], rtol=1e-15)
    # Quaternion and back: the rotation to a few ulp.
    np.testing.assert_allclose(ds.tip_rotation, tr.tip_rotation, atol=1e-15)


def test_saved_trajectory_reads_as_dataset(tmp_path):
    tr = arc_trajectory()
    ds = load_dataset(tr.save(tmp_path / "run.parquet"))  # SI columns: exact
    np.testing.assert_array_equal(ds.tip_position, tr.tip_position)
    np.testing.assert_array_equal(ds.pressures, tr.pressure)
    np.testing.assert_array_equal(ds.extra["tip_R23"], tr.tip_rotation[:, 1, 2])
    assert ds.metadata["design"] == tr.metadata["design"]


def test_newer_format_is_a_clear_error(tmp_path):
    import pyarrow.parquet as pq

    tr = arc_trajectory(n=3)
    path = tr.save(tmp_path / "run.parquet")
    table = pq.read_table(path)
    kv = dict(table.schema.metadata)
    layout = json.loads(kv[b"softrod.trajectory"])
    layout["format"] = 99
    kv[b"softrod.trajectory"] = json.dumps(layout).encode()
    pq.write_table(table.replace_schema_metadata(kv), path)
    with pytest.raises(InputError, match="newer softrod .trajectory format 99"):
        Trajectory.load(path)


def test_save_load_errors(tmp_path):
    tr = arc_trajectory(n=3)
    with pytest.raises(InputError, match=r"'\.csv'.*\.parquet or \.npz"):
        tr.save(tmp_path / "run.csv")
    with pytest.raises(InputError, match="no such file"):
        Trajectory.load(tmp_path / "none.npz")
    pd.DataFrame({"a": [1.0]}).to_parquet(tmp_path / "other.parquet")
    with pytest.raises(InputError, match="other.parquet: .*not a softrod trajectory"):
        Trajectory.load(tmp_path / "other.parquet")
    np.savez(tmp_path / "other.npz", a=np.zeros(2))
    with pytest.raises(InputError, match="other.npz: .*not a softrod trajectory"):
        Trajectory.load(tmp_path / "other.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(InputError, match="not a readable"):
        Trajectory.load(tmp_path / "junk.npz")


@pytest.mark.parametrize("suffix", [".parquet", ".npz"])
def test_failed_save_leaves_old_file_and_no_temporary(tmp_path, monkeypatch, suffix):
    tr = arc_trajectory(n=3)
    path = tr.save(tmp_path / f"run{suffix}")
    before = path.read_bytes()

    def broken(target, *args, **kwargs):
        with open(target, "wb") as fh:  # half a file, then a crash
            fh.write(b"partial")
        raise OSError("disk full")

    if suffix == ".npz":
        monkeypatch.setattr(np, "savez_compressed", lambda fh, **kw: broken(fh.name))
    else:
        monkeypatch.setattr(pq, "write_table", lambda table, target: broken(target))
    with pytest.raises(OSError, match="disk full"):
        arc_trajectory(n=5).save(path)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"run{suffix}"]
    with pytest.raises(OSError):
        arc_trajectory(n=5).save(tmp_path / f"new{suffix}")
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"run{suffix}"]


def _fields(tr: Trajectory) -> dict:
    return {
        k: getattr(tr, k)
        for k in (
            "time",
            "command",
            "pressure",
            "tip_position",
            "tip_rotation",
            "tip_velocity",
            "energy",
            "shape_time",
            "shape_s",
            "shape_position",
            "metadata",
        )
    }


@pytest.mark.parametrize(
    ("change", "fragments"),
    [
        ({"time": [0.0, 0.5, 0.5]}, ("time[2] = 0.5", "strictly increasing")),
        ({"time": [0.0, np.nan, 1.0]}, ("time", "finite")),
        ({"pressure": np.zeros((3, 2))}, ("pressure", "shape (3, 2)", "channels = 3")),
        ({"tip_rotation": np.zeros((3, 3))}, ("tip_rotation", "(3, 3, 3)")),
        ({"tip_velocity": np.full((3, 3), np.inf)}, ("tip_velocity", "finite", "index 0")),
        ({"energy": np.zeros(4)}, ("energy", "shape (4,)")),
        ({"shape_time": [0.0, 0.75]}, ("shape_time[1] = 0.75", "one of the sample times")),
        ({"shape_position": np.zeros((2, 9, 3))}, ("shape_position", "(k = 3, p = 9, 3)")),
        ({"shape_s": np.linspace(0, 1, 9)[::-1]}, ("shape_s[1]", "strictly increasing")),
        ({"metadata": {"x": object()}}, ("metadata", "JSON")),
        ({"metadata": {"rtf": float("nan")}}, ("metadata", "JSON")),
        ({"command": np.zeros((3, 0))}, ("pressure", "(n = 3, channels = 0)")),
    ],
)
def test_validation_errors(change, fragments):
    fields = {**_fields(arc_trajectory(n=3, save_every=1)), **change}
    with pytest.raises(InputError) as info:
        Trajectory(**fields)
    for f in fragments:
        assert f in str(info.value), (f, str(info.value))


# --- tip error ------------------------------------------------------------------------------


def test_tip_error_against_known_offset():
    tr = Trajectory(
        time=[0.0, 1.0, 2.0],
        command=np.zeros((3, 1)),
        pressure=np.zeros((3, 1)),
        tip_position=[[0.0, 0.0, -0.2], [0.1, 0.0, -0.2], [0.1, 0.2, -0.2]],
        tip_rotation=np.tile(np.eye(3), (3, 1, 1)),
        tip_velocity=np.zeros((3, 3)),
    )
    t = np.array([0.0, 0.5, 1.5, 2.0])
    model = np.array([[0, 0, -0.2], [0.05, 0, -0.2], [0.1, 0.1, -0.2], [0.1, 0.2, -0.2]])
    np.testing.assert_allclose(tr.tip_position_at(t), model, atol=_TIP_TOL, rtol=0)
    measured = model + np.array([0.0, 0.003, 0.004])  # 3-4-5: 5 mm everywhere
    np.testing.assert_allclose(tr.tip_error(t, measured), 0.005, atol=_TIP_TOL, rtol=0)
    with pytest.raises(InputError) as info:
        tr.tip_error([0.5, 2.5, 3.0], np.zeros((3, 3)))
    msg = str(info.value)
    assert "measured_time[1] = 2.5" in msg and "[0, 2] s" in msg and "2 of 3" in msg
    with pytest.raises(InputError, match="measured_position"):
        tr.tip_error([0.5], np.zeros((2, 3)))


# --- plots and animations --------------------------------------------------------------------


def test_plot_tip_writes_png_with_reference(tmp_path):
    tr = arc_trajectory()
    measured = pd.DataFrame(
        {
            "time_s": tr.time,
            "tip_x_mm": tr.tip_position[:, 0] * 1e3 + 2.0,
            "tip_y_mm": tr.tip_position[:, 1] * 1e3,
            "tip_z_mm": tr.tip_position[:, 2] * 1e3,
        }
    )
    path = tmp_path / "tip.png"
    fig = tr.plot_tip(path, reference=measured)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    top, bottom = fig.axes
    assert top.get_ylabel() == "tip position (mm)"
    assert bottom.get_ylabel() == "pressure (kPa)" and bottom.get_xlabel() == "time (s)"
    x_ref = next(line for line in top.get_lines() if line.get_label() == "x measured")
    np.testing.assert_allclose(x_ref.get_ydata(), measured["tip_x_mm"])
    assert len(bottom.get_lines()) == 2 * tr.n_channels  # actual and command per channel
    # Other reference kinds; no file without a path.
    tr.plot_tip(reference=tr)
    tr.plot_tip(reference=(tr.time, tr.tip_position))
    with pytest.raises(InputError, match="tip_z"):
        tr.plot_tip(reference=measured.drop(columns="tip_z_mm"))
    with pytest.raises(InputError, match="unknown figure format"):
        tr.plot_tip(tmp_path / "tip.xyz")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tip.png"]


def test_animate_gif_frames(tmp_path):
    tr = arc_trajectory(n=21, t_end=1.0, save_every=2)  # shapes every 0.1 s, 11 of them
    small = {"dpi": 30, "figsize": (2.0, 2.0)}
    path = tr.animate(tmp_path / "run.gif", fps=10, **small)
    with Image.open(path) as img:
        assert img.format == "GIF"
        assert img.n_frames == 11  # one frame per 0.1 s, shapes 0 ... 1 s
        assert img.info["duration"] == 100  # ms per frame at 10 fps
    tr.animate(tmp_path / "fast.gif", fps=10, speed=2.0, trail=False, **small)
    with Image.open(tmp_path / "fast.gif") as img:
        assert img.n_frames == 6  # twice as fast: 0, 0.2, ... 1 s
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fast.gif", "run.gif"]


def test_animate_frame_choice():
    tr = arc_trajectory(n=21, t_end=1.0, save_every=2)
    # Frame j at j * speed / fps s shows the nearest stored shape (shapes every 0.1 s).
    np.testing.assert_array_equal(tr._frame_indices(3.0, 1.0), [0, 3, 7, 10])
    np.testing.assert_array_equal(tr._frame_indices(7.0, 1.0), [0, 1, 3, 4, 6, 7, 9, 10])
    np.testing.assert_array_equal(tr._frame_indices(3.5, 0.5), [0, 1, 3, 4, 6, 7, 9, 10])
    assert tr._frame_indices(1.0, 10.0).tolist() == [0]  # one frame covers the whole run


def test_animate_errors(tmp_path, monkeypatch):
    tr = arc_trajectory(n=3, save_every=5)  # one shape only
    with pytest.raises(InputError, match="at least 2 stored shapes"):
        tr.animate(tmp_path / "a.gif")
    tr = arc_trajectory(n=3, save_every=1)
    with pytest.raises(InputError, match=r"'\.avi'.*\.gif or \.mp4"):
        tr.animate(tmp_path / "a.avi")
    with pytest.raises(InputError, match="fps = 0"):
        tr.animate(tmp_path / "a.gif", fps=0)
    import shutil

    monkeypatch.setattr(shutil, "which", lambda name: None)
    with pytest.raises(InputError, match="install ffmpeg.*gif"):
        tr.animate(tmp_path / "a.mp4")
    assert list(tmp_path.iterdir()) == []
