"""PCC model (paper 003) against the Cosserat rod on ``stiff_flop_pcc`` (a script, not a test).

    python benchmarks/bench_pcc.py          # full run (~1 min), writes results/pcc.json
    python benchmarks/bench_pcc.py --quick  # smoke run (~10 s), writes results/pcc_quick.json

One core: RAYON_NUM_THREADS = 1 is set before softrod is imported (neither model runs in
parallel here; it keeps the machine's other core for other jobs). All times are wall-clock
(time.perf_counter_ns) with the garbage collector off, medians of repeated calls; the two
models are timed in alternation (reversed every other round), so a change in machine load
hits both alike. Ratios are PCC time / rod time: above 1 the PCC model is slower.

The bundled arm: one 110 mm section, six chambers on six channels, PCC parameters of paper
003 (k_L 246 N/m, b_L 119 N s/m, k_theta 0.06 N m/rad, b_theta 0.02 N m s/rad), the rod with
EA = k_L L0, EI = k_theta L0 and the design's 16 RK4 steps, upright, gravity on.

1. **Statics.** ``solve_statics(design, p, model="pcc")`` against ``solve_statics(design, p)``
   (cold solves, no ``initial``) at 7 pressures (rest, one chamber, a pair, three alternate
   and three adjacent chambers, mixed; up to 1.5 bar); also the bindings alone:
   ``pcc_model(design).statics(p)`` (model compiled once) and ``design._rod.solve``.
   Headline: the median over the pressures of the per-pressure medians.
2. **Dynamics.** A 10 s square-pulse input (``PressureSchedule.square_pulses``: 1 bar on
   each pair in turn, 1.2 bar on chambers 1, 3, 5, 1.5 bar on chambers 6, 1, 2; 1 s pulses,
   1 s rests, from 0.5 s) at dt = 1 ms and 5 ms. PCC: ``run_pcc(design, dt, P)`` with P the
   schedule sampled at the step times (sampled before timing), from ``initial="rest"``. Rod:
   ``simulate(design, schedule, 10 s, dt=dt, energy=False)`` from ``initial="static"`` (the
   same state: the input is zero at t = 0). Both save every 10 ms. Reported: wall time,
   real-time factor (10 s / wall), steps per second, Newton iterations per step, and for
   information the tip change from 5 ms to 1 ms and the PCC - rod tip difference.
3. **Chain.** The same arm cut into n = 1, 2, 3 stacked sections of 110/n mm (each with the
   six chambers on the same channels; n times k_L, b_L, k_theta, b_theta per segment, springs
   in series, so the chain is the same arm): 3n PCC coordinates. Statics at 3 pressures and
   the 10 s dynamics at both dt, with the rod on the same design
   (``numerics.steps_per_section = ceil(16 / n)``, 16-18 steps in all).
"""

from __future__ import annotations

import os

os.environ["RAYON_NUM_THREADS"] = "1"

import copy  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import softrod  # noqa: E402
from softrod.pcc import pcc_model, run_pcc  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import (  # noqa: E402
    bench_main,
    binding_solver,
    gc_disabled,
    load_average,
    machine,
    median,
    result_header,
)

DESIGN = "stiff_flop_pcc"
BAR = 1e5
# Representative pressures (bar) on the six channels (chambers 1-6 at 0, 60, ..., 300 deg).
STATIC_PRESSURES_BAR = [
    (0, 0, 0, 0, 0, 0),  # rest (gravity sag only)
    (0.5, 0, 0, 0, 0, 0),  # one chamber
    (1.0, 1.0, 0, 0, 0, 0),  # a pair
    (1.0, 0, 1.0, 0, 1.0, 0),  # chambers 1, 3, 5: elongation
    (1.5, 1.5, 0, 0, 0, 1.5),  # three adjacent: paper Sec. V-C, 145 deg
    (0.3, 0.1, 0.5, 0, 0.2, 0.7),  # mixed
    (1.0, 0.5, 0, 0, 0, 0),  # unequal pair
]
CHAIN_PRESSURES_BAR = STATIC_PRESSURES_BAR[1:4]
T_END = 10.0
DTS = [1e-3, 5e-3]
SAMPLE = 1e-2  # both models save every 10 ms
PULSES = [
    ((0, 1), 1.0 * BAR, 1.0),
    ((2, 3), 1.0 * BAR, 1.0),
    ((4, 5), 1.0 * BAR, 1.0),
    ((0, 2, 4), 1.2 * BAR, 1.0),
    ((5, 0, 1), 1.5 * BAR, 1.0),
]


