"""Contact statics benchmark (a script, not a test): the pre-curved finger pressed onto a
table (design ``prebent_finger_on_table``, docs/contact.md).

    python benchmarks/bench_contact.py            # full run, writes results/contact.json
    python benchmarks/bench_contact.py --quick    # smoke run (< 20 s), contact_quick.json

Cold solves (no warm start) at pressures over the operating range 0-50 kPa, in contact
and free, through ``solve_statics`` and through the binding directly (``design._rod.solve``,
no Python validation or result object); medians of wall-clock times with the garbage
collector off. The same solves without the table give the cost of contact (the design's
obstacle removed: 3 shooting unknowns instead of 6, no contact law). Target (issue 17): under
1 ms per cold solve.

Frictional batch: the table with friction 0.5, 64 rows from 5 to 50 kPa (8 with --quick),
each row its own load path of 80 increments (docs/contact.md, "Friction in the statics"):
one ``solve_statics_batch`` on 1 and 2 threads against a loop of ``solve_statics`` calls
(the same answers, bitwise); medians of 3 runs (1 with --quick).

Mesh table: the same table as a triangle mesh (``kind = "mesh"``, docs/contact.md,
"Triangle meshes") of 50 x 50 squares over 200 mm x 200 mm, 5,000 triangles: cold solves
at the same pressures against the plane (the same answers: the mesh's distance there is the
plane's), and the time to load the design (reading its vertices and building the
hierarchy).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import softrod

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import (  # noqa: E402  (sibling module of this script)
    bench_main,
    binding_solver,
    load_average,
    machine,
    median,
    result_header,
    timed,
)

DESIGN = "prebent_finger_on_table"
PRESSURES_KPA = [0.0, 10.0, 20.0, 30.0, 40.0, 50.0]
TARGET_S = 1e-3
MU = 0.5
FRICTION_ROWS = 64


def frictional_batch(design, quick: bool) -> dict:
    """Wall-clock seconds of a frictional batch on 1 and 2 threads and of its rows as
    single solves (medians)."""
    rough = design.replace({"obstacles[0].friction": MU})
    m = 8 if quick else FRICTION_ROWS
    p = [[x] for x in np.linspace(5e3, 50e3, m)]
    reps = 1 if quick else 3
    out = {"rows": m, "friction": MU}
    out["singles_s"] = median(timed(lambda: [softrod.solve_statics(rough, row) for row in p], reps))
    for threads in (1, 2):
        out[f"batch_{threads}_thread_s"] = median(
            timed(lambda t=threads: softrod.solve_statics_batch(rough, p, threads=t), reps)
        )
    print(
        f"frictional batch, {m} rows (mu = {MU}): {m} solve_statics {out['singles_s']:.3f} s, "
        f"batch {out['batch_1_thread_s']:.3f} s (1 thread), "
        f"{out['batch_2_thread_s']:.3f} s (2 threads)"
    )
    return out


MESH_SQUARES = 50  # per side: 2 * 50^2 = 5,000 triangles


def mesh_table(design):
    """The design with its table as a flat mesh of 2 MESH_SQUARES^2 triangles at the
    plane's height (z = -82 mm)."""
    n = MESH_SQUARES
    x = np.linspace(-100.0, 100.0, n + 1)
    gx, gy = np.meshgrid(x, x)
    v = np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, -82.0)])
    a = (np.arange(n)[None, :] + (n + 1) * np.arange(n)[:, None]).ravel()
    f = np.concatenate(
        [np.column_stack([a, a + 1, a + n + 2]), np.column_stack([a, a + n + 2, a + n + 1])]
    )
    table = {
        "kind": "mesh",
        "vertices": v.tolist(),
        "faces": f.tolist(),
        "units": "mm",
        "stiffness": "1e7 N/m^2",
        "tolerance": "0.2 mm",
    }
    return design.with_obstacles([table]), len(f)


def mesh_case(design, reps: int) -> dict:
    """Cold solves on the mesh table against the plane (medians), and the load time."""
    mesh, n_tri = mesh_table(design)
    t_load = median(timed(lambda: mesh_table(design), max(3, reps // 20)))
    print(f"mesh table: {n_tri} triangles, design load {t_load * 1e3:.1f} ms")
    rows = []
    for p in PRESSURES_KPA:
        pp = [p * 1e3]
        a, b = softrod.solve_statics(design, pp), softrod.solve_statics(mesh, pp)
        diff = float(np.abs(a.position - b.position).max())
        t_plane = median(timed(binding_solver(design, pp, tensions=[0.0]), reps))
        t_mesh = median(timed(binding_solver(mesh, pp, tensions=[0.0]), reps))
        t_api = median(timed(lambda pp=pp: softrod.solve_statics(mesh, pp), reps))
        rows.append(
            {
                "pressure_kPa": p,
                "plane_binding_s": t_plane,
                "mesh_binding_s": t_mesh,
                "mesh_solve_statics_s": t_api,
                "max_position_difference_m": diff,
            }
        )
        print(
            f"  {p:4.0f} kPa: mesh {t_mesh * 1e6:7.1f} us (solve_statics {t_api * 1e6:7.1f} us), "
            f"plane {t_plane * 1e6:7.1f} us, ratio {t_mesh / t_plane:.2f}; shapes differ by "
            f"{diff:.1e} m"
        )
    return {"triangles": n_tri, "design_load_s": t_load, "rows": rows}


def run(args) -> dict:
    t_start = time.perf_counter()
    reps = 20 if args.quick else 300
    design = softrod.load_design(DESIGN)
    free = design.replace({"obstacles": []})
    info = machine()
    print(f"{DESIGN}: cold solves, median of {reps} (load {load_average()})")
    rows = []
    for p in PRESSURES_KPA:
        pp = [p * 1e3]
        sol = softrod.solve_statics(design, pp)
        contact = sol.contact
        t_api = median(timed(lambda pp=pp: softrod.solve_statics(design, pp), reps))
        t_bind = median(timed(binding_solver(design, pp, tensions=[0.0]), reps))
        t_free = median(timed(binding_solver(free, pp, tensions=[0.0]), reps))
        row = {
            "pressure_kPa": p,
            "contact_force_N": float(contact.total[2]),
            "max_penetration_m": contact.max_penetration,
            "iterations": sol.iterations,
            "load_steps": sol.load_steps,
            "solve_statics_s": t_api,
            "binding_s": t_bind,
            "without_table_binding_s": t_free,
        }
        rows.append(row)
        print(
            f"  {p:4.0f} kPa: force {row['contact_force_N']:.4f} N, "
            f"{t_api * 1e6:7.1f} us (binding {t_bind * 1e6:7.1f} us; without the table "
            f"{t_free * 1e6:6.1f} us), {sol.iterations} Newton iterations"
        )
    worst = max(r["solve_statics_s"] for r in rows)
    print(f"slowest cold solve {worst * 1e6:.1f} us (target < {TARGET_S * 1e6:.0f} us)")
    friction = frictional_batch(design, args.quick)
    mesh = mesh_case(design, reps)
    return {
        **result_header("contact", args.quick, info, design=DESIGN),
        "repetitions": reps,
        "rows": rows,
        "slowest_cold_solve_s": worst,
        "target_s": TARGET_S,
        "target_met": worst < TARGET_S,
        "frictional_batch": friction,
        "mesh_table": mesh,
        "wall_time_s": time.perf_counter() - t_start,
    }


if __name__ == "__main__":
    sys.exit(bench_main(sys.argv[1:], __doc__, "contact", run))
