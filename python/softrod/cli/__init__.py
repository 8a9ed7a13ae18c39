"""``softrod`` command line: solve one equilibrium, sweep a pressure grid, compare models on
a paper's experiments, calibrate parameters to measured tip positions, identify a design from
axial measurements, simulate motion, run the PCC model, list designs and presets, run the demo,
view a design in the browser.

One module per command group: ``statics`` (solve, sweep, demo), ``compare``, ``calibrate``
(calibrate, calibrate-axial, identify), ``simulate``, ``pcc`` (compare-pcc, pcc-identify),
``designs``, ``view``; shared parsing, error handling and output helpers in ``_common``.

Units at the boundary: pressures and loads are read with pint ("30kPa", "0.3bar", "-1 N");
a bare number is SI (Pa, N, N m). Outputs state their units (table headers, JSON keys,
column names such as ``tip_x_mm``); every table written is in the dataset schema
(docs/datasets.md).

Start-up is kept fast (`softrod --help` imports neither numpy nor pandas): the command
modules import the model, numpy, pandas, scipy, pyarrow and matplotlib inside the commands.

``--quiet`` leaves out progress bars, notes and log lines; ``-v``/``-vv`` show the
``softrod`` logger's INFO/DEBUG records on stderr.

Exit codes: 0 success; 2 bad design, input or output path (also click's usage errors);
3 the solver did not converge. Errors print one red line ``error: <message>`` on stderr.
"""

from __future__ import annotations

import logging
import sys

import click

from .. import __version__
from .calibrate import calibrate, calibrate_axial, identify
from .compare import compare
from .designs import designs
from .pcc import compare_pcc_cmd, pcc_identify
from .simulate import simulate_cmd
from .statics import demo, solve, sweep
from .view import view


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


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
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
    Quantities take units ("30kPa", "0.3bar", "-1 N"); a bare number is SI.
    Exit codes: 0 ok, 2 bad design or input, 3 no convergence.
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
    identify,
    designs,
    simulate_cmd,
    compare_pcc_cmd,
    pcc_identify,
    view,
):
    main.add_command(_command)
