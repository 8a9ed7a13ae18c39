"""CLI commands of the PCC model (paper 003): ``compare-pcc`` and ``pcc-identify``.

Registered on the ``softrod`` group by ``add_pcc_commands`` (end of cli.py).
"""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np
from rich.progress import Progress

from .design import load_design
from .errors import InputError, design_error
from .io import atomic_path, check_table_path, write_table
from .units import to_si

KINDS = ("longitudinal-stiffness", "bending-stiffness", "longitudinal-damping", "bending-damping")


def _channels(text: str) -> list[int]:
    try:
        return [int(t) for t in text.split(",")]
    except ValueError:
        raise design_error(
            "--channels", text, "give comma-separated channel indices, e.g. 0,1,5", InputError
        ) from None


def _read_columns(path: Path, needed: list[str]) -> dict[str, np.ndarray]:
    import pandas as pd

    df = pd.read_parquet(path) if path.suffix.lower() == ".parquet" else pd.read_csv(path)
    missing = [c for c in needed if c not in df.columns]
    if missing:
        raise design_error(
            str(path),
            ", ".join(df.columns),
            f"needs the column(s) {', '.join(missing)} (SI units in the names)",
            InputError,
        )
    return {c: df[c].to_numpy(dtype=float) for c in df.columns}


def add_pcc_commands(main: click.Group) -> None:
    """Add the PCC commands to the ``softrod`` group."""
    from .cli import _for_option, _handle_errors, _progress_columns, _pyplot, _stdout

    @main.command("compare-pcc")
    @click.argument("design")
    @click.option("--channels", required=True, help="Channels pressurised together, e.g. 0,1,5.")
    @click.option("--p-max", "p_max", default="1 bar", show_default=True, help="Largest pressure.")
    @click.option("--steps", default=11, show_default=True, help="Pressure levels from 0.")
    @click.option(
        "--tip-force",
        "tip_force",
        default="0,0,-0.0981 N",
        show_default=True,
        help="Tip load of the third case, world frame (default: a 10 g weight).",
    )
    @click.option(
        "--out",
        "out",
        required=True,
        type=click.Path(dir_okay=False, path_type=Path),
        help="Figure (.png, .pdf, .svg): tip error vs pressure and tip paths.",
    )
    @click.option(
        "--table",
        "table",
        type=click.Path(dir_okay=False, path_type=Path),
        help="Also write the numbers (.csv or .parquet).",
    )
    @_handle_errors
    def compare_pcc_cmd(design, channels, p_max, steps, tip_force, out, table):
        """PCC model vs Cosserat rod on DESIGN: tip positions while CHANNELS ramp to P_MAX,
        weightless, with gravity, and with gravity and a tip load (docs/pcc.md)."""
        from .cli import _parse_vector
        from .pcc.compare import compare_pcc, plot_pcc_comparison

        d = load_design(design)
        chans = _channels(channels)
        if any(c < 0 or c >= d.n_channels for c in chans):
            raise design_error(
                "--channels", channels, f"must be channel indices 0..{d.n_channels - 1}", InputError
            )
        pmax = to_si(p_max, "pressure", "--p-max", InputError)
        force = _parse_vector(tip_force, "force", "--tip-force", 3)
        if out.suffix.lower() not in (".png", ".pdf", ".svg"):
            raise design_error("--out", str(out), "must end in .png, .pdf or .svg", InputError)
        if table is not None:
            table = _for_option(check_table_path, table, "--table")
        console = _stdout()
        with Progress(*_progress_columns(), console=console) as progress:
            task = progress.add_task("solves", total=3 * 2 * steps)
            df = compare_pcc(
                d,
                chans,
                pmax,
                steps=steps,
                tip_force=force,
                progress=lambda n: progress.advance(task, n),
            )
        plt = _pyplot()
        fig = plot_pcc_comparison(df, title=f"{d.name}: PCC vs Cosserat rod")
        try:
            with atomic_path(out) as tmp:
                fig.savefig(tmp, format=out.suffix[1:], dpi=150)
        finally:
            plt.close(fig)
        if table is not None:
            write_table(df, table)
        for case, sub in df.groupby("case", sort=False):
            worst = sub["error_mm"].max()
            console.print(f"{case:>20}: largest tip difference {worst:8.3f} mm")
        console.print(f"wrote {out}" + (f" and {table}" if table else ""), soft_wrap=True)

    @main.command("pcc-identify")
    @click.argument("kind", type=click.Choice(KINDS))
    @click.argument("data", type=click.Path(exists=True, dir_okay=False, path_type=Path))
    @click.option("--design", "design", help="Design (for chamber areas, moments, k values).")
    @click.option("--chambers", default=3, show_default=True, help="Chambers pressurised (k_L).")
    @click.option("--k-L", "k_l", help="k_L for longitudinal-damping (default: the design's).")
    @click.option(
        "--k-theta", "k_theta", help="k_theta for bending-damping (default: the design's)."
    )
    @click.option("--degree", default=2, show_default=True, help="k_theta(theta) polynomial.")
    @_handle_errors
    def pcc_identify(kind, data, design, chambers, k_l, k_theta, degree):
        """Identify a PCC parameter from DATA (CSV/Parquet, SI columns) as in paper 003
        Sec. V. Columns: longitudinal-stiffness p_Pa, d_m; bending-stiffness p1_Pa..pN_Pa,
        theta_rad; longitudinal-damping t_s, z_m; bending-damping t_s, theta_rad. Prints the
        value, its standard error and the [pcc] line to put in the design."""
        from .pcc import identify as idf
        from .pcc.model import pcc_parameters

        d = load_design(design) if design else None

        def need_design(what):
            if d is None:
                raise design_error("--design", None, f"is needed for {what}", InputError)
            return d

        if kind == "longitudinal-stiffness":
            cols = _read_columns(data, ["p_Pa", "d_m"])
            sec = next(s for s in need_design("the chamber area").sections() if s["chambers"])
            fit = idf.fit_longitudinal_stiffness(
                cols["p_Pa"], cols["d_m"], area=sec["chambers"][0][0], n_chambers=chambers
            )
        elif kind == "bending-stiffness":
            dd = need_design("the chamber moment")
            names = [f"p{k + 1}_Pa" for k in range(dd.n_channels)]
            cols = _read_columns(data, [*names, "theta_rad"])
            moment = idf.chamber_moment(dd, np.column_stack([cols[n] for n in names]))
            fit = idf.fit_bending_stiffness(cols["theta_rad"], moment, degree=degree)
        elif kind == "longitudinal-damping":
            cols = _read_columns(data, ["t_s", "z_m"])
            k = (
                to_si(k_l, "force_per_length", "--k-L", InputError)
                if k_l
                else pcc_parameters(need_design("k_L"))[0]["k_L"]
            )
            fit = idf.fit_longitudinal_damping(cols["t_s"], cols["z_m"], k_L=k)
        else:
            cols = _read_columns(data, ["t_s", "theta_rad"])
            k = (
                to_si(k_theta, "moment", "--k-theta", InputError)
                if k_theta
                else pcc_parameters(need_design("k_theta"))[0]["k_theta"]
            )
            fit = idf.fit_bending_damping(cols["t_s"], cols["theta_rad"], k_theta=k)
        console = _stdout()
        from .units import SI_UNIT

        for key, val in fit.values.items():
            unit = SI_UNIT[idf._UNITS[key]]
            console.print(f"{key} = {val:.6g} {unit} +- {fit.stderr[key]:.3g} (1 s.e.)")
            console.print(f'[pcc] line: {key} = "{val:.6g} {unit}"', markup=False)
        if fit.table is not None:
            a, k = fit.table
            console.print(
                "[pcc] table: k_theta = { angle = ["
                + ", ".join(f"{x:.4f}" for x in a)
                + "], stiffness = ["
                + ", ".join(f"{x:.5g}" for x in k)
                + "] }",
                markup=False,
            )
        console.print(f"fit residual (RMS): {fit.residual:.3g} {fit.residual_unit}")
