"""Cost of a paper-002-sized global calibration (a script, not a test).

    python benchmarks/bench_calibration.py           # full run (~30 s), results/calibration.json
    python benchmarks/bench_calibration.py --quick   # smoke run (< 20 s)

Issue 4, item 7: "a paper-002-sized fit (4 experiments, 60 equilibria each, 5 parameters) in at
most 2 s". Paper 002's model M3 (``paper002_M3_vertical``: Ogden law, chamber offset, swelling)
at the default numerics (16 RK4 steps per section) makes a SYNTHETIC dataset: 4 experiments of
60 equilibria (each chamber alone ramped to 60 kPa, then chambers 1+2 together), 0.2 mm
Gaussian noise per axis, with c_b = 1.45, c_e = 2.6, alpha = 7, offsets (0.5, 1.2) mm. The fit
starts from the Table IV values (c_b 1.31, c_e 2.82, alpha 8.89, offsets (0.89, 0.98) mm) and
frees those 5 parameters; experiment 4 is the test set. Timed: the whole ``softrod.calibrate``
call (design rebuilds, parallel batches with exact Jacobians, the final predictions on all 240
samples, error tables), median of repeats, both methods (``lm`` and paper 002's
``nelder-mead``, the latter capped at 200 model evaluations as in calibrate's default).
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

import numpy as np
import softrod
from softrod.calibration import CalibrationWarning, calibrate
from softrod.calibration.params import design_changes, parse_parameters

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import bench_main, machine, median, result_header  # noqa: E402

PARAMS = ["c_b", "c_e", "alpha", "offset_1", "offset_2"]
TRUTH = [1.45, 2.6, 7.0, 0.5e-3, 1.2e-3]
TARGET_S = 2.0


def dataset(design):
    ramp = 60e3 * np.arange(1, 61) / 60
    patterns = ([1, 0, 0], [0, 1, 0], [0, 0, 1], [0.6, 0.4, 0])
    p = np.vstack([np.outer(ramp, q) for q in patterns])
    made = design.replace(design_changes(parse_parameters(PARAMS, design), TRUTH, design))
    return softrod.synthesize_dataset(
        made, p, noise_mm=0.2, seed=2, experiment=np.repeat(np.arange(4), 60)
    )


def run(args) -> dict:
    t_start = time.perf_counter()
    info = machine()
    design = softrod.load_design("paper002_M3_vertical")
    data = dataset(design)
    reps = 2 if args.quick else 7
    out = {}
    for method in ("lm", "nelder-mead"):
        times, res = [], None
        for _ in range(reps if method == "lm" else max(1, reps // 3)):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", CalibrationWarning)
                t0 = time.perf_counter()
                res = calibrate(design, data, PARAMS, method=method, split="experiment", test=3)
                times.append(time.perf_counter() - t0)
        table = res.error_table.set_index("set")
        out[method] = {
            "median_s": median(times),
            "times_s": times,
            "model_evaluations": res.evaluations,
            "success": res.success,
            "values": dict(zip(res.names, res.values.tolist(), strict=True)),
            "std_errors": dict(zip(res.names, res.std_errors.tolist(), strict=True)),
            "train_mean_error_mm": float(table.loc["train", "mean_error_mm"]),
            "test_mean_error_mm": float(table.loc["test", "mean_error_mm"]),
            "warnings": list(res.warnings),
        }
        print(
            f"{method:12s} median {out[method]['median_s']:.3f} s over {len(times)} runs, "
            f"{res.evaluations} evaluations, test mean error "
            f"{out[method]['test_mean_error_mm']:.3f} mm"
        )
    met = out["lm"]["median_s"] <= TARGET_S
    print(f"target: lm fit <= {TARGET_S} s -> {'met' if met else 'MISSED'}")
    return {
        **result_header(
            "calibration",
            args.quick,
            info,
            design="paper002_M3_vertical (SYNTHETIC data, noise 0.2 mm)",
            samples=len(data),
            parameters=PARAMS,
            truth=dict(zip(PARAMS, TRUTH, strict=True)),
            target_s=TARGET_S,
        ),
        "results": out,
        "wall_time_s": time.perf_counter() - t_start,
    }


if __name__ == "__main__":
    sys.exit(bench_main(sys.argv[1:], __doc__, "calibration", run))
