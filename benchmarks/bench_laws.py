"""Cost of the nonlinear constitutive laws against the linear law (a script, not a test).

    python benchmarks/bench_laws.py            # full run (~1-2 min), writes results/laws.json
    python benchmarks/bench_laws.py --quick    # smoke run (< 20 s), writes laws_quick.json
    python benchmarks/bench_laws.py --core     # also time the Rust core alone (cargo example)

Issue 3, item 5: "the nonlinear laws cost at most 2 times the linear law's solve time". Three
groups, each a linear baseline and variants of the same actuator at the same discretisation:
1. paper 002's actuator (``spa_three_chamber_134mm_vertical``, body = sections[1]): model M0
   (linear law, c_e 0.92) against M1 (Ogden), M2 (Ogden + chamber offset), M3 (Ogden + offset +
   chamber swelling) of Table IV, and each ingredient of M3 alone on top of M0; 0-60 kPa;
2. paper 004's actuator (``modular_two_module``, modules = sections[1] and [3]): EA = 200 N,
   EI = 0.0133333 N m^2 given directly against the partition law (j = 3, E_I, r_I; bending
   stiffness times the stretch) and against a SYNTHETIC EA(F) table; 0-95 kPa. Both variants
   are built from the document here, whichever law the design file holds;
3. paper 001's actuator (``spa_three_chamber_130mm``): no stiffness map against
   ``law.stiffness_map = true`` on the body (paper 001 eq. 13), 0-70 kPa, with constant maps
   sigma = 1 and sigma = (1.2, 0.9, 1.1) (``StiffnessMap.constant``; the binding gets
   ``stiffness_scale``), and a SYNTHETIC 5^3 PCHIP table map (``StiffnessMap.from_table``),
   which solve_statics evaluates in every call.
Discretisation: in each group the largest step length (``numerics.step_length``) at which every
variant's tip moves by at most 1e-6 of the length against a run with 4x the steps in every
section; each variant's error at that step is reported, so the comparison is at equal
discretisation and comparable accuracy.
Timing: single cold solves (no warm start), ``solve_statics`` and the binding
``design._rod.solve`` directly, every variant and path timed once per round with the order
reversed every other round (ABC..CBA..), so load changes on the shared machine hit all variants
alike. Medians of wall-clock times (time.perf_counter_ns), garbage collector off; the headline
per variant is the median over the pressures of the per-pressure medians.
With ``--core``, every variant (sigma = 1) is also timed in Rust alone by
the example ``profile_solve`` (crates/softrod-core/examples; built with cargo): its f64 pass,
dual-number pass (residual and Jacobian) and cold solve at 70/35/0 kPa, without the binding's
shape output and Python objects, the variants again run in turn.
"""

from __future__ import annotations

import copy
import inspect
import json
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import softrod

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import (  # noqa: E402  (sibling module of this script)
    HERE,
    KPA,
    P001_PRESSURES_KPA,
    bench_main,
    binding_solver,
    gc_disabled,
    kpa,
    load_average,
    machine,
    median,
    result_header,
    steps_of,
    with_step_length,
)

ACCURACY = 1e-6  # every variant's tip error (vs 4x the steps) at most 1e-6 of the length
TARGET_RATIO = 2.0  # issue 3, item 5
SIGMA = (1.2, 0.9, 1.1)  # stiffness scale of the stiffness-map variant (EA, EI1, EI2)
SIGMA_LABEL = "map on, sigma = (1.2,0.9,1.1)"
TABLE_MAP_LABEL = "map on, 5^3 table (synthetic)"

# Paper 002 Table IV (c_b = 1.31 in all models); the ingredients alone use M3's values.
M3_OGDEN = {"axial": "ogden", "alpha": 8.89}
M3_OFFSET = {"chamber_offset": ["0.89 mm", "0.98 mm"]}
M3_SWELLING = {"c_p": 0.48, "p_ref": "0.8 bar"}
# Synthetic EA(F) table for paper 004's modules (NOT from the paper): monotone, 250 N at rest
# to 170 N at 35 N, about the force of three chambers at 95 kPa.
SYNTHETIC_TABLE = {
    "axial": "table",
    "axial_force": ["0 N", "10 N", "20 N", "35 N"],
    "axial_stiffness": ["250 N", "220 N", "195 N", "170 N"],
}
LINEAR_004 = {"EA": "200 N", "EI": "0.0133333 N*m^2", "GA": "2e6 N", "GJ": "133.333 N*m^2"}
PARTITION_004 = {"j": 3, "E_I": "66.6667 N", "r_I": "11.547 mm"}
LAW_KEYS = ("law", "partition")
STIFFNESS_KEYS = ("EA", "EI", "EI1", "EI2", "GA", "GJ")


