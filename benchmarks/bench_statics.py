"""Statics benchmark of softrod against scipy's solve_bvp (a script, not a test).

    python benchmarks/bench_statics.py            # full run, writes benchmarks/results/statics.json
    python benchmarks/bench_statics.py --quick    # smoke run (< 20 s), writes statics_quick.json

For the design ``spa_three_chamber_130mm`` (paper 001's actuator, 0-70 kPa per chamber):
1. discretisation: tip error of softrod at several step lengths (``numerics.step_length``:
   every section gets ceil(length / h) RK4 steps) against a reference with h = 0.25 mm, as a
   fraction of the length, at demanding pressures; the largest h meeting 1e-6 L is used for
   all timings;
2. the same accuracy criterion picks the tolerance of the solve_bvp baseline
   (benchmarks/baseline_bvp.py);
3. single cold solves (``solve_statics`` without ``initial``), median over many repetitions,
   and the same solve through the binding directly (``design._rod.solve``) without the Python
   wrapper's validation and result object;
4. the 21^3 = 9261-point sweep 0-70 kPa with ``solve_statics_batch(threads=0)``; and the
   same sweep with a network stiffness map on the body (``law.stiffness_map``; three
   SYNTHETIC random 3-12-10-1 tanh networks, the hybrid model's size): the batch and, apart,
   the map's evaluation for all rows as the batch does it (one call);
5. the baseline per cold solve, and the sweep time extrapolated from it.
All times are medians of wall-clock times (time.perf_counter_ns) with the garbage collector off.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np
import softrod

sys.path.insert(0, str(Path(__file__).resolve().parent))
import baseline_bvp  # noqa: E402  (sibling modules of this script)
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
    steps_of,
    timed,
    with_step_length,
)

DESIGN = "spa_three_chamber_130mm"
ACCURACY = 1e-6  # target: tip error <= 1e-6 of the length
REFERENCE_STEP_MM = 0.25  # reference step length; RK4 error ~ h^4 puts it ~1e-13 L
# Demanding cases of the paper's range: 70 kPa on one chamber, on two.
DEMANDING = [(70.0, 0.0, 0.0), (0.0, 0.0, 70.0), (70.0, 70.0, 0.0), (0.0, 70.0, 70.0)]
# Representative pressures for single solves (kPa): rest, one/two/three chambers, mixed.
REPRESENTATIVE = P001_PRESSURES_KPA
CHECKED = DEMANDING + [p for p in REPRESENTATIVE if p not in DEMANDING]
STEP_CANDIDATES_MM = [22.0, 16.0, 13.0, 11.0, 10.0, 9.0, 8.0, 6.0, 5.0, 4.0, 3.0]
TOL_CANDIDATES = [1e-3, 1e-4, 1e-5, 1e-6]
BVP_NODES = 20  # initial mesh nodes per section (60 over the three sections)
TARGETS = {"single_cold_solve_s": 50e-6, "sweep_s": 0.3, "speedup_vs_baseline": 100.0}


def row(label: str, cells) -> str:
    return f"    {label:<18}" + " ".join(cells)


def fmt_t(seconds: float) -> str:
    if seconds < 1e-3:
        return f"{seconds * 1e6:.1f} us"
    if seconds < 1.0:
        return f"{seconds * 1e3:.2f} ms"
    return f"{seconds:.3f} s"


def network_map_sweep(design, pressures: np.ndarray, runs: int) -> tuple[float, float]:
    """Median times of the sweep with a network stiffness map on the body, and of the map's
    evaluation for all rows as solve_statics_batch does it. The networks are SYNTHETIC
    (random weights, 3-12-10-1 tanh, sigma = exp(0.1 net(p)) near 1): the cost depends on
    their size, not their values."""
    from softrod.statics import _sigma_rows

    rng = np.random.default_rng(0)
    sizes = [3, 12, 10, 1]
    nets = [
        {
            "input_mean": [35e3] * 3,
            "input_scale": [20e3] * 3,
            "weights": [
                rng.normal(size=(a, b)) for a, b in zip(sizes[:-1], sizes[1:], strict=True)
            ],
            "biases": [rng.normal(size=b) for b in sizes[1:]],
            "activation": "tanh",
            "target_mean": 0.0,
            "target_scale": 0.1,
        }
        for _ in range(3)
    ]
    smap = softrod.StiffnessMap.from_networks(nets)
    mapped = design.replace({"sections[1].law": {"stiffness_map": True}})
    softrod.solve_statics_batch(mapped, pressures[:200], stiffness_map=smap, threads=0)
    batch = timed(
        lambda: softrod.solve_statics_batch(mapped, pressures, stiffness_map=smap, threads=0), runs
    )
    evaluation = timed(lambda: _sigma_rows(smap, pressures), max(runs, 5))
    return median(batch), median(evaluation)


def run(quick: bool) -> dict:
    t_start = time.perf_counter()
    base = softrod.load_design(DESIGN)
    length = base.length
    design_steps = steps_of(base)
    info = machine()
    print(
        f"softrod statics benchmark: {DESIGN} (L = {length * 1e3:.1f} mm, "
        f"{base.n_channels} channels), {'quick' if quick else 'full'} mode"
    )
    print(
        f"machine: {info['cpu_count']} CPUs, {info['platform']}, Python {info['python']}, "
        f"numpy {info['numpy']}, scipy {info['scipy']}, softrod {info['softrod']} "
        f"({info['git_commit']}), load average {info['load_average_before']}"
    )

    # 1. Discretisation study --------------------------------------------------------------
    # Errors on the demanding cases (shown) and on all cases timed below; the accuracy
    # criterion applies to all of them, for softrod's steps and the baseline's tol alike.
    ref_design = with_step_length(base, REFERENCE_STEP_MM)
    ref_steps = steps_of(ref_design)
    reference = {p: softrod.solve_statics(ref_design, kpa(p)).tip_position for p in CHECKED}

    def worst(tips: dict, cases) -> float:
        return max(float(np.linalg.norm(tips[p] - reference[p])) for p in cases) / length

    study = {}
    for h in STEP_CANDIDATES_MM:
        d = with_step_length(base, h)
        tips = {p: softrod.solve_statics(d, kpa(p)).tip_position for p in CHECKED}
        study[h] = (worst(tips, DEMANDING), worst(tips, CHECKED), steps_of(d))
    tips = {p: softrod.solve_statics(base, kpa(p)).tip_position for p in CHECKED}
    design_err = worst(tips, CHECKED)
    meeting = [h for h, e in study.items() if e[1] <= ACCURACY]
    step_mm = max(meeting) if meeting else REFERENCE_STEP_MM
    design = with_step_length(base, step_mm)
    steps = steps_of(design)
    chosen_err = study[step_mm][1] if step_mm in study else 0.0
    # The reference itself, checked by the independent solver at a tight tolerance.
    ref_check = worst(
        {
            p: baseline_bvp.solve_bvp_tip(base, kpa(p), nodes=BVP_NODES, tol=1e-8)[0]
            for p in DEMANDING[: 2 if quick else None]
        },
        DEMANDING[: 2 if quick else None],
    )
    print(
        f"\n[1] discretisation: worst tip error vs step length {REFERENCE_STEP_MM} mm "
        f"(steps per section {ref_steps}), fraction of L"
    )
    print(row("step length mm", [f"{h:>8g}" for h in study]))
    print(row("steps per section", [f"{'/'.join(map(str, e[2])):>8}" for e in study.values()]))
    print(row(f"{len(DEMANDING)} demanding cases", [f"{e[0]:8.1e}" for e in study.values()]))
    print(row(f"all {len(CHECKED)} cases", [f"{e[1]:8.1e}" for e in study.values()]))
    print("    (demanding: 70 kPa on one chamber, on two; all: plus the timed pressures)")
    print(
        f"    design file's setting (steps {design_steps}): {design_err:.1e} L; largest step "
        f"meeting {ACCURACY:.0e} L: {step_mm:g} mm, steps {steps} (used for all timings)"
    )
    print(f"    reference checked against solve_bvp (tol 1e-8): agree to {ref_check:.1e} L")

    # 2. Baseline tolerance by the same criterion ------------------------------------------
    tol_study = {}
    for tol in TOL_CANDIDATES:
        tips = {
            p: baseline_bvp.solve_bvp_tip(base, kpa(p), nodes=BVP_NODES, tol=tol)[0]
            for p in CHECKED
        }
        tol_study[tol] = (worst(tips, DEMANDING), worst(tips, CHECKED))
    tol_ok = [t for t, e in tol_study.items() if e[1] <= ACCURACY]
    bvp_tol = max(tol_ok) if tol_ok else min(TOL_CANDIDATES)
    print(
        f"\n[2] solve_bvp baseline ({BVP_NODES} initial nodes per section, exact Jacobians): "
        "worst tip error vs the reference"
    )
    print(row("tol", [f"{t:8.0e}" for t in tol_study]))
    print(row(f"{len(DEMANDING)} demanding cases", [f"{e[0]:8.1e}" for e in tol_study.values()]))
    print(row(f"all {len(CHECKED)} cases", [f"{e[1]:8.1e}" for e in tol_study.values()]))
    print(f"    largest tol meeting {ACCURACY:.0e} L on all cases: {bvp_tol:.0e}")

    # 3. Single cold solves ---------------------------------------------------------------
    reps = 30 if quick else 300
    warm = 5 if quick else 50
    newton_tol = softrod.SolverOptions().as_kwargs()["tol"]
    single = {}
    for p in REPRESENTATIVE:
        pp = kpa(p)
        sol = softrod.solve_statics(design, pp)
        api = lambda pp=pp: softrod.solve_statics(design, pp)  # noqa: E731
        core = binding_solver(design, pp)
        timed(api, warm)
        timed(core, warm)
        single[p] = {
            "api_s": median(timed(api, reps)),
            "binding_s": median(timed(core, reps)),
            "iterations": int(sol.iterations),
            "load_steps": int(sol.load_steps),
            "tip_mm": (sol.tip_position * 1e3).round(4).tolist(),
        }
    api_all = median([v["api_s"] for v in single.values()])
    core_all = median([v["binding_s"] for v in single.values()])
    default_api = None
    if steps != design_steps:
        d16 = base
        timed(lambda: softrod.solve_statics(d16, kpa(DEMANDING[0])), warm)
        default_api = median(
            [
                median(timed(lambda p=p: softrod.solve_statics(d16, kpa(p)), max(reps // 3, 10)))
                for p in REPRESENTATIVE
            ]
        )

    # 4. Sweep ----------------------------------------------------------------------------
    grid = np.linspace(0.0, 70.0 * KPA, 21)
    pressures = np.stack(np.meshgrid(grid, grid, grid, indexing="ij"), axis=-1).reshape(-1, 3)
    runs = 1 if quick else 7
    softrod.solve_statics_batch(design, pressures[:200], threads=0)  # warm-up (thread pool)
    sweep_times = []
    converged = None
    for _ in range(runs):
        t0 = time.perf_counter_ns()
        batch = softrod.solve_statics_batch(design, pressures, threads=0)
        sweep_times.append((time.perf_counter_ns() - t0) * 1e-9)
        converged = int(np.count_nonzero(batch.converged))
    sweep = median(sweep_times)
    mapped_sweep, map_eval = network_map_sweep(design, pressures, runs)

    # 5. Baseline ---------------------------------------------------------------------------
    b_reps = 2 if quick else 15
    b_cases = REPRESENTATIVE[1:4] if quick else REPRESENTATIVE
    base_stats = {}
    agree = 0.0
    for p in b_cases:
        pp = kpa(p)
        res = baseline_bvp.solve_bvp_full(base, pp, nodes=BVP_NODES, tol=bvp_tol)
        tip = softrod.solve_statics(design, pp).tip_position
        agree = max(agree, float(np.linalg.norm(res.tip_position - tip)) / length)
        times = timed(
            lambda pp=pp: baseline_bvp.solve_bvp_tip(base, pp, nodes=BVP_NODES, tol=bvp_tol), b_reps
        )
        base_stats[p] = {
            "time_s": median(times),
            "success": res.success,
            "nfev": res.nfev,
            "final_nodes": res.nodes,
        }
    bvp_single = median([v["time_s"] for v in base_stats.values()])
    bvp_fd = None
    if not quick:
        fd_times = [
            median(
                timed(
                    lambda p=p: baseline_bvp.solve_bvp_tip(
                        base, kpa(p), nodes=BVP_NODES, tol=bvp_tol, exact_jacobian=False
                    ),
                    3,
                )
            )
            for p in b_cases
        ]
        bvp_fd = median(fd_times)
    bvp_sweep = bvp_single * len(pressures)

    ratio_single = bvp_single / api_all
    ratio_sweep = bvp_sweep / sweep
    checks = {
        "single_cold_solve": api_all <= TARGETS["single_cold_solve_s"],
        "sweep": sweep <= TARGETS["sweep_s"],
        "speedup_single": ratio_single >= TARGETS["speedup_vs_baseline"],
        "speedup_sweep": ratio_sweep >= TARGETS["speedup_vs_baseline"],
    }

    # Table --------------------------------------------------------------------------------
    def ok(flag: bool) -> str:
        return "met" if flag else "MISSED"

    print(
        f"\n[3] single cold solve, step {step_mm:g} mm (steps {steps}), median of {reps} per "
        "pressure"
    )
    print(
        f"    {'pressures kPa':<20} {'solve_statics':>14} {'_rod.solve':>12} {'Newton it':>9} "
        f"{'loads':>5}  tip mm"
    )
    for p, v in single.items():
        print(
            f"    {str(p):<20} {fmt_t(v['api_s']):>14} {fmt_t(v['binding_s']):>12} "
            f"{v['iterations']:>9d} {v['load_steps']:>5d}  {v['tip_mm']}"
        )
    print(f"\n[4] baseline solve_bvp, tol {bvp_tol:.0e}, median of {b_reps} per pressure")
    for p, v in base_stats.items():
        print(
            f"    {str(p):<20} {fmt_t(v['time_s']):>14}  success={v['success']} "
            f"rhs evaluations={v['nfev']} final nodes={v['final_nodes']}"
        )
    print(
        f"    tip agreement softrod (step {step_mm:g} mm) vs baseline (tol {bvp_tol:.0e}): "
        f"{agree:.1e} L"
    )

    w = 44
    print("\n" + "=" * 96)
    print(f"{'quantity':<{w}} {'softrod':>12} {'solve_bvp':>12} {'ratio':>8}  target")
    print("-" * 96)
    print(
        f"{'single cold solve, solve_statics (median)':<{w}} {fmt_t(api_all):>12} "
        f"{fmt_t(bvp_single):>12} {ratio_single:>7.0f}x  "
        f"<= 50 us: {ok(checks['single_cold_solve'])}"
        f"; >= 100x: {ok(checks['speedup_single'])}"
    )
    print(
        f"{'single cold solve, _rod.solve (binding only)':<{w}} {fmt_t(core_all):>12} "
        f"{'':>12} {bvp_single / core_all:>7.0f}x"
    )
    if default_api is not None:
        print(
            f"{'single cold solve at the design file steps':<{w}} "
            f"{fmt_t(default_api):>12} {'':>12} {bvp_single / default_api:>7.0f}x"
        )
    if bvp_fd is not None:
        print(
            f"{'baseline with finite-difference Jacobians':<{w}} {'':>12} {fmt_t(bvp_fd):>12} "
            f"{bvp_fd / api_all:>7.0f}x"
        )
    print(
        f"{'sweep with a network stiffness map':<{w}} {fmt_t(mapped_sweep):>12}"
        f"   (the map's evaluation for all rows: {fmt_t(map_eval)})"
    )
    print(
        f"{'sweep 21^3 = 9261 points (threads=0)':<{w}} {fmt_t(sweep):>12} "
        f"{fmt_t(bvp_sweep) + '*':>12} {ratio_sweep:>7.0f}x  <= 0.3 s: {ok(checks['sweep'])}"
        f"; >= 100x: {ok(checks['speedup_sweep'])}"
    )
    print(f"{'  converged':<{w}} {f'{converged}/{len(pressures)}':>12}")
    print("-" * 96)
    print(
        f"* extrapolated: baseline median cold solve x {len(pressures)}, one core; softrod's "
        f"sweep uses all {os.cpu_count()} cores; every row is solved cold."
    )
    print(
        f"settings: step {step_mm:g} mm, steps {steps} (tip error {chosen_err:.1e} L; design "
        f"file: steps {design_steps}), Newton tol {newton_tol:.0e}; solve_bvp tol {bvp_tol:.0e}, "
        f"{BVP_NODES} nodes/section, exact Jacobians; medians of {reps} (single), {runs} "
        f"(sweep), {b_reps} (baseline) runs"
    )
    print(
        f"machine: {info['cpu_count']} CPUs, {info['platform']}; load average now {load_average()}"
    )
    print("=" * 96)

    info["load_average_after"] = load_average()
    return {
        **result_header("statics", quick, info, design=DESIGN),
        "units": "seconds; errors as a fraction of the length",
        "discretisation": {
            "accuracy_target": ACCURACY,
            "reference_step_length_mm": REFERENCE_STEP_MM,
            "reference_steps": ref_steps,
            "demanding_pressures_kPa": [list(p) for p in DEMANDING],
            "checked_pressures_kPa": [list(p) for p in CHECKED],
            "worst_tip_error_by_step_mm_demanding_all_steps": {
                f"{h:g}": list(e) for h, e in study.items()
            },
            "design_file_steps": design_steps,
            "design_file_error": design_err,
            "chosen_step_length_mm": step_mm,
            "chosen_steps": steps,
            "reference_vs_solve_bvp_tol_1e-8": ref_check,
        },
        "baseline_settings": {
            "solver": "scipy.integrate.solve_bvp",
            "nodes_per_section": BVP_NODES,
            "worst_tip_error_by_tol_demanding_all": {f"{t:.0e}": e for t, e in tol_study.items()},
            "chosen_tol": bvp_tol,
            "exact_jacobians": True,
            "tip_agreement_with_softrod": agree,
        },
        "single_cold_solve": {
            "repetitions_per_pressure": reps,
            "per_pressure_kPa": {str(p): v for p, v in single.items()},
            "median_api_s": api_all,
            "median_binding_s": core_all,
            "median_api_at_design_steps_s": default_api,
        },
        "sweep": {
            "points": len(pressures),
            "runs": runs,
            "threads": 0,
            "median_s": sweep,
            "times_s": sweep_times,
            "converged": converged,
            "network_map_median_s": mapped_sweep,
            "network_map_evaluation_median_s": map_eval,
        },
        "baseline": {
            "repetitions_per_pressure": b_reps,
            "per_pressure_kPa": {str(p): v for p, v in base_stats.items()},
            "median_single_s": bvp_single,
            "median_single_finite_difference_jacobian_s": bvp_fd,
            "sweep_extrapolated_s": bvp_sweep,
        },
        "ratios": {"single": ratio_single, "sweep": ratio_sweep},
        "targets": TARGETS,
        "targets_met": checks,
        "wall_time_s": time.perf_counter() - t_start,
    }


def main(argv=None) -> int:
    return bench_main(argv, __doc__, "statics", lambda args: run(args.quick))


if __name__ == "__main__":
    sys.exit(main())
