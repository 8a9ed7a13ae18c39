"""The frictional finger of the friction tests (tests/test_friction_statics.py and
tests/test_friction_batch.py; their fixtures ``finger`` and ``rough`` are in
tests/conftest.py): the bundled finger pressed onto its table, and with Coulomb friction
MU on the table."""

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
