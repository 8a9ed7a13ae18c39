"""Calibration parameters: names, the sections they act on, their values in a design, and
how a new value is written into the design document.

A parameter is written ``kind`` or ``kind[selector]``:

======================  ==============================================================  =====
kind                    meaning (paper)                                                 unit
======================  ==============================================================  =====
c_s, c_e, c_b, c_t      correction factors of shear, extension, bending, torsion        1
                        (paper 002 eqs. 17-20)
E                       Young's modulus of a material; G scales with it (Poisson's      Pa
                        ratio held fixed). Selector: the material name
alpha                   Ogden exponent (paper 002 eq. 16)                               1
c_p                     chamber swelling coefficient (paper 002 eq. 22)                 1
offset_1, offset_2      chamber offset along d1, d2 (paper 002 eq. 21)                  m
area_scale              factor on the pressurised chamber areas (1 = as designed;       1
                        paper 000's effective area A_eff)
density                 mass density of a material (its weight; its inertia in          kg/m^3
                        dynamics). Selector: the material name
mass                    mass of a section whose mass is given directly                  kg
sigma_ext, sigma_bend_1,
sigma_bend_2            constant stiffness scaling factors (paper 001 eq. 13)           1
damping_time            Kelvin-Voigt damping time tau = B/K of ``[dynamics]`` (paper    s
                        000 eq. 8); dynamic fits only
======================  ==============================================================  =====

Without a selector a section parameter acts on every elastic section with chambers or
tendons (the actuated part, where the papers' factors live); ``c_b[cap_a]`` or ``c_b[cap_a,cap_c]``
names sections, ``c_b[*]`` takes every elastic section, ``alpha`` every Ogden section,
``c_p`` every swelling section. One parameter has one value: the sections it names must
share it (the core checks this).
"""

from __future__ import annotations

import copy
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

from .. import _validate as V
from .._validate import si_text
from ..design import Design, _library

_FACTORS = ("c_s", "c_e", "c_b", "c_t")
_MATERIAL_KINDS = ("E", "density")
_SECTION_KINDS = _FACTORS + (
    "E",
    "alpha",
    "c_p",
    "offset_1",
    "offset_2",
    "area_scale",
    "density",
    "mass",
)
SIGMA_KINDS = ("sigma_ext", "sigma_bend_1", "sigma_bend_2")
#: Parameters of the design's [dynamics] table: they act in dynamic fits only.
DYNAMIC_KINDS = ("damping_time",)
KINDS = _SECTION_KINDS + SIGMA_KINDS + DYNAMIC_KINDS
_UNITS = {
    "E": "Pa",
    "offset_1": "m",
    "offset_2": "m",
    "density": "kg/m^3",
    "mass": "kg",
    "damping_time": "s",
}
_NAME = re.compile(r"^\s*([A-Za-z_0-9]+)\s*(?:\[\s*([^\]]*)\])?\s*$")


@dataclass(frozen=True)
class Parameter:
    """One calibration parameter of a design."""

    name: str
    kind: str
    #: Indices of the sections it acts on (empty for sigma and damping_time).
    sections: tuple[int, ...]
    #: The material it sets (E and density only).
    material: str | None = None

    @property
    def unit(self) -> str:
        return _UNITS.get(self.kind, "1")

    @property
    def positive(self) -> bool:
        """Must stay > 0 (everything but the offsets)."""
        return not self.kind.startswith("offset")

    def core(self) -> tuple[str, list[int]]:
        """The (kind, sections) pair of the Rust core."""
        return self.kind, list(self.sections)

    def value(self, design: Design) -> float:
        """Its value in ``design`` (SI). Sigma and area_scale are 1 in any design: they are
        relative to it."""
        if self.kind in SIGMA_KINDS or self.kind == "area_scale":
            return 1.0
        if self.kind == "damping_time":
            return float(design.spec["dynamics"]["damping_time"])
        sec = design.spec["sections"][self.sections[0]]
        if self.kind == "density":
            return float(sec["material"]["density"])
        if self.kind == "mass":
            return float(sec["mass"])
        law = sec.get("law", {})
        if self.kind in _FACTORS:
            return float(sec.get(self.kind, 1.0))
        if self.kind == "E":
            return float(sec["material"]["youngs_modulus"])
        if self.kind == "alpha":
            return float(law["axial"]["alpha"])
        if self.kind == "c_p":
            return float(law["swelling"]["c_p"])
        return float(law.get("chamber_offset", [0.0, 0.0])[int(self.kind[-1]) - 1])


