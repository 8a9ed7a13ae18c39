"""Cold starts, the sweep and batch-equals-single of the static solver (a script, not a test).

    python benchmarks/bench_statics_robust.py           # writes results/statics_robust.json
    python benchmarks/bench_statics_robust.py --quick   # smoke run

1. The soft cantilever of issue 14 (L = 0.22 m, r = 12.5 mm, E = 100 kPa, nu = 0.5,
   1000 kg/m^3, mounted horizontally, 20 RK4 steps): cold static solve under gravity, where
   the tip sags by about 0.4 L and Newton from the straight rod fails, so the solver needs its
   load continuation. Target: <= 100 us.
2. ``spa_three_chamber_130mm`` (paper 001, 0-70 kPa) at its design file's steps: cold solves at
   the representative pressures of bench_statics.py. Target: no slower than before (~30 us).
3. The 21^3 = 9261-point sweep 0-70 kPa (``solve_statics_batch``), threads=0 and threads=1.
   Target: <= 0.3 s (threads=0).
4. Batch equals single: every row of a 200-row random batch against ``solve_statics`` of the
   same row, for 1, 2 and 4 threads; counts rows that are not bitwise equal.
All times are medians of wall-clock times with the garbage collector off.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import softrod

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import (  # noqa: E402
    KPA,
    P001_PRESSURES_KPA,
    bench_main,
    binding_solver,
    kpa,
    load_average,
    machine,
    median,
    result_header,
    timed,
)

TARGETS = {"soft_cantilever_s": 100e-6, "sweep_s": 0.3}


def soft_cantilever(steps: int = 20) -> softrod.Design:
    """Issue 14's soft cantilever: 0.22 m, r 12.5 mm, E 100 kPa, nu 0.5, 1000 kg/m^3."""
    return softrod.load_design(
        {
            "design": {
                "name": "soft_cantilever_220mm",
                "citation": "issue 14 benchmark: 0.22 m, r = 12.5 mm, E = 100 kPa, nu = 0.5",
            },
            "mounting": {"orientation": "horizontal"},
            "materials": {"soft": {"E": "100 kPa", "poisson": 0.5, "density": "1000 kg/m^3"}},
            "sections": [
                {
                    "name": "rod",
                    "length": "0.22 m",
                    "outer_radius": "12.5 mm",
                    "material": "soft",
                    "steps": steps,
                }
            ],
        }
    )


def fmt_us(seconds: float) -> str:
    return f"{seconds * 1e6:.1f} us"


