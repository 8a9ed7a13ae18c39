"""How the bundled example datasets were made (synthetic, seeded), and their regeneration:
``python -c "from softrod._examples import write_examples; write_examples()"``. Tests check
that the recipes still reproduce the bundled files."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .calibration.axial import _write_axial_examples
from .calibration.params import design_changes, parse_parameters
from .catalog import load_design
from .datasets import _EXAMPLES_DIR, Dataset, write_dataset
from .synthetic import synthesize_dataset

# How the bundled example was made; write_examples() rebuilds it (tests check it still does).
SPA130_EXAMPLE = {
    "design": "spa_three_chamber_130mm",
    "grid_kPa": [0.0, 14.0, 28.0, 42.0, 56.0, 70.0],  # 6 x 6 x 6 = 216 rows
    "noise_mm": 0.3,
    "seed": 130,
    "experiments": [1, 2, 3],
    "mounting": "hanging",
    "seconds_per_sample": 5.0,
}


def _spa130_example() -> Dataset:
    """216 grid points, shuffled (seeded) into three experiments of 72 rows each."""
    spec = SPA130_EXAMPLE
    grid = np.asarray(spec["grid_kPa"]) * 1e3
    p = np.array(np.meshgrid(grid, grid, grid, indexing="ij")).reshape(3, -1).T
    n_exp = len(spec["experiments"])
    order = np.random.default_rng(spec["seed"]).permutation(len(p))
    exp_index = np.empty(len(p), dtype=int)
    exp_index[order] = np.arange(len(p)) % n_exp
    rows = np.lexsort((np.arange(len(p)), exp_index))  # by experiment, grid order within
    p, exp_index = p[rows], exp_index[rows]
    within = np.concatenate([np.arange(np.sum(exp_index == k)) for k in range(n_exp)])
    return synthesize_dataset(
        spec["design"],
        p,
        noise_mm=spec["noise_mm"],
        seed=spec["seed"],
        experiment=np.asarray(spec["experiments"])[exp_index],
        mounting=spec["mounting"],
        time=within * spec["seconds_per_sample"],
    )


# The calibration tutorial's example (docs/calibration.md): paper 002's protocol on its model M3
# with parameters that differ from Table IV, so that a fit from Table IV has work to do.
PAPER002_EXAMPLE = {
    "design": "paper002_M3_vertical",
    "truth": {"c_b": 1.45, "c_e": 2.6, "alpha": 7.0, "offset_1": 0.5e-3, "offset_2": 1.2e-3},
    "ramp_kPa": 60.0,  # each experiment ramps to 60 kPa in 60 equilibria
    "patterns": [[1, 0, 0], [0, 1, 0], [0, 0, 1], [0.6, 0.4, 0]],  # experiments 1-4
    "noise_mm": 0.2,
    "seed": 2,
    "mounting": "hanging",
}


def _paper002_example() -> Dataset:
    """4 experiments x 60 equilibria of paper002_M3_vertical with the ``truth`` parameters."""
    spec = PAPER002_EXAMPLE
    base = load_design(spec["design"])
    names, values = list(spec["truth"]), list(spec["truth"].values())
    made = base.replace(design_changes(parse_parameters(names, base), values, base))
    ramp = spec["ramp_kPa"] * 1e3 * np.arange(1, 61) / 60
    p = np.vstack([np.outer(ramp, q) for q in spec["patterns"]])
    n = len(spec["patterns"])
    ds = synthesize_dataset(
        made,
        p,
        noise_mm=spec["noise_mm"],
        seed=spec["seed"],
        experiment=np.repeat(np.arange(1, n + 1), 60),
        mounting=spec["mounting"],
    )
    truth = ", ".join(f"{k} = {v:g}" for k, v in spec["truth"].items())
    meta = {
        **ds.metadata,
        "design": f"{spec['design']} with {truth}",
        "true_parameters": spec["truth"],
    }
    return Dataset(**{**ds.__dict__, "metadata": meta})


def write_examples(folder: str | os.PathLike | None = None) -> list[Path]:
    """Regenerate the bundled examples: ``python -c "from softrod._examples import
    write_examples; write_examples()"``."""
    folder = Path(folder) if folder is not None else _EXAMPLES_DIR
    ds = _spa130_example()
    return [
        write_dataset(ds, folder / "spa130_synthetic.csv"),
        write_dataset(_paper002_example(), folder / "paper002_m3_synthetic.csv"),
        *_write_axial_examples(folder / "axial"),
    ]