def schedule() -> softrod.PressureSchedule:
    """The 10 s input: five 1 s pulses with 1 s rests from 0.5 s (last pulse ends at 9.5 s)."""
    return softrod.PressureSchedule.square_pulses(6, PULSES, rest=1.0, start=0.5)


def chain(n: int):
    """The bundled arm as n stacked sections of 110/n mm: the same arm for both models."""
    base = softrod.load_design(DESIGN)
    if n == 1:
        return base
    doc = base.document
    sec = doc["sections"][0]
    sections = []
    for i in range(n):
        s = copy.deepcopy(sec)
        s["name"] = f"arm{i + 1}"
        s["length"] = f"{110.0 / n!r} mm"
        s["mass"] = f"{59.0 / n!r} g"
        sections.append(s)
    return base.replace(
        {
            "sections": sections,
            "pcc.k_L": f"{246.0 * n} N/m",
            "pcc.b_L": f"{119.0 * n} N*s/m",
            "pcc.k_theta": f"{0.06 * n} N*m/rad",
            "pcc.b_theta": f"{0.02 * n} N*m*s/rad",
            "numerics": {"steps_per_section": math.ceil(16 / n)},
        }
    )


def fmt_t(seconds: float) -> str:
    if seconds < 1e-3:
        return f"{seconds * 1e6:.1f} us"
    if seconds < 1.0:
        return f"{seconds * 1e3:.2f} ms"
    return f"{seconds:.2f} s"


def interleaved(fns: dict, reps: int) -> dict:
    """Wall seconds of ``reps`` calls of each fn, in alternation (order reversed every other
    round), GC off; one warm-up call each first."""
    for fn in fns.values():
        fn()
    out: dict = {k: [] for k in fns}
    names = list(fns)
    with gc_disabled():
        for r in range(reps):
            for k in names if r % 2 == 0 else names[::-1]:
                t0 = time.perf_counter_ns()
                fns[k]()
                out[k].append((time.perf_counter_ns() - t0) * 1e-9)
    return out


def statics_case(design, pressures_bar, reps: int) -> dict:
    model = pcc_model(design)
    rows = []
    for pb in pressures_bar:
        p = [x * BAR for x in pb]
        a = softrod.solve_statics(design, p, model="pcc")
        c = softrod.solve_statics(design, p)
        walls = interleaved(
            {
                "pcc": lambda p=p: softrod.solve_statics(design, p, model="pcc"),
                "rod": lambda p=p: softrod.solve_statics(design, p),
                "pcc_binding": lambda p=p: model.statics(p),
                "rod_binding": binding_solver(design, p),
            },
            reps,
        )
        med = {k: median(v) for k, v in walls.items()}
        length, tx, ty = a.shooting_unknowns[:3]
        rows.append(
            {
                "pressures_bar": list(pb),
                "pcc_s": med["pcc"],
                "rod_s": med["rod"],
                "pcc_binding_s": med["pcc_binding"],
                "rod_binding_s": med["rod_binding"],
                "ratio_pcc_over_rod": med["pcc"] / med["rod"],
                "ratio_binding": med["pcc_binding"] / med["rod_binding"],
                "pcc_newton_iterations": int(a.iterations),
                "rod_newton_iterations": int(c.iterations),
                "theta_first_segment_deg": float(np.degrees(np.hypot(tx, ty))),
                "tip_difference_mm": float(np.linalg.norm(a.tip_position - c.tip_position) * 1e3),
            }
        )
    head = {k: median([r[k] for r in rows]) for k in ("pcc_s", "rod_s")}
    head_b = {k: median([r[k] for r in rows]) for k in ("pcc_binding_s", "rod_binding_s")}
    return {
        "repetitions": reps,
        "by_pressure": rows,
        "median_pcc_s": head["pcc_s"],
        "median_rod_s": head["rod_s"],
        "ratio_pcc_over_rod": head["pcc_s"] / head["rod_s"],
        "median_pcc_binding_s": head_b["pcc_binding_s"],
        "median_rod_binding_s": head_b["rod_binding_s"],
        "ratio_binding": head_b["pcc_binding_s"] / head_b["rod_binding_s"],
    }


