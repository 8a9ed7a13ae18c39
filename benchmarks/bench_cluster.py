"""Sweep on a Dask cluster against the in-process batch (a script, not a test).

    python benchmarks/bench_cluster.py          # 10^6 rows -> results/cluster.json (~4 min)
    python benchmarks/bench_cluster.py --quick  # 20^3 rows, smoke run

A 100^3 = 10^6-point full-factorial sweep of ``spa_three_chamber_130mm`` (0-70 kPa per
chamber, the design file's 16 RK4 steps per section), timed two ways on the same machine:
``solve_statics_batch`` in this process with all cores, and the same call with
``executor=`` a ``distributed.LocalCluster`` of 2 worker processes x 1 task slot (each task
runs the Rust batch on its share of the cores: cores / 2). Chunks follow softrod.cluster's
rule (4 per task slot, 2,000 to 100,000 rows). Overhead = cluster time / in-process time - 1
(target at this size: <= 10 %). The cluster's start-up (~2 s) is outside the timing, as it
is on a real cluster that serves many calls; a warm-up call loads the design on the workers.
One run of each (the sweep is long enough that its timing noise is the machine's load, which
is recorded before and after).
"""

from __future__ import annotations

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


def run(args) -> dict:
    from distributed import Client, LocalCluster

    t_start = time.perf_counter()
    info = machine()
    design = softrod.load_design(DESIGN)
    n = 20 if args.quick else 100
    p = grid(n)
    m = len(p)
    softrod.solve_statics_batch(design, p[:1000])  # warm-up (page in, thread pool)
    t0 = time.perf_counter()
    local = softrod.solve_statics_batch(design, p)
    t_local = time.perf_counter() - t0
    print(f"in process: {m:,} rows in {t_local:.2f} s ({m / t_local:,.0f} solves/s)")

    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, Client(cluster) as client:
        softrod.solve_statics_batch(design, p[:1000], executor=client)  # design on workers
        t0 = time.perf_counter()
        remote = softrod.solve_statics_batch(design, p, executor=client)
        t_cluster = time.perf_counter() - t0
    print(f"on the cluster: {t_cluster:.2f} s ({m / t_cluster:,.0f} solves/s)")
    overhead = t_cluster / t_local - 1.0
    print(f"overhead {100 * overhead:+.1f} % (target <= 10 %)")
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
        "in_process_s": t_local,
        "cluster_s": t_cluster,
        "in_process_solves_per_s": m / t_local,
        "cluster_solves_per_s": m / t_cluster,
        "overhead": overhead,
        "converged_in_process": int(local.converged.sum()),
        "converged_cluster": int(remote.converged.sum()),
        # Chunks of different sizes warm-start different rows, so the two runs agree to the
        # solver tolerance, not bitwise (tests/test_cluster.py checks bitwise equality).
        "max_tip_difference_m": diff,
        "load_average_after": load_average(),
        "wall_time_s": time.perf_counter() - t_start,
    }


if __name__ == "__main__":
    raise SystemExit(bench_main(sys.argv[1:], __doc__, "cluster", run))
