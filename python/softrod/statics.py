"""Static equilibria: ``solve_statics`` and ``solve_statics_batch``.

Model (``Design``), method (solver options) and result (``StaticSolution``) are separate.
All inputs and outputs are SI: pressures in Pa (gauge), one per channel.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .design import Design, load_design
from .errors import ConvergenceError, InputError, design_error
from .stiffness_map import StiffnessMap, _check_pressure_rows
from .units import to_si


@dataclass(frozen=True)
class SolverOptions:
    """Settings of the shooting solver.

    tol: convergence tolerance on the scaled tip-wrench residual (relative, see docs).
    max_iter: Newton iterations per load level.
    continuation: ramp pressures, gravity and loads from zero when Newton fails.
    max_load_steps: most load levels continuation may take.
    """

    tol: float = 1e-10
    max_iter: int = 25
    continuation: bool = True
    max_load_steps: int = 200

    def __post_init__(self):
        if not (isinstance(self.tol, float | int) and 0 < self.tol < 1):
            raise design_error("tol", self.tol, "must be in (0, 1)", InputError)
        for name in ("max_iter", "max_load_steps"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise design_error(name, v, "must be an integer >= 1", InputError)

    def as_kwargs(self) -> dict:
        return {
            "tol": float(self.tol),
            "max_iter": self.max_iter,
            "continuation": self.continuation,
            "max_load_steps": self.max_load_steps,
        }


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

    @classmethod
    def failed(cls, design, pressures, exc, n_unknowns: int, **extra) -> StaticSolution:
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


@dataclass(frozen=True)
class BatchSolution:
    """Results of ``solve_statics_batch``: one row per input row, failed rows kept.

    tip_position (m, 3) m; tip_rotation (m, 3, 3); base_force (m, 3) N; base_moment (m, 3) N m;
    converged (m,) bool (rows that failed hold NaN); iterations (m,); residual (m,).
    stiffness_scale (m, 3): sigma of every row when the design has mapped sections
    (docs/stiffness-map.md), else None. x (m, 3): the solver's scaled unknowns (warm starts).
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


def _pressures(design: Design, pressures) -> list[float]:
    if isinstance(pressures, (int, float, str)):
        pressures = [pressures]
    try:
        values = list(pressures)
    except TypeError:
        raise design_error(
            "pressures", pressures, "must be a sequence of gauge pressures (Pa)", InputError
        ) from None
    if len(values) != design.n_channels:
        raise design_error(
            "pressures",
            values,
            f"the design has {design.n_channels} pressure channels; give one gauge pressure per "
            "channel",
            InputError,
        )
    return [to_si(p, "pressure", f"pressures[{i}]", InputError) for i, p in enumerate(values)]


def _vec3(value, kind: str, name: str, default) -> list[float]:
    if value is None:
        return list(default)
    arr = list(value) if not isinstance(value, str) else value
    if isinstance(arr, str) or len(arr) != 3:
        raise design_error(name, value, f"must be 3 {kind} values (world frame)", InputError)
    return [to_si(x, kind, f"{name}[{i}]", InputError) for i, x in enumerate(arr)]


def _options(options: SolverOptions | None) -> SolverOptions:
    if options is None:
        return SolverOptions()
    if not isinstance(options, SolverOptions):
        raise design_error("options", options, "must be a softrod.SolverOptions", InputError)
    return options


def _mapped_sections(design: Design) -> list[str]:
    return [
        sec["name"]
        for sec in design.spec["sections"]
        if (sec.get("law") or {}).get("stiffness_map", False)
    ]


def _stiffness_map(design: Design, stiffness_map) -> StiffnessMap | None:
    """The map to use, or None for a design without mapped sections."""
    mapped = _mapped_sections(design)
    if stiffness_map is None:
        if mapped:
            raise design_error(
                "stiffness_map",
                None,
                f"section(s) {', '.join(mapped)} of design {design.name!r} set [sections.law] "
                "stiffness_map = true: pass stiffness_map=, a softrod.StiffnessMap (e.g. "
                "StiffnessMap.from_table or from_csv; sigma is never assumed to be 1)",
                InputError,
            )
        return None
    if not isinstance(stiffness_map, StiffnessMap):
        raise design_error(
            "stiffness_map",
            type(stiffness_map).__name__,
            "must be a softrod.StiffnessMap (build one with StiffnessMap.from_table, "
            "from_csv, from_callable or from_regressor)",
            InputError,
        )
    if not mapped:
        raise design_error(
            "stiffness_map",
            stiffness_map,
            f"design {design.name!r} has no section with [sections.law] stiffness_map = true, "
            "so the map would have no effect",
            InputError,
        )
    if stiffness_map.n_channels != design.n_channels:
        raise design_error(
            "stiffness_map",
            stiffness_map,
            f"takes {stiffness_map.n_channels} pressure channel(s), the design has "
            f"{design.n_channels}",
            InputError,
        )
    return stiffness_map


