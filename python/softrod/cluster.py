"""Running batch work on a Dask cluster (docs/cluster.md).

``solve_statics_batch``, ``identify_stiffness`` and the restarts of ``calibrate`` take
``executor=``, a ``distributed.Client``. The work is cut into chunks of rows; each chunk is
one task that runs the Rust batch on the worker with the cores that worker may use; results
are gathered in input order. When a worker dies, the scheduler reruns its unfinished tasks
on the others (every task is a pure function of its arguments, so a rerun gives the same
rows), and each chunk is placed in the output exactly once, by its index.

Designs travel as their TOML text, never as pickled objects: a worker rebuilds (and caches)
the design from the text with the same validation as a file. dask.distributed is an optional
dependency (``pip install 'softrod[cluster]'``), imported only when an executor is given.
"""

from __future__ import annotations

import hashlib
import math
import os
import uuid
from collections import OrderedDict
from collections.abc import Callable, Sequence
from typing import Any

from .errors import InputError, design_error

#: Chunk-size rule (rows per task): at least CHUNKS_PER_SLOT chunks for every task slot of
#: the cluster, so that the slots stay busy to the end and a lost worker costs little, but
#: at least MIN_CHUNK_ROWS rows, so that a task's fixed cost (scheduling, transfer, a few
#: ms) stays below 1 % of its solves (~50 us or more each), and at most MAX_CHUNK_ROWS, so
#: that one result stays a few tens of MB and the progress bar moves.
CHUNKS_PER_SLOT = 4
MIN_CHUNK_ROWS = 2_000
MAX_CHUNK_ROWS = 100_000

#: How long `connect` waits for a scheduler before it gives up.
CONNECT_TIMEOUT = "10s"

#: A worker keeps this many rebuilt designs (by the hash of their TOML text).
_DESIGN_CACHE_SIZE = 16
_designs: OrderedDict[str, Any] = OrderedDict()


def check_executor(executor):
    """``executor`` if it is a ``distributed.Client`` (or None); an InputError otherwise."""
    if executor is None:
        return None
    try:
        from distributed import Client
    except ModuleNotFoundError:  # pragma: no cover (extra not installed)
        raise design_error(
            "executor",
            type(executor).__name__,
            "needs dask.distributed: pip install 'softrod[cluster]'",
            InputError,
        ) from None
    if not isinstance(executor, Client):
        raise design_error(
            "executor",
            type(executor).__name__,
            "must be a distributed.Client (e.g. Client(LocalCluster()) or Client('tcp://...'))",
            InputError,
        )
    if executor.status not in ("running", "connecting", "newly-created"):
        raise design_error(
            "executor", executor, f"is {executor.status}: connect it first", InputError
        )
    return executor


def connect(address: str):
    """A ``distributed.Client`` connected to the scheduler at ``address`` (the CLI's
    ``--scheduler``), or an InputError that says why not."""
    try:
        from distributed import Client
    except ModuleNotFoundError:  # pragma: no cover (extra not installed)
        raise design_error(
            "--scheduler",
            address,
            "needs dask.distributed: pip install 'softrod[cluster]'",
            InputError,
        ) from None
    try:
        return Client(address, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError, ValueError) as exc:
        raise design_error(
            "--scheduler",
            address,
            f"cannot connect to a Dask scheduler there ({exc})",
            InputError,
        ) from None


def design_text(design) -> str:
    """The TOML text of a design's document (what travels to the workers): units on every
    value (as Design.save writes them), a stiffness map or mesh file by its absolute path."""
    import tomli_w

    from .design import _with_units

    doc = _with_units(_plain(design.document))
    if design.stiffness_map_source is not None:
        doc["stiffness_map"] = {**doc["stiffness_map"], "file": str(design.stiffness_map_source)}
    for k, file in design.mesh_sources:
        doc["obstacles"][k] = {**doc["obstacles"][k], "file": str(file)}
    return tomli_w.dumps(doc)


def _plain(value):
    """numpy scalars and arrays (e.g. fitted values put into a document) as Python ones."""
    import numpy as np

    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    return value