def run(args) -> dict:
    quick = args.quick
    t_start = time.perf_counter()
    info = machine()
    reps = 50 if quick else 1000
    print(f"softrod statics robustness benchmark, {'quick' if quick else 'full'} mode")
    print(
        f"machine: {info['cpu_count']} CPUs, {info['platform']}, softrod {info['softrod']} "
        f"({info['git_commit']}), load average {info['load_average_before']}"
    )

    # 1. Soft cantilever cold solve ---------------------------------------------------------
    cant = soft_cantilever()
    sol = softrod.solve_statics(cant, [])
    api = lambda: softrod.solve_statics(cant, [])  # noqa: E731
    core = binding_solver(cant, [])
    timed(api, 20)
    cant_api = median(timed(api, reps))
    cant_core = median(timed(core, reps))
    sag = float(-sol.tip_position[2]) / cant.length
    print(
        f"\n[1] soft cantilever cold solve (20 RK4 steps): solve_statics {fmt_us(cant_api)}, "
        f"_rod.solve {fmt_us(cant_core)}; {sol.iterations} Newton iterations over "
        f"{sol.load_steps} load levels; tip sag {sag:.4f} L"
    )

    # 2. spa_three_chamber_130mm cold solves ------------------------------------------------
    spa = softrod.load_design("spa_three_chamber_130mm")
    spa_rows = {}
    for p in P001_PRESSURES_KPA:
        pp = kpa(p)
        s = softrod.solve_statics(spa, pp)
        f = lambda pp=pp: softrod.solve_statics(spa, pp)  # noqa: E731
        timed(f, 20)
        spa_rows[str(p)] = {
            "api_s": median(timed(f, reps // 2)),
            "binding_s": median(timed(binding_solver(spa, pp), reps // 2)),
            "iterations": int(s.iterations),
        }
    spa_api = median([v["api_s"] for v in spa_rows.values()])
    spa_core = median([v["binding_s"] for v in spa_rows.values()])
    print(
        f"\n[2] spa_three_chamber_130mm cold solves ({len(spa_rows)} pressures): "
        f"solve_statics {fmt_us(spa_api)}, _rod.solve {fmt_us(spa_core)} (medians)"
    )
    for p, v in spa_rows.items():
        print(
            f"    {p:<20} {fmt_us(v['api_s']):>10} {fmt_us(v['binding_s']):>10} "
            f"{v['iterations']:>3} iterations"
        )

    # 3. Sweep ------------------------------------------------------------------------------
    grid = np.linspace(0.0, 70.0 * KPA, 21)
    pressures = np.stack(np.meshgrid(grid, grid, grid, indexing="ij"), axis=-1).reshape(-1, 3)
    runs = 1 if quick else 5
    sweep = {}
    for threads in (0, 1):
        softrod.solve_statics_batch(spa, pressures[:200], threads=threads)
        times = []
        for _ in range(runs):
            t0 = time.perf_counter_ns()
            b = softrod.solve_statics_batch(spa, pressures, threads=threads)
            times.append((time.perf_counter_ns() - t0) * 1e-9)
        sweep[threads] = {
            "time_s": median(times),
            "converged": int(np.count_nonzero(b.converged)),
        }
    print(
        f"\n[3] sweep 21^3 = 9261 points: threads=0 {sweep[0]['time_s']:.3f} s, threads=1 "
        f"{sweep[1]['time_s']:.3f} s; converged {sweep[0]['converged']}/{len(pressures)}"
    )

    # 4. Batch equals single ----------------------------------------------------------------
    rng = np.random.default_rng(1)
    rows = rng.uniform(0.0, 70.0 * KPA, size=(200, 3))
    single = np.array([softrod.solve_statics(spa, r).tip_position for r in rows])
    equal = {}
    for threads in (1, 2, 4):
        b = softrod.solve_statics_batch(spa, rows, threads=threads)
        diff = np.abs(b.tip_position - single).max(axis=1)
        equal[threads] = {
            "rows_not_bitwise_equal": int(np.count_nonzero(diff != 0.0)),
            "rows_differing_over_1e-12_m": int(np.count_nonzero(diff > 1e-12)),
            "max_difference_m": float(diff.max()),
        }
        print(
            f"\n[4] batch vs single, threads={threads}: "
            f"{equal[threads]['rows_not_bitwise_equal']}/200 rows not bitwise equal, "
            f"{equal[threads]['rows_differing_over_1e-12_m']} differ by > 1e-12 m, max "
            f"{equal[threads]['max_difference_m']:.2e} m"
        )

    checks = {
        "soft_cantilever": cant_api <= TARGETS["soft_cantilever_s"],
        "sweep": sweep[0]["time_s"] <= TARGETS["sweep_s"],
        "batch_equals_single": all(v["rows_not_bitwise_equal"] == 0 for v in equal.values()),
    }
    print(f"\nchecks: {checks}; load average now {load_average()}")
    info["load_average_after"] = load_average()
    return {
        **result_header("statics_robust", quick, info),
        "units": "seconds",
        "soft_cantilever": {
            "api_s": cant_api,
            "binding_s": cant_core,
            "iterations": int(sol.iterations),
            "load_steps": int(sol.load_steps),
            "tip_sag_over_L": sag,
        },
        "spa_three_chamber_130mm": {
            "api_s": spa_api,
            "binding_s": spa_core,
            "by_pressure_kPa": spa_rows,
        },
        "sweep_9261": {str(k): v for k, v in sweep.items()},
        "batch_vs_single_200_rows": {str(k): v for k, v in equal.items()},
        "targets": TARGETS,
        "checks": checks,
        "wall_time_s": time.perf_counter() - t_start,
    }


if __name__ == "__main__":
    sys.exit(bench_main(sys.argv[1:], __doc__, "statics_robust", run))