def _elastic(design: Design) -> list[int]:
    return [i for i, s in enumerate(design.spec["sections"]) if not s["rigid"]]


def _default_sections(design: Design, kind: str) -> list[int]:
    secs = design.spec["sections"]
    elastic = _elastic(design)
    if kind == "alpha":
        return [
            i for i in elastic if secs[i].get("law", {}).get("axial", {}).get("kind") == "ogden"
        ]
    if kind == "c_p":
        return [i for i in elastic if secs[i].get("law", {}).get("swelling")]
    # The actuated part: sections with chambers or tendons.
    actuated = [i for i in elastic if secs[i]["chambers"] or secs[i].get("tendons")]
    if kind == "mass":
        return [i for i in actuated if "mass" in secs[i]]
    return actuated


def parse_parameter(name: str, design: Design) -> Parameter:
    """Resolve a parameter name such as ``"c_b"``, ``"c_b[body]"`` or ``"E[ecoflex]"``."""
    if not isinstance(name, str):
        raise V.fail("params", name, "each parameter must be a name such as 'c_b' or 'c_b[body]'")
    m = _NAME.match(name)
    if not m or m.group(1) not in KINDS:
        raise V.fail("params", name, f"unknown parameter; known kinds: {', '.join(KINDS)}")
    kind, selector = m.group(1), m.group(2)
    secs = design.spec["sections"]
    names = [s["name"] for s in secs]
    if kind in SIGMA_KINDS:
        if selector:
            raise V.fail(
                "params", name, "sigma factors act on the stiffness-mapped sections: no selector"
            )
        return Parameter(name.strip(), kind, ())
    if kind in DYNAMIC_KINDS:
        if selector:
            raise V.fail("params", name, f"{kind} is one value of [dynamics]: no selector")
        return Parameter(name.strip(), kind, ())
    if kind in _MATERIAL_KINDS:
        doc_secs = design.document["sections"]  # one copy, read only
        mats = {
            i: doc_secs[i].get("material")
            for i in _elastic(design)
            if "material" in doc_secs[i] and "outer_radius" in secs[i]
        }
        if selector:
            material = selector.strip()
            if material not in mats.values():
                known = ", ".join(sorted({v for v in mats.values() if v}))
                raise V.fail(
                    "params", name, f"no elastic section uses material {material!r} (used: {known})"
                )
        else:
            used = {mats[i] for i in _default_sections(design, kind) if i in mats}
            if len(used) != 1:
                raise V.fail(
                    "params",
                    name,
                    f"the chambered sections use {len(used)} materials "
                    f"({', '.join(sorted(used)) or 'none'}); name one: E[material]",
                )
            material = used.pop()
        idx = tuple(i for i, m_ in mats.items() if m_ == material)
        return Parameter(name.strip(), kind, idx, material)
    if selector is None:
        idx = _default_sections(design, kind)
    elif selector.strip() == "*":
        idx = _elastic(design)
    else:
        idx = []
        for part in selector.split(","):
            part = part.strip()
            if part not in names:
                raise V.fail(
                    "params", name, f"no section named {part!r} (sections: {', '.join(names)})"
                )
            idx.append(names.index(part))
    if not idx:
        raise V.fail(
            "params", name, f"no section of design {design.name!r} has what {kind} acts on"
        )
    return Parameter(name.strip(), kind, tuple(idx))


