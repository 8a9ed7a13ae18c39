"""Stability and validity of static solutions (docs/model.md, "Validity and stability"):
the buckled column against the elastica, the unstable straight column, the invalid states
of issues 13 and 14 (negative stretch, pressures far beyond the operating range, absurd
pressures), stability of the bundled designs, and the boundary of the Rust core (no panic
or abort on huge channel indices; JSON errors name the field)."""

import json
import warnings

import numpy as np
import pytest
import softrod
from scipy.optimize import brentq
from scipy.special import ellipeinc, ellipkinc
from softrod import (
    DesignError,
    InternalError,
    InvalidStateError,
    SolverOptions,
    StabilityWarning,
    ValidityWarning,
    load_design,
    solve_statics,
    solve_statics_batch,
)

pytestmark = pytest.mark.fast

L = 1.0  # m
EI = 1.0  # N m^2
P_CR = np.pi**2 * EI / (4 * L**2)  # Euler load of the clamped-free column


def column(steps: int = 400, chambers: list | None = None) -> softrod.Design:
    """An upright column, clamped at the base, weightless; extension and shear 1e10 times
    stiffer than bending (EA L^2 / EI), so it is the inextensible elastica to ~1e-9 L."""
    extra = {} if chambers is None else {"chambers": chambers}
    return load_design(
        {
            "design": {"name": "column", "citation": "Euler column, clamped-free"},
            "mounting": {"orientation": "upright", "gravity": "0 m/s^2"},
            "sections": [
                {
                    "name": "column",
                    "length": f"{L} m",
                    "mass": "0 kg",
                    "EA": "1e10 N",
                    "GA": "1e10 N",
                    "EI": f"{EI} N*m^2",
                    "GJ": f"{2 * EI} N*m^2",
                    "steps": steps,
                    **extra,
                }
            ],
        }
    )


def elastica_tip(p: float, h: float) -> tuple[float, float]:
    """Tip (lateral, vertical) of the inextensible elastica clamped upright at the base under
    a dead tip force of h along +x and p down, on the branch that bends with h (no
    inflection point), by elliptic integrals.

    With theta the angle from +z towards +x, EI theta'' = -(h cos theta + p sin theta) =
    -F sin(psi), F = hypot(p, h), psi = theta + gamma, tan gamma = h / p. With
    sin(psi / 2) = k sin(phi): L sqrt(F / EI) = K(k) - F(phi0, k), sin(phi0) =
    sin(gamma / 2) / k; int sin(psi) ds = 2 k cos(phi0) c and int cos(psi) ds =
    (2 (E(k) - E(phi0, k)) - (K(k) - F(phi0, k))) c, c = sqrt(EI / F)."""
    f = np.hypot(p, h)
    gamma = np.arctan2(h, p)
    s0 = np.sin(gamma / 2)
    c = np.sqrt(EI / f)

    def phi0(k):
        return np.arcsin(min(1.0, s0 / k))

    def length_error(k):
        m = k * k
        return (ellipkinc(np.pi / 2, m) - ellipkinc(phi0(k), m)) * c - L

    k = brentq(length_error, s0 * (1 + 1e-12), 1 - 1e-15, xtol=1e-16, rtol=1e-15)
    m = k * k
    big_f = ellipkinc(np.pi / 2, m) - ellipkinc(phi0(k), m)
    big_e = ellipeinc(np.pi / 2, m) - ellipeinc(phi0(k), m)
    s_int = 2 * k * np.cos(phi0(k)) * c
    c_int = (2 * big_e - big_f) * c
    x = np.cos(gamma) * s_int - np.sin(gamma) * c_int
    z = np.cos(gamma) * c_int + np.sin(gamma) * s_int
    return float(x), float(z)


def test_elastica_reference_reduces_to_the_linear_beam():
    # Tiny loads: the tip deflects by h L^3 / (3 EI) (the reference itself is checked).
    x, z = elastica_tip(1e-9, 1e-6)
    assert abs(x - 1e-6 * L**3 / (3 * EI)) < 1e-12 and abs(z - L) < 1e-9


