"""Design files: TOML with units -> validated, SI ``Design`` backed by the Rust core.

The schema is documented in docs/design-format.md. Unknown keys are errors. Every
dimensional quantity needs its unit (``"110 mm"``); a bare number is an error naming the
field, unless the document starts with ``units = "SI"`` (zero needs no unit). Geometry rules
(chambers inside the section, no overlaps, Poisson ratio range, ...) are checked by the Rust
core so that Rust users get them too; this module checks types, structure, sizes and units
(through :mod:`softrod._validate`), so the core only ever sees a well-formed spec.
"""

from __future__ import annotations

import copy
import json
import math
import os
import re
import sys
from collections.abc import Mapping
from contextvars import ContextVar
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from . import _core
from . import _validate as V
from ._frozen import freeze, thaw
from .constraints import from_tip_table
from .errors import DesignError, InputError, design_error
from .io import as_path

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

PACKAGE_DIR = Path(__file__).resolve().parent
DEFAULT_STEPS = 16
MAX_FILE_BYTES = 16 * 2**20  # design files larger than this are refused before reading

# What a bare number means while a document is read: "si" with units = "SI", else an error
# (whose message suggests the fix). Set by _to_spec for the document being read.
_BARE: ContextVar[str] = ContextVar("softrod_design_bare", default="si")
_BARE_FIX = '(or put units = "SI" at the top of the file to read bare numbers as SI)'
# The folder a design file's relative paths start from (mesh files), and the mesh files
# read for the document being built (obstacle index -> resolved path). Set by _build.
_FOLDER: ContextVar[Path | None] = ContextVar("softrod_design_folder", default=None)
_MESH_FILES: ContextVar[dict | None] = ContextVar("softrod_mesh_files", default=None)

_SCHEMA: dict[str, set[str]] = {
    "": {
        "units",
        "design",
        "mounting",
        "materials",
        "sections",
        "tip",
        "loads",
        "numerics",
        "dynamics",
        "pcc",
        "stiffness_map",
        "operating_range",
        "obstacles",
    },
    "operating_range": {"pressure", "tension", "source"},
    "obstacle": {
        "kind",
        "point",
        "normal",
        "center",
        "axis",
        "start",
        "end",
        "radius",
        "stiffness",
        "tolerance",
        "smoothing",
        "friction",
        "slip_velocity",
        "file",
        "vertices",
        "faces",
        "units",
        "position",
        "rotation",
    },
    "design": {"name", "citation", "description", "assumptions", "provenance"},
    "stiffness_map": {"file", "method", "outside"},
    "mounting": {"orientation", "roll", "base_position", "gravity", "base_rotation"},
    "material": {"E", "poisson", "G", "density", "source", "notes"},
    "section": {
        "name",
        "length",
        "material",
        "outer_radius",
        "bore_radius",
        "rigid",
        "mass",
        "c_s",
        "c_e",
        "c_b",
        "c_t",
        "EA",
        "GA",
        "EI",
        "EI1",
        "EI2",
        "GJ",
        "chambers",
        "steps",
        "law",
        "partition",
        "rotary_inertia",
        "damping_se",
        "damping_bt",
        "curvature",
        "u_star",
        "bend_radius",
        "bend_direction",
        "v_star",
        "reference_table",
        "outer_radius_end",
        "tendons",
    },
    "reference_table": {"s", "curvature", "v_star"},
    "tendon": {"channel", "distance", "angle", "distance_end", "angle_end"},
    "law": {
        "axial",
        "alpha",
        "axial_force",
        "axial_stiffness",
        "chamber_offset",
        "c_p",
        "p_ref",
        "stretch_bending",
        "stiffness_map",
    },
    "partition": {"j", "E_I", "r_I", "E_II", "r_II", "E_III"},
    "chamber": {"radius", "area", "distance", "angle", "channel", "distance_end", "radius_end"},
    "tip": {
        "mass",
        "com_offset",
        "force",
        "moment",
        "inertia",
        "frame",
        "constraint",
        "position",
        "orientation",
    },
    "dynamics": {"damping_time", "pressure_time_constant", "pressure_rate_limit"},
    "load": {"section", "force_per_length", "moment_per_length", "frame"},
    "pcc": {
        "k_L",
        "b_L",
        "k_theta",
        "b_theta",
        "k_phi",
        "b_phi",
        "mass_model",
        "pressure_force",
        "plane",
        "quadrature",
    },
    "pcc_table": {"angle", "stiffness"},
    "numerics": {"steps_per_section", "step_length"},
}

_ORIENTATIONS = {
    # Columns are d1, d2, d3 in world coordinates (rows of the matrix below are world axes).
    "upright": np.eye(3),
    "hanging": np.diag([1.0, -1.0, -1.0]),
    "horizontal": np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]]),
}


def designs_dir() -> Path:
    """Folder of the bundled design files."""
    return PACKAGE_DIR / "designs"


def _q(value: Any, kind: str, field: str) -> float:
    """A quantity of the document being read (bare numbers as its ``units`` key says)."""
    return V.quantity(value, kind, field, DesignError, bare=_BARE.get())


def _qvec(value: Any, kind: str, field: str, length: int | None = 3) -> list[float]:
    """A list of quantities: ``length`` of them, or up to MAX_TABLE_POINTS if None."""
    if not isinstance(value, (list, tuple)) or (length is not None and len(value) != length):
        count = "" if length is None else f"{length} "
        raise V.fail(field, value, f"must be a list of {count}{kind} values", DesignError)
    if len(value) > V.MAX_TABLE_POINTS:
        rule = f"has too many values: at most {V.MAX_TABLE_POINTS}"
        raise V.fail(field, value, rule, DesignError)
    return [_q(v, kind, f"{field}[{i}]") for i, v in enumerate(value)]


def number(value: Any, field: str) -> float:
    """A dimensionless finite number of a design (a factor, an exponent)."""
    return V.real(value, field, DesignError)


def _check_keys(table: Any, kind: str, where: str) -> dict:
    if not isinstance(table, Mapping):
        raise design_error(where or "design", type(table).__name__, "must be a table")
    allowed = _SCHEMA[kind]
    unknown = sorted((k for k in table if not isinstance(k, str) or k not in allowed), key=str)
    if unknown:
        key = unknown[0]
        name = key if isinstance(key, str) and key.isidentifier() else repr(key)
        raise V.fail(
            f"{where}.{name}" if where else name,
            table[unknown[0]],
            f"unknown key (allowed here: {', '.join(sorted(allowed))})",
            DesignError,
        )
    return dict(table)


def _require(table: Mapping, key: str, where: str) -> Any:
    if key not in table:
        raise design_error(f"{where}.{key}" if where else key, "missing", "is required")
    return table[key]


def _integer(value: Any, field: str, minimum: int, maximum: int | None = None) -> int:
    return V.integer(value, field, DesignError, minimum=minimum, maximum=maximum)


def _library() -> dict:
    with open(PACKAGE_DIR / "data" / "materials.toml", "rb") as fh:
        return tomllib.load(fh)


def _positive(value: float, raw: Any, field: str) -> float:
    if not value > 0:
        raise V.fail(field, raw, "must be > 0", DesignError)
    return value


def _material(name: str, inline: Mapping, field: str) -> dict:
    """The SI material ``name`` (inline first, then the library); errors name the entry of
    the table the value came from (``materials.<name>.E``), not the section using it."""
    if name in inline:
        table, where = inline[name], f"materials.{name}"
    else:
        lib = _library()
        if name not in lib:
            known = ", ".join(sorted(set(map(str, inline)) | set(lib)))
            raise V.fail(field, name, f"unknown material (known: {known})", DesignError)
        table, where = lib[name], f"library material {name}"
    table = _check_keys(table, "material", where)
    for key in ("source", "notes"):
        if key in table:
            V.text(table[key], f"{where}.{key}", DesignError, max_length=V.MAX_TEXT_LENGTH)
    raw_e = _require(table, "E", where)
    e = _positive(_q(raw_e, "pressure", f"{where}.E"), raw_e, f"{where}.E")
    if "G" in table and "poisson" in table:
        raise design_error(f"{where}.G", table["G"], "give either G or poisson, not both")
    if "G" in table:
        g = _positive(_q(table["G"], "pressure", f"{where}.G"), table["G"], f"{where}.G")
        nu = e / (2.0 * g) - 1.0
        if not -1.0 < nu <= 0.5 + 1e-12:
            raise V.fail(
                f"{where}.G",
                table["G"],
                f"gives Poisson's ratio E/(2G) - 1 = {nu:.4g}, which must lie in (-1, 0.5]",
                DesignError,
            )
    else:
        nu = number(_require(table, "poisson", where), f"{where}.poisson")
        if not -1.0 < nu <= 0.5:
            raise design_error(f"{where}.poisson", nu, "Poisson's ratio must lie in (-1, 0.5]")
        g = e / (2.0 * (1.0 + nu))
    raw_rho = _require(table, "density", where)
    rho = _positive(_q(raw_rho, "density", f"{where}.density"), raw_rho, f"{where}.density")
    return {"youngs_modulus": e, "shear_modulus": g, "density": rho}


