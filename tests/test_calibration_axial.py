"""Axial-only identification (paper 004, Sec. 3.1): fits, standard errors, designs, inputs."""

import math

import numpy as np
import pandas as pd
import pytest
import softrod
from softrod import InputError, load_design, solve_statics
from softrod.calibration import (
    AxialData,
    axial_example_paths,
    calibrate_axial,
    identify_axial,
    load_axial_data,
    synthesize_axial_data,
    write_axial_data,
)
from softrod.calibration import axial as axial_module
from softrod.calibration.axial import AXIAL_EXAMPLE, _axial_example

pytestmark = pytest.mark.fast  # linear fits and a few straight-rod solves: seconds in all

BASE = "modular_two_module"
E_TRUE = 200.0  # N, paper 004 Table 1 / Sec. 4.1
A_TRUE = 33.0 / (3 * 96e3)  # m^2, 33 N at 96 kPa for three chambers (Sec. 3.1)
L0_TRUE = 44.8e-3  # m, L_c,0 of Actuator 2 (Table 1), the base design's module length

# Estimates from noisy data must lie within this many of their reported standard errors
# (3 sigma: a correct estimate fails with probability 0.3 % per quantity and seed).
N_SIGMA = 3.0
# Noise-free data are fitted exactly up to rounding in the linear algebra (condition of the
# scaled normal equations ~1e2 times 1e-16).
EXACT_RTOL = 1e-10
# The design's elongation against the fit: the strain of a straight, gravity-free section is
# uniform, so RK4 integrates it exactly; what is left is the solver tolerance (1e-10 on the
# scaled residual) and the 12 digits the design stores. 1 nm on elongations of up to 7 mm
# is far below any measurement and far above those errors.
ELONGATION_ATOL = 1e-9  # m


def e_of_f(force):
    """A progressive stiffness as in Sec. 3.1: E(0) = 240 N falling to 165 N (20 % stretch)
    at 33 N, of the form 1/(c1 + c2 F) the table fit uses."""
    c1 = 1 / 240.0
    c2 = (1 / 165.0 - c1) / 33.0
    return 1.0 / (c1 + c2 * np.asarray(force))


def noisy(seed, E=E_TRUE, **kw):
    """Five pressure levels, force 25 rows (three cycles), length 5 repeats per level."""
    kw.setdefault("length_pressure", np.repeat([0.0, 24e3, 48e3, 72e3, 96e3], 5))
    return synthesize_axial_data(
        E=E, A_eff=A_TRUE, L0=L0_TRUE, force_noise_N=0.2, length_noise_mm=0.1, seed=seed, **kw
    )


def _arrays(d):
    return d.force_pressure, d.force, d.length_pressure, d.length


def within(value, truth, se):
    assert abs(value - truth) <= N_SIGMA * se, (value, truth, se)


# --- identification ------------------------------------------------------------------------


def test_constant_round_trip_within_standard_errors():
    for seed in (1, 2, 3):
        r = identify_axial(noisy(seed))
        within(r.E, E_TRUE, r.E_se)
        within(r.A_eff, A_TRUE, r.A_eff_se)
        within(r.L0, L0_TRUE, r.L0_se)
        # The errors are small enough to mean something (not inflated to pass).
        assert r.E_se < 0.02 * E_TRUE and r.A_eff_se < 0.01 * A_TRUE
        assert r.force_quality.dof == 24 and r.length_quality.dof == 23
        assert r.force_quality.unit == "N" and r.length_quality.unit == "m"
        # The residuals are data minus fit, row by row.
        d = r.data
        np.testing.assert_allclose(d.force - r.predict_force(d.force_pressure), r.force_residuals)
        np.testing.assert_allclose(
            d.length - r.predict_length(d.length_pressure), r.length_residuals, atol=1e-15
        )


def test_standard_errors_match_the_scatter_of_the_estimates():
    # 300 noisy data sets: the spread of the estimates must equal the reported standard
    # error. The sample standard deviation of 300 normal values is within +-12 % (3 sigma of
    # 1/sqrt(2*299)) of the truth; E is a ratio, so allow [0.85, 1.15].
    fits = [identify_axial(noisy(seed)) for seed in range(100, 400)]
    for name in ("E", "A_eff", "L0"):
        values = np.array([getattr(r, name) for r in fits])
        se = np.mean([getattr(r, f"{name}_se") for r in fits])
        assert 0.85 < values.std(ddof=1) / se < 1.15, name


