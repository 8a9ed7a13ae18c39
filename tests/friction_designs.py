"""The frictional finger of the friction tests (tests/test_friction_statics.py and
tests/test_friction_batch.py; their fixtures ``finger`` and ``rough`` are in
tests/conftest.py): the bundled finger pressed onto its table, and with Coulomb friction
MU on the table."""

FINGER = "prebent_finger_on_table"
MU = 0.5