def _base_rotation(mount: Mapping) -> list[list[float]]:
    if "base_rotation" in mount:
        if "orientation" in mount or "roll" in mount:
            raise design_error(
                "mounting.base_rotation",
                mount["base_rotation"],
                "give either base_rotation or orientation/roll, not both",
            )
        rot = mount["base_rotation"]
        if not (
            isinstance(rot, (list, tuple))
            and len(rot) == 3
            and all(isinstance(r, (list, tuple)) and len(r) == 3 for r in rot)
        ):
            raise V.fail(
                "mounting.base_rotation", rot, "must be a 3x3 matrix (list of rows)", DesignError
            )
        return [
            [number(x, f"mounting.base_rotation[{i}][{j}]") for j, x in enumerate(r)]
            for i, r in enumerate(rot)
        ]
    if "orientation" not in mount:
        # No silent default: a hanging actuator mounted upright is a wrong answer, not a
        # convenience. The file must say which way the rod points.
        raise design_error(
            "mounting.orientation",
            "missing",
            "is required: the mounting decides where gravity acts; write [mounting] "
            'orientation = "hanging", "upright" or "horizontal" (or give base_rotation)',
        )
    orientation = V.choice(
        mount["orientation"], sorted(_ORIENTATIONS), "mounting.orientation", DesignError
    )
    roll = _q(mount.get("roll", 0.0), "angle", "mounting.roll")
    c, s = math.cos(roll), math.sin(roll)
    rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return (_ORIENTATIONS[orientation] @ rz).tolist()


def _section(sec: Any, i: int, materials: Mapping, numerics: tuple[str, float]) -> dict:
    where = f"sections[{i}]"
    sec = _check_keys(sec, "section", where)
    name = V.text(_require(sec, "name", where), f"{where}.name", DesignError, non_empty=True)
    length = _q(_require(sec, "length", where), "length", f"{where}.length")
    mode, value = numerics
    if "steps" in sec:
        steps = _integer(sec["steps"], f"{where}.steps", 1, V.MAX_SECTION_STEPS)
    elif mode == "step_length" and math.isfinite(length) and length > 0:
        # Steps of at most step_length (a tiny relative slack keeps 110 mm / 11 mm at 10).
        ratio = length / value * (1.0 - 1e-12)
        if ratio > V.MAX_SECTION_STEPS:
            raise V.fail(
                "numerics.step_length",
                f"{value:g} m",
                f"gives {where} ({length:g} m) {ratio:.3g} steps; the limit is "
                f"{V.MAX_SECTION_STEPS} per section",
                DesignError,
            )
        steps = max(1, math.ceil(ratio))
    else:
        steps = int(value)
    rigid = V.boolean(sec.get("rigid", False), f"{where}.rigid", DesignError)
    out: dict[str, Any] = {
        "name": name,
        "length": length,
        "rigid": rigid,
        "bore_radius": _q(sec.get("bore_radius", 0.0), "length", f"{where}.bore_radius"),
        "steps": steps,
    }
    if "outer_radius" in sec:
        out["outer_radius"] = _q(sec["outer_radius"], "length", f"{where}.outer_radius")
    if "material" in sec:
        material = V.text(sec["material"], f"{where}.material", DesignError, non_empty=True)
        out["material"] = _material(material, materials, f"{where}.material")
    if "mass" in sec:
        out["mass"] = _q(sec["mass"], "mass", f"{where}.mass")
    for k in ("c_s", "c_e", "c_b", "c_t"):
        if k in sec:
            out[k] = number(sec[k], f"{where}.{k}")
    stiff: dict[str, float] = {}
    if "EA" in sec:
        stiff["ea"] = _q(sec["EA"], "force", f"{where}.EA")
    if "GA" in sec:
        stiff["ga"] = _q(sec["GA"], "force", f"{where}.GA")
    if "EI" in sec:
        if "EI1" in sec or "EI2" in sec:
            raise design_error(f"{where}.EI", sec["EI"], "give EI or EI1/EI2, not both")
        stiff["ei1"] = stiff["ei2"] = _q(sec["EI"], "stiffness_bending", f"{where}.EI")
    for k in ("EI1", "EI2", "GJ"):
        if k in sec:
            stiff[k.lower()] = _q(sec[k], "stiffness_bending", f"{where}.{k}")
    out["stiffness"] = stiff
    if "law" in sec:
        out["law"] = _law(sec["law"], f"{where}.law")
    if "partition" in sec:
        out["partition"] = _partition(sec["partition"], f"{where}.partition")
    for key, kind in (
        ("rotary_inertia", "inertia_per_length"),
        ("damping_se", "damping_force"),
        ("damping_bt", "damping_moment"),
    ):
        if key in sec:
            out[key] = _qvec(sec[key], kind, f"{where}.{key}")
    chambers = sec.get("chambers", [])
    if not isinstance(chambers, list):
        raise V.fail(f"{where}.chambers", chambers, "must be an array of tables", DesignError)
    if len(chambers) > V.MAX_CHAMBERS:
        raise V.fail(
            f"{where}.chambers",
            f"{len(chambers)} chambers",
            f"too many: at most {V.MAX_CHAMBERS} per section",
            DesignError,
        )
    out["chambers"] = [_chamber(c, f"{where}.chambers[{k}]") for k, c in enumerate(chambers)]
    if "outer_radius_end" in sec:
        out["outer_radius_end"] = _q(sec["outer_radius_end"], "length", f"{where}.outer_radius_end")
    reference = _reference(sec, where, length)
    if reference is not None:
        out["reference"] = reference
    tendons = sec.get("tendons", [])
    if not isinstance(tendons, list):
        raise V.fail(f"{where}.tendons", tendons, "must be an array of tables", DesignError)
    if len(tendons) > V.MAX_TENDONS:
        raise V.fail(
            f"{where}.tendons",
            f"{len(tendons)} tendons",
            f"too many: at most {V.MAX_TENDONS} per section",
            DesignError,
        )
    if tendons:
        out["tendons"] = [_tendon(t, f"{where}.tendons[{k}]") for k, t in enumerate(tendons)]
    return out


