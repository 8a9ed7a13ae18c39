"""Progress of the calls that can take more than a few seconds.

``simulate``, ``simulate_system``, ``run_closed_loop``, the sensitivities of motion,
``Trajectory.animate``, ``calibrate``, ``identify_stiffness``, ``fit_stiffness_map`` and
``compare_models`` take ``progress=``:

- ``None`` (the default): a progress bar on stderr in an interactive session (the Python
  prompt, IPython, Jupyter), nothing in a script, so that batch jobs and their logs stay
  clean. The environment variable ``SOFTROD_PROGRESS=1`` (or ``0``) turns the default on (or
  off) everywhere.
- ``True``: always a bar; ``False``: never.
- a callable: called instead of drawing a bar, with the arguments each function documents
  (e.g. ``simulate`` calls ``progress(t_done, t_run, wall_s)``, t_run the run's length);
  one that cannot take them is refused before the work starts.

Bars are drawn with rich, imported only when one is shown.
"""

from __future__ import annotations

import contextlib
import inspect
import os
import sys
import time
from collections.abc import Callable, Iterator
from typing import Any

from .errors import InputError, design_error

__all__ = ["check_progress", "chunks", "interactive", "reporter"]

ENV = "SOFTROD_PROGRESS"
CHUNK_WALL_S = 0.2  # wall time of work between two progress reports of a stepped run


def interactive() -> bool:
    """True in the Python prompt, IPython or Jupyter (where a bar helps someone waiting)."""
    if hasattr(sys, "ps1") or sys.flags.interactive:
        return True
    ipython = sys.modules.get("IPython")
    if ipython is not None:
        get = getattr(ipython, "get_ipython", None)
        return get is not None and get() is not None
    return False


def check_progress(progress: Any, field: str = "progress") -> Any:
    """``progress`` if it is None, True, False or a callable; InputError otherwise."""
    if progress is None or isinstance(progress, bool) or callable(progress):
        return progress
    raise design_error(
        field,
        type(progress).__name__,
        "must be None (a bar in interactive sessions), True, False or a callable",
        InputError,
    )


def _check_arguments(progress: Callable, update: Callable, field: str) -> None:
    """Refuse, before any work, a callable that cannot take the arguments the call will pass
    (as many as ``update`` takes), rather than fail with a TypeError at its first report.
    Callables without a signature (some builtins) are let through."""
    try:
        wanted = inspect.signature(update).parameters.values()
        given = inspect.signature(progress)
    except (TypeError, ValueError):
        return
    if any(p.kind is p.VAR_POSITIONAL for p in wanted):
        return
    n = sum(p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) for p in wanted)
    try:
        given.bind(*([0.0] * n))
    except TypeError:
        raise design_error(
            field,
            getattr(progress, "__name__", type(progress).__name__),
            f"must be callable with {n} positional argument{'s' if n != 1 else ''} (see the "
            "function's documentation of progress=)",
            InputError,
        ) from None


def _wants_bar(progress: Any) -> bool:
    if progress is True:
        return True
    if progress is not None:
        return False
    setting = os.environ.get(ENV, "").strip().lower()
    if setting in ("1", "true", "yes", "on"):
        return True
    if setting in ("0", "false", "no", "off"):
        return False
    return interactive()


@contextlib.contextmanager
def reporter(
    progress: Any,
    label: str,
    total: float | None,
    update: Callable[..., tuple[float | None, str]],
    *,
    field: str = "progress",
) -> Iterator[Callable[..., None] | None]:
    """The callback a long call passes on while the block runs.

    ``progress`` (see the module docstring) as given when it is a callable; a function that
    moves a rich bar on stderr when a bar is wanted; else None. ``update(*args)`` turns the
    callback's arguments into (completed, text shown after the bar).
    """
    progress = check_progress(progress, field)
    if callable(progress) and not isinstance(progress, bool):
        _check_arguments(progress, update, field)
        yield progress
        return
    if not _wants_bar(progress):
        yield None
        return
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        Progress,
        SpinnerColumn,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    columns = [SpinnerColumn(), TextColumn("[bold]{task.description}")]
    if total is not None:
        columns += [BarColumn(bar_width=24), TextColumn("{task.percentage:>3.0f}%")]
    columns += [TextColumn("{task.fields[text]}"), TimeElapsedColumn()]
    if total is not None:
        columns += [TextColumn("ETA"), TimeRemainingColumn()]
    with Progress(*columns, console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task(label, total=total, text="")

        def advance(*args) -> None:
            completed, text = update(*args)
            bar.update(task, completed=completed, text=text)

        yield advance


def chunks(
    n: int, first: int = 32, smallest: int = 8, largest: int = 100_000, multiple: int = 1
) -> Iterator[tuple[int, int]]:
    """The index ranges ``(start, stop)`` that cover the steps ``0 ... n`` of a stepped run,
    each sized from the wall time the caller spent on the one before for about CHUNK_WALL_S
    of work (within ``smallest ... largest``, a multiple of ``multiple`` but for the last):
    a long run reports its progress often and samples its inputs a chunk at a time (memory
    stays bounded), a quick one is not slowed by many small calls into the core."""
    start, size = 0, first
    while start < n:
        stop = min(n, start + size)
        t = time.perf_counter()
        yield start, stop
        spent = time.perf_counter() - t
        size = min(max(int(size * CHUNK_WALL_S / max(spent, 1e-6)), smallest), largest)
        size = max(multiple, size // multiple * multiple)
        start = stop
