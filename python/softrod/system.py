"""Several rods whose tips hold one rigid platform: parallel continuum robots
(docs/model.md, "Systems of rods"; Black, Till & Rucker, IEEE T-RO 2018,
doi 10.1109/TRO.2017.2753829).

A system file (TOML) names its rods' designs and where they hold the platform::

    [system]
    name = "two_spa_platform"
    citation = "..."

    [platform]
    position = ["0 mm", "0 mm", "-130 mm"]   # nominal pose, world frame
    orientation = ["0 deg", "0 deg", "0 deg"] # rotation vector or 3x3 matrix (optional)
    mass = "20 g"                             # optional
    com_offset = ["0 mm", "0 mm", "0 mm"]     # platform frame (optional)
    inertia = ["2e-6 kg*m^2", "2e-6 kg*m^2", "4e-6 kg*m^2"]  # about the centre of mass,
                                              # platform frame: principal values or 3x3
                                              # (optional, dynamics only)
    force = ["0 N", "0 N", "0 N"]             # external load, world frame (optional)
    moment = ["0 N*m", "0 N*m", "0 N*m"]      # about the platform origin (optional)

    [[rods]]
    design = "spa_three_chamber_130mm"        # a file (relative to this one) or bundled
    base_position = ["-30 mm", "0 mm", "0 mm"] # replaces the design's mounting position
    attachment = ["-30 mm", "0 mm", "0 mm"]    # tip position in the platform frame
    attachment_orientation = ["0 deg", "0 deg", "0 deg"]  # tip frame in the platform
                                               # frame (optional, default: aligned)
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from . import _core
from . import _validate as V
from .catalog import load_design
from .constraints import orientation as _orientation
from .design import Design, read_toml
from .errors import ConvergenceError, DesignError, InputError
from .io import as_path
from .io import exists as _exists
from .io import is_file as _is_file
from .solution import Contact, StaticSolution, SystemJacobian, _mm
from .statics import (
    _UNIT_SCALE,
    SolverOptions,
    _options,
    _policy,
    _pressures,
    _report_stability,
    _sigma_rows,
    _stiffness_map,
    _tensions,
)
from .stiffness_map import SIGMA_NAMES, StiffnessMap

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.figure import Figure

    from ._types import Units
    from .control.linear import SystemLinearSystem

_SCHEMA = {
    "": {"units", "system", "platform", "rods"},
    "system": {"name", "citation", "description"},
    "platform": {"position", "orientation", "mass", "com_offset", "inertia", "force", "moment"},
    "rod": {"design", "base_position", "attachment", "attachment_orientation"},
}


def _keys(table: Any, kind: str, where: str) -> dict:
    if not isinstance(table, dict):
        raise V.fail(where, table, "must be a table", DesignError)
    unknown = sorted(set(table) - _SCHEMA[kind])
    if unknown:
        raise V.fail(
            f"{where}.{unknown[0]}" if where else unknown[0],
            table[unknown[0]],
            f"unknown key; known: {', '.join(sorted(_SCHEMA[kind]))}",
            DesignError,
        )
    return table


def _vec(value: Any, kind: str, field: str, default=(0.0, 0.0, 0.0)) -> np.ndarray:
    if value is None:
        return np.array(default, dtype=float)
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise V.fail(field, value, f"must be 3 {kind} values", DesignError)
    return np.array(
        [V.quantity(v, kind, f"{field}[{i}]", DesignError) for i, v in enumerate(value)]
    )


def _read_only(obj: Any, names: tuple[str, ...]) -> None:
    """Replace the array fields ``names`` of the frozen dataclass ``obj`` by read-only float
    copies, so that neither the caller's array nor ``obj.field[...] = x`` can change the
    model after it is built. A value that is not numeric is left as given: the solve's
    checks name it."""
    for name in names:
        value = getattr(obj, name)
        try:
            frozen = np.array(value, dtype=float)
        except (TypeError, ValueError, OverflowError):
            continue
        frozen.flags.writeable = False
        object.__setattr__(obj, name, frozen)


@dataclass(frozen=True)
class SystemRod:
    """One rod of a system: its design (with its own mounting: the base pose) and where its
    tip holds the platform: ``attachment`` (m) and ``attachment_rotation`` (its tip frame),
    both in the platform frame."""

    design: Design
    attachment: np.ndarray
    attachment_rotation: np.ndarray = field(default_factory=lambda: np.eye(3))

    def __post_init__(self) -> None:
        _read_only(self, ("attachment", "attachment_rotation"))


@dataclass(frozen=True)
class Platform:
    """The rigid platform (SI): nominal pose (world; continuation starts there), external
    force (world) and moment (about its origin, world), mass and centre of mass (platform
    frame), and the inertia tensor about the centre of mass (platform frame, kg m^2; only
    the dynamics reads it; zero: a point mass)."""

    position: np.ndarray
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    force: np.ndarray = field(default_factory=lambda: np.zeros(3))
    moment: np.ndarray = field(default_factory=lambda: np.zeros(3))
    mass: float = 0.0
    com_offset: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))

    def __post_init__(self) -> None:
        _read_only(self, ("position", "rotation", "force", "moment", "com_offset", "inertia"))


def platform_inertia(value: Any, field: str, cls: type[DesignError] = DesignError) -> np.ndarray:
    """A platform's inertia tensor about its centre of mass (kg m^2, platform frame) from
    three principal values or a 3x3 tensor (numbers in SI or strings with units); it must be
    symmetric and positive semi-definite (a rigid body's)."""
    if value is None:
        return np.zeros((3, 3))
    if isinstance(value, np.ndarray):
        value = value.tolist()
    rows = (
        isinstance(value, (list, tuple))
        and len(value) == 3
        and all(isinstance(r, (list, tuple)) for r in value)
    )
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise V.fail(field, value, "must be 3 principal values or a 3x3 tensor (kg m^2)", cls)
    if rows:
        for i, row in enumerate(value):
            if len(row) != 3:
                raise V.fail(f"{field}[{i}]", row, "must be 3 values (kg m^2)", cls)
        j = np.array(
            [
                [V.quantity(v, "inertia", f"{field}[{i}][{k}]", cls) for k, v in enumerate(row)]
                for i, row in enumerate(value)
            ]
        )
    else:
        j = np.diag([V.quantity(v, "inertia", f"{field}[{i}]", cls) for i, v in enumerate(value)])
    scale = max(np.abs(j).max(), 1e-300)
    if np.abs(j - j.T).max() > 1e-12 * scale:
        raise V.fail(field, j.tolist(), "must be symmetric (an inertia tensor)", cls)
    low = np.linalg.eigvalsh(j).min()
    if low < -1e-12 * scale:
        raise V.fail(
            field,
            j.tolist(),
            f"must be positive semi-definite (a rigid body's; its smallest principal "
            f"value is {low:.3g} kg m^2)",
            cls,
        )
    return j


# For methods whose argument shadows the name.
_inertia_of = platform_inertia


@dataclass(frozen=True)
class System:
    """A parallel mechanism: rods clamped at their bases (their designs' mountings) and at
    their tips to one platform. Load one with :func:`load_system`, or build it from
    :class:`SystemRod` and :class:`Platform`; solve it with :func:`solve_system`."""

    name: str
    rods: tuple[SystemRod, ...]
    platform: Platform
    citation: str = ""
    description: str = ""
    source: Path | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        # A list of rods would stay the caller's: appending to it would change the system.
        if isinstance(self.rods, list):
            object.__setattr__(self, "rods", tuple(self.rods))

    def save(self, path: str | os.PathLike) -> Path:
        """Write the system as a system file (``path``, .toml) and each rod's design beside
        it (``<stem>_rod<i>.toml``, the mounting included), all files or none; returns
        ``path``. :func:`load_system` reads it back to an equal system (e.g. the calibrated
        system of :func:`softrod.calibrate_system`)."""
        import tomli_w

        from .io import staged_paths

        path = as_path(path)
        if path.suffix.lower() != ".toml":
            raise V.fail("path", str(path), "a system file must end in .toml", InputError)
        files = [path.with_name(f"{path.stem}_rod{i}.toml") for i in range(len(self.rods))]
        texts = [rod.design.toml_text(f) for rod, f in zip(self.rods, files, strict=True)]

        def lengths(v, unit="m"):
            return [f"{float(x)!r} {unit}" for x in v]

        def rows(m):
            return [[float(x) for x in row] for row in np.asarray(m, dtype=float)]

        pf = self.platform
        doc: dict[str, Any] = {
            "system": {"name": self.name},
            "platform": {
                "position": lengths(pf.position),
                "orientation": rows(pf.rotation),
                "mass": f"{float(pf.mass)!r} kg",
                "com_offset": lengths(pf.com_offset),
                "inertia": [lengths(r, "kg*m^2") for r in np.asarray(pf.inertia)],
                "force": lengths(pf.force, "N"),
                "moment": lengths(pf.moment, "N*m"),
            },
            "rods": [
                {
                    "design": f.name,
                    "attachment": lengths(rod.attachment),
                    "attachment_orientation": rows(rod.attachment_rotation),
                }
                for rod, f in zip(self.rods, files, strict=True)
            ],
        }
        if self.citation:
            doc["system"]["citation"] = self.citation
        if self.description:
            doc["system"]["description"] = self.description
        with staged_paths([*files, path]) as staged:
            for tmp, text in zip(staged, [*texts, tomli_w.dumps(doc)], strict=True):
                tmp.write_text(text, encoding="utf-8")
        return path

    def __repr__(self) -> str:
        rods = ", ".join(r.design.name for r in self.rods)
        return (
            f"System({self.name!r}, {len(self.rods)} rods: {rods}; platform "
            f"{self.platform.mass * 1e3:g} g at {_mm(self.platform.position)})"
        )


@dataclass(frozen=True)
class SystemSolution:
    """A system's equilibrium: each rod's :class:`StaticSolution` (with the wrench the
    platform applies to its tip in ``tip_reaction_force`` / ``tip_reaction_moment``) and
    the platform's pose. ``stable``: the whole system's equilibrium is stable (docs/model.md,
    "Systems of rods"; every rod's ``stable`` says the same), None where it is not assessed
    (a follower load on some rod, friction) or the solve failed. ``friction_state``: where
    a frictional load path stands (a ``softrod._core.SystemFrictionState``: every rod's
    loads and contact memory, the platform's load), for ``solve_system(...,
    history=this)`` to go on from; None without friction."""

    system: System
    rods: tuple[StaticSolution, ...]
    platform_position: np.ndarray
    platform_rotation: np.ndarray
    converged: bool
    iterations: int
    residual: float
    load_steps: int
    unknowns: np.ndarray = field(repr=False)
    stable: bool | None = None
    friction_state: Any = field(default=None, repr=False)
    #: The binding's arguments the system was solved with (rods, platform, each rod's
    #: sigma): what :meth:`jacobian` differentiates. None where the solve failed.
    solved_with: tuple | None = field(default=None, repr=False, compare=False)

    def __repr__(self) -> str:
        if not self.converged:
            return f"SystemSolution({self.system.name!r}, not converged)"
        from .system_plots import platform_tilt_deg

        tilt = float(platform_tilt_deg(self.platform_rotation))
        return (
            f"SystemSolution({self.system.name!r}, platform at {_mm(self.platform_position)}, "
            f"tilt {tilt:.2f} deg, stable {self.stable}, {self.iterations} iterations)"
        )

    def jacobian(self) -> SystemJacobian:
        """The exact derivatives of the platform's pose and of every rod's base wrench with
        respect to every rod's pressures and tendon tensions and to the platform's force and
        moment (:class:`SystemJacobian`; docs/control.md, "Jacobians of a system"): implicit
        differentiation of the system's residual, no finite differences. A rod with a
        stiffness-mapped section adds the part through its map (the map must give a
        derivative, docs/stiffness-map.md). Refused: a solve that did not converge, a
        frictional equilibrium (its derivatives depend on the load path)."""
        entries, platform, sigmas, inputs, names, mapped = self._differentiated("jacobian")
        p_cols = [n for n in names if "_p" in n]
        t_cols = [n for n in names if "_t" in n]
        rods = self.system.rods
        out = _core.system_jacobian_of(
            entries, platform, self.unknowns.tolist(), inputs, stiffness_scale=sigmas
        )
        pose, base = np.asarray(out["pose"]), np.asarray(out["base"])
        edges = np.cumsum([0, len(p_cols), len(t_cols), 3, 3])
        blocks = ("pressures", "tensions", "platform_force", "platform_moment")
        spans = list(zip(blocks, edges[:-1], edges[1:], strict=True))
        own = {b: pose[:, a:z].copy() for b, a, z in spans}
        at_base = {b: base[:, :, a:z].copy() for b, a, z in spans}
        sigma_pose: list[np.ndarray | None] = [None] * len(rods)
        sigma_base: list[np.ndarray | None] = [None] * len(rods)
        widths = np.cumsum([0] + [rod.design.n_channels for rod in rods])
        for q, i in enumerate(mapped):
            at = edges[-1] + 3 * q
            sigma_pose[i], sigma_base[i] = pose[:, at : at + 3], base[:, :, at : at + 3]
            # sigma_i(p_i) moves with rod i's pressures: add d/dsigma_i dsigma_i/dp_i.
            dsigma = self._map_derivative(i)
            cols = slice(widths[i], widths[i + 1])
            own["pressures"][:, cols] += sigma_pose[i] @ dsigma
            at_base["pressures"][:, :, cols] += sigma_base[i] @ dsigma
        at_base["stiffness_scale"] = tuple(sigma_base)
        return SystemJacobian(
            position=np.array(out["position"]),
            rotation=np.array(out["rotation"]),
            base=at_base,
            pressure_columns=tuple(p_cols),
            tension_columns=tuple(t_cols),
            stiffness_scale=tuple(sigma_pose),
            **own,
        )

    def linearise(self, *, nodes: int = 8, platform_inertia: Any = None) -> SystemLinearSystem:
        """The linearised dynamics M q'' + D q' + K q = B u about this equilibrium, with its
        modes (:class:`softrod.SystemLinearSystem`; docs/control.md, "Modes of a system"):
        ``nodes`` nodes inside every rod plus the platform's pose; ``platform_inertia``
        (kg m^2 about the platform's centre of mass, platform frame; three principal values
        or a 3x3 tensor; None: the system's ``[platform] inertia``). K is the system's exact
        tangent (the implicit function theorem on its residual), M and D those of the rods'
        static deflection shapes plus the platform and every rod's tip body as rigid bodies;
        B has a column per rod pressure and tension and per component of the platform's
        force and moment. A rod with a stiffness-mapped section adds its map's part to its
        pressure columns (the map must give a derivative). Rods on obstacles (without
        friction) bring the contact's penalty stiffness into K, follower line loads their
        non-symmetric part (docs/control.md, "Follower loads and obstacles"). Refused as by
        :meth:`jacobian`: a failed solve, friction."""
        from .control.linear import SystemLinearSystem

        nodes = V.integer(nodes, "nodes", minimum=1, maximum=200)
        inertia = (
            self.system.platform.inertia
            if platform_inertia is None
            else _inertia_of(platform_inertia, "platform_inertia", InputError)
        )
        entries, platform, sigmas, inputs, names, mapped = self._differentiated("linearise")
        out = _core.system_linearise_of(
            entries,
            platform,
            self.unknowns.tolist(),
            inputs,
            nodes,
            np.asarray(inertia, dtype=float).tolist(),
            stiffness_scale=sigmas,
        )
        b = np.asarray(out["input"])
        width = len(names)
        widths = np.cumsum([0] + [rod.design.n_channels for rod in self.system.rods])
        for q, i in enumerate(mapped):
            # sigma_i(p_i) moves with rod i's pressures: add B_sigma dsigma_i/dp_i.
            dsigma = self._map_derivative(i)
            b[:, widths[i] : widths[i + 1]] += b[:, width + 3 * q : width + 3 * q + 3] @ dsigma
        return SystemLinearSystem(
            system=self.system,
            nodes=tuple(np.asarray(v) for v in out["nodes"]),
            mass=out["mass"],
            damping=out["damping"],
            stiffness=out["stiffness"],
            input=b[:, :width].copy(),
            input_names=names,
            equilibrium=self,
        )

    def _differentiated(self, method: str) -> tuple:
        """What the implicit differentiation of this equilibrium needs: the binding's
        arguments it was solved with (rods, platform, sigmas), the inputs (every rod's
        pressures, then tensions, the platform's force and moment, then the mapped rods'
        sigma factors), the names of all but the sigma columns, and the mapped rods.
        InputError naming the field for a failed solve, one without its arguments, or a
        frictional one."""
        if not self.converged:
            raise V.fail(
                "solution", "converged = False", "must be a converged SystemSolution", InputError
            )
        if self.solved_with is None:
            raise V.fail(
                "solution.solved_with",
                None,
                f"SystemSolution.{method} differentiates the system as it was solved "
                "(solve_system keeps its arguments in solved_with)",
                InputError,
            )
        if self.friction_state is not None:
            i = next(i for i, r in enumerate(self.rods) if r.friction_state is not None)
            k = self.rods[i].design.frictional_obstacle or 0
            raise V.fail(
                f"rods[{i}].design.obstacles[{k}].friction",
                self.rods[i].design.spec["obstacles"][k]["friction"],
                f"SystemSolution.{method} is not available for a frictional equilibrium: it "
                "depends on the load path, and the stick/slip switch has no derivative there "
                "(docs/contact.md, 'Friction in the statics')",
                InputError,
            )
        entries, platform, sigmas = self.solved_with
        rods = self.system.rods
        inputs: list[tuple[str, int, int]] = []
        names: list[str] = []
        for i, rod in enumerate(rods):
            inputs += [("pressure", i, c) for c in range(rod.design.n_channels)]
            names += [f"rod{i}_p{c}" for c in range(rod.design.n_channels)]
        for i, rod in enumerate(rods):
            inputs += [("tension", i, c) for c in range(rod.design.n_tendons)]
            names += [f"rod{i}_t{c}" for c in range(rod.design.n_tendons)]
        inputs += [("platform_force", 0, j) for j in range(3)]
        inputs += [("platform_moment", 0, j) for j in range(3)]
        names += ["F_x", "F_y", "F_z", "M_x", "M_y", "M_z"]
        mapped = [i for i, rod in enumerate(rods) if rod.design.mapped_sections]
        for i in mapped:
            inputs += [("stiffness_scale", i, k) for k in range(3)]
        return entries, platform, sigmas, inputs, tuple(names), mapped

    def _map_derivative(self, i: int) -> np.ndarray:
        """d sigma / d p (3, channels) of mapped rod i at its pressures; InputError naming
        ``rods[i].stiffness_map`` when the solution lost its map."""
        smap = self.rods[i].stiffness_map
        if smap is None:
            raise V.fail(
                f"rods[{i}].stiffness_map",
                None,
                "a mapped rod's pressure derivatives need the stiffness map it was solved "
                "with (solve_system keeps it): sigma(p) moves with the pressures",
                InputError,
            )
        return smap.derivative(np.asarray(self.rods[i].pressures, dtype=float))

    def plot(self, path: str | os.PathLike | None = None, *, title: str | None = None) -> Figure:
        """Front (x-z) and side (y-z) views of the equilibrium
        (:func:`softrod.plot_system`; several solutions in one figure: call
        that function with a list). Written to ``path`` when given; returns the Figure."""
        from .system_plots import plot_system

        return plot_system(self, path, title=title)


def systems_dir() -> Path:
    """The folder of the bundled system files."""
    return Path(__file__).resolve().parent / "designs" / "systems"


def bundled_systems() -> list[str]:
    """Names of the bundled system files (usable in :func:`load_system`)."""
    return sorted(p.stem for p in systems_dir().glob("*.toml"))


def load_system(source: str | Path) -> System:
    """Read a system file (see the module's docstring), or a bundled one by name. Rod
    designs are files relative to the system file, or bundled designs. Raises
    :class:`DesignError` naming the field, the value and the rule."""
    if not isinstance(source, (str, os.PathLike)):
        raise V.fail(
            "system",
            type(source).__name__,
            "must be a System, a system file's path or a bundled system's name "
            f"({', '.join(bundled_systems())})",
            DesignError,
        )
    path = Path(source)
    if not _exists(path) and path.suffix == "" and _exists(systems_dir() / f"{source}.toml"):
        path = systems_dir() / f"{source}.toml"
    if not _is_file(path):
        raise V.fail(
            "system",
            str(source),
            f"no such file or bundled system ({', '.join(bundled_systems())})",
            DesignError,
        )
    # Size, encoding, syntax and nesting depth checked as for design files.
    doc = read_toml(path)
    doc = _keys(doc, "", "")
    meta = _keys(doc.get("system", {}), "system", "system")
    name = V.text(meta.get("name", path.stem), "system.name", DesignError, non_empty=True)
    pf = _keys(doc.get("platform"), "platform", "platform") if "platform" in doc else None
    if pf is None or "position" not in pf:
        raise V.fail(
            "platform.position",
            "(missing)",
            "the platform's nominal position is required (3 lengths, world frame)",
            DesignError,
        )
    platform = Platform(
        position=_vec(pf["position"], "length", "platform.position"),
        rotation=(
            _orientation(pf["orientation"], "platform.orientation", DesignError)
            if "orientation" in pf
            else np.eye(3)
        ),
        force=_vec(pf.get("force"), "force", "platform.force"),
        moment=_vec(pf.get("moment"), "moment", "platform.moment"),
        mass=V.quantity(pf.get("mass", 0.0), "mass", "platform.mass", DesignError),
        com_offset=_vec(pf.get("com_offset"), "length", "platform.com_offset"),
        inertia=platform_inertia(pf.get("inertia"), "platform.inertia"),
    )
    if platform.mass < 0:
        raise V.fail("platform.mass", pf["mass"], "must be >= 0", DesignError)
    rods_doc = doc.get("rods")
    if not isinstance(rods_doc, list) or not rods_doc:
        raise V.fail(
            "rods", rods_doc, "must be a non-empty array of tables ([[rods]])", DesignError
        )
    if len(rods_doc) > 64:
        raise V.fail("rods", f"{len(rods_doc)} rods", "a system has at most 64 rods", DesignError)
    rods = []
    for i, r in enumerate(rods_doc):
        where = f"rods[{i}]"
        r = _keys(r, "rod", where)
        if "design" not in r or "attachment" not in r:
            missing = "design" if "design" not in r else "attachment"
            raise V.fail(f"{where}.{missing}", "(missing)", "is required", DesignError)
        given = r["design"]
        if not isinstance(given, str) or not given:
            raise V.fail(
                f"{where}.design", given, "must be a design file or bundled name", DesignError
            )
        local = path.parent / given
        design = load_design(local if _exists(local) else given)
        if "base_position" in r:
            design = design.replace({"mounting.base_position": r["base_position"]})
        rods.append(
            SystemRod(
                design=design,
                attachment=_vec(r["attachment"], "length", f"{where}.attachment"),
                attachment_rotation=(
                    _orientation(
                        r["attachment_orientation"], f"{where}.attachment_orientation", DesignError
                    )
                    if "attachment_orientation" in r
                    else np.eye(3)
                ),
            )
        )
    return System(
        name=name,
        rods=tuple(rods),
        platform=platform,
        citation=str(meta.get("citation", "")),
        description=str(meta.get("description", "")),
        source=path,
    )


def solve_system(
    system: System | str | Path,
    pressures: Any = None,
    *,
    tensions: Any = None,
    platform_force: Any = None,
    platform_moment: Any = None,
    options: SolverOptions | None = None,
    initial: SystemSolution | None = None,
    history: SystemSolution | None = None,
    check: bool = True,
    on_invalid: str = "raise",
    on_unstable: str = "warn",
    stiffness_maps: Any = None,
) -> SystemSolution:
    """Static equilibrium of a :class:`System` (or a system file / bundled name).

    pressures: one list of gauge pressures (Pa or strings with units) per rod, None: all
    zero; tensions likewise (None: slack). platform_force (N, world) and platform_moment
    (N m, about the platform origin, world) replace the system's platform load when given;
    the platform's weight always acts (gravity of the first rod's design). Each rod's own
    tip body and tip loads act on its tip. ``initial`` warm-starts from a previous
    solution. On non-convergence raises :class:`ConvergenceError`, or with ``check=False``
    returns a solution with ``converged=False`` and NaN platform pose. Every rod passes the
    validity checks of :func:`solve_statics` (``on_invalid`` as there). The whole system's
    stability is assessed (``stable``; docs/model.md, "Systems of rods"); ``on_unstable``
    says what an unstable equilibrium does, as for :func:`solve_statics`: "warn" (default, a
    :class:`StabilityWarning`), "raise" (:class:`InvalidStateError` with rule "stability")
    or "ignore".

    A rod whose design has a stiffness-mapped section (``[sections.law] stiffness_map =
    true``, docs/stiffness-map.md) has its stiffness scaled by sigma of its own pressures,
    evaluated once as :func:`solve_statics` evaluates it for that rod alone: from its
    design's map (``[stiffness_map] file``), or from ``stiffness_maps`` (one
    :class:`StiffnessMap` or None per rod; a map given replaces the design's). A mapped
    rod without a map is refused (sigma is never assumed to be 1). Each rod's solution
    reports its sigma in ``stiffness_scale``.

    Where some rod's design has an obstacle with friction > 0 the system follows a load
    path (docs/contact.md, "Friction in the statics", "Systems of rods"): from the
    unloaded rods, or with ``history`` (a frictional SystemSolution of this system) from
    that solution's loads and contact memory, to the requested pressures, tensions,
    platform load and attachments in ``options.friction_steps`` equal increments; the
    answer depends on the path, ``stable`` is None, ``friction_state`` carries the path
    on, and a warm start (``initial``) is refused.
    """
    if not isinstance(system, System):
        system = load_system(system)
    on_invalid = _policy("on_invalid", on_invalid)
    on_unstable = _policy("on_unstable", on_unstable)
    V.boolean(check, "check")
    n = len(system.rods)
    opts = _options(options)

    def per_rod(value, name):
        if value is None:
            return [None] * n
        if isinstance(value, np.ndarray) and value.ndim >= 1:
            value = list(value)  # one row per rod, as simulate_system takes
        if not isinstance(value, (list, tuple)) or len(value) != n:
            raise V.fail(name, value, f"must be a list of {n} entries, one per rod", InputError)
        return list(value)

    maps = check_rods(system, stiffness_maps, argument=True)
    ps = per_rod(pressures, "pressures")
    ts = per_rod(tensions, "tensions")
    entries = []
    sigmas = []
    for i, (rod, p, t, smap) in enumerate(zip(system.rods, ps, ts, maps, strict=True)):
        d = rod.design
        pv = [0.0] * d.n_channels if p is None else _pressures(d, p)
        sigmas.append(None if smap is None else _rod_sigma(i, smap, np.array([pv]))[0])
        tip = d.spec["tip"]
        entries.append(
            (
                d._rod,
                pv,
                _tensions(d, t),
                list(tip["force"]),
                list(tip["moment"]),
                [float(v) for v in rod.attachment],
                np.asarray(rod.attachment_rotation, dtype=float).tolist(),
            )
        )
    platform = _platform_args(system, platform_force, platform_moment)
    guess = None
    if initial is not None:
        if not isinstance(initial, SystemSolution):
            raise V.fail("initial", type(initial).__name__, "must be a SystemSolution or None")
        if initial.converged:
            guess = initial.unknowns.tolist()
    state = _system_history(history)
    try:
        out = _core.solve_rod_system(
            entries,
            platform,
            guess=guess,
            on_invalid=on_invalid,
            friction_steps=int(opts.friction_steps),
            history=state,
            stiffness_scale=[None if sg is None else sg.tolist() for sg in sigmas],
            **opts.as_kwargs(),
        )
    except ConvergenceError as exc:
        if check:
            raise
        nan3 = np.full(3, np.nan)
        return SystemSolution(
            system=system,
            rods=(),
            platform_position=nan3,
            platform_rotation=np.full((3, 3), np.nan),
            converged=False,
            iterations=exc.iterations,
            residual=exc.residual,
            load_steps=0,
            unknowns=np.full(6 * n + 6, np.nan),
        )
    _report_stability(out["stable"], on_unstable, f"the system {system.name!r}'s equilibrium")
    sols = []
    for rod, entry, o, sg, smap in zip(
        system.rods, entries, out["rods"], sigmas, maps, strict=True
    ):
        sols.append(
            StaticSolution(
                design=rod.design,
                pressures=np.array(entry[1]),
                s=o["s"],
                section=o["section"],
                position=o["position"],
                rotation=o["rotation"],
                force=o["force"],
                moment=o["moment"],
                v=o["v"],
                u=o["u"],
                converged=True,
                iterations=o["iterations"],
                residual=o["residual"],
                load_steps=o["load_steps"],
                shooting_unknowns=np.array(o["x"]),
                stiffness_scale=_UNIT_SCALE if sg is None else sg,
                stiffness_map=smap,
                stable=out["stable"],
                violations=tuple(o["violations"]),
                tip_loads=(tuple(entry[3]), tuple(entry[4])),
                tensions=np.array(entry[2]),
                tip_constraint="clamped",
                tip_reaction_force=np.array(o["tip_reaction_force"]),
                tip_reaction_moment=np.array(o["tip_reaction_moment"]),
                contact=Contact.from_core(o["contact"]) if "contact" in o else None,
                friction_state=o.get("friction_state"),
            )
        )
    return SystemSolution(
        system=system,
        rods=tuple(sols),
        platform_position=np.array(out["platform_position"]),
        platform_rotation=np.array(out["platform_rotation"]),
        converged=True,
        iterations=out["iterations"],
        residual=out["residual"],
        load_steps=out["load_steps"],
        unknowns=np.array(out["x"]),
        stable=out["stable"],
        friction_state=out.get("friction_state"),
        solved_with=(
            entries,
            platform,
            [None if sg is None else sg.tolist() for sg in sigmas],
        ),
    )


def _system_history(history):
    """The friction state a system's frictional path continues from (``history=``): a
    converged frictional SystemSolution (the core checks that it belongs to this system's
    designs, obstacles and platform, and that the system has friction)."""
    if history is None:
        return None
    if not isinstance(history, SystemSolution):
        raise V.fail(
            "history",
            type(history).__name__,
            "must be a frictional SystemSolution (from solve_system) or None",
            InputError,
        )
    if history.friction_state is None:
        raise V.fail(
            "history",
            history.system.name,
            "must be a converged frictional SystemSolution (its friction_state is None: "
            "frictionless, or failed)",
            InputError,
        )
    return history.friction_state


def _load3(value, kind: str, name: str) -> np.ndarray:
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise V.fail(name, value, f"must be 3 {kind} values (world frame)", InputError)
    return np.array([V.quantity(v, kind, f"{name}[{i}]", InputError) for i, v in enumerate(value)])


@dataclass(frozen=True)
class SystemBatchSolution:
    """Results of :func:`solve_system_batch`: one equilibrium of the whole system per input
    row (n rods), failed rows kept (``converged`` False, NaN).

    pressures, tensions: per rod, its (m, channels) gauge pressures (Pa) and (m, tendon
    channels) tensions (N). converged (m,) bool; iterations (m,); residual (m,); load_steps
    (m,). platform_position (m, 3) m and platform_rotation (m, 3, 3) (world). Per rod
    (axis 1): tip_position (m, n, 3) m, tip_rotation (m, n, 3, 3), base_force (m, n, 3) N,
    base_moment (m, n, 3) N m and the wrench the platform applies to its tip,
    tip_reaction_force (m, n, 3) N and tip_reaction_moment (m, n, 3) N m (world frame).
    unknowns (m, 6 n + 6): the solver's unknowns (``SystemSolution.unknowns`` of each row).
    violation (m,) str: the validity rule a rod broke ("rods[i]: ...", "" if none). stable
    (m,) bool: the row's system equilibrium is stable (False on failed rows and where not
    assessed); stability_assessed (m,) bool (as :func:`solve_system`). contact_force and
    friction_force: per rod, None (no obstacles) or its obstacles' resultant contact forces
    and their tangential (friction) parts, (m, obstacles, 3) N (world frame; NaN on failed
    rows). stiffness_scale: per rod, None (no stiffness-mapped section) or its (m, 3) sigma
    (sigma_ext, sigma_bend_x, sigma_bend_y; docs/stiffness-map.md). metadata: the metadata
    block of :meth:`to_frame`.
    """

    system: System
    pressures: tuple[np.ndarray, ...]
    tensions: tuple[np.ndarray, ...]
    converged: np.ndarray
    iterations: np.ndarray
    residual: np.ndarray
    load_steps: np.ndarray
    platform_position: np.ndarray
    platform_rotation: np.ndarray
    tip_position: np.ndarray
    tip_rotation: np.ndarray
    base_force: np.ndarray
    base_moment: np.ndarray
    tip_reaction_force: np.ndarray
    tip_reaction_moment: np.ndarray
    unknowns: np.ndarray = field(repr=False)
    violation: np.ndarray = field(repr=False)
    stable: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool), repr=False)
    stability_assessed: np.ndarray = field(
        default_factory=lambda: np.zeros(0, dtype=bool), repr=False
    )
    contact_force: tuple = field(default=(), repr=False)
    friction_force: tuple = field(default=(), repr=False)
    stiffness_scale: tuple = field(default=(), repr=False)
    metadata: dict = field(default_factory=dict, compare=False, repr=False)

    def __len__(self) -> int:
        return int(self.converged.shape[0])

    def __repr__(self) -> str:
        return (
            f"SystemBatchSolution({self.system.name!r}, {len(self)} rows, "
            f"{int(np.sum(self.converged))} converged)"
        )

    def to_frame(self, units: Units = None) -> pd.DataFrame:
        """The results as a DataFrame, one row per system equilibrium, units in the column
        names as in the dataset schema (docs/datasets.md; ``units`` as there): per rod i its
        inputs ``rod<i>_p<k>_kPa`` and ``rod<i>_t<k>_N``; the platform pose
        ``platform_x_mm`` ... ``platform_z_mm``, ``platform_qw`` ... ``platform_qz``; per rod
        its tip position ``rod<i>_tip_x_mm`` ... and the platform's reaction on its tip
        ``rod<i>_tip_reaction_fx_N`` ... ``rod<i>_tip_reaction_mz_Nmm`` (world frame); per
        rod with obstacles its contact forces ``rod<i>_contact<k>_fx_N`` ... and their
        friction parts ``rod<i>_friction<k>_fx_N`` ...; per stiffness-mapped rod its sigma
        ``rod<i>_sigma_ext``, ``rod<i>_sigma_bend_x``, ``rod<i>_sigma_bend_y``; then
        ``converged``, ``iterations``, ``residual``, ``stable`` (empty where stability was
        not assessed: friction, follower loads). Failed rows keep NaN. The metadata block
        (``frame.attrs["softrod.metadata"]``) is :attr:`metadata`."""
        import pandas as pd

        from .schema import table_units

        chosen, factor = table_units(units)
        cols = system_columns(self, chosen, factor)
        for i, (fc, ff) in enumerate(zip(self.contact_force, self.friction_force, strict=True)):
            for arr, name in ((fc, "contact"), (ff, "friction")):
                if arr is None:
                    continue
                for k in range(arr.shape[1]):
                    for j, a in enumerate("xyz"):
                        cols[f"rod{i}_{name}{k}_f{a}_{chosen['force']}"] = (
                            arr[:, k, j] / factor["force"]
                        )
        for i, sigma in enumerate(self.stiffness_scale):
            if sigma is not None:
                for k, name in enumerate(SIGMA_NAMES):
                    cols[f"rod{i}_{name}"] = sigma[:, k]
        cols["converged"] = np.asarray(self.converged, dtype=bool)
        cols["iterations"] = np.asarray(self.iterations)
        cols["residual"] = np.asarray(self.residual, dtype=float)
        if self.stable.shape == self.converged.shape:
            stable = np.asarray(self.stable, dtype=bool)
            assessed = np.asarray(self.stability_assessed, dtype=bool)
            if assessed.shape == stable.shape and not assessed.all():
                # Not assessed is no verdict: an empty cell, never a False that a reader
                # would take for "unstable".
                stable = pd.array(np.where(assessed, stable, None), dtype="boolean")
            cols["stable"] = stable
        frame = pd.DataFrame(cols)
        frame.attrs["softrod.metadata"] = dict(self.metadata)
        return frame


