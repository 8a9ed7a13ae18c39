"""Presets: paper 002's models M0-M3 (Sec. VI, Table IV) and paper 004's partition model."""

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import softrod
from softrod import DesignError, load_design, solve_statics, solve_statics_batch
from softrod.compare import clamp_frame
from softrod.presets import PRESETS, Preset, load_preset, paper002_preset

pytestmark = pytest.mark.fast  # the whole module runs in about a second

NAMES = [p.name for p in softrod.list_presets()]
MM = 1e-3
P_TEST = 0.6e5  # Pa: the top of paper 002's ramps (Sec. V)


def lateral_drift(design, pressures) -> float:
    """Tip movement across the clamp axis (paper e1, e2) from zero pressure, m.

    Measured from the zero-pressure tip because the marker's centre-of-mass offset (Sec. V)
    already tilts the unpressurised rod by a fraction of a millimetre."""
    out = solve_statics_batch(design, [[0.0, 0.0, 0.0], pressures])
    xy = clamp_frame(design, out.tip_position)[:, :2]
    return float(np.linalg.norm(xy[1] - xy[0]))


def test_preset_names():
    expected = {
        f"paper002_{m}_{mount}"
        for m in ("M0", "M1", "M2", "M3")
        for mount in ("vertical", "horizontal")
    } | {"paper004", "paper004_1N_tip"}
    assert set(NAMES) == expected
    assert not set(NAMES) & set(softrod.bundled_designs())  # one meaning per name
    for p in softrod.list_presets():
        assert isinstance(p, Preset)
        assert p.summary and "\n" not in p.summary  # one line for `softrod designs`
        assert "Table" in p.citation and "eq" in p.citation


@pytest.mark.parametrize("name", NAMES)
def test_preset_loads_and_solves(name):
    d = load_design(name)
    assert d.name == name  # the preset's name, not its base file's
    assert d.citation == PRESETS[name].citation
    assert d.n_channels == 3
    out = solve_statics_batch(d, [[0.0, 0.0, 0.0], [30e3, 0.0, 0.0], [30e3, 30e3, 30e3]])
    assert out.converged.all()
    reach = np.linalg.norm(out.tip_position, axis=1)
    assert np.all((0.5 * d.length < reach) & (reach < 1.5 * d.length))


def test_preset_via_api_and_helpers():
    assert load_preset("paper002_M1_horizontal").name == "paper002_M1_horizontal"
    assert paper002_preset("M2", "vertical") == "paper002_M2_vertical"
    with pytest.raises(DesignError, match="model.*M5"):
        paper002_preset("M5", "vertical")
    with pytest.raises(DesignError, match="mounting.*upside"):
        paper002_preset("M0", "upside")
    with pytest.raises(DesignError, match="presets: .*paper002_M0_vertical"):
        load_design("paper002_M9_vertical")


def test_preset_with_a_missing_section_names_it():
    bad = Preset("x", "s", "c", "spa_three_chamber_134mm_vertical", {"nosuch": {"c_e": 1.0}})
    with pytest.raises(DesignError, match="nosuch"):
        bad.load()


@pytest.mark.parametrize("mounting", ["vertical", "horizontal"])
def test_m0_preset_is_the_bundled_design(mounting):
    """M0 is the bundled 134 mm design as it is (Table IV M0): same spec, same shapes."""
    base = load_design(f"spa_three_chamber_134mm_{mounting}")
    m0 = load_design(f"paper002_M0_{mounting}")
    assert {**m0.spec, "name": ""} == {**base.spec, "name": ""}
    for p in ([0.0, 0.0, 0.0], [P_TEST, 0.0, 0.0], [20e3, 45e3, 10e3]):
        np.testing.assert_array_equal(
            solve_statics(m0, p).position, solve_statics(base, p).position
        )


# Table IV: (c_e, alpha, theta^{2,off}, theta^{3,off} in mm, c_p); c_b = 1.31 in all.
TABLE_IV = {
    "M0": (0.92, None, 0.0, 0.0, None),
    "M1": (2.95, 0.61, 0.0, 0.0, None),
    "M2": (3.10, 0.62, 1.46, 1.64, None),
    "M3": (2.82, 8.89, 0.89, 0.98, 0.48),
}


@pytest.mark.parametrize("model", TABLE_IV)
def test_paper002_presets_carry_table_iv(model):
    c_e, alpha, th2, th3, c_p = TABLE_IV[model]
    d = load_design(f"paper002_{model}_vertical")
    body = d.document["sections"][1]
    assert body["name"] == "body" and body["c_b"] == 1.31 and body["c_e"] == c_e
    caps = [d.document["sections"][i] for i in (0, 2)]
    assert all("c_e" not in c and "c_b" not in c and "law" not in c for c in caps)  # Sec. VI
    law = d.spec["sections"][1].get("law", {"axial": {"kind": "linear"}})
    if alpha is None:
        assert law["axial"] == {"kind": "linear"}
    else:
        assert law["axial"] == {"kind": "ogden", "alpha": alpha}
    # Eq. 21: rho_k = (ideal centroid) + rho_off, rho_off = theta2 d2 + theta3 d3 (paper)
    # = (theta2, theta3) along softrod (d1, d2). Ideal centroids at 180/300/60 deg, 12 mm.
    rho_p = 12 * MM
    ideal = [
        (-rho_p, 0.0),
        (rho_p / 2, -rho_p * math.sqrt(3) / 2),
        (rho_p / 2, rho_p * math.sqrt(3) / 2),
    ]
    chambers = d.sections()[1]["chambers"]
    for (area, c1, c2, channel), (i1, i2), k in zip(chambers, ideal, range(3), strict=True):
        assert channel == k
        assert c1 == pytest.approx(i1 + th2 * MM, abs=1e-12)
        assert c2 == pytest.approx(i2 + th3 * MM, abs=1e-12)
        assert area == pytest.approx(math.pi * (5.15 * MM) ** 2, rel=1e-12)  # Table I, r_p
    if c_p is None:
        assert "swelling" not in law
    else:
        assert law["swelling"] == {"c_p": c_p, "p_ref": pytest.approx(0.8e5)}  # Sec. VI


