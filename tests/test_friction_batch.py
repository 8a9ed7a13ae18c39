"""Batches with Coulomb friction (docs/contact.md, "Friction in the statics"):
``solve_statics_batch`` of a design whose obstacle has friction > 0 solves every row as its
own load path from the unloaded rod, bitwise equal to ``solve_statics`` of that row (same
``friction_steps``, same halvings) for 1, 2 and 4 threads, contact and friction forces
included; failed rows kept as in any batch; a frictionless batch unchanged;
``friction_steps`` reaching the batch (API, ``softrod sweep --friction-steps``); what is
refused by name; and a hypothesis property (any rows, any thread count: batch == single).
The core's own checks are in crates/softrod-core/tests/suite/friction_batch.rs."""

from __future__ import annotations

import numpy as np
import pytest
import softrod
from friction_designs import FINGER, MU
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from softrod import (
    InputError,
    SolverOptions,
    TipConstraint,
    load_design,
    solve_statics,
    solve_statics_batch,
)

pytestmark = pytest.mark.fast

#: Few increments keep the tests short; the increment count changes the answer (first
#: order), never whether batch and single agree.
STEPS = SolverOptions(friction_steps=20)
#: Pressures (Pa) and tendon tensions (N): off the table, landing, pressed, pressed harder,
#: pressed and pulled back by the tendon.
P = [[0.0], [15e3], [25e3], [35e3], [45e3], [35e3]]
T = [[0.0], [0.0], [0.0], [0.0], [0.0], [0.05]]
FIELDS = ("tip_position", "tip_rotation", "base_force", "base_moment")


@pytest.fixture(scope="module")
def singles(rough):
    return [solve_statics(rough, p, tensions=t, options=STEPS) for p, t in zip(P, T, strict=True)]


def assert_row_is_single(batch, k, s):
    """Row k of ``batch`` bitwise equal to the single solve ``s``."""
    assert batch.converged[k] and s.converged
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(batch, name)[k], getattr(s, name), err_msg=name)
    assert batch.iterations[k] == s.iterations
    assert batch.residual[k] == s.residual
    np.testing.assert_array_equal(batch.x[k], s.shooting_unknowns)
    np.testing.assert_array_equal(batch.contact_force[k], s.contact.total_force)
    np.testing.assert_array_equal(batch.friction_force[k], s.contact.friction_force)
    # Friction has no potential: not assessed, as the single solve's stable None.
    assert s.stable is None and not batch.stability_assessed[k] and not batch.stable[k]


def test_friction_batch_equals_single_solves_bitwise(rough, singles):
    for threads in (1, 2, 4):
        batch = solve_statics_batch(rough, P, tensions=T, options=STEPS, threads=threads)
        assert batch.x.shape == (len(P), 6)
        assert batch.contact_force.shape == batch.friction_force.shape == (len(P), 1, 3)
        for k, s in enumerate(singles):
            assert_row_is_single(batch, k, s)
    # Not vacuous: the lifted finger touches nothing and the pressed rows carry friction
    # (tens of mN; 0.1 mN is far above the solver's resolution of it).
    assert np.all(batch.contact_force[0] == 0.0)
    assert (np.abs(batch.friction_force[:, 0, 0]) > 1e-4).sum() >= 3
    assert batch.metadata["solver"]["friction_steps"] == 20


def test_held_friction_batch_equals_single_held_solves_bitwise(finger, rough):
    """A clamped tip: every row its own path with the clamp moved from the unloaded rod's
    tip to its pose, bitwise the single held frictional solve, tip reactions included."""
    rest = solve_statics(finger, [35e3])
    clamp = TipConstraint.clamped(rest.tip_position, rest.tip_rotation)
    rows = P[1:5]
    singles = [solve_statics(rough, p, tip_constraint=clamp, options=STEPS) for p in rows]
    for threads in (1, 2):
        batch = solve_statics_batch(
            rough, rows, tip_constraint=clamp, options=STEPS, threads=threads
        )
        assert batch.tip_constraint == "clamped" and batch.x.shape == (len(rows), 6)
        for k, s in enumerate(singles):
            assert_row_is_single(batch, k, s)
            np.testing.assert_array_equal(batch.tip_reaction_force[k], s.tip_reaction_force)
            np.testing.assert_array_equal(batch.tip_reaction_moment[k], s.tip_reaction_moment)
    # Not vacuous: the clamp takes up friction and contact (tens of mN) on the pressed rows.
    assert (np.abs(batch.friction_force[:, 0, 0]) > 1e-4).sum() >= 2
    assert (np.linalg.norm(batch.tip_reaction_force, axis=1) > 1e-3).all()