def _reference(sec: Mapping, where: str, length: float) -> dict | None:
    """The section's reference (stress-free) shape, docs/scope.md: precurvature u* as
    ``curvature`` (alias ``u_star``, 1/m about d1, d2 and twist) or ``bend_radius`` with
    ``bend_direction``, pre-strain ``v_star``, or both tabulated along s in
    ``reference_table``. None for the straight rod."""
    given = [k for k in ("curvature", "u_star", "bend_radius") if k in sec]
    if len(given) > 1:
        raise design_error(
            f"{where}.{given[1]}",
            sec[given[1]],
            f"give one of curvature, u_star or bend_radius, not {given[0]} and {given[1]}",
        )
    if "bend_direction" in sec and "bend_radius" not in sec:
        raise design_error(f"{where}.bend_direction", sec["bend_direction"], "needs bend_radius")
    out: dict[str, Any] = {}
    if given and given[0] in ("curvature", "u_star"):
        out["curvature"] = _qvec(sec[given[0]], "curvature", f"{where}.{given[0]}")
    elif given:
        radius = _q(sec["bend_radius"], "length", f"{where}.bend_radius")
        if not (math.isfinite(radius) and radius > 0):
            raise design_error(f"{where}.bend_radius", sec["bend_radius"], "must be > 0")
        phi = _q(sec.get("bend_direction", 0.0), "angle", f"{where}.bend_direction")
        # Bends towards (cos phi, sin phi) in (d1, d2): d3' = u x d3 = (u2, -u1, 0).
        out["curvature"] = [-math.sin(phi) / radius, math.cos(phi) / radius, 0.0]
    if "v_star" in sec:
        v_star = _list3(sec["v_star"], f"{where}.v_star")
        out["strain"] = [number(v, f"{where}.v_star[{k}]") for k, v in enumerate(v_star)]
    if "reference_table" in sec:
        if out:
            raise design_error(
                f"{where}.reference_table",
                "a table",
                "give the reference shape as constants or as a table, not both",
            )
        tab = _check_keys(sec["reference_table"], "reference_table", f"{where}.reference_table")
        w = f"{where}.reference_table"
        s = _qvec(_require(tab, "s", w), "length", f"{w}.s", length=None)
        n = len(s)
        if n < 2:
            raise V.fail(f"{w}.s", tab["s"], "needs at least 2 points", DesignError)

        def rows(key: str, kind: str | None, default: list[float]) -> list[list[float]]:
            raw = tab.get(key)
            if raw is None:
                return [list(default) for _ in range(n)]
            if not isinstance(raw, list) or len(raw) != n:
                rule = f"must be a list of {n} rows (one per s)"
                raise V.fail(f"{w}.{key}", raw, rule, DesignError)
            if kind is None:
                return [
                    [
                        number(v, f"{w}.{key}[{i}][{k}]")
                        for k, v in enumerate(_list3(r, f"{w}.{key}[{i}]"))
                    ]
                    for i, r in enumerate(raw)
                ]
            return [_qvec(r, kind, f"{w}.{key}[{i}]") for i, r in enumerate(raw)]

        if "curvature" not in tab and "v_star" not in tab:
            raise design_error(w, "a table", "needs curvature or v_star rows")
        out["table"] = {
            "s": s,
            "curvature": rows("curvature", "curvature", [0.0, 0.0, 0.0]),
            "strain": rows("v_star", None, [0.0, 0.0, 1.0]),
        }
    return out or None


def _list3(value: Any, field: str) -> list:
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise V.fail(field, value, "must be a list of 3 values", DesignError)
    return list(value)


def _tendon(t: Any, where: str) -> dict:
    """A ``[[sections.tendons]]`` entry: its tension channel and its routing (offset
    distance and angle in the cross-section, linear along the section to ``*_end``)."""
    t = _check_keys(t, "tendon", where)
    out: dict[str, Any] = {
        "channel": V.integer(
            _require(t, "channel", where),
            f"{where}.channel",
            DesignError,
            minimum=0,
            maximum=V.MAX_CHANNELS - 1,
            hint=f" (softrod supports {V.MAX_CHANNELS} tendon channels, numbered from 0)",
        ),
        "distance": _q(_require(t, "distance", where), "length", f"{where}.distance"),
        "angle": _q(t.get("angle", 0.0), "angle", f"{where}.angle"),
    }
    if "distance_end" in t:
        out["distance_end"] = _q(t["distance_end"], "length", f"{where}.distance_end")
    if "angle_end" in t:
        out["angle_end"] = _q(t["angle_end"], "angle", f"{where}.angle_end")
    return out


_FRAMES = ("world", "body")


def _frame(table: Mapping, where: str) -> str:
    return V.choice(table.get("frame", "world"), _FRAMES, f"{where}.frame", DesignError)


_AXIAL_LAWS = ("linear", "ogden", "table")


def _law(law: Any, where: str) -> dict:
    """[sections.law]: the refinements of the linear law (docs/laws.md)."""
    law = _check_keys(law, "law", where)
    kind = V.choice(law.get("axial", "linear"), _AXIAL_LAWS, f"{where}.axial", DesignError)
    out: dict[str, Any] = {}
    if kind == "ogden":
        out["axial"] = {
            "kind": "ogden",
            "alpha": number(_require(law, "alpha", where), f"{where}.alpha"),
        }
    elif "alpha" in law:
        raise design_error(f"{where}.alpha", law["alpha"], 'is only used with axial = "ogden"')
    if kind == "table":
        force = _require(law, "axial_force", where)
        stiff = _require(law, "axial_stiffness", where)
        for key, value in (("axial_force", force), ("axial_stiffness", stiff)):
            if not isinstance(value, list):
                raise V.fail(f"{where}.{key}", value, "must be an array of forces", DesignError)
        out["axial"] = {
            "kind": "table",
            "force": _qvec(force, "force", f"{where}.axial_force", length=None),
            "stiffness": _qvec(stiff, "force", f"{where}.axial_stiffness", length=None),
        }
    else:
        for key in ("axial_force", "axial_stiffness"):
            if key in law:
                raise design_error(f"{where}.{key}", law[key], 'is only used with axial = "table"')
    if kind == "linear":
        out["axial"] = {"kind": "linear"}
    if "chamber_offset" in law:
        out["chamber_offset"] = _qvec(
            law["chamber_offset"], "length", f"{where}.chamber_offset", length=2
        )
    if "c_p" in law or "p_ref" in law:
        out["swelling"] = {
            "c_p": number(_require(law, "c_p", where), f"{where}.c_p"),
            "p_ref": _q(_require(law, "p_ref", where), "pressure", f"{where}.p_ref"),
        }
    for key in ("stretch_bending", "stiffness_map"):
        if key in law:
            out[key] = V.boolean(law[key], f"{where}.{key}", DesignError)
    return out


def _partition(part: Any, where: str) -> dict:
    """[sections.partition]: paper 004's partitioned cross-section (eqs. 13-15, 23, 29)."""
    part = _check_keys(part, "partition", where)
    return {
        "j": _integer(_require(part, "j", where), f"{where}.j", 1, V.MAX_CHAMBERS),
        "e_i": _q(_require(part, "E_I", where), "force", f"{where}.E_I"),
        "r_i": _q(_require(part, "r_I", where), "length", f"{where}.r_I"),
        "e_ii": _q(part.get("E_II", 0.0), "force", f"{where}.E_II"),
        "r_ii": _q(part.get("r_II", 0.0), "length", f"{where}.r_II"),
        "e_iii": _q(part.get("E_III", 0.0), "force", f"{where}.E_III"),
    }


def _chamber(ch: Any, where: str) -> dict:
    ch = _check_keys(ch, "chamber", where)
    radius = _q(ch["radius"], "length", f"{where}.radius") if "radius" in ch else None
    if "area" in ch:
        area = _q(ch["area"], "area", f"{where}.area")
    elif radius is not None:
        area = math.pi * radius * radius  # (** raises OverflowError on a huge radius)
        if not math.isfinite(area):
            raise design_error(
                f"{where}.radius", ch["radius"], "must give a finite area pi r^2 (m^2)"
            )
    else:
        raise design_error(f"{where}.radius", "missing", "give radius or area")
    taper = {
        key: _q(ch[key], "length", f"{where}.{key}")
        for key in ("distance_end", "radius_end")
        if key in ch
    }
    return {
        **taper,
        "area": area,
        "radius": radius,
        "distance": _q(_require(ch, "distance", where), "length", f"{where}.distance"),
        "angle": _q(_require(ch, "angle", where), "angle", f"{where}.angle"),
        "channel": V.integer(
            _require(ch, "channel", where),
            f"{where}.channel",
            DesignError,
            minimum=0,
            maximum=V.MAX_CHANNELS - 1,
            hint=f" (softrod supports {V.MAX_CHANNELS} pressure channels, numbered from 0)",
        ),
    }


def _numerics(numerics: Mapping) -> tuple[str, float]:
    """The discretisation rule: ("steps_per_section", n) or ("step_length", h in m)."""
    if "steps_per_section" in numerics and "step_length" in numerics:
        raise design_error(
            "numerics.step_length",
            numerics["step_length"],
            "give steps_per_section or step_length, not both",
        )
    if "step_length" in numerics:
        h = _q(numerics["step_length"], "length", "numerics.step_length")
        if not (math.isfinite(h) and h > 0):
            raise design_error("numerics.step_length", numerics["step_length"], "must be > 0")
        return ("step_length", h)
    n = numerics.get("steps_per_section", DEFAULT_STEPS)
    return (
        "steps_per_section",
        _integer(n, "numerics.steps_per_section", 1, V.MAX_SECTION_STEPS),
    )


