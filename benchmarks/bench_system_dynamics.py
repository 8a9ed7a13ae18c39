"""Cost of a time step of a system of rods in motion (``SystemSimulation``) against one held
actuator alone (a script, not a test).

    python benchmarks/bench_system_dynamics.py          # full (~5 s): system_dynamics.json
    python benchmarks/bench_system_dynamics.py --quick  # smoke (~2 s): system_dynamics_quick.json

One core: RAYON_NUM_THREADS = 1 is set before softrod is imported. Wall-clock times
(time.perf_counter) of ``run`` only (the start, a static solve, is not timed), garbage
collector off, medians of repeated runs after a warm-up run; the CPU time of the process is
recorded too (on a shared machine the wall adds the waits for the core).

1. **Two-rod system** (the bundled ``two_spa_platform``: two of paper 001's actuators holding
   a 20 g platform), dt = 2 ms, the left actuator's channel 0 stepped to 40 kPa at t = 0:
   the bundled (undamped) rods for 0.2 s, and the rods damped with tau = 50 ms (as
   examples/two_spa_platform_motion.py) for 0.5 s. Milliseconds per step, Newton
   iterations and Jacobians (bordered matrices factored) per step.
2. **One held actuator**: the system's left actuator alone, its tip clamped where the
   platform holds it at rest, the same step and dt: the cost a rod's share of the system
   would have on its own. The ratio of (1) to (2) is reported.
3. **Sensitivities** (``calibrate_system(dynamic=True)``'s engine): the damped two-rod
   system of (1) run with the exact forward sensitivities of one parameter (the body's E
   on both rods) and of two (E and the platform's mass) tracked, against the same run
   untracked; ratios reported.
"""

from __future__ import annotations

import os

os.environ["RAYON_NUM_THREADS"] = "1"

import dataclasses  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import softrod  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import (  # noqa: E402
    bench_main,
    gc_disabled,
    load_average,
    machine,
    median,
    result_header,
)

SYSTEM = "two_spa_platform"
DT = 2e-3
STEP_PA = 40e3


def _commands():
    return [[STEP_PA, 0.0, 0.0], [0.0, 0.0, 0.0]]


def _damped(system, tau: str):
    rods = [
        dataclasses.replace(r, design=r.design.replace({"dynamics.damping_time": tau}))
        for r in system.rods
    ]
    return dataclasses.replace(system, rods=rods)


def _timed(make, go, reps: int) -> dict:
    """Medians over ``reps`` runs (after a warm-up) of ``go(make())``, only ``go`` timed;
    ``go`` returns (steps, stats)."""
    walls, cpus, out = [], [], None
    go(make())  # warm-up
    with gc_disabled():
        for _ in range(reps):
            sim = make()
            t0, c0 = time.perf_counter(), time.process_time()
            out = go(sim)
            walls.append(time.perf_counter() - t0)
            cpus.append(time.process_time() - c0)
    steps, stats = out
    return {
        "steps": steps,
        "wall_s": median(walls),
        "walls_s": walls,
        "cpu_s": median(cpus),
        "ms_per_step": median(walls) / steps * 1e3,
        "cpu_ms_per_step": median(cpus) / steps * 1e3,
        "newton_iterations_per_step": stats["newton_iterations"] / stats["internal_steps"],
        "jacobians_per_step": stats["jacobians"] / stats["internal_steps"],
        "jacobians": int(stats["jacobians"]),
        "internal_steps": int(stats["internal_steps"]),
    }


def _report(name: str, row: dict, reps: int) -> None:
    print(
        f"    {name}: {row['ms_per_step']:.3f} ms/step wall, {row['cpu_ms_per_step']:.3f} ms/step "
        f"CPU (medians of {reps}), {row['steps']} steps, "
        f"{row['newton_iterations_per_step']:.2f} Newton it/step, "
        f"{row['jacobians_per_step']:.3f} Jacobians/step"
    )