def law_variant(base, sections: dict, drop=LAW_KEYS):
    """``base`` with, in every listed section, the keys ``drop`` removed and ``sections[i]``
    set: variants are built from the document, independent of the law the file holds."""
    doc = copy.deepcopy(base.document)
    for i, entries in sections.items():
        sec = doc["sections"][i]
        for key in drop:
            sec.pop(key, None)
        sec.update(copy.deepcopy(entries))
    return softrod.load_design(doc)


def finer(design, factor: int = 4):
    """The design with ``factor`` times the steps in every section."""
    return design.replace(
        {f"sections[{i}].steps": factor * n for i, n in enumerate(steps_of(design))}
    )


def groups() -> list[dict]:
    """The three comparison groups: design, pressures (kPa), step candidates, variants."""
    d002 = softrod.load_design("spa_three_chamber_134mm_vertical")
    m0 = {"c_e": 0.92, "c_b": 1.31}
    p002 = {
        "M0 linear (baseline)": {1: m0},
        "M1 Ogden": {1: {"c_e": 2.95, "c_b": 1.31, "law": {"axial": "ogden", "alpha": 0.61}}},
        "M2 Ogden+offset": {
            1: {
                "c_e": 3.10,
                "c_b": 1.31,
                "law": {"axial": "ogden", "alpha": 0.62, "chamber_offset": ["1.46 mm", "1.64 mm"]},
            }
        },
        "M3 Ogden+offset+swell": {
            1: {"c_e": 2.82, "c_b": 1.31, "law": {**M3_OGDEN, **M3_OFFSET, **M3_SWELLING}}
        },
        "M0 + Ogden only": {1: {**m0, "law": dict(M3_OGDEN)}},
        "M0 + offset only": {1: {**m0, "law": dict(M3_OFFSET)}},
        "M0 + swelling only": {1: {**m0, "law": dict(M3_SWELLING)}},
    }
    d004 = softrod.load_design("modular_two_module")
    modules = (1, 3)
    p004 = {
        "linear EA, EI (baseline)": {i: dict(LINEAR_004) for i in modules},
        "partition (paper 004)": {
            i: {"GA": LINEAR_004["GA"], "GJ": LINEAR_004["GJ"], "partition": dict(PARTITION_004)}
            for i in modules
        },
        "EA(F) table (synthetic)": {
            i: {**LINEAR_004, "law": dict(SYNTHETIC_TABLE)} for i in modules
        },
    }
    d001 = softrod.load_design("spa_three_chamber_130mm")
    p001 = {
        "no stiffness map (baseline)": {1: {}},
        "map on, sigma = 1": {1: {"law": {"stiffness_map": True}}},
        SIGMA_LABEL: {1: {"law": {"stiffness_map": True}}},
    }
    if api_supports_map():
        p001[TABLE_MAP_LABEL] = {1: {"law": {"stiffness_map": True}}}
    return [
        {
            "key": "paper002_laws",
            "title": "paper 002 actuator (spa_three_chamber_134mm_vertical), 0-60 kPa",
            "design": d002,
            "variants": {
                k: law_variant(d002, v, drop=LAW_KEYS + ("c_e", "c_b")) for k, v in p002.items()
            },
            # rest, one chamber, two, three (Sec. V experiments i-iii) at 30 and 60 kPa
            "pressures": [
                (0.0, 0.0, 0.0),
                (30.0, 0.0, 0.0),
                (60.0, 0.0, 0.0),
                (30.0, 30.0, 0.0),
                (60.0, 60.0, 0.0),
                (30.0, 30.0, 30.0),
                (60.0, 60.0, 60.0),
            ],
            "steps_mm": [22.0, 16.0, 14.0, 12.0, 10.0, 8.0],
            "sigma": {},
        },
        {
            "key": "paper004_partition_table",
            "title": "paper 004 actuator (modular_two_module), 0-95 kPa",
            "design": d004,
            "variants": {
                k: law_variant(d004, v, drop=LAW_KEYS + STIFFNESS_KEYS) for k, v in p004.items()
            },
            # rest, one, two, three chambers (Sec. 3.2 grid: steps of 23.75 kPa), mixed
            "pressures": [
                (0.0, 0.0, 0.0),
                (47.5, 0.0, 0.0),
                (95.0, 0.0, 0.0),
                (47.5, 47.5, 0.0),
                (95.0, 95.0, 0.0),
                (95.0, 95.0, 95.0),
                (23.75, 71.25, 95.0),
            ],
            "steps_mm": [22.4, 15.0, 11.2, 9.0, 7.5],
            "sigma": {},
        },
        {
            "key": "paper001_stiffness_map",
            "title": "paper 001 actuator (spa_three_chamber_130mm), 0-70 kPa",
            "design": d001,
            "variants": {k: law_variant(d001, v) for k, v in p001.items()},
            "pressures": P001_PRESSURES_KPA,
            "steps_mm": [22.0, 16.0, 13.0, 11.0, 10.0, 8.0],
            "sigma": {
                "map on, sigma = 1": (1.0, 1.0, 1.0),
                SIGMA_LABEL: SIGMA,
                TABLE_MAP_LABEL: "table",
            },
        },
    ]