def _to_spec(doc: Mapping) -> dict:
    """Types, structure, sizes and units: a design document -> SI spec for the Rust core."""
    doc = _check_keys(doc, "", "")
    units = doc.get("units")
    if units is not None and units != "SI":
        raise V.fail(
            "units",
            units,
            'must be "SI" (bare numbers are then SI: m, kg, s, N, Pa, rad), or left out (every '
            'dimensional quantity then carries its unit, e.g. "110 mm")',
            DesignError,
        )
    token = _BARE.set("si" if units == "SI" else _BARE_FIX)
    try:
        return _spec(doc)
    finally:
        _BARE.reset(token)


def _spec(doc: dict) -> dict:
    meta = _check_keys(_require(doc, "design", ""), "design", "design")
    V.text(_require(meta, "name", "design"), "design.name", DesignError, non_empty=True)
    V.text(
        _require(meta, "citation", "design"),
        "design.citation",
        DesignError,
        max_length=V.MAX_TEXT_LENGTH,
        non_empty=True,
    )
    if "description" in meta:
        V.text(meta["description"], "design.description", DesignError, max_length=V.MAX_TEXT_LENGTH)
    assumptions = meta.get("assumptions", [])
    if not isinstance(assumptions, list) or len(assumptions) > V.MAX_TABLE_POINTS:
        raise V.fail("design.assumptions", assumptions, "must be a list of strings", DesignError)
    for k, a in enumerate(assumptions):
        V.text(a, f"design.assumptions[{k}]", DesignError, max_length=V.MAX_TEXT_LENGTH)
    mount = _check_keys(doc.get("mounting", {}), "mounting", "mounting")
    numerics = _check_keys(doc.get("numerics", {}), "numerics", "numerics")
    steps = _numerics(numerics)
    materials = doc.get("materials", {})
    if not isinstance(materials, Mapping):
        raise V.fail("materials", materials, "must be a table of materials", DesignError)
    sections = _require(doc, "sections", "")
    if not isinstance(sections, list) or not sections:
        raise V.fail("sections", sections, "must be a non-empty array of tables", DesignError)
    if len(sections) > V.MAX_SECTIONS:
        raise V.fail(
            "sections",
            f"{len(sections)} sections",
            f"too many: at most {V.MAX_SECTIONS}",
            DesignError,
        )
    secs = [_section(s, i, materials, steps) for i, s in enumerate(sections)]
    total = sum(s["steps"] for s in secs)
    if total > V.MAX_DESIGN_STEPS:
        raise V.fail(
            "numerics",
            f"{total} steps in all",
            f"the sections' integration steps add up to more than {V.MAX_DESIGN_STEPS}; use "
            "fewer steps per section or a longer step_length",
            DesignError,
        )
    _check_channels(secs)
    _check_channels(secs, "tendons", "tendon")
    names = [s["name"] for s in secs]
    tip = _check_keys(doc.get("tip", {}), "tip", "tip")
    loads = doc.get("loads", [])
    if not isinstance(loads, list):
        raise V.fail("loads", loads, "must be an array of tables", DesignError)
    if len(loads) > V.MAX_LOADS:
        rule = f"too many: at most {V.MAX_LOADS}"
        raise V.fail("loads", f"{len(loads)} loads", rule, DesignError)
    load_specs = []
    for k, ld in enumerate(loads):
        ld = _check_keys(ld, "load", f"loads[{k}]")
        sec_name = _require(ld, "section", f"loads[{k}]")
        if not isinstance(sec_name, str) or sec_name not in names:
            raise V.fail(
                f"loads[{k}].section",
                sec_name,
                f"must name a section ({', '.join(names)})",
                DesignError,
            )
        load_specs.append(
            {
                "section": names.index(sec_name),
                "force_per_length": _qvec(
                    ld.get("force_per_length", [0, 0, 0]),
                    "force_per_length",
                    f"loads[{k}].force_per_length",
                ),
                "moment_per_length": _qvec(
                    ld.get("moment_per_length", [0, 0, 0]), "force", f"loads[{k}].moment_per_length"
                ),
                "frame": _frame(ld, f"loads[{k}]"),
            }
        )
    g = _q(mount.get("gravity", "9.81 m/s^2"), "acceleration", "mounting.gravity")
    if g < 0:
        raise design_error(
            "mounting.gravity",
            mount["gravity"],
            "is a magnitude (>= 0); gravity always points along -z of the world",
        )
    return {
        "name": meta["name"],
        "mounting": {
            "base_position": _qvec(
                mount.get("base_position", [0, 0, 0]), "length", "mounting.base_position"
            ),
            "base_rotation": _base_rotation(mount),
            "gravity": [0.0, 0.0, -g],
        },
        "sections": secs,
        "tip": {
            "mass": _q(tip.get("mass", 0.0), "mass", "tip.mass"),
            "com_offset": _qvec(tip.get("com_offset", [0, 0, 0]), "length", "tip.com_offset"),
            "force": _qvec(tip.get("force", [0, 0, 0]), "force", "tip.force"),
            "moment": _qvec(tip.get("moment", [0, 0, 0]), "moment", "tip.moment"),
            "inertia": _qvec(tip.get("inertia", [0, 0, 0]), "inertia", "tip.inertia"),
            "frame": _frame(tip, "tip"),
        },
        "loads": load_specs,
        # Popped by _build before the spec goes to the core (the constraint is a solve's
        # boundary condition, kept on the Design).
        "tip_constraint": from_tip_table(tip, _q, _qvec),
        "dynamics": _dynamics(_check_keys(doc.get("dynamics", {}), "dynamics", "dynamics")),
        **({"pcc": _pcc(_check_keys(doc["pcc"], "pcc", "pcc"))} if "pcc" in doc else {}),
        **(
            {"operating_range": _operating_range(doc["operating_range"])}
            if "operating_range" in doc
            else {}
        ),
        **({"obstacles": _obstacles(doc["obstacles"])} if "obstacles" in doc else {}),
    }


OBSTACLE_KINDS = ("plane", "sphere", "cylinder", "capsule", "mesh")
# The keys only a mesh takes (checked here: the core sees its vertices and faces in metres).
_MESH_KEYS = ("file", "vertices", "faces", "units", "position", "rotation")
# The pose and size keys of each kind (the Rust core refuses any other and checks values).
_OBSTACLE_POSE = {
    "point": "length",
    "center": "length",
    "start": "length",
    "end": "length",
    "radius": "length",
    "normal": None,
    "axis": None,
}


def _obstacles(obstacles: Any) -> list[dict]:
    """[[obstacles]]: rigid obstacles the rod may touch (docs/contact.md): kind, pose and
    size with units, penalty stiffness (force per length per penetration, e.g.
    "2e6 N/m^2"), penetration tolerance, optional smoothing length, friction
    coefficient and the friction law's regularisation velocity ``slip_velocity`` (e.g.
    "1 mm/s"; dynamics only). Rules on values (positive radius, non-zero normal, smoothing
    within the tolerance, ...) are the core's (``ObstacleSpec::validate``)."""
    if not isinstance(obstacles, list):
        raise V.fail("obstacles", obstacles, "must be an array of tables", DesignError)
    if len(obstacles) > V.MAX_OBSTACLES:
        rule = f"too many: at most {V.MAX_OBSTACLES}"
        raise V.fail("obstacles", f"{len(obstacles)} obstacles", rule, DesignError)
    out = []
    for k, ob in enumerate(obstacles):
        where = f"obstacles[{k}]"
        ob = _check_keys(ob, "obstacle", where)
        kind = V.choice(_require(ob, "kind", where), OBSTACLE_KINDS, f"{where}.kind", DesignError)
        spec: dict[str, Any] = {"kind": kind}
        if kind == "mesh":
            spec.update(_mesh(ob, k))
        else:
            for key in _MESH_KEYS:
                if key in ob:
                    raise V.fail(
                        f"{where}.{key}",
                        ob[key],
                        f'only a mesh obstacle (kind = "mesh") takes {key}',
                        DesignError,
                    )
        for key, unit in _OBSTACLE_POSE.items():
            if key not in ob:
                continue
            field = f"{where}.{key}"
            if key == "radius":
                spec[key] = _q(ob[key], "length", field)
            elif unit is None:
                if not isinstance(ob[key], (list, tuple)) or len(ob[key]) != 3:
                    raise V.fail(
                        field, ob[key], "must be a list of 3 numbers (a direction)", DesignError
                    )
                spec[key] = [number(v, f"{field}[{i}]") for i, v in enumerate(ob[key])]
            else:
                spec[key] = _qvec(ob[key], unit, field)
        spec["stiffness"] = _q(
            _require(ob, "stiffness", where), "contact_stiffness", f"{where}.stiffness"
        )
        spec["tolerance"] = _q(_require(ob, "tolerance", where), "length", f"{where}.tolerance")
        if "smoothing" in ob:
            spec["smoothing"] = _q(ob["smoothing"], "length", f"{where}.smoothing")
        if "friction" in ob:
            spec["friction"] = number(ob["friction"], f"{where}.friction")
        if "slip_velocity" in ob:
            field = f"{where}.slip_velocity"
            spec["slip_velocity"] = _q(ob["slip_velocity"], "velocity", field)
        out.append(spec)
    return out


