"""Batches of held tips and of systems of rods (docs/model.md, "End constraints" and
"Systems of rods"): ``solve_statics_batch(..., tip_constraint=...)`` and
``solve_system_batch`` row by row bitwise equal to ``solve_statics`` / ``solve_system``
(every row is solved cold, as alone), for 1, 2 and 4 threads; failed rows kept with their
status; the stability and validity policies of the free batch; the tip reaction columns of
``to_frame`` and of ``softrod sweep``; bad inputs refused by name before any work; and a
hypothesis property (any rows, any thread count: batch == single)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import softrod
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from softrod import (
    InputError,
    SolverOptions,
    TipConstraint,
    load_design,
    solve_statics,
    solve_statics_batch,
    solve_system,
    solve_system_batch,
)

pytestmark = pytest.mark.fast

SPA = "spa_three_chamber_130mm"
#: paper 001's actuator with coarse steps: fast solves, same physics.
COARSE = {"numerics": {"step_length": "13 mm"}}
#: Hanging, its unloaded tip near (0, 0, -131 mm): pinned or clamped a little aside.
PIN = TipConstraint.pinned(["4 mm", "-2 mm", "-127 mm"])
#: The hanging tip frame (d3 down: Rx(pi)) turned by 5 degrees about y.
TILTED = softrod.constraints.rotation_from_vector([0.0, np.radians(5.0), 0.0]) @ np.diag(
    [1.0, -1.0, -1.0]
)
CLAMP = TipConstraint.clamped(["4 mm", "-2 mm", "-127 mm"], TILTED)
HELD = {"pinned": PIN, "clamped": CLAMP}


@pytest.fixture(scope="module")
def spa():
    return load_design(SPA).replace(COARSE)


def rows() -> np.ndarray:
    g = np.linspace(0.0, 40e3, 3)
    return np.stack(np.meshgrid(g, g, [0.0, 20e3], indexing="ij"), axis=-1).reshape(-1, 3)


def singles(design, pressures, constraint, **kwargs):
    return [
        solve_statics(design, p, tip_constraint=constraint, on_unstable="ignore", **kwargs)
        for p in pressures
    ]


def assert_rows_equal(batch, single, rows=None):
    """Every batch row bitwise equal to its single solve."""
    rows = range(len(single)) if rows is None else rows
    for k, s in zip(rows, single, strict=True):
        np.testing.assert_array_equal(batch.tip_position[k], s.tip_position, err_msg=f"{k}")
        np.testing.assert_array_equal(batch.tip_rotation[k], s.tip_rotation, err_msg=f"{k}")
        np.testing.assert_array_equal(batch.base_force[k], s.force[0], err_msg=f"{k}")
        np.testing.assert_array_equal(batch.base_moment[k], s.moment[0], err_msg=f"{k}")
        np.testing.assert_array_equal(batch.x[k], s.shooting_unknowns, err_msg=f"{k}")
        np.testing.assert_array_equal(
            batch.tip_reaction_force[k], s.tip_reaction_force, err_msg=f"{k}"
        )
        np.testing.assert_array_equal(
            batch.tip_reaction_moment[k], s.tip_reaction_moment, err_msg=f"{k}"
        )
        assert batch.iterations[k] == s.iterations
        assert batch.residual[k] == s.residual
        assert bool(batch.stable[k]) == bool(s.stable)
        assert bool(batch.stability_assessed[k]) == (s.stable is not None)


@pytest.mark.parametrize("kind", ["pinned", "clamped"])
def test_held_batch_equals_single_solves_bitwise(spa, kind):
    """Every row is solved cold exactly as solve_statics solves it alone with the same
    constraint: bitwise equal for 1, 2 and 4 threads and for other groupings of the rows."""
    c = HELD[kind]
    p = rows()
    single = singles(spa, p, c)
    spread = np.ptp([s.tip_reaction_force for s in single], axis=0).max()
    assert spread > 1e-3  # the rows really differ
    for threads in (1, 2, 4):
        batch = solve_statics_batch(spa, p, tip_constraint=c, threads=threads, on_unstable="ignore")
        assert batch.converged.all()
        assert batch.tip_constraint == kind and batch.x.shape == (len(p), 6)
        assert_rows_equal(batch, single)
    part = solve_statics_batch(spa, p[5:], tip_constraint=c, threads=3, on_unstable="ignore")
    assert_rows_equal(part, single[5:])
    # the tip is held where it was told
    np.testing.assert_allclose(
        batch.tip_position, np.tile(c.position, (len(p), 1)), rtol=0, atol=1e-9
    )
    if kind == "pinned":
        assert (batch.tip_reaction_moment == 0).all()


def test_design_file_constraint_is_the_default_and_free_overrides_it(spa):
    held = spa.replace({"tip": {"constraint": "pinned", "position": ["4 mm", "-2 mm", "-127 mm"]}})
    p = rows()[:4]
    batch = solve_statics_batch(held, p, on_unstable="ignore")
    assert batch.tip_constraint == "pinned"
    assert_rows_equal(batch, singles(held, p, None))
    free = solve_statics_batch(held, p, tip_constraint="free")
    assert free.tip_constraint == "free" and free.tip_reaction_force is None
    np.testing.assert_array_equal(
        free.tip_position, [s.tip_position for s in singles(held, p, "free")]
    )


def test_reaction_columns_in_the_table(spa, tmp_path):
    p = rows()[:3]
    batch = solve_statics_batch(spa, p, tip_constraint=CLAMP, on_unstable="ignore")
    frame = batch.to_frame()
    names = [f"tip_reaction_f{a}_N" for a in "xyz"] + [f"tip_reaction_m{a}_Nmm" for a in "xyz"]
    assert all(n in frame.columns for n in names)
    np.testing.assert_array_equal(frame[names[:3]].to_numpy(), batch.tip_reaction_force)
    np.testing.assert_allclose(
        frame[names[3:]].to_numpy(), batch.tip_reaction_moment * 1e3, rtol=1e-15
    )
    meta = frame.attrs["softrod.metadata"]
    assert meta["tip_constraint"]["type"] == "clamped"
    assert all(n in meta["columns"] for n in names)
    # the dataset reader takes the table back (the reactions are declared columns)
    data = softrod.load_dataset(frame)
    np.testing.assert_array_equal(data.pressures, p)
    # a free batch's table has no reaction columns
    free = solve_statics_batch(spa, p).to_frame()
    assert not [c for c in free.columns if c.startswith("tip_reaction")]


def test_failed_rows_are_kept_with_their_status(spa):
    """A tight stretch range: rows whose equilibrium leaves it fail (NaN, the rule in
    ``violation``) and stay in place; the others equal their single solves; with "warn"
    they keep their values and one ValidityWarning says how many."""
    p = np.array([[0.0, 0.0, 0.0], [60e3, 0.0, 0.0], [5e3, 0.0, 0.0], [0.0, 60e3, 60e3]])
    opts = SolverOptions(stretch_range=(0.9, 1.1))
    batch = solve_statics_batch(
        spa, p, tip_constraint=PIN, options=opts, threads=2, on_unstable="ignore"
    )
    ok = batch.converged
    assert ok.any() and not ok.all(), batch.violation
    assert len(batch) == len(p)
    for k in np.flatnonzero(~ok):
        assert np.isnan(batch.tip_reaction_force[k]).all()
        assert np.isnan(batch.x[k]).all()
        assert not batch.stable[k]
        assert "stretch" in batch.violation[k]
        with pytest.raises(softrod.InvalidStateError):
            solve_statics(spa, p[k], tip_constraint=PIN, options=opts)
    ok_rows = np.flatnonzero(ok)
    assert_rows_equal(batch, singles(spa, p[ok_rows], PIN, options=opts), rows=ok_rows)
    with pytest.warns(softrod.ValidityWarning, match="rows lie outside"):
        warned = solve_statics_batch(
            spa, p, tip_constraint=PIN, options=opts, on_invalid="warn", on_unstable="ignore"
        )
    assert warned.converged.all()
    # a pose out of reach: every row fails, every row is kept
    far = TipConstraint.pinned(["0 mm", "0 mm", "-400 mm"])
    out = solve_statics_batch(
        spa, p[:2], tip_constraint=far, options=SolverOptions(max_load_steps=8)
    )
    assert len(out) == 2 and not out.converged.any()
    assert np.isnan(out.tip_reaction_force).all()


def column_with_tendon():
    """An upright elastic column without gravity and one tendon (slack here): a design with
    no pressure channels, whose rows are tension rows."""
    return load_design(
        {
            "design": {"name": "held_column", "citation": "closed-form check"},
            "mounting": {"orientation": "upright", "gravity": "0 m/s^2"},
            "sections": [
                {
                    "name": "rod",
                    "length": "0.1 m",
                    "mass": "10 g",
                    "outer_radius": "5 mm",
                    "EA": "1e4 N",
                    "GA": "5e3 N",
                    "EI": "0.01 N*m^2",
                    "GJ": "0.01 N*m^2",
                    "steps": 48,
                    "tendons": [{"channel": 0, "distance": "3 mm", "angle": "0 deg"}],
                }
            ],
        }
    )


def test_stability_policies_apply_per_row():
    """A column clamped at both ends and pressed beyond its Euler load (4 pi^2 EI / L^2 =
    39.5 N; here 1.5 times it) is unstable in every row: one StabilityWarning by default,
    InvalidStateError (rule "stability") with on_unstable="raise", as the free batch."""
    d = column_with_tendon()
    pe = 4 * np.pi**2 * 0.01 / 0.1**2
    c = TipConstraint.clamped([0.0, 0.0, 0.1 * (1 - 1.5 * pe / 1e4)], [0.0, 0.0, 0.0])
    t = np.zeros((2, 1))
    with pytest.warns(softrod.StabilityWarning, match="2 of 2 rows"):
        batch = solve_statics_batch(
            d, np.zeros((2, 0)), tensions=t, tip_constraint=c, options=SolverOptions(tol=1e-12)
        )
    assert batch.converged.all() and batch.stability_assessed.all()
    assert not batch.stable.any()
    with pytest.raises(softrod.InvalidStateError) as exc:
        solve_statics_batch(
            d,
            np.zeros((2, 0)),
            tensions=t,
            tip_constraint=c,
            options=SolverOptions(tol=1e-12),
            on_unstable="raise",
        )
    assert exc.value.rule == "stability"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        solve_statics_batch(
            d,
            np.zeros((2, 0)),
            tensions=t,
            tip_constraint=c,
            options=SolverOptions(tol=1e-12),
            on_unstable="ignore",
        )


def test_tension_rows_equal_single_solves():
    d = column_with_tendon()
    c = TipConstraint.pinned(["1 mm", "0 mm", "99.8 mm"])
    t = np.array([[0.0], [0.5], [1.5]])
    batch = solve_statics_batch(d, np.zeros((3, 0)), tensions=t, tip_constraint=c, threads=2)
    single = [solve_statics(d, [], tensions=row, tip_constraint=c) for row in t]
    assert_rows_equal(batch, single)
    np.testing.assert_array_equal(batch.tensions, t)


@pytest.mark.parametrize(
    "kwargs, field, words",
    [
        ({"pressures": np.zeros((2, 2))}, "pressures", "(m, 3)"),
        ({"pressures": [[0.0, float("nan"), 0.0]]}, "pressures[0][1]", "finite"),
        ({"tip_constraint": "glued"}, "tip_constraint.type", "glued"),
        ({"tip_constraint": {"type": "pinned"}}, "tip_constraint.position", "missing"),
        (
            {"tip_constraint": {"type": "pinned", "position": [0, 0, 0], "x": 1}},
            "tip_constraint",
            "unknown keys",
        ),
        (
            {
                "tip_constraint": {
                    "type": "clamped",
                    "position": [0, 0, -0.1],
                    "orientation": [[1, 0.1, 0], [0, 1, 0], [0, 0, 1]],
                }
            },
            "tip_constraint.orientation",
            "rotation matrix",
        ),
        ({"tensions": [[1.0]]}, "tensions", "no tendons"),
        ({"threads": -1}, "threads", ""),
    ],
)
def test_bad_inputs_are_refused_by_name(spa, kwargs, field, words):
    args = {"pressures": rows()[:2], "tip_constraint": PIN, **kwargs}
    p = args.pop("pressures")
    with pytest.raises(InputError) as exc:
        solve_statics_batch(spa, p, **args)
    assert exc.value.field == field, exc.value
    assert words in str(exc.value)


def test_negative_tension_is_refused_by_row():
    d = column_with_tendon()
    with pytest.raises(InputError) as exc:
        solve_statics_batch(
            d,
            np.zeros((2, 0)),
            tensions=[[0.0], [-1.0]],
            tip_constraint=TipConstraint.pinned([0, 0, 0.1]),
        )
    assert exc.value.field == "tensions[1, 0]" and ">= 0" in str(exc.value)


def test_cli_sweep_of_a_held_design(spa, run, tmp_path):
    """`softrod sweep` of a design whose [tip] clamps the tip: the table holds the
    reactions (the API's numbers) and the constraint in its metadata."""
    import pandas as pd

    doc = spa.replace(
        {
            "tip": {
                "constraint": "clamped",
                "position": ["4 mm", "-2 mm", "-127 mm"],
                "orientation": TILTED.tolist(),
            }
        }
    )
    path = tmp_path / "held.toml"
    doc.save(path)
    out = tmp_path / "sweep.parquet"
    result = run("sweep", path, "--grid", "0:30kPa:2", "--out", out, "--threads", "2")
    assert result.exit_code == 0, result.output
    frame = pd.read_parquet(out)
    assert len(frame) == 8
    api = solve_statics_batch(
        load_design(path),
        frame[["p0_kPa", "p1_kPa", "p2_kPa"]].to_numpy() * 1e3,
        on_unstable="ignore",
    )
    np.testing.assert_array_equal(
        frame[[f"tip_reaction_f{a}_N" for a in "xyz"]].to_numpy(), api.tip_reaction_force
    )
    assert {f"tip_reaction_m{a}_Nmm" for a in "xyz"} <= set(frame.columns)


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    p=st.lists(st.tuples(*[st.floats(0.0, 40e3)] * 3), min_size=1, max_size=4),
    threads=st.sampled_from([0, 1, 2, 3]),
    kind=st.sampled_from(["pinned", "clamped"]),
)
def test_any_rows_any_threads_batch_equals_single(p, threads, kind):
    d = load_design(SPA).replace(COARSE)
    c = HELD[kind]
    batch = solve_statics_batch(d, p, tip_constraint=c, threads=threads, on_unstable="ignore")
    assert len(batch) == len(p)
    for k, row in enumerate(p):
        try:
            s = solve_statics(d, list(row), tip_constraint=c, on_unstable="ignore")
        except (softrod.ConvergenceError, softrod.InvalidStateError):
            assert not batch.converged[k]
            assert np.isnan(batch.tip_reaction_force[k]).all()
            continue
        assert_rows_equal(batch, [s], rows=[k])


