"""softrod.linearise with a held tip (docs/control.md, "A held tip"): a clamped tip does not
move, so it is no coordinate; a pinned tip keeps its three small rotations. The static
response K^-1 B against the held equilibrium's own Jacobian at every node
(StaticSolution.jacobian, another code path), the tip load's columns, the pinned tip's rows
in the frequency response and the mode shapes, and the refusals by name. The clamped-clamped
and clamped-pinned beams' frequencies against the closed forms are in
crates/softrod-core/tests/suite/linearise.rs."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from softrod import InputError, TipConstraint, linearise, load_design, solve_statics

SPA = "spa_three_chamber_130mm"
P = [30e3, 5e3, 45e3]


@pytest.fixture(scope="module")
def held():
    design = load_design(SPA)
    free = solve_statics(design, P)
    # 6 mm aside of where the free tip would be: the clamp carries load.
    clamp = TipConstraint.clamped(free.tip_position + [0.006, 0.0, 0.0], free.tip_rotation)
    return design, clamp, solve_statics(design, P, tip_constraint=clamp)


def test_clamped_static_response_is_the_held_jacobian(held):
    design, clamp, sol = held
    system = linearise(design, P, tip_constraint=clamp, nodes=6)
    assert system.tip_constraint == "clamped"
    assert system.mass.shape == (36, 36)
    assert np.all((system.nodes > 0) & (system.nodes < design.length))
    response = np.linalg.solve(system.stiffness, system.input)
    for k, s in enumerate(system.nodes):
        jac = sol.jacobian(point=float(s))
        rows = response[6 * k : 6 * k + 6]
        # Two exact derivatives of one equilibrium (the linearisation's flexibility and the
        # point Jacobian): they agree to the solves' tolerance relative to the column.
        for c in range(3):
            scale = np.linalg.norm(jac.pressures[:, c])
            assert np.linalg.norm(rows[:, c] - jac.pressures[:, c]) < 1e-6 * scale
    # A load on the clamped tip goes whole into the clamp.
    tip_columns = [system.input_names.index(n) for n in ("F_x", "F_y", "F_z", "M_x", "M_y", "M_z")]
    assert not system.input[:, tip_columns].any()
    modes = system.modes(3)
    assert np.all(modes.frequency > 0)
    # The same from the solved equilibrium.
    again = linearise(sol, nodes=6)
    np.testing.assert_allclose(again.stiffness, system.stiffness, rtol=1e-9, atol=0.0)
    # A node's frequency response at w = 0 is its static response, at any node index.
    for k in (2, -1):
        np.testing.assert_allclose(
            system.frequency_response(0.0, node=k).real,
            response[6 * (k % 6) : 6 * (k % 6) + 6],
            rtol=1e-12,
            atol=1e-12 * np.abs(response).max(),
        )


def test_clamping_the_tip_raises_the_frequencies(held):
    """Held at its free equilibrium's pose (no load on the clamp), the actuator's first
    bending frequency is that of a clamped-clamped rod: far above the cantilever's."""
    design, _, _ = held
    free = solve_statics(design, P)
    clamp = TipConstraint.clamped(free.tip_position, free.tip_rotation)
    f_free = linearise(design, P, nodes=8).modes(1).frequency[0]
    f_held = linearise(design, P, tip_constraint=clamp, nodes=7).modes(1).frequency[0]
    assert f_held > 3 * f_free


def test_clamped_linearisation_refusals_name_the_field(held):
    _, clamp, sol = held
    system = linearise(sol, nodes=4)
    for call in (lambda: system.tip_rows, lambda: system.frequency_response(10.0)):
        with pytest.raises(InputError) as info:
            call()
        assert info.value.field == "tip_constraint"
    for bad in (4, -5, 1.0, True, "0"):
        with pytest.raises(InputError) as info:
            system.frequency_response(10.0, node=bad)
        assert info.value.field == "node"
    with pytest.raises(InputError) as info:
        linearise(sol, nodes=4, tip_constraint=clamp)  # the equilibrium fixes it
    assert info.value.field == "tip_constraint"
    with pytest.raises(InputError) as info:  # a held equilibrium that lost its pose
        linearise(dataclasses.replace(sol, tip_hold=None), nodes=4)
    assert info.value.field == "initial.tip_hold"


