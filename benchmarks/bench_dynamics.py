"""Dynamics benchmark of softrod (``simulate``) against PyElastica (a script, not a test).

    python benchmarks/bench_dynamics.py          # full run (~4 min), writes results/dynamics.json
    python benchmarks/bench_dynamics.py --quick  # smoke run (~20 s), writes dynamics_quick.json
    python benchmarks/bench_dynamics.py --cantilever-only  # section 3 alone (~1 min)

One core: RAYON_NUM_THREADS, NUMBA_NUM_THREADS and OMP_NUM_THREADS are set to 1 before softrod
and PyElastica are imported. All times are wall-clock (time.perf_counter) with the garbage
collector off; softrod's are medians of repeated runs after a warm-up, PyElastica's one run per
setting after a warm-up run (its numba kernels are compiled on first use; not timed).

1. **Paper 000 arm** (``pam_arm_220mm``, 116 s of ``PressureSchedule.paper000_square_pulses()``,
   ``initial="static"``, tau = 0.19 s) with ``numerics.steps_per_section = 24`` (25 nodes, as
   the issue-5 run): fixed dt = 5 and 2 ms, and adaptive steps (``error_tol`` 0.05 and 0.01
   mm) on 20, 50 and 100 ms output grids (the output interval is the largest step); tip
   error of each against a dt = 0.5 ms reference. Target (issue 14): at
   most 0.5 s on one core.
2. **Cost per time step against the number of nodes**: the same arm with 24 ... 384 steps (25
   to 385 nodes) for 0.5 s of a 1.5 bar pulse at dt = 5 ms (100 steps, all of them moving):
   wall per step and per step and node (medians of 3). Target: linear.
3. **Undamped soft cantilever vs PyElastica** (issue 14): L = 0.22 m, E = 100 kPa, nu = 0.5,
   r = 12.5 mm, 1000 kg/m^3, gravity 9.81 m/s^2, clamped at x = 0 along +x (softrod
   ``orientation = "horizontal"``; PyElastica ``direction = +x``, ``normal = +z``,
   OneEndFixedBC on node 0 and element 0, GravityForces on the lumped nodal masses), released
   straight and at rest, no damping in either, 1 s, tip sampled every 1 ms. PyElastica 1.0's
   shear stiffness is alpha_c G A with alpha_c = 27/28 (rod/factory_function.py), so softrod
   gets c_s = 27/28; rotary inertia rho I in both. The rod has no chamber.
   softrod's reference: BDF-alpha at dt 0.1 and 0.05 ms with 40 intervals, Richardson
   (4 r(dt/2) - r(dt)) / 3, plus the space correction 80 - 40 intervals. softrod with 16 and
   32 intervals at dt 2, 1, 0.5 ms (medians of 5, wall and CPU time). Errors are |tip(t) -
   tip_ref(t)| on the 1 ms grid, max and RMS.
   The two codes' continuum models differ: PyElastica 1.0 divides the internal force by the
   dilatation e, the bending/twist couple by e^3 and the rotary inertia by e (Gazzola et al.
   2018's law for an incompressible rod); softrod's law is n = R K_se (v - e3), m = R K_bt u.
   This rod stretches to e = 1.17 while it swings, so the limits differ (by 25 mm at 80
   elements). PyElastica therefore runs twice, PositionVerlet at the largest stable dt of
   PE_DTS for each number of elements (a blow-up after 0.1 s is not a step-size limit: one
   more try at dt/4, then none): **as shipped** (20 ... 320 elements), and **with softrod's
   law** (pyelastica_laws.py swaps its three kernels for copies without the dilatation
   factors; 20 ... 1280 elements), the same continuum rod as softrod's, so its errors are
   measured against softrod's reference. Self-convergence: |t(n/2) - t(n)|, and the
   first-order extrapolation 2 t(n) - t(n/2) (PyElastica's error falls as 1/n: its clamp
   holds the first element's rotation, see pyelastica_checks.py). At 80 elements each
   dilatation factor alone is compared with softrod's law. A small-amplitude case (1 % of g,
   where the laws agree to first order) checks that PyElastica as shipped converges to
   softrod's reference of that case. A run has blown up when the tip leaves 1.5 L, is not
   finite, or an element's dilatation leaves (0.5, 2); it stops there.
   Target: at 1 mm max tip error, softrod at least 50x faster than PyElastica. "1 mm" is each
   code's error against its own model's converged solution: for PyElastica with softrod's law
   that is softrod's reference (the cheapest such run at <= 1 mm against softrod's cheapest
   at <= 1 mm, wall and CPU time); PyElastica as shipped is undamped-unstable beyond 80
   elements, and its error against its own limit is estimated by |t(n/2) - t(n)|.
   ``--cantilever-only`` runs this section alone and keeps sections 1-2 of the results file.
"""

