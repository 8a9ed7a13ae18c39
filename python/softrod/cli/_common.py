"""Shared pieces of the ``softrod`` commands: error handling (one red line and an exit code,
never a traceback), parsing of quantities with units, number formatting, progress columns,
output checks and staged (all-or-none) writes.

Quantities on the command line need units: ``--pressure 30kPa,0,0``, ``--dt "2 ms"``. A bare
non-zero number is refused as ambiguous (30000 what?); zero needs no unit, and a unit on the
last item of a list applies to every item (``10,20,30kPa``, ``0:70kPa:21``).
"""

from __future__ import annotations

import contextlib
import functools
import math
import os
from pathlib import Path

import click

from .._limits import MAX_QUANTITY_LENGTH, MAX_THREADS
from ..errors import ConvergenceError, DesignError, InputError, SoftrodError, design_error
from ..io import check_target, staged_paths

# Imported inside the functions that need them, never here: numpy, rich, pint (softrod.units)
# and the model (softrod.design). `softrod --help` imports this module and must stay fast.

ATM = 101_325.0  # Pa; gauge pressures below -1 atm are impossible

#: The figure formats the commands write.
PLOT_SUFFIXES = (".png", ".pdf", ".svg")


def _settings() -> dict:
    """The group options of this invocation (--quiet, --verbose)."""
    ctx = click.get_current_context(silent=True)
    meta = ctx.find_root().meta if ctx is not None else {}
    return meta.get("softrod.cli", {"quiet": False, "verbose": 0})


def _quiet() -> bool:
    """True with ``softrod --quiet``: results and errors only, no progress or notes."""
    return bool(_settings()["quiet"])


def _say(text: str, *, stderr: bool = False) -> None:
    """A note for people (``wrote out.csv``): one line, left out with --quiet."""
    if _quiet():
        return
    from rich.console import Console
    from rich.text import Text

    Console(stderr=stderr, highlight=False).print(Text(text), soft_wrap=True)


@contextlib.contextmanager
def _progress(label: str, total: float | None):
    """A progress bar on stderr while the block runs; yields ``advance(n)``.

    Shown only when stderr is a terminal and not with --quiet (redirected output and logs
    stay clean); it disappears when done, a summary line follows."""
    from rich.console import Console
    from rich.progress import Progress

    console = Console(stderr=True, highlight=False)
    if _quiet() or not console.is_terminal:
        yield lambda n=1: None
        return
    with Progress(*_progress_columns(), console=console, transient=True) as bar:
        task = bar.add_task(label, total=total)
        yield lambda n=1: bar.advance(task, n)


def _stdout():
    """A rich Console on the current sys.stdout."""
    from rich.console import Console

    # Made per call so that it writes to the current sys.stdout (click's test runner swaps it).
    return Console(highlight=False)


def _fail(message: str, code: int) -> None:
    from rich.console import Console
    from rich.text import Text

    line = " ".join(str(message).split())  # one line, whatever the message contains
    err = Console(stderr=True, highlight=False, soft_wrap=True)
    err.print(Text(f"error: {line}", style="bold red"))
    raise click.exceptions.Exit(code)