# ---- systems of rods ----

SYSTEM_ROWS = [
    [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]],
    [[40e3, 0.0, 0.0], [0.0, 0.0, 0.0]],
    [[0.0, 20e3, 10e3], [10e3, 0.0, 30e3]],
    [[30e3, 30e3, 0.0], [0.0, 30e3, 30e3]],
]


@pytest.fixture(scope="module")
def system():
    return softrod.load_system("two_spa_platform")


def test_system_batch_equals_single_solves_bitwise(system):
    single = [solve_system(system, row) for row in SYSTEM_ROWS]
    for threads in (1, 2, 4):
        batch = solve_system_batch(system, SYSTEM_ROWS, threads=threads)
        assert len(batch) == 4 and batch.converged.all()
        for k, s in enumerate(single):
            np.testing.assert_array_equal(batch.platform_position[k], s.platform_position)
            np.testing.assert_array_equal(batch.platform_rotation[k], s.platform_rotation)
            np.testing.assert_array_equal(batch.unknowns[k], s.unknowns)
            assert batch.iterations[k] == s.iterations
            assert s.stable is True and batch.stable[k] and batch.stability_assessed[k]
            for i, r in enumerate(s.rods):
                np.testing.assert_array_equal(batch.tip_position[k, i], r.tip_position)
                np.testing.assert_array_equal(batch.tip_rotation[k, i], r.tip_rotation)
                np.testing.assert_array_equal(batch.base_force[k, i], r.force[0])
                np.testing.assert_array_equal(batch.tip_reaction_force[k, i], r.tip_reaction_force)
                np.testing.assert_array_equal(
                    batch.tip_reaction_moment[k, i], r.tip_reaction_moment
                )
    # an array of rows, and a platform load shared by every row
    arr = np.array(SYSTEM_ROWS)
    loaded = solve_system_batch(system, arr[1:3], platform_force=[0.0, 0.05, 0.0])
    one = solve_system(system, SYSTEM_ROWS[2], platform_force=[0.0, 0.05, 0.0])
    np.testing.assert_array_equal(loaded.platform_position[1], one.platform_position)