def tip_gap(a: np.ndarray, b: np.ndarray) -> dict:
    e = np.linalg.norm(a - b, axis=1) * 1e3
    return {"max_mm": float(e.max()), "rms_mm": float(np.sqrt(np.mean(e**2)))}


def dynamics_case(design, dts, reps: int) -> dict:
    sched = schedule()
    rows = {}
    tips = {}
    for dt in dts:
        n = round(T_END / dt)
        every = round(SAMPLE / dt)
        pressures = sched.sample(np.arange(n + 1) * dt)
        out = {}

        def pcc(dt=dt, pressures=pressures, every=every, out=out):
            out["pcc"] = run_pcc(design, dt, pressures, save_every=every)

        def rod(dt=dt, every=every, out=out):
            out["rod"] = softrod.simulate(
                design, sched, T_END, dt=dt, energy=False, save_every=every
            )

        walls = interleaved({"pcc": pcc, "rod": rod}, reps)
        w_pcc, w_rod = median(walls["pcc"]), median(walls["rod"])
        a, tr = out["pcc"], out["rod"]
        assert len(a["time"]) == len(tr.time) and np.allclose(a["time"], tr.time)
        tips[dt] = (a["tip_position"], tr.tip_position)
        rows[f"{dt:g}"] = {
            "dt_s": dt,
            "steps": n,
            "pcc_wall_s": w_pcc,
            "rod_wall_s": w_rod,
            "pcc_walls_s": walls["pcc"],
            "rod_walls_s": walls["rod"],
            "ratio_pcc_over_rod": w_pcc / w_rod,
            "pcc_real_time_factor": T_END / w_pcc,
            "rod_real_time_factor": T_END / w_rod,
            "pcc_steps_per_s": n / w_pcc,
            "rod_steps_per_s": n / w_rod,
            "pcc_newton_per_step": int(a["newton_iterations"]) / n,
            "pcc_jacobians": int(a["jacobian_evaluations"]),
            "rod_newton_per_step": int(tr.metadata["newton_iterations"]) / n,
            "rod_jacobians": int(tr.metadata["jacobians"]),
            "pcc_minus_rod_tip": tip_gap(a["tip_position"], tr.tip_position),
        }
    res = {"repetitions": reps, "by_dt": rows}
    if len(dts) == 2:
        fine, coarse = min(dts), max(dts)
        res["dt_change_tip"] = {
            "pcc": tip_gap(tips[coarse][0], tips[fine][0]),
            "rod": tip_gap(tips[coarse][1], tips[fine][1]),
            "between_s": [fine, coarse],
        }
    return res


def print_statics(label: str, st: dict) -> None:
    print(
        f"    {label}: PCC {fmt_t(st['median_pcc_s'])}, rod {fmt_t(st['median_rod_s'])}, "
        f"PCC/rod {st['ratio_pcc_over_rod']:.1f}x; bindings alone PCC "
        f"{fmt_t(st['median_pcc_binding_s'])}, rod {fmt_t(st['median_rod_binding_s'])}, "
        f"{st['ratio_binding']:.1f}x"
    )


