"""Batch work on a real local Dask cluster (two worker processes): sweeps, per-sample
identification and calibration restarts give bitwise the single-process results, a worker
killed in the middle of a sweep changes nothing, and designs travel as TOML text.

Fair comparison: today a batch row warm-starts from its neighbour within the core's
internal chunks, whose size depends on the rows per call and the thread count. So the
single-process reference runs the same chunks with the same thread count (one per task),
which is exactly what a worker does; then the results must agree to the last bit. Once batch
rows are independent of chunking, the reference can be one call.
"""

from __future__ import annotations

import os
import signal

import numpy as np
import pytest
import softrod
from softrod import identify_stiffness, load_design, solve_statics_batch
from softrod.cluster import chunk_rows, design_from_text, design_text

distributed = pytest.importorskip("distributed", reason="needs the cluster extra (dask)")

SPA = "spa_three_chamber_130mm"
#: paper 001's actuator with coarse steps (1/9/1): fast solves, same physics.
COARSE = {"numerics": {"step_length": "13 mm"}}
BATCH_FIELDS = (
    "tip_position",
    "tip_rotation",
    "base_force",
    "base_moment",
    "converged",
    "iterations",
    "residual",
    "x",
)


@pytest.fixture(scope="module")
def client():
    from distributed import Client, LocalCluster

    cluster = LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    )
    client = Client(cluster)
    yield client
    client.close()
    cluster.close()


@pytest.fixture(scope="module")
def design():
    return load_design(SPA).replace(COARSE)


def grid(n: int, top: float = 70e3) -> np.ndarray:
    g = np.linspace(0.0, top, n)
    return np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)


def in_chunks(design, pressures, rows: int):
    """The single-process reference: the same chunks as the cluster, one thread each."""
    parts = [
        solve_statics_batch(design, pressures[lo : lo + rows], threads=1)
        for lo in range(0, len(pressures), rows)
    ]
    return {k: np.concatenate([getattr(p, k) for p in parts]) for k in BATCH_FIELDS}


def assert_batch_equal(out, ref):
    for k in BATCH_FIELDS:
        np.testing.assert_array_equal(getattr(out, k), ref[k], err_msg=k)


def test_designs_travel_as_toml_text():
    names = softrod.bundled_designs() + [p.name for p in softrod.list_presets()]
    for name in names:
        d = load_design(name)
        text = design_text(d)
        assert isinstance(text, str) and "[design]" in text
        assert design_from_text(text).spec == d.spec, name


def test_sweep_on_the_cluster_equals_the_single_process_batch(client, design):
    p = grid(8)  # 512 rows
    seen = []
    out = solve_statics_batch(
        design,
        p,
        threads=1,
        executor=client,
        chunk_size=64,
        progress=lambda done, total: seen.append((done, total)),
    )
    assert_batch_equal(out, in_chunks(design, p, 64))
    assert out.converged.all()
    # Progress after each of the 8 chunks, counted in rows, ending at all of them.
    assert len(seen) == 8 and seen[-1] == (512, 512)
    assert [d for d, _ in seen] == sorted(d for d, _ in seen)


def test_held_tip_batch_on_the_cluster_equals_the_local_batch(client, design):
    """A pinned tip travels to the workers (as the binding's arguments): every row is solved
    cold, so the cluster's chunks give bitwise the one local call, reactions included."""
    pin = softrod.TipConstraint.pinned(["4 mm", "-2 mm", "-127 mm"])
    p = grid(3)  # 27 rows in 4 chunks
    out = solve_statics_batch(
        design,
        p,
        threads=1,
        executor=client,
        chunk_size=8,
        tip_constraint=pin,
        on_unstable="ignore",
    )
    ref = solve_statics_batch(design, p, threads=2, tip_constraint=pin, on_unstable="ignore")
    assert out.converged.all() and out.tip_constraint == "pinned"
    for k in (*BATCH_FIELDS, "tip_reaction_force", "tip_reaction_moment", "stable"):
        np.testing.assert_array_equal(getattr(out, k), getattr(ref, k), err_msg=k)
    assert out.metadata["tip_constraint"]["type"] == "pinned"