def solve_statics(
    design,
    pressures,
    *,
    tip_force=None,
    tip_moment=None,
    options: SolverOptions | None = None,
    initial: StaticSolution | None = None,
    check: bool = True,
    stiffness_map: StiffnessMap | None = None,
    model: str = "cosserat",
) -> StaticSolution:
    """Static shape of ``design`` under chamber ``pressures`` (Pa gauge, one per channel).

    model: "cosserat" (the rod) or "pcc" (paper 003's piecewise-constant-curvature model,
    docs/pcc.md): the same design and inputs; its shape is the chain of arcs, its ``force``
    and ``moment`` are NaN (the PCC model does not resolve the internal wrench) and
    ``options.max_iter`` bounds its Newton iterations.

    tip_force / tip_moment (N, N m; world frame) replace the design's ``[tip]`` force and
    moment when given; gravity and the tip body always act. ``initial`` warm-starts from a
    previous solution. On non-convergence raises :class:`ConvergenceError`, or with
    ``check=False`` returns a solution with ``converged=False`` and NaN arrays.
    ``stiffness_map`` (a :class:`StiffnessMap`) is required exactly when a section sets
    ``[sections.law] stiffness_map = true``; it is evaluated once at ``pressures``.
    """
    design = load_design(design)
    p = _pressures(design, pressures)
    if model not in ("cosserat", "pcc"):
        raise design_error("model", model, "must be 'cosserat' or 'pcc'", InputError)
    if model == "pcc":
        if stiffness_map is not None:
            raise design_error(
                "stiffness_map", stiffness_map, "is not used by model='pcc'", InputError
            )
        from .pcc.statics import solve_pcc_statics

        return solve_pcc_statics(
            design,
            p,
            tip_force=tip_force,
            tip_moment=tip_moment,
            max_iter=_options(options).max_iter,
            initial=initial,
            check=check,
        )
    smap = _stiffness_map(design, stiffness_map)
    sigma = np.ones(3) if smap is None else smap(np.array([p]))[0]
    tip = design.spec["tip"]
    tf = _vec3(tip_force, "force", "tip_force", tip["force"])
    tm = _vec3(tip_moment, "moment", "tip_moment", tip["moment"])
    guess = None if initial is None else [float(x) for x in initial.shooting_unknowns]
    opts = _options(options)
    try:
        out = design._rod.solve(
            p, tf, tm, guess=guess, stiffness_scale=sigma.tolist(), **opts.as_kwargs()
        )
    except ConvergenceError as exc:
        if check:
            raise
        return StaticSolution.failed(design, p, exc, 3, stiffness_scale=sigma)
    return StaticSolution(
        design=design,
        pressures=np.array(p),
        s=out["s"],
        section=out["section"],
        position=out["position"],
        rotation=out["rotation"],
        force=out["force"],
        moment=out["moment"],
        v=out["v"],
        u=out["u"],
        converged=True,
        iterations=out["iterations"],
        residual=out["residual"],
        load_steps=out["load_steps"],
        shooting_unknowns=np.array(out["x"]),
        stiffness_scale=sigma,
    )


def solve_statics_batch(
    design,
    pressures,
    *,
    tip_force=None,
    tip_moment=None,
    options: SolverOptions | None = None,
    threads: int = 0,
    stiffness_map: StiffnessMap | None = None,
) -> BatchSolution:
    """Solve for every row of an (m, channels) pressure array (Pa) in parallel.

    Runs in Rust on ``threads`` cores (0 = all) with the GIL released; rows in order warm-start
    from their neighbour, so sweeps should be ordered. Rows that fail to converge are kept with
    ``converged = False`` and NaN results. ``stiffness_map`` as in :func:`solve_statics`,
    evaluated in one call for all rows.
    """
    design = load_design(design)
    arr = np.asarray(pressures, dtype=float)
    if arr.ndim == 1 and design.n_channels == 1:
        arr = arr[:, None]
    _check_pressure_rows(
        arr, design.n_channels, f"must be an (m, {design.n_channels}) array of gauge pressures (Pa)"
    )
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 0:
        raise design_error(
            "threads", threads, "must be an integer >= 0 (0 = all cores)", InputError
        )
    smap = _stiffness_map(design, stiffness_map)
    sigma = None if smap is None else np.ascontiguousarray(smap(arr), dtype=float)
    tip = design.spec["tip"]
    tf = _vec3(tip_force, "force", "tip_force", tip["force"])
    tm = _vec3(tip_moment, "moment", "tip_moment", tip["moment"])
    out = design._rod.solve_batch(
        np.ascontiguousarray(arr),
        tf,
        tm,
        threads=threads,
        stiffness_scale=sigma,
        **_options(options).as_kwargs(),
    )
    return BatchSolution(pressures=arr, stiffness_scale=sigma, **out)