def _plain_rows(raw: list, kind: type) -> np.ndarray | None:
    """``raw`` as an (n, 3) array when every entry is a triple of plain Python numbers of
    ``kind`` (int: ints; float: ints or floats), each within 2^53 and finite: the fast path
    of a mesh written inline (thousands of numbers); None otherwise, and the caller checks
    entry by entry to name the first bad one."""
    allowed = (int,) if kind is int else (int, float)
    if not all(
        type(row) in (list, tuple) and len(row) == 3 and all(type(x) in allowed for x in row)
        for row in raw
    ):
        return None
    try:
        a = np.array(raw, dtype=np.int64 if kind is int else float)
    except OverflowError:  # an int beyond int64
        return None
    if kind is int:
        return a if np.abs(a).max() <= V.MAX_ABS_INT else None
    ints = [x for row in raw for x in row if type(x) is int and abs(x) > V.MAX_ABS_INT]
    return a if not ints and np.isfinite(a).all() else None


def _mesh(ob: Mapping, k: int) -> dict:
    """A mesh obstacle's ``vertices`` (m, world frame) and ``faces``: from ``file`` (STL or
    OBJ, relative to the design file's folder, in the length unit ``units``: required, as
    neither format records one) or inline (``vertices`` as lengths with units, or bare
    numbers in ``units``; ``faces`` as 0-based index triples), then placed by the optional
    ``rotation`` (a 3x3 matrix) and ``position``: x_world = rotation @ x + position. The
    core checks the values (docs/contact.md, "Triangle meshes")."""
    from .mesh_io import MAX_MESH_TRIANGLES, read_mesh

    where = f"obstacles[{k}]"
    if ("file" in ob) == ("vertices" in ob):
        raise V.fail(
            where,
            sorted(ob),
            "a mesh obstacle takes either file (an STL or OBJ file) or inline vertices and faces",
            DesignError,
        )
    scale = None
    if "units" in ob:
        unit = ob["units"]
        if not isinstance(unit, str) or not unit.strip() or any(c.isdigit() for c in unit):
            raise V.fail(
                f"{where}.units",
                unit,
                'must be a length unit such as "mm" or "m" (the unit of the mesh\'s numbers)',
                DesignError,
            )
        scale = V.quantity(f"1 {unit}", "length", f"{where}.units", DesignError)
    if "file" in ob:
        given = ob["file"]
        if "faces" in ob:
            raise V.fail(
                f"{where}.faces", ob["faces"], "comes from the file: leave it out", DesignError
            )
        if not isinstance(given, str) or not given.strip():
            raise V.fail(f"{where}.file", given, "must be a file name (a string)", DesignError)
        if scale is None:
            raise V.fail(
                f"{where}.units",
                "missing",
                "is required with a mesh file: STL and OBJ carry no unit, so say which length "
                'unit the file is in (e.g. units = "mm")',
                DesignError,
            )
        path = Path(given)
        if not path.is_absolute():
            path = (_FOLDER.get() or Path.cwd()) / path
        vertices, faces = read_mesh(path, f"{where}.file")
        files = _MESH_FILES.get()
        if files is not None:
            files[k] = path.resolve()
        vertices = vertices * scale
    else:
        raw = ob["vertices"]
        if not isinstance(raw, list) or not raw:
            raise V.fail(
                f"{where}.vertices",
                raw,
                "must be a non-empty list of [x, y, z] points",
                DesignError,
            )
        if len(raw) > 3 * MAX_MESH_TRIANGLES:
            rule = f"has too many vertices: at most {3 * MAX_MESH_TRIANGLES}"
            raise V.fail(f"{where}.vertices", f"{len(raw)} vertices", rule, DesignError)
        vertices = None if scale is None else _plain_rows(raw, float)
        if vertices is not None:
            vertices = vertices * scale
        rows = []
        for i, v in enumerate(raw if vertices is None else ()):
            field = f"{where}.vertices[{i}]"
            if scale is None:
                rows.append(_qvec(v, "length", field))
            else:
                if not isinstance(v, (list, tuple)) or len(v) != 3:
                    raise V.fail(field, v, "must be a list of 3 numbers", DesignError)
                rows.append([number(x, f"{field}[{j}]") * scale for j, x in enumerate(v)])
        if vertices is None:
            vertices = np.array(rows, dtype=float)
        rawf = _require(ob, "faces", where)
        if not isinstance(rawf, list) or not rawf:
            raise V.fail(
                f"{where}.faces",
                rawf,
                "must be a non-empty list of [i, j, k] vertex index triples",
                DesignError,
            )
        if len(rawf) > MAX_MESH_TRIANGLES:
            rule = f"a mesh obstacle may have at most {MAX_MESH_TRIANGLES} triangles"
            raise V.fail(f"{where}.faces", f"{len(rawf)} triangles", rule, DesignError)
        faces = _plain_rows(rawf, int)
        if faces is None or faces.min() < 0 or faces.max() >= len(vertices):
            rows = []
            for i, f in enumerate(rawf):
                field = f"{where}.faces[{i}]"
                if not isinstance(f, (list, tuple)) or len(f) != 3:
                    raise V.fail(field, f, "must be a list of 3 vertex indices", DesignError)
                rows.append(
                    [_integer(x, f"{field}[{j}]", 0, len(vertices) - 1) for j, x in enumerate(f)]
                )
            faces = np.array(rows, dtype=np.int64)
    rotation = np.eye(3)
    if "rotation" in ob:
        rot = ob["rotation"]
        if not (
            isinstance(rot, (list, tuple))
            and len(rot) == 3
            and all(isinstance(r, (list, tuple)) and len(r) == 3 for r in rot)
        ):
            raise V.fail(
                f"{where}.rotation", rot, "must be a 3x3 matrix (list of rows)", DesignError
            )
        rotation = np.array(
            [
                [number(x, f"{where}.rotation[{i}][{j}]") for j, x in enumerate(r)]
                for i, r in enumerate(rot)
            ]
        )
        if (
            not np.allclose(rotation.T @ rotation, np.eye(3), rtol=0.0, atol=1e-9)
            or np.linalg.det(rotation) < 0
        ):
            raise V.fail(
                f"{where}.rotation",
                rot,
                "must be a rotation matrix (orthonormal columns, determinant +1)",
                DesignError,
            )
    position = np.array(_qvec(ob.get("position", [0, 0, 0]), "length", f"{where}.position"))
    with np.errstate(all="ignore"):
        vertices = vertices @ rotation.T + position
    bad = np.argwhere(~np.isfinite(vertices))
    if len(bad):
        i, j = (int(x) for x in bad[0])
        field = f"{where}.file" if "file" in ob else f"{where}.vertices[{i}][{j}]"
        rule = f"vertex {i} coordinate {j} must be a finite number (got {vertices[i, j]} m)"
        raise V.fail(field, str(vertices[i].tolist()), rule, DesignError)
    return {"vertices": vertices.tolist(), "faces": faces.tolist()}


