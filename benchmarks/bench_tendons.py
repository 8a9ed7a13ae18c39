"""Tendon statics benchmark (a script, not a test): issue 17's "statics with one tendon per
chamber pair: within 1.5x of the chamber-only solve".

    python benchmarks/bench_tendons.py            # full run, writes results/tendons.json
    python benchmarks/bench_tendons.py --quick    # smoke run (< 20 s), tendons_quick.json

Design: ``spa_three_chamber_130mm`` (paper 001's actuator, the design of bench_statics.py,
whose chamber-only cold solve is the statics headline), at bench_statics' timing step of
13 mm (1/9/1 RK4 steps). Its three chambers sit 12 mm off the axis at 90, 210 and 330 deg;
one straight tendon per adjacent chamber pair runs at the chambers' distance halfway
between them (150, 270 and 30 deg) through all three sections and ends at the tip, added to
the design document with ``Design.replace``. Its soft Ecoflex body makes a few newtons of
tension bend it as much as the chambers do (1 N at 12 mm: about 0.9 1/m; 70 kPa in one
chamber: about 5 1/m), so the tendon law works in the same range of strains as the pressure.

Cold solves (no warm start) at the pressure and tension points ``POINTS`` through
``solve_statics`` and through the binding directly (``design._rod.solve``), against the same
design without tendons at the same pressures. The two are timed in alternating blocks so that
load changes on the shared machine hit both alike; medians of wall-clock times with the
garbage collector off. The headline is the median over the points of the per-point ratio
(tendons / chamber-only); the target is <= 1.5. For information: the same tendons routed
helically (one turn over the length), and the Till tendon robot (``till_tendon_robot``, four
tendons, 40 steps) against its own solve with every tendon slack.
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
STEP_MM = 13.0  # bench_statics.py's timing step (tip error <= 1e-6 L chamber-only)
DISTANCE_MM = 12.0  # the chambers' distance from the axis (Table I, d_ch)
CHAMBER_ANGLES_DEG = [90.0, 210.0, 330.0]
# Pressures (kPa) and tensions (N, one per tendon): tendon only, chambers and tendons
# together, tendons against the chambers, all three of each.
POINTS = [
    ((0.0, 0.0, 0.0), (2.0, 0.0, 0.0)),
    ((35.0, 0.0, 0.0), (2.0, 0.0, 0.0)),
    ((70.0, 0.0, 0.0), (0.0, 3.0, 0.0)),
    ((70.0, 70.0, 0.0), (1.0, 1.0, 0.0)),
    ((20.0, 45.0, 70.0), (0.0, 2.0, 4.0)),
    ((70.0, 35.0, 10.0), (3.0, 0.0, 1.0)),
]
TILL_POINTS = [(15.0, 0.0, 0.0, 0.0), (10.0, 5.0, 0.0, 0.0), (0.0, 8.0, 0.0, 4.0)]
TARGET_RATIO = 1.5


def pair_angles() -> list[float]:
    """Halfway between adjacent chambers: 150, 270, 30 deg."""
    a = CHAMBER_ANGLES_DEG
    n = len(a)
    return [(a[i] + ((a[(i + 1) % n] - a[i]) % 360) / 2) % 360 for i in range(n)]


def with_tendons(design, turns: float = 0.0):
    """``design`` with one tendon per chamber pair in every section, ending at the tip;
    ``turns`` full turns about the axis over the whole length (0: straight), the angle
    continuous across the sections."""
    secs = design.spec["sections"]
    total = sum(float(s["length"]) for s in secs)
    changes = {}
    s0 = 0.0
    for k, sec in enumerate(secs):
        s1 = s0 + float(sec["length"])
        tendons = []
        for ch, a in enumerate(pair_angles()):
            t = {"channel": ch, "distance": f"{DISTANCE_MM} mm", "angle": f"{a} deg"}
            if turns:
                t["angle"] = f"{a + 360.0 * turns * s0 / total} deg"
                t["angle_end"] = f"{a + 360.0 * turns * s1 / total} deg"
            tendons.append(t)
        changes[f"sections[{k}].tendons"] = tendons
        s0 = s1
    return design.replace(changes)


def time_pair(fa, fb, reps: int, blocks: int) -> tuple[float, float]:
    """Medians of fa() and fb(), timed in ``blocks`` alternating blocks of reps // blocks."""
    ta, tb = [], []
    per = max(1, reps // blocks)
    for b in range(blocks):
        first, second = (fa, fb) if b % 2 == 0 else (fb, fa)
        x = timed(first, per)
        y = timed(second, per)
        if b % 2 == 0:
            ta += x
            tb += y
        else:
            ta += y
            tb += x
    return median(ta), median(tb)


def compare(label: str, base, other, points, reps: int, blocks: int) -> dict:
    """Per point: cold solves of ``base`` (pressures only, tensions as given to it) and
    ``other`` (pressures and tensions), through solve_statics and the binding."""
    rows = []
    for p_kpa, t_n, base_t in points:
        pp, tt = kpa(p_kpa), list(t_n)
        kw_base = {"tensions": list(base_t)} if base_t is not None else {}
        sa = softrod.solve_statics(base, pp, **kw_base)
        sb = softrod.solve_statics(other, pp, tensions=tt)
        api_a, api_b = time_pair(
            lambda pp=pp, kw=kw_base: softrod.solve_statics(base, pp, **kw),
            lambda pp=pp, tt=tt: softrod.solve_statics(other, pp, tensions=tt),
            reps,
            blocks,
        )
        bind_a, bind_b = time_pair(
            binding_solver(base, pp, **kw_base),
            binding_solver(other, pp, tensions=tt),
            reps,
            blocks,
        )
        row = {
            "pressure_kPa": list(p_kpa),
            "tension_N": tt,
            "tip_mm": [float(x) * 1e3 for x in sb.tip_position],
            "tip_shift_by_tendons_mm": float(
                np.linalg.norm(np.subtract(sa.tip_position, sb.tip_position)) * 1e3
            ),
            "iterations": [sa.iterations, sb.iterations],
            "load_steps": [sa.load_steps, sb.load_steps],
            "solve_statics_s": [api_a, api_b],
            "binding_s": [bind_a, bind_b],
            "ratio_solve_statics": api_b / api_a,
            "ratio_binding": bind_b / bind_a,
        }
        rows.append(row)
        print(
            f"  {label} p = {p_kpa} kPa, T = {tt} N: {api_a * 1e6:6.1f} -> {api_b * 1e6:6.1f} us "
            f"({row['ratio_solve_statics']:.2f}x; binding {bind_a * 1e6:6.1f} -> "
            f"{bind_b * 1e6:6.1f} us, {row['ratio_binding']:.2f}x), Newton it "
            f"{sa.iterations} -> {sb.iterations}, tip moved {row['tip_shift_by_tendons_mm']:.1f} mm"
        )
    summary = {
        "median_solve_statics_s": [
            median(r["solve_statics_s"][0] for r in rows),
            median(r["solve_statics_s"][1] for r in rows),
        ],
        "median_binding_s": [
            median(r["binding_s"][0] for r in rows),
            median(r["binding_s"][1] for r in rows),
        ],
        "ratio_solve_statics": median(r["ratio_solve_statics"] for r in rows),
        "ratio_binding": median(r["ratio_binding"] for r in rows),
    }
    print(
        f"  {label}: median ratio {summary['ratio_solve_statics']:.2f}x (solve_statics), "
        f"{summary['ratio_binding']:.2f}x (binding)"
    )
    return {"rows": rows, **summary}


def run(args) -> dict:
    t_start = time.perf_counter()
    reps = 40 if args.quick else 600
    blocks = 2 if args.quick else 6
    base = with_step_length(softrod.load_design(DESIGN), STEP_MM)
    straight = with_tendons(base)
    helical = with_tendons(base, turns=1.0)
    till = softrod.load_design("till_tendon_robot")
    info = machine()
    print(
        f"{DESIGN} at {STEP_MM} mm steps ({steps_of(base)}), tendons at {pair_angles()} deg, "
        f"cold solves, median of {reps} (load {load_average()})"
    )
    pts = [(p, t, None) for p, t in POINTS]
    res_straight = compare("straight", base, straight, pts, reps, blocks)
    res_helical = compare("helical", base, helical, pts, reps, blocks)
    till_pts = [((), t, (0.0,) * till.n_tendons) for t in TILL_POINTS]
    res_till = compare("till", till, till, till_pts, max(reps // 3, 10), blocks)
    ratio = max(res_straight["ratio_solve_statics"], res_straight["ratio_binding"])
    met = ratio <= TARGET_RATIO
    print(
        f"one straight tendon per chamber pair: {ratio:.2f}x the chamber-only cold solve "
        f"(target <= {TARGET_RATIO}x: {'met' if met else 'missed'})"
    )
    info["load_average_after"] = load_average()
    return {
        **result_header("tendons", args.quick, info, design=DESIGN),
        "step_length_mm": STEP_MM,
        "steps": steps_of(base),
        "tendon_angles_deg": pair_angles(),
        "tendon_distance_mm": DISTANCE_MM,
        "repetitions": reps,
        "straight": res_straight,
        "helical_one_turn": res_helical,
        "till_tendon_robot_vs_slack": res_till,
        "ratio": ratio,
        "target_ratio": TARGET_RATIO,
        "target_met": met,
        "wall_time_s": time.perf_counter() - t_start,
    }


if __name__ == "__main__":
    sys.exit(bench_main(sys.argv[1:], __doc__, "tendons", run))
