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

Calibration of a system (``calibrate_system``): 30 equilibria of ``two_spa_platform``
(each chamber off or at 5-30 kPa) with the platform and four markers, one thread: a batch
of cold solves against the same batch with the exact derivatives of the platform and the
markers with respect to three parameters (the body's E, rod 1's c_e, the platform's mass;
``_core.rod_system_sensitivity_batch``), and the whole fit from the bundled values
(examples/calibrate_two_spa_platform.py's, 0.1 mm of noise).
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


def _calibration(system, reps: int) -> dict:
    """The system's batch with and without parameter derivatives, and one whole fit."""
    import numpy as np
    from softrod import _core
    from softrod.calibration.system import calibrated_system, parse_system_parameters
    from softrod.system import _batch_entries, _platform_args

    names = ["E[ecoflex_00_50_table1]", "rods[1].c_e", "platform_mass"]
    params = parse_system_parameters(names, system)
    bundled = np.array([p.value(system) for p in params])
    truth = calibrated_system(system, params, bundled * [1.15, 0.9, 1.25])
    rng = np.random.default_rng(4)
    pressures = rng.uniform(5e3, 30e3, size=(30, 2, 3)) * (rng.random((30, 2, 3)) < 0.5)
    markers = [
        ("platform", ["20 mm", "0 mm", "5 mm"]),
        ("platform", ["-20 mm", "10 mm", "0 mm"]),
        ("rod0", "60 mm", ["21.1 mm", "0 mm"]),
        ("rod1", "90 mm", ["0 mm", "21.1 mm"]),
    ]
    data = softrod.synthesize_system_dataset(
        truth, pressures, markers=markers, noise_mm=0.1, seed=7
    )
    core_markers = [
        (None, 0.0, [0.02, 0.0, 0.005]),
        (None, 0.0, [-0.02, 0.01, 0.0]),
        (0, 0.06, [0.0211, 0.0, 0.0]),
        (1, 0.09, [0.0, 0.0211, 0.0]),
    ]
    flat = np.ascontiguousarray(data.pressures)

    def batch(with_params: bool):
        return _core.rod_system_sensitivity_batch(
            _batch_entries(system),
            _platform_args(system, None, None),
            flat,
            [p.core() for p in params] if with_params else [],
            markers=core_markers,
            threads=1,
        )

    plain = median(timed(lambda: batch(False), reps))
    derived = median(timed(lambda: batch(True), reps))
    fit = median(
        timed(
            lambda: softrod.calibrate_system(system, data, names, threads=1, progress=False),
            max(1, reps // 3),
        )
    )
    result = softrod.calibrate_system(system, data, names, threads=1, progress=False)
    print(f"  30-row batch, cold, 1 thread       {plain * 1e3:8.2f} ms")
    print(f"  ... with 3 parameters' derivatives  {derived * 1e3:8.2f} ms ({derived / plain:.2f}x)")
    evals = result.evaluations
    print(f"  calibrate_system, 3 parameters      {fit * 1e3:8.2f} ms ({evals} evaluations)")
    return {
        "rows": 30,
        "parameters": names,
        "batch_s": plain,
        "batch_with_derivatives_s": derived,
        "derivative_ratio": derived / plain,
        "fit_s": fit,
        "fit_evaluations": int(result.evaluations),
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
    calibration = _calibration(platform, reps)
    info["load_average_after"] = load_average()
    return {
        **result_header("system_statics", args.quick, info),
        "repetitions": reps,
        "friction": MU,
        "friction_steps": softrod.SolverOptions().friction_steps,
        "rows": rows,
        "calibration": calibration,
        "wall_time_s": time.perf_counter() - t_start,
    }


if __name__ == "__main__":
    sys.exit(bench_main(sys.argv[1:], __doc__, "system_statics", run))