def api_supports_map() -> bool:
    """Whether solve_statics takes a stiffness map (softrod.StiffnessMap)."""
    return hasattr(softrod, "StiffnessMap") and (
        "stiffness_map" in inspect.signature(softrod.solve_statics).parameters
    )


def synthetic_table_map(n_channels: int):
    """A SYNTHETIC sigma(p) on a 5^3 grid 0-70 kPa (PCHIP), smooth and positive: sigma_ext
    1 -> 1.3 with channel 0, sigma_bend_x 1 -> 0.9 with channel 1, sigma_bend_y 1 -> 1.1 with
    channel 2. Stands in for an identified map (paper 001 fits regressors)."""
    axis = np.linspace(0.0, 70.0 * KPA, 5)
    grid = np.stack(np.meshgrid(*[axis] * n_channels, indexing="ij"), axis=-1) / (70.0 * KPA)
    sigma = np.stack(
        [1.0 + 0.3 * grid[..., 0], 1.0 - 0.1 * grid[..., 1], 1.0 + 0.1 * grid[..., 2]], axis=-1
    )
    return softrod.StiffnessMap.from_table([axis] * n_channels, sigma)


def stiffness_map(design, spec):
    """The StiffnessMap for a variant's ``spec`` (a constant sigma, or "table"), or None when
    solve_statics takes no map."""
    if spec is None or not api_supports_map():
        return None
    if isinstance(spec, str):
        return synthetic_table_map(design.n_channels)
    return softrod.StiffnessMap.constant(spec, design.n_channels)


def solvers(design, pp: list[float], spec):
    """(api, binding) callables of one cold solve. ``spec``: None (no map), a constant sigma,
    or "table" (the synthetic table map): solve_statics gets the map and evaluates it in
    every call; the binding gets sigma at ``pp`` (evaluated once here). api is None when the
    Python API cannot pass the map."""
    if spec is None:
        api = lambda: softrod.solve_statics(design, pp)  # noqa: E731
        return api, binding_solver(design, pp)
    smap = stiffness_map(design, spec)
    if smap is not None:
        scale = [float(s) for s in smap(np.array([pp]))[0]]
        api = lambda: softrod.solve_statics(design, pp, stiffness_map=smap)  # noqa: E731
    elif isinstance(spec, str):
        raise RuntimeError("a table stiffness map needs softrod.StiffnessMap")
    else:
        # Before solve_statics took a map, sigma = 1 was its only (implicit) value.
        scale = [float(s) for s in spec]
        api = None
        if all(s == 1.0 for s in scale):
            api = lambda: softrod.solve_statics(design, pp)  # noqa: E731
    return api, binding_solver(design, pp, stiffness_scale=scale)


def tip_of(design, pp, sigma) -> tuple[np.ndarray, int, int]:
    """Tip position (m), Newton iterations and load steps of one cold solve (binding)."""
    out = solvers(design, pp, sigma)[1]()
    return np.asarray(out["position"][-1]), int(out["iterations"]), int(out["load_steps"])


