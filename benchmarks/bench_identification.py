"""Per-sample stiffness identification benchmark (a script, not a test).

    python benchmarks/bench_identification.py          # full run -> results/identification.json
    python benchmarks/bench_identification.py --quick  # smoke run (< 20 s), 11^3 poses

Paper 001's dataset size: the 21^3 = 9261 poses of ``spa_three_chamber_130mm`` at 0-70 kPa
in 3.5 kPa steps per chamber (Sec. V). The data are SYNTHETIC: the model's tip positions at
a known, smooth sigma(p) (paper 001 Fig. 5's trends, not its data) plus 0.1 mm Gaussian
tracking noise per axis; positions only, as in the paper's identification (Sec. V-A).
``softrod.identify_stiffness`` identifies sigma for every pose (one parallel core call per
Levenberg-Marquardt iteration for all poses still iterating). Reported: wall time (median of
repeated runs after a warm-up), core calls and iterations, the fraction of poses at which
each factor is identifiable, and the accuracy against the known sigma (relative error, and
the spread of the errors in units of their propagated standard error, which should be ~1).
Two discretisations: the design file's 16 RK4 steps per section (headline) and the 13 mm
step of the statics benchmark (1/9/1 steps, tip error 7.7e-7 L).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import softrod
from softrod.calibration.per_sample import STATUS, stiffness_mapped_design
from softrod.stiffness_map import SIGMA_NAMES

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import (  # noqa: E402  (sibling module of this script)
    KPA,
    bench_main,
    load_average,
    machine,
    median,
    result_header,
    steps_of,
    with_step_length,
)

DESIGN = "spa_three_chamber_130mm"
NOISE_M = 0.1e-3  # tracking noise per axis, m
SEED = 2026
TARGET_S = 60.0  # the target for 9261 poses on a 2-core machine


def true_sigma(p: np.ndarray) -> np.ndarray:
    """SYNTHETIC sigma(p): sigma_ext < 1 rising with pressure, bending factors softening."""
    q = p / (70 * KPA)
    load = q.sum(axis=1) / 3.0
    return np.column_stack(
        [
            0.6 + 0.3 * load + 0.1 * q[:, 0],
            1.2 - 0.5 * load + 0.2 * q[:, 1] * q[:, 2],
            1.3 - 0.4 * load - 0.1 * q[:, 0],
        ]
    )


def dataset(design, levels: int):
    """levels^3 poses 0-70 kPa (channel 0 slowest), tips at true_sigma plus noise."""
    g = np.linspace(0.0, 70.0 * KPA, levels)
    p = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
    mapped, _ = stiffness_mapped_design(design)
    truth = softrod.StiffnessMap.from_callable(true_sigma, 3)
    batch = softrod.solve_statics_batch(mapped, p, stiffness_map=truth)
    assert batch.converged.all()
    noise = np.random.default_rng(SEED).normal(0.0, NOISE_M, batch.tip_position.shape)
    return softrod.Dataset(
        pressures=p,
        tip_position=batch.tip_position + noise,
        metadata={"synthetic": True, "sigma": "bench_identification.true_sigma", "seed": SEED},
    )


def accuracy(ident, data) -> dict:
    ok = ident.identifiable
    truth = true_sigma(data.pressures)
    rel = np.abs(ident.sigma[ok] / truth[ok] - 1.0)
    z = (np.log(ident.sigma[ok]) - np.log(truth[ok])) / (NOISE_M / ident.sensitivity[ok])
    return {
        "median_relative_error": float(np.median(rel)),
        "p95_relative_error": float(np.percentile(rel, 95)),
        "max_relative_error": float(rel.max()),
        "z_score_std": float(z.std()),
        "max_abs_z_score": float(np.abs(z).max()),
    }


def case(design, data, runs: int) -> dict:
    times, ident = [], None
    for _ in range(runs):
        t0 = time.perf_counter_ns()
        ident = softrod.identify_stiffness(design, data, threads=0)
        times.append((time.perf_counter_ns() - t0) * 1e-9)
    statuses = {s: int(np.sum(ident.status == s)) for s in STATUS}
    return {
        "steps": steps_of(design),
        "runs": runs,
        "median_s": median(times),
        "times_s": times,
        "core_calls": ident.calls,
        "iterations_max": int(ident.iterations.max()),
        "iterations_mean": float(ident.iterations.mean()),
        "iterations_histogram": np.bincount(ident.iterations).tolist(),
        "status": statuses,
        "identified_fraction": dict(
            zip(SIGMA_NAMES, ident.identified_fraction.tolist(), strict=True)
        ),
        "all_three_identified_fraction": float(ident.identifiable.all(axis=1).mean()),
        "at_bound": int(ident.at_bound.any(axis=1).sum()),
        "median_residual_mm": float(np.nanmedian(ident.residual_mm)),
        "min_sensitivity_mm": 1e3 * ident.settings["min_sensitivity"],
        "accuracy": accuracy(ident, data),
    }


def run(quick: bool) -> dict:
    t_start = time.perf_counter()
    info = machine()
    levels = 11 if quick else 21
    runs = 1 if quick else 3
    base = softrod.load_design(DESIGN)
    print(
        f"softrod per-sample identification benchmark: {DESIGN}, {levels}^3 = {levels**3} "
        f"SYNTHETIC poses, noise {NOISE_M * 1e3:g} mm, {'quick' if quick else 'full'} mode"
    )
    print(
        f"machine: {info['cpu_count']} CPUs, {info['platform']}, Python {info['python']}, "
        f"numpy {info['numpy']}, softrod {info['softrod']} ({info['git_commit']}), "
        f"load average {info['load_average_before']}"
    )
    cases = {}
    for label, design in (("design_file", base), ("step_13mm", with_step_length(base, 13.0))):
        data = dataset(design, levels)
        softrod.identify_stiffness(design, data.subset(np.arange(0, len(data), 50)))  # warm-up
        cases[label] = c = case(design, data, runs)
        frac = ", ".join(f"{k} {100 * v:.1f} %" for k, v in c["identified_fraction"].items())
        acc = c["accuracy"]
        print(
            f"\n[{label}] steps per section {c['steps']}: median {c['median_s']:.2f} s over "
            f"{runs} run(s) ({', '.join(f'{t:.2f}' for t in c['times_s'])} s)"
        )
        print(
            f"    {c['core_calls']} core calls; iterations per pose: mean "
            f"{c['iterations_mean']:.2f}, max {c['iterations_max']}; status {c['status']}"
        )
        print(f"    identified: {frac}; all three {100 * c['all_three_identified_fraction']:.1f} %")
        print(
            f"    vs the known sigma: median relative error {acc['median_relative_error']:.2e}, "
            f"95th percentile {acc['p95_relative_error']:.2e}; error / propagated standard "
            f"error: std {acc['z_score_std']:.2f}, max {acc['max_abs_z_score']:.2f}"
        )
    headline = cases["design_file"]["median_s"]
    met = headline <= TARGET_S if not quick else None
    print(
        f"\nheadline (design file's steps): {headline:.2f} s for {levels**3} poses; target "
        f"<= {TARGET_S:g} s for 9261 poses on 2 cores: "
        + ("n/a (quick)" if met is None else ("met" if met else "missed"))
    )
    return {
        **result_header("identification", quick, info, design=DESIGN),
        "load_average_after": load_average(),
        "poses": levels**3,
        "noise_mm": NOISE_M * 1e3,
        "seed": SEED,
        "synthetic": True,
        "cases": cases,
        "target_s": TARGET_S,
        "target_met": met,
        "wall_time_s": time.perf_counter() - t_start,
    }


def main(argv=None) -> int:
    return bench_main(argv, __doc__, "identification", lambda args: run(args.quick))


if __name__ == "__main__":
    sys.exit(main())
