"""Control tools on ``spa_three_chamber_130mm`` (a script, not a test).

    python benchmarks/bench_control.py          # full run (~1 min), writes results/control.json
    python benchmarks/bench_control.py --quick  # smoke run (~10 s), results/control_quick.json

1. **Warm-started inverse statics** through the Python API: an :class:`InverseProblem`
   (bounds 0-70 kPa, tip position target) solved for a target moving 0.5 mm per call along
   a circle of 10 mm radius around the tip at 35 kPa in every chamber, each call warm-started
   from the previous answer (``initial=previous``). Per-call wall times (time.perf_counter_ns,
   garbage collector off) after a warm-up; the rate is 1 / median. Also the CPU time of the
   whole loop per call (time.thread_time: less sensitive to other jobs on a shared machine),
   the dual passes per call and the worst tip distance (all calls must reach the target).
   The same for ``solve_inverse(design, target, initial=previous, ...)`` (the function, which
   reads its arguments anew on each call), and the cold start (``problem.solve(target)``
   without ``initial``) at 7 targets. Run at the design file's 16 steps per section and at
   the 13 mm steps that bench_statics uses for its timings (the largest meeting 1e-6 L).
   One core: RAYON_NUM_THREADS = 1 (the inverse is sequential).
2. **Workspace** of the actuator, 21 x 21 boundary samples on each of the 6 faces of the
   pressure box (2646 solves): ``softrod.workspace`` on 2 cores and on 1, median of 5 runs
   each (alternating), at the design file's steps.

3. **Jacobians and linearisations** (no target; what they cost): `StaticSolution.jacobian()`
   of a free tip and of a tip clamped 6 mm aside of it (the reaction's derivatives too),
   `SystemSolution.jacobian()` of the bundled two-rod platform (six pressures and the
   platform's load), `linearise` with a free tip (12 nodes), a clamped one (11 nodes) and a
   pinned one (12 nodes), from a solved equilibrium, and `SystemSolution.linearise()` of
   the two-rod platform (8 nodes per rod). With six shooting unknowns and the free tip's
   balance: `linearise` under a follower tip force (the actuator, 12 nodes) and of the
   bundled finger pressed onto its table at 20 kPa (contact, 10 nodes). A long, soft arm
   that statics solves by collocation (1 m, 64 steps, EI = 1e-3 N m^2, 100 g, hanging, one
   chamber at 3 kPa): its `jacobian()` and `linearise` (16 nodes), by implicit
   differentiation of the collocation equations. Median wall time of repeated calls, one
   core.

4. **Inverse of the long, soft arm** (collocation iterates, docs/control.md "Long, soft
   rods"): cold `solve_inverse` of the tip where the arm hangs at 3 kPa (from 0 Pa), and
   `InverseProblem.solve` warm-started from the previous answer along the tips of 3.0-4.0
   kPa (0.1 kPa apart, about 1 mm of tip motion per call). Median wall times, one core.

The machine's load average before and after is recorded: on a shared machine wall times
stretch with the load, CPU times much less.
"""

from __future__ import annotations

import math
import os
import sys
import time

os.environ.setdefault("RAYON_NUM_THREADS", "2")

import numpy as np  # noqa: E402
import softrod  # noqa: E402
from common import (  # noqa: E402
    bench_main,
    gc_disabled,
    load_average,
    machine,
    median,
    result_header,
    steps_of,
    with_step_length,
)

DESIGN = "spa_three_chamber_130mm"
#: A 1 m arm, soft in bending: single shooting's growth exponent is about 20 (> 12), so
#: statics solves it by collocation (docs/model.md, "Collocation").
LONG_SOFT_ARM = "long_soft_arm_1m"
BOUNDS = (0.0, 70e3)
STEP = 0.5e-3  # m per call
RADIUS = 10e-3  # m


def _targets(centre: np.ndarray, n: int) -> list[np.ndarray]:
    da = STEP / RADIUS
    return [centre + RADIUS * np.array([math.cos(k * da), math.sin(k * da), 0.0]) for k in range(n)]


