"""Results of static solves: ``StaticSolution`` (one equilibrium, any model) and
``BatchSolution`` (many). Kept apart from the solvers so that every model's solver (the rod's,
the PCC model's) returns the same types without importing each other."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .design import Design

if TYPE_CHECKING:
    from collections.abc import Sequence

    import pandas as pd

    from ._types import ArrayLike, Units
    from .control.linear import Jacobian


@dataclass(frozen=True)
class StaticSolution:
    """A static equilibrium, sampled at every integration node (n nodes).

    s: (n,) reference arc length, m.            section: (n,) section index of each node.
    position: (n, 3) centreline r, m (world).   rotation: (n, 3, 3) [d1 d2 d3] (world).
    force: (n, 3) total internal force n, N.    moment: (n, 3) total internal moment m, N m.
    v: (n, 3) shear/stretch strain (body).      u: (n, 3) curvature/twist, 1/m (body).
    Forces and moments are the totals of the balance laws (material plus pressure part).
    stiffness_scale: (3,) sigma = (sigma_ext, sigma_bend_x, sigma_bend_y) applied to the
    mapped sections (docs/stiffness-map.md); ones when the design has none.
    stable: the equilibrium is stable (docs/model.md, "Validity and stability"); None where
    the model does not assess it (the PCC model) or the solve failed.
    violations: the validity ranges the solution lies outside (only with
    ``on_invalid="warn"``; otherwise such a solution is refused).
    """

    design: Design
    pressures: np.ndarray
    s: np.ndarray
    section: np.ndarray
    position: np.ndarray
    rotation: np.ndarray
    force: np.ndarray
    moment: np.ndarray
    v: np.ndarray
    u: np.ndarray
    converged: bool
    iterations: int
    residual: float
    load_steps: int
    shooting_unknowns: np.ndarray = field(repr=False)
    stiffness_scale: np.ndarray = field(default_factory=lambda: np.ones(3))
    stable: bool | None = None
    violations: tuple[str, ...] = ()
    #: (tip force, tip moment) the equilibrium was solved under (world frame, N and N m).
    tip_loads: tuple | None = field(default=None, repr=False)

    @classmethod
    def failed(
        cls,
        design: Design,
        pressures: ArrayLike,
        exc: Exception,
        n_unknowns: int,
        **extra: Any,
    ) -> StaticSolution:
        """The result of a solve that did not converge (``check=False``): NaN shape and
        wrench, ``converged`` False, the iterations and residual of ``exc``."""
        nan3 = np.full((1, 3), np.nan)
        return cls(
            design=design,
            pressures=np.array(pressures),
            s=np.array([np.nan]),
            section=np.array([-1]),
            position=nan3,
            rotation=np.full((1, 3, 3), np.nan),
            force=nan3,
            moment=nan3,
            v=nan3,
            u=nan3,
            converged=False,
            iterations=exc.iterations,
            residual=exc.residual,
            load_steps=0,
            shooting_unknowns=np.full(n_unknowns, np.nan),
            **extra,
        )

    @property
    def tip_position(self) -> np.ndarray:
        """Tip position (end of the last section), m."""
        return self.position[-1]

    @property
    def tip_rotation(self) -> np.ndarray:
        """Tip rotation [d1 d2 d3], world frame."""
        return self.rotation[-1]

    @property
    def base_force(self) -> np.ndarray:
        """Total internal force at the base (the wrench the mount takes), N."""
        return self.force[0]

    @property
    def base_moment(self) -> np.ndarray:
        return self.moment[0]

    @property
    def strains(self) -> dict[str, np.ndarray]:
        return {"v": self.v, "u": self.u}

    def jacobian(
        self, *, params: Sequence[str] = (), point: float | str | None = None
    ) -> Jacobian:
        """The exact Jacobian of the tip pose (or the pose at arc length ``point``) with
        respect to the pressures, the tip force and moment, and named calibration
        parameters (tip only): a :class:`softrod.control.Jacobian` (docs/control.md)."""
        from .control.linear import jacobian

        return jacobian(self, params=params, point=point)


@dataclass(frozen=True)
class BatchSolution:
    """Results of ``solve_statics_batch``: one row per input row, failed rows kept.

    tip_position (m, 3) m; tip_rotation (m, 3, 3); base_force (m, 3) N; base_moment (m, 3) N m;
    converged (m,) bool (rows that failed hold NaN); iterations (m,); residual (m,).
    stiffness_scale (m, 3): sigma of every row when the design has mapped sections
    (docs/stiffness-map.md), else None. x (m, 3): the solver's scaled unknowns (warm starts).
    stable (m,) bool: the row's equilibrium is stable (False on failed rows). violation (m,)
    str: the validity rule a row broke ("" if none; docs/model.md, "Validity and stability").
    metadata: design, softrod version and solver settings (the metadata block of
    :meth:`to_frame`).
    """

    pressures: np.ndarray
    tip_position: np.ndarray
    tip_rotation: np.ndarray
    base_force: np.ndarray
    base_moment: np.ndarray
    converged: np.ndarray
    iterations: np.ndarray
    residual: np.ndarray
    stiffness_scale: np.ndarray | None = None
    x: np.ndarray | None = None
    stable: np.ndarray | None = None
    violation: np.ndarray | None = None
    metadata: dict = field(default_factory=dict, compare=False)

    def __len__(self) -> int:
        return self.pressures.shape[0]

    def to_frame(self, units: Units = None) -> pd.DataFrame:
        """The results as a DataFrame in the dataset schema (docs/datasets.md), one row per
        solve: ``p0_kPa`` ..., ``tip_x_mm`` ..., ``tip_qw`` ... ``tip_qz``, ``base_fx_N`` ...,
        ``base_mx_Nmm`` ..., then the result columns ``converged``, ``iterations``,
        ``residual`` and, with a stiffness map, ``sigma_ext``, ``sigma_bend_x``,
        ``sigma_bend_y``. Rows that did not converge keep NaN (empty cells in a file).
        ``units`` as in :meth:`softrod.Dataset.to_frame`. The metadata block
        (``frame.attrs["softrod.metadata"]``) is :attr:`metadata`: design, softrod version,
        solver settings. The same quantities get the same names as in
        :meth:`softrod.Trajectory.to_frame`; ``load_dataset(frame)`` reads it back.
        """
        from .schema import Extra, schema_frame

        extras = [
            Extra("converged", np.asarray(self.converged, dtype=bool), "the solve converged"),
            Extra("iterations", np.asarray(self.iterations), "Newton iterations"),
            Extra("residual", np.asarray(self.residual, dtype=float), "scaled final residual"),
        ]
        if self.stable is not None:
            extras.append(
                Extra("stable", np.asarray(self.stable, dtype=bool), "the equilibrium is stable")
            )
        if self.stiffness_scale is not None:
            from .stiffness_map import SIGMA_NAMES

            extras += [
                Extra(name, self.stiffness_scale[:, k], f"stiffness factor {name} (paper 001)")
                for k, name in enumerate(SIGMA_NAMES)
            ]
        return schema_frame(
            pressures=self.pressures,
            tip_position=self.tip_position,
            tip_rotation=self.tip_rotation,
            base_force=self.base_force,
            base_moment=self.base_moment,
            extras=extras,
            units=units,
            metadata=self.metadata,
        )
