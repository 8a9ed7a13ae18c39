"""Helpers shared by the benchmark scripts (bench_statics.py, bench_laws.py); not a benchmark.

The scripts put this folder on sys.path and import it as a sibling module (``import common``).
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import platform
import statistics
import subprocess
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import scipy
import softrod

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
KPA = 1e3
# Representative pressures (kPa) on paper 001's actuator (spa_three_chamber_130mm, 0-70 kPa):
# rest, one/two/three chambers, mixed. bench_statics times its single solves on them,
# bench_laws its stiffness-map group.
P001_PRESSURES_KPA = [
    (0.0, 0.0, 0.0),
    (35.0, 0.0, 0.0),
    (70.0, 0.0, 0.0),
    (70.0, 70.0, 0.0),
    (20.0, 45.0, 70.0),
    (70.0, 35.0, 10.0),
    (70.0, 70.0, 70.0),
]


def kpa(p) -> list[float]:
    """Pressures in kPa as a list in Pa."""
    return [x * KPA for x in p]


def with_step_length(design, h_mm: float):
    """The design with numerics.step_length = h_mm (replaces its [numerics] table)."""
    return design.replace({"numerics": {"step_length": f"{h_mm} mm"}})


def steps_of(design) -> list[int]:
    """RK4 steps per section of the compiled design."""
    return [int(s["steps"]) for s in design.spec["sections"]]


def median(xs) -> float:
    """Median of the values that are not None; NaN when none is left."""
    xs = [x for x in xs if x is not None]
    return float(statistics.median(xs)) if xs else float("nan")


@contextmanager
def gc_disabled() -> Iterator[None]:
    """The garbage collector off inside the block (restored to its previous state)."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def timed(fn, reps: int) -> list[float]:
    """Wall-clock seconds of ``reps`` calls of fn(), GC off."""
    out = []
    with gc_disabled():
        for _ in range(reps):
            t0 = time.perf_counter_ns()
            fn()
            out.append((time.perf_counter_ns() - t0) * 1e-9)
    return out


def binding_solver(design, pp: list[float], **extra) -> Callable[[], dict]:
    """One cold solve at pressures ``pp`` (Pa) through the binding ``design._rod.solve``
    directly (no Python wrapper's validation or result object), with the design's tip force
    and moment and the default SolverOptions; ``extra`` keywords go to the binding too (e.g.
    ``stiffness_scale``)."""
    rod = design._rod
    tip = design.spec["tip"]
    tf = [float(x) for x in tip["force"]]
    tm = [float(x) for x in tip["moment"]]
    kwargs = {**extra, **softrod.SolverOptions().as_kwargs()}
    return lambda: rod.solve(pp, tf, tm, guess=None, **kwargs)


def load_average() -> list[float] | None:
    """The system's 1, 5 and 15 minute load averages (None where the OS has none)."""
    return list(os.getloadavg()) if hasattr(os, "getloadavg") else None


def machine() -> dict:
    """The machine and versions, for the results file."""
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            cwd=HERE,
            capture_output=True,
            text=True,
            timeout=5,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        commit = ""
    return {
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "softrod": softrod.__version__,
        "git_commit": commit,
        "core_debug_assertions": core_checked(),
        "load_average_before": load_average(),
    }


def core_checked() -> bool:
    """Whether the installed core checks debug assertions and integer overflow (the test
    command's ``checked`` build, or a debug build): slower than the release build that the
    timings are meant for."""
    return bool(getattr(softrod._core, "_debug_assertions", False))


def result_header(benchmark: str, quick: bool, info: dict, **extra) -> dict:
    """The first entries of a results file: the benchmark's name, ``extra`` (e.g. the design),
    the mode, the date (UTC) and the machine ``info``."""
    return {
        "benchmark": benchmark,
        **extra,
        "mode": "quick" if quick else "full",
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "machine": info,
    }


def write_json(path: Path, data: dict) -> None:
    """Whole or not at all, through softrod's one atomic writer (softrod.io.atomic_path)."""
    from softrod.io import atomic_path

    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        with open(tmp, "w") as fh:
            json.dump(data, fh, indent=2)
            fh.write("\n")


def bench_main(
    argv,
    doc: str,
    name: str,
    run: Callable[[argparse.Namespace], dict],
    add_arguments: Callable[[argparse.ArgumentParser], None] | None = None,
) -> int:
    """Command line of a benchmark script: ``--quick``, the script's own options
    (``add_arguments``), ``--output`` (default results/<name>.json, or <name>_quick.json with
    --quick); ``run(args)`` gives the results, written atomically as JSON."""
    parser = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="smoke run (< 20 s)")
    if add_arguments is not None:
        add_arguments(parser)
    parser.add_argument(
        "--output",
        type=Path,
        default=None,
        help=f"JSON file (default benchmarks/results/{name}.json, or {name}_quick.json with "
        "--quick)",
    )
    args = parser.parse_args(argv)
    if core_checked():
        print(
            "warning: softrod's core is a checked build (debug assertions and overflow checks, "
            "as scripts/test.sh installs it): these timings are slower than the release build's. "
            "For release timings: pip install -e '.[bench]'"
        )
    result = run(args)
    out = args.output or RESULTS / (f"{name}_quick.json" if args.quick else f"{name}.json")
    write_json(out, result)
    print(f"results written to {out} ({result['wall_time_s']:.1f} s)")
    return 0
