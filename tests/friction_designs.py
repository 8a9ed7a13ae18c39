"""The frictional finger of the friction tests (tests/test_friction_statics.py and
tests/test_friction_batch.py; their fixtures ``finger`` and ``rough`` are in
tests/conftest.py): the bundled finger pressed onto its table, and with Coulomb friction
MU on the table; two of them holding one clip (the bundled system two_fingers_on_table,
tests/test_friction_system.py); and the three-chamber SPA hanging beside a rough
wall (compare_models and compare_hybrid need paper 002's three channels;
tests/test_compare.py, the fuzz suite)."""

FINGER = "prebent_finger_on_table"
MU = 0.5

# The two fingers of the frictional system tests (tests/test_friction_system.py): the bundled
# system two_fingers_on_table, its table with Coulomb friction.
PAIR = "two_fingers_on_table"


def two_fingers(friction: float = 0.0):
    """The bundled two-finger system (two prebent_finger_on_table fingers whose tips hold one
    clip), every finger's table with Coulomb friction ``friction`` (0: as bundled)."""
    import dataclasses

    from softrod import load_system

    system = load_system(PAIR)
    if friction == 0.0:
        return system
    rods = tuple(
        dataclasses.replace(r, design=r.design.replace({"obstacles[0].friction": friction}))
        for r in system.rods
    )
    return dataclasses.replace(system, rods=rods)


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
