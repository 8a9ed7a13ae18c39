"""Where people wait (a script, not a test): start-up, the hybrid map's fit, the animation.

    python benchmarks/bench_waiting.py          # full run -> results/waiting.json
    python benchmarks/bench_waiting.py --quick  # smoke run (< 30 s)

1. **Start-up.** ``softrod --help`` and ``python -c "import softrod"`` in fresh interpreters:
   median wall time of 9 runs after one warm-up (the files are in the page cache), and the
   heavy libraries each has imported (none is the design: numpy, pandas, scipy, pyarrow and
   matplotlib load inside the commands).
2. **fit_stiffness_map** (paper 001's 3-45-50-1 networks) on the per-sample factors of the
   bundled synthetic example (216 poses of ``spa_three_chamber_130mm``): as softrod runs it
   (BLAS on one thread, softrod._threads) and, for comparison, the same function without that
   limit (``fit_stiffness_map.__wrapped__``) at the BLAS library's default thread count.
   Each variant runs in its own fresh process, alternating (ABAB...), with wall and CPU time
   (user + system of the process), so a busy machine shows up as CPU time spent spinning.
   The networks of the two must be identical (printed).
3. **Animation.** The README's example: paper 000's 116 s square pulses on ``pam_arm_220mm``
   (dt 2 ms), shapes stored as the animation plan asks, a GIF at the defaults: frames, clip
   length and rendering time.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import bench_main, load_average, machine, median, result_header  # noqa: E402

HEAVY = ("numpy", "pandas", "scipy", "pyarrow", "matplotlib", "pint", "sklearn", "rich")

_FIT = """
import json, os, resource, sys, time
import numpy as np
import softrod
from softrod.calibration import fit_stiffness_map, identify_stiffness
from threadpoolctl import threadpool_info
data = softrod.load_dataset("spa130_synthetic")
ident = identify_stiffness("spa_three_chamber_130mm", data)
fit = fit_stiffness_map if sys.argv[1] == "one" else fit_stiffness_map.__wrapped__
r0, t0 = resource.getrusage(resource.RUSAGE_SELF), time.perf_counter()
model = fit(ident, seed=0)
wall = time.perf_counter() - t0
r1 = resource.getrusage(resource.RUSAGE_SELF)
cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
np.save(sys.argv[2], model.predict(data.pressures))
threads = sorted({p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"})
print(json.dumps({"wall_s": wall, "cpu_s": cpu, "blas_default_threads": threads}))
"""


def _run(args: list[str], **kw) -> subprocess.CompletedProcess:
    return subprocess.run(args, capture_output=True, text=True, check=True, **kw)


def startup(reps: int) -> dict:
    softrod_cli = str(Path(sys.executable).with_name("softrod"))
    cases = {
        "softrod --help": [softrod_cli, "--help"],
        "import softrod": [sys.executable, "-c", "import softrod"],
    }
    out = {}
    for name, args in cases.items():
        _run(args)  # warm-up: files in the page cache
        times = []
        for _ in range(reps):
            t0 = time.perf_counter()
            _run(args)
            times.append(time.perf_counter() - t0)
        out[name] = {"median_s": median(times), "runs": reps}
    code = (
        "import sys\nfrom softrod.cli import main\n"
        "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
        f"print(sorted(m for m in {HEAVY!r} if m in sys.modules), file=sys.stderr)"
    )
    out["softrod --help"]["heavy_modules_imported"] = _run([sys.executable, "-c", code]).stderr
    return out


def hybrid_fit(pairs: int) -> dict:
    runs: dict[str, list[dict]] = {"one BLAS thread (softrod)": [], "default BLAS threads": []}
    with tempfile.TemporaryDirectory() as tmp:
        arrays = {}
        variants = (("one BLAS thread (softrod)", "one"), ("default BLAS threads", "default"))
        for i in range(pairs):
            for label, mode in variants:
                path = str(Path(tmp) / f"{mode}{i}.npy")
                res = json.loads(_run([sys.executable, "-c", _FIT, mode, path]).stdout)
                runs[label].append(res)
                arrays.setdefault(mode, []).append(path)
        import numpy as np

        first = np.load(arrays["one"][0])
        identical = all(np.array_equal(first, np.load(p)) for mode in arrays for p in arrays[mode])
    summary = {
        label: {
            "median_wall_s": median([r["wall_s"] for r in rs]),
            "median_cpu_s": median([r["cpu_s"] for r in rs]),
            "walls_s": [round(r["wall_s"], 3) for r in rs],
            "blas_default_threads": rs[0]["blas_default_threads"],
        }
        for label, rs in runs.items()
    }
    summary["identical_predictions_in_every_run"] = identical
    return summary


def animation(quick: bool) -> dict:
    import softrod
    from softrod.dynamics import PressureSchedule, animation_plan

    duration = 20.0 if quick else 116.0
    plan = animation_plan(duration)
    t0 = time.perf_counter()
    traj = softrod.simulate(
        "pam_arm_220mm",
        PressureSchedule.paper000_square_pulses(),
        duration,
        dt=2e-3,
        shapes=plan.frame_interval_s,
        progress=False,
    )
    sim = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        t1 = time.perf_counter()
        path = traj.animate(Path(tmp) / "arm.gif", progress=False)
        render = time.perf_counter() - t1
        from PIL import Image

        with Image.open(path) as img:
            frames, ms = img.n_frames, img.info["duration"]
        size = os.path.getsize(path)
    return {
        "simulated_s": duration,
        "simulate_wall_s": sim,
        "plan": {"speed": plan.speed, "fps": plan.fps, "frames": plan.n_frames},
        "gif_frames": frames,
        "gif_ms_per_frame": ms,
        "clip_s": frames * ms / 1000,
        "render_wall_s": render,
        "gif_bytes": size,
    }


def run(args) -> dict:
    t0 = time.perf_counter()
    info = machine()
    result = result_header("waiting", args.quick, info)
    result["startup"] = startup(3 if args.quick else 9)
    result["fit_stiffness_map"] = hybrid_fit(1 if args.quick else 3)
    result["animation"] = animation(args.quick)
    result["load_average_after"] = load_average()
    result["wall_time_s"] = time.perf_counter() - t0
    shown = {k: result[k] for k in ("startup", "fit_stiffness_map", "animation")}
    print(json.dumps(shown, indent=2))
    return result


if __name__ == "__main__":
    sys.exit(bench_main(sys.argv[1:], __doc__, "waiting", run))