def _operating_range(table: Any) -> dict:
    """[operating_range]: what the actuator is built and validated for: the gauge pressures
    of every channel (``pressure = ["0 kPa", "70 kPa"]``), the tensions of every tendon
    channel (``tension = ["0 N", "20 N"]``), or both, and the ``source`` of the range. Solves
    outside it are refused or warned about (docs/model.md, "Validity and stability")."""
    table = _check_keys(table, "operating_range", "operating_range")
    if "pressure" not in table and "tension" not in table:
        raise V.fail(
            "operating_range",
            sorted(table),
            'must state pressure = ["low", "high"], tension = ["low", "high"] or both',
            DesignError,
        )
    if "source" in table and not isinstance(table["source"], str):
        raise V.fail("operating_range.source", table["source"], "must be a string", DesignError)
    out = {}
    for key, kind, example in (
        ("pressure", "pressure", '["0 kPa", "70 kPa"]'),
        ("tension", "force", '["0 N", "20 N"]'),
    ):
        if key not in table:
            continue
        bounds = table[key]
        if isinstance(bounds, str) or not isinstance(bounds, list) or len(bounds) != 2:
            raise V.fail(
                f"operating_range.{key}",
                bounds,
                f"must be [low, high], e.g. {example}",
                DesignError,
            )
        out[key] = _qvec(bounds, kind, f"operating_range.{key}", length=2)
    return out


def _check_channels(secs: list[dict], key: str = "chambers", what: str = "pressure") -> None:
    """Channels (of the chambers, or of the tendons) numbered 0, 1, ... without gaps; the
    error names the entry with the highest channel (the one that declares the unused
    ones)."""
    where: dict[int, str] = {}
    for i, sec in enumerate(secs):
        for k, ch in enumerate(sec.get(key, [])):
            where.setdefault(ch["channel"], f"sections[{i}].{key}[{k}].channel")
    if not where:
        return
    top = max(where)
    missing = [c for c in range(top + 1) if c not in where]
    if missing:
        raise V.fail(
            where[top],
            top,
            f"{what} channels must be numbered 0, 1, ... without gaps: channel {missing[0]} is "
            f"unused but channel {top} is given ({top + 1} channels declared)",
            DesignError,
        )


def _dynamics(dyn: Mapping) -> dict:
    """[dynamics]: Kelvin-Voigt damping time and pressure supply (docs/dynamics.md)."""
    out = {
        "damping_time": _q(dyn.get("damping_time", 0.0), "time", "dynamics.damping_time"),
        "pressure_time_constant": _q(
            dyn.get("pressure_time_constant", 0.0), "time", "dynamics.pressure_time_constant"
        ),
    }
    if "pressure_rate_limit" in dyn:
        out["pressure_rate_limit"] = _q(
            dyn["pressure_rate_limit"], "pressure_rate", "dynamics.pressure_rate_limit"
        )
    return out


def _pcc(pcc: Mapping) -> dict:
    """[pcc]: parameters of the piecewise-constant-curvature model (docs/pcc.md)."""
    kinds = {
        "k_L": ("k_l", "force_per_length"),
        "b_L": ("b_l", "damping_linear"),
        "b_theta": ("b_theta", "damping_rotational"),
        "k_phi": ("k_phi", "moment"),
        "b_phi": ("b_phi", "damping_rotational"),
    }
    out: dict[str, Any] = {}
    for key, (name, kind) in kinds.items():
        if key in pcc:
            out[name] = _q(pcc[key], kind, f"pcc.{key}")
    if "k_theta" in pcc:
        kt = pcc["k_theta"]
        if isinstance(kt, Mapping):
            kt = _check_keys(kt, "pcc_table", "pcc.k_theta")
            angles = _require(kt, "angle", "pcc.k_theta")
            stiff = _require(kt, "stiffness", "pcc.k_theta")
            for key, val in (("angle", angles), ("stiffness", stiff)):
                if not isinstance(val, list):
                    raise V.fail(f"pcc.k_theta.{key}", val, "must be an array", DesignError)
            out["k_theta_table"] = {
                "angle": _qvec(angles, "angle", "pcc.k_theta.angle", length=None),
                "stiffness": _qvec(stiff, "moment", "pcc.k_theta.stiffness", length=None),
            }
        else:
            out["k_theta"] = _q(kt, "moment", "pcc.k_theta")
    for key, allowed in (
        ("mass_model", ("distributed", "tip")),
        ("pressure_force", ("chamber", "tip_force")),
    ):
        if key in pcc:
            out[key] = V.choice(pcc[key], allowed, f"pcc.{key}", DesignError)
    if "plane" in pcc:
        out["plane"] = _q(pcc["plane"], "angle", "pcc.plane")
    if "quadrature" in pcc:
        out["quadrature"] = _integer(pcc["quadrature"], "pcc.quadrature", 2, V.MAX_TABLE_POINTS)
    return out


