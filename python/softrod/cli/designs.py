"""``softrod designs``: the bundled designs and the presets."""

from __future__ import annotations

import click

from ._common import _handle_errors, _stdout


@click.command()
@_handle_errors
def designs():
    """List the bundled designs, the presets, the systems of rods and the example datasets,
    with their channel count and source."""
    from rich.text import Text

    from ..catalog import bundled_designs
    from ..datasets import example_dataset_path, example_datasets
    from ..presets import list_presets
    from ..system import bundled_systems, load_system

    console = _stdout()
    console.print(Text("bundled designs (use the name as DESIGN):", style="bold"))
    for name in bundled_designs():
        _list_design(console, name, lambda d: d.citation)
    console.print()
    console.print(
        Text(
            "presets (published models built from a bundled design; use the name as DESIGN):",
            style="bold",
        )
    )
    summaries = {p.name: p.summary for p in list_presets()}
    for name, summary in summaries.items():
        _list_design(console, name, lambda d, s=summary: s)
    console.print()
    console.print(
        Text(
            "systems of rods (use the name as SYSTEM in solve-system and simulate-system):",
            style="bold",
        )
    )
    for name in bundled_systems():
        system = load_system(name)
        rods = ", ".join(r.design.name for r in system.rods)
        console.print(Text.assemble((name, "bold cyan"), f"  {len(system.rods)} rods: {rods}"))
    console.print()
    console.print(Text("example datasets (SYNTHETIC; use the name as DATA):", style="bold"))
    for name in example_datasets():
        path = example_dataset_path(name)
        console.print(Text.assemble((name, "bold cyan"), f"  {path.name}"))


def _list_design(console, name: str, note) -> None:
    from rich.padding import Padding
    from rich.text import Text

    from ..catalog import load_design
    from ..errors import DesignError

    try:
        d = load_design(name)
    except DesignError as exc:
        console.print(Text(name, style="bold"), Text(f"cannot load: {exc}", style="red"))
        return
    n = d.n_channels
    console.print(
        Text.assemble(
            (name, "bold cyan"),
            f"  {n} channel{'s' if n != 1 else ''}, {d.length * 1e3:.1f} mm",
        )
    )
    console.print(Padding(Text(note(d), style="dim"), (0, 0, 0, 4)))