def system_columns(result: Any, chosen: dict, factor: dict) -> dict[str, np.ndarray]:
    """The columns a system's table has in common, equilibria (a
    :class:`SystemBatchSolution`) or samples of a motion (a
    :class:`~softrod.SystemTrajectory`), read from ``result``'s arrays of those names, in
    the units ``chosen``/``factor`` of :func:`softrod.schema.table_units`: per rod i its
    inputs ``rod<i>_p<k>_kPa`` and ``rod<i>_t<k>_N``, the platform pose ``platform_x_mm``
    ... ``platform_qw`` ... ``platform_qz``, per rod its tip ``rod<i>_tip_x_mm`` ... and the
    platform's reaction on its tip ``rod<i>_tip_reaction_fx_N`` ... (world frame)."""
    from .schema import matrix_to_quat

    cols: dict[str, np.ndarray] = {}
    for i, p in enumerate(result.pressures):
        for k in range(p.shape[1]):
            cols[f"rod{i}_p{k}_{chosen['pressure']}"] = p[:, k] / factor["pressure"]
    for i, t in enumerate(result.tensions):
        for k in range(t.shape[1]):
            cols[f"rod{i}_t{k}_{chosen['force']}"] = t[:, k] / factor["force"]
    for k, a in enumerate("xyz"):
        cols[f"platform_{a}_{chosen['length']}"] = result.platform_position[:, k] / factor["length"]
    q = matrix_to_quat(result.platform_rotation)
    for k, a in enumerate("wxyz"):
        cols[f"platform_q{a}"] = q[:, k]
    for i in range(result.tip_position.shape[1]):
        for k, a in enumerate("xyz"):
            cols[f"rod{i}_tip_{a}_{chosen['length']}"] = (
                result.tip_position[:, i, k] / factor["length"]
            )
        for name, arr, kind in (
            ("f", result.tip_reaction_force, "force"),
            ("m", result.tip_reaction_moment, "moment"),
        ):
            for k, a in enumerate("xyz"):
                cols[f"rod{i}_tip_reaction_{name}{a}_{chosen[kind]}"] = arr[:, i, k] / factor[kind]
    return cols