def test_equal_pressures_drift_only_with_an_offset():
    """Paper 002 Sec. VII / Fig. 5 bottom: with p1 = p2 = p3, M1 only elongates (axisymmetric
    load), while the chamber offset of M2 and M3 drives the tip sideways."""
    p = [P_TEST] * 3
    drift = {m: lateral_drift(load_design(f"paper002_{m}_vertical"), p) for m in TABLE_IV}
    # 0.1 mm: M0/M1 move only through the marker's small centre-of-mass offset (0.02 mm).
    assert drift["M0"] < 0.1 * MM and drift["M1"] < 0.1 * MM
    assert drift["M2"] > 5 * MM and drift["M3"] > 5 * MM


def test_offset_drift_points_away_from_the_offset():
    """The pressure force acts at the shifted chamber centroids, so that side stretches more
    and the rod bends away from it: the drift is antiparallel to rho_off (eq. 21, eq. 7)."""
    d = load_design("paper002_M2_vertical")
    out = solve_statics_batch(d, [[0.0, 0.0, 0.0], [P_TEST] * 3])
    drift = np.diff(clamp_frame(d, out.tip_position)[:, :2], axis=0)[0]
    offset = np.array([1.46, 1.64])
    cosine = drift @ offset / (np.linalg.norm(drift) * np.linalg.norm(offset))
    assert cosine < -0.99


def test_swelling_strengthens_the_actuation():
    """Paper 002 Sec. VII: the pressure-dependent radius (eq. 22) of M3 gives a much larger
    bending than M2 for one chamber (experiment i, Fig. 6)."""
    p = [P_TEST, 0.0, 0.0]
    m2 = lateral_drift(load_design("paper002_M2_vertical"), p)
    m3 = lateral_drift(load_design("paper002_M3_vertical"), p)
    assert m3 > 1.5 * m2


def test_ogden_stiffens_the_axial_response():
    """M1's Ogden law with c_e 2.95 is stiffer in tension than M0's linear c_e 0.92: less
    elongation with all three chambers pressurised (experiment iii)."""
    stretch = {}
    for m in ("M0", "M1"):
        d = load_design(f"paper002_{m}_vertical")
        out = solve_statics_batch(d, [[0.0] * 3, [P_TEST] * 3])
        stretch[m] = np.diff(clamp_frame(d, out.tip_position)[:, 2])[0]
    assert 0 < stretch["M1"] < 0.5 * stretch["M0"]


@pytest.mark.parametrize(
    ("preset", "base"),
    [("paper004", "modular_two_module"), ("paper004_1N_tip", "modular_two_module_1N_tip")],
)
def test_paper004_presets_use_the_partition_law(preset, base):
    """Table 1, eqs. 29-31: j = 3, E^I = 200/3 N, r^I = 20/sqrt(3) mm -> EA = 200 N and
    B = (3/2) E^I (r^I)^2 = 0.0133 N m^2 at stretch 1, growing with the stretch."""
    d = load_design(preset)
    np.testing.assert_array_equal(
        solve_statics(d, [95e3, 0.0, 0.0]).position,
        solve_statics(base, [95e3, 0.0, 0.0]).position,
    )
    for k in (1, 3):  # the two chamber modules
        sec = d.spec["sections"][k]
        assert sec["partition"]["j"] == 3
        assert "ea" not in sec["stiffness"] and "ei1" not in sec["stiffness"]
        props = d.sections()[k]
        # 1e-5 relative: E_I is written with 6 digits (66.6667 N) and r_I as 11.547 mm.
        assert props["k_se"][2] == pytest.approx(200.0, rel=1e-5)
        assert props["k_bt"][0][0] == pytest.approx(
            1.5 * 200 / 3 * (0.02 / math.sqrt(3)) ** 2, rel=1e-5
        )


def test_paper004_example_prints_seven_positions():
    """examples/paper004_extreme_positions.py runs and prints positions 1-7 for both loads."""
    script = Path(__file__).resolve().parents[1] / "examples" / "paper004_extreme_positions.py"
    out = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=60, check=True
    ).stdout
    for name in ("paper004 (no load)", "paper004_1N_tip (1 N at the tip)"):
        assert name in out
    rows = [line.split() for line in out.splitlines() if line.strip()[:1].isdigit()]
    assert [int(r[0]) for r in rows] == list(range(1, 8)) * 2
    assert all(r[-1] == "True" for r in rows)  # converged
    assert [r[1] for r in rows[:7]] == ["1", "1+2", "2", "2+3", "3", "3+1", "1+2+3"]
    lateral = np.array([float(r[-2]) for r in rows])  # mm
    # One or two chambers bend the actuator by tens of mm; all three only stretch it; the
    # 1 N weight straightens it (less lateral reach).
    # (printed to 0.01 mm; position 7 is symmetric, so its lateral reach prints as 0.00)
    assert np.all(lateral[0:6] > 20.0) and lateral[6] == 0.0 and lateral[13] == 0.0
    assert np.all(lateral[7:13] < lateral[0:6])