def print_dynamics(label: str, dy: dict) -> None:
    for row in dy["by_dt"].values():
        print(
            f"    {label} dt {row['dt_s'] * 1e3:g} ms: PCC {fmt_t(row['pcc_wall_s'])} "
            f"({row['pcc_real_time_factor']:.0f}x real time, {row['pcc_steps_per_s']:.0f} "
            f"steps/s, {row['pcc_newton_per_step']:.2f} Newton it/step), rod "
            f"{fmt_t(row['rod_wall_s'])} ({row['rod_real_time_factor']:.0f}x, "
            f"{row['rod_steps_per_s']:.0f} steps/s), PCC/rod {row['ratio_pcc_over_rod']:.1f}x; "
            f"PCC - rod tip max {row['pcc_minus_rod_tip']['max_mm']:.1f} mm"
        )
    if "dt_change_tip" in dy:
        ch = dy["dt_change_tip"]
        print(
            f"    {label} tip change 5 ms -> 1 ms: PCC max {ch['pcc']['max_mm']:.2f} mm, "
            f"rod max {ch['rod']['max_mm']:.2f} mm"
        )


def run(quick: bool) -> dict:
    t_start = time.perf_counter()
    info = machine()
    info["threads"] = "RAYON_NUM_THREADS = 1"
    print(
        f"softrod PCC benchmark, {'quick' if quick else 'full'} mode; machine: "
        f"{info['cpu_count']} CPUs, {info['platform']}, softrod {info['softrod']} "
        f"({info['git_commit']}), load average {info['load_average_before']}"
    )
    design = softrod.load_design(DESIGN)
    reps_s = 30 if quick else 200
    reps_d = 1 if quick else 5
    dts = [5e-3] if quick else DTS

    print(f"\n[1] statics on {DESIGN}, {len(STATIC_PRESSURES_BAR)} pressures, {reps_s} calls each")
    st = statics_case(design, STATIC_PRESSURES_BAR, reps_s)
    for r in st["by_pressure"]:
        print(
            f"    p = {r['pressures_bar']} bar: PCC {fmt_t(r['pcc_s'])} "
            f"({r['pcc_newton_iterations']} it), rod {fmt_t(r['rod_s'])} "
            f"({r['rod_newton_iterations']} it), {r['ratio_pcc_over_rod']:.1f}x; "
            f"theta {r['theta_first_segment_deg']:.0f} deg, tip difference "
            f"{r['tip_difference_mm']:.1f} mm"
        )
    print_statics("median", st)

    print(f"\n[2] dynamics, {T_END:g} s square pulses, median of {reps_d}")
    dy = dynamics_case(design, dts, reps_d)
    print_dynamics("1 segment", dy)

    print("\n[3] chain: the arm as n stacked segments (3n PCC coordinates)")
    chains = {}
    for n in [1, 2] if quick else [1, 2, 3]:
        d = chain(n)
        cs = statics_case(d, CHAIN_PRESSURES_BAR, max(reps_s // 4, 10))
        print_statics(f"n = {n} statics", cs)
        cd = dynamics_case(d, dts, 1 if quick else 3) if n > 1 else dy
        if n > 1:
            print_dynamics(f"n = {n}", cd)
        chains[str(n)] = {
            "segments": n,
            "coordinates": 3 * n,
            "rod_steps": [int(s["steps"]) for s in d.spec["sections"]],
            "statics": cs,
            "dynamics": cd if n > 1 else "same as [2]",
        }
    info["load_average_after"] = load_average()
    print(f"\nload average now {info['load_average_after']}")
    return {
        **result_header("pcc", quick, info, design=DESIGN),
        "units": "seconds; tip differences in mm",
        "ratio": "PCC time / rod time (> 1: the PCC model is slower)",
        "statics": st,
        "dynamics": {
            "t_end_s": T_END,
            "schedule": [
                {"channels": list(c), "pressure_Pa": p, "duration_s": d} for c, p, d in PULSES
            ],
            "rest_s": 1.0,
            "start_s": 0.5,
            "save_every_s": SAMPLE,
            **dy,
        },
        "chain": chains,
        "wall_time_s": time.perf_counter() - t_start,
    }


def main(argv=None) -> int:
    return bench_main(argv, __doc__, "pcc", lambda args: run(args.quick))


if __name__ == "__main__":
    sys.exit(main())