def _system_rows(system: System, value: Any, name: str, kind: str, widths: list[int]):
    """Per rod, an (m, width_i) float array of the rows ``value``: m rows, each as
    :func:`solve_system` takes it (one list per rod), e.g. an (m, n, width) array when every
    rod has as many channels. Values are SI numbers or strings with units, finite."""
    n = len(system.rods)
    rule = (
        f"must be one row per equilibrium, each a list of {n} per-rod lists ({widths} "
        f"{'channels' if kind == 'pressure' else 'tendon channels'}), e.g. an (m, {n}, "
        f"{widths[0]}) array"
        if len(set(widths)) == 1
        else f"must be one row per equilibrium, each a list of {n} per-rod lists ({widths} "
        f"{'channels' if kind == 'pressure' else 'tendon channels'})"
    )
    if isinstance(value, (str, bytes, dict)) or not hasattr(value, "__len__"):
        raise V.fail(name, value, rule, InputError)
    limit = V.MAX_ROWS * max(sum(widths), 1)
    if len(set(widths)) == 1:
        arr = V.real_array(value, name, unit_kind=kind, max_size=limit)
        if arr.ndim != 3 or arr.shape[1:] != (n, widths[0]):
            if not (arr.ndim == 1 and arr.size == 0):
                raise V.fail(name, f"shape {arr.shape}", rule, InputError)
            arr = arr.reshape(0, n, widths[0])
        return [np.ascontiguousarray(arr[:, i, :]) for i in range(n)]
    rows = list(value)
    if len(rows) > V.MAX_ROWS:
        raise V.fail(name, f"{len(rows)} rows", f"too many rows: at most {V.MAX_ROWS:,}")
    blocks = [np.empty((len(rows), w)) for w in widths]
    for r, row in enumerate(rows):
        if isinstance(row, (str, bytes, dict)) or not hasattr(row, "__len__") or len(row) != n:
            raise V.fail(f"{name}[{r}]", row, rule, InputError)
        for i, w in enumerate(widths):
            a = V.real_array(row[i], f"{name}[{r}][{i}]", unit_kind=kind, max_size=64)
            if a.shape != (w,):
                raise V.fail(
                    f"{name}[{r}][{i}]",
                    f"shape {a.shape}",
                    f"rod {i} has {w} channel(s): give {w} values",
                    InputError,
                )
            blocks[i][r] = a
    return blocks