def discretisation(group: dict) -> tuple[float, dict]:
    """Worst tip error (vs 4x the steps) per variant and candidate step length; the largest
    candidate at which every variant meets ACCURACY."""
    length = group["design"].length
    candidates = group["steps_mm"]
    study: dict[str, dict[float, float]] = {}
    for name, d in group["variants"].items():
        sigma = group["sigma"].get(name)
        study[name] = {}
        for h in candidates:
            coarse = with_step_length(d, h)
            fine = finer(coarse)
            err = 0.0
            for p in group["pressures"]:
                a = tip_of(coarse, kpa(p), sigma)[0]
                b = tip_of(fine, kpa(p), sigma)[0]
                err = max(err, float(np.linalg.norm(a - b)) / length)
            study[name][h] = err
    ok = [h for h in candidates if all(study[n][h] <= ACCURACY for n in study)]
    return (max(ok) if ok else min(candidates)), study


def timed_round_robin(calls: dict, reps: int, warm: int) -> dict:
    """Median wall-clock seconds of each callable, all timed once per round; the order is
    reversed every other round."""
    keys = list(calls)
    times = {k: [] for k in keys}
    with gc_disabled():
        for _ in range(warm):
            for k in keys:
                calls[k]()
        for r in range(reps):
            for k in keys if r % 2 == 0 else reversed(keys):
                fn = calls[k]
                t0 = time.perf_counter_ns()
                fn()
                times[k].append(time.perf_counter_ns() - t0)
    return {k: float(statistics.median(v)) * 1e-9 for k, v in times.items()}


def run_group(group: dict, quick: bool, reps: int, warm: int) -> dict:
    length = group["design"].length
    step_mm, study = discretisation(group)
    variants = {n: with_step_length(d, step_mm) for n, d in group["variants"].items()}
    names = list(variants)
    baseline = names[0]
    per = {n: {} for n in names}
    for p in group["pressures"]:
        pp = kpa(p)
        calls = {}
        for n, d in variants.items():
            sigma = group["sigma"].get(n)
            api, core = solvers(d, pp, sigma)
            if api is not None:
                calls[(n, "api")] = api
            calls[(n, "binding")] = core
            tip, it, ls = tip_of(d, pp, sigma)
            per[n][p] = {
                "iterations": it,
                "load_steps": ls,
                "tip_mm": (tip * 1e3).round(4).tolist(),
            }
        medians = timed_round_robin(calls, reps, warm)
        for n in names:
            per[n][p]["api_s"] = medians.get((n, "api"))
            per[n][p]["binding_s"] = medians[(n, "binding")]
    rows = {}
    for n in names:
        api = median(v["api_s"] for v in per[n].values())
        core = median(v["binding_s"] for v in per[n].values())
        rows[n] = {"api_s": api if any(v["api_s"] for v in per[n].values()) else None}
        rows[n]["binding_s"] = core
    base_api, base_core = rows[baseline]["api_s"], rows[baseline]["binding_s"]
    for n in names:
        row = rows[n]
        its = [v["iterations"] for v in per[n].values()]
        row["ratio_api"] = None if row["api_s"] is None else row["api_s"] / base_api
        row["ratio_binding"] = row["binding_s"] / base_core
        pp_ratios = [
            per[n][p]["binding_s"] / per[baseline][p]["binding_s"] for p in group["pressures"]
        ]
        row["ratio_binding_worst_pressure"] = max(pp_ratios)
        row["iterations"] = its
        row["load_steps"] = [v["load_steps"] for v in per[n].values()]
        row["tip_error_vs_4x_steps"] = study[n][step_mm]
        checked = [r for r in (row["ratio_api"], row["ratio_binding"]) if r is not None]
        row["met"] = n == baseline or all(r <= TARGET_RATIO for r in checked)
        row["per_pressure_kPa"] = {str(p): v for p, v in per[n].items()}
    return {
        "title": group["title"],
        "design": group["design"].name,
        "length_m": length,
        "pressures_kPa": [list(p) for p in group["pressures"]],
        "baseline": baseline,
        "step_length_mm": step_mm,
        "steps": steps_of(variants[baseline]),
        "discretisation_study": {
            "candidates_mm": group["steps_mm"],
            "tip_error_vs_4x_steps": {n: list(e.values()) for n, e in study.items()},
        },
        "variants": rows,
    }


PROFILE_LINE = re.compile(
    r"f64 pass ([0-9.]+) us, dual pass ([0-9.]+) us, cold solve ([0-9.]+) us "
    r"\((\d+) iterations\)"
)


