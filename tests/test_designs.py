"""Every bundled design loads and solves; a published measurement; units; mappings."""

import copy
import re

import numpy as np
import pytest
import softrod
from softrod import load_design, solve_statics

pytestmark = pytest.mark.fast  # the whole module runs in seconds

DESIGNS = softrod.bundled_designs()
SPA = "spa_three_chamber_130mm"


def test_designs_are_bundled():
    assert SPA in DESIGNS
    assert len(DESIGNS) >= 6
    assert (softrod.designs_dir() / f"{SPA}.toml").is_file()


@pytest.mark.parametrize("name", DESIGNS)
def test_bundled_design_loads(name):
    d = load_design(name)
    assert d.name == name  # file name and [design].name agree, so names are unambiguous
    assert d.citation.strip()
    assert d.n_channels + d.n_tendons >= 1  # pressures or tensions drive it
    assert d.length > 0
    assert d.source is not None and d.source.stem == name


@pytest.mark.parametrize("name", DESIGNS)
@pytest.mark.parametrize("pressure", [0.0, 30e3], ids=["0kPa", "30kPa"])
def test_bundled_design_solves(name, pressure):
    d = load_design(name)
    sol = solve_statics(d, [pressure] * d.n_channels)
    assert sol.converged
    for arr in (sol.s, sol.position, sol.rotation, sol.force, sol.moment, sol.v, sol.u):
        assert np.all(np.isfinite(arr))
    # The tip is roughly one rod length from the base: nothing blew up or folded back.
    reach = np.linalg.norm(sol.tip_position - sol.position[0])
    assert 0.5 * d.length < reach < 1.5 * d.length


def test_paper_002_horizontal_sag_matches_measurement():
    """Paper 002, eq. (24): measured end point at zero pressure, horizontal mounting.

    The design's description maps the paper's point (x, y, z) = (-34.5, 2.8, 130.8) mm to
    softrod world (130.8, -2.8, -34.5) mm. Tolerance 10 mm: the design is model M0, a linear
    law with literature shear stiffness; paper 002 Table V reports a mean tip error of 9-11 mm
    for M0 over its experiments, so a model within 10 mm of this single point is as good as
    the paper's own M0. (c_b = 1.31 was identified from this very deflection, so a much larger
    miss would point to a mounting or sign error, not to model error.)
    """
    d = load_design("spa_three_chamber_134mm_horizontal")
    assert "130.8, -2.8, -34.5" in d.description  # the number below is the documented one
    measured = np.array([130.8, -2.8, -34.5]) * 1e-3
    sol = solve_statics(d, [0.0, 0.0, 0.0])
    diff = sol.tip_position - measured
    dist = np.linalg.norm(diff)
    print(
        f"\npaper 002 horizontal, p = 0: model tip {np.round(sol.tip_position * 1e3, 2)} mm, "
        f"measured {measured * 1e3} mm, difference {np.round(diff * 1e3, 2)} mm, "
        f"|difference| = {dist * 1e3:.2f} mm"
    )
    assert dist < 10e-3
    # The sag is downwards (gravity along -z) and of the measured size, not just "close".
    assert sol.tip_position[2] < -20e-3


def _with_si_units(text: str) -> str:
    """Rewrite every "<number> mm|kPa|g" string of a design file as metres, pascals, kg."""
    factor = {"mm": ("m", 1e-3), "kPa": ("Pa", 1e3), "g": ("kg", 1e-3)}

    def convert(m: re.Match) -> str:
        unit, scale = factor[m.group(2)]
        return f'"{float(m.group(1)) * scale!r} {unit}"'

    return re.sub(r'"(-?[0-9.]+) (mm|kPa|g)"', convert, text)


def test_units_mm_and_m_give_identical_results(tmp_path):
    original = softrod.designs_dir() / f"{SPA}.toml"
    text = original.read_text()
    rewritten = _with_si_units(text)
    assert '"110 mm"' in text and '"0.11 m"' in rewritten  # the rewrite did happen
    assert '"82700.0 Pa"' in rewritten and '"0.006 kg"' in rewritten
    path = tmp_path / "spa_si.toml"
    path.write_text(rewritten)

    a = load_design(original)
    b = load_design(path)
    # 1e-15: the SI inputs agree to the last bit or two (e.g. 110 * 1e-3 vs 0.11); such a
    # relative change of ~1e-16 moves nothing by more than a few ulps.
    np.testing.assert_allclose(b.spec["sections"][1]["length"], 0.11, rtol=1e-15)
    for p in ([0.0, 0.0, 0.0], [50e3, 10e3, 0.0]):
        sa, sb = solve_statics(a, p), solve_statics(b, p)
        # 1e-12 m: inputs differ by ~1 ulp; the well-conditioned solve keeps the positions
        # within a few ulps of 0.13 m (~1e-16 m each), far below this.
        np.testing.assert_allclose(sb.position, sa.position, rtol=0, atol=1e-12)
        np.testing.assert_allclose(sb.rotation, sa.rotation, rtol=0, atol=1e-12)


def test_load_design_from_mapping():
    by_name = load_design(SPA)
    doc = copy.deepcopy(by_name.document)
    from_dict = load_design(doc)
    assert from_dict.name == SPA and from_dict.source is None
    assert from_dict.spec == by_name.spec
    assert doc == by_name.document  # load_design does not modify the caller's mapping
    p = [20e3, 0.0, 40e3]
    # Same SI spec, same deterministic solver: identical to the last bit.
    np.testing.assert_array_equal(
        solve_statics(from_dict, p).position, solve_statics(by_name, p).position
    )


