"""``softrod view``: the interactive 3-D viewer in the browser (docs/viewer.md)."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import InputError, design_error
from ._common import (
    _handle_errors,
    _parse_pressures,
    _parse_quantities,
    _parse_vector,
    _stdout,
)

_host_option = click.option(
    "--host",
    default="127.0.0.1",
    show_default=True,
    help="Interface to listen on (0.0.0.0: reachable from other machines).",
)
_port_option = click.option(
    "--port", type=click.IntRange(1, 65535), help="Port (default: a free one)."
)


def _pressure_range(text: str) -> tuple[float, float]:
    """--pressure-range LOW:HIGH in Pa."""
    parts = text.split(":")
    if len(parts) != 2:
        raise design_error("--pressure-range", text, "must read LOW:HIGH, e.g. 0:70kPa", InputError)
    low, high = _parse_quantities(
        parts, "pressure", ["--pressure-range.low", "--pressure-range.high"]
    )
    if not low < high:
        raise design_error("--pressure-range", text, "LOW must be below HIGH", InputError)
    return low, high


@click.command("view")
@click.argument("design")
@click.option(
    "--pressure",
    "-p",
    metavar="P1,P2,...",
    help="Initial gauge pressure per channel, e.g. 30kPa,0,0 (default 0).",
)
@click.option(
    "--pressure-range",
    metavar="LOW:HIGH",
    help="Range of the pressure sliders, e.g. 0:70kPa (default: 0 to the pressure that bends "
    "the softest chambered section by about half a turn).",
)
@click.option(
    "--tension",
    "-t",
    metavar="T1,T2,...",
    help="Initial tension per tendon channel, e.g. 2N,0 (>= 0; default 0: slack).",
)
@click.option(
    "--max-tension",
    metavar="T",
    help="Top of the tension sliders, e.g. 5N (default: the design's [operating_range] "
    "tension, else the tension that bends the softest tendon section by about half a turn).",
)
@click.option(
    "--max-force",
    metavar="F",
    help="Range of the tip-force sliders, +-F, e.g. 0.5N (default: the force that deflects the "
    "rod by about half its length).",
)
@click.option(
    "--trajectory",
    type=click.Path(dir_okay=False, exists=True, path_type=Path),
    help="Play back a saved trajectory (.parquet or .npz from `softrod simulate`).",
)
@click.option(
    "--data",
    type=click.Path(dir_okay=False, exists=True, path_type=Path),
    help="Show a dataset's measured tips against DESIGN's predictions (e.g. a calibrated "
    "design from `softrod calibrate --out`).",
)
@_host_option
@_port_option
@_handle_errors
def view(
    design, pressure, pressure_range, tension, max_tension, max_force, trajectory, data, host, port
):
    """Serve an interactive 3-D view of DESIGN in the browser (Ctrl-C stops it).

    One slider per pressure channel, per tendon and per tip-force component re-solves the
    shape live; the solver's state (converged, iterations, tip position, contact forces on
    the design's obstacles) shows beside it. Needs the viewer extra:
    pip install 'softrod[viewer]'.
    """
    from rich.text import Text

    from ..catalog import load_design

    d = load_design(design)
    p = None if pressure is None else _parse_pressures(pressure, d)
    p_range = None if pressure_range is None else _pressure_range(pressure_range)
    from .statics import _parse_tensions

    t = _parse_tensions(tension, d)
    t_max = None
    if max_tension is not None:
        (t_max,) = _parse_vector(max_tension, "force", "--max-tension", 1)
        if not t_max > 0:
            raise design_error("--max-tension", max_tension, "must be a positive force", InputError)
    f_max = None
    if max_force is not None:
        (f_max,) = _parse_vector(max_force, "force", "--max-force", 1)
        if not f_max > 0:
            raise design_error("--max-force", max_force, "must be a positive force", InputError)
    from ..viewer import view as start

    viewer = start(
        d,
        pressures=p,
        pressure_range=p_range,
        tensions=t,
        tension_max=t_max,
        force_max=f_max,
        trajectory=trajectory,
        dataset=data,
        host=host,
        port=port,
    )
    _stdout().print(
        Text(f"softrod viewer of {d.name}: open {viewer.url}  (Ctrl-C stops)"), soft_wrap=True
    )
    viewer.wait()


@click.command("view-system")
@click.argument("system")
@click.option(
    "--pressure-range",
    metavar="LOW:HIGH",
    help="Range of every pressure slider, e.g. 0:70kPa (default: 0 to the largest of the "
    "rods' defaults, as `softrod view` chooses them).",
)
@_host_option
@_port_option
@_handle_errors
def view_system_cmd(system, pressure_range, host, port):
    """Serve an interactive 3-D view of a SYSTEM of rods holding one platform (a system file
    or a bundled system) in the browser (Ctrl-C stops it): one slider per rod's pressure
    channel and tendon re-solves the whole system live; the platform's pose and the
    solver's state show beside it (docs/viewer.md, "Systems of rods")."""
    from rich.text import Text

    from ..system import load_system
    from ..viewer import view_system

    sysm = load_system(system)
    p_range = None if pressure_range is None else _pressure_range(pressure_range)
    viewer = view_system(sysm, pressure_range=p_range, host=host, port=port)
    _stdout().print(
        Text(f"softrod viewer of {sysm.name}: open {viewer.url}  (Ctrl-C stops)"),
        soft_wrap=True,
    )
    viewer.wait()