def test_noise_free_recovery_is_exact_for_every_option():
    clean = synthesize_axial_data(E=E_TRUE, A_eff=A_TRUE, L0=L0_TRUE, force_offset=0.5)
    r = identify_axial(clean, force_law="affine")
    for value, truth in ((r.E, E_TRUE), (r.A_eff, A_TRUE), (r.L0, L0_TRUE), (r.force_offset, 0.5)):
        assert value == pytest.approx(truth, rel=EXACT_RTOL)
    # A proportional law on offset data is biased: the option matters.
    assert identify_axial(clean).A_eff > A_TRUE * 1.005
    # L0 given: the fit goes through the origin in strain and reports no L0 error.
    given = AxialData(
        clean.force_pressure, clean.force - 0.5, clean.length_pressure, clean.length, L0=L0_TRUE
    )
    r = identify_axial(given)
    assert r.E == pytest.approx(E_TRUE, rel=EXACT_RTOL) and r.L0_se == 0 and not r.L0_fitted


def test_rigid_length_is_not_stretched():
    # Lengths measured over 10 mm of stiff caps: the chambers' strain is (L - L0)/(L0 - 10 mm).
    clean = synthesize_axial_data(E=E_TRUE, A_eff=A_TRUE, L0=L0_TRUE)
    over_caps = AxialData(
        clean.force_pressure,
        clean.force,
        clean.length_pressure,
        clean.length + 10e-3,
        rigid_length=10e-3,
    )
    r = identify_axial(over_caps)
    assert r.E == pytest.approx(E_TRUE, rel=EXACT_RTOL)
    assert r.L0 == pytest.approx(L0_TRUE + 10e-3, rel=EXACT_RTOL)
    assert identify_axial(AxialData(*_arrays(over_caps))).E > 1.2 * E_TRUE  # caps ignored


def test_force_dependent_stiffness_table_recovered():
    clean = synthesize_axial_data(E=e_of_f, A_eff=A_TRUE, L0=L0_TRUE)
    r = identify_axial(clean, stiffness="table")
    # Table at F = 0 and at the force of each pressure level of the length data.
    np.testing.assert_allclose(r.table_force, A_TRUE * 3 * np.arange(0, 97e3, 24e3), rtol=1e-12)
    np.testing.assert_allclose(r.table_stiffness, e_of_f(r.table_force), rtol=EXACT_RTOL)
    assert r.stiffness_at(33.0) == pytest.approx(165.0, rel=EXACT_RTOL)
    assert np.all(np.diff(r.table_stiffness) < 0)  # softer at higher force (Sec. 3.1)
    # A constant E cannot describe it: its residuals are far above the table fit's.
    assert identify_axial(clean).length_quality.rms > 1e3 * r.length_quality.rms
    # Noisy: every table value and both compliances within 3 standard errors.
    for seed in (11, 12):
        r = identify_axial(noisy(seed, E=e_of_f), stiffness="table")
        for f, e, se in zip(r.table_force, r.table_stiffness, r.table_stiffness_se, strict=True):
            within(e, float(e_of_f(f)), se)
        within(r.compliance[0], 1 / 240.0, r.compliance_se[0])
        within(r.compliance[1], (1 / 165.0 - 1 / 240.0) / 33.0, r.compliance_se[1])


def test_bending_stiffness_follows_eq_31():
    r = identify_axial(synthesize_axial_data(E=E_TRUE, A_eff=A_TRUE, L0=L0_TRUE))
    r_I = 20e-3 / math.sqrt(3)  # Table 1
    # eq. 31: B = (3/2) E_I r_I^2 L_c/L_c0 with E = 3 E_I.
    assert r.bending_stiffness(r_I, 1.2) == pytest.approx(1.5 * (E_TRUE / 3) * r_I**2 * 1.2)


# --- designs ---------------------------------------------------------------------------------