@pytest.fixture(scope="module")
def pinned():
    design = load_design(SPA)
    free = solve_statics(design, P)
    # 6 mm aside of where the free tip would be: the pin carries load.
    pin = TipConstraint.pinned(free.tip_position + [0.006, 0.0, 0.0])
    return design, pin, solve_statics(design, P, tip_constraint=pin)


def test_pinned_static_response_is_the_held_jacobian(pinned):
    design, pin, sol = pinned
    n = 6
    system = linearise(design, P, tip_constraint=pin, nodes=n)
    assert system.tip_constraint == "pinned"
    # Five inner nodes with six coordinates, the tip with its three rotations.
    assert system.mass.shape == (6 * n - 3, 6 * n - 3)
    assert system.nodes[-1] == pytest.approx(design.length, rel=1e-12)
    assert system.tip_rows == slice(6 * n - 6, 6 * n - 3)
    response = np.linalg.solve(system.stiffness, system.input)
    moments = [system.input_names.index(m) for m in ("M_x", "M_y", "M_z")]
    forces = [system.input_names.index(f) for f in ("F_x", "F_y", "F_z")]
    for k, s in enumerate(system.nodes):
        jac = sol.jacobian(point=float(s))
        rows = system.node_rows(response, k)
        # Two exact derivatives of one equilibrium (the linearisation's flexibility and the
        # point Jacobian): they agree to the solves' tolerance relative to the column. The
        # pinned tip's displacement rows are zeros, as is its Jacobian's.
        for c in range(3):
            for got, want in (
                (rows[:, c], jac.pressures[:, c]),
                (rows[:, moments[c]], jac.tip_moment[:, c]),
            ):
                assert np.linalg.norm(got - want) < 1e-6 * np.linalg.norm(want)
    assert not np.asarray(system.node_rows(response, -1))[:3].any()
    # A force on the pinned tip goes whole into the pin.
    assert not system.input[:, forces].any()
    # The frequency response at w = 0 is the static response, the tip's with zero
    # displacement rows.
    tip = system.frequency_response(0.0)
    assert tip.shape == (6, system.input.shape[1])
    np.testing.assert_allclose(
        tip.real, system.node_rows(response, -1), rtol=1e-12, atol=1e-12 * np.abs(response).max()
    )
    # Mode shapes over every node, the pinned tip's displacement zero.
    modes = system.modes(4)
    assert modes.shapes.shape == (4, n, 6)
    assert not modes.shapes[:, -1, :3].any()
    assert np.all(np.abs(modes.shapes).reshape(4, -1).max(axis=1) == pytest.approx(1.0))
    np.testing.assert_allclose(
        linearise(sol, nodes=n).stiffness, system.stiffness, rtol=1e-9, atol=0.0
    )


def test_a_pin_stiffens_less_than_a_clamp(pinned):
    """Held where the free tip rests, the first bending frequency with a pin lies between
    the cantilever's and the clamped-clamped rod's (a pin frees the tip's rotation)."""
    design, _, _ = pinned
    free = solve_statics(design, P)
    f = [
        linearise(design, P, nodes=8, tip_constraint=held).modes(1).frequency[0]
        for held in (
            None,
            TipConstraint.pinned(free.tip_position),
            TipConstraint.clamped(free.tip_position, free.tip_rotation),
        )
    ]
    assert f[0] < f[1] < f[2]
    # A pinned design file is linearised held too.
    pinned_design = design.replace(
        {"tip": {"constraint": "pinned", "position": [f"{v * 1e3} mm" for v in free.tip_position]}}
    )
    from_file = linearise(pinned_design, P, nodes=8)
    assert from_file.tip_constraint == "pinned"
    assert from_file.modes(1).frequency[0] == pytest.approx(f[1], rel=1e-9)


def test_node_rows_refusals_name_the_field(pinned):
    design, pin, sol = pinned
    system = linearise(sol, nodes=4)
    for bad in (4, -5, 1.0, True, "0"):
        with pytest.raises(InputError) as info:
            system.node_rows(np.zeros(system.mass.shape[0]), bad)
        assert info.value.field == "node"
    with pytest.raises(InputError) as info:
        system.node_rows(np.zeros(24), 0)  # a free tip's q: 6 rows too many
    assert info.value.field == "x"