def run_system(quick: bool) -> dict:
    print(f"\n[1] {SYSTEM}: dt {DT * 1e3:g} ms, left channel 0 stepped to {STEP_PA / 1e3:g} kPa")
    bundled = softrod.load_system(SYSTEM)
    reps = 2 if quick else 5
    rows = []
    for name, system, t_end in (
        ("bundled (undamped)", bundled, 0.1 if quick else 0.2),
        ("damped, tau 50 ms", _damped(bundled, "50 ms"), 0.1 if quick else 0.5),
    ):

        def make(system=system):
            return softrod.SystemSimulation(system, [[0.0] * 3, [0.0] * 3], dt=DT)

        def go(sim, t_end=t_end):
            sim.run(_commands(), t_end)
            return sim.stats["steps"], sim.stats

        row = {"setting": name, "t_end_s": t_end, **_timed(make, go, reps)}
        rows.append(row)
        _report(name, row, reps)
    return {"system": SYSTEM, "dt_s": DT, "repetitions": reps, "runs": rows}


def run_held(quick: bool) -> dict:
    print(
        "\n[2] one held actuator: the left rod alone, its tip clamped where the platform holds it"
    )
    system = softrod.load_system(SYSTEM)
    rest = softrod.solve_system(system, [[0.0] * 3, [0.0] * 3])
    rod = system.rods[0]
    rot = np.asarray(rest.platform_rotation)
    tip = np.asarray(rest.platform_position) + rot @ np.asarray(rod.attachment, dtype=float)
    hold = softrod.TipConstraint.clamped(
        [f"{x} m" for x in tip], rot @ np.asarray(rod.attachment_rotation, dtype=float)
    )
    reps = 2 if quick else 5
    t_end = 0.1 if quick else 0.2

    def make():
        return softrod.Simulation(rod.design, [0.0] * 3, dt=DT, tip_constraint=hold)

    def go(sim):
        sim.run([STEP_PA, 0.0, 0.0], t_end)
        return sim.stats["steps"], sim.stats

    row = {"setting": "left actuator, tip clamped", "t_end_s": t_end, **_timed(make, go, reps)}
    _report(row["setting"], row, reps)
    return {"design": rod.design.name, "dt_s": DT, "repetitions": reps, **row}


def run_tracked(quick: bool) -> dict:
    print("\n[3] forward parameter sensitivities (damped system, tau 50 ms)")
    from softrod.calibration.system import parse_system_parameters

    system = _damped(softrod.load_system(SYSTEM), "50 ms")
    reps = 2 if quick else 5
    t_end = 0.1 if quick else 0.3
    rows = []
    for names in ([], ["E"], ["E", "platform_mass"]):
        params = [p.core() for p in parse_system_parameters(names, system)] if names else []

        def make(params=params):
            sim = softrod.SystemSimulation(system, [[0.0] * 3, [0.0] * 3], dt=DT)
            if params:
                sim._sim.track_sensitivities(params)
            return sim

        def go(sim):
            sim.run(_commands(), t_end)
            return sim.stats["steps"], sim.stats

        label = "untracked" if not names else "tracked: " + ", ".join(names)
        row = {"setting": label, "t_end_s": t_end, **_timed(make, go, reps)}
        rows.append(row)
        _report(label, row, reps)
    base = rows[0]["cpu_s"]
    ratios = {r["setting"]: r["cpu_s"] / base for r in rows[1:]}
    for name, x in ratios.items():
        print(f"    {name}: {x:.2f}x the untracked run (CPU)")
    return {"system": SYSTEM, "dt_s": DT, "repetitions": reps, "runs": rows, "ratio": ratios}


def run(quick: bool) -> dict:
    t_start = time.perf_counter()
    info = machine()
    info["threads"] = "RAYON_NUM_THREADS = 1"
    print(
        f"softrod system dynamics benchmark, {'quick' if quick else 'full'} mode; machine: "
        f"{info['cpu_count']} CPUs, softrod {info['softrod']} ({info['git_commit']}), load "
        f"average {info['load_average_before']}"
    )
    system = run_system(quick)
    held = run_held(quick)
    tracked = run_tracked(quick)
    ratio = {r["setting"]: r["ms_per_step"] / held["ms_per_step"] for r in system["runs"]}
    for name, x in ratio.items():
        print(f"    {name}: {x:.1f}x the held actuator's cost per step")
    info["load_average_after"] = load_average()
    return {
        **result_header("system_dynamics", quick, info),
        "units": "seconds; ms per step",
        "system": system,
        "held_actuator": held,
        "system_to_held_ratio": ratio,
        "sensitivities": tracked,
        "wall_time_s": time.perf_counter() - t_start,
    }


def main(argv=None) -> int:
    return bench_main(argv, __doc__, "system_dynamics", lambda args: run(args.quick))


if __name__ == "__main__":
    sys.exit(main())