@pytest.mark.parametrize("ratio", [1.5, 2.0])
def test_straight_column_above_the_buckling_load_is_flagged_unstable(ratio):
    d = column(200)
    with pytest.warns(StabilityWarning, match="unstable equilibrium"):
        sol = solve_statics(d, [], tip_force=[0, 0, -ratio * P_CR])
    assert sol.stable is False
    assert np.abs(sol.tip_position[:2]).max() < 1e-12  # the perfect column stays straight
    with pytest.raises(InvalidStateError, match="unstable") as err:
        solve_statics(d, [], tip_force=[0, 0, -ratio * P_CR], on_unstable="raise")
    assert err.value.rule == "stability"
    failed = solve_statics(d, [], tip_force=[0, 0, -ratio * P_CR], on_unstable="raise", check=False)
    assert failed.converged is False
    below = solve_statics(d, [], tip_force=[0, 0, -0.9 * P_CR])
    assert below.stable is True


@pytest.mark.parametrize("ratio", [1.5, 2.0])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_column_with_a_lateral_imperfection_bends_with_the_force(ratio, sign):
    p = ratio * P_CR
    h = 1e-3 * p
    sol = solve_statics(column(), [], tip_force=[sign * h, 0, -p])
    assert sol.stable is True
    x, z = elastica_tip(p, h)
    assert sign * sol.tip_position[0] > 0.1 * L  # it buckled, towards the force
    # 1e-6 L: 400 RK4 steps (~1e-10 L) and the extensibility (P / EA ~ 5e-10) are far below.
    assert abs(sign * sol.tip_position[0] - x) < 1e-6 * L
    assert abs(sol.tip_position[2] - z) < 1e-6 * L


@pytest.mark.parametrize(("ratio", "rel"), [(1.01, 1e-4), (1.05, 1e-6), (2.0, 1e-8), (3.0, 1e-6)])
def test_column_with_a_tiny_imperfection_still_bends_with_the_force(ratio, rel):
    """Just past the Euler load, or far past it, a lateral force of 1e-4 to 1e-8 of the axial
    one turns the path off the straight branch within about rel^(2/3) of the buckling load
    (Koiter): the continuation resolves that turn and returns the stable elastica, not the
    straight column (at 2 P_cr with rel = 1e-8 it returned the straight, unstable one)."""
    p = ratio * P_CR
    sol = solve_statics(column(), [], tip_force=[rel * p, 0, -p])
    assert sol.stable is True
    x, z = elastica_tip(p, rel * p)
    # 1e-6 L, as in the test above: RK4 and the extensibility are far below it.
    assert abs(sol.tip_position[0] - x) < 1e-6 * L
    assert abs(sol.tip_position[2] - z) < 1e-6 * L


def straight_finger() -> softrod.Design:
    """The bundled tendon finger without its pre-bend and without gravity: an 80 mm silicone
    column whose Euler load under a dead tip force is about 0.39 N."""
    d = load_design("prebent_tendon_finger")
    sec = dict(d.document["sections"][0])
    sec.pop("bend_radius")
    sec.pop("bend_direction")
    return d.replace({"sections": [sec], "mounting.gravity": "0 m/s^2"})


@pytest.mark.parametrize("axial", [0.5, 1.0])
@pytest.mark.parametrize("lateral", [1e-4, 1e-6])
def test_soft_finger_past_its_buckling_load_takes_the_stable_branch(axial, lateral):
    """1.3 and 2.6 times the Euler load with a lateral force of 1e-4 or 1e-6 of it: the
    finger buckles towards the force. (It returned the straight, unstable equilibrium: the
    continuation's loose intermediate levels strayed 0.3 rad from the path near the
    critical load, where the Jacobian is nearly singular, and the step cut stopped at 1/64.)
    Independent check of the branch: Newton warm-started from the solution under a 1000
    times larger lateral force lands on the same equilibrium."""
    d = straight_finger()
    force = [lateral * axial, 0.0, -axial]
    sol = solve_statics(d, [0.0], tip_force=force)
    assert sol.stable is True
    assert sol.tip_position[0] > 0.5 * d.length  # buckled, towards the force
    nearby = solve_statics(d, [0.0], tip_force=[1e3 * lateral * axial, 0.0, -axial])
    warm = solve_statics(d, [0.0], tip_force=force, initial=nearby)
    # Both are the same equilibrium solved to tol = 1e-10 (relative, scaled unknowns):
    # 1e-9 of the length bounds their difference with room for the conditioning.
    assert np.abs(warm.tip_position - sol.tip_position).max() < 1e-9 * d.length