def test_friction_steps_reach_the_batch(rough, singles):
    """Another increment count is another path: the default's rows differ from 20's, and
    equal the default single solve."""
    batch = solve_statics_batch(rough, P[3:4], threads=1)
    np.testing.assert_array_equal(batch.tip_position[0], solve_statics(rough, P[3]).tip_position)
    assert not np.array_equal(batch.tip_position[0], singles[3].tip_position)


def test_failed_friction_rows_are_kept_as_in_any_batch(rough):
    """One Newton iteration per increment cannot follow the pressed rows: they come back
    converged False with NaN (forces too), the row off the table converges, and each is
    what solve_statics(check=False) says of that row."""
    opts = SolverOptions(friction_steps=20, max_iter=1)
    batch = solve_statics_batch(rough, P, tensions=T, options=opts, threads=2)
    assert not batch.converged.all() and batch.converged.any()
    for k, (p, t) in enumerate(zip(P, T, strict=True)):
        s = solve_statics(rough, p, tensions=t, options=opts, check=False)
        assert batch.converged[k] == s.converged
        if not s.converged:
            assert np.isnan(batch.tip_position[k]).all()
            assert np.isnan(batch.contact_force[k]).all()
            assert np.isnan(batch.friction_force[k]).all()
            assert batch.iterations[k] == s.iterations
        else:
            assert_row_is_single(batch, k, s)


def test_stiffness_map_rows_are_carried(rough):
    """A mapped section's sigma is evaluated per row and reaches each row's path: the
    batch row equals solve_statics with the same map, and a finger stiffer in its bending
    plane (sigma_bend_y 2: the finger bends about d2) presses otherwise than sigma 1."""
    from softrod import StiffnessMap

    mapped = rough.replace({"sections[0].law": {"stiffness_map": True}})
    smap = StiffnessMap.from_callable(
        lambda p: np.column_stack([np.ones(len(p)), np.ones(len(p)), 1.0 + p[:, 0] / 35e3]), 1
    )
    batch = solve_statics_batch(mapped, P[2:4], stiffness_map=smap, options=STEPS, threads=2)
    np.testing.assert_array_equal(batch.stiffness_scale[:, 2], [1.0 + 25e3 / 35e3, 2.0])
    for k, p in enumerate(P[2:4]):
        s = solve_statics(mapped, p, stiffness_map=smap, options=STEPS)
        assert_row_is_single(batch, k, s)
    ones = StiffnessMap.constant((1.0, 1.0, 1.0), 1)
    soft = solve_statics_batch(mapped, P[3:4], stiffness_map=ones, options=STEPS, threads=1)
    assert not np.array_equal(soft.friction_force[0], batch.friction_force[1])