def design_from_text(text: str):
    """The Design of a TOML text, rebuilt once per worker and cached."""
    key = hashlib.sha256(text.encode()).hexdigest()
    design = _designs.get(key)
    if design is None:
        import sys

        from .design import read_design

        if sys.version_info >= (3, 11):
            import tomllib
        else:  # pragma: no cover
            import tomli as tomllib
        design = read_design(tomllib.loads(text))
        _designs[key] = design
        while len(_designs) > _DESIGN_CACHE_SIZE:
            _designs.popitem(last=False)
    else:
        _designs.move_to_end(key)
    return design


def task_slots(executor) -> tuple[int, dict[str, int]]:
    """(task slots of the whole cluster, task slots per host)."""
    info = (
        executor.scheduler_info(n_workers=-1)
        if _takes_n_workers(executor)
        else (executor.scheduler_info())
    )
    per_host: dict[str, int] = {}
    for w in info["workers"].values():
        host = w.get("host", "")
        per_host[host] = per_host.get(host, 0) + int(w.get("nthreads", 1))
    return max(sum(per_host.values()), 1), per_host


def _takes_n_workers(executor) -> bool:
    import inspect

    return "n_workers" in inspect.signature(executor.scheduler_info).parameters


def chunk_rows(m: int, slots: int, chunk_size: int | None = None) -> int:
    """Rows per task for ``m`` rows on ``slots`` task slots (the rule above), or
    ``chunk_size`` when given (checked)."""
    if chunk_size is not None:
        if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1:
            raise design_error("chunk_size", chunk_size, "must be an integer >= 1", InputError)
        return chunk_size
    want = math.ceil(m / (CHUNKS_PER_SLOT * max(slots, 1)))
    return max(1, min(max(want, MIN_CHUNK_ROWS), MAX_CHUNK_ROWS))


def worker_threads(per_host: dict[str, int], threads: int) -> int:
    """Rust threads for one task on this worker: ``threads`` when given (> 0), else the
    cores this process may use divided by the task slots on its host, so that the tasks
    running side by side on a machine share its cores without oversubscription."""
    if threads > 0:
        return threads
    try:
        from distributed import get_worker

        worker = get_worker()
        host = worker.address.split("://")[-1].rsplit(":", 1)[0]
        slots = per_host.get(host, worker.state.nthreads)
    except (ImportError, ValueError):
        slots = 1
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return max(1, (cores or 1) // max(slots, 1))


def run_chunks(
    executor,
    func: Callable,
    chunks: Sequence[tuple],
    *,
    sizes: Sequence[int] | None = None,
    progress: Callable[[int, int], None] | None = None,
    name: str = "softrod",
) -> list:
    """``[func(*args) for args in chunks]`` on the cluster, in order.

    Every chunk is one task with a unique key; a task whose worker dies is rerun by the
    scheduler (up to its ``allowed-failures``; then this raises the scheduler's
    ``KilledWorker``). ``progress(done, total)`` is called after each chunk, counted in
    ``sizes`` (default: one per chunk)."""
    from distributed import as_completed

    sizes = [1] * len(chunks) if sizes is None else list(sizes)
    total = sum(sizes)
    tag = uuid.uuid4().hex[:12]
    futures = [
        executor.submit(func, *args, key=f"{name}-{tag}-{i}", pure=False)
        for i, args in enumerate(chunks)
    ]
    index = {f.key: i for i, f in enumerate(futures)}
    results: list = [None] * len(futures)
    filled = [False] * len(futures)
    done = 0
    try:
        for future in as_completed(futures):
            i = index[future.key]
            results[i] = future.result()  # re-raises the task's error, if any
            if filled[i]:  # pragma: no cover (as_completed yields each future once)
                raise RuntimeError(f"chunk {i} arrived twice")
            filled[i] = True
            done += sizes[i]
            if progress is not None:
                progress(done, total)
    finally:
        for f in futures:
            if not f.done():
                f.cancel()
    return results