def test_frictional_batch_on_the_cluster_equals_the_local_batch(client):
    """With friction every row follows its own load path in friction_steps increments,
    which travel to the workers: the cluster's chunks give bitwise the one local call,
    contact and friction forces included, and progress still counts the chunks' rows."""
    rough = load_design("prebent_finger_on_table").replace({"obstacles[0].friction": 0.5})
    opts = softrod.SolverOptions(friction_steps=10)
    p = np.linspace(0.0, 45e3, 6)[:, None]
    seen = []
    out = solve_statics_batch(
        rough,
        p,
        options=opts,
        threads=1,
        executor=client,
        chunk_size=2,
        progress=lambda done, total: seen.append((done, total)),
    )
    ref = solve_statics_batch(rough, p, options=opts, threads=2)
    assert out.converged.all()
    for k in (*BATCH_FIELDS, "contact_force", "friction_force"):
        np.testing.assert_array_equal(getattr(out, k), getattr(ref, k), err_msg=k)
    assert len(seen) == 3 and seen[-1] == (6, 6)


def test_worker_killed_mid_sweep_changes_nothing(client, design):
    p = grid(12)  # 1728 rows in 36 chunks: each worker has several queued when one dies
    rows = 48
    pids = client.run(os.getpid)
    killed = []

    def progress(done, total):
        if killed:
            return
        busy = [w for w, keys in client.processing().items() if keys and w in pids]
        if busy:  # kill a worker while it is solving a chunk
            os.kill(pids[busy[0]], signal.SIGKILL)
            killed.append(busy[0])

    out = solve_statics_batch(
        design, p, threads=1, executor=client, chunk_size=rows, progress=progress
    )
    assert killed, "no worker was busy when the first chunk finished"
    assert_batch_equal(out, in_chunks(design, p, rows))
    assert len(out.converged) == len(p) and out.converged.all()
    client.wait_for_workers(2, timeout=60)  # the nanny restarts it for the next tests
    assert killed[0] not in client.scheduler_info()["workers"]


def test_per_sample_identification_on_the_cluster(client, design):
    from softrod.calibration.per_sample import stiffness_mapped_design

    mapped = stiffness_mapped_design(design)[0]
    p = grid(4)  # 64 samples
    truth = softrod.StiffnessMap.from_callable(
        lambda q: np.stack([1 + q[:, 0] / 400e3, 1 + q[:, 1] / 300e3, 1 - q[:, 2] / 500e3], 1),
        n_channels=3,
    )
    batch = solve_statics_batch(mapped, p, stiffness_map=truth)
    data = softrod.Dataset(
        pressures=p,
        tip_position=batch.tip_position,
        tip_rotation=batch.tip_rotation,
        metadata={"synthetic": True},
    )
    rows = 16
    ident = identify_stiffness(design, data, executor=client, chunk_size=rows, threads=1)
    parts = [
        identify_stiffness(design, data.subset(np.arange(lo, lo + rows)), threads=1)
        for lo in range(0, len(p), rows)
    ]
    for name in (
        "sigma",
        "sigma_solver",
        "sensitivity",
        "tip_position",
        "residual_mm",
        "iterations",
        "status",
        "identifiable",
        "at_bound",
    ):
        ref = np.concatenate([getattr(r, name) for r in parts])
        np.testing.assert_array_equal(getattr(ident, name), ref, err_msg=name)
    assert ident.design.spec == parts[0].design.spec
    assert ident.dataset is data
    assert (ident.status == "converged").all()


