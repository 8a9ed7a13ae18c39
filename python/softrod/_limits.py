"""The size limits of softrod's inputs (docs/errors.md, "Limits"), checked by
:mod:`softrod._validate` before anything is allocated. Plain Python: the command line reads
them without importing numpy."""

from __future__ import annotations

import os

MAX_CHANNELS = 64  # pressure channels of a design: channel indices 0 ... 63
MAX_SECTIONS = 1000  # sections of a design
MAX_CHAMBERS = 64  # chambers of one section
MAX_TENDONS = 64  # tendons of one section
MAX_LOADS = 1000  # [[loads]] entries of a design
MAX_OBSTACLES = 1000  # [[obstacles]] entries of a design
MAX_MESH_TRIANGLES = 200_000  # triangles of one mesh obstacle (the core's mesh::MAX_MESH_TRIANGLES)
MAX_MESH_FILE_BYTES = 128 * 2**20  # size of a mesh file (STL, OBJ)
MAX_TABLE_POINTS = 10_000  # points of a tabulated law (axial table, PCC k_theta table)
MAX_SECTION_STEPS = 100_000  # integration steps of one section
MAX_DESIGN_STEPS = 1_000_000  # integration steps of a whole design (nodes of its shape)
MAX_ITERATIONS = 100_000  # Newton iterations, load steps, optimiser evaluations
MAX_RESTARTS = 10_000  # extra starting points of a calibration (each one a whole fit)
MAX_ROWS = 10_000_000  # rows of a batch, a dataset, a schedule or a pressure grid
MAX_DYNAMIC_STEPS = 10_000_000  # time steps of one simulation run
MAX_SAVED_SAMPLES = 2_000_000  # samples a trajectory keeps
MAX_SHAPE_POINTS = 20_000_000  # centreline points a trajectory keeps (samples x nodes)
MAX_THREADS = max(256, 4 * (os.cpu_count() or 1))  # worker threads of a parallel call
MAX_NAME_LENGTH = 200  # characters of a name (design, section, material, column)
MAX_TEXT_LENGTH = 100_000  # characters of free text (description, citation, assumption)
MAX_QUANTITY_LENGTH = 100  # characters of a quantity string such as "110 mm"
MAX_DEPTH = 32  # nesting of tables and arrays in documents and metadata
MAX_ABS_INT = 2**53  # integers beyond this are not exact as floats: refused as values
VACUUM_PA = -101325.0  # the lowest gauge pressure there is (absolute zero at 1 atm ambient)

LIMITS = {
    "channels": MAX_CHANNELS,
    "sections": MAX_SECTIONS,
    "chambers per section": MAX_CHAMBERS,
    "tendons per section": MAX_TENDONS,
    "loads": MAX_LOADS,
    "obstacles": MAX_OBSTACLES,
    "mesh triangles": MAX_MESH_TRIANGLES,
    "mesh file bytes": MAX_MESH_FILE_BYTES,
    "table points": MAX_TABLE_POINTS,
    "steps per section": MAX_SECTION_STEPS,
    "steps per design": MAX_DESIGN_STEPS,
    "iterations": MAX_ITERATIONS,
    "restarts": MAX_RESTARTS,
    "rows": MAX_ROWS,
    "time steps": MAX_DYNAMIC_STEPS,
    "saved samples": MAX_SAVED_SAMPLES,
    "shape points": MAX_SHAPE_POINTS,
    "threads": MAX_THREADS,
    "name length": MAX_NAME_LENGTH,
    "text length": MAX_TEXT_LENGTH,
    "quantity length": MAX_QUANTITY_LENGTH,
    "nesting depth": MAX_DEPTH,
}