def test_a_stable_path_ending_outside_the_validity_range_is_not_replaced_by_the_straight_one():
    """Five times its Euler load, the finger buckles so far that fibres at its base stretch
    below the strain range: the answer is that error (rule strain_range), not the straight,
    unstable equilibrium met on the way, which was returned with only a stability warning."""
    d = straight_finger()
    force = [1e-4 * 2.0, 0.0, -2.0]
    with pytest.raises(InvalidStateError) as err:
        solve_statics(d, [0.0], tip_force=force)
    assert err.value.rule == "strain_range"
    with pytest.warns(ValidityWarning):
        sol = solve_statics(d, [0.0], tip_force=force, on_invalid="warn")
    assert sol.stable is True and sol.tip_position[0] > 0.4 * d.length


def soft_rod(length: float, orientation: str) -> softrod.Design:
    """A soft silicone rod (E = 100 kPa, nu = 0.5, 1000 kg/m^3, r = 12.5 mm) under its own
    weight, 32 steps. At 1 m single shooting's growth exponent int sqrt(|n| / EI) ds is 33
    (beyond 12), so statics solves it by collocation (docs/model.md, "Collocation")."""
    return load_design(
        {
            "design": {"name": "soft_rod", "citation": "a soft silicone rod"},
            "mounting": {"orientation": orientation, "gravity": "9.81 m/s^2"},
            "materials": {"soft": {"E": "100 kPa", "poisson": 0.5, "density": "1000 kg/m^3"}},
            "sections": [
                {
                    "name": "rod",
                    "length": f"{length} m",
                    "material": "soft",
                    "outer_radius": "12.5 mm",
                    "steps": 32,
                }
            ],
        }
    )


def test_collocation_solutions_report_stability():
    # Upright, the 1 m soft rod stands at q L^3 / EI = 2510, 320 times Greenhill's
    # self-weight load 7.837: the straight column is an equilibrium (the one continuation
    # follows without an imperfection) and it is unstable, which a collocation solve now
    # says as a shooting solve does. Hanging, the same rod is stable.
    upright = soft_rod(1.0, "upright")
    with pytest.warns(StabilityWarning, match="unstable equilibrium"):
        sol = solve_statics(upright, [])
    assert sol.stable is False
    assert np.abs(sol.tip_position[:2]).max() < 1e-9  # straight
    with pytest.raises(InvalidStateError, match="unstable") as err:
        solve_statics(upright, [], on_unstable="raise")
    assert err.value.rule == "stability"
    with warnings.catch_warnings():
        warnings.simplefilter("error", StabilityWarning)
        hanging = solve_statics(soft_rod(1.0, "hanging"), [])
    # Clamped horizontally it hangs down (tip > 0.9 L below), bent at the clamp beyond
    # the default fibre-stretch range (docs/model.md "Collocation"): a ValidityWarning, and
    # no StabilityWarning.
    with pytest.warns(ValidityWarning, match="strain_range") as record:
        horizontal = solve_statics(soft_rod(1.0, "horizontal"), [], on_invalid="warn")
    assert not [w for w in record if issubclass(w.category, StabilityWarning)]
    assert hanging.stable is True and horizontal.stable is True
    assert horizontal.tip_position[2] < -0.9


def test_negative_stretch_is_refused_naming_the_node():
    # issue 14: the tip 94 mm below the base with v3 = -0.87 came back "converged"
    with pytest.raises(InvalidStateError, match="stretch v3") as err:
        solve_statics("stiff_flop_pcc", [0.0] * 6, tip_force=[0, 0, -50])
    assert err.value.rule == "positive_stretch"
    assert err.value.node is not None and err.value.value <= 0


