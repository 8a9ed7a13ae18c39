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
    return {
        **result_header("contact", args.quick, info, design=DESIGN),
        "repetitions": reps,
        "rows": rows,
        "slowest_cold_solve_s": worst,
        "target_s": TARGET_S,
        "target_met": worst < TARGET_S,
        "frictional_batch": friction,
        "wall_time_s": time.perf_counter() - t_start,
    }


if __name__ == "__main__":
    sys.exit(bench_main(sys.argv[1:], __doc__, "contact", run))