from __future__ import annotations

import os

for _var in ("RAYON_NUM_THREADS", "NUMBA_NUM_THREADS", "OMP_NUM_THREADS"):
    os.environ[_var] = "1"

import contextlib  # noqa: E402
import io  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import softrod  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import (  # noqa: E402
    RESULTS,
    bench_main,
    gc_disabled,
    load_average,
    machine,
    median,
    result_header,
)

try:  # benchmark-only dependency: python3 -m pip install pyelastica
    import elastica as ea
    import numba  # noqa: F401  (its version is recorded; PyElastica needs it)

    ELASTICA_ERROR = None
except ImportError as exc:  # pragma: no cover - depends on the environment
    ea = None
    ELASTICA_ERROR = str(exc)

ARM = "pam_arm_220mm"
ARM_STEPS = 24  # 25 nodes
ARM_T_END = 116.0
ARM_DTS = [5e-3, 2e-3]
ARM_REF_DT = 5e-4
ARM_ADAPTIVE = [(2e-2, 5e-5), (5e-2, 5e-5), (1e-1, 5e-5), (5e-2, 1e-5)]  # (output dt, error_tol m)
TARGET_ARM_WALL = 0.5  # s, one core, 116 s of pulses
SCALING_STEPS = [24, 48, 96, 192, 384]
TARGET_SPEEDUP = 50.0
TARGET_ACCURACY = 1e-3  # m, max tip error of the PyElastica comparison

# The soft cantilever of issue 14.
L, RADIUS, E_MOD, RHO, G_ACC = 0.22, 0.0125, 100e3, 1000.0, 9.81
G_MOD = E_MOD / 3.0
C_S = 27.0 / 28.0  # PyElastica's shear coefficient alpha_c, given to softrod as c_s
T_END = 1.0
SAMPLE = 1e-3  # tip samples every 1 ms
GRID = np.round(np.arange(0.0, T_END + SAMPLE / 2, SAMPLE), 12)
# PyElastica: steps tried from the largest (each divides the 1 ms sample interval), elements
# of PyElastica 1.0 as shipped and of PyElastica with softrod's law, and the small-amplitude
# check's gravity (1 % of g: tip amplitude 15 mm, dilatation within 5e-5 of 1).
PE_DTS = [1e-4, 5e-5, 4e-5, 2.5e-5, 2e-5, 1.25e-5, 1e-5, 5e-6, 2.5e-6]
PE_ELEMS = [20, 40, 80, 160, 320]
PE_ELEMS_SOFTROD_LAW = [20, 40, 80, 160, 320, 640, 1280]
SMALL_G = 0.01 * G_ACC
SMALL_ELEMS = [20, 40, 80, 160]
DECOMPOSE_ELEMS = 80


def _pe_version():
    try:
        from importlib.metadata import version

        return version("pyelastica")
    except Exception:  # noqa: BLE001
        return None


def fmt_t(seconds: float) -> str:
    if seconds < 1.0:
        return f"{seconds * 1e3:.1f} ms"
    return f"{seconds:.2f} s"


def errors(tip: np.ndarray, ref: np.ndarray) -> dict:
    """Max and RMS of |tip - ref| over the samples, mm and % of L."""
    e = np.linalg.norm(tip - ref, axis=1)
    mx, rms = float(e.max()), float(np.sqrt(np.mean(e**2)))
    return {
        "max_mm": mx * 1e3,
        "rms_mm": rms * 1e3,
        "max_pct_L": 100 * mx / L,
        "rms_pct_L": 100 * rms / L,
    }


# ---------------------------------------------------------------------------------------------
# softrod
# ---------------------------------------------------------------------------------------------


def cantilever(steps: int, g: float = G_ACC, length: float = L) -> softrod.Design:
    section = {
        "name": "rod",
        "length": f"{length} m",
        "outer_radius": f"{RADIUS * 1e3} mm",
        "material": "soft",
        "steps": steps,
        "c_s": C_S,
    }
    doc = {
        "design": {
            "name": "soft_cantilever_220mm",
            "citation": "issue 14 benchmark: 0.22 m, E = 100 kPa, r = 12.5 mm, 1000 kg/m^3",
        },
        "mounting": {"orientation": "horizontal", "gravity": f"{g} m/s^2"},
        "materials": {"soft": {"E": f"{E_MOD} Pa", "G": f"{G_MOD} Pa", "density": f"{RHO} kg/m^3"}},
        "sections": [section],
    }
    return softrod.load_design(doc)


def sr_cantilever(design, dt: float, **kw):
    return softrod.simulate(
        design, None, T_END, dt=dt, initial="straight", energy=False, progress=False, **kw
    )