def _inverse(design, n_calls: int, warmup: int) -> dict:
    problem = softrod.InverseProblem(design, pressure_bounds=BOUNDS)
    centre = softrod.solve_statics(design, [35e3] * 3).tip_position
    targets = _targets(centre, n_calls + warmup + 1)
    prev = problem.solve(targets[0])
    for t in targets[1 : warmup + 1]:
        prev = problem.solve(t, initial=prev)
    times, passes, worst = [], 0, 0.0
    with gc_disabled():
        cpu0 = time.thread_time()
        for t in targets[warmup + 1 :]:
            t0 = time.perf_counter_ns()
            prev = problem.solve(t, initial=prev)
            times.append((time.perf_counter_ns() - t0) * 1e-9)
            passes += prev.passes
            worst = max(worst, prev.distance)
            assert prev.reached
        cpu = (time.thread_time() - cpu0) / n_calls
    # The one-shot function (arguments read on every call).
    fn_times = []
    with gc_disabled():
        for t in targets[1 : min(len(targets), 1 + n_calls // 4)]:
            t0 = time.perf_counter_ns()
            prev = softrod.solve_inverse(design, t, pressure_bounds=BOUNDS, initial=prev)
            fn_times.append((time.perf_counter_ns() - t0) * 1e-9)
    cold = []
    for p in (
        [10e3, 0, 0],
        [70e3, 0, 0],
        [35e3, 35e3, 0],
        [20e3, 45e3, 70e3],
        [70e3, 35e3, 10e3],
        [5e3, 5e3, 60e3],
        [50e3, 50e3, 50e3],
    ):
        tip = softrod.solve_statics(design, p).tip_position
        with gc_disabled():
            t0 = time.perf_counter_ns()
            sol = problem.solve(tip)
            cold.append((time.perf_counter_ns() - t0) * 1e-9)
        assert sol.reached
    med = median(times)
    return {
        "steps": steps_of(design),
        "calls": n_calls,
        "median_us": med * 1e6,
        "p90_us": float(np.percentile(times, 90)) * 1e6,
        "rate_kHz": 1e-3 / med,
        "cpu_per_call_us": cpu * 1e6,
        "rate_by_cpu_kHz": 1e-3 / cpu,
        "dual_passes_per_call": passes / n_calls,
        "worst_tip_distance_over_L": worst / design.length,
        "function_median_us": median(fn_times) * 1e6,
        "cold_median_us": median(cold) * 1e6,
    }


def _workspace(design, runs: int) -> dict:
    out = {"solves": None, "two_cores_s": [], "one_core_s": []}
    for r in range(runs):
        order = (2, 1) if r % 2 == 0 else (1, 2)
        for threads in order:
            t0 = time.perf_counter()
            ws = softrod.workspace(design, pressure_bounds=BOUNDS, samples=21, threads=threads)
            wall = time.perf_counter() - t0
            out["two_cores_s" if threads == 2 else "one_core_s"].append(wall)
            out["solves"] = int(len(ws.converged))
            out["converged"] = int(ws.converged.sum())
    out["two_cores_median_s"] = median(out["two_cores_s"])
    out["one_core_median_s"] = median(out["one_core_s"])
    out["speed_up"] = out["one_core_median_s"] / out["two_cores_median_s"]
    return out


def _derivatives(design, calls: int) -> dict:
    """Median wall times (ms) of the Jacobians and linearisations of section 3."""
    p = [30e3, 5e3, 45e3]
    free = softrod.solve_statics(design, p)
    clamp = softrod.TipConstraint.clamped(free.tip_position + [0.006, 0, 0], free.tip_rotation)
    held = softrod.solve_statics(design, p, tip_constraint=clamp)
    pin = softrod.TipConstraint.pinned(free.tip_position + [0.006, 0, 0])
    pinned = softrod.solve_statics(design, p, tip_constraint=pin)
    pcr = softrod.solve_system("two_spa_platform", [[20e3, 5e3, 3e3], [2e3, 15e3, 10e3]])
    turning = design.replace({"tip.frame": "body", "tip.force": ["20 mN", "-10 mN", "-30 mN"]})
    follower = softrod.solve_statics(turning, p)
    finger = softrod.solve_statics("prebent_finger_on_table", [20e3])
    long_arm = softrod.solve_statics(LONG_SOFT_ARM, [3e3])

    def timed(fn, n: int) -> float:
        fn()  # warm-up (imports, caches)
        times = []
        with gc_disabled():
            for _ in range(n):
                t0 = time.perf_counter_ns()
                fn()
                times.append((time.perf_counter_ns() - t0) * 1e-9)
        return median(times) * 1e3

    return {
        "jacobian_free_tip_ms": timed(free.jacobian, calls),
        "jacobian_clamped_tip_ms": timed(held.jacobian, calls),
        "system_jacobian_ms": timed(pcr.jacobian, calls),
        "linearise_free_12_nodes_ms": timed(lambda: softrod.linearise(free, nodes=12), calls // 5),
        "linearise_clamped_11_nodes_ms": timed(
            lambda: softrod.linearise(held, nodes=11), calls // 5
        ),
        "linearise_pinned_12_nodes_ms": timed(
            lambda: softrod.linearise(pinned, nodes=12), calls // 5
        ),
        "system_linearise_8_nodes_ms": timed(lambda: pcr.linearise(nodes=8), calls // 5),
        "linearise_follower_12_nodes_ms": timed(
            lambda: softrod.linearise(follower, nodes=12), calls // 5
        ),
        "linearise_finger_contact_10_nodes_ms": timed(
            lambda: softrod.linearise(finger, nodes=10), calls // 5
        ),
        "jacobian_collocation_arm_ms": timed(long_arm.jacobian, calls // 5),
        "linearise_collocation_arm_16_nodes_ms": timed(
            lambda: softrod.linearise(long_arm, nodes=16), calls // 5
        ),
    }


def _collocation_inverse(calls: int) -> dict:
    """Median wall times (ms) of section 4, and the iterations per warm call."""
    design = softrod.load_design(LONG_SOFT_ARM)
    bounds = [(0.0, 2e4)]
    target = softrod.solve_statics(design, [3e3]).tip_position
    path = [softrod.solve_statics(design, [p]).tip_position for p in np.linspace(3.1e3, 4e3, 10)]
    cold = []
    warm = []
    iterations = []
    problem = softrod.InverseProblem(design, pressure_bounds=bounds)
    with gc_disabled():
        for _ in range(calls):
            t0 = time.perf_counter_ns()
            prev = softrod.solve_inverse(design, target, pressure_bounds=bounds)
            cold.append((time.perf_counter_ns() - t0) * 1e-6)
            for goal in path:
                t0 = time.perf_counter_ns()
                prev = problem.solve(goal, initial=prev)
                warm.append((time.perf_counter_ns() - t0) * 1e-6)
                iterations.append(prev.iterations)
    return {
        "cold_ms": median(cold),
        "warm_ms": median(warm),
        "warm_iterations_mean": float(np.mean(iterations)),
    }


def run(args) -> dict:
    t_start = time.perf_counter()
    info = machine()
    design = softrod.load_design(DESIGN)
    coarse = with_step_length(design, 13)
    n, warm = (300, 50) if args.quick else (3000, 200)
    os.environ["RAYON_NUM_THREADS"] = "1"
    result = result_header("control", args.quick, info, design=DESIGN)
    result["inverse_design_steps"] = _inverse(design, n, warm)
    result["inverse_13mm_steps"] = _inverse(coarse, n, warm)
    result["workspace"] = _workspace(design, 2 if args.quick else 5)
    result["derivatives"] = _derivatives(design, 20 if args.quick else 200)
    result["collocation_inverse"] = _collocation_inverse(2 if args.quick else 10)
    info["load_average_after"] = load_average()
    result["wall_time_s"] = time.perf_counter() - t_start
    for key in ("inverse_design_steps", "inverse_13mm_steps"):
        r = result[key]
        print(
            f"{key}: {r['steps']} steps: warm median {r['median_us']:.1f} us "
            f"({r['rate_kHz']:.1f} kHz; CPU {r['cpu_per_call_us']:.1f} us = "
            f"{r['rate_by_cpu_kHz']:.1f} kHz), {r['dual_passes_per_call']:.3f} dual passes "
            f"per call; function {r['function_median_us']:.1f} us; cold "
            f"{r['cold_median_us']:.0f} us"
        )
    w = result["workspace"]
    print(
        f"workspace: {w['solves']} solves, 2 cores {w['two_cores_median_s']:.3f} s, "
        f"1 core {w['one_core_median_s']:.3f} s"
    )
    d = result["derivatives"]
    print(
        "derivatives (median ms): "
        + ", ".join(f"{k.removesuffix('_ms')} {v:.3f}" for k, v in d.items())
    )
    c = result["collocation_inverse"]
    print(
        f"long soft arm inverse: cold {c['cold_ms']:.2f} ms, warm {c['warm_ms']:.2f} ms "
        f"({c['warm_iterations_mean']:.1f} iterations per warm call)"
    )
    print(f"load average before {info['load_average_before']}, after {info['load_average_after']}")
    return result


if __name__ == "__main__":
    sys.exit(bench_main(sys.argv[1:], __doc__, "control", run))
