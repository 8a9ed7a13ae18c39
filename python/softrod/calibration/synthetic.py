"""Synthetic time-series datasets: the model's own tip trajectories plus noise, the data of
dynamic round trips (paper 000 Sec. III-D recorded its arm at 50 Hz)."""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np
from numpy.typing import ArrayLike

from .. import _validate as V
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
    tensions: Callable[[float], ArrayLike] | None = None,
) -> Dataset:
    """A time-series dataset made by the model: ``schedule`` sampled at ``rate`` Hz (paper
    000 recorded at 50 Hz), the model driven by those samples joined linearly (as
    ``softrod.calibrate(..., dynamic=True)`` replays them), and its tip at the samples with
    Gaussian noise of ``noise_mm`` per coordinate. ``tensions``: None (slack tendons) or a
    function of t (s) returning the tendon tensions (N, one per tendon channel): sampled
    at ``rate`` Hz into the dataset's tension columns and, joined linearly, driving the
    model as the replay does. Marked synthetic in its metadata, with the seed."""
    d = load_design(design)
    rng = np.random.default_rng(seed)
    seed_used = seed
    times = np.arange(0.0, t_end + 0.5 / rate, 1.0 / rate)
    # The model is driven by the sampled pressures joined linearly, as a fit replays them.
    sampled = PressureSchedule.piecewise_linear(times, schedule.sample(times))
    knots = None
    if tensions is not None:
        if not callable(tensions):
            raise V.fail("tensions", type(tensions).__name__, "must be a function of t (s)")
        knots = np.array([_tension_row(d, tensions, t) for t in times], dtype=float)
        knots = knots.reshape(len(times), d.n_tendons)
    joined = None if knots is None else _joined(times, knots)
    tr = simulate(d, sampled, times[-1], dt=dt, energy=False, tensions=joined)
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
        tensions=knots,
        metadata=dict(meta),
    )


def _tension_row(design, tensions, t: float) -> np.ndarray:
    """The tensions (N) of the function ``tensions`` at t, checked (one per channel)."""
    from ..dynamics.simulate import _tension_rows

    return _tension_rows(design, tensions, np.array([t]))[0]


def _joined(times: np.ndarray, knots: np.ndarray):
    """The tension samples joined linearly: a function of t (s)."""
    return lambda t: np.array([np.interp(t, times, k) for k in knots.T])