def timed_runs(fn, reps: int, cpu: list | None = None):
    """(median wall s, walls, last result) of reps calls, GC off; the process CPU time of
    each call is appended to ``cpu`` when given (one core: on a shared machine the CPU time
    is what the run itself took, the wall includes waiting for the core)."""
    walls, out = [], None
    with gc_disabled():
        for _ in range(reps):
            t0, c0 = time.perf_counter(), time.process_time()
            out = fn()
            walls.append(time.perf_counter() - t0)
            if cpu is not None:
                cpu.append(time.process_time() - c0)
    return median(walls), walls, out


# ---------------------------------------------------------------------------------------------
# PyElastica
# ---------------------------------------------------------------------------------------------

if ea is not None:
    import pyelastica_laws

    class TipRecorder(ea.CallBackBaseClass):
        def __init__(self, every: int, out: list, dil: list):
            super().__init__()
            self.every, self.out, self.dil = every, out, dil

        def make_callback(self, system, time, current_step):
            if current_step % self.every == 0:
                self.out.append(system.position_collection[:, -1].copy())
                self.dil.append((float(system.dilatation.min()), float(system.dilatation.max())))

    class Cantilever(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping, ea.CallBacks):
        pass


def blown_up(tip, dil) -> bool:
    """Not finite, the tip beyond 1.5 L, or an element stretched or squeezed by 2x."""
    return not (
        np.all(np.isfinite(tip)) and np.abs(tip).max() < 1.5 * L and 0.5 < dil[0] and dil[1] < 2.0
    )


def pe_cantilever(
    n_elem: int,
    dt: float,
    t_end: float = T_END,
    law: str = "pyelastica",
    g: float = G_ACC,
    damping: float | None = None,
) -> dict:
    """PyElastica run: wall s of the stepping loop, tip positions on the 1 ms grid, the time
    of a blow-up (None if none; the run stops there) and the dilatation range. ``damping``:
    AnalyticalLinearDamper's uniform_damping_constant (1/s; None: undamped, as in the
    benchmark; pyelastica_checks.py damps to reach rest states)."""
    sim = Cantilever()
    rod = ea.CosseratRod.straight_rod(
        n_elem,
        np.zeros(3),
        np.array([1.0, 0.0, 0.0]),
        np.array([0.0, 0.0, 1.0]),
        L,
        RADIUS,
        RHO,
        youngs_modulus=E_MOD,
        shear_modulus=G_MOD,
    )
    sim.append(rod)
    sim.constrain(rod).using(
        ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,)
    )
    sim.add_forcing_to(rod).using(ea.GravityForces, acc_gravity=np.array([0.0, 0.0, -g]))
    if damping is not None:
        sim.dampen(rod).using(
            ea.AnalyticalLinearDamper, uniform_damping_constant=damping, time_step=dt
        )
    every = round(SAMPLE / dt)
    if abs(every * dt - SAMPLE) > 1e-12:
        raise ValueError(f"dt = {dt} must divide the sample interval {SAMPLE}")
    tips: list = []
    dil: list = []
    sim.collect_diagnostics(rod).using(TipRecorder, every=every, out=tips, dil=dil)
    sim.finalize()
    stepper = ea.PositionVerlet()
    steps = round(t_end / dt)
    blew = None
    with pyelastica_laws.law(law), gc_disabled():
        t0, c0 = time.perf_counter(), time.process_time()
        t = np.float64(0.0)
        for i in range(1, steps + 1):
            t = stepper.step(sim, t, np.float64(dt))
            if i % every == 0 and blown_up(tips[-1], dil[-1]):
                blew = float(t)
                break
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    d = np.array(dil)
    return {
        "wall": wall,
        "cpu": cpu,
        "tips": np.array(tips),
        "blew_up_at_s": blew,
        "dilatation_range": [float(d[:, 0].min()), float(d[:, 1].max())],
    }


def pe_largest_stable(n_elem: int, law: str, t_end: float = T_END, g: float = G_ACC):
    """The run at the largest stable dt of PE_DTS, or None, and the unstable tries. A blow-up
    after 0.1 s is no step-size limit (those blow up within a few ms): after the first one,
    one more try at a quarter of the step or less, then give up."""
    tried = []
    late = None
    for dt in PE_DTS:
        if late is not None and dt > late / 4:
            continue
        r = pe_cantilever(n_elem, dt, t_end, law, g)
        if r["blew_up_at_s"] is None:
            return dt, r, tried
        tried.append({"dt_s": dt, "blew_up_at_s": r["blew_up_at_s"]})
        print(
            f"      {law} law, {n_elem} elements, dt {dt * 1e6:g} us: blew up at "
            f"{r['blew_up_at_s']:.3f} s (dilatation up to {r['dilatation_range'][1]:.3g})"
        )
        if r["blew_up_at_s"] > 0.1:
            if late is not None:
                break
            late = dt
    return None, None, tried


# ---------------------------------------------------------------------------------------------


