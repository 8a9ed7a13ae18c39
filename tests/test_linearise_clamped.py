"""softrod.linearise with a clamped tip (docs/control.md, "A clamped tip"): the tip does not
move, so it is no coordinate. The static response K^-1 B against the held equilibrium's own
Jacobian at every node (StaticSolution.jacobian, another code path), zero tip-load columns,
and the refusals by name. The clamped-clamped beam's frequencies against the closed forms are
in crates/softrod-core/tests/suite/linearise.rs."""

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
    design, clamp, sol = held
    system = linearise(sol, nodes=4)
    for call in (lambda: system.tip_rows, lambda: system.frequency_response(10.0)):
        with pytest.raises(InputError) as info:
            call()
        assert info.value.field == "tip_constraint"
    for bad in (4, -5, 1.0, True, "0"):
        with pytest.raises(InputError) as info:
            system.frequency_response(10.0, node=bad)
        assert info.value.field == "node"
    # A pinned tip, given or in the design file: refused before any work.
    pin = TipConstraint.pinned(clamp.position)
    pinned_design = design.replace(
        {"tip": {"constraint": "pinned", "position": ["0 mm", "10 mm", "-125 mm"]}}
    )
    for call in (
        lambda: linearise(design, P, tip_constraint=pin, nodes=4),
        lambda: linearise(pinned_design, P, nodes=4),
    ):
        with pytest.raises(InputError, match="pinned tip") as info:
            call()
        assert info.value.field == "tip_constraint"
    with pytest.raises(InputError) as info:
        linearise(sol, nodes=4, tip_constraint=clamp)  # the equilibrium fixes it
    assert info.value.field == "tip_constraint"
    with pytest.raises(InputError) as info:  # a held equilibrium that lost its pose
        linearise(dataclasses.replace(sol, tip_hold=None), nodes=4)
    assert info.value.field == "initial.tip_hold"