def test_editing_a_design_document_cannot_change_the_design(tmp_path):
    d = load_design(SPA)
    before = copy.deepcopy(d.document)
    edited = d.document
    edited["design"]["name"] = "edited"
    edited["sections"][1]["length"] = "1 m"
    del edited["sections"][0]
    assert d.document == before  # each read is a new copy of the file as loaded
    # What replace() and save() build from is the design's own document, not the edit.
    again = d.replace({})
    assert again == d and again.document == before
    renamed = d.replace({"design.name": "renamed"})
    assert renamed.name == "renamed" and d.name == SPA and d.document == before
    saved = load_design(d.save(tmp_path / "spa.toml"))
    assert saved == d
    # The copy is a plain document: edited and loaded, it is a new design.
    assert load_design(d.document | {"design": {**before["design"], "name": "x"}}).name == "x"


def test_the_spec_is_read_only():
    """Design.spec is what the compiled rod was built from: an edit in place would leave
    Python's readers of it (tip_mass, the PCC model, calibration's parameters) and the
    solver disagreeing, so every in-place change is refused, at any depth, naming the way
    to a changed copy; a deep copy is a plain editable dict."""
    import json
    import pickle

    d = load_design(SPA)
    spec = d.spec
    edits = [
        lambda: spec.__setitem__("name", "x"),
        lambda: spec["tip"].__setitem__("mass", 1.0),
        lambda: spec["tip"].update(mass=1.0),
        lambda: spec["tip"].pop("mass"),
        lambda: spec["sections"].append({}),
        lambda: spec["sections"].__delitem__(0),
        lambda: spec["sections"][0].setdefault("new", 1),
        lambda: spec["sections"][0]["chambers"].clear(),
        lambda: spec["mounting"].clear(),
    ]
    for edit in edits:
        with pytest.raises(TypeError, match=r"read-only.*Design\.replace"):
            edit()
    assert d.spec == load_design(SPA).spec and d.tip_mass == spec["tip"]["mass"]
    # Still a dict to read and serialise (the cluster and the saved states use JSON).
    assert isinstance(spec, dict) and json.loads(json.dumps(spec)) == spec
    editable = copy.deepcopy(spec)
    editable["tip"]["mass"] = 1.0
    editable["sections"].append({})
    assert type(editable) is dict and type(editable["sections"]) is list
    assert d.spec != editable
    # Pickled (a process pool's arguments), the copy is read-only too.
    back = pickle.loads(pickle.dumps(spec))
    assert back == spec
    with pytest.raises(TypeError, match="read-only"):
        back["tip"]["mass"] = 1.0
    # replace() builds a new design with its own read-only spec.
    heavier = d.replace({"tip.mass": "50 g"})
    assert heavier.tip_mass == pytest.approx(0.05) and d.tip_mass == spec["tip"]["mass"]


def test_load_design_accepts_path_and_design():
    path = softrod.designs_dir() / f"{SPA}.toml"
    d = load_design(path)
    assert load_design(str(path)).spec == d.spec
    assert load_design(d) is d


@pytest.mark.parametrize(
    ("step", "expected"),
    [("13 mm", [1, 9, 1]), ("5 mm", [2, 22, 2]), ("110 mm", [1, 1, 1]), ("0.011 m", [1, 10, 1])],
)
def test_step_length_sets_steps_per_section(step, expected):
    # Each section gets ceil(length / step) steps; 110 mm / 11 mm is exactly 10, not 11.
    d = load_design(SPA).replace({"numerics": {"step_length": step}})
    assert [s["steps"] for s in d.spec["sections"]] == expected


def test_step_length_rejects_bad_values():
    base = load_design(SPA)
    for bad in ("0 mm", "-1 mm", "5 kPa"):
        with pytest.raises(softrod.DesignError, match="numerics.step_length"):
            base.replace({"numerics": {"step_length": bad}})


def test_section_steps_override_step_length():
    d = load_design(SPA).replace({"numerics": {"step_length": "5 mm"}, "sections[1].steps": 4})
    assert [s["steps"] for s in d.spec["sections"]] == [2, 4, 2]


def test_documents_copy_deep_and_plain():
    """Design.document and replace() copy document data deeply (softrod._frozen.thaw, the
    fast copy of an inline mesh's thousands of numbers): an edit of the copy, or of a value
    after it was given to replace(), never reaches the design; frozen parts come back as
    plain dicts and lists, and other values (numpy arrays) are deep-copied."""
    from softrod._frozen import freeze, thaw

    d = load_design(SPA)
    doc = d.document
    doc["sections"][0]["length"] = "1 m"
    assert d.document != doc and d.document == load_design(SPA).document
    value = {
        "kind": "plane",
        "point": ["0 mm", "0 mm", "-90 mm"],
        "normal": [0, 0, 1],
        "stiffness": "1e7 N/m^2",
        "tolerance": "0.2 mm",
    }
    moved = d.with_obstacles([value])
    value["point"][2] = "+90 mm"
    assert moved.document["obstacles"][0]["point"][2] == "-90 mm"
    frozen = freeze({"a": [[1.0, 2], ("x", None)], "b": {"c": True}})
    plain = thaw(frozen)
    assert plain == frozen and type(plain) is dict and type(plain["a"]) is list
    assert type(plain["a"][0]) is list and type(plain["a"][1]) is tuple
    plain["a"][0][0] = 5.0
    assert frozen["a"][0][0] == 1.0
    arr = np.zeros(2)
    copied = thaw({"x": arr})["x"]
    assert copied is not arr and np.array_equal(copied, arr)