def parse_parameters(names: Sequence[str] | str, design: Design) -> list[Parameter]:
    """Resolve a list of names (or one comma-separated string outside brackets)."""
    if isinstance(names, str):
        names = [n for n in re.split(r",(?![^\[]*\])", names) if n.strip()]
    if not isinstance(names, (list, tuple)):
        raise V.fail("params", names, "must be a name, a comma-separated string or a list of names")
    params = [parse_parameter(n, design) for n in names]
    if not params:
        raise V.fail("params", names, "name at least one parameter")
    seen: dict[tuple, str] = {}
    for p in params:
        for key in [(p.kind, i) for i in p.sections] or [(p.kind, None)]:
            if key in seen:
                raise V.fail("params", p.name, f"acts on the same thing as {seen[key]!r}")
            seen[key] = p.name
    return params


def design_changes(params: Sequence[Parameter], values: Sequence[float], base: Design) -> dict:
    """Document entries (for :meth:`Design.replace`) that give ``params`` the ``values``
    (SI, written as strings with SI units) on top of ``base``. Sigma is left out: it is
    not part of a design. ``area_scale`` multiplies ``base``'s areas."""
    doc = base.document
    changes: dict = {}
    laws: dict[int, dict] = {}

    def law(i: int) -> dict:
        if i not in laws:
            laws[i] = dict(doc["sections"][i].get("law", {}))
            offset = base.spec["sections"][i].get("law", {}).get("chamber_offset")
            if offset is not None:
                laws[i]["chamber_offset"] = [si_text(x, "length") for x in offset]
        return laws[i]

    materials: dict = {}
    for p, v in zip(params, values, strict=False):
        v = float(v)
        if p.kind in SIGMA_KINDS:
            continue
        if p.kind == "damping_time":
            changes["dynamics.damping_time"] = si_text(v, "time")
            continue
        if p.kind in _MATERIAL_KINDS:
            table = materials.get(p.material) or _material_table(base, p.material)
            materials[p.material] = _material_change(base, table, p.material, p.kind, v)
            continue
        if p.kind == "mass":
            for i in p.sections:
                changes[f"sections[{i}].mass"] = si_text(v, "mass")
            continue
        for i in p.sections:
            if p.kind in _FACTORS:
                changes[f"sections[{i}].{p.kind}"] = v
            elif p.kind in ("alpha", "c_p"):
                law(i)[p.kind] = v
            elif p.kind.startswith("offset"):
                offset = law(i).setdefault("chamber_offset", ["0 m", "0 m"])
                offset[int(p.kind[-1]) - 1] = si_text(v, "length")
            else:  # area_scale
                chambers = copy.deepcopy(doc["sections"][i]["chambers"])
                for ch, ch_si in zip(chambers, base.spec["sections"][i]["chambers"], strict=False):
                    # The hole stays as designed; only the pressurised area scales.
                    radius = ch_si["radius"] or math.sqrt(ch_si["area"] / math.pi)
                    ch["radius"] = si_text(radius, "length")
                    ch["area"] = si_text(v * ch_si["area"], "area")
                changes[f"sections[{i}].chambers"] = chambers
    for i, table in laws.items():
        changes[f"sections[{i}].law"] = table
    if materials:
        changes["materials"] = {**base.document.get("materials", {}), **materials}
    return changes


def _material_table(base: Design, name: str) -> dict:
    inline = base.document.get("materials", {})
    return dict(inline[name]) if name in inline else dict(_library()[name])


def _material_change(base: Design, table: dict, name: str, kind: str, value: float) -> dict:
    """``table`` ([materials.<name>]) with E (G scaled with it when G is given) or the
    density set."""
    table = dict(table)
    compiled = next(
        s["material"]
        for s, d in zip(base.spec["sections"], base.document["sections"], strict=False)
        if d.get("material") == name
    )
    if kind == "density":
        table["density"] = si_text(value, "density")
        return table
    if "G" in table:
        g = compiled["shear_modulus"]
        table["G"] = si_text(g * value / compiled["youngs_modulus"], "pressure")
    table["E"] = si_text(value, "pressure")
    return table
