"""Systems of rods the statics and dynamics tests share."""

from __future__ import annotations

import dataclasses

import softrod

#: The bundled system's left actuator pressurised so that it swings towards +y.
LEFT_AT_40_KPA = [[40e3, 0.0, 0.0], [0.0, 0.0, 0.0]]


def walled(system):
    """``system`` (the bundled ``two_spa_platform``) with a wall that its left actuator, at
    ``LEFT_AT_40_KPA``, would cross by 4 mm: a plane facing -y, penalty 1e6 N/m^2,
    tolerance 0.5 mm (docs/contact.md)."""
    reach = softrod.solve_system(system, LEFT_AT_40_KPA).rods[0].position[:, 1].max()
    radius = system.rods[0].design.spec["sections"][0]["outer_radius"]
    wall = {
        "kind": "plane",
        "point": ["0 mm", f"{(reach + radius) * 1e3 - 4.0} mm", "0 mm"],
        "normal": [0, -1, 0],
        "stiffness": "1e6 N/m^2",
        "tolerance": "0.5 mm",
    }
    left = dataclasses.replace(
        system.rods[0], design=system.rods[0].design.replace({"obstacles": [wall]})
    )
    return dataclasses.replace(system, rods=(left, system.rods[1]))