def core_profile(group: dict, step_mm: float, rounds: int) -> dict | None:
    """The Rust core alone: ``profile_solve`` (f64 pass, dual pass, cold solve at 70/35/0
    kPa, each a mean of 2000 calls) for every variant with sigma = 1, the variants run in
    turn, ``rounds`` times (order reversed every other round); medians over the rounds."""
    repo = HERE.parent
    build = ["cargo", "build", "--release", "-p", "softrod-core", "--example", "profile_solve"]
    try:
        res = subprocess.run(
            build + ["--message-format=json"], cwd=repo, capture_output=True, text=True, timeout=900
        )
    except (OSError, subprocess.SubprocessError) as exc:
        print(f"    core profile skipped: {exc}")
        return None
    exe = None
    for line in res.stdout.splitlines():
        try:
            msg = json.loads(line)
        except ValueError:
            continue
        if msg.get("reason") == "compiler-artifact" and msg.get("executable"):
            if msg["target"]["name"] == "profile_solve":
                exe = msg["executable"]
    if res.returncode != 0 or exe is None:
        print(f"    core profile skipped: cargo build failed\n{res.stderr[-2000:]}")
        return None
    ones = (1.0, 1.0, 1.0)
    names = [n for n in group["variants"] if group["sigma"].get(n, ones) == ones]
    out: dict[str, list] = {n: [] for n in names}
    with tempfile.TemporaryDirectory() as tmp:
        specs = {}
        for k, n in enumerate(names):
            d = with_step_length(group["variants"][n], step_mm)
            specs[n] = Path(tmp) / f"spec{k}.json"
            specs[n].write_text(json.dumps(d.spec))
        for r in range(rounds):
            for n in names if r % 2 == 0 else reversed(names):
                res = subprocess.run([exe, str(specs[n])], capture_output=True, text=True)
                m = PROFILE_LINE.search(res.stdout)
                if m is None:
                    print(f"    core profile of {n} failed: {res.stdout}{res.stderr[-500:]}")
                    return None
                out[n].append([float(x) for x in m.groups()])
    base = names[0]
    rows = {}
    for n in names:
        f64, dual, cold, its = (median(c) for c in zip(*out[n], strict=True))
        rows[n] = {
            "f64_pass_s": f64 * 1e-6,
            "dual_pass_s": dual * 1e-6,
            "cold_solve_s": cold * 1e-6,
        }
        rows[n]["iterations"] = int(its)
    for n in names:
        for key in ("f64_pass_s", "dual_pass_s", "cold_solve_s"):
            rows[n][key[:-2] + "_ratio"] = rows[n][key] / rows[base][key]
    return {"pressures_kPa": [70.0, 35.0, 0.0], "rounds": rounds, "variants": rows}


def print_core(results: dict) -> None:
    w = 30
    print(
        "\nRust core alone (example profile_solve, 70/35/0 kPa, sigma = 1; mean of 2000 calls, "
        "median of the rounds), us and ratio to the group's baseline"
    )
    print(
        f"{'variant':<{w}} {'f64 pass':>14} {'dual pass':>15} {'cold solve':>15} {'Newton it':>9}"
    )
    for res in results.values():
        core = res.get("core")
        if not core:
            continue
        for n, r in core["variants"].items():
            cells = [
                f"{r[k + '_s'] * 1e6:6.2f} ({r[k + '_ratio']:.2f}x)"
                for k in ("f64_pass", "dual_pass", "cold_solve")
            ]
            print(f"{n:<{w}} {cells[0]:>14} {cells[1]:>15} {cells[2]:>15} {r['iterations']:>9d}")


def us(x) -> str:
    return "n/a" if x is None else f"{x * 1e6:.1f}"


def ratio(x) -> str:
    return "n/a" if x is None else f"{x:.2f}x"


def print_group(res: dict) -> None:
    cands = res["discretisation_study"]["candidates_mm"]
    print(f"\n{res['title']}")
    print(
        "  discretisation: worst tip error over the timed pressures vs 4x the steps, "
        f"fraction of L = {res['length_m'] * 1e3:.1f} mm"
    )
    print(f"    {'step length mm':<28}" + " ".join(f"{h:>8g}" for h in cands))
    for n, errs in res["discretisation_study"]["tip_error_vs_4x_steps"].items():
        print(f"    {n:<28}" + " ".join(f"{e:8.1e}" for e in errs))
    print(
        f"    used: {res['step_length_mm']:g} mm, steps per section {res['steps']} (largest "
        f"meeting {ACCURACY:.0e} L for every variant)"
    )