@dataclass(frozen=True)
class Design:
    """A validated design (immutable). All numbers are SI.

    ``spec`` is the SI description handed to the Rust core, read-only (an edit in place
    raises a TypeError; ``copy.deepcopy`` gives an editable dict); ``document`` the parsed
    file (units as written), a fresh copy on every read: editing it cannot change the design
    (use :meth:`replace` for a changed copy). Use :func:`load_design` to make one, :meth:`save`
    to write one.
    Two designs are equal when they describe the same model (name, citation, description,
    assumptions, the SI spec and the stiffness map file), whatever file they came from and
    however their units were written.
    """

    name: str
    citation: str
    description: str
    assumptions: tuple[str, ...]
    spec: dict
    # The parsed file, private: ``document`` hands out copies, so that no caller can change
    # what a later replace(), save() or cluster transfer builds from it.
    _document: dict = field(repr=False, compare=False)
    source: Path | None = field(default=None, compare=False)
    _rod: Any = field(default=None, repr=False, compare=False)
    #: The stiffness map the file references (``[stiffness_map] file = ...``), loaded.
    stiffness_map: Any = field(default=None, repr=False, compare=False)
    #: The map's file, resolved (part of the design's identity: a design is its contents).
    stiffness_map_source: Path | None = field(default=None, repr=False)
    #: How the tip is held (``[tip] constraint``; softrod.TipConstraint), None: free.
    tip_constraint: Any = field(default=None, repr=False)
    #: The mesh files of ``kind = "mesh"`` obstacles, resolved: (obstacle index, path)
    #: pairs (the design's identity is the meshes' contents, in ``spec``).
    mesh_sources: tuple = field(default=(), repr=False, compare=False)
    # Compiled PCC models by tip loads, built on first use (softrod.pcc.pcc_model).
    _pcc: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        # The compiled rod was built from the spec: it is read-only, so that no edit in
        # place can make Python's readers of it and the solver disagree (softrod._frozen).
        object.__setattr__(self, "spec", freeze(self.spec))

    def __repr__(self) -> str:
        # The whole spec and document are one attribute away; a REPL shows what tells
        # designs apart.
        def count(n: int, what: str) -> str:
            return f"{n} {what}" + ("" if n == 1 else "s")

        parts = [
            f"L = {self.length * 1e3:g} mm",
            count(len(self.spec["sections"]), "section"),
            count(self.n_channels, "channel"),
        ]
        if self.n_tendons:
            parts.append(count(self.n_tendons, "tendon"))
        if self.spec.get("obstacles"):
            parts.append(count(len(self.spec["obstacles"]), "obstacle"))
        if self.tip_constraint is not None:
            parts.append(f"tip {self.tip_constraint.kind}")
        return f"Design({self.name!r}, {', '.join(parts)})"

    @property
    def n_channels(self) -> int:
        """Number of pressure channels (inputs)."""
        return self._rod.n_channels

    @property
    def n_tendons(self) -> int:
        """Number of tendon tension channels (inputs; ``[[sections.tendons]]``)."""
        return self._rod.n_tendons

    @property
    def length(self) -> float:
        """Reference length in m."""
        return self._rod.length

    @property
    def mass(self) -> float:
        """Mass of the rod without the tip body, kg."""
        return self._rod.mass

    @property
    def mapped_sections(self) -> list[str]:
        """Names of the sections whose stiffness a stiffness map scales (``[sections.law]
        stiffness_map = true``, docs/stiffness-map.md); empty when there are none."""
        return [
            sec["name"]
            for sec in self.spec["sections"]
            if (sec.get("law") or {}).get("stiffness_map", False)
        ]

    @property
    def frictional_obstacle(self) -> int | None:
        """Index of the first ``[[obstacles]]`` entry with Coulomb friction (friction > 0),
        or None: such a design's statics follow a load path (docs/contact.md, "Friction in
        the statics")."""
        for k, o in enumerate(self.spec.get("obstacles", [])):
            if float(o.get("friction", 0.0)) > 0:
                return k
        return None

    @property
    def tip_mass(self) -> float:
        """Mass of the rigid tip body, kg."""
        return self.spec["tip"]["mass"]

    @property
    def document(self) -> dict:
        """The parsed design file (units as written) as a new deep copy on each read: a
        plain dict to read, serialise or edit and pass to :func:`load_design`; editing it
        leaves this design unchanged (:meth:`replace` makes a changed copy)."""
        return thaw(self._document)

    def sections(self) -> list[dict]:
        """Compiled section properties (SI): stiffness matrices, line mass, chambers."""
        return self._rod.sections()

    @property
    def provenance(self) -> dict | None:
        """``[design.provenance]``: how the design was made (e.g. by ``calibrate``: the
        dataset, the fitted values with standard errors, the softrod version, the date), or
        None for a hand-written design."""
        value = self._document["design"].get("provenance")
        return None if value is None else copy.deepcopy(value)

    def replace(self, changes: Mapping[str, Any]) -> Design:
        """A copy with some document entries changed, e.g.
        ``{"sections[1].c_b": 1.2, "tip.mass": "10 g"}``; validated like a new file."""
        if not isinstance(changes, Mapping):
            raise V.fail("changes", changes, "must be a mapping {entry path: value}", DesignError)
        V.check_depth(changes, "changes", DesignError)
        doc = self.document
        for path, value in changes.items():
            _set_path(doc, path, thaw(value))
        return _build(doc, self.source)

    def with_obstacles(self, obstacles: list[Mapping[str, Any]]) -> Design:
        """A copy with the rigid obstacles ``obstacles`` (tables with the keys of the design
        file's ``[[obstacles]]``, units as strings; docs/contact.md) in place of the file's;
        ``[]`` removes them. Validated like a new file."""
        if not isinstance(obstacles, (list, tuple)):
            raise design_error(
                "obstacles",
                type(obstacles).__name__,
                "must be a list of obstacle tables ([] for none)",
                InputError,
            )
        return self.replace({"obstacles": list(obstacles)})

    def with_stiffness_map(self, path: str | Path | None) -> Design:
        """A copy whose ``[stiffness_map]`` references the map file ``path`` (a table CSV or
        a map saved with :meth:`softrod.StiffnessMap.save` / ``HybridStiffnessModel.save``;
        a relative path is relative to the current folder), or has none (None)."""
        doc = self.document
        if path is None:
            doc.pop("stiffness_map", None)
        else:
            doc["stiffness_map"] = {"file": str(as_path(path).resolve())}
        return _build(doc, self.source)

    def save(self, path: str | Path) -> Path:
        """Write the design as a TOML design file, whole or not at all; returns the path.

        The file loads with :func:`softrod.load_design` to an equal design. Every
        dimensional value carries its unit: the units of the original file as written, and
        the SI unit for the plain numbers of a ``units = "SI"`` document (``mass = 0.01`` is
        written ``"0.01 kg"``). A stiffness map file keeps its reference, rewritten relative
        to the new file's folder.
        """
        from .io import atomic_path

        path = as_path(path)
        text = self.toml_text(path)
        with atomic_path(path) as tmp:
            tmp.write_text(text, encoding="utf-8")
        return path

    def toml_text(self, path: str | Path) -> str:
        """The text :meth:`save` writes to ``path`` (a .toml file: a stiffness map's
        reference is written relative to its folder)."""
        import tomli_w

        path = as_path(path)
        if path.suffix.lower() != ".toml":
            raise design_error("path", str(path), "a design file must end in .toml", InputError)
        doc = _with_units(_plain(self.document))
        if self.stiffness_map_source is not None:
            target = Path(path).resolve().parent
            try:
                rel = Path(os.path.relpath(self.stiffness_map_source, target))
            except ValueError:  # another drive (Windows)
                rel = self.stiffness_map_source
            doc["stiffness_map"]["file"] = rel.as_posix()
        for k, file in self.mesh_sources:
            try:
                rel = Path(os.path.relpath(file, Path(path).resolve().parent))
            except ValueError:  # another drive (Windows)
                rel = file
            doc["obstacles"][k]["file"] = rel.as_posix()
        return tomli_w.dumps(doc)


_KEY = r"[A-Za-z_][A-Za-z0-9_]*(?:\[\d{1,9}\])*"  # a key with optional [index] parts
_PATH = re.compile(rf"{_KEY}(?:\.{_KEY})*")


def _set_path(doc: dict, path: str, value: Any) -> None:
    if not isinstance(path, str) or len(path) > V.MAX_NAME_LENGTH or not _PATH.fullmatch(path):
        raise V.fail(
            "changes",
            path,
            "an entry path reads like 'sections[1].c_b' or 'tip.mass'",
            DesignError,
        )
    parts: list[Any] = []
    for token in path.replace("]", "").split("."):
        name, *idx = token.split("[")
        parts.append(name)
        parts.extend(int(i) for i in idx)
    target: Any = doc
    try:
        for p, nxt in zip(parts[:-1], parts[1:], strict=True):
            if isinstance(target, dict) and isinstance(p, str) and isinstance(nxt, str):
                # A table the file leaves out (e.g. [dynamics]) is created; the schema
                # check of the rebuilt design still rejects unknown names.
                target = target.setdefault(p, {})
            else:
                target = target[p]
    except (KeyError, IndexError, TypeError):
        raise design_error(path, value, "no such entry in the design") from None
    target[parts[-1]] = value


def _build(doc: dict, source: Path | None) -> Design:
    files: dict[int, Path] = {}
    tokens = (
        _FOLDER.set(source.resolve().parent if source is not None else None),
        _MESH_FILES.set(files),
    )
    try:
        spec = _to_spec(doc)
    finally:
        _MESH_FILES.reset(tokens[1])
        _FOLDER.reset(tokens[0])
    tip_constraint = spec.pop("tip_constraint")
    try:
        rod = _core.Rod(json.dumps(spec, allow_nan=False))
    except DesignError as exc:
        raise _from_mesh_file(exc, doc, files) from None
    meta = doc["design"]
    assumptions = meta.get("assumptions", [])
    if "provenance" in meta and not isinstance(meta["provenance"], Mapping):
        raise design_error("design.provenance", meta["provenance"], "must be a table")
    smap, smap_source = _stiffness_map(doc, spec, rod, source)
    return Design(
        name=meta["name"],
        citation=meta["citation"],
        description=str(meta.get("description", "")),
        assumptions=tuple(assumptions),
        spec=spec,
        _document=doc,
        source=source,
        _rod=rod,
        stiffness_map=smap,
        stiffness_map_source=smap_source,
        tip_constraint=tip_constraint,
        mesh_sources=tuple(sorted(files.items())),
    )


def _from_mesh_file(exc: DesignError, doc: Mapping, files: Mapping[int, Path]) -> DesignError:
    """The core's error about the vertices or faces of a mesh read from a file, told about
    the design's key ``file`` (which the user wrote) with the mesh entry it concerns."""
    m = re.fullmatch(r"obstacles\[(\d+)\]\.((?:vertices|faces).*)", exc.field or "")
    if m is None or int(m.group(1)) not in files:
        return exc
    k = int(m.group(1))
    given = doc["obstacles"][k]["file"]
    rule = f"its mesh's {m.group(2)} = {exc.value}: {exc.rule}"
    return design_error(f"obstacles[{k}].file", given, rule)


def _stiffness_map(doc: Mapping, spec: Mapping, rod, source: Path | None):
    """The map of ``[stiffness_map]`` (loaded) and its resolved file, or (None, None)."""
    if "stiffness_map" not in doc:
        return None, None
    table = _check_keys(doc["stiffness_map"], "stiffness_map", "stiffness_map")
    given = _require(table, "file", "stiffness_map")
    if not isinstance(given, str) or not given.strip():
        raise design_error("stiffness_map.file", given, "must be a file name (a string)")
    file = Path(given)
    if not file.is_absolute():
        # Relative to the design file's folder, as a reader of the file would expect.
        file = (source.resolve().parent if source is not None else Path.cwd()) / file
    options = {k: table[k] for k in ("method", "outside") if k in table}
    mapped = [
        s["name"] for s in spec["sections"] if (s.get("law") or {}).get("stiffness_map", False)
    ]
    if not mapped:
        raise design_error(
            "stiffness_map.file",
            given,
            "no section sets [sections.law] stiffness_map = true, so the map would have no effect",
        )
    from .stiffness_map import load_stiffness_map

    try:
        smap = load_stiffness_map(file, **options)
    except DesignError as exc:
        # The loader names its path argument "path"; in the design that is the key "file".
        key = "file" if exc.field in ("", "path") else exc.field
        raise design_error(f"stiffness_map.{key}", exc.value, exc.rule) from None
    if smap.n_channels != rod.n_channels:
        raise design_error(
            "stiffness_map.file",
            given,
            f"the map takes {smap.n_channels} pressure channel(s), the design has {rod.n_channels}",
        )
    return smap, file.resolve()


