"""Systems of rods the statics and dynamics tests share."""

from __future__ import annotations

import dataclasses

import numpy as np
import softrod
from softrod import StiffnessMap

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


#: The bundled SPA whose chambered body section is stiffness-mapped.
SPA = "spa_three_chamber_130mm"


def mapped(design=SPA):
    """The bundled SPA with its chambered body section stiffness-mapped."""
    return softrod.load_design(design).replace({"sections[1].law": {"stiffness_map": True}})


def table_map() -> StiffnessMap:
    """A smooth 3-channel PCHIP table over 0..60 kPa, sigma between 0.4 and 1.8 (pressures
    outside it are refused)."""
    rng = np.random.default_rng(3)
    axes = [np.array([0.0, 15e3, 30e3, 60e3])] * 3
    return StiffnessMap.from_table(axes, rng.uniform(0.4, 1.8, (4, 4, 4, 3)))


def network_map() -> StiffnessMap:
    """Three random networks (paper 001's hybrid model as arrays), 3 channels."""
    rng = np.random.default_rng(9)
    sizes = [3, 8, 6, 1]
    return StiffnessMap.from_networks(
        [
            {
                "input_mean": [2e4, 2e4, 2e4],
                "input_scale": [1.5e4, 1.5e4, 1.5e4],
                "weights": [
                    rng.normal(size=(a, b)) for a, b in zip(sizes[:-1], sizes[1:], strict=True)
                ],
                "biases": [rng.normal(size=b) for b in sizes[1:]],
                "activation": "tanh",
                "target_mean": 0.0,
                "target_scale": 0.15,
            }
            for _ in range(3)
        ]
    )


def two_mapped_rods(system=None):
    """``system`` (default: the bundled ``two_spa_platform``) with both rods' body sections
    mapped."""
    system = softrod.load_system("two_spa_platform") if system is None else system
    rods = tuple(
        dataclasses.replace(
            r, design=r.design.replace({"sections[1].law": {"stiffness_map": True}})
        )
        for r in system.rods
    )
    return dataclasses.replace(system, rods=rods)