def run_arm(quick: bool) -> dict:
    print(f"\n[1] paper 000 arm {ARM}: {ARM_T_END:g} s square pulses, {ARM_STEPS} steps")
    base = softrod.load_design(ARM)
    design = base.replace({"numerics.steps_per_section": ARM_STEPS})
    nodes = int(design.spec["sections"][0]["steps"]) + 1
    schedule = softrod.PressureSchedule.paper000_square_pulses()
    t_end = 20.0 if quick else ARM_T_END
    reps = 1 if quick else 3

    def sim(d, dt, **kw):
        return softrod.simulate(d, schedule, t_end, dt=dt, energy=False, progress=False, **kw)

    ref = sim(design, ARM_REF_DT)
    settings = [(f"dt {dt * 1e3:g} ms", dt, {}) for dt in ARM_DTS] + [
        (f"adaptive, output {dt * 1e3:g} ms, error_tol {tol * 1e3:g} mm", dt, {"error_tol": tol})
        for dt, tol in ARM_ADAPTIVE
    ]
    rows = []
    for name, dt, kw in settings:
        sim(design, dt, **kw)  # warm-up
        cpus: list[float] = []
        wall, walls, tr = timed_runs(lambda dt=dt, kw=kw: sim(design, dt, **kw), reps, cpus)
        # clip: the last sample time can exceed the reference's end by roundoff (3e-13 s)
        err = errors(tr.tip_position, ref.tip_position_at(np.minimum(tr.time, ref.time[-1])))
        m = tr.metadata
        row = {
            "setting": name,
            "dt_s": dt,
            **kw,
            "wall_s": wall,
            "walls_s": walls,
            "cpu_s": median(cpus),
            "real_time_factor": t_end / wall,
            "time_steps": int(m["internal_steps"]),
            "newton_iterations": int(m["newton_iterations"]),
            "jacobians": int(m["jacobians"]),
            "tip_error_vs_ref": err,
            # One core (RAYON_NUM_THREADS = 1): its CPU time (the wall adds a shared
            # machine's waits for the core).
            "target_met": median(cpus) <= TARGET_ARM_WALL * t_end / ARM_T_END,
        }
        rows.append(row)
        print(
            f"    {name}: wall {fmt_t(wall)}, CPU {fmt_t(row['cpu_s'])} (medians of {reps}), "
            f"{t_end / wall:.0f}x real time, "
            f"{row['time_steps']} steps, {row['newton_iterations'] / row['time_steps']:.2f} "
            f"Newton it/step, {row['jacobians']} Jacobians; tip error vs dt "
            f"{ARM_REF_DT * 1e3:g} ms: max {err['max_mm']:.2f} mm, RMS {err['rms_mm']:.3f} mm"
        )
    return {
        "design": ARM,
        "t_end_s": t_end,
        "steps_per_section": ARM_STEPS,
        "nodes": nodes,
        "initial": "static",
        "scheme": "bdf-alpha",
        "alpha": -0.2,
        "repetitions": reps,
        "reference_dt_s": ARM_REF_DT,
        "reference_wall_s": ref.metadata["wall_time_s"],
        "runs": rows,
        "target_wall_s_for_116_s": TARGET_ARM_WALL,
    }


def run_scaling(quick: bool) -> dict:
    print("\n[2] cost per time step against the number of nodes (arm, 1.5 bar pulse, 5 ms)")
    base = softrod.load_design(ARM)
    pulse = softrod.PressureSchedule.steps([0.0, 0.05], [[0, 0, 0], [1.5e5, 0, 0]])
    reps = 1 if quick else 3
    rows = []
    for steps in SCALING_STEPS[:3] if quick else SCALING_STEPS:
        d = base.replace({"numerics.steps_per_section": steps})

        def run(d=d):
            return softrod.simulate(d, pulse, 0.5, dt=5e-3, energy=False, progress=False)

        run()  # warm-up
        wall, walls, tr = timed_runs(run, reps)
        m = tr.metadata
        per_step = wall / m["internal_steps"]
        rows.append(
            {
                "steps": steps,
                "nodes": steps + 1,
                "wall_s": wall,
                "per_step_s": per_step,
                "per_step_per_node_s": per_step / (steps + 1),
                "newton_iterations_per_step": m["newton_iterations"] / m["internal_steps"],
                "jacobians": int(m["jacobians"]),
            }
        )
        print(
            f"    {steps + 1} nodes: {per_step * 1e6:.0f} us/step, "
            f"{per_step / (steps + 1) * 1e6:.2f} us/step/node, "
            f"{rows[-1]['newton_iterations_per_step']:.2f} Newton it/step, "
            f"{rows[-1]['jacobians']} Jacobians"
        )
    ratio = rows[-1]["per_step_per_node_s"] / rows[0]["per_step_per_node_s"]
    print(
        f"    cost per step and node, {rows[-1]['nodes']} against {rows[0]['nodes']} nodes: "
        f"x{ratio:.2f} (linear: 1)"
    )
    return {"runs": rows, "per_node_cost_ratio_last_to_first": ratio}


