"""Synthetic datasets: the model's equilibria plus measurement noise, marked as synthetic
so they are never mistaken for measurements (docs/datasets.md). Above both the dataset
format (``softrod.datasets``) and the solvers (``softrod.statics``), which know nothing of
each other."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from . import _validate as V
from .catalog import load_design
from .constraints import held_kwargs
from .datasets import (
    _MAX_LISTED,
    Dataset,
    _fail,
    _matrix_to_quat,
    _quat_to_matrix,
    noise_seed,
    parse_marker_sites,
    parse_system_marker_sites,
)
from .design import Design
from .errors import ConvergenceError, InputError
from .statics import _options, batch_pressures, solve_statics_batch
from .units import vector_to_si

if TYPE_CHECKING:
    from ._types import ArrayLike, DesignLike, PathLike
    from .statics import SolverOptions
    from .system import System

__all__ = ["synthesize_dataset", "synthesize_system_dataset"]


def synthesize_dataset(
    design: DesignLike,
    pressures: ArrayLike,
    *,
    noise_mm: float = 0.0,
    seed: int | None = None,
    experiment: ArrayLike | None = None,
    mounting: str | ArrayLike | None = None,
    time: ArrayLike | None = None,
    tip_force: ArrayLike | None = None,
    tip_moment: ArrayLike | None = None,
    options: SolverOptions | None = None,
    threads: int = 0,
    markers: Sequence | None = None,
    tip: bool = True,
    tensions: ArrayLike | None = None,
) -> Dataset:
    """A synthetic dataset: the model's equilibria at ``pressures`` plus measurement noise.

    ``pressures``: (m, channels) gauge pressures in Pa. The tip position gets isotropic
    Gaussian noise of standard deviation ``noise_mm`` (millimetres, per axis, independent);
    orientation and base wrench are the model's, noise-free. ``seed`` makes the noise
    reproducible; without one a seed is drawn and recorded. ``experiment``: one label for
    every row or one per row; ``mounting``: one label (every row is solved with the design
    as mounted, so several labels are refused); ``time``: (m,) seconds. ``tip_force``,
    ``tip_moment``, ``options`` and ``threads`` go to :func:`~softrod.solve_statics_batch`,
    and so do ``tensions`` ((m, tendon channels) in N, each >= 0; None: slack), which the
    dataset records in its ``t0``, ``t1``, ... columns.
    ``markers``: points on the body to record as motion-capture markers, each
    ``(s, offset)``: arc length from the base in [0, L] and offset in the cross-section
    frame (d1, d2[, d3]), or ``s`` alone, SI numbers or strings with units
    (``("55 mm", ["12 mm", "0 mm"])``), checked before any solve;
    their positions get the same noise. ``tip=False`` leaves the tip columns out (markers
    only).

    A design whose ``[tip]`` pins or clamps the tip gives the held equilibria (as
    :func:`~softrod.solve_statics_batch` solves them with that constraint): the markers are
    read on the held rod, and the tip columns then hold the prescribed tip position (to the
    solver's tolerance, plus the noise), which no parameter moves, so a fit of such a
    dataset needs ``markers`` to see anything (:func:`~softrod.calibrate` refuses a held
    tip's dataset without markers, naming ``dataset.markers``). The metadata records the
    constraint (``tip_constraint``).

    Raises :class:`~softrod.errors.ConvergenceError` listing the rows that did not converge
    (nothing is dropped silently). ``metadata["synthetic"]`` is True and the metadata records
    the design, noise, seed and loads, so the data is never mistaken for measurements.
    """
    from . import __version__

    design = load_design(design)
    held = design.tip_constraint
    seed = noise_seed(noise_mm, seed)
    p = batch_pressures(design, pressures)
    sites = parse_marker_sites(markers, design.length)  # checked before any solve
    rough = design.frictional_obstacle
    if sites is not None and rough is not None:
        # Refused before the (frictional) batch runs: the markers are read off the
        # sensitivity solve, which has no load path (docs/contact.md).
        raise _fail(
            f"obstacles[{rough}].friction",
            design.spec["obstacles"][rough]["friction"],
            "markers are read off the parameter-sensitivity solve, which is frictionless "
            "(a frictional equilibrium depends on its load path): synthesize the tip only, "
            "or set friction = 0",
        )
    labels = None if mounting is None else np.unique(np.asarray(mounting)).tolist()
    if labels is not None and len(labels) > 1:
        # Every row is solved with the design as mounted, while a fit solves the rows of
        # several labels each in its orientation: such rows would contradict their label.
        raise _fail(
            "mounting",
            labels,
            "every row is solved with the design as mounted: synthesize each mounting with "
            "the design mounted that way (design.replace({'mounting.orientation': ...})) "
            "and join the rows",
        )
    batch = solve_statics_batch(
        design,
        p,
        tip_force=tip_force,
        tip_moment=tip_moment,
        options=options,
        threads=threads,
        tensions=tensions,
    )
    p = batch.pressures
    m = p.shape[0]
    failed = np.flatnonzero(~np.asarray(batch.converged, dtype=bool))
    if failed.size:
        shown = "; ".join(
            f"row {i}: p = ({', '.join(f'{x / 1e3:g}' for x in p[i])}) kPa"
            for i in failed[:_MAX_LISTED]
        )
        more = f" and {failed.size - _MAX_LISTED} more" if failed.size > _MAX_LISTED else ""
        raise ConvergenceError(
            f"synthesize_dataset: {failed.size} of {m} rows did not converge ({shown}{more}); "
            "remove them from pressures or change the solver options"
        )
    rng = np.random.default_rng(int(seed))
    noise = rng.normal(0.0, noise_mm * 1e-3, size=(m, 3)) if noise_mm > 0 else np.zeros((m, 3))
    marker_pos = None
    if sites is not None:
        smap = design.stiffness_map
        out = design._rod.sensitivity_batch(
            p,
            _tip_load(design, tip_force, "force"),
            _tip_load(design, tip_moment, "moment"),
            [],
            stiffness_scale=None if smap is None else np.ascontiguousarray(smap(p)),
            markers=[(float(a), [float(v) for v in b]) for a, b in zip(*sites, strict=True)],
            threads=threads,
            tensions=batch.tensions,
            **_options(options).as_kwargs(),
            **held_kwargs(held),
        )
        marker_pos = out["marker_position"]
        if noise_mm > 0:
            marker_pos = marker_pos + rng.normal(0.0, noise_mm * 1e-3, size=marker_pos.shape)
    if not tip and sites is None:
        raise _fail("tip", tip, "a dataset without tip columns needs markers")

    def per_row(value, name):
        if value is None:
            return None
        if isinstance(value, (str, int, np.integer)) and not isinstance(value, bool):
            return np.full(m, value)
        a = np.asarray(value)
        if a.shape != (m,):
            raise _fail(name, f"shape {a.shape}", f"must be one label or one per row ({m},)")
        return a

    tf = _tip_load(design, tip_force, "force")
    tm = _tip_load(design, tip_moment, "moment")
    meta = {
        "synthetic": True,
        "note": "SYNTHETIC: generated by the softrod model, not measurements",
        "generator": "softrod.synthesize_dataset",
        "softrod_version": __version__,
        "design": design.name,
        "design_source": None if design.source is None else design.source.name,
        "noise_mm": float(noise_mm),
        "noise": "isotropic Gaussian on tip_position and markers (per axis, independent); "
        "tip_rotation and base wrench are noise-free",
        "seed": int(seed),
        "tip_force_N": tf,
        "tip_moment_Nm": tm,
    }
    if held is not None:
        meta["tip_constraint"] = {"type": held.kind, "position_m": list(held.position)}
        if held.rotation is not None:
            meta["tip_constraint"]["rotation"] = [list(r) for r in held.rotation]
    return Dataset(
        pressures=p,
        tensions=batch.tensions,
        tip_position=batch.tip_position + noise if tip else None,
        markers=marker_pos,
        marker_s=None if sites is None else sites[0],
        marker_offset=None if sites is None else sites[1],
        # Through the quaternion once, so the stored rotation is exactly what a file holds.
        tip_rotation=_quat_to_matrix(_matrix_to_quat(batch.tip_rotation)),
        base_force=batch.base_force,
        base_moment=batch.base_moment,
        experiment=per_row(experiment, "experiment"),
        mounting=per_row(mounting, "mounting"),
        time=None if time is None else V.real_array(time, "time", what="times (s)"),
        metadata=meta,
        source=None,
    )


def _tip_load(design: Design, value, kind: str) -> list[float]:
    """The tip load the solve used (SI): ``value`` or, if None, the design's ``[tip]`` entry."""
    if value is None:
        return [float(x) for x in design.spec["tip"][kind]]
    return vector_to_si(list(value), kind, f"tip_{kind}", InputError)


def synthesize_system_dataset(
    system: System | str | PathLike,
    pressures: ArrayLike | None = None,
    *,
    tensions: ArrayLike | None = None,
    markers: Sequence | None = None,
    noise_mm: float = 0.0,
    seed: int | None = None,
    experiment: ArrayLike | None = None,
    options: SolverOptions | None = None,
    threads: int = 0,
    tip: bool = True,
) -> Dataset:
    """A synthetic dataset of a :class:`~softrod.System`: its equilibria plus measurement
    noise, for :func:`~softrod.calibrate_system`.

    ``pressures`` and ``tensions``: the rows as :func:`~softrod.solve_system_batch` takes
    them (one list per rod per row); the dataset's p columns are rod 0's channels, then
    rod 1's, ... (t columns likewise). The tip columns hold the platform origin's position
    (``tip=False`` leaves them out). ``markers``: points to record, each
    ``("platform", offset)`` (platform frame) or ``("rod<i>", s, offset)`` (on rod i),
    SI numbers or strings with units, checked before any solve. Positions get isotropic
    Gaussian noise of ``noise_mm`` (per axis); ``seed`` makes it reproducible (drawn and
    recorded when None). Frictional systems are refused (their equilibria depend on the
    load path). Raises :class:`~softrod.errors.ConvergenceError` listing rows that did not
    converge. ``metadata["synthetic"]`` is True and records the system, noise and seed. A
    stiffness-mapped rod's sigma comes from its design's map (``[stiffness_map] file``),
    for every row as :func:`~softrod.solve_system_batch` evaluates it.
    """
    from . import __version__, _core
    from .system import (
        System,
        _batch_entries,
        _platform_args,
        _system_rows,
        check_rods,
        load_system,
        rod_blocks,
        system_sigma,
    )

    if not isinstance(system, System):
        system = load_system(system)
    seed = noise_seed(noise_mm, seed)
    V.boolean(tip, "tip")
    lengths = [rod.design.length for rod in system.rods]
    sites = parse_system_marker_sites(markers, lengths)
    if not tip and sites is None:
        raise _fail("tip", False, "leaves nothing to record: give markers or keep the tip")
    for i, rod in enumerate(system.rods):
        rough = rod.design.frictional_obstacle
        if rough is not None:
            raise _fail(
                f"system.rods[{i}].design.obstacles[{rough}].friction",
                rod.design.spec["obstacles"][rough]["friction"],
                "a frictional system's equilibria depend on their load path: synthesize "
                "with frictionless obstacles",
            )
    # Each stiffness-mapped rod's design map (sigma never assumed to be 1).
    maps = check_rods(system)
    nc = [rod.design.n_channels for rod in system.rods]
    nt = [rod.design.n_tendons for rod in system.rods]
    if pressures is None and tensions is None:
        raise _fail("pressures", None, "give the rows: pressures (or tensions) of every rod")
    ps = None if pressures is None else _system_rows(system, pressures, "pressures", "pressure", nc)
    ts = None if tensions is None else _system_rows(system, tensions, "tensions", "force", nt)
    m = len(ps[0]) if ps is not None else len(ts[0])
    if ts is not None and len(ts[0]) != m:
        raise _fail("tensions", f"{len(ts[0])} rows", f"must have as many rows as pressures ({m})")
    flat_p = np.concatenate(ps, axis=1) if ps is not None and sum(nc) else np.zeros((m, sum(nc)))
    flat_t = None if ts is None or not sum(nt) else np.concatenate(ts, axis=1)
    if flat_t is not None and not (flat_t >= 0).all():
        r, k = (int(v) for v in np.argwhere(~(flat_t >= 0))[0])
        raise _fail(f"tensions[{r}]", float(flat_t[r, k]), "a tendon tension must be >= 0")
    if (flat_p < V.VACUUM_PA).any():
        r, k = (int(v) for v in np.argwhere(flat_p < V.VACUUM_PA)[0])
        raise _fail(
            f"pressures[{r}]", float(flat_p[r, k]), f"gauge pressures must be >= {V.VACUUM_PA:g} Pa"
        )
    sigma = system_sigma(maps, rod_blocks(np.asarray(flat_p, dtype=float), nc))
    core_markers = (
        []
        if sites is None
        else [
            (None if int(b) < 0 else int(b), float(s), [float(v) for v in o])
            for s, o, b in zip(*sites, strict=True)
        ]
    )
    out = _core.rod_system_sensitivity_batch(
        _batch_entries(system),
        _platform_args(system, None, None),
        np.ascontiguousarray(flat_p, dtype=float),
        [],
        tensions=None if flat_t is None else np.ascontiguousarray(flat_t, dtype=float),
        markers=core_markers,
        threads=V.threads(threads),
        stiffness_scale=sigma,
        **_options(options).as_kwargs(),
    )
    failed = np.flatnonzero(~np.asarray(out["converged"], dtype=bool))
    if failed.size:
        rows = ", ".join(str(int(i)) for i in failed[:_MAX_LISTED])
        more = f" and {failed.size - _MAX_LISTED} more" if failed.size > _MAX_LISTED else ""
        raise ConvergenceError(
            f"synthesize_system_dataset: {failed.size} of {m} rows did not converge (rows "
            f"{rows}{more}); nothing is dropped silently: remove them or change the inputs"
        )
    rng = np.random.default_rng(int(seed))
    sd = noise_mm * 1e-3

    def noisy(x):
        return x + rng.normal(0.0, sd, size=x.shape) if noise_mm > 0 else x

    platform = noisy(np.asarray(out["platform_position"]))
    marker_pos = None if sites is None else noisy(np.asarray(out["marker_position"]))
    meta = {
        "synthetic": True,
        "system": system.name,
        "rods": [rod.design.name for rod in system.rods],
        "softrod_version": __version__,
        "noise_mm": float(noise_mm),
        "noise": "isotropic Gaussian on the platform position and markers (per axis, independent)",
        "seed": int(seed),
        "tip": "the platform origin's position",
    }
    if sigma is not None:
        meta["stiffness_maps"] = [None if smap is None else repr(smap) for smap in maps]
    exp = None
    if experiment is not None:
        exp = np.asarray(experiment)
        if exp.ndim == 0:
            exp = np.full(m, exp.item())
    return Dataset(
        pressures=flat_p,
        tensions=flat_t,
        tip_position=platform if tip else None,
        experiment=exp,
        metadata=meta,
        markers=marker_pos,
        marker_s=None if sites is None else sites[0],
        marker_offset=None if sites is None else sites[1],
        marker_body=None if sites is None else sites[2],
    )
