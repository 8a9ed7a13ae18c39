"""What is derived from an equilibrium that statics solved by collocation (a long, soft rod
whose single shooting cannot be resolved: docs/model.md, "Collocation"): motion-capture
markers are read from the solution's own nodes, and the exact derivatives, which are taken by
shooting passes that would leave such an equilibrium, are refused by name instead of being
returned wrong (crates/softrod-core/tests/suite/collocation.rs checks the core's side)."""

from __future__ import annotations

import numpy as np
import pytest
from softrod import InputError, linearise, load_design, solve_statics, synthesize_dataset


def long_soft_arm() -> dict:
    """A 1 m arm hanging under its own weight, soft in bending (EI = 1e-3 N m^2): single
    shooting's growth exponent int sqrt(|n| / EI) ds is about 20, beyond the limit of 12."""
    return {
        "design": {"name": "long_soft_arm", "citation": "collocation check"},
        "mounting": {"orientation": "hanging", "gravity": "9.81 m/s^2"},
        "sections": [
            {
                "name": "arm",
                "length": "1 m",
                "mass": "100 g",
                "outer_radius": "10 mm",
                "EA": "1e4 N",
                "GA": "1e4 N",
                "EI": "1e-3 N*m^2",
                "GJ": "1e-3 N*m^2",
                "steps": 64,
                "chambers": [
                    {"radius": "2 mm", "distance": "4 mm", "angle": "0 deg", "channel": 0}
                ],
            }
        ],
    }


def test_markers_are_read_from_the_collocation_nodes():
    """A marker at the tip is the tip (before, markers were shot from the base unknowns and
    landed centimetres away on such a rod); one at mid-length lies on the solution's
    centreline at its node."""
    design = load_design(long_soft_arm())
    p = [[0.0], [3e3]]
    data = synthesize_dataset(design, p, markers=[("1 m", [0, 0]), ("0.5 m", [0, 0])], seed=1)
    np.testing.assert_allclose(data.markers[:, 0], data.tip_position, rtol=0, atol=1e-12)
    for row, pressure in enumerate(p):
        sol = solve_statics(design, pressure)
        mid = sol.position[np.argmin(np.abs(sol.s - 0.5))]
        np.testing.assert_allclose(data.markers[row, 1], mid, rtol=0, atol=1e-12)


def test_derivatives_of_collocation_solutions_are_refused():
    design = load_design(long_soft_arm())
    sol = solve_statics(design, [3e3])
    for call in (sol.jacobian, lambda: linearise(sol, nodes=8)):
        with pytest.raises(InputError) as info:
            call()
        assert info.value.field == "solution"
        assert "collocation" in str(info.value)
