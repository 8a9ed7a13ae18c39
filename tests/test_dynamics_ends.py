"""Dynamics with a held tip (docs/dynamics.md, "Held tip"): a damped run settles on the
constrained statics, a moving pose is followed and its reaction recorded and kept by the
files, save/restore, the design file's constraint as the default, bad input by name, and
hypothesis over kinds and poses. (Frequencies against Euler-Bernoulli, the exact step
Jacobian and the energy books are in crates/softrod-core/tests/suite/dynamics_ends.rs.)
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import softrod
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from softrod import DesignError, InputError, Simulation, TipConstraint, load_design, simulate
from softrod.dynamics import Trajectory

L = 0.1  # m
EI = 1e-3  # N m^2
RHO_A = 0.05  # kg/m (5 g over 0.1 m)
# First clamped-clamped frequency, rad/s (beta1 L = 4.73): the step is a fiftieth of it.
OMEGA = 4.73**2 / L**2 * math.sqrt(EI / RHO_A)
DT = 2 * math.pi / OMEGA / 50
# The damped runs below: tau = 0.5 / omega, a damping ratio of 0.25 on the first mode.
TAU = 0.5 / OMEGA
TIP = [L, 0.0, 0.0]
# Horizontal mounting: d3 = +x, d1 = +z, d2 = -y (HORIZONTAL of
# crates/softrod-core/tests/suite/common.rs).
HORIZONTAL = [[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]]


def beam(tip: dict | None = None, tau: float = TAU, g: float = 9.81) -> softrod.Design:
    """A horizontal beam along +x with direct stiffnesses under gravity -z."""
    doc = {
        "design": {"name": "held_beam", "citation": "closed-form check"},
        "mounting": {"orientation": "horizontal", "gravity": f"{g} m/s^2"},
        "sections": [
            {
                "name": "beam",
                "length": f"{L} m",
                "mass": f"{RHO_A * L * 1e3} g",
                "outer_radius": "5 mm",
                "EA": "1e3 N",
                "GA": "5e2 N",
                "EI": f"{EI} N*m^2",
                "GJ": f"{EI} N*m^2",
                "steps": 8,
            }
        ],
        "dynamics": {"damping_time": f"{tau} s"},
    }
    if tip:
        doc["tip"] = tip
    return load_design(doc)


def clamped(position=TIP, rotation=HORIZONTAL) -> TipConstraint:
    return TipConstraint.clamped(position, np.asarray(rotation))


def test_the_mounting_is_the_straight_tip_pose():
    d = beam()
    s = Simulation(d, initial="straight", dt=DT, tip_constraint=clamped())
    np.testing.assert_allclose(s.state().tip_position, TIP, atol=1e-15)
    np.testing.assert_allclose(s.state().tip_rotation, HORIZONTAL, atol=1e-15)


@pytest.mark.parametrize("kind", ["pinned", "clamped"])
def test_a_damped_run_settles_on_the_constrained_statics(kind):
    """Released straight under gravity, the damped beam settles on the equilibrium of the
    'static' start (this discretisation's) to the Newton tolerance, and that is
    solve_statics' (shooting) to the two discretisations' difference."""
    c = TipConstraint.pinned(TIP) if kind == "pinned" else clamped()
    d = beam()
    rest = Simulation(d, initial="static", dt=DT, tol=1e-12, tip_constraint=c).state()
    # 40 periods of the first mode at damping ratio 0.25: exp(-63) of the start's motion.
    traj = simulate(
        d,
        None,
        40 * 50 * DT,
        dt=DT,
        initial="straight",
        tol=1e-12,
        tip_constraint=c,
        shapes="saved",
        save_every=500,
    )
    # 1e-12 of the scaled residual in position (1e-12 L), x10 for the banded solve.
    np.testing.assert_allclose(traj.shape_position[-1], rest.shape_position, rtol=0, atol=1e-11 * L)
    # Reactions: a position error of 1e-11 L over an interval L / 8 strains the beam by
    # 8e-11 at its axial stiffness EA = 1e3 N.
    np.testing.assert_allclose(
        traj.tip_reaction_force[-1], rest.tip_reaction_force, rtol=0, atol=8e-11 * 1e3
    )
    sol = softrod.solve_statics(d, [], tip_constraint=c)
    w = RHO_A * L * 9.81
    # Both fourth order on 8 intervals: (1/8)^4 = 2.4e-4 of the weight across the beam.
    # (Along it, the tension of the sag is a second-order effect of the deflection that the
    # discretisations resolve less well, 0.5 % apart here: the Rust tests show the
    # reactions' difference falling 16x per halving of the intervals.)
    np.testing.assert_allclose(
        rest.tip_reaction_force[1:], sol.tip_reaction_force[1:], rtol=0, atol=2.4e-4 * w
    )
    np.testing.assert_allclose(
        rest.tip_reaction_moment, sol.tip_reaction_moment, rtol=0, atol=2.4e-4 * w * L
    )
    # The reactions and the base's force balance the weight (round-off of the weight).
    total = rest.tip_reaction_force - rest.base_force + np.array([0.0, 0.0, -w])
    np.testing.assert_allclose(total, 0.0, atol=1e-12 * w)
    if kind == "pinned":
        assert np.all(rest.tip_reaction_moment == 0.0)


def swing(t: float) -> TipConstraint:
    """The clamp swings on the circle of radius L about the base (no axial compression) and
    turns with it; at rest at t = 0."""
    phi = 0.05 * (1.0 - math.cos(2 * math.pi * t / (40 * DT)))
    c, s = math.cos(phi), math.sin(phi)
    turn = np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])  # about y by -phi
    return clamped([L * c, 0.0, L * s], turn @ np.array(HORIZONTAL))


def test_a_moving_clamp_is_followed_and_its_reaction_kept(tmp_path):
    traj = simulate(beam(), None, 60 * DT, dt=DT, tip_constraint=swing)
    assert traj.metadata["tip_constraint"] == "clamped"
    for t, p, r in zip(traj.time, traj.tip_position, traj.tip_rotation, strict=True):
        pose = swing(float(t))
        # The pose is an equation of every step: held to the Newton tolerance (1e-9 L).
        np.testing.assert_allclose(p, pose.position, rtol=0, atol=1e-9 * L)
        np.testing.assert_allclose(r, pose.rotation, rtol=0, atol=1e-9)
    assert traj.tip_reaction_force.shape == (len(traj.time), 3)
    assert np.all(np.isfinite(traj.tip_reaction_moment))
    # The clamp moves: its reaction changes and does work (energy books).
    assert np.ptp(traj.tip_reaction_force[:, 2]) > 0.0
    assert abs(traj.work_in[-1]) > 0.0
    cols = traj.to_frame().columns
    assert {"tip_reaction_fx_N", "tip_reaction_mz_Nmm"} <= set(cols)
    for suffix in (".npz", ".parquet"):
        back = Trajectory.load(traj.save(tmp_path / f"held{suffix}"))
        np.testing.assert_array_equal(back.tip_reaction_force, traj.tip_reaction_force)
        np.testing.assert_array_equal(back.tip_reaction_moment, traj.tip_reaction_moment)


def test_a_free_run_has_no_reaction_columns(tmp_path):
    """Older files and free runs: no reaction arrays, and they load without them."""
    traj = simulate(beam(), None, 3 * DT, dt=DT)
    assert traj.tip_reaction_force is None
    assert not any(c.startswith("tip_reaction") for c in traj.to_frame().columns)
    for suffix in (".npz", ".parquet"):
        assert Trajectory.load(traj.save(tmp_path / f"free{suffix}")).tip_reaction_force is None


def test_set_tip_pose_and_restore_bit_for_bit():
    a = Simulation(beam(), dt=DT, tip_constraint=TipConstraint.pinned(TIP))
    for k in range(1, 4):
        a.set_tip_pose(TipConstraint.pinned([L, 0.0, 1e-3 * k]))
        a.step()
    state = a.state()
    b = Simulation(beam(), dt=DT, tip_constraint=TipConstraint.pinned(TIP))
    b.restore(state)
    for s in (a, b):
        s.set_tip_pose({"type": "pinned", "position": ["100 mm", "0 mm", "5 mm"]})
        s.step()
    np.testing.assert_array_equal(a.state().data, b.state().data)
    assert a.tip_constraint.kind == "pinned"
    np.testing.assert_allclose(a.tip_constraint.position, [L, 0.0, 5e-3], atol=1e-15)


def test_the_design_files_constraint_is_the_default():
    d = beam(tip={"constraint": "pinned", "position": ["100 mm", "0 mm", "0 mm"]})
    traj = simulate(d, None, 5 * DT, dt=DT)
    assert traj.metadata["tip_constraint"] == "pinned"
    np.testing.assert_allclose(traj.tip_position, np.tile(TIP, (6, 1)), atol=1e-9 * L)
    # "free" overrides the file.
    free = simulate(d, None, 2 * DT, dt=DT, tip_constraint="free")
    assert free.tip_reaction_force is None


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        (
            {"tip_constraint": TipConstraint.pinned([0.09, 0, 0]), "initial": "straight"},
            "tip_constraint.position",
        ),
        (
            {"tip_constraint": clamped(rotation=np.eye(3)), "initial": "straight"},
            "tip_constraint.orientation",
        ),
        ({"tip_constraint": clamped(), "scheme": "midpoint"}, "scheme"),
        (
            {"tip_constraint": {"type": "pinned", "position": [math.nan, 0, 0]}},
            "tip_constraint.position",
        ),
        (
            {
                "tip_constraint": {
                    "type": "clamped",
                    "position": TIP,
                    "orientation": [[1, 0, 0], [0, 1, 0], [0, 0.5, 1]],
                }
            },
            "tip_constraint.orientation",
        ),
        ({"tip_constraint": lambda t: "clamped"}, "tip_constraint(t = 0 s)"),
        (
            {"tip_constraint": lambda t: TipConstraint.pinned([L, 0, 0]) if t == 0 else clamped()},
            "tip_constraint",
        ),
        ({"tip_constraint": clamped(), "model": "pcc"}, "tip_constraint"),
    ],
)
def test_bad_input_is_refused_by_name(kwargs, field):
    with pytest.raises((InputError, DesignError)) as exc:
        simulate(beam(), None, 3 * DT, dt=DT, **kwargs)
    assert exc.value.field.startswith(field), exc.value


def test_a_pose_of_another_kind_is_refused_and_nothing_changes():
    s = Simulation(beam(), dt=DT, tip_constraint=clamped())
    before = s.state().data
    with pytest.raises(InputError) as exc:
        s.set_tip_pose(TipConstraint.pinned(TIP))
    assert exc.value.field == "tip_constraint"
    np.testing.assert_array_equal(s.state().data, before)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    kind=st.sampled_from(["free", "pinned", "clamped"]),
    offset=st.lists(st.floats(-0.5, 0.5), min_size=3, max_size=3),
    turn=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
    scale=st.sampled_from([1e-3, 1e-1, 1.0, 1e3, math.inf]),
    initial=st.sampled_from(["static", "straight", "reference"]),
)
def test_hypothesis_any_held_run_is_finite_or_refused_by_name(kind, offset, turn, scale, initial):
    """Each kind at any pose near or far from the tip (or non-finite), from either start:
    a finite trajectory whose tip holds the pose, or the library's error naming a field. (A
    pose that compresses the beam past its buckling load starts at an unstable equilibrium:
    that warning is the start's honest verdict, tested elsewhere, so it is not asked for.)"""
    pos = [TIP[k] + scale * L * offset[k] for k in range(3)]
    c = {"type": kind}
    if kind != "free":
        c["position"] = pos
    if kind == "clamped":
        c["orientation"] = [f"{x} rad" for x in turn]
    try:
        traj = simulate(
            beam(), None, 3 * DT, dt=DT, initial=initial, tip_constraint=c, on_unstable="ignore"
        )
    except (InputError, DesignError) as exc:
        assert exc.field, exc
        return
    except softrod.ConvergenceError:
        return  # a pose the rod cannot reach: reported as such
    except softrod.InvalidStateError as exc:
        assert exc.rule, exc
        return
    assert np.all(np.isfinite(traj.tip_position))
    if kind != "free":
        np.testing.assert_allclose(traj.tip_position[-1], pos, rtol=0, atol=1e-9 * L)
        assert np.all(np.isfinite(traj.tip_reaction_force))


def test_cli_simulate_honours_the_design_files_constraint(run, tmp_path):
    base = load_design("spa_three_chamber_130mm")
    tip = softrod.solve_statics(base, [0, 0, 0]).tip_position
    held = base.replace(
        {"tip": {"constraint": "pinned", "position": [f"{x} m" for x in tip + [0.002, 0, 0]]}}
    )
    path = held.save(tmp_path / "held.toml")
    inp = softrod.PressureSchedule.steps([0.0], [[0, 0, 0]]).write(tmp_path / "p.csv")
    out = tmp_path / "t.npz"
    res = run("simulate", path, "--input", inp, "--t-end", "10 ms", "--dt", "2 ms", "--out", out)
    assert res.exit_code == 0, res.output
    tr = Trajectory.load(out)
    assert tr.metadata["tip_constraint"] == "pinned"
    # The pin holds the tip 2 mm beside where it hangs, to the Newton tolerance.
    np.testing.assert_allclose(
        tr.tip_position, np.tile(tip + [0.002, 0, 0], (len(tr.time), 1)), rtol=0, atol=1e-9
    )
    assert np.all(np.isfinite(tr.tip_reaction_force))


def test_a_static_start_at_an_unstable_equilibrium_warns_raises_or_is_ignored():
    """A straight finger (gravity off) pinned 30 mm short of its length is compressed far
    past its Euler load: the straight rod is an equilibrium, and an unstable one. Started
    there, a run stays until disturbed, and a coarse fixed step damps the disturbance away
    (it stayed straight at dt = 20 ms with a 23.9 N reaction instead of buckling to 3.4 N):
    the start says so, as solve_statics does."""
    from softrod import InvalidStateError, StabilityWarning

    d = load_design("prebent_tendon_finger")
    sec = dict(d.document["sections"][0])
    sec.pop("bend_radius")
    sec.pop("bend_direction")
    straight = d.replace({"sections": [sec], "mounting.gravity": "0 m/s^2"})
    short = softrod.TipConstraint.pinned([0.0, 0.0, 0.05])
    with pytest.warns(StabilityWarning, match="initial static state .* unstable"):
        sim = softrod.Simulation(straight, [0.0], tip_constraint=short, dt=0.02)
    assert sim.start_stable is False
    with pytest.raises(InvalidStateError) as info:
        softrod.simulate(straight, [0.0], 0.04, tip_constraint=short, on_unstable="raise")
    assert info.value.rule == "stability"
    quiet = softrod.Simulation(straight, [0.0], tip_constraint=short, on_unstable="ignore")
    assert quiet.start_stable is False
    # Barely shortened (0.1 mm), below the Euler load: stable, no warning (the suite turns
    # warnings into errors). A 'straight' start is no equilibrium test: None.
    mild = softrod.TipConstraint.pinned([0.0, 0.0, 0.0799])
    assert softrod.Simulation(straight, [0.0], tip_constraint=mild).start_stable is True
    assert softrod.Simulation("spa_three_chamber_130mm", initial="straight").start_stable is None
    with pytest.raises(InputError, match="on_unstable"):
        softrod.Simulation("spa_three_chamber_130mm", on_unstable="maybe")
