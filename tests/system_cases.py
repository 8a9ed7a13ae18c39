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


def follower(system):
    """``system`` (the bundled ``two_spa_platform``) with a follower tip load on its left
    actuator (``[tip] frame = "body"``): 0.05 N along the tip's d1 and 2 N mm about its d2,
    in the tip frame, so that they turn with the tip (and the platform that holds it)."""
    left = dataclasses.replace(
        system.rods[0],
        design=system.rods[0].design.replace(
            {
                "tip.frame": "body",
                "tip.force": ["0.05 N", "0 N", "0 N"],
                "tip.moment": ["0 N*mm", "2 N*mm", "0 N*mm"],
            }
        ),
    )
    return dataclasses.replace(system, rods=(left, system.rods[1]))
