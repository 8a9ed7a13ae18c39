"""Synthetic time-series datasets: the model's own tip (and marker) trajectories plus noise,
the data of dynamic round trips (paper 000 Sec. III-D recorded its arm at 50 Hz)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from .. import _validate as V
from ..catalog import load_design
from ..datasets import Dataset, parse_marker_sites
from ..dynamics import PressureSchedule, simulate
from ..dynamics.simulate import _seconds, tracked_trajectory
from .adapters.rod_dynamic import sample_run, step_tensions

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
    markers: Sequence | None = None,
    tip: bool = True,
) -> Dataset:
    """A time-series dataset made by the model: ``schedule`` sampled at ``rate`` Hz (paper
    000 recorded at 50 Hz), the model driven by those samples joined linearly (as
    ``softrod.calibrate(..., dynamic=True)`` replays them), and its tip at the samples with
    Gaussian noise of ``noise_mm`` per coordinate. ``tensions``: None (slack tendons) or a
    function of t (s) returning the tendon tensions (N, one per tendon channel): sampled
    at ``rate`` Hz into the dataset's tension columns and, joined linearly, driving the
    model as the replay does. ``markers``: points on the body recorded as motion-capture
    markers, as :func:`~softrod.synthesize_dataset` takes them (``(s, offset)`` pairs or ``s``
    alone, SI or strings with units), with the same noise; ``tip=False`` leaves the tip columns out
    (markers only). A design whose ``[tip]`` pins or clamps the tip moves held (its tip
    columns hold the prescribed position plus the noise: a fit reads its markers). Marked
    synthetic in its metadata, with the seed."""
    d = load_design(design)
    sites = parse_marker_sites(markers, d.length)
    if not tip and sites is None:
        raise V.fail("tip", tip, "a dataset without tip columns needs markers")
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
    marker_pos = None
    if sites is None:
        joined = None if knots is None else _joined(times, knots)
        tr = simulate(d, sampled, times[-1], dt=dt, energy=False, tensions=joined)
        tip_pos = tr.tip_position_at(times)
    else:
        # The replay of a fit with markers (RodDynamic): the same run, read the same way.
        step = _seconds(dt, "dt")
        rows = None if knots is None else step_tensions(times, knots, step)
        pairs = [(float(s), [float(v) for v in o]) for s, o in zip(*sites, strict=True)]
        run = tracked_trajectory(d, sampled, times[-1], step, [], rows, pairs)
        tip_pos = sample_run(run, "tip_position", times)
        marker_pos = sample_run(run, "marker_position", times)
        marker_pos = marker_pos + rng.normal(0.0, noise_mm * _MM, marker_pos.shape)
    tip_pos = tip_pos + rng.normal(0.0, noise_mm * _MM, (len(times), 3))
    meta: Mapping = {
        "synthetic": True,
        "source": f"softrod.simulate of {d.name}, {rate:g} Hz, noise {noise_mm:g} mm",
        "seed": seed_used,
    }
    return Dataset(
        pressures=sampled.pressures,
        tip_position=tip_pos if tip else None,
        markers=marker_pos,
        marker_s=None if sites is None else sites[0],
        marker_offset=None if sites is None else sites[1],
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
