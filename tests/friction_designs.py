"""The frictional finger of the friction tests (tests/test_friction_statics.py and
tests/test_friction_batch.py; their fixtures ``finger`` and ``rough`` are in
tests/conftest.py): the bundled finger pressed onto its table, and with Coulomb friction
MU on the table; two of them holding one platform (tests/test_friction_system.py,
benchmarks/bench_system_statics.py); and the three-chamber SPA hanging beside a rough
wall (compare_models and compare_hybrid need paper 002's three channels;
tests/test_compare.py, the fuzz suite)."""

FINGER = "prebent_finger_on_table"
MU = 0.5

# The two fingers of the frictional system (tests/test_friction_system.py): the second
# finger's base GAP to the side (world y) of the first; a massless platform holds both tips
# where the unloaded fingers have them, its origin midway.
GAP = 0.03


def two_fingers(design, name: str = "two_fingers"):
    """A system of two copies of ``design`` (the bundled finger over its table, smooth or
    rough) GAP apart, their tips clamped to one massless platform at the unloaded tips."""
    import numpy as np
    from softrod import solve_statics
    from softrod.system import Platform, System, SystemRod

    unloaded = design.replace({"mounting.gravity": "0 m/s^2"}).with_obstacles([])
    ref = solve_statics(unloaded, [0.0])
    tip, rot = ref.tip_position, ref.rotation[-1]
    side = np.array([0.0, GAP, 0.0])
    origin = tip + 0.5 * side
    second = design.replace({"mounting.base_position": ["0 mm", f"{GAP * 1e3:g} mm", "0 mm"]})
    rods = (SystemRod(design, tip - origin, rot), SystemRod(second, tip + side - origin, rot))
    return System(name, rods, Platform(position=origin))


#: A rough wall beside the hanging three-chamber SPA (outer radius 21.1 mm): 9 mm clear of
#: its surface at rest, reached by the bend of channel 0 (towards +y) above about 18 kPa.
SPA_WALL = {
    "kind": "plane",
    "point": ["0 mm", "30 mm", "0 mm"],
    "normal": [0.0, -1.0, 0.0],
    "stiffness": "2e6 N/m^2",
    "tolerance": "0.05 mm",
    "friction": MU,
}


def spa_beside_rough_wall():
    """spa_three_chamber_130mm with SPA_WALL as its one obstacle."""
    import copy

    from softrod import load_design

    doc = copy.deepcopy(load_design("spa_three_chamber_130mm").document)
    doc["obstacles"] = [dict(SPA_WALL)]
    return load_design(doc)