def _module_strain(design, pressure):
    """Strain of module_1 (section 1) under equal pressures, gravity off (pure pressure)."""
    still = design.replace({"mounting.gravity": "0 m/s^2"})
    sol = solve_statics(still, [pressure] * 3)
    idx = np.flatnonzero(sol.section == 1)
    ends = sol.position[[idx[0] - 1, idx[-1]]]  # the node before the section is its start
    return np.linalg.norm(ends[1] - ends[0]) / L0_TRUE - 1.0


@pytest.mark.parametrize("stiffness", ["constant", "table"])
def test_design_elongation_matches_the_data(stiffness):
    E = E_TRUE if stiffness == "constant" else e_of_f
    # Noise-free data: the design's pure-pressure elongation is the data's.
    clean = synthesize_axial_data(E=E, A_eff=A_TRUE, L0=L0_TRUE)
    design = identify_axial(clean, stiffness=stiffness).to_design(BASE)
    for p, length in zip(clean.length_pressure, clean.length, strict=True):
        assert abs(L0_TRUE * (1 + _module_strain(design, p)) - length) < ELONGATION_ATOL
    # Noisy data: the design reproduces the fit, i.e. the data up to the fit's residuals.
    r = identify_axial(noisy(21, E=E), stiffness=stiffness)
    design = r.to_design(BASE)
    d = r.data
    for p, length, res in zip(d.length_pressure, d.length, r.length_residuals, strict=True):
        model = r.L0 + (r.L0 - d.rigid_length) * _module_strain(design, p)
        assert abs((length - model) - res) < ELONGATION_ATOL


def test_design_contents_and_written_file(tmp_path):
    force, length = axial_example_paths()
    out = tmp_path / "identified.toml"
    r, written = calibrate_axial(force, length, BASE, out, n_chambers=3)
    memory = r.to_design(BASE)
    assert written.source == out and written.spec == memory.spec
    assert written.name == "modular_two_module_axial"
    sec = memory.document["sections"][1]
    assert sec["partition"]["j"] == 3 and "EA" not in sec
    assert float(sec["partition"]["E_I"].split()[0]) == pytest.approx(r.E / 3, rel=1e-11)
    for ch in memory.spec["sections"][3]["chambers"]:
        assert ch["area"] == pytest.approx(r.A_eff, rel=1e-11)
    # EA = E and EI = E r_I^2 / 2 at stretch 1 (eqs. 23, 29-31), as compiled by the core,
    # with r_I the design's chamber distance.
    base = load_design(BASE)
    r_I = base.spec["sections"][1]["chambers"][0]["distance"]
    compiled = memory.sections()[1]
    assert compiled["k_se"][2] == pytest.approx(r.E, rel=1e-11)
    assert compiled["k_bt"][0][0] == pytest.approx(0.5 * r.E * r_I**2, rel=1e-11)
    line = written.assumptions[-1]
    assert "SYNTHETIC" in line and force.name in line and length.name in line
    assert f"E = {r.E:.5g}" in line and f"A_eff = {r.A_eff * 1e6:.5g}" in line
    assert written.assumptions[:-1] == base.assumptions
    # Same solution from the file and from memory, with gravity and a bending pressure.
    for p in ([95e3, 0, 0], [95e3, 95e3, 0], [0, 0, 0]):
        a, b = solve_statics(written, p), solve_statics(memory, p)
        np.testing.assert_array_equal(a.tip_position, b.tip_position)
        assert a.converged
    # Pressurising one chamber bends the emitted design away from it (it really solves).
    assert np.linalg.norm(solve_statics(written, [95e3, 0, 0]).tip_position[:2]) > 20e-3


def test_table_design_contents():
    r = identify_axial(synthesize_axial_data(E=e_of_f, A_eff=A_TRUE, L0=L0_TRUE), stiffness="table")
    design = r.to_design(BASE, name="tabled")
    sec = design.spec["sections"][1]
    assert "partition" not in design.document["sections"][1]
    assert sec["law"]["axial"]["kind"] == "table" and sec["law"]["stretch_bending"]
    np.testing.assert_allclose(sec["law"]["axial"]["stiffness"], r.table_stiffness, rtol=1e-11)
    r_I = sec["chambers"][0]["distance"]
    assert sec["stiffness"]["ei1"] == pytest.approx(0.5 * r.E * r_I**2, rel=1e-11)
    assert design.name == "tabled" and "axial = 'table'" in design.assumptions[-1]


# --- inputs ----------------------------------------------------------------------------------