def test_system_batch_table_and_failed_rows(system):
    tight = SolverOptions(max_iter=2, continuation=False)
    batch = solve_system_batch(system, SYSTEM_ROWS, options=tight, threads=2)
    assert len(batch) == 4 and not batch.converged.all()
    for k in np.flatnonzero(~batch.converged):
        assert np.isnan(batch.platform_position[k]).all()
        assert np.isnan(batch.tip_reaction_force[k]).all()
        with pytest.raises(softrod.ConvergenceError):
            solve_system(system, SYSTEM_ROWS[k], options=tight)
    frame = solve_system_batch(system, SYSTEM_ROWS[:2]).to_frame()
    for name in (
        "rod0_p0_kPa",
        "rod1_p2_kPa",
        "platform_x_mm",
        "platform_qw",
        "rod1_tip_z_mm",
        "rod0_tip_reaction_fz_N",
        "rod1_tip_reaction_my_Nmm",
        "converged",
        "stable",
    ):
        assert name in frame.columns, name
    assert frame["rod0_p0_kPa"].tolist() == [0.0, 40.0]
    assert frame.attrs["softrod.metadata"]["system"] == "two_spa_platform"


@pytest.mark.parametrize(
    "pressures, kwargs, field",
    [
        ([[[0.0, 0.0], [0.0, 0.0, 0.0]]], {}, "pressures"),
        (np.zeros((2, 3, 3)), {}, "pressures"),
        ([[[0.0, float("nan"), 0.0], [0.0, 0.0, 0.0]]], {}, "pressures[0][0][1]"),
        ([[[0.0, 0.0, 0.0], [0.0, -2e5, 0.0]]], {}, "pressures[0][1][1]"),
        ("30 kPa", {}, "pressures"),
        (None, {}, "pressures"),
        (SYSTEM_ROWS, {"tensions": [[[1.0], [1.0]]] * 4}, "tensions"),
        (SYSTEM_ROWS, {"threads": 1.5}, "threads"),
        (SYSTEM_ROWS, {"platform_force": [0.0, 1.0]}, "platform_force"),
        (SYSTEM_ROWS, {"on_invalid": "shout"}, "on_invalid"),
    ],
)
def test_bad_system_batch_inputs_are_refused_by_name(system, pressures, kwargs, field):
    with pytest.raises(InputError) as exc:
        solve_system_batch(system, pressures, **kwargs)
    assert exc.value.field == field, exc.value
