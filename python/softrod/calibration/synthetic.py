"""Synthetic time-series datasets: the model's own tip trajectories plus noise, the data of
dynamic round trips (paper 000 Sec. III-D recorded its arm at 50 Hz)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..catalog import load_design
from ..datasets import Dataset
from ..dynamics import PressureSchedule, simulate

__all__ = ["synthesize_trajectory_dataset"]

_MM = 1e-3


def synthesize_trajectory_dataset(
    design,
    schedule: PressureSchedule,
    t_end: float,
    *,
    rate: float = 50.0,
    noise_mm: float = 0.0,
    seed: int | None = None,
    dt=2e-3,
) -> Dataset:
    """A time-series dataset made by the model: ``schedule`` sampled at ``rate`` Hz (paper
    000 recorded at 50 Hz), the model driven by those samples joined linearly (as
    ``softrod.calibrate(..., dynamic=True)`` replays them), and its tip at the samples with
    Gaussian noise of ``noise_mm`` per coordinate. Marked synthetic in its metadata, with
    the seed."""
    d = load_design(design)
    rng = np.random.default_rng(seed)
    seed_used = seed
    times = np.arange(0.0, t_end + 0.5 / rate, 1.0 / rate)
    # The model is driven by the sampled pressures joined linearly, as a fit replays them.
    sampled = PressureSchedule.piecewise_linear(times, schedule.sample(times))
    tr = simulate(d, sampled, times[-1], dt=dt, energy=False)
    tip = tr.tip_position_at(times) + rng.normal(0.0, noise_mm * _MM, (len(times), 3))
    meta: Mapping = {
        "synthetic": True,
        "source": f"softrod.simulate of {d.name}, {rate:g} Hz, noise {noise_mm:g} mm",
        "seed": seed_used,
    }
    return Dataset(
        pressures=sampled.pressures,
        tip_position=tip,
        time=times,
        experiment=np.zeros(len(times), dtype=np.int64),
        metadata=dict(meta),
    )