# The quantity kind of every dimensional entry of a design document, by table kind and key
# (Design.save writes a plain number in these with its SI unit).
_KINDS: dict[str, dict[str, str]] = {
    "mounting": {"base_position": "length", "roll": "angle", "gravity": "acceleration"},
    "material": {"E": "pressure", "G": "pressure", "density": "density"},
    "section": {
        "length": "length",
        "outer_radius": "length",
        "bore_radius": "length",
        "mass": "mass",
        "EA": "force",
        "GA": "force",
        "EI": "stiffness_bending",
        "EI1": "stiffness_bending",
        "EI2": "stiffness_bending",
        "GJ": "stiffness_bending",
        "rotary_inertia": "inertia_per_length",
        "damping_se": "damping_force",
        "damping_bt": "damping_moment",
        "curvature": "curvature",
        "u_star": "curvature",
        "bend_radius": "length",
        "bend_direction": "angle",
        "outer_radius_end": "length",
    },
    "reference_table": {"s": "length", "curvature": "curvature"},
    "tendon": {
        "distance": "length",
        "angle": "angle",
        "distance_end": "length",
        "angle_end": "angle",
    },
    "law": {
        "axial_force": "force",
        "axial_stiffness": "force",
        "chamber_offset": "length",
        "p_ref": "pressure",
    },
    "partition": {
        "E_I": "force",
        "E_II": "force",
        "E_III": "force",
        "r_I": "length",
        "r_II": "length",
    },
    "chamber": {
        "radius": "length",
        "area": "area",
        "distance": "length",
        "angle": "angle",
        "distance_end": "length",
        "radius_end": "length",
    },
    "tip": {
        "mass": "mass",
        "com_offset": "length",
        "force": "force",
        "moment": "moment",
        "inertia": "inertia",
    },
    "dynamics": {
        "damping_time": "time",
        "pressure_time_constant": "time",
        "pressure_rate_limit": "pressure_rate",
    },
    "load": {"force_per_length": "force_per_length", "moment_per_length": "force"},
    "pcc": {
        "k_L": "force_per_length",
        "b_L": "damping_linear",
        "k_theta": "moment",
        "b_theta": "damping_rotational",
        "k_phi": "moment",
        "b_phi": "damping_rotational",
        "plane": "angle",
    },
    "pcc_table": {"angle": "angle", "stiffness": "moment"},
    "numerics": {"step_length": "length"},
    "obstacle": {
        "point": "length",
        "center": "length",
        "start": "length",
        "end": "length",
        "radius": "length",
        "position": "length",
        "stiffness": "contact_stiffness",
        "tolerance": "length",
        "smoothing": "length",
    },
}


def _plain(x):
    """Python scalars for TOML (numpy floats and ints are not TOML types)."""
    if isinstance(x, Mapping):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    return x


def _with_unit(value: Any, kind: str) -> Any:
    """A plain number (or a list of them) as a string with its SI unit; strings (units as
    written) and anything else unchanged."""
    from .units import SI_UNIT

    if isinstance(value, list):
        return [_with_unit(v, kind) for v in value]
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        unit = "rad" if kind == "angle" else SI_UNIT[kind]
        return f"{float(value)!r} {unit}"
    return value


def _units_in(table: Mapping, kind: str) -> dict:
    out = dict(table)
    for key, k in _KINDS.get(kind, {}).items():
        if key in out:
            if kind == "pcc" and key == "k_theta" and isinstance(out[key], Mapping):
                out[key] = _units_in(out[key], "pcc_table")
            else:
                out[key] = _with_unit(out[key], k)
    return out


def _with_units(doc: dict) -> dict:
    """The document with a unit on every dimensional value (see ``_KINDS``)."""
    doc = dict(doc)
    for key in ("mounting", "tip", "dynamics", "pcc", "numerics"):
        if isinstance(doc.get(key), Mapping):
            doc[key] = _units_in(doc[key], key)
    if isinstance(doc.get("materials"), Mapping):
        doc["materials"] = {
            name: _units_in(m, "material") if isinstance(m, Mapping) else m
            for name, m in doc["materials"].items()
        }
    if isinstance(doc.get("loads"), list):
        doc["loads"] = [
            _units_in(ld, "load") if isinstance(ld, Mapping) else ld for ld in doc["loads"]
        ]
    if isinstance(doc.get("obstacles"), list):
        doc["obstacles"] = [
            _units_in(ob, "obstacle") if isinstance(ob, Mapping) else ob for ob in doc["obstacles"]
        ]
        for ob in doc["obstacles"]:
            # Inline mesh vertices are lengths, unless the obstacle's units key gives them
            # as plain numbers in its unit.
            if isinstance(ob, dict) and "vertices" in ob and "units" not in ob:
                ob["vertices"] = _with_unit(ob["vertices"], "length")
    sections = []
    for sec in doc.get("sections", []):
        if not isinstance(sec, Mapping):
            sections.append(sec)
            continue
        sec = _units_in(sec, "section")
        for key, kind in (("law", "law"), ("partition", "partition")):
            if isinstance(sec.get(key), Mapping):
                sec[key] = _units_in(sec[key], kind)
        if isinstance(sec.get("chambers"), list):
            sec["chambers"] = [
                _units_in(c, "chamber") if isinstance(c, Mapping) else c for c in sec["chambers"]
            ]
        if isinstance(sec.get("tendons"), list):
            sec["tendons"] = [
                _units_in(t, "tendon") if isinstance(t, Mapping) else t for t in sec["tendons"]
            ]
        if isinstance(sec.get("reference_table"), Mapping):
            sec["reference_table"] = _units_in(sec["reference_table"], "reference_table")
        sections.append(sec)
    if "sections" in doc:
        doc["sections"] = sections
    return doc


def read_design(design: str | Path | Mapping[str, Any] | Design) -> Design:
    """Read and validate a design from a TOML file, a mapping with the file's structure, or a
    Design (returned as is). Names of bundled designs and presets are resolved one level up,
    by :func:`softrod.load_design` (``softrod.catalog``).
    Raises :class:`DesignError` naming the field, the value and the rule.
    """
    if isinstance(design, Design):
        return design
    if isinstance(design, Mapping):
        V.check_depth(design, "design", DesignError)
        return _build(thaw(dict(design)), None)
    if not isinstance(design, (str, os.PathLike)):
        raise design_error(
            "design",
            type(design).__name__,
            "must be a path, a bundled design name, a mapping or a Design",
        )
    path = Path(design)
    doc = read_toml(path)
    try:
        return _build(doc, path)
    except DesignError as exc:
        exc.args = (f"{path.name}: {exc.args[0]}",)
        raise


def read_toml(path: Path) -> dict:
    """The document of a TOML file; DesignError naming the file for anything that is not a
    readable, reasonably small, valid UTF-8 TOML document (design and system files)."""
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            rule = f"is too large for a design file ({MAX_FILE_BYTES} bytes at most)"
            raise V.fail(str(path), f"{size} bytes", rule, DesignError)
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError, RecursionError, ValueError) as exc:
        if isinstance(exc, DesignError):
            raise
        reason = (
            "not UTF-8 text"
            if isinstance(exc, UnicodeDecodeError)
            else "nested too deeply"
            if isinstance(exc, RecursionError)
            else str(exc)
        )
        raise DesignError(f"{path}: not valid TOML: {reason}", str(path), "", reason) from None
    except OSError as exc:
        reason = exc.strerror or str(exc)
        message = f"{path}: cannot read the design file: {reason}"
        raise DesignError(message, str(path), "", reason) from None
    V.check_depth(doc, str(path), DesignError)
    return doc