def test_bundled_example_is_synthetic_and_reproducible():
    force, length = axial_example_paths()
    for path in (force, length):
        assert path.read_text().startswith("# SYNTHETIC")
    data = load_axial_data(force, length)
    fresh = _axial_example()
    assert data.synthetic and data.metadata["seed"] == AXIAL_EXAMPLE["seed"]
    for a, b in zip(_arrays(data), _arrays(fresh), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12)  # kPa/mm text round trip
    r = identify_axial(data)
    within(r.E, AXIAL_EXAMPLE["E_N"], r.E_se)
    assert "SYNTHETIC" in r.summary() and "A_eff" in r.summary()


def test_write_and_load_round_trip(tmp_path):
    data = noisy(5)
    f, ln = write_axial_data(data, tmp_path / "f.csv", tmp_path / "l.csv")
    back = load_axial_data(f, ln, L0="44.8 mm")
    for a, b in zip(_arrays(back), _arrays(data), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12)
    assert back.metadata == data.metadata and back.L0 == pytest.approx(L0_TRUE)
    assert back.sources == (f, ln)
    # DataFrames with other spellings of the units, per-chamber pressures and a units block.
    force_df = pd.DataFrame(
        {
            "p0 [bar]": [0, 0.5, 1.0],
            "p1_kPa": [0, 50, 100],
            "p2": [0, 50e3, 100e3],
            "force [mN]": [0, 17e3, 34e3],
        }
    )
    force_df.attrs["softrod.units"] = {"p2": "Pa"}
    length_df = pd.DataFrame({"pressure_kPa": [0, 50, 100], "length [cm]": [4.0, 4.4, 4.8]})
    d = load_axial_data(force_df, length_df)
    np.testing.assert_allclose(d.force_pressure, [0, 50e3, 100e3])
    np.testing.assert_allclose(d.force, [0, 17, 34])
    np.testing.assert_allclose(d.length, [0.04, 0.044, 0.048])


BAD = [
    # (id, which table, header, rows, fragments the message must contain)
    (
        "nan-row",
        "force",
        "pressure [kPa],force [N]",
        ["0,0", "24,", "48,16", "72,nan", "96,33"],
        ["lines 5, 7", "2 row(s)"],
    ),
    (
        "text",
        "length",
        "pressure [kPa],length [mm]",
        ["0,44.8", "48,4x8.1", "96,52"],
        ["length [mm]", "'4x8.1'", "line 5"],
    ),
    (
        "negative-pressure",
        "force",
        "pressure [kPa],force [N]",
        ["0,0", "-24,8", "48,16"],
        ["must be >= 0", "line 5"],
    ),
    (
        "non-monotone",
        "length",
        "pressure [kPa],length [mm]",
        ["0,44.8", "48,49", "96,48"],
        ["increase strictly", "48 -> 96 kPa (49 -> 48 mm)"],
    ),
    (
        "one-level",
        "force",
        "pressure [kPa],force [N]",
        ["96,33", "96,33.1"],
        ["too few points", "1 pressure level"],
    ),
    ("no-unit", "force", "pressure,force [N]", ["0,0", "96,33"], ["needs a unit", "pressure"]),
    (
        "wrong-unit",
        "length",
        "pressure [kPa],length [kPa]",
        ["0,44.8", "96,52"],
        ["length [kPa]", "wrong unit"],
    ),
    (
        "unknown-column",
        "force",
        "pressure [kPa],force [N],time [s]",
        ["0,0,0", "96,33,1"],
        ["unknown column", "time [s]"],
    ),
    ("no-force", "force", "pressure [kPa]", ["0", "96"], ["missing force column"]),
    (
        "length-in-force",
        "force",
        "pressure [kPa],length [mm]",
        ["0,0", "96,33"],
        ["unknown column", "length [mm]"],
    ),
    (
        "unequal-chambers",
        "force",
        "p0 [kPa],p1 [kPa],p2 [kPa],force [N]",
        ["0,0,0,0", "48,48,48.2,16", "96,90,96,33"],
        ["differ by more than", "line 6"],
    ),
    ("two-chambers", "force", "p0 [kPa],p1 [kPa],force [N]", ["0,0,0", "96,96,33"], ["p0 ... p2"]),
]