def solve_system_batch(
    system: System | str | Path,
    pressures: Any = None,
    *,
    tensions: Any = None,
    platform_force: Any = None,
    platform_moment: Any = None,
    options: SolverOptions | None = None,
    threads: int = 0,
    on_invalid: str = "raise",
    on_unstable: str = "warn",
    stiffness_maps: Any = None,
) -> SystemBatchSolution:
    """Static equilibria of a :class:`System` for many inputs at once, in parallel (Rust,
    ``threads`` cores, 0 = all, GIL released).

    pressures: one row per equilibrium, each as :func:`solve_system` takes it (one list of
    gauge pressures per rod, Pa or strings with units), e.g. an (m, n_rods, channels) array
    when every rod has as many channels; None: all zero (the rows then come from
    ``tensions``). tensions likewise (N, each >= 0; None: slack). platform_force,
    platform_moment, options and on_invalid as in :func:`solve_system`, shared by every
    row. Every row is solved exactly as :func:`solve_system` solves it alone (cold), so a
    row is bitwise equal to the single solve whatever the thread count or grouping of rows.
    Rows that fail (no convergence, an invalid state) are kept with ``converged`` False, NaN
    and the broken rule in ``violation``; with ``on_invalid="warn"`` rows outside the
    validity range keep their values and one :class:`ValidityWarning` says how many.
    ``stable`` (m,) says which equilibria are stable (``stability_assessed`` False where not
    assessed); ``on_unstable``: "warn" (default, one :class:`StabilityWarning` naming how
    many rows are unstable), "raise" or "ignore". Bad inputs raise :class:`InputError`
    naming the row, the rod and the rule before any work. Where some rod's obstacle has
    friction > 0 every row is its own load path from the unloaded rods in
    ``options.friction_steps`` increments, exactly as :func:`solve_system` solves it alone.
    Stiffness-mapped rods and ``stiffness_maps`` as in :func:`solve_system`: each rod's map
    is evaluated on its block of rows as :func:`solve_statics_batch` evaluates a map, each
    row's sigma bitwise the single solve's (``stiffness_scale``: per rod, None or its (m, 3)
    sigma).
    """
    import warnings

    from .errors import ValidityWarning

    if not isinstance(system, System):
        system = load_system(system)
    on_invalid = _policy("on_invalid", on_invalid)
    on_unstable = _policy("on_unstable", on_unstable)
    threads = V.threads(threads)
    opts = _options(options)
    maps = check_rods(system, stiffness_maps, argument=True)
    nc = [rod.design.n_channels for rod in system.rods]
    nt = [rod.design.n_tendons for rod in system.rods]
    if not sum(nc) and not sum(nt):
        raise V.fail(
            "pressures",
            "no channels",
            "the system's rods have neither pressure "
            "channels nor tendons, so every row would be the same equilibrium: use "
            "solve_system",
            InputError,
        )
    if pressures is None and tensions is None:
        raise V.fail(
            "pressures",
            None,
            "give the rows: pressures (or tensions) of every rod for every equilibrium",
            InputError,
        )
    ps = None if pressures is None else _system_rows(system, pressures, "pressures", "pressure", nc)
    if tensions is not None and sum(nt) == 0:
        raise V.fail(
            "tensions",
            "an array",
            "the system's rods have no tendons; leave tensions out",
            InputError,
        )
    ts = None if tensions is None else _system_rows(system, tensions, "tensions", "force", nt)
    m = len(ps[0]) if ps is not None else len(ts[0])
    if ps is None:
        ps = [np.zeros((m, w)) for w in nc]
    if ts is not None and len(ts[0]) != m:
        raise V.fail(
            "tensions",
            f"{len(ts[0])} rows",
            f"must have as many rows as pressures ({m})",
            InputError,
        )
    if ts is None:
        ts = [np.zeros((m, w)) for w in nt]
    for i, p in enumerate(ps):
        low = np.argwhere(p < V.VACUUM_PA)
        if low.size:
            r, k = (int(v) for v in low[0])
            raise V.fail(
                f"pressures[{r}][{i}][{k}]",
                float(p[r, k]),
                f"gauge pressures must be >= {V.VACUUM_PA:g} Pa (-1 atm, a perfect vacuum)",
                InputError,
            )
    for i, t in enumerate(ts):
        bad = np.argwhere(~(t >= 0.0))
        if bad.size:
            r, k = (int(v) for v in bad[0])
            raise V.fail(
                f"tensions[{r}][{i}][{k}]",
                f"{float(t[r, k])!r} N",
                "a tendon tension must be >= 0 (a tendon pulls or is slack, it cannot push)",
                InputError,
            )
    sigma = system_sigma(maps, ps)
    entries = _batch_entries(system)
    platform = _platform_args(system, platform_force, platform_moment)
    flat_p = np.ascontiguousarray(np.concatenate(ps, axis=1) if ps else np.zeros((m, 0)))
    flat_t = np.ascontiguousarray(np.concatenate(ts, axis=1)) if sum(nt) else None
    out = _core.solve_rod_system_batch(
        entries,
        platform,
        flat_p,
        tensions=flat_t,
        threads=threads,
        on_invalid=on_invalid,
        friction_steps=int(opts.friction_steps),
        stiffness_scale=sigma,
        **opts.as_kwargs(),
    )
    violation = np.asarray(out["violation"], dtype=object)
    converged = np.asarray(out["converged"], dtype=bool)
    stable = np.asarray(out["stable"], dtype=bool)
    assessed = np.asarray(out["assessed"], dtype=bool)
    unstable = np.flatnonzero(converged & assessed & ~stable)
    if unstable.size:
        _report_stability(
            False,
            on_unstable,
            f"{unstable.size} of {m} rows (first: row {unstable[0]})"
            if unstable.size > 1
            else f"row {unstable[0]}",
        )
    outside = np.flatnonzero(converged & (violation != ""))
    if outside.size and on_invalid == "warn":
        warnings.warn(
            ValidityWarning(
                f"{outside.size} of {m} rows lie outside the validity range (first: row "
                f"{outside[0]}: {violation[outside[0]]}); see SystemBatchSolution.violation"
            ),
            stacklevel=2,
        )
    from .schema import provenance

    meta = provenance(
        "softrod.solve_system_batch",
        None,
        system=system.name,
        rods=[rod.design.name for rod in system.rods],
        solver=opts.as_kwargs(),
        platform_force_N=platform[2],
        platform_moment_Nm=platform[3],
    )
    if sigma is not None:
        meta["stiffness_maps"] = [None if smap is None else repr(smap) for smap in maps]
    contact = out["contact"]
    if any(r.design.frictional_obstacle is not None for r in system.rods):
        meta["friction_steps"] = int(opts.friction_steps)  # every row's load path
    return SystemBatchSolution(
        system=system,
        pressures=tuple(ps),
        tensions=tuple(ts),
        converged=converged,
        iterations=np.asarray(out["iterations"]),
        residual=np.asarray(out["residual"]),
        load_steps=np.asarray(out["load_steps"]),
        platform_position=out["platform_position"],
        platform_rotation=out["platform_rotation"],
        tip_position=out["tip_position"],
        tip_rotation=out["tip_rotation"],
        base_force=out["base_force"],
        base_moment=out["base_moment"],
        tip_reaction_force=out["tip_reaction_force"],
        tip_reaction_moment=out["tip_reaction_moment"],
        unknowns=out["x"],
        violation=violation,
        stable=stable,
        stability_assessed=assessed,
        contact_force=tuple(None if c is None else c["contact_force"] for c in contact),
        friction_force=tuple(None if c is None else c["friction_force"] for c in contact),
        stiffness_scale=tuple(
            None if smap is None else _read_only_rows(sigma[:, i, :]) for i, smap in enumerate(maps)
        ),
        metadata=meta,
    )