def print_table(results: dict, reps: int) -> None:
    w = 30
    line = "=" * 118
    print("\n" + line)
    print(
        f"{'variant':<{w}} {'solve_statics':>13} {'_rod.solve':>10} {'ratio api':>9} "
        f"{'ratio core':>10} {'worst p':>7} {'Newton it':>9} {'tip err/L':>9}  target <= 2x"
    )
    print(f"{'':<{w}} {'(us)':>13} {'(us)':>10} {'':>9} {'':>10} {'(core)':>7} {'min-max':>9}")
    for res in results.values():
        print("-" * 118)
        print(f"{res['title']}; step {res['step_length_mm']:g} mm, steps {res['steps']}")
        for n, r in res["variants"].items():
            its = r["iterations"]
            base = n == res["baseline"]
            print(
                f"{n:<{w}} {us(r['api_s']):>13} {us(r['binding_s']):>10} "
                f"{ratio(r['ratio_api']):>9} {ratio(r['ratio_binding']):>10} "
                f"{ratio(r['ratio_binding_worst_pressure']):>7} "
                f"{f'{min(its)}-{max(its)}':>9} {r['tip_error_vs_4x_steps']:9.1e}  "
                f"{'baseline' if base else ('met' if r['met'] else 'MISSED')}"
            )
    print("-" * 118)
    print(
        "times: median over the pressures of the per-pressure medians of "
        f"{reps} cold solves; ratio: to the group's baseline (first row); worst p: largest "
        "per-pressure ratio of _rod.solve (information); met: both ratios <= 2"
    )
    print(line)


def run(quick: bool, core: bool = False) -> dict:
    t_start = time.perf_counter()
    info = machine()
    reps = 150 if quick else 1500
    warm = 3 if quick else 50
    print(f"softrod nonlinear-law benchmark, {'quick' if quick else 'full'} mode")
    print(
        f"machine: {info['cpu_count']} CPUs, {info['platform']}, Python {info['python']}, "
        f"softrod {info['softrod']} ({info['git_commit']}), load average "
        f"{info['load_average_before']}"
    )
    print(
        "stiffness map through solve_statics: "
        + ("yes" if api_supports_map() else "not available; sigma != 1 via _rod.solve only")
    )
    results = {}
    for g in groups():
        res = run_group(g, quick, reps, warm)
        if core:
            res["core"] = core_profile(g, res["step_length_mm"], 3 if quick else 15)
        results[g["key"]] = res
        print_group(res)
    print_table(results, reps)
    if core:
        print_core(results)
    info["load_average_after"] = load_average()
    print(f"load average before {info['load_average_before']}, after {info['load_average_after']}")
    met = all(r["met"] for res in results.values() for r in res["variants"].values())
    missed = [n for res in results.values() for n, r in res["variants"].items() if not r["met"]]
    print(
        f"every variant within {TARGET_RATIO:g}x of its linear baseline: {met}"
        + (f" (missed: {', '.join(missed)})" if missed else "")
    )
    return {
        **result_header("laws", quick, info),
        "units": "seconds; errors as a fraction of the length; pressures in kPa",
        "settings": {
            "repetitions_per_pressure": reps,
            "warm_up_per_pressure": warm,
            "accuracy_target": ACCURACY,
            "error_reference": "4x the steps in every section",
            "newton": softrod.SolverOptions().as_kwargs(),
            "sigma": list(SIGMA),
            "table_map": "synthetic, 5^3 grid 0-70 kPa, PCHIP; sigma_ext 1-1.3 (channel 0), "
            "sigma_bend_x 1-0.9 (channel 1), sigma_bend_y 1-1.1 (channel 2)",
            "synthetic_table": SYNTHETIC_TABLE,
            "stiffness_map_via_solve_statics": api_supports_map(),
            "order": "round robin, reversed every other round",
        },
        "target_ratio": TARGET_RATIO,
        "groups": results,
        "all_met": met,
        "wall_time_s": time.perf_counter() - t_start,
    }


def main(argv=None) -> int:
    def core_option(parser) -> None:
        parser.add_argument(
            "--core",
            action="store_true",
            help="also time the Rust core alone (builds and runs the profile_solve example)",
        )

    return bench_main(argv, __doc__, "laws", lambda args: run(args.quick, args.core), core_option)


if __name__ == "__main__":
    sys.exit(main())