@pytest.mark.parametrize("case", BAD, ids=[c[0] for c in BAD])
def test_bad_csv_rejected_with_rows(tmp_path, case):
    _, which, header, rows, fragments = case
    force, length = axial_example_paths()  # the other table is valid
    bad = tmp_path / f"{which}.csv"
    # Two comment lines and the header: the first data row is line 4 in an editor.
    bad.write_text(f"# a comment line\n# another\n{header}\n" + "\n".join(rows) + "\n")
    args = (bad, length) if which == "force" else (force, bad)
    with pytest.raises(InputError) as info:
        load_axial_data(*args)
    message = str(info.value)
    assert message.startswith(f"{which}.csv: ")
    for fragment in fragments:
        assert fragment in message, message


def test_bad_frames_and_arrays():
    force = pd.DataFrame(
        {"pressure [kPa]": [0, 48, 96], "force [N]": [0, np.nan, 33]}, index=[10, 11, 12]
    )
    length = pd.DataFrame({"pressure [kPa]": [0, 96], "length [mm]": [44.8, 52]})
    with pytest.raises(InputError, match="at index 11;"):
        load_axial_data(force, length)
    with pytest.raises(InputError, match=r"force_pressure = -1.0: must be >= 0.*row 1"):
        AxialData([0, -1, 2], [0, 1, 2], [0, 1], [1, 2])
    with pytest.raises(InputError, match="length = nan: must be finite, at rows 1-2"):
        AxialData([0, 1], [0, 1], [0, 1, 2], [1, np.nan, np.nan])
    with pytest.raises(InputError, match="L0 = 0.01: must exceed rigid_length"):
        AxialData([0, 1], [0, 1], [0, 1], [1, 2], L0=0.01, rigid_length=0.02)
    # Too few points for the chosen fit: three levels suffice for a line, not for E(F)
    # with a fitted L0 (three parameters and a standard error need four rows, three levels).
    few = AxialData([0, 1e4, 2e4], [0, 3, 6], [0, 1e4, 2e4], [0.04, 0.041, 0.0421])
    identify_axial(few)
    with pytest.raises(InputError, match="too few points for the E.F. .L0 fitted. fit"):
        identify_axial(few, stiffness="table")
    with pytest.raises(InputError, match="stiffness = 'secant'"):
        identify_axial(few, stiffness="secant")


# --- no partial files ------------------------------------------------------------------------


def test_no_file_when_writing_fails(tmp_path, monkeypatch):
    r = identify_axial(_axial_example())
    missing = tmp_path / "no_such_folder" / "design.toml"
    with pytest.raises(InputError, match="does not exist"):
        r.to_design(BASE, missing)
    assert not missing.parent.exists()
    with pytest.raises(InputError, match="must end in .toml"):
        r.to_design(BASE, tmp_path / "design.txt")
    # A design the identification does not fit (four chambers measured, three in the design).
    data = _axial_example()
    four = AxialData(*_arrays(data), n_chambers=4, metadata=data.metadata)
    out = tmp_path / "design.toml"
    with pytest.raises(InputError, match="n_chambers = 4"):
        identify_axial(four).to_design(BASE, out)
    # A base design with a law the identification cannot represent (sigma(p) scaling).
    mapped = load_design(BASE).replace({"sections[1].law": {"stiffness_map": True}})
    with pytest.raises(InputError, match=r"sections\[1\].law.stiffness_map"):
        r.to_design(mapped, out)
    assert list(tmp_path.iterdir()) == []
    # A failure while writing leaves an older file untouched and no temporary file.
    out.write_text("old")

    def broken(doc):
        raise OSError("disk full")

    monkeypatch.setattr("tomli_w.dumps", broken)
    with pytest.raises(OSError, match="disk full"):
        r.to_design(BASE, out)
    assert out.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["design.toml"]


def test_public_names():
    import softrod.calibration as calibration

    for name in axial_module.__all__:
        assert getattr(axial_module, name) is not None
    for name in (
        "AxialData",
        "identify_axial",
        "load_axial_data",
        "calibrate_axial",
        "synthesize_axial_data",
        "write_axial_data",
        "axial_example_paths",
    ):
        assert getattr(calibration, name) is getattr(axial_module, name)
        assert name in calibration.__all__
    assert softrod.load_design is load_design