def _read_only_rows(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.flags.writeable = False
    return a


def check_rods(
    system: System, stiffness_maps: Any = None, *, argument: bool = False
) -> list[StiffnessMap | None]:
    """Check what a system's statics can carry, naming the rod, and return each rod's
    stiffness map (None for a rod without stiffness-mapped sections). A rod whose design
    holds its own tip ([tip] constraint: the platform holds it) is refused. A rod with a
    mapped section uses the map of ``stiffness_maps`` (one :class:`StiffnessMap` or None
    per rod; ``argument``: the entry point takes that argument) or else its design's
    (``[stiffness_map] file``); one with neither is refused (sigma is never assumed to be
    1), as is a map given for a rod without mapped sections or for another number of
    channels."""
    n = len(system.rods)
    _check_tips(system)
    if stiffness_maps is None:
        given = [None] * n
    else:
        if isinstance(stiffness_maps, (str, bytes, dict, StiffnessMap)) or not isinstance(
            stiffness_maps, (list, tuple)
        ):
            raise V.fail(
                "stiffness_maps",
                stiffness_maps,
                f"must be a list of {n} entries, one per rod: a softrod.StiffnessMap or None",
                InputError,
            )
        if len(stiffness_maps) != n:
            raise V.fail(
                "stiffness_maps",
                f"{len(stiffness_maps)} entries",
                f"must be a list of {n} entries, one per rod: a softrod.StiffnessMap or None",
                InputError,
            )
        given = list(stiffness_maps)
    maps: list[StiffnessMap | None] = []
    for i, (rod, smap) in enumerate(zip(system.rods, given, strict=True)):
        d = rod.design
        if smap is None and d.stiffness_map is None:
            mapped = d.mapped_sections
            if mapped:
                hint = (
                    "give it a map in stiffness_maps= (one softrod.StiffnessMap or None per "
                    "rod, e.g. StiffnessMap.from_table or from_csv) or reference"
                    if argument
                    else "reference"
                )
                raise V.fail(
                    f"rods[{i}].design.stiffness_map",
                    None,
                    f"section(s) {', '.join(mapped)} of design {d.name!r} set [sections.law] "
                    f"stiffness_map = true: {hint} a map file in the rod's design "
                    '([stiffness_map] file = "sigma.json"); sigma is never assumed to be 1',
                    InputError,
                )
            maps.append(None)
            continue
        try:
            maps.append(_stiffness_map(d, smap))
        except DesignError as e:
            raise V.fail(
                f"stiffness_maps[{i}]", e.value, f"rods[{i}]: {e.rule}", InputError
            ) from None
    return maps


def _check_tips(system: System) -> None:
    """Refuse, naming the rod, a rod whose design holds its own tip ([tip] constraint: the
    platform holds it)."""
    for i, rod in enumerate(system.rods):
        d = rod.design
        if d.tip_constraint is not None:
            raise V.fail(
                f"rods[{i}].design",
                d.name,
                "its [tip] constraint is set; a system's rod tips hold the platform",
                InputError,
            )


def _rod_sigma(i: int, smap: StiffnessMap, pressures: np.ndarray) -> np.ndarray:
    """sigma (m, 3) of rod ``i``'s pressure rows (m, channels), each row as
    :func:`solve_statics` evaluates it for that row alone (``statics._sigma_rows``: so a
    batch row is bitwise the single solve's); a map's refusal names the rod."""
    try:
        return np.ascontiguousarray(_sigma_rows(smap, pressures), dtype=float)
    except DesignError as e:
        raise V.fail(
            f"rods[{i}].{e.field}", e.value, f"{e.rule} (rod {i}'s {smap!r})", InputError
        ) from None


def rod_blocks(flat: np.ndarray, widths: list[int]) -> list[np.ndarray]:
    """Per rod, its (m, width_i) columns of an (m, sum of widths) array whose rows hold rod
    0's values, then rod 1's, ... (a system dataset's pressure columns)."""
    edges = np.cumsum([0, *widths])
    return [np.ascontiguousarray(flat[:, a:b]) for a, b in zip(edges[:-1], edges[1:], strict=True)]


def system_sigma(maps: list[StiffnessMap | None], pressures: list[np.ndarray]) -> np.ndarray | None:
    """The (m, n, 3) sigma of every row and rod of a system batch from each rod's map
    (:func:`check_rods`) and its (m, channels) pressure block, each row as
    :func:`solve_system` evaluates it alone (a rod without a map: 1, which acts nowhere);
    None when no rod has a map."""
    if all(smap is None for smap in maps):
        return None
    m = len(pressures[0]) if pressures else 0
    out = np.ones((m, len(maps), 3))
    for i, (smap, p) in enumerate(zip(maps, pressures, strict=True)):
        if smap is not None:
            out[:, i, :] = _rod_sigma(i, smap, p)
    return out


def _batch_entries(system: System) -> list[tuple]:
    """The binding's rods of a system batch: each rod's core rod, its design's tip loads
    and its attachment (the rows give the pressures, tensions and sigma: :func:`check_rods`
    and :func:`system_sigma`); no rod may hold its own tip."""
    _check_tips(system)
    entries = []
    for rod in system.rods:
        tip = rod.design.spec["tip"]
        entries.append(
            (
                rod.design._rod,
                list(tip["force"]),
                list(tip["moment"]),
                [float(v) for v in rod.attachment],
                np.asarray(rod.attachment_rotation, dtype=float).tolist(),
            )
        )
    return entries


def _platform_args(system: System, platform_force, platform_moment) -> tuple:
    """The binding's platform tuple: pose, load (given or the system's), mass, centre of
    mass, gravity (of the first rod's design)."""
    pf = system.platform
    force = (
        pf.force if platform_force is None else _load3(platform_force, "force", "platform_force")
    )
    moment = (
        pf.moment
        if platform_moment is None
        else _load3(platform_moment, "moment", "platform_moment")
    )
    gravity = system.rods[0].design.spec["mounting"]["gravity"]
    return (
        [float(v) for v in pf.position],
        np.asarray(pf.rotation, dtype=float).tolist(),
        [float(v) for v in force],
        [float(v) for v in moment],
        float(pf.mass),
        [float(v) for v in pf.com_offset],
        list(gravity),
    )