def test_calibration_restarts_on_the_cluster(client):
    m3 = load_design("paper002_M3_vertical").replace(COARSE)
    truth = m3.replace({"sections[1].c_b": 1.3})
    ramp = 50e3 * np.arange(1, 6) / 5
    p = np.vstack([np.outer(ramp, e) for e in np.eye(3)])
    data = softrod.synthesize_dataset(truth, p)
    kw = dict(restarts=3, seed=7, threads=1, bounds={"c_b": (0.5, 3.0)})
    remote = softrod.calibrate(m3, data, ["c_b"], executor=client, **kw)
    local = softrod.calibrate(m3, data, ["c_b"], **kw)
    np.testing.assert_array_equal(remote.values, local.values)
    assert remote.starts.equals(local.starts)
    assert len(remote.starts) == 4 and remote.starts["best"].sum() == 1
    assert remote.values[0] == pytest.approx(1.3, rel=1e-6)  # noise-free data: the truth


def test_chunk_size_rule():
    # At least 4 chunks per slot, but no chunk below 2,000 rows or above 100,000.
    assert chunk_rows(10**6, 2) == 100_000
    assert chunk_rows(10**6, 64) == 3_907
    assert chunk_rows(1_000, 2) == 2_000
    assert chunk_rows(500, 2, chunk_size=64) == 64
    with pytest.raises(softrod.InputError, match="chunk_size"):
        chunk_rows(500, 2, chunk_size=0)


def test_bad_executor_is_rejected(design):
    with pytest.raises(softrod.InputError, match="executor"):
        solve_statics_batch(design, grid(2), executor="tcp://localhost:8786")
    with pytest.raises(softrod.InputError, match="applies with executor= only"):
        solve_statics_batch(design, grid(2), chunk_size=10)


def test_sweep_command_with_scheduler(client, run, tmp_path, monkeypatch):
    import pandas as pd
    import softrod.cluster

    args = ("sweep", SPA, "--grid", "0:70kPa:5", "--threads", "1")
    local = run(*args, "--out", tmp_path / "local.csv")
    remote = run(*args, "--out", tmp_path / "remote.csv", "--scheduler", client.scheduler.address)
    assert local.exit_code == 0 and remote.exit_code == 0, remote.output
    assert "on the Dask cluster" in remote.output
    # 125 rows: one chunk, one thread, as in process: the same table to the last digit.
    pd.testing.assert_frame_equal(
        pd.read_csv(tmp_path / "remote.csv"), pd.read_csv(tmp_path / "local.csv")
    )
    monkeypatch.setattr(softrod.cluster, "CONNECT_TIMEOUT", "1s")  # nothing listens there
    bad = run(*args, "--out", tmp_path / "x.csv", "--scheduler", "tcp://127.0.0.1:9")
    assert bad.exit_code == 2 and "--scheduler" in bad.stderr


def test_system_calibration_restarts_on_the_cluster(client):
    """calibrate_system's starts as cluster tasks (the system's rods travel as TOML text):
    the same fits as in process."""
    from softrod.calibration.system import calibrated_system, parse_system_parameters

    pcr = softrod.load_system("two_spa_platform")
    params = parse_system_parameters(["E", "platform_mass"], pcr)
    truth = calibrated_system(pcr, params, [95e3, 0.025])
    p = np.array(
        [[[20e3, 0, 0], [0, 0, 0]], [[0, 15e3, 0], [0, 0, 25e3]], [[0, 0, 0], [10e3, 0, 0]]]
    )
    data = softrod.synthesize_system_dataset(truth, p, markers=[("platform", [0.02, 0, 0])])
    kw = dict(restarts=2, seed=3, threads=1, progress=False)
    remote = softrod.calibrate_system(pcr, data, ["E", "platform_mass"], executor=client, **kw)
    local = softrod.calibrate_system(pcr, data, ["E", "platform_mass"], **kw)
    np.testing.assert_array_equal(remote.values, local.values)
    assert remote.starts.equals(local.starts) and len(remote.starts) == 3
    np.testing.assert_allclose(remote.values, [95e3, 0.025], rtol=1e-6)  # noise-free
