"""Sweep on a Dask cluster against the in-process batch (a script, not a test).

    python benchmarks/bench_cluster.py             # 10^6 rows -> results/cluster.json (~8 min)
    python benchmarks/bench_cluster.py --quick     # 20^3 rows, smoke run
    python benchmarks/bench_cluster.py --n 60      # 60^3 rows

A 100^3 = 10^6-point full-factorial sweep of ``spa_three_chamber_130mm`` (0-70 kPa per
chamber, the design file's 16 RK4 steps per section), timed two ways on the same machine:
``solve_statics_batch`` in this process with all cores, and the same call with
``executor=`` a ``distributed.LocalCluster`` of 2 worker processes x 1 task slot (each task
runs the Rust batch on its share of the cores: cores / 2). Chunks follow softrod.cluster's
rule (4 per task slot, 2,000 to 100,000 rows). Overhead = cluster time / in-process time - 1
(target at this size: <= 10 %). The cluster's start-up (~2 s) is outside the timing, as it
is on a real cluster that serves many calls; a warm-up call loads the design on the workers.
On a shared machine the load drifts over minutes, so the runs go in the order in process,
cluster, cluster, in process (ABBA) and the overhead compares the sums; the CPU seconds of
this process (in process) and of the two workers (cluster) are recorded too, a measure that
the other processes on the machine hardly change.
"""

from __future__ import annotations

import resource
import sys
import time
from pathlib import Path

import numpy as np
import softrod
from softrod.cluster import chunk_rows

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import bench_main, load_average, machine, result_header  # noqa: E402

DESIGN = "spa_three_chamber_130mm"
TOP = 70e3  # Pa


def grid(n: int) -> np.ndarray:
    g = np.linspace(0.0, TOP, n)
    return np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)


def cpu_s() -> float:
    """CPU seconds (user + system) of the calling process."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def add_arguments(parser) -> None:
    parser.add_argument("--n", type=int, default=None, help="points per channel (default 100)")


def run(args) -> dict:
    from distributed import Client, LocalCluster

    t_start = time.perf_counter()
    info = machine()
    design = softrod.load_design(DESIGN)
    n = args.n or (20 if args.quick else 100)
    p = grid(n)
    m = len(p)
    softrod.solve_statics_batch(design, p[:1000])  # warm-up (page in, thread pool)
    times = {"in_process": [], "cluster": []}
    cpus = {"in_process": [], "cluster": []}
    with (
        LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster,
        Client(cluster) as client,
    ):
        softrod.solve_statics_batch(design, p[:1000], executor=client)  # design on workers
        for where in ("in_process", "cluster", "cluster", "in_process"):
            executor = client if where == "cluster" else None
            c0 = sum(client.run(cpu_s).values()) if executor else cpu_s()
            t0 = time.perf_counter()
            out = softrod.solve_statics_batch(design, p, executor=executor)
            times[where].append(time.perf_counter() - t0)
            cpus[where].append((sum(client.run(cpu_s).values()) if executor else cpu_s()) - c0)
            print(
                f"{where}: {m:,} rows in {times[where][-1]:.2f} s, {cpus[where][-1]:.2f} "
                f"CPU s, {int(out.converged.sum()):,} converged"
            )
            if where == "cluster":
                remote = out
            else:
                local = out
    t_local, t_cluster = sum(times["in_process"]), sum(times["cluster"])
    overhead = t_cluster / t_local - 1.0
    cpu_overhead = sum(cpus["cluster"]) / sum(cpus["in_process"]) - 1.0
    print(
        f"overhead {100 * overhead:+.1f} % wall, {100 * cpu_overhead:+.1f} % CPU (target <= 10 %)"
    )
    ok = local.converged & remote.converged
    diff = float(np.abs(local.tip_position[ok] - remote.tip_position[ok]).max())
    return {
        **result_header("cluster", args.quick, info, design=DESIGN),
        "rows": m,
        "grid": f"{n}^3, 0-{TOP / 1e3:g} kPa per chamber",
        "workers": 2,
        "task_slots_per_worker": 1,
        "chunk_rows": chunk_rows(m, 2),
        "chunks": -(-m // chunk_rows(m, 2)),
        "order": "in process, cluster, cluster, in process",
        "in_process_s": times["in_process"],
        "cluster_s": times["cluster"],
        "in_process_cpu_s": cpus["in_process"],
        "cluster_worker_cpu_s": cpus["cluster"],
        "in_process_solves_per_s": 2 * m / t_local,
        "cluster_solves_per_s": 2 * m / t_cluster,
        "overhead": overhead,
        "cpu_overhead": cpu_overhead,
        "converged_in_process": int(local.converged.sum()),
        "converged_cluster": int(remote.converged.sum()),
        # Every row is solved cold, so the two runs agree bitwise whatever the chunks
        # (tests/test_cluster.py checks it too).
        "max_tip_difference_m": diff,
        "load_average_after": load_average(),
        "wall_time_s": time.perf_counter() - t_start,
    }


if __name__ == "__main__":
    raise SystemExit(bench_main(sys.argv[1:], __doc__, "cluster", run, add_arguments))
