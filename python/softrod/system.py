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

import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from . import _core
from . import _validate as V
from .catalog import load_design
from .constraints import orientation as _orientation
from .design import Design
from .errors import ConvergenceError, DesignError, InputError
from .solution import StaticSolution
from .statics import SolverOptions, _options, _policy, _pressures, _tensions

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

_SCHEMA = {
    "": {"units", "system", "platform", "rods"},
    "system": {"name", "citation", "description"},
    "platform": {"position", "orientation", "mass", "com_offset", "force", "moment"},
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


@dataclass(frozen=True)
class SystemRod:
    """One rod of a system: its design (with its own mounting: the base pose) and where its
    tip holds the platform: ``attachment`` (m) and ``attachment_rotation`` (its tip frame),
    both in the platform frame."""

    design: Design
    attachment: np.ndarray
    attachment_rotation: np.ndarray = field(default_factory=lambda: np.eye(3))


@dataclass(frozen=True)
class Platform:
    """The rigid platform (SI): nominal pose (world; continuation starts there), external
    force (world) and moment (about its origin, world), mass and centre of mass (platform
    frame)."""

    position: np.ndarray
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    force: np.ndarray = field(default_factory=lambda: np.zeros(3))
    moment: np.ndarray = field(default_factory=lambda: np.zeros(3))
    mass: float = 0.0
    com_offset: np.ndarray = field(default_factory=lambda: np.zeros(3))


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


@dataclass(frozen=True)
class SystemSolution:
    """A system's equilibrium: each rod's :class:`StaticSolution` (with the wrench the
    platform applies to its tip in ``tip_reaction_force`` / ``tip_reaction_moment``) and
    the platform's pose. ``stable`` is None: not assessed for constrained ends."""

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
    path = Path(source)
    if not path.exists() and path.suffix == "" and (systems_dir() / f"{source}.toml").exists():
        path = systems_dir() / f"{source}.toml"
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise V.fail("system", str(source),
                     f"no such file or bundled system ({', '.join(bundled_systems())})",
                     DesignError) from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise V.fail("system", str(source), f"cannot be read as TOML: {exc}", DesignError) from None
    doc = _keys(doc, "", "")
    meta = _keys(doc.get("system", {}), "system", "system")
    name = V.text(meta.get("name", path.stem), "system.name", DesignError, non_empty=True)
    pf = _keys(doc.get("platform"), "platform", "platform") if "platform" in doc else None
    if pf is None or "position" not in pf:
        raise V.fail("platform.position", "(missing)",
                     "the platform's nominal position is required (3 lengths, world frame)",
                     DesignError)
    platform = Platform(
        position=_vec(pf["position"], "length", "platform.position"),
        rotation=(_orientation(pf["orientation"], "platform.orientation", DesignError)
                  if "orientation" in pf else np.eye(3)),
        force=_vec(pf.get("force"), "force", "platform.force"),
        moment=_vec(pf.get("moment"), "moment", "platform.moment"),
        mass=V.quantity(pf.get("mass", 0.0), "mass", "platform.mass", DesignError),
        com_offset=_vec(pf.get("com_offset"), "length", "platform.com_offset"),
    )
    if platform.mass < 0:
        raise V.fail("platform.mass", pf["mass"], "must be >= 0", DesignError)
    rods_doc = doc.get("rods")
    if not isinstance(rods_doc, list) or not rods_doc:
        raise V.fail("rods", rods_doc, "must be a non-empty array of tables ([[rods]])",
                     DesignError)
    if len(rods_doc) > 64:
        raise V.fail("rods", f"{len(rods_doc)} rods", "a system has at most 64 rods",
                     DesignError)
    rods = []
    for i, r in enumerate(rods_doc):
        where = f"rods[{i}]"
        r = _keys(r, "rod", where)
        if "design" not in r or "attachment" not in r:
            missing = "design" if "design" not in r else "attachment"
            raise V.fail(f"{where}.{missing}", "(missing)", "is required", DesignError)
        given = r["design"]
        if not isinstance(given, str) or not given:
            raise V.fail(f"{where}.design", given, "must be a design file or bundled name",
                         DesignError)
        local = path.parent / given
        design = load_design(local if local.exists() else given)
        if "base_position" in r:
            design = design.replace({"mounting.base_position": r["base_position"]})
        rods.append(
            SystemRod(
                design=design,
                attachment=_vec(r["attachment"], "length", f"{where}.attachment"),
                attachment_rotation=(
                    _orientation(r["attachment_orientation"],
                                 f"{where}.attachment_orientation", DesignError)
                    if "attachment_orientation" in r else np.eye(3)
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
    check: bool = True,
    on_invalid: str = "raise",
) -> SystemSolution:
    """Static equilibrium of a :class:`System` (or a system file / bundled name).

    pressures: one list of gauge pressures (Pa or strings with units) per rod, None: all
    zero; tensions likewise (None: slack). platform_force (N, world) and platform_moment
    (N m, about the platform origin, world) replace the system's platform load when given;
    the platform's weight always acts (gravity of the first rod's design). Each rod's own
    tip body and tip loads act on its tip. ``initial`` warm-starts from a previous
    solution. On non-convergence raises :class:`ConvergenceError`, or with ``check=False``
    returns a solution with ``converged=False`` and NaN platform pose. Every rod passes the
    validity checks of :func:`solve_statics` (``on_invalid`` as there); stability is not
    assessed (``stable`` None).
    """
    if not isinstance(system, System):
        system = load_system(system)
    on_invalid = _policy("on_invalid", on_invalid)
    V.boolean(check, "check")
    n = len(system.rods)
    opts = _options(options)

    def per_rod(value, name):
        if value is None:
            return [None] * n
        if not isinstance(value, (list, tuple)) or len(value) != n:
            raise V.fail(name, value, f"must be a list of {n} entries, one per rod", InputError)
        return list(value)

    ps = per_rod(pressures, "pressures")
    ts = per_rod(tensions, "tensions")
    entries = []
    for i, (rod, p, t) in enumerate(zip(system.rods, ps, ts, strict=True)):
        d = rod.design
        if d.tip_constraint is not None:
            raise V.fail(f"rods[{i}].design", d.name,
                         "its [tip] constraint is set; a system's rod tips hold the platform",
                         InputError)
        pv = [0.0] * d.n_channels if p is None else _pressures(d, p)
        tip = d.spec["tip"]
        entries.append((d._rod, pv, _tensions(d, t), list(tip["force"]), list(tip["moment"]),
                        [float(v) for v in rod.attachment],
                        np.asarray(rod.attachment_rotation, dtype=float).tolist()))
    pf = system.platform
    force = pf.force if platform_force is None else _load3(platform_force, "force",
                                                            "platform_force")
    moment = pf.moment if platform_moment is None else _load3(platform_moment, "moment",
                                                               "platform_moment")
    gravity = system.rods[0].design.spec["mounting"]["gravity"]
    platform = (
        [float(v) for v in pf.position],
        np.asarray(pf.rotation, dtype=float).tolist(),
        [float(v) for v in force],
        [float(v) for v in moment],
        float(pf.mass),
        [float(v) for v in pf.com_offset],
        list(gravity),
    )
    guess = None
    if initial is not None:
        if not isinstance(initial, SystemSolution):
            raise V.fail("initial", type(initial).__name__, "must be a SystemSolution or None")
        if initial.converged:
            guess = initial.unknowns.tolist()
    try:
        out = _core.solve_rod_system(entries, platform, guess=guess, on_invalid=on_invalid,
                                     **opts.as_kwargs())
    except ConvergenceError as exc:
        if check:
            raise
        nan3 = np.full(3, np.nan)
        return SystemSolution(system=system, rods=(), platform_position=nan3,
                              platform_rotation=np.full((3, 3), np.nan), converged=False,
                              iterations=exc.iterations, residual=exc.residual, load_steps=0,
                              unknowns=np.full(6 * n + 6, np.nan))
    sols = []
    for (rod, entry, o) in zip(system.rods, entries, out["rods"], strict=True):
        sols.append(
            StaticSolution(
                design=rod.design, pressures=np.array(entry[1]), s=o["s"], section=o["section"],
                position=o["position"], rotation=o["rotation"], force=o["force"],
                moment=o["moment"], v=o["v"], u=o["u"], converged=True,
                iterations=o["iterations"], residual=o["residual"], load_steps=o["load_steps"],
                shooting_unknowns=np.array(o["x"]), stable=None,
                violations=tuple(o["violations"]), tip_loads=(tuple(entry[3]), tuple(entry[4])),
                tensions=np.array(entry[2]), tip_constraint="clamped",
                tip_reaction_force=np.array(o["tip_reaction_force"]),
                tip_reaction_moment=np.array(o["tip_reaction_moment"]),
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
    )


def _load3(value, kind: str, name: str) -> np.ndarray:
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise V.fail(name, value, f"must be 3 {kind} values (world frame)", InputError)
    return np.array([V.quantity(v, kind, f"{name}[{i}]", InputError)
                     for i, v in enumerate(value)])