def _handle_errors(func):
    """Turn every exception into one red line and an exit code, never a traceback: softrod's
    errors (2 bad input, 3 no convergence), file-system errors (2), and anything else as an
    internal error (1; a bug to report; SOFTROD_DEBUG=1 shows the traceback)."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except click.exceptions.Exit:
            raise
        except ConvergenceError as exc:
            _fail(exc, 3)
        except DesignError as exc:  # includes InputError
            _fail(exc, 2)
        except SoftrodError as exc:
            _fail(exc, 2)
        except OSError as exc:
            where = f" ({exc.filename})" if getattr(exc, "filename", None) else ""
            _fail(f"{exc.strerror or exc}{where}", 2)
        except (click.ClickException, click.Abort, KeyboardInterrupt):
            raise
        except MemoryError:
            _fail("out of memory: the computation needs more memory than this machine has", 2)
        except BaseException as exc:  # a Rust panic (pyo3's PanicException) included
            if os.environ.get("SOFTROD_DEBUG"):
                raise
            _fail(
                f"internal error {type(exc).__name__}: {exc} (a bug in softrod: please report "
                "it with the command; SOFTROD_DEBUG=1 shows the traceback)",
                1,
            )

    return wrapper


def _is_bare(text: str) -> bool:
    """True for a number without a unit ("30000", "0", "1e3")."""
    try:
        from .._validate import split_quantity

        return split_quantity(text)[1] == ""
    except ValueError:
        return False


def _quantity(text: str, kind: str, option: str) -> float:
    """One quantity of a command-line option: it needs a unit unless it is zero."""
    from .._validate import quantity

    return quantity(text, kind, option, bare="error")


def _parse_quantities(items: list[str], kind: str, fields: list[str]) -> list[float]:
    """SI values of quantity strings, with one shorthand and one safety rule.

    - If only the last item carries a unit, it applies to every item ("0,0,-1 N",
      "10,20,30kPa", and in grids "0:70kPa").
    - Otherwise every item stands alone; a bare number other than zero is refused as
      ambiguous (30000 Pa or 30000 kPa?): it needs its unit.
    """
    from .. import _validate as V

    items = [t.strip() for t in items]
    for t, f in zip(items, fields, strict=True):
        if not t:
            raise design_error(f, t, f"is empty: give a {kind} such as '30kPa'", InputError)
        if len(t) > MAX_QUANTITY_LENGTH:
            raise design_error(f, t, f"is too long for a {kind}", InputError)
    bare = [_is_bare(t) for t in items]
    if len(items) > 1 and not bare[-1] and all(bare[:-1]):
        V.quantity(items[-1], kind, fields[-1], bare="error")  # a bad unit is named where given
        unit = V.split_quantity(items[-1])[1]
        items = [f"{t} {unit}" if b else t for t, b in zip(items, bare, strict=True)]
    hint = "(a unit on the last item alone applies to all items)" if len(items) > 1 else ""
    return [
        V.quantity(t, kind, f, bare=hint or "error") for t, f in zip(items, fields, strict=True)
    ]


def _parse_vector(text: str, kind: str, option: str, count: int) -> list[float]:
    items = text.split(",")
    if len(items) != count:
        raise design_error(option, text, f"give {count} comma-separated {kind} values", InputError)
    return _parse_quantities(items, kind, [f"{option}[{i}]" for i in range(count)])


def _parse_pressures(text: str | None, design) -> list[float]:
    n = design.n_channels
    if text is None:
        return [0.0] * n
    items = text.split(",")
    if len(items) != n:
        raise design_error(
            "--pressure",
            text,
            f"design {design.name} has {n} pressure channel{'s' if n != 1 else ''}; give {n} "
            "comma-separated gauge pressures, e.g. " + ",".join(["30kPa"] + ["0"] * (n - 1)),
            InputError,
        )
    values = _parse_quantities(items, "pressure", [f"--pressure[{i}]" for i in range(n)])
    for i, p in enumerate(values):
        if p < -ATM:
            raise design_error(
                f"--pressure[{i}]",
                items[i].strip(),
                "gauge pressure must be >= -1 atm (-101325 Pa)",
                InputError,
            )
    return values


def _parse_span(text: str, option: str, form: str, check_n) -> tuple[float, float, int]:
    """START:STOP:N with pressures START and STOP -> (start Pa, stop Pa, N). ``form``: the rule
    when the text is not three parts; ``check_n(start, stop, n, raw)`` rejects a bad N (n = 0
    when ``raw`` is not an integer), before both ends are checked to be >= -1 atm."""
    parts = text.split(":")
    if len(parts) != 3:
        raise design_error(option, text, form, InputError)
    start, stop = _parse_quantities(parts[:2], "pressure", [f"{option}.start", f"{option}.stop"])
    raw = parts[2].strip()
    n = int(raw) if raw.isascii() and raw.isdigit() and len(raw) <= 9 else 0
    check_n(start, stop, n, parts[2])
    for name, value, raw in (
        (f"{option}.start", start, parts[0]),
        (f"{option}.stop", stop, parts[1]),
    ):
        if value < -ATM:
            raise design_error(
                name, raw.strip(), "gauge pressure must be >= -1 atm (-101325 Pa)", InputError
            )
    return start, stop, n


def _parse_grid(text: str, option: str = "--grid"):
    """START:STOP:COUNT -> COUNT evenly spaced pressures in Pa (both ends included)."""
    import numpy as np

    def check_count(start: float, stop: float, count: int, raw: str) -> None:
        if count < 1:
            raise design_error(f"{option}.count", raw, "must be an integer >= 1", InputError)
        if count == 1 and start != stop:
            raise design_error(
                f"{option}.count",
                raw,
                "COUNT = 1 needs START = STOP (or give COUNT >= 2)",
                InputError,
            )

    start, stop, count = _parse_span(
        text, option, "must read START:STOP:COUNT, e.g. 0:70kPa:21", check_count
    )
    return np.linspace(start, stop, count)


def _full_factorial(axes: list):
    """All combinations, channel 0 slowest and the last channel fastest (C order)."""
    import numpy as np

    mesh = np.meshgrid(*axes, indexing="ij")
    return np.stack([m.ravel() for m in mesh], axis=1)


def _fmt(x: float, digits: int) -> str:
    # round first, then + 0.0 turns the -0.0 of tiny negative values into 0.0
    return f"{round(float(x), digits) + 0.0:.{digits}f}"


def _fmt_vec(v, scale: float = 1.0, digits: int = 3) -> str:
    return "(" + ", ".join(_fmt(x * scale, digits) for x in v) + ")"


def _channels(prefix: str, n: int) -> str:
    """How a table names n inputs: 'p0' for one, 'p0..p2' for three."""
    return f"{prefix}0" if n == 1 else f"{prefix}0..{prefix}{n - 1}"


def _fmt_kpa(pressures) -> str:
    return ", ".join(f"{p / 1e3:g}" for p in pressures)


def _for_option(check, path: Path, option: str) -> Path:
    """Run a path check; name the command-line option in the error instead of 'path'."""
    try:
        return check(path)
    except InputError as exc:
        raise design_error(option, str(path), exc.rule, InputError) from None


def _pyplot():
    # The CLI only writes files, never opens windows: the non-interactive Agg backend works
    # with and without a display. Selected here, never when the library is imported.
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _write_shape_plot(solutions, path: Path, title: str | None = None) -> Path:
    plt = _pyplot()
    from ..plotting import plot_shape, save_figure

    fig = plot_shape(solutions, title=title)
    try:
        return save_figure(fig, path)
    finally:
        plt.close(fig)


def _progress_columns() -> tuple:
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        ProgressColumn,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )
    from rich.text import Text

    class _RateColumn(ProgressColumn):
        """Rows per second of a progress task."""

        def render(self, task) -> Text:
            # The mean rate since the start: steadier than rich's windowed estimate, and
            # defined after a single advance (a sweep of one chunk).
            elapsed = task.elapsed
            if not elapsed or not task.completed:
                return Text("-- rows/s", style="cyan")
            return Text(f"{task.completed / elapsed:,.0f} rows/s", style="cyan")

    return (  # fits in 80 columns
        TextColumn("[bold]{task.description}"),
        BarColumn(bar_width=24),
        MofNCompleteColumn(),
        _RateColumn(),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
    )


def _threads_option(help_text: str):
    """The ``--threads`` option of the commands that solve batches (0 = all cores)."""
    return click.option(
        "--threads",
        default=0,
        show_default=True,
        type=click.IntRange(min=0, max=MAX_THREADS),
        help=help_text,
    )


def _scheduler_option(help_text: str):
    """The ``--scheduler ADDRESS`` option of the commands that can run on a Dask cluster."""
    return click.option("--scheduler", metavar="ADDRESS", default=None, help=help_text)


# The time integrator's options shared by `simulate` and `simulate-system`.
_alpha_option = click.option(
    "--alpha",
    default=None,
    type=float,
    help="BDF-alpha parameter in [-0.5, 0] (default -0.2; -0.5: the trapezoidal rule; 0: "
    "BDF2). Not with --scheme midpoint.",
)
_energy_tol_option = click.option(
    "--energy-tol",
    "energy_tol",
    default=0.02,
    show_default=True,
    type=float,
    help="The energy check: growth of the energy balance beyond this fraction of the "
    "energy moved stops the run with an error.",
)


@contextlib.contextmanager
def _scheduler(address: str | None):
    """A ``distributed.Client`` connected to ``address`` for the block (None: no cluster)."""
    if address is None:
        yield None
        return
    from ..cluster import connect

    client = connect(address)
    try:
        yield client
    finally:
        client.close()


def _check_output(path: Path, option: str, suffixes: tuple[str, ...], what: str) -> Path:
    """Fail fast on an output path (suffix, an existing writable folder), before a long
    computation; the error names the option and the target."""
    if path.suffix.lower() not in suffixes:
        raise design_error(
            option,
            str(path),
            f"{what}: the file name must end in {' or '.join(suffixes)}",
            InputError,
        )
    return _for_option(check_target, path, option)


@contextlib.contextmanager
def _staged(paths: list[Path]):
    """Yield a temporary path per destination (beside it, named so that a later write into
    the folder removes it if this process dies). When the block succeeds every file is moved
    into place; when it fails none is, and the destinations are left as they were: several
    outputs are written all or none."""
    with staged_paths(paths) as staged:
        yield staged


def _as_option(exc: InputError, renames: dict[str, str], values: dict[str, str] | None = None):
    """The error with the command-line option in place of the API field it names (others
    unchanged); ``values`` replaces the value by what was typed for that option."""
    option = renames.get(exc.field)
    if option is None:
        return exc
    value = (values or {}).get(exc.field, exc.value)
    return design_error(option, value, exc.rule, InputError)


def _renamed(option: str, func, *args):
    """Call func; name the command-line option in an InputError instead of the API field."""
    try:
        return func(*args)
    except InputError as exc:
        raise design_error(option, exc.value, exc.rule, InputError) from None


def _num(x: float, scale: float = 1.0, digits: int = 6) -> str:
    x = float(x)
    if math.isnan(x):
        return "n/a"
    if math.isinf(x):
        return "inf"
    return f"{x * scale:.{digits}g}"


def _print_warnings(console, messages: list[str]) -> None:
    from rich.text import Text

    for message in messages:
        console.print(Text(f"warning: {message}", style="bold yellow"))


def _friction_steps_option(what: str):
    return click.option(
        "--friction-steps",
        type=click.IntRange(1, 100_000),
        help=f"Load increments of {what} (an obstacle with friction > 0; the answer "
        "follows the load path to first order in the increment, docs/contact.md 'Friction "
        "in the statics'). Default: SolverOptions' (80).",
    )


def _contact_json(sol) -> dict:
    """A solution's contact with its obstacles for --json: {"contact": {...}} with each
    obstacle's resultant force and its friction part (N, world frame), the deepest
    penetration (m) and the nodes in contact; nothing without obstacles."""
    if sol.contact is None:
        return {}
    return {
        "contact": {
            "total_force_N": sol.contact.total_force.tolist(),
            "friction_force_N": sol.contact.friction_force.tolist(),
            "max_penetration_m": sol.contact.max_penetration,
            "nodes_in_contact": int(sol.contact.in_contact.sum()),
        }
    }