@pytest.mark.parametrize("bar", [5.0, 50.0])
def test_pressures_beyond_the_operating_range_are_refused(bar):
    d = load_design("spa_three_chamber_130mm")
    with pytest.raises(InvalidStateError, match="operating_range") as err:
        solve_statics(d, [bar * 1e5, 0, 0])
    assert err.value.rule == "operating_range" and err.value.value == bar * 1e5
    # asked to warn: the operating range warns, and the state is checked too (5 bar bends
    # the actuator beyond the strain range; 50 bar beyond what its steps can represent)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            sol = solve_statics(d, [bar * 1e5, 0, 0], on_invalid="warn")
        except InvalidStateError as exc:  # a physical rule: no state to warn about
            assert exc.rule in ("rotation", "positive_stretch", "stretch_limit", "chamber_collapse")
        else:
            assert any("operating_range" in v for v in sol.violations)
            assert any(issubclass(w.category, ValidityWarning) for w in caught)
    # a batch refuses the row before any work, naming it
    with pytest.raises(InvalidStateError, match="row 1"):
        solve_statics_batch(d, [[0, 0, 0], [bar * 1e5, 0, 0]])


def test_tensions_beyond_the_operating_range_are_refused():
    """A design's [operating_range] tension (till_tendon_robot: 0-20 N) bounds every tendon
    channel as the pressure range bounds the chambers: an error naming the channel before
    any work, a warning when asked, a batch row named."""
    d = load_design("till_tendon_robot")
    assert d.spec["operating_range"] == {"tension": [0.0, 20.0]}
    solve_statics(d, [], tensions=[20.0, 0, 0, 0])  # the bound itself is inside
    with pytest.raises(InvalidStateError, match=r"tensions\[2\] = 25(\.0)? N") as err:
        solve_statics(d, [], tensions=[0, 0, 25.0, 0])
    assert err.value.rule == "operating_range" and err.value.value == 25.0
    with pytest.warns(ValidityWarning):
        sol = solve_statics(d, [], tensions=[0, 0, 25.0, 0], on_invalid="warn")
    assert any("operating_range.tension" in v for v in sol.violations)
    with pytest.raises(InvalidStateError, match="row 1"):
        solve_statics_batch(d, np.zeros((2, 0)), tensions=[[1.0, 0, 0, 0], [0, 0, 0, 30.0]])


@pytest.mark.parametrize(
    "table, field",
    [
        ({"source": "x"}, "operating_range"),
        ({"tension": ["-1 N", "20 N"]}, "operating_range.tension"),
        ({"tension": ["20 N", "10 N"]}, "operating_range.tension"),
        ({"tension": ["0 kPa", "20 kPa"]}, "operating_range.tension[0]"),
        ({"tension": "20 N"}, "operating_range.tension"),
    ],
)
def test_bad_operating_ranges_name_the_field(table, field):
    doc = json.loads(json.dumps(load_design("till_tendon_robot").document))  # a deep copy
    doc["operating_range"] = table
    with pytest.raises(softrod.DesignError) as err:
        load_design(doc)
    assert err.value.field == field


@pytest.mark.parametrize("pressure", [1e9, 1e12, 1e15, 1e19])
def test_absurd_pressures_never_converge(pressure):
    # issue 13: 1e9 to 1e19 Pa "converged" with the tip 60 L to 1e12 L from the base. Even
    # with the validity ranges switched off, a physical rule or non-convergence stops them.
    with pytest.raises(softrod.ConvergenceError):
        solve_statics("spa_three_chamber_130mm", [pressure, pressure, 0], on_invalid="ignore")


def test_strain_range_is_configurable():
    d = load_design("spa_three_chamber_130mm")
    narrow = SolverOptions(stretch_range=(0.99, 1.01))
    with pytest.raises(InvalidStateError, match="fibre stretch") as err:
        solve_statics(d, [70e3, 0, 0], options=narrow)
    assert err.value.rule == "strain_range" and err.value.node is not None
    with pytest.warns(ValidityWarning, match="fibre stretch"):
        sol = solve_statics(d, [70e3, 0, 0], options=narrow, on_invalid="warn")
    assert sol.converged and len(sol.violations) == 1
    for bad in [(0.0, 2.0), (1.0, 2.0), (0.5, 1.0), (0.5, float("inf")), "wide"]:
        with pytest.raises(softrod.InputError, match="stretch_range"):
            SolverOptions(stretch_range=bad)
    with pytest.raises(softrod.InputError, match="on_invalid"):
        solve_statics(d, [0, 0, 0], on_invalid="maybe")


