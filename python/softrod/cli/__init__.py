"""``softrod`` command line: solve one equilibrium, sweep a pressure grid, compare models on
a paper's experiments, calibrate parameters to measured tip positions (of a design or a
system of rods), identify a design from axial measurements, simulate motion, solve and
simulate systems of rods, run the PCC model, list designs and presets, run the demo, view a
design or a system in the browser, invert statics, map the workspace and track a path.

One module per command group: ``statics`` (solve, sweep, demo), ``compare``, ``calibrate``
(calibrate, calibrate-axial, calibrate-system, identify), ``simulate``, ``system``
(solve-system, simulate-system), ``pcc`` (compare-pcc, pcc-identify), ``designs``, ``view``
(view, view-system), ``control`` (inverse, workspace, modes, track); shared parsing, error
handling and output helpers in ``_common``.

Units at the boundary: quantities carry their units ("30kPa", "0.3bar", "-1 N", "2 ms"),
read by softrod's restricted unit grammar; a bare non-zero number is refused as ambiguous
(zero needs no unit; a unit on the last item of a list applies to all). Outputs state their
units (table headers, JSON keys, column names such as ``tip_x_mm``); every table written is
in the dataset schema (docs/datasets.md).

Start-up is kept fast (`softrod --help` imports neither numpy nor pandas): the command
modules import the model, numpy, pandas, scipy, pyarrow and matplotlib inside the commands.

``--quiet`` leaves out progress bars, notes and log lines; ``-v``/``-vv`` show the
``softrod`` logger's INFO/DEBUG records on stderr.

Exit codes: 0 success; 1 internal error (a bug); 2 bad design, input or output path (also
click's usage errors); 3 the solver did not converge. Errors print one red line
``error: <message>`` on stderr, never a traceback.
"""

from __future__ import annotations

import logging
import sys

import click

from .. import __version__
from .calibrate import calibrate, calibrate_axial, calibrate_system_cmd, identify
from .compare import compare
from .control import inverse, modes, track, workspace_cmd
from .designs import designs
from .pcc import compare_pcc_cmd, pcc_identify
from .simulate import simulate_cmd
from .statics import demo, solve, sweep
from .system import simulate_system_cmd, solve_system_cmd
from .view import view, view_system_cmd


class _StderrHandler(logging.Handler):
    """Log records as ``softrod: message`` lines on the current sys.stderr (looked up per
    record, so click's test runner, which swaps it, sees them too)."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            sys.stderr.write(f"{record.name}: {self.format(record)}\n")
        except Exception:  # pragma: no cover - logging must never break a command
            self.handleError(record)


_HANDLER = _StderrHandler()


def _configure_logging(ctx, quiet: bool, verbose: int) -> None:
    """The "softrod" logger for this command: warnings by default, errors only with
    --quiet, steps with -v (INFO) and details with -vv (DEBUG). Undone when the command
    ends, so that a program that calls ``main`` keeps its own logging."""
    logger = logging.getLogger("softrod")
    previous = logger.level
    if _HANDLER not in logger.handlers:
        logger.addHandler(_HANDLER)
    if quiet:
        level = logging.ERROR
    else:
        level = {0: logging.WARNING, 1: logging.INFO}.get(verbose, logging.DEBUG)
    logger.setLevel(level)

    def restore() -> None:
        logger.removeHandler(_HANDLER)
        logger.setLevel(previous)

    ctx.call_on_close(restore)


class _Main(click.Group):
    """The softrod group: click's usage errors (a bad option value, a missing argument)
    print as one red line with exit code 2, like every other error."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        try:
            code = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        except click.ClickException as exc:
            from ._common import _fail

            hint = ""
            if isinstance(exc, click.UsageError) and exc.ctx is not None:
                hint = f" (see: {exc.ctx.command_path} --help)"
            try:
                _fail(exc.format_message() + hint, exc.exit_code or 2)
            except click.exceptions.Exit as done:
                code = done.exit_code
        except click.Abort:
            click.echo("Aborted!", err=True)
            code = 1
        if not standalone_mode:
            return code
        sys.exit(code if isinstance(code, int) else 0)


@click.group(cls=_Main, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, "--version", prog_name="softrod", message="%(prog)s %(version)s")
@click.option(
    "--quiet",
    "-q",
    is_flag=True,
    help="Results and errors only: no progress bars, notes or log lines.",
)
@click.option(
    "--verbose",
    "-v",
    count=True,
    help="Log what softrod does on stderr (-v: steps, -vv: details).",
)
@click.pass_context
def main(ctx, quiet, verbose):
    """softrod: Cosserat-rod models of soft pneumatic actuators.

    DESIGN arguments are a TOML file or the name of a bundled design or preset (see
    `softrod designs`); DATA arguments are a .csv/.parquet file or the name of a bundled
    example dataset (spa130_synthetic, paper002_m3_synthetic).
    Quantities need units ("30kPa", "0.3bar", "-1 N", "2 ms"); zero needs none, and a unit
    on the last item of a list applies to all ("10,20,30kPa").
    Exit codes: 0 ok, 1 internal error, 2 bad design or input, 3 no convergence.
    """
    if quiet and verbose:
        raise click.UsageError("give --quiet or --verbose, not both")
    ctx.meta["softrod.cli"] = {"quiet": quiet, "verbose": verbose}
    _configure_logging(ctx, quiet, verbose)


for _command in (
    solve,
    sweep,
    demo,
    compare,
    calibrate,
    calibrate_axial,
    calibrate_system_cmd,
    identify,
    designs,
    simulate_cmd,
    solve_system_cmd,
    simulate_system_cmd,
    compare_pcc_cmd,
    pcc_identify,
    view,
    view_system_cmd,
    inverse,
    workspace_cmd,
    modes,
    track,
):
    main.add_command(_command)
