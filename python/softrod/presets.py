"""Presets: named, ready-to-solve designs that reproduce the published models of the papers.

A preset is a bundled design file plus a few changes applied with :meth:`Design.replace`
(validated like a new file). ``load_design("paper002_M3_vertical")`` builds one; the
resulting design's ``name`` is the preset's name. :func:`list_presets` lists them.

Paper 002 (Sec. VI, Table IV) identified four models of its 134 mm three-chamber actuator.
They differ only in the body section (section b); the caps keep c_e = c_b = 1 (Sec. VI):

- M0: linear law, c_b 1.31, c_e 0.92 (the bundled 134 mm designs as they are);
- M1: Ogden law (eq. 16), c_e 2.95, alpha 0.61;
- M2: Ogden, c_e 3.10, alpha 0.62, chamber offset theta^{2,off} 1.46 mm, theta^{3,off} 1.64 mm
  (eq. 21);
- M3: Ogden, c_e 2.82, alpha 8.89, offset (0.89, 0.98) mm and chamber swelling c_p 0.48 at
  p_ref 0.8 bar (eq. 22).

Offset mapping: the paper writes rho_off = theta^{2,off} d2 + theta^{3,off} d3 with d1 the
tangent; softrod's body axes are (d1, d2) = paper (d2, d3) (the same map that puts chamber 1,
rho_1 = -rho_p d2 of eq. 21, at 180 deg), so ``chamber_offset = [theta2, theta3]``.

Paper 004's modular actuator with its partition law (Table 1, eqs. 29-31) is ``paper004``
(no load) and ``paper004_1N_tip`` (1 N at the free end).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from .design import Design, designs_dir, read_design
from .errors import DesignError, design_error

PAPER002_TITLE = (
    "Soft Pneumatic Actuator Model Based on a Pressure-Dependent Spatial Nonlinear Rod Theory"
)
PAPER004_TITLE = (
    "A Novel and Practicable Approach for Determining the Beam Parameters of Soft Pneumatic "
    "Multi-Chamber Bending Actuators"
)


@dataclass(frozen=True)
class Preset:
    """A named design: ``base`` (a bundled design) with ``section_changes`` applied.

    name: the name to pass to :func:`softrod.load_design`.
    summary: one line saying what it models.
    citation: paper, tables and equations its values come from.
    base: the bundled design it starts from.
    section_changes: {section name: {key: value}} written into that section of the base
        document (TOML keys and values with units, as in a design file).
    assumptions: lines put before the base design's assumptions.
    replaces_assumption: a base assumption containing this text is dropped (it describes
        what the preset changes).
    note: text put between the summary and the base design's description.
    """

    name: str
    summary: str
    citation: str
    base: str
    section_changes: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    assumptions: tuple[str, ...] = ()
    replaces_assumption: str = ""
    note: str = ""

    def load(self) -> Design:
        """Build the design (a fresh, validated :class:`Design`)."""
        # The bundled file itself, never a same-named file in the working folder.
        base = read_design(designs_dir() / f"{self.base}.toml")
        names = [s.get("name") for s in base.document["sections"]]
        changes: dict[str, Any] = {}
        for sec, values in self.section_changes.items():
            if sec not in names:  # a bundled file was edited out from under the preset
                raise design_error(
                    f"preset {self.name}", sec, f"base design {self.base} has no such section"
                )
            i = names.index(sec)
            for key, value in values.items():
                changes[f"sections[{i}].{key}"] = value
        kept = [
            a
            for a in base.assumptions
            if not (self.replaces_assumption and self.replaces_assumption in a)
        ]
        changes["design.name"] = self.name
        changes["design.citation"] = self.citation
        changes["design.description"] = (
            f"{self.summary} Preset built from the bundled design {self.base}{self.note}. "
            f"{base.description}"
        )
        changes["design.assumptions"] = [*self.assumptions, *kept]
        try:
            return base.replace(changes)
        except DesignError as exc:
            exc.args = (f"preset {self.name}: {exc.args[0]}",)
            raise


# --------------------------------------------------------------------------- paper 002

# Table IV. c_b = 1.31 in every model (identified first from the zero-pressure sag, eq. 24).
# Ogden law of eq. 16 on the body only; offsets along softrod (d1, d2) = paper (d2, d3).
_C_B = 1.31
_PAPER002_MODELS: dict[str, tuple[str, dict[str, Any]]] = {
    "M0": ("linear law, constant chamber radii, no offset", {"c_e": 0.92}),
    "M1": (
        "Ogden law (eq. 16), constant radii, no offset",
        {"c_e": 2.95, "law": {"axial": "ogden", "alpha": 0.61}},
    ),
    "M2": (
        "Ogden law (eq. 16), chamber offset (eq. 21), constant radii",
        {
            "c_e": 3.10,
            "law": {"axial": "ogden", "alpha": 0.62, "chamber_offset": ["1.46 mm", "1.64 mm"]},
        },
    ),
    "M3": (
        "Ogden law (eq. 16), chamber offset (eq. 21), pressure-dependent chamber radii (eq. 22)",
        {
            "c_e": 2.82,
            "law": {
                "axial": "ogden",
                "alpha": 8.89,
                "chamber_offset": ["0.89 mm", "0.98 mm"],
                "c_p": 0.48,
                "p_ref": "0.8 bar",  # Sec. VI: "The reference pressure was set to 0.8 bar"
            },
        },
    ),
}
# Eqs. 17, 19, 20: stiffnesses k_e = c_e E A_m, k_s, k_t, k_b = c_b E I; 16: Ogden energy;
# 21: chamber centroids (with the offset); 22: swelling.
_PAPER002_EQUATIONS = {
    "M0": "eqs. 17, 19-21",
    "M1": "eqs. 16-21",
    "M2": "eqs. 16-21",
    "M3": "eqs. 16-22",
}
_PAPER002_MOUNTINGS = {
    "vertical": (
        "spa_three_chamber_134mm_vertical",
        "vertical (hanging) mounting, experiments (i)-(iii) of Sec. V-b",
    ),
    "horizontal": (
        "spa_three_chamber_134mm_horizontal",
        "horizontal mounting, experiment (a) of Sec. V-a",
    ),
}


def _paper002(model: str, mounting: str) -> Preset:
    what, body = _PAPER002_MODELS[model]
    base, where = _PAPER002_MOUNTINGS[mounting]
    law = body.get("law", {})
    values = ", ".join(
        [f"c_b {_C_B}", f"c_e {body['c_e']}"]
        + ([f"alpha {law['alpha']}"] if "alpha" in law else [])
        + (
            [f"offset ({law['chamber_offset'][0]}, {law['chamber_offset'][1]})"]
            if "chamber_offset" in law
            else []
        )
        + ([f"c_p {law['c_p']} at p_ref {law['p_ref']}"] if "c_p" in law else [])
    )
    eqs = _PAPER002_EQUATIONS[model]
    assumptions = [
        f"Model {model} of Sec. VI: body section (b) {what}; {values} (Table IV). The caps keep "
        "the linear law with c_e = c_b = 1 (Sec. VI); c_s = c_t = 1 (eq. 19)."
    ]
    if "chamber_offset" in law:
        assumptions.append(
            "chamber_offset = [theta^{2,off}, theta^{3,off}]: rho_off = theta^{2,off} d2 + "
            "theta^{3,off} d3 in the paper's body frame (d1 tangent) is (d1, d2) in softrod's, "
            "the same map that puts chamber 1 (rho_1 = -rho_p d2, eq. 21) at 180 deg."
        )
    if "c_p" in law:
        assumptions.append(
            "Swelling r_p(p) = r_p (1 + c_p p / p_ref) (eq. 22) per chamber with its own "
            "pressure; it changes the pressure force and couple and A_m, I of the body (eqs. "
            "17, 19, 20) but not the weight, which acts on A_m,0 (eq. 27)."
        )
    return Preset(
        name=f"paper002_{model}_{mounting}",
        summary=f"Paper 002 actuator, {where}; model {model} of Table IV: {what}.",
        citation=f"{PAPER002_TITLE}, Sec. VI, Table IV ({model}), {eqs}; Tables I-II, Sec. V",
        base=base,
        section_changes={"body": {"c_b": _C_B, **body}},
        assumptions=tuple(assumptions),
        replaces_assumption="M0 values of Table IV",
        note=" (model M0) by changing its body section; the rest of this text is that design's",
    )


# --------------------------------------------------------------------------- paper 004

_PAPER004 = (
    Preset(
        name="paper004",
        summary="Paper 004 modular two-module actuator (Actuator 2), partition law (Table 1, "
        "eqs. 29-31), no tip load.",
        citation=f"{PAPER004_TITLE}, Tables 1-2, eqs. 13-15, 23, 29-31, Secs. 3-4",
        base="modular_two_module",
    ),
    Preset(
        name="paper004_1N_tip",
        summary="Paper 004 modular two-module actuator (Actuator 2), partition law, 1 N weight "
        "at the free end (Secs. 3.2, 4.1).",
        citation=f"{PAPER004_TITLE}, Tables 1-3, eqs. 13-15, 23, 29-31, Secs. 3-4",
        base="modular_two_module_1N_tip",
    ),
)

PRESETS: dict[str, Preset] = {
    p.name: p
    for p in (
        *(_paper002(m, mount) for mount in _PAPER002_MOUNTINGS for m in _PAPER002_MODELS),
        *_PAPER004,
    )
}
PAPER002_MODELS = tuple(_PAPER002_MODELS)  # ("M0", "M1", "M2", "M3")


def list_presets() -> list[Preset]:
    """All presets, paper 002 models first (vertical, then horizontal), then paper 004."""
    return list(PRESETS.values())


def load_preset(name: str) -> Design:
    """The design of preset ``name`` (also reachable as ``load_design(name)``)."""
    if name not in PRESETS:
        raise design_error("preset", name, f"unknown preset (known: {', '.join(PRESETS)})")
    return PRESETS[name].load()


def paper002_preset(model: str, mounting: str) -> str:
    """Preset name of paper 002 model ``model`` (M0-M3) in ``mounting`` (vertical/horizontal)."""
    if model not in _PAPER002_MODELS:
        raise design_error("model", model, f"must be one of {', '.join(_PAPER002_MODELS)}")
    if mounting not in _PAPER002_MOUNTINGS:
        raise design_error("mounting", mounting, f"must be one of {', '.join(_PAPER002_MOUNTINGS)}")
    return f"paper002_{model}_{mounting}"