def run_cantilever(quick: bool) -> dict:
    print(
        f"\n[3] undamped soft cantilever: L {L} m, E {E_MOD / 1e3:g} kPa, nu 0.5, "
        f"r {RADIUS * 1e3} mm, {RHO:g} kg/m^3, gravity, horizontal, released straight, "
        f"{T_END:g} s"
    )
    out: dict = {
        "rod": {
            "length_m": L,
            "radius_m": RADIUS,
            "E_Pa": E_MOD,
            "G_Pa": G_MOD,
            "density_kg_m3": RHO,
            "gravity_m_s2": G_ACC,
            "shear_coefficient": C_S,
            "damping": "none",
            "t_end_s": T_END,
            "sample_s": SAMPLE,
        }
    }

    def tips(tr):
        # clip: the last sample time can fall short of t_end by roundoff
        return tr.tip_position_at(np.minimum(GRID, tr.time[-1]))

    # Reference: second-order Richardson in dt at 40 intervals plus the space correction.
    n_ref = 16 if quick else 40
    dt_ref = 2e-4 if quick else 1e-4
    ra = tips(sr_cantilever(cantilever(n_ref), dt_ref))
    rb = tips(sr_cantilever(cantilever(n_ref), dt_ref / 2))
    rs = tips(sr_cantilever(cantilever(2 * n_ref), dt_ref))
    ref = (4.0 * rb - ra) / 3.0 + (rs - ra)
    dt_corr = errors(rb, (4.0 * rb - ra) / 3.0)
    space = errors(rs, ra)
    print(
        f"    reference: Richardson (dt {dt_ref * 1e3:g}/{dt_ref * 5e2:g} ms, {n_ref} intervals) + "
        f"space correction ({2 * n_ref} intervals): dt correction max {dt_corr['max_mm']:.4f} "
        f"mm, space correction max {space['max_mm']:.4f} mm; tip at 1 s "
        f"{np.round(ref[-1] * 1e3, 2).tolist()} mm"
    )
    out["reference"] = {
        "method": f"(4 tip({n_ref}, {dt_ref / 2:g} s) - tip({n_ref}, {dt_ref:g} s)) / 3 + "
        f"tip({2 * n_ref}, {dt_ref:g} s) - tip({n_ref}, {dt_ref:g} s)",
        "dt_correction": dt_corr,
        "space_correction": space,
        "tip_at_t_end_mm": (ref[-1] * 1e3).tolist(),
    }

    reps = 2 if quick else 5
    sr_rows = []
    for steps in (16, 32):
        d = cantilever(steps)
        for dt in (2e-3, 1e-3, 5e-4):
            sr_cantilever(d, dt)  # warm-up
            cpus: list[float] = []
            wall, walls, tr = timed_runs(lambda d=d, dt=dt: sr_cantilever(d, dt), reps, cpus)
            row = {
                "steps": steps,
                "dt_s": dt,
                "wall_s": wall,
                "walls_s": walls,
                "cpu_s": median(cpus),
                "newton_iterations": int(tr.metadata["newton_iterations"]),
                "tip_error_vs_ref": errors(tips(tr), ref),
            }
            sr_rows.append(row)
            print(
                f"    softrod {steps} intervals, dt {dt * 1e3:g} ms: wall {fmt_t(wall)}, CPU "
                f"{fmt_t(row['cpu_s'])}, tip "
                f"error max {row['tip_error_vs_ref']['max_mm']:.3f} mm, RMS "
                f"{row['tip_error_vs_ref']['rms_mm']:.3f} mm"
            )
    out["softrod"] = sr_rows

    if ea is None:
        msg = f"PyElastica not importable ({ELASTICA_ERROR}): pip install pyelastica==1.0.0"
        print(f"    SKIPPED the PyElastica comparison: {msg}")
        out["pyelastica"] = {"skipped": msg}
        return out

    t0 = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        for law in ("pyelastica", "softrod"):
            pe_cantilever(20, 1e-4, t_end=0.01, law=law)
    warm = time.perf_counter() - t0
    print(f"    PyElastica warm-up (numba JIT, both laws): {warm:.1f} s (not timed)")
    t_pe = 0.05 if quick else T_END
    grid_pe = slice(0, round(t_pe / SAMPLE) + 1)

    def pe_series(law, elems):
        rows, tips_by_n = [], {}
        for n in elems:
            dt, r, tried = pe_largest_stable(n, law, t_pe)
            row = {"n_elem": n, "unstable_tries": tried}
            if r is None:
                row["stable"] = False
                print(f"    {law} law, {n} elements: no stable dt (tries above)")
                rows.append(row)
                continue
            tips_by_n[n] = r["tips"]
            err = errors(r["tips"], ref[grid_pe])
            row.update(
                {
                    "stable": True,
                    "dt_s": dt,
                    "wall_s": r["wall"],
                    "cpu_s": r["cpu"],
                    "t_end_s": t_pe,
                    "dilatation_range": r["dilatation_range"],
                    "tip_error_vs_softrod_ref": err,
                }
            )
            half = tips_by_n.get(n // 2)
            if half is not None:
                # first order (differences halve): t(n) - limit ~ t(n/2) - t(n)
                row["difference_to_half_elements"] = errors(half, r["tips"])
            rows.append(row)
            extra = (
                f", |t({n // 2}) - t({n})| max {row['difference_to_half_elements']['max_mm']:.2f}"
                " mm"
                if half is not None
                else ""
            )
            print(
                f"    {law} law, {n} elements, dt {dt * 1e6:g} us: wall {fmt_t(r['wall'])}, CPU "
                f"{fmt_t(r['cpu'])}, vs "
                f"softrod's reference max {err['max_mm']:.2f} mm, RMS {err['rms_mm']:.2f} mm{extra}"
                f"; dilatation {r['dilatation_range'][0]:.3f} ... {r['dilatation_range'][1]:.3f}"
            )
        return rows, tips_by_n

    def richardson(tips_by_n):
        """First-order extrapolation 2 t(n) - t(n/2) of the two finest stable runs."""
        ns = sorted(n for n in tips_by_n if n // 2 in tips_by_n)
        if not ns:
            return None
        n = ns[-1]
        return n, 2.0 * tips_by_n[n] - tips_by_n[n // 2]

    print("    PyElastica 1.0 as shipped (its law: n / e, m / e^3, J / e):")
    pe_rows, pe_tips = pe_series("pyelastica", [20] if quick else PE_ELEMS)
    print("    PyElastica with softrod's law (pyelastica_laws.py; same continuum model):")
    lin_rows, lin_tips = pe_series("softrod", [20, 40] if quick else PE_ELEMS_SOFTROD_LAW)
    # The laws' difference at the same discretisation (their discretisation errors alike).
    law_diff = [
        {"n_elem": n, **errors(pe_tips[n], lin_tips[n])}
        for n in sorted(set(pe_tips) & set(lin_tips))
    ]
    for d in law_diff:
        print(
            f"    law difference at {d['n_elem']} elements (PyElastica's law - softrod's): max "
            f"{d['max_mm']:.2f} mm, RMS {d['rms_mm']:.2f} mm"
        )
    # Which of PyElastica's dilatation factors makes the difference: each alone (and force
    # and couple together) at DECOMPOSE_ELEMS elements, against softrod's law there.
    decomposition = []
    if not quick and DECOMPOSE_ELEMS in lin_tips:
        dt_d = next(r["dt_s"] for r in lin_rows if r["n_elem"] == DECOMPOSE_ELEMS)
        for name in list(pyelastica_laws.VARIANTS)[1:] + ["pyelastica"]:
            r = pe_cantilever(DECOMPOSE_ELEMS, dt_d, law=name)
            row = {"variant": name, "dt_s": dt_d, "blew_up_at_s": r["blew_up_at_s"]}
            if r["blew_up_at_s"] is None:
                row["vs_softrod_law"] = errors(r["tips"], lin_tips[DECOMPOSE_ELEMS])
                row["dilatation_range"] = r["dilatation_range"]
            decomposition.append(row)
            print(
                f"    {DECOMPOSE_ELEMS} elements, {name}: "
                + (
                    f"vs softrod's law max {row['vs_softrod_law']['max_mm']:.2f} mm, RMS "
                    f"{row['vs_softrod_law']['rms_mm']:.2f} mm"
                    if "vs_softrod_law" in row
                    else f"blew up at {r['blew_up_at_s']:.3f} s"
                )
            )
    extrapolated = {}
    for name, tips_by_n in (("pyelastica_law", pe_tips), ("softrod_law", lin_tips)):
        rich = richardson(tips_by_n)
        if rich is not None:
            n, r_tip = rich
            extrapolated[name] = {
                "from_n_elem": [n // 2, n],
                "vs_softrod_ref": errors(r_tip, ref[grid_pe]),
            }
            print(
                f"    {name}: 2 t({n}) - t({n // 2}) vs softrod's reference: max "
                f"{extrapolated[name]['vs_softrod_ref']['max_mm']:.2f} mm"
            )

    # Small amplitude (1 % of g): the laws agree to first order in the strains, so PyElastica
    # as shipped should converge to softrod's reference of that case.
    small = None
    if not quick:
        sa = tips(sr_cantilever(cantilever(n_ref, SMALL_G), dt_ref))
        sb = tips(sr_cantilever(cantilever(n_ref, SMALL_G), dt_ref / 2))
        ss = tips(sr_cantilever(cantilever(2 * n_ref, SMALL_G), dt_ref))
        sref = (4.0 * sb - sa) / 3.0 + (ss - sa)
        amp = float(np.linalg.norm(sref - sref[0], axis=1).max())
        s_rows, s_tips = [], {}
        for n in SMALL_ELEMS:
            r = pe_cantilever(n, 2.5e-5, law="pyelastica", g=SMALL_G)
            s_tips[n] = r["tips"]
            s_rows.append(
                {
                    "n_elem": n,
                    "dt_s": 2.5e-5,
                    "blew_up_at_s": r["blew_up_at_s"],
                    "dilatation_range": r["dilatation_range"],
                    "tip_error_vs_softrod_ref": errors(r["tips"], sref),
                }
            )
        n, r_tip = richardson(s_tips)
        small = {
            "gravity_m_s2": SMALL_G,
            "softrod_ref_tip_amplitude_mm": amp * 1e3,
            "pyelastica_as_shipped": s_rows,
            "extrapolated_2t160_minus_t80_vs_softrod_ref": errors(r_tip, sref),
        }
        print(
            f"    small amplitude (g = {SMALL_G:g} m/s^2, tip amplitude {amp * 1e3:.1f} mm): "
            "PyElastica as shipped vs softrod's reference, max "
            + ", ".join(f"{r['tip_error_vs_softrod_ref']['max_mm']:.3f}" for r in s_rows)
            + f" mm at {SMALL_ELEMS} elements; 2 t({n}) - t({n // 2}): "
            f"{small['extrapolated_2t160_minus_t80_vs_softrod_ref']['max_mm']:.4f} mm"
        )

    # 1 mm: softrod against its reference; PyElastica with softrod's law against the same
    # reference (the same continuum model). PyElastica as shipped converges to another model:
    # its own error is estimated by |t(n/2) - t(n)| (first order).
    goal_mm = TARGET_ACCURACY * 1e3
    sr_mm = [r for r in sr_rows if r["tip_error_vs_ref"]["max_mm"] <= goal_mm]
    lin_mm = [
        r for r in lin_rows if r["stable"] and r["tip_error_vs_softrod_ref"]["max_mm"] <= goal_mm
    ]
    own_mm = [
        r for r in pe_rows if r.get("difference_to_half_elements", {}).get("max_mm", 1e9) <= goal_mm
    ]
    summary = {"target": TARGET_SPEEDUP, "accuracy_mm": goal_mm}
    sr_best = min(sr_mm, key=lambda r: r["wall_s"]) if sr_mm else None
    if sr_best is not None:
        summary["softrod"] = {k: sr_best[k] for k in ("steps", "dt_s", "wall_s")} | {
            "tip_error_max_mm": sr_best["tip_error_vs_ref"]["max_mm"]
        }
    if lin_mm and sr_best is not None and not quick:
        best = min(lin_mm, key=lambda r: r["wall_s"])
        summary["pyelastica_softrod_law"] = {k: best[k] for k in ("n_elem", "dt_s", "wall_s")} | {
            "tip_error_max_mm": best["tip_error_vs_softrod_ref"]["max_mm"]
        }
        summary["pyelastica_softrod_law"]["cpu_s"] = best["cpu_s"]
        summary["softrod"]["cpu_s"] = sr_best["cpu_s"]
        summary["speedup_same_model"] = best["wall_s"] / sr_best["wall_s"]
        summary["speedup_same_model_cpu"] = best["cpu_s"] / sr_best["cpu_s"]
        summary["target_met_same_model"] = summary["speedup_same_model"] >= TARGET_SPEEDUP
        print(
            f"    at <= {goal_mm:g} mm against softrod's reference: PyElastica with softrod's law "
            f"{best['n_elem']} elements, dt {best['dt_s'] * 1e6:g} us, {fmt_t(best['wall_s'])}; "
            f"softrod {sr_best['steps']} intervals, dt {sr_best['dt_s'] * 1e3:g} ms, "
            f"{fmt_t(sr_best['wall_s'])}: {summary['speedup_same_model']:.0f}x in wall, "
            f"{summary['speedup_same_model_cpu']:.0f}x in CPU time (target {TARGET_SPEEDUP:g}x)"
        )
    elif quick:
        print("    (quick: 0.05 s only, no comparison at 1 mm)")
    else:
        print(f"    no PyElastica run with softrod's law reached {goal_mm:g} mm")
    # Not what PyElastica does, but what its first order invites: the cheapest pair of runs
    # (n/2, n) with softrod's law whose extrapolation 2 t(n) - t(n/2) is within 1 mm.
    walls = {r["n_elem"]: r for r in lin_rows if r["stable"]}
    pairs = [
        (walls[n // 2]["wall_s"] + walls[n]["wall_s"], n)
        for n in walls
        if n // 2 in walls
        and errors(2.0 * lin_tips[n] - lin_tips[n // 2], ref[grid_pe])["max_mm"] <= goal_mm
    ]
    if pairs and sr_best is not None and not quick:
        w, n = min(pairs)
        err = errors(2.0 * lin_tips[n] - lin_tips[n // 2], ref[grid_pe])
        summary["pyelastica_softrod_law_extrapolated_pair"] = {
            "n_elem": [n // 2, n],
            "wall_s": w,
            "tip_error_max_mm": err["max_mm"],
            "speedup": w / sr_best["wall_s"],
        }
        print(
            f"    (first-order extrapolation of PyElastica with softrod's law, {n // 2} and {n} "
            f"elements: {err['max_mm']:.2f} mm for {fmt_t(w)} of both runs, "
            f"{w / sr_best['wall_s']:.0f}x softrod's time)"
        )
    summary["pyelastica_as_shipped_reached_1mm_of_own_limit"] = bool(own_mm)
    stable_pe = [r for r in pe_rows if r["stable"] and "difference_to_half_elements" in r]
    if stable_pe:
        finest = stable_pe[-1]
        summary["pyelastica_as_shipped_finest_stable"] = {
            "n_elem": finest["n_elem"],
            "dt_s": finest["dt_s"],
            "wall_s": finest["wall_s"],
            "estimated_error_vs_own_limit_max_mm": finest["difference_to_half_elements"]["max_mm"],
        }
        print(
            f"    PyElastica as shipped: finest stable run {finest['n_elem']} elements, its "
            "error against its own limit about "
            f"{finest['difference_to_half_elements']['max_mm']:.1f} mm (first order); "
            + ("a run reached 1 mm" if own_mm else "none reached 1 mm")
        )
    out["pyelastica"] = {
        "version": _pe_version(),
        "stepper": "PositionVerlet",
        "damping": "none",
        "warm_up_s": warm,
        "dt_candidates_s": PE_DTS,
        "as_shipped": pe_rows,
        "softrod_law": lin_rows,
        "law_difference_same_elements": law_diff,
        "law_decomposition": decomposition,
        "first_order_extrapolation": extrapolated,
        "small_amplitude": small,
    }
    out["at_1mm"] = summary
    return out


def run(quick: bool, cantilever_only: bool = False, output: Path | None = None) -> dict:
    t_start = time.perf_counter()
    info = machine()
    info["pyelastica"] = _pe_version()
    info["threads"] = "RAYON_NUM_THREADS = NUMBA_NUM_THREADS = OMP_NUM_THREADS = 1"
    print(
        f"softrod dynamics benchmark, {'quick' if quick else 'full'} mode"
        f"{', cantilever only' if cantilever_only else ''}; machine: "
        f"{info['cpu_count']} CPUs, {info['platform']}, softrod {info['softrod']} "
        f"({info['git_commit']}), PyElastica {info['pyelastica']}, load average "
        f"{info['load_average_before']}"
    )
    if cantilever_only:
        # Sections 1 and 2 stay those of the results file's last full run.
        path = output or RESULTS / ("dynamics_quick.json" if quick else "dynamics.json")
        previous = json.loads(path.read_text()) if path.exists() else {}
        cant = run_cantilever(quick)
        info["load_average_after"] = load_average()
        print(f"load average now {info['load_average_after']}")
        return {
            **previous,
            "cantilever": cant,
            "cantilever_run": {
                **result_header("dynamics, section 3 alone (--cantilever-only)", quick, info),
                "wall_time_s": time.perf_counter() - t_start,
            },
            "wall_time_s": time.perf_counter() - t_start,
        }
    arm = run_arm(quick)
    scaling = run_scaling(quick)
    cant = run_cantilever(quick)
    info["load_average_after"] = load_average()
    print(f"load average now {info['load_average_after']}")
    return {
        **result_header("dynamics", quick, info),
        "units": "seconds; tip errors in mm and % of L",
        "paper000_arm": arm,
        "scaling": scaling,
        "cantilever": cant,
        "targets": {
            "arm_wall_s_116_s": TARGET_ARM_WALL,
            "scaling": "linear",
            "speedup_vs_pyelastica_at_1mm": TARGET_SPEEDUP,
        },
        "wall_time_s": time.perf_counter() - t_start,
    }


def main(argv=None) -> int:
    def options(parser):
        parser.add_argument(
            "--cantilever-only",
            action="store_true",
            help="run section 3 alone; sections 1-2 are kept from the results file",
        )

    return bench_main(
        argv,
        __doc__,
        "dynamics",
        lambda args: run(args.quick, args.cantilever_only, args.output),
        options,
    )


if __name__ == "__main__":
    sys.exit(main())