def test_batch_reports_stability_and_validity_per_row():
    # a batch needs a pressure channel: a 1 um chamber on the axis, always at 0 Pa
    dummy = [{"radius": "1 um", "distance": "0 mm", "angle": "0 deg", "channel": 0}]
    d = column(100, dummy)
    rows = np.zeros((3, 1))
    with pytest.warns(StabilityWarning, match="row"):
        out = solve_statics_batch(d, rows, tip_force=[0, 0, -2 * P_CR])
    assert out.converged.all() and not out.stable.any()
    frame = out.to_frame()
    assert "stable" in frame.columns and not frame["stable"].any()
    spa = load_design("spa_three_chamber_130mm")
    # at rest the hanging body stretches by 1.5 % under the cap's weight; at 70 kPa one side
    # shortens by 6.5 %
    narrow = SolverOptions(stretch_range=(0.95, 1.05))
    kept = solve_statics_batch(spa, [[0, 0, 0], [70e3, 0, 0]], options=narrow)
    assert kept.converged.tolist() == [True, False]
    assert kept.violation[0] == "" and "strain_range" in kept.violation[1]
    with pytest.warns(ValidityWarning, match="1 of 2 rows"):
        warned = solve_statics_batch(
            spa, [[0, 0, 0], [70e3, 0, 0]], options=narrow, on_invalid="warn"
        )
    assert warned.converged.all() and "strain_range" in warned.violation[1]


def _range_corners(design) -> tuple[np.ndarray, np.ndarray | None]:
    """Pressure and tension rows at the corners of the operating range: all inputs low, all
    high, each one high alone, all at mid-range (inputs without a stated range stay at 0)."""
    rng = design.spec["operating_range"]
    lows, highs = [], []
    for key, n in (("pressure", design.n_channels), ("tension", design.n_tendons)):
        lo, hi = rng.get(key, (0.0, 0.0))
        lows += [lo] * n
        highs += [hi] * n
    n = len(lows)
    rows = [lows, highs] + [[highs[k] if k == j else lows[k] for k in range(n)] for j in range(n)]
    rows = np.array(rows + [[0.5 * (a + b) for a, b in zip(lows, highs, strict=True)]])
    tensions = rows[:, design.n_channels :] if design.n_tendons else None
    return rows[:, : design.n_channels], tensions


@pytest.mark.parametrize("name", softrod.bundled_designs())
def test_bundled_designs_are_stable_across_their_operating_range(name):
    d = load_design(name)
    assert "operating_range" in d.spec, f"{name} states no operating range"
    pressures, tensions = _range_corners(d)
    out = solve_statics_batch(d, pressures, tensions=tensions, threads=1)
    assert out.converged.all(), out.violation
    assert out.stability_assessed.all(), name  # every bundled design has dead loads
    assert out.stable.all(), name


@pytest.mark.parametrize(
    "channel", [10**12, 2**63 - 1, 2**64 - 1], ids=["1e12", "i64_max", "u64_max"]
)
def test_huge_channel_indices_are_a_design_error_not_an_abort(channel):
    # issue 13: 1e12 aborted the interpreter (a 1e12-entry allocation), 2^63 - 1 and
    # 2^64 - 1 raised pyo3's PanicException (capacity overflow, index out of bounds).
    spec = load_design("spa_three_chamber_130mm").spec
    spec = json.loads(json.dumps(spec))
    spec["sections"][1]["chambers"][0]["channel"] = channel
    with pytest.raises(DesignError) as err:
        softrod._core.Rod(json.dumps(spec))
    assert err.value.field == "sections[1].chambers[0].channel"


def test_json_errors_name_the_field_path():
    spec = json.loads(json.dumps(load_design("spa_three_chamber_130mm").spec))
    spec["sections"][1]["chambers"][2]["channel"] = -1
    with pytest.raises(DesignError) as err:
        softrod._core.Rod(json.dumps(spec))
    assert err.value.field == "sections[1].chambers[2].channel"
    assert "-1" in str(err.value) and "line 1 column" not in str(err.value)
    spec["sections"][1]["chambers"][2]["channel"] = 2
    spec["sections"][0]["length"] = "long"
    with pytest.raises(DesignError) as err:
        softrod._core.Rod(json.dumps(spec))
    assert err.value.field == "sections[0].length"


def test_a_panic_in_the_core_is_an_internal_error():
    # every binding entry runs under the same guard; this entry panics on purpose
    with pytest.raises(InternalError, match="deliberate panic"):
        softrod._core._panic_inside_guard()
