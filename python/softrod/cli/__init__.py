"""``softrod`` command line: solve one equilibrium, sweep a pressure grid, compare models on
a paper's experiments, calibrate parameters to measured tip positions, identify a design from
axial measurements, simulate motion, run the PCC model, list designs and presets, run the demo,
view a design in the browser.

One module per command group: ``statics`` (solve, sweep, demo), ``compare``, ``calibrate``
(calibrate, calibrate-axial, identify), ``simulate``, ``pcc`` (compare-pcc, pcc-identify),
``designs``, ``view``; shared parsing, error handling and output helpers in ``_common``.

Units at the boundary: pressures and loads are read with pint ("30kPa", "0.3bar", "-1 N");
a bare number is SI (Pa, N, N m). Outputs state their units (table headers, JSON keys,
column names such as ``x_mm``).

Exit codes: 0 success; 2 bad design, input or output path (also click's usage errors);
3 the solver did not converge. Errors print one red line ``error: <message>`` on stderr.
"""

from __future__ import annotations

import click

from .. import __version__
from .calibrate import calibrate, calibrate_axial, identify
from .compare import compare
from .designs import designs
from .pcc import compare_pcc_cmd, pcc_identify
from .simulate import simulate_cmd
from .statics import demo, solve, sweep
from .view import view


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, "--version", prog_name="softrod", message="%(prog)s %(version)s")
def main():
    """softrod: Cosserat-rod models of soft pneumatic actuators.

    DESIGN arguments are a TOML file or the name of a bundled design (see `softrod designs`).
    Quantities take units ("30kPa", "0.3bar", "-1 N"); a bare number is SI.
    Exit codes: 0 ok, 2 bad design or input, 3 no convergence.
    """


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