def test_frictionless_batch_is_unchanged(finger):
    """mu = 0: the frictionless batch as before (rows equal to the single solves,
    stability assessed), without contact columns, and friction_steps has no effect."""
    a = solve_statics_batch(finger, P, tensions=T, threads=2)
    b = solve_statics_batch(finger, P, tensions=T, threads=2, options=STEPS)
    assert a.contact_force is None and a.friction_force is None
    for name in (*FIELDS, "iterations", "residual", "x", "stable", "stability_assessed"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert "friction_steps" not in a.metadata["solver"]
    for k, (p, t) in enumerate(zip(P, T, strict=True)):
        s = solve_statics(finger, p, tensions=t, on_unstable="ignore")
        np.testing.assert_array_equal(a.tip_position[k], s.tip_position)
        assert a.stability_assessed[k]


def test_to_frame_has_the_contact_and_friction_columns(rough):
    batch = solve_statics_batch(rough, P[2:4], options=STEPS, threads=1)
    frame = batch.to_frame()
    np.testing.assert_array_equal(
        frame[[f"friction0_f{a}_N" for a in "xyz"]].to_numpy(), batch.friction_force[:, 0]
    )
    np.testing.assert_array_equal(
        frame[[f"contact0_f{a}_N" for a in "xyz"]].to_numpy(), batch.contact_force[:, 0]
    )
    # Friction has no potential: no verdict on stability, so the table's cell is empty
    # (a False would read as "unstable"), and the metadata says what empty means.
    assert not batch.stability_assessed.any()
    assert frame["stable"].isna().all()
    assert "empty: not assessed" in frame.attrs["softrod.metadata"]["columns"]["stable"]


def test_friction_batch_refuses_bad_input_by_name(rough, monkeypatch):
    for bad in (0, -1, 100_001, 2.5, "80", True, None):
        with pytest.raises(InputError, match="friction_steps"):
            solve_statics_batch(rough, P, options=SolverOptions(friction_steps=bad))
    # Warm starts have no place on a path: the core's batch with guesses (x0, as the
    # calibrations pass them) refuses a frictional design by name, and so do the
    # parameter sensitivities without them.
    p = np.array(P)
    for x0 in (np.zeros((len(P), 6)), None):
        with pytest.raises(InputError, match=r"obstacles\[0\]\.friction"):
            rough._rod.sensitivity_batch(p, [0.0] * 3, [0.0] * 3, [], x0=x0)
    # Malformed rows keep their own refusals.
    with pytest.raises(InputError, match=r"tensions"):
        solve_statics_batch(rough, P, tensions=T[:2], options=STEPS)
    with pytest.raises(InputError, match=r"pressures\[1\]"):
        solve_statics_batch(rough, [[0.0], [-2e5]], options=STEPS)
    # Markers come from the frictionless sensitivity solve: refused before any row is solved
    # (a million rows would otherwise run their frictional paths first).
    import softrod.synthetic

    calls = []
    real = softrod.synthetic.solve_statics_batch
    monkeypatch.setattr(
        softrod.synthetic, "solve_statics_batch", lambda *a, **k: calls.append(1) or real(*a, **k)
    )
    with pytest.raises(InputError, match=r"obstacles\[0\]\.friction.*markers"):
        softrod.synthesize_dataset(rough, P[:2], markers=[0.04])
    assert calls == []


def _rough_file(tmp_path):
    from softrod.design import designs_dir

    text = (designs_dir() / f"{FINGER}.toml").read_text()
    path = tmp_path / "rough_finger.toml"
    path.write_text(text.replace('tolerance = "0.2 mm"', 'tolerance = "0.2 mm"\nfriction = 0.5', 1))
    return path


def test_cli_sweep_of_a_frictional_design(run, tmp_path):
    """softrod sweep --friction-steps N: every row the API batch's with
    SolverOptions(friction_steps=N) (bitwise), the contact and friction columns written,
    no row counted unstable (stability is not assessed with friction); on a frictionless
    design the option is refused by name."""
    import pandas as pd

    path = _rough_file(tmp_path)
    out = tmp_path / "sweep.parquet"
    result = run(
        "sweep",
        path,
        "--grid",
        "20kPa:40kPa:3",
        "--out",
        out,
        "--friction-steps",
        "5",
        "--threads",
        "2",
    )
    assert result.exit_code == 0, result.output
    assert "0 unstable" in result.output
    frame = pd.read_parquet(out)
    api = solve_statics_batch(
        load_design(path), [[20e3], [30e3], [40e3]], options=SolverOptions(friction_steps=5)
    )
    # Against the API batch's own table (the same metres-to-millimetres conversion: the
    # claim is that the rows are bitwise the batch's, not how a scaling rounds).
    cols = ["tip_x_mm", "tip_y_mm", "tip_z_mm"]
    np.testing.assert_array_equal(frame[cols].to_numpy(), api.to_frame()[cols].to_numpy())
    np.testing.assert_allclose(frame[cols].to_numpy(), api.tip_position * 1e3, rtol=1e-15)
    np.testing.assert_array_equal(
        frame[[f"friction0_f{a}_N" for a in "xyz"]].to_numpy(), api.friction_force[:, 0]
    )
    smooth = run("sweep", FINGER, "--grid", "0:20kPa:2", "--out", out, "--friction-steps", "5")
    assert smooth.exit_code != 0 and "--friction-steps" in smooth.output


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    p=st.lists(st.floats(0.0, 50e3), min_size=1, max_size=3),
    threads=st.sampled_from([0, 1, 2, 3]),
    steps=st.integers(1, 20),
)
def test_any_rows_any_threads_friction_batch_equals_single(p, threads, steps):
    rough = load_design(FINGER).replace({"obstacles[0].friction": MU})
    opts = SolverOptions(friction_steps=steps)
    batch = solve_statics_batch(rough, [[x] for x in p], options=opts, threads=threads)
    assert len(batch) == len(p)
    for k, x in enumerate(p):
        try:
            s = solve_statics(rough, [x], options=opts)
        except (softrod.ConvergenceError, softrod.InvalidStateError):
            assert not batch.converged[k]
            assert np.isnan(batch.friction_force[k]).all()
            continue
        assert_row_is_single(batch, k, s)


def test_workspace_of_a_frictional_design_is_its_rows_loaded_from_rest(rough):
    """The control workspace samples its box with the frictional batch: each sample is
    the single frictional solve of its inputs from the unloaded rod, bitwise."""
    ws = softrod.workspace(
        rough,
        pressure_bounds=[[0.0, 45e3]],
        tension_bounds=[[0.0, 0.0]],
        samples=3,
        options=STEPS,
        threads=2,
    )
    assert ws.converged.all()
    for p, t, tip in zip(ws.pressures, ws.tensions, ws.tip_position, strict=True):
        s = solve_statics(rough, p, tensions=t, options=STEPS)
        np.testing.assert_array_equal(tip, s.tip_position)
