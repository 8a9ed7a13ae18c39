"""The corpus of issue 13: every defect a hostile user found, kept as a regression test.

Each case runs in a worker subprocess with a time and a memory limit (tests/fuzzing.py), so
a regression that aborts, hangs or eats memory fails its test instead of the test run. The
Rust core's statics now checks results before returning them and solves batch rows exactly
as single solves (those cases pass); defects still open elsewhere are marked
``xfail(strict=True)``: once fixed they pass, strict xfail turns that into a failure, and the
mark goes.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import softrod
from conftest import with_entries
from fuzzing import CliArgs, Pool

SPA = "spa_three_chamber_130mm"
BODY = "sections[1]"
QUICK_S = 2.0  # a refusal is instant: well under this, even on a loaded 2-core machine


def _doc(entries):
    return with_entries(SPA, entries)


def _without_orientation():
    doc = _doc({})
    del doc["mounting"]["orientation"]
    return doc


CSV_OK = "p0_kPa,p1_kPa,p2_kPa,tip_x_mm,tip_y_mm,tip_z_mm\n0,0,0,0,0,-130\n10,0,0,1,0,-130\n"
ACCEPTED = ("ok", None)

# (id, case, expected kind, a fragment the error must hold (its field, line, ...))
CASES = [
    # --- process abort and panics: absurd channel numbers (valid TOML integers) --------------
    *(
        (
            f"channel-{c}",
            ("design", _doc({f"{BODY}.chambers[0].channel": c})),
            "error",
            f"{BODY}.chambers[0].channel",
        )
        for c in (10**12, 2**63 - 1, 2**64 - 1)
    ),
    # --- hangs and memory exhaustion -------------------------------------------------------------
    (
        "pint-expression-design",
        ("design", _doc({f"{BODY}.length": "10**10**10 mm"})),
        "error",
        f"{BODY}.length",
    ),
    (
        "pint-expression-pressure",
        ("statics", {"design": SPA, "pressures": ["10**10**10 Pa", 0, 0]}),
        "error",
        "pressures[0]",
    ),
    (
        "pint-expression-cli-pressure",
        ("cli", CliArgs(["solve", SPA, "--pressure", "10**10**10 Pa,0,0"])),
        "error",
        "--pressure",
    ),
    (
        "pint-expression-cli-grid",
        ("cli", CliArgs(["sweep", SPA, "--grid", "0:10**10**10 kPa:3", "--out", "o.csv"])),
        "error",
        "--grid",
    ),
    (
        "pint-expression-dataset-header",
        ("dataset_file", {"data": CSV_OK.replace("p0_kPa", "p0_10**10**10kPa").encode()}),
        "error",
        "p0_10**10**10kPa",
    ),
    (
        "huge-channel-dataset-header",
        ("dataset_file", {"data": CSV_OK.replace("p2_kPa", "p99999999999999999999_kPa").encode()}),
        "error",
        "p99999999999999999999_kPa",
    ),
    (
        "huge-channel-calibrate",
        (
            "cli",
            CliArgs(
                ["calibrate", SPA, "d.csv", "--params", "c_b"],
                {"d.csv": CSV_OK.replace("p2_kPa", "p99999999999999999999_kPa").encode()},
            ),
        ),
        "error",
        "p99999999999999999999_kPa",
    ),
    (
        "threads-100000",
        ("batch", {"design": SPA, "pressures": np.zeros((2, 3)), "kwargs": {"threads": 100000}}),
        "error",
        "threads",
    ),
    (
        "threads-100000-cli",
        (
            "cli",
            CliArgs(["sweep", SPA, "--grid", "0:1kPa:2", "--out", "o.csv", "--threads", "100000"]),
        ),
        "error",
        "--threads",
    ),
    (
        "dt-1e-9",
        ("simulate", {"design": SPA, "schedule": [0, 0, 0], "t_end": 1.0, "kwargs": {"dt": 1e-9}}),
        "error",
        "t_end",
    ),
    (
        "t_end-1e9",
        ("simulate", {"design": SPA, "schedule": [0, 0, 0], "t_end": 1e9}),
        "error",
        "t_end",
    ),
    # --- silently wrong values -------------------------------------------------------------------
    (
        "deg-as-pressure",
        ("statics", {"design": SPA, "pressures": ["30 deg", 0, 0]}),
        "error",
        "pressures[0]",
    ),
    ("deg-as-length", ("design", _doc({f"{BODY}.length": "30 deg"})), "error", f"{BODY}.length"),
    ("percent-as-length", ("design", _doc({f"{BODY}.length": "5 %"})), "error", f"{BODY}.length"),
    (
        "mm-per-m-as-length",
        ("design", _doc({f"{BODY}.length": "5 mm/m"})),
        "error",
        f"{BODY}.length",
    ),
    ("percent-as-mass", ("design", _doc({"tip.mass": "0.5 %"})), "error", "tip.mass"),
    ("bare-number-length", ("design", _doc({f"{BODY}.length": 90})), "error", 'units = "SI"'),
    (
        "dict-of-pressures",
        ("statics", {"design": SPA, "pressures": {0: 3e4, 1: 0.0, 2: 0.0}}),
        "error",
        "pressures",
    ),
    (
        "complex-pressures",
        ("statics", {"design": SPA, "pressures": [3e4 + 1j, 0, 0]}),
        "error",
        "pressures[0]",
    ),
    (
        "complex-batch",
        ("batch", {"design": SPA, "pressures": np.ones((2, 3), dtype=complex)}),
        "error",
        "complex",
    ),
    (
        "masked-row-batch",
        (
            "batch",
            {
                "design": SPA,
                "pressures": np.ma.masked_array(np.zeros((2, 3)), mask=[[1, 0, 0], [0, 0, 0]]),
            },
        ),
        "error",
        "masked",
    ),
    (
        "bools-batch",
        ("batch", {"design": SPA, "pressures": np.ones((2, 3), dtype=bool)}),
        "error",
        "booleans",
    ),
    (
        "numpy-scalars-batch",
        ("batch", {"design": SPA, "pressures": [[np.float32(1e3), np.int64(0), 0.0]]}),
        *ACCEPTED,
    ),
    (
        "numpy-scalars-single",
        ("statics", {"design": SPA, "pressures": [np.float32(1e3), np.int64(0), 0.0]}),
        *ACCEPTED,
    ),
    (
        "timestamp-column",
        (
            "dataset_frame",
            {
                "frame": pd.DataFrame(
                    {
                        "p0_kPa": pd.to_datetime(["2020-01-01"]),
                        "p1_kPa": [0.0],
                        "p2_kPa": [0.0],
                        "tip_x_mm": [0.0],
                        "tip_y_mm": [0.0],
                        "tip_z_mm": [-130.0],
                    }
                )
            },
        ),
        "error",
        "p0_kPa",
    ),
    ("missing-orientation", ("design", _without_orientation()), "error", "mounting.orientation"),
    (
        "max_iter-1.5",
        ("api", {"function": "SolverOptions", "kwargs": {"max_iter": 1.5}}),
        "error",
        "max_iter",
    ),
    # --- raw Python exceptions -------------------------------------------------------------------
    ("huge-int-mass", ("design", _doc({"tip.mass": 10**400})), "error", "tip.mass"),
    ("huge-radius", ("design", _doc({f"{BODY}.outer_radius": "1e300 mm"})), "error", None),
    # pi r^2 overflowed (an OverflowError from Python's **) before the area was checked
    (
        "huge-chamber-radius",
        ("design", _doc({f"{BODY}.chambers[0].radius": "1e200 m"})),
        "error",
        f"{BODY}.chambers[0].radius",
    ),
    # R^T R of a huge matrix and the norm of a huge rotation vector overflowed with numpy
    # warnings before the rule refused them
    *(
        (
            f"huge-tip-orientation-{kind}",
            (
                "statics",
                {
                    "design": SPA,
                    "pressures": [0, 0, 0],
                    "kwargs": {
                        "tip_constraint": {
                            "type": "clamped",
                            "position": [0, 0, -0.13],
                            "orientation": orientation,
                        }
                    },
                },
            ),
            "error",
            "tip_constraint.orientation",
        )
        for kind, orientation in (
            ("vector", [1e300, 0, 0]),
            ("matrix", [[1e300, 0, 0], [0, 1, 0], [0, 0, 1]]),
        )
    ),
    (
        "orientation-list",
        ("design", _doc({"mounting.orientation": ["hanging"]})),
        "error",
        "mounting.orientation",
    ),
    (
        "simulate-save_every-huge",
        (
            "simulate",
            {
                "design": SPA,
                "schedule": [0, 0, 0],
                "t_end": "20 ms",
                "kwargs": {"save_every": 2**70},
            },
        ),
        "error",
        "save_every",
    ),
    (
        "simulate-shapes-huge",
        (
            "simulate",
            {"design": SPA, "schedule": [0, 0, 0], "t_end": "20 ms", "kwargs": {"shapes": [1e300]}},
        ),
        "error",
        "after the run's end",
    ),
    (
        "simulate-pressures-short",
        ("simulate", {"design": SPA, "schedule": [0, 0], "t_end": "20 ms"}),
        "error",
        None,
    ),
    (
        "binary-dataset",
        ("dataset_file", {"data": b"\x89PNG\r\n\x1a\n\x00\x00\xff"}),
        "error",
        "file",
    ),
    ("utf16-dataset", ("dataset_file", {"data": CSV_OK.encode("utf-16")}), "error", "UTF-16"),
    # Found by a --fuzz-long run: an integer of 401 digits in a cell (pandas overflowed).
    (
        "schedule-huge-int-cell",
        (
            "dataset_file",
            {
                "reader": "schedule",
                "suffix": ".csv",
                "data": f"time_s,p0_kPa,p1_kPa\n0,0,0\n1,1{'0' * 400},0\n".encode(),
            },
        ),
        "error",
        "p0_kPa",
    ),
    (
        "dataset-huge-int-cell",
        ("dataset_file", {"data": CSV_OK.replace("10,0,0,1", f"1{'0' * 400},0,0,1").encode()}),
        "error",
        "p0_kPa",
    ),
    (
        "nested-metadata",
        (
            "dataset_file",
            {"data": ("# metadata: " + "[" * 5000 + "]" * 5000 + "\n" + CSV_OK).encode()},
        ),
        "error",
        "metadata",
    ),
    (
        "calibrate-binary-data",
        (
            "cli",
            CliArgs(["calibrate", SPA, "d.csv", "--params", "c_b"], {"d.csv": b"\xff\xfe\x00"}),
        ),
        "error",
        "d.csv",
    ),
    (
        "simulate-input-binary",
        (
            "cli",
            CliArgs(["simulate", SPA, "--input", "s.csv", "--out", "t.npz"], {"s.csv": b"\xff"}),
        ),
        "error",
        "s.csv",
    ),
    (
        "sweep-bare-grid",
        ("cli", CliArgs(["sweep", SPA, "--grid", "0:70000:3", "--out", "o.csv"])),
        "error",
        "--grid",
    ),
    # --- errors that say where -------------------------------------------------------------------
    (
        "json-type-steps",
        ("design", _doc({"numerics.steps_per_section": 2**64})),
        "error",
        "numerics.steps_per_section",
    ),
    (
        "json-type-partition",
        ("design", with_entries("modular_two_module", {"sections[1].partition.j": 1.5})),
        "error",
        "sections[1].partition.j",
    ),
    (
        "inline-material-E",
        ("design", _doc({"materials.ecoflex_00_50_table1.E": "0 kPa"})),
        "error",
        "materials.ecoflex_00_50_table1.E",
    ),
    (
        "calibrate-names-the-line",
        (
            "cli",
            CliArgs(
                ["calibrate", SPA, "d.csv", "--params", "c_b"],
                {"d.csv": ("# data\n" + CSV_OK.replace("10,0,0", "-200,0,0")).encode()},
            ),
        ),
        "error",
        "line 4",
    ),
    (
        "missing-target-folder",
        ("cli", CliArgs(["sweep", SPA, "--grid", "0:1kPa:2", "--out", "nowhere/o.csv"])),
        "error",
        "nowhere/o.csv",
    ),
]

LONG_NAME = "9" * 400 + " mm"  # 403 bytes: beyond the file system's 255 per name

# compare_models of a frictional design (the fuzz suite's friction target): values that
# raised AttributeError or TypeError deep inside, now named before any solve.
_COMPARE = {"design": "spa_wall", "call": "compare"}
_COMPARE_ARGS = {"experiments": "i-0", "pressures": [0.0], "progress": False}
CASES += [
    (
        "compare-options-not-solver-options",
        ("friction", {**_COMPARE, "options": 2, "kwargs": _COMPARE_ARGS}),
        "error",
        "options = 2",
    ),
    (
        "compare-experiments-a-number",
        ("friction", {**_COMPARE, "kwargs": {**_COMPARE_ARGS, "experiments": 3}}),
        "error",
        "experiments = 3",
    ),
    (
        "compare-pressures-text",
        ("friction", {**_COMPARE, "kwargs": {**_COMPARE_ARGS, "pressures": "abc"}}),
        "error",
        "pressures = 'abc'",
    ),
    (
        # found through the viewer's trajectory= (TypeError from pathlib)
        "trajectory-load-not-a-path",
        ("api", {"function": "Trajectory.load", "args": ({},)}),
        "error",
        "path = 'dict'",
    ),
    # A file name too long for the file system: pathlib's exists()/is_file() raised OSError
    # (ENAMETOOLONG) out of every reader; now "no such file" naming the path (found through
    # the viewer's dataset=).
    *(
        (
            f"name-too-long-{fn}",
            ("api", {"function": fn, "args": (LONG_NAME + suffix,)}),
            "error",
            "no such file",
        )
        for fn, suffix in (
            ("load_dataset", ""),
            ("load_dataset", ".csv"),
            ("load_design", ""),
            ("load_system", ""),
            ("Trajectory.load", ".npz"),
            ("StiffnessMap.from_csv", ".csv"),
            ("PressureSchedule.from_file", ".csv"),
            ("HybridStiffnessModel.load", ".json"),
        )
    ),
    (
        "compare-pressures-with-units",
        ("friction", {**_COMPARE, "kwargs": {**_COMPARE_ARGS, "pressures": ["0 kPa", "30 kPa"]}}),
        "ok",
        None,
    ),
]

# softrod.view and Viewer.set_inputs (the fuzz suite's viewer target): values that raised
# ValueError, TypeError or OverflowError from numpy, or were taken silently (a bool as 1 N).
VIEWER_CASES = [
    (
        "viewer-scalar-pressure-move",
        ("viewer", {"design": SPA, "moves": [{"pressures": 1.5}]}),
        "error",
        "pressures",
    ),
    (
        "viewer-text-tensions",
        ("viewer", {"design": "till_tendon_robot", "kwargs": {"tensions": "obstacles"}}),
        "error",
        "tensions",
    ),
    (
        "viewer-complex-tip-force",
        ("viewer", {"design": SPA, "moves": [{"tip_force": [1j, 0, 0]}]}),
        "error",
        "tip_force",
    ),
    (
        "viewer-huge-integer-tension",
        ("viewer", {"design": "till_tendon_robot", "moves": [{"tensions": [10**400, 0, 0, 0]}]}),
        "error",
        "tensions[0]",
    ),
    (
        "viewer-nested-pressures",
        ("viewer", {"design": SPA, "kwargs": {"pressures": [[1], 0, 0]}}),
        "error",
        "pressures",
    ),
    (
        "viewer-bool-tension-max",
        ("viewer", {"design": "till_tendon_robot", "kwargs": {"tension_max": True}}),
        "error",
        "tension_max",
    ),
    (
        "viewer-options-not-solver-options",
        ("viewer", {"design": SPA, "kwargs": {"options": 5}}),
        "error",
        "options = 5",
    ),
    (
        "viewer-trajectory-not-a-path",
        ("viewer", {"design": SPA, "kwargs": {"trajectory": [1.5]}}),
        "error",
        "path = 'list'",
    ),
    (
        "viewer-quantities-with-units",
        (
            "viewer",
            {
                "design": SPA,
                "kwargs": {"pressures": ["10 kPa", 0, 0], "pressure_range": ["0 kPa", "70 kPa"]},
                "moves": [{"tip_force": ["0 N", "10 mN", "0 N"]}],
            },
        ),
        "ok",
        None,
    ),
]

RUST_CASES = [
    # rotations that are not rotations, returned as converged (coarse steps, long module)
    (
        "rotation-coarse-steps",
        (
            "statics",
            {
                "design": "pam_arm_220mm",
                "pressures": [1e6, 0, 0],
                "changes": {"numerics": {"steps_per_section": 4}},
                "kwargs": {"options": "<default solver options>"},
            },
        ),
    ),
    # the rod turned inside out (v3 < 0) under a compressive tip force
    (
        "negative-stretch",
        (
            "statics",
            {
                "design": SPA,
                "pressures": [0, 0, 0],
                "kwargs": {"tip_force": [0.0, 0.0, 100.0], "options": "<default solver options>"},
            },
        ),
    ),
]


def test_dynamic_rotations_stay_rotations(pool):
    # A ramp to 10 MPa in 50 ms: the tip rotation came back with det 0.736.
    ramp = softrod.PressureSchedule.piecewise_linear([0, 0.05], [[0, 0, 0], [1e7, 0, 0]])
    case = (
        "simulate",
        {
            "design": "pam_arm_220mm",
            "schedule": ramp,
            "t_end": 0.1,
            "kwargs": {"dt": 5e-3, "progress": False},
        },
    )
    (out,) = pool.run([case])
    assert out.kind in ("ok", "error"), out


@pytest.fixture(scope="module")
def pool():
    with Pool(2) as p:
        yield p


@pytest.mark.parametrize(
    ("case", "kind", "fragment"), [c[1:] for c in CASES], ids=[c[0] for c in CASES]
)
def test_regression(pool, case, kind, fragment):
    (out,) = pool.run([case])
    assert out.kind == kind, (out, case)
    if fragment is not None:
        assert fragment in out.detail, out.detail
    if kind == "error":
        assert out.seconds < QUICK_S, f"a refusal took {out.seconds:.2f} s"


@pytest.mark.parametrize(
    ("case", "kind", "fragment"), [c[1:] for c in VIEWER_CASES], ids=[c[0] for c in VIEWER_CASES]
)
def test_viewer_regression(pool, case, kind, fragment):
    pytest.importorskip("viser", reason="needs the viewer extra (viser)")
    test_regression(pool, case, kind, fragment)


@pytest.mark.parametrize("case", [c[1] for c in RUST_CASES], ids=[c[0] for c in RUST_CASES])
def test_rust_result_checks(pool, case):
    (out,) = pool.run([case])
    assert out.kind in ("ok", "error"), out  # a clean refusal (InvalidStateError) or valid


def test_far_beyond_any_actuator_is_not_converged():
    # 1 GPa on a silicone module "converged" with the tip 60 lengths from the base.
    with pytest.raises(softrod.ConvergenceError):
        softrod.solve_statics("modular_two_module", [1e9, 0, 0])


def test_batch_rows_equal_single_solves():
    d = softrod.load_design(SPA)
    p = np.random.default_rng(0).uniform(0, 7e4, (200, 3))
    batch = softrod.solve_statics_batch(d, p)
    single = np.array([softrod.solve_statics(d, row).tip_position for row in p])
    # every row is solved cold, exactly as the single solve: bitwise equal
    assert np.array_equal(batch.tip_position, single)


def test_batch_does_not_depend_on_threads():
    d = softrod.load_design(SPA)
    p = np.random.default_rng(1).uniform(0, 7e4, (200, 3))
    one = softrod.solve_statics_batch(d, p, threads=1).tip_position
    two = softrod.solve_statics_batch(d, p, threads=2).tip_position
    assert np.array_equal(one, two)


# --- files: whole or not at all -----------------------------------------------------------------

WRITER = textwrap.dedent(
    """
    import sys, numpy as np, pandas as pd
    from softrod.io import write_table
    frame = pd.DataFrame(np.random.default_rng(0).normal(size=(3_000_000, 4)), columns=list("abcd"))
    print("writing", flush=True)
    write_table(frame, sys.argv[1])
    """
)


def test_killed_writer_leaves_target_and_next_write_cleans_up(tmp_path):
    target = tmp_path / "table.csv"
    target.write_text("old,content\n1,2\n")
    proc = subprocess.Popen(
        [sys.executable, "-c", WRITER, str(target)], stdout=subprocess.PIPE, text=True
    )
    assert proc.stdout.readline().strip() == "writing"
    # Kill it while the temporary grows (a 3e6-row CSV takes seconds to write).
    deadline = time.monotonic() + 30
    while not list(tmp_path.glob(".softrod-tmp-*")) or _size(tmp_path) < 1 << 20:
        assert time.monotonic() < deadline and proc.poll() is None, "the writer never started"
        time.sleep(0.02)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    proc.stdout.close()
    assert target.read_text() == "old,content\n1,2\n"  # untouched
    stale = list(tmp_path.glob(".softrod-tmp-*"))
    assert len(stale) == 1  # named so that the next write recognises it
    softrod.io.write_table(pd.DataFrame({"x": [1.0]}), tmp_path / "other.csv")
    assert not stale[0].exists()
    assert target.read_text() == "old,content\n1,2\n"


def _size(folder: Path) -> int:
    return sum(p.stat().st_size for p in folder.glob(".softrod-tmp-*") if p.exists())


def test_live_writers_temporaries_are_kept(tmp_path):
    mine = tmp_path / f".softrod-tmp-{os.getpid()}-0123abcd-x.csv"
    mine.write_text("in progress")
    softrod.io.write_table(pd.DataFrame({"x": [1.0]}), tmp_path / "y.csv")
    assert mine.exists()  # this process still runs: its temporary is not stale


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_folder_is_named_before_the_work(tmp_path, run):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o500)
    try:
        result = run("sweep", SPA, "--grid", "0:70kPa:3", "--out", folder / "o.csv")
    finally:
        folder.chmod(0o700)
    assert result.exit_code == 2
    assert str(folder / "o.csv") in result.stderr and "not writable" in result.stderr
    assert "rows" not in result.stdout  # refused before the sweep started


def test_failed_write_leaves_no_temporary(tmp_path):
    class Broken:  # a frame whose writing fails half-way
        attrs: dict = {}

        def to_csv(self, fh, **kwargs):
            fh.write("half")
            raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        softrod.io.write_table(Broken(), tmp_path / "t.csv")
    assert list(tmp_path.iterdir()) == []


def _random_networks(seed: int, hidden=(12, 10)):
    """Three tanh networks of fixed random weights on three pressure channels."""
    rng = np.random.default_rng(seed)
    nets = []
    for _ in range(3):
        sizes = [3, *hidden, 1]
        nets.append(
            {
                "input_mean": [2e4, 2e4, 2e4],
                "input_scale": [2e4, 2e4, 2e4],
                "weights": [
                    rng.normal(size=(a, b)) for a, b in zip(sizes[:-1], sizes[1:], strict=True)
                ],
                "biases": [rng.normal(size=b) for b in sizes[1:]],
                "activation": "tanh",
                "target_mean": 0.0,
                "target_scale": 0.1,
            }
        )
    return nets


def test_network_map_batch_rows_are_the_single_solves():
    """A network stiffness map (the hybrid model's) evaluated on all rows of a batch at
    once gave a row other last bits of sigma than the single solve's evaluation of that row
    (one matrix product of all rows, which BLAS rounds differently with the row count), so
    solve_statics_batch's and compare_hybrid's rows were not the single solves bitwise. The
    map's forward pass now sums its products in one fixed order, row by row, so all rows
    at once are each row alone, bit for bit, and the batch evaluates the map in one call."""
    from softrod.calibration.per_sample import stiffness_mapped_design

    nets = _random_networks(0)
    smap = softrod.StiffnessMap.from_networks(nets)
    p = np.random.default_rng(1).uniform(0.0, 7e4, size=(64, 3))
    # Not vacuous: a BLAS product of the hidden layer over all rows rounds some row
    # differently from that row alone (the hazard), while the map's rows are their own.
    x = np.tanh(np.random.default_rng(2).normal(size=(len(p), 12)))
    w = np.asarray(nets[0]["weights"][1])
    blas = x @ w
    assert any(not np.array_equal(blas[k], (x[k : k + 1] @ w)[0]) for k in range(len(p)))
    whole = smap(p)
    for k in range(len(p)):
        np.testing.assert_array_equal(whole[k], smap(p[k : k + 1])[0])
    design, _ = stiffness_mapped_design(SPA)  # the chambered body scaled by the map
    batch = softrod.solve_statics_batch(design, p, stiffness_map=smap, threads=2)
    for k, row in enumerate(p):
        single = softrod.solve_statics(design, row, stiffness_map=smap)
        np.testing.assert_array_equal(batch.stiffness_scale[k], single.stiffness_scale)
        np.testing.assert_array_equal(batch.tip_position[k], single.tip_position)
