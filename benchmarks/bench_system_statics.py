"""System statics benchmark (a script, not a test): cold `solve_system` of systems of rods,
frictionless and on a frictional load path.

    python benchmarks/bench_system_statics.py            # full run, results/system_statics.json
    python benchmarks/bench_system_statics.py --quick    # smoke run (< 20 s)

Systems: the bundled ``two_spa_platform`` (two of paper 001's actuators holding a 20 g
platform, the left one's channel 0 at 0, 30 and 60 kPa), and the bundled
``two_fingers_on_table`` (two ``prebent_finger_on_table`` fingers 30 mm apart whose tips
hold one clip) pressed onto their table at 10 to 40 kPa, without and with Coulomb friction
mu = 0.5 on the table (``SolverOptions().friction_steps`` increments), against one rough
finger alone. Medians of
wall-clock times of cold solves, garbage collector off.
"""

from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

import softrod

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import bench_main, load_average, machine, median, result_header, timed  # noqa: E402
from softrod.system import solve_system  # noqa: E402

MU = 0.5

PLATFORM_KPA = [0.0, 30.0, 60.0]
FINGER_KPA = [10.0, 20.0, 30.0, 40.0]


def _row(label: str, fn, reps: int) -> dict:
    sol = fn()
    t = median(timed(fn, reps))
    print(f"  {label:<34} {t * 1e3:8.2f} ms  ({sol.load_steps} steps, {sol.iterations} it)")
    return {
        "case": label,
        "solve_s": t,
        "load_steps": int(sol.load_steps),
        "iterations": int(sol.iterations),
    }


def run(args) -> dict:
    t_start = time.perf_counter()
    reps = 3 if args.quick else 9
    info = machine()
    print(f"cold solve_system, median of {reps} (load {load_average()})")
    platform = softrod.load_system("two_spa_platform")
    rough = softrod.load_design("prebent_finger_on_table").replace({"obstacles[0].friction": MU})
    smooth_pair = softrod.load_system("two_fingers_on_table")
    rough_rods = tuple(
        dataclasses.replace(r, design=r.design.replace({"obstacles[0].friction": MU}))
        for r in smooth_pair.rods
    )
    rough_pair = dataclasses.replace(smooth_pair, rods=rough_rods)
    rows = []
    for p in PLATFORM_KPA:
        ps = [[p * 1e3, 0.0, 0.0], [0.0, 0.0, 0.0]]
        rows.append(
            _row(
                f"two_spa_platform {p:g} kPa",
                lambda ps=ps: solve_system(platform, ps, on_unstable="ignore"),
                reps,
            )
        )
    for p in FINGER_KPA:
        both = [[p * 1e3], [p * 1e3]]
        rows.append(
            _row(f"two fingers {p:g} kPa", lambda b=both: solve_system(smooth_pair, b), reps)
        )
        rows.append(
            _row(f"two rough fingers {p:g} kPa", lambda b=both: solve_system(rough_pair, b), reps)
        )
        rows.append(
            _row(
                f"one rough finger {p:g} kPa",
                lambda p=p: softrod.solve_statics(rough, [p * 1e3]),
                reps,
            )
        )
    info["load_average_after"] = load_average()
    return {
        **result_header("system_statics", args.quick, info),
        "repetitions": reps,
        "friction": MU,
        "friction_steps": softrod.SolverOptions().friction_steps,
        "rows": rows,
        "wall_time_s": time.perf_counter() - t_start,
    }


if __name__ == "__main__":
    sys.exit(bench_main(sys.argv[1:], __doc__, "system_statics", run))
