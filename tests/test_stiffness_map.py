"""Pressure-dependent stiffness scaling sigma(p) (paper 001 eq. 13): StiffnessMap and its use
in solve_statics / solve_statics_batch. Closed forms, interpolation properties, CSV, errors."""

import math

import numpy as np
import pytest
from scipy.interpolate import RegularGridInterpolator
from softrod import (
    InputError,
    StiffnessMap,
    load_design,
    solve_statics,
    solve_statics_batch,
)

pytestmark = pytest.mark.fast

SPA = "spa_three_chamber_130mm"
L = 0.1  # m
EA = 100.0  # N
EI = 0.01  # N m^2
AREA = 20e-6  # m^2, chamber area
DIST = 0.008  # m, chamber centroid distance from the centreline
# Quantities of order 1 (strains, sigma) computed by a handful of flops: round-off only.
ROUND_OFF = 1e-14


def four_chamber_rod(mapped: bool = True) -> dict:
    """Upright rod with direct stiffnesses, no gravity, no tip body, four equal chambers on
    +d1, +d2, -d1, -d2 (channels 0..3)."""
    sec = {
        "name": "body",
        "length": f"{L} m",
        "mass": "10 g",
        "EA": f"{EA} N",
        "GA": "50 N",
        "EI": f"{EI} N*m^2",
        "GJ": "0.008 N*m^2",
        "steps": 16,
        "chambers": [
            {"area": f"{AREA} m^2", "distance": f"{DIST} m", "angle": f"{a} deg", "channel": k}
            for k, a in enumerate((0, 90, 180, 270))
        ],
    }
    if mapped:
        sec["law"] = {"stiffness_map": True}
    return {
        "design": {"name": "four_chamber_rod", "citation": "closed-form check"},
        "mounting": {"orientation": "upright", "gravity": "0 m/s^2"},
        "sections": [sec],
    }


def mapped_spa():
    """The bundled SPA with its body section mapped."""
    return load_design(SPA).replace({"sections[1].law": {"stiffness_map": True}})


def smooth_table():
    """A 3-channel table, 5 x 4 x 6 points, sigma between 0.3 and 1.9."""
    rng = np.random.default_rng(1)
    axes = [
        np.array([0.0, 10e3, 25e3, 40e3, 60e3]),
        np.array([0.0, 20e3, 45e3, 60e3]),
        np.linspace(0.0, 60e3, 6),
    ]
    return axes, rng.uniform(0.3, 1.9, (5, 4, 6, 3))


# -- the solver with a map ---------------------------------------------------------------------


def test_constant_unit_map_equals_unmapped_design():
    plain = load_design(SPA)
    mapped = mapped_spa()
    ones = StiffnessMap.constant((1.0, 1.0, 1.0), 3)
    for p in ([0.0, 0.0, 0.0], [40e3, 0.0, 0.0], [30e3, 50e3, 10e3]):
        a = solve_statics(plain, p)
        b = solve_statics(mapped, p, stiffness_map=ones)
        # sigma = 1 multiplies by exactly 1 and the inverse is recomputed by the same routine:
        # bitwise equal in practice; allow 1e-14 (round-off of the recomputed compliances).
        for name in ("position", "rotation", "force", "moment", "v", "u"):
            np.testing.assert_allclose(
                getattr(b, name), getattr(a, name), rtol=ROUND_OFF, atol=ROUND_OFF
            )
        np.testing.assert_array_equal(b.stiffness_scale, [1.0, 1.0, 1.0])
    np.testing.assert_array_equal(a.stiffness_scale, [1.0, 1.0, 1.0])


@pytest.mark.parametrize("sigma_ext", [1.0, 2.0, 0.5])
def test_equal_pressures_stretch_by_force_over_sigma_ea(sigma_ext):
    design = load_design(four_chamber_rod())
    p = 5e3  # Pa
    smap = StiffnessMap.constant((sigma_ext, 3.0, 0.7), 4)  # bending factors must not matter
    sol = solve_statics(design, [p] * 4, stiffness_map=smap)
    strain = 4 * p * AREA / (sigma_ext * EA)
    # Uniform stretch: the ODE is linear in s and RK4 integrates it exactly (round-off only).
    np.testing.assert_allclose(sol.v[:, 2], 1.0 + strain, rtol=ROUND_OFF)
    np.testing.assert_allclose(sol.tip_position, [0.0, 0.0, L * (1.0 + strain)], atol=ROUND_OFF)
    np.testing.assert_allclose(sol.u, 0.0, atol=ROUND_OFF)
    np.testing.assert_array_equal(sol.stiffness_scale, [sigma_ext, 3.0, 0.7])


@pytest.mark.parametrize(
    "chamber, body_axis, sigma_name", [(0, 1, "sigma_bend_y"), (1, 0, "sigma_bend_x")]
)
@pytest.mark.parametrize("factor", [1.0, 2.0, 0.25])
def test_one_chamber_bends_into_arc_with_curvature_over_sigma_bend(
    chamber, body_axis, sigma_name, factor
):
    """A chamber on d1 bends the rod about d2 (sigma_bend_y acts), one on d2 about d1
    (sigma_bend_x acts); the other factor has no effect."""
    design = load_design(four_chamber_rod())
    p = 5e3
    sigma = {"sigma_ext": 1.5, "sigma_bend_x": 7.0, "sigma_bend_y": 7.0}
    sigma[sigma_name] = factor
    smap = StiffnessMap.constant(tuple(sigma.values()), 4)
    pressures = [0.0] * 4
    pressures[chamber] = p
    sol = solve_statics(design, pressures, stiffness_map=smap)
    # Pressure moment sum p A (y, -x, 0): about -d2 for the +d1 chamber, about +d1 for +d2.
    kappa = p * AREA * DIST / (factor * EI) * (-1.0 if chamber == 0 else 1.0)
    expected_u = np.zeros(3)
    expected_u[body_axis] = kappa
    # Tip free, no gravity: the total moment vanishes, so u is the pressure shift exactly.
    np.testing.assert_allclose(sol.u, np.tile(expected_u, (len(sol.s), 1)), atol=ROUND_OFF)
    stretch = 1.0 + p * AREA / (1.5 * EA)
    np.testing.assert_allclose(sol.v[:, 2], stretch, rtol=ROUND_OFF)
    # Constant-curvature arc of angle kappa L and radius stretch / |kappa|, bending away from
    # the chamber. RK4 tip error C L (angle/steps)^4 with C < 0.02 (tests/test_statics_api.py).
    angle = abs(kappa) * L
    radius = stretch / abs(kappa)
    lateral = -radius * (1.0 - math.cos(angle))  # towards the opposite side
    tip = np.zeros(3)
    tip[chamber] = lateral  # d1 = world x, d2 = world y (upright, no roll)
    tip[2] = radius * math.sin(angle)
    tol = 0.02 * L * (angle / 16) ** 4 + ROUND_OFF
    np.testing.assert_allclose(sol.tip_position, tip, atol=tol)


def test_coupling_term_scales_with_geometric_mean():
    """With a product of area (chambers off the principal axes), K_bt(sigma) has
    EI_12 * sqrt(sigma_x sigma_y); u is then K_bt(sigma)^-1 times the pressure moment."""
    doc = {
        "design": {"name": "coupled", "citation": "closed-form check"},
        "mounting": {"orientation": "upright", "gravity": "0 m/s^2"},
        "sections": [
            {
                "name": "body",
                "length": "100 mm",
                "material": "ecoflex_00_50",
                "outer_radius": "15 mm",
                "law": {"stiffness_map": True},
                "chambers": [
                    {"radius": "4 mm", "distance": "8 mm", "angle": f"{a} deg", "channel": k}
                    for k, a in enumerate((30, 100))
                ],
            }
        ],
    }
    design = load_design(doc)
    sec = design.sections()[0]
    k_bt = np.array(sec["k_bt"])
    assert abs(k_bt[0, 1]) > 1e-2 * k_bt[0, 0]  # the coupling is really there
    p = np.array([3e3, 1e3])
    m_p = sum(p[ch] * a * np.array([y, -x, 0.0]) for a, x, y, ch in sec["chambers"])
    for sx, sy in ((1.0, 1.0), (0.5, 2.0), (3.0, 0.4)):
        k = k_bt.copy()
        k[0, 0] *= sx
        k[1, 1] *= sy
        k[0, 1] *= math.sqrt(sx * sy)
        k[1, 0] *= math.sqrt(sx * sy)
        sol = solve_statics(design, p, stiffness_map=StiffnessMap.constant((1.0, sx, sy), 2))
        # u of order 1/m from a 3x3 solve: round-off only.
        np.testing.assert_allclose(
            sol.u, np.tile(np.linalg.solve(k, m_p), (len(sol.s), 1)), atol=1e-13
        )


def test_batch_with_map_equals_single_solves():
    design = mapped_spa()
    axes, values = smooth_table()
    smap = StiffnessMap.from_table(axes, values)
    pressures = np.array(
        [[0.0, 0.0, 0.0], [20e3, 0.0, 0.0], [40e3, 10e3, 0.0], [55e3, 30e3, 12e3], [0, 0, 60e3]]
    )
    batch = solve_statics_batch(design, pressures, stiffness_map=smap, threads=2)
    assert batch.converged.all()
    np.testing.assert_array_equal(batch.stiffness_scale, smap(pressures))
    for k, p in enumerate(pressures):
        single = solve_statics(design, p, stiffness_map=smap)
        np.testing.assert_array_equal(single.stiffness_scale, batch.stiffness_scale[k])
        # Same solver, different warm starts: equal to the solver tolerance (1e-10 relative
        # residual gives ~1e-12 m here; allow 1e-10 m against a 130 mm rod).
        np.testing.assert_allclose(single.tip_position, batch.tip_position[k], atol=1e-10)
    # The map matters: sigma = 1 gives a different shape.
    plain = solve_statics_batch(load_design(SPA), pressures)
    assert np.abs(plain.tip_position - batch.tip_position).max() > 1e-3
    assert plain.stiffness_scale is None


def _networks(seed: int, activation: str, hidden=(12, 10)) -> list[dict]:
    """Three random networks (3 channels, pressures standardised around 30 kPa)."""
    rng = np.random.default_rng(seed)
    sizes = [3, *hidden, 1]
    return [
        {
            "input_mean": [3e4, 3e4, 3e4],
            "input_scale": [2e4, 2e4, 2e4],
            "weights": [
                rng.normal(size=(a, b)) for a, b in zip(sizes[:-1], sizes[1:], strict=True)
            ],
            "biases": [rng.normal(size=b) for b in sizes[1:]],
            "activation": activation,
            "target_mean": 0.0,
            "target_scale": 0.1,
        }
        for _ in range(3)
    ]


@pytest.mark.parametrize("activation", ["tanh", "relu", "logistic"])
def test_network_map_rows_are_their_own_bits_in_any_block(activation):
    """A network map's row is the same double whether it is evaluated alone or in a block
    of any size (the batch evaluates all rows in one call, the single solve one row): odd
    sizes against the vector width, and past the forward pass's block of rows."""
    from softrod.stiffness_map import _FORWARD_BLOCK

    smap = StiffnessMap.from_networks(_networks(4, activation))
    p = np.random.default_rng(5).uniform(0.0, 7e4, size=(_FORWARD_BLOCK + 37, 3))
    alone = np.vstack([smap(p[k : k + 1]) for k in range(len(p))])
    for m in (1, 2, 3, 5, 8, 17, 64, 1000, len(p)):
        np.testing.assert_array_equal(smap(p[:m]), alone[:m], err_msg=f"{m} rows")
    # A block that starts elsewhere: rows do not depend on their position either.
    np.testing.assert_array_equal(smap(p[3:70]), alone[3:70])


def test_network_map_batch_evaluates_the_map_once(monkeypatch):
    """solve_statics_batch evaluates a network map in one call for all its rows (each row
    still bitwise the single solve's, tests/test_boundary_regressions.py), not one call per
    row; a callable map, whose rows softrod cannot know to be independent, row by row after
    one checking call."""
    import softrod.stiffness_map as sm

    calls = []
    forward = sm._forward

    def counted(net, p):
        calls.append(len(p))
        return forward(net, p)

    monkeypatch.setattr(sm, "_forward", counted)
    design = mapped_spa()
    smap = StiffnessMap.from_networks(_networks(6, "tanh"))
    p = np.random.default_rng(7).uniform(0.0, 5e4, size=(40, 3))
    batch = solve_statics_batch(design, p, stiffness_map=smap, threads=2)
    assert batch.converged.all()
    assert calls == [40, 40, 40]  # one forward pass of all rows per network (three)
    np.testing.assert_array_equal(batch.stiffness_scale, smap(p))
    rows = []

    def sigma(q):
        rows.append(len(q))
        return np.ones((len(q), 3))

    solve_statics_batch(design, p[:5], stiffness_map=StiffnessMap.from_callable(sigma, 3))
    assert rows == [5, 1, 1, 1, 1, 1]


def test_map_without_mapped_section_raises():
    with pytest.raises(InputError, match="stiffness_map") as info:
        solve_statics(SPA, [0, 0, 0], stiffness_map=StiffnessMap.constant((1, 1, 1), 3))
    assert info.value.field == "stiffness_map"
    with pytest.raises(InputError, match="no section"):
        solve_statics_batch(
            SPA, np.zeros((2, 3)), stiffness_map=StiffnessMap.constant((1, 1, 1), 3)
        )


def test_mapped_design_without_map_raises():
    design = mapped_spa()
    for call in (
        lambda: solve_statics(design, [0, 0, 0]),
        lambda: solve_statics_batch(design, np.zeros((2, 3))),
    ):
        with pytest.raises(InputError, match="stiffness_map") as info:
            call()
        assert info.value.field == "stiffness_map"
        assert "body" in str(info.value)  # names the mapped section


def test_no_entry_point_takes_sigma_as_one_for_a_mapped_design():
    """Below the public solvers too: calibrate without a map or sigma parameters, the PCC
    model (which has its own stiffness), and the binding's solves and batches called without
    sigma refuse a mapped design by name instead of solving it with sigma = 1."""
    import softrod
    from softrod import _core

    design = mapped_spa()
    data = softrod.load_dataset("spa130_synthetic").subset(range(4))
    with pytest.raises(InputError, match="never assumed to be 1") as info:
        softrod.calibrate(design, data, "c_b", progress=False)
    assert info.value.field == "design.stiffness_map"
    # A design the PCC model cannot carry: a DesignError, as for its other refusals.
    with pytest.raises(softrod.DesignError, match="PCC model") as info:
        solve_statics(design, [2e4, 0, 0], model="pcc")
    assert info.value.field == "sections[1].law.stiffness_map"
    rod, zero = design._rod, [0.0, 0.0, 0.0]
    for call in (
        lambda: rod.solve([2e4, 0, 0], zero, zero),
        lambda: rod.solve_batch(np.zeros((2, 3)), zero, zero),
        lambda: rod.sensitivity_batch(np.zeros((2, 3)), zero, zero, []),
        lambda: _core.solve_constrained_tip(
            rod, [0, 0, 0], zero, zero, "pinned", position=[0.0, 0.0, -0.13]
        ),
    ):
        with pytest.raises(InputError, match="never assumed to be 1") as info:
            call()
        assert info.value.field == "stiffness_scale"


def test_map_with_wrong_channel_count_or_type_raises():
    design = mapped_spa()
    with pytest.raises(InputError, match="2 pressure channel") as info:
        solve_statics(design, [0, 0, 0], stiffness_map=StiffnessMap.constant((1, 1, 1), 2))
    assert info.value.field == "stiffness_map"
    with pytest.raises(InputError, match="must be a softrod.StiffnessMap"):
        solve_statics(design, [0, 0, 0], stiffness_map=lambda p: np.ones((1, 3)))


def test_non_positive_sigma_from_callable_names_the_row():
    def fn(p):
        s = np.ones((p.shape[0], 3))
        s[:, 1] = 1.0 - p[:, 0] / 30e3  # reaches zero at 30 kPa
        return s

    smap = StiffnessMap.from_callable(fn, 3)
    pressures = np.array([[0.0, 0, 0], [10e3, 0, 0], [30e3, 5e3, 0], [40e3, 0, 0]])
    with pytest.raises(InputError, match=r"sigma\[2\].*stay positive.*30000\.0, 5000\.0") as info:
        smap(pressures)
    assert info.value.field == "sigma[2]"
    with pytest.raises(InputError, match=r"sigma\[2\]"):
        solve_statics_batch(mapped_spa(), pressures, stiffness_map=smap)
    with pytest.raises(InputError, match=r"stay positive"):
        solve_statics(mapped_spa(), [40e3, 0, 0], stiffness_map=smap)
    nan_map = StiffnessMap.from_callable(lambda p: np.full((len(p), 3), np.nan), 3)
    with pytest.raises(InputError, match=r"sigma\[0\]"):
        nan_map(pressures)
    wrong_shape = StiffnessMap.from_callable(lambda p: np.ones(len(p)), 3)
    with pytest.raises(InputError, match=r"\(4, 3\)"):
        wrong_shape(pressures)


def test_call_validates_pressures():
    smap = StiffnessMap.constant((1, 1, 1), 3)
    assert smap([1.0, 2.0, 3.0]).shape == (3,)  # one row
    assert smap(np.zeros((5, 3))).shape == (5, 3)
    with pytest.raises(InputError, match=r"\(m, 3\)"):
        smap(np.zeros((5, 2)))
    with pytest.raises(InputError, match=r"pressures\[1\]"):
        smap([[0, 0, 0], [np.nan, 0, 0]])


# -- tables ------------------------------------------------------------------------------------

# Interpolation of values of order 1 by a few dozen flops: round-off only.
INTERP = 1e-13


def test_table_reproduces_nodes_and_matches_scipy_pchip():
    axes, values = smooth_table()
    smap = StiffnessMap.from_table(axes, values)
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    np.testing.assert_allclose(smap(nodes), values.reshape(-1, 3), rtol=0, atol=INTERP)
    # Independent reference: scipy's RegularGridInterpolator(method="pchip") (point by point).
    rng = np.random.default_rng(2)
    pts = rng.uniform(0.0, 60e3, (200, 3))
    ref = RegularGridInterpolator(axes, values, method="pchip")(pts)
    np.testing.assert_allclose(smap(pts), ref, rtol=0, atol=INTERP)
    lin = StiffnessMap.from_table(axes, values, method="linear")
    np.testing.assert_allclose(lin(pts), RegularGridInterpolator(axes, values)(pts), atol=INTERP)
    # Positive data: every interpolated value lies within the table's range.
    assert smap(pts).min() >= values.min() - INTERP
    assert smap(pts).max() <= values.max() + INTERP


def test_table_is_monotone_and_positive_between_nodes():
    # sigma_ext rises, sigma_bend_x falls, sigma_bend_y dips sharply close to 0 and back: a
    # cubic spline would overshoot below zero there; PCHIP keeps every interval within its
    # end values.
    axis = np.array([0.0, 10e3, 20e3, 30e3, 40e3, 50e3])
    values = np.array(
        [
            [0.5, 1.4, 1.0],
            [0.6, 1.2, 1.0],
            [0.9, 1.1, 0.01],
            [1.0, 0.7, 1.0],
            [1.3, 0.5, 1.0],
            [1.4, 0.4, 1.0],
        ]
    )
    smap = StiffnessMap.from_table([axis], values)
    p = np.linspace(0.0, 50e3, 2001)[:, None]
    s = smap(p)
    assert np.all(np.diff(s[:, 0]) >= 0) and np.all(np.diff(s[:, 1]) <= 0)
    assert s.min() >= 0.01 - INTERP
    for k in range(len(axis) - 1):  # each interval stays between its end values
        inside = (p[:, 0] >= axis[k]) & (p[:, 0] <= axis[k + 1])
        lo = np.minimum(values[k], values[k + 1]) - INTERP
        hi = np.maximum(values[k], values[k + 1]) + INTERP
        assert np.all((s[inside] >= lo) & (s[inside] <= hi))
    # Smooth: the slope is continuous at an interior node where the data are monotone.
    h = 1.0
    left = (smap([[20e3]]) - smap([[20e3 - h]])) / h
    right = (smap([[20e3 + h]]) - smap([[20e3]])) / h
    np.testing.assert_allclose(left[0, 0], right[0, 0], rtol=1e-3)


def test_two_point_axis_is_linear():
    smap = StiffnessMap.from_table([[0.0, 40e3]], [[1.0, 1.0, 1.0], [2.0, 0.5, 1.0]])
    np.testing.assert_allclose(smap([[10e3]]), [[1.25, 0.875, 1.0]], atol=INTERP)


def test_outside_the_table_raises_or_clamps():
    axes = [[0.0, 20e3, 40e3], ["0 kPa", "0.3 bar"]]  # units accepted in axes
    values = np.ones((3, 2, 3))
    values[..., 0] = np.array([1.0, 1.5, 2.0])[:, None]
    strict = StiffnessMap.from_table(axes, values)
    np.testing.assert_array_equal(strict.axes[1], [0.0, 30e3])
    with pytest.raises(InputError, match=r"pressures\[1\].*channel 0 = 50000 Pa.*\[0, 40000\]"):
        strict([[10e3, 0.0], [50e3, 0.0]])
    # Round-off at the edge (e.g. from a unit conversion) counts as inside.
    strict([[40e3 * (1 + 1e-15), 30e3 * (1 + 1e-15)]])
    clamped = StiffnessMap.from_table(axes, values, outside="clamp")
    np.testing.assert_allclose(clamped([[50e3, -5e3], [-1e3, 90e3]])[:, 0], [2.0, 1.0])


@pytest.mark.parametrize(
    "axes, sigma, match",
    [
        ([[0.0, 1e3, 1e3]], np.ones((3, 3)), "strictly increasing"),
        ([[0.0]], np.ones((1, 3)), "at least 2"),
        ([[0.0, 1e3]], np.ones((3, 3)), r"shape \(2, 3\)"),
        ([[0.0, 1e3]], [[1, 1, 1], [1, 0, 1]], r"sigma\[1, 1\].*stay positive"),
        ([[0.0, "1 m"]], np.ones((2, 3)), "wrong unit"),
        ([], np.ones(3), "StiffnessMap.constant"),
    ],
)
def test_bad_tables_raise(axes, sigma, match):
    with pytest.raises(InputError, match=match):
        StiffnessMap.from_table(axes, sigma)


# -- CSV -----------------------------------------------------------------------------------------


def write_csv(path, axes_kpa, values, order, header=None):
    grid = np.stack(np.meshgrid(*axes_kpa, indexing="ij"), axis=-1).reshape(-1, len(axes_kpa))
    rows = np.hstack([grid, values.reshape(-1, 3)])[order]
    header = header or [f"p{k}_kPa" for k in range(len(axes_kpa))] + [
        "sigma_ext",
        "sigma_bend_x",
        "sigma_bend_y",
    ]
    lines = [",".join(header)] + [",".join(repr(float(v)) for v in r) for r in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_csv_round_trip(tmp_path):
    axes, values = smooth_table()
    axes_kpa = [a / 1e3 for a in axes]
    order = np.random.default_rng(3).permutation(values[..., 0].size)  # rows in any order
    path = write_csv(tmp_path / "sigma.csv", axes_kpa, values, order)
    from_csv = StiffnessMap.from_csv(path)
    from_table = StiffnessMap.from_table(axes, values)
    for a, b in zip(from_csv.axes, axes, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-15)  # kPa -> Pa: one rounding
    pts = np.random.default_rng(4).uniform(0.0, 60e3, (100, 3))
    np.testing.assert_allclose(from_csv(pts), from_table(pts), atol=INTERP)
    assert "sigma.csv" in repr(from_csv) and "5x4x6" in repr(from_csv)


def test_csv_units_bar_and_pa(tmp_path):
    header = ["sigma_ext", "p1_Pa", "sigma_bend_x", "p0_bar", "sigma_bend_y"]
    text = "\n".join(
        [",".join(header)]
        + [f"{1 + a + b},{b * 1e4},1,{a / 10},1" for a in range(3) for b in range(2)]
    )
    (tmp_path / "t.csv").write_text(text + "\n")
    smap = StiffnessMap.from_csv(tmp_path / "t.csv")
    np.testing.assert_allclose(smap.axes[0], [0.0, 10e3, 20e3])
    np.testing.assert_allclose(smap.axes[1], [0.0, 10e3])
    np.testing.assert_allclose(smap([[20e3, 10e3]])[0], [4.0, 1.0, 1.0], atol=INTERP)


def test_csv_errors(tmp_path):
    axes_kpa = [np.array([0.0, 20.0, 40.0]), np.array([0.0, 30.0])]
    values = np.ones((3, 2, 3))
    n = values[..., 0].size
    # A missing grid point.
    path = write_csv(tmp_path / "gap.csv", axes_kpa, values, np.arange(n - 1))
    with pytest.raises(InputError, match=r"p0_kPa = 40, p1_kPa = 30\).*full grid 3x2"):
        StiffnessMap.from_csv(path)
    # A repeated grid point.
    path = write_csv(tmp_path / "dup.csv", axes_kpa, values, [0, 1, 2, 3, 4, 5, 2])
    with pytest.raises(InputError, match="line 8.*repeats the grid point of line 4"):
        StiffnessMap.from_csv(path)
    # NaN: the line number of the file (header = line 1).
    path = write_csv(tmp_path / "nan.csv", axes_kpa, values, np.arange(n))
    lines = path.read_text().splitlines()
    lines[4] = lines[4].rsplit(",", 1)[0] + ",nan"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match="line 5, sigma_bend_y"):
        StiffnessMap.from_csv(path)
    # Non-positive sigma.
    bad = values.copy()
    bad[1, 1, 2] = -0.5
    path = write_csv(tmp_path / "neg.csv", axes_kpa, bad, np.arange(n))
    with pytest.raises(InputError, match="line 5.*stay positive"):
        StiffnessMap.from_csv(path)
    # Wrong columns.
    for header, match in (
        (["p0_kPa", "p1_kPa", "sigma_ext", "sigma_bend_x", "sigma_bendy"], "unknown column"),
        (["p0_kPa", "p2_kPa", "sigma_ext", "sigma_bend_x", "sigma_bend_y"], "channel 0..c-1"),
        (["p0_kPa", "p1_mm", "sigma_ext", "sigma_bend_x", "sigma_bend_y"], "must be a pressure"),
    ):
        path = write_csv(tmp_path / "cols.csv", axes_kpa, values, np.arange(n), header)
        with pytest.raises(InputError, match=match):
            StiffnessMap.from_csv(path)
    # A channel count that does not match the design.
    path = write_csv(tmp_path / "ok.csv", axes_kpa, values, np.arange(n))
    with pytest.raises(InputError, match="stiffness_map"):
        solve_statics(mapped_spa(), [0, 0, 0], stiffness_map=StiffnessMap.from_csv(path))


# -- callables and regressors --------------------------------------------------------------------


class Linear:
    """A stand-in for a trained regressor: predict(X) = X @ w + b."""

    def __init__(self, w, b):
        self.w, self.b = np.asarray(w, dtype=float), np.asarray(b, dtype=float)

    def predict(self, x):
        return x @ self.w + self.b


def test_regressor_in_its_training_unit():
    p = np.array([[0.0, 0.0], [20e3, 10e3]])
    one = StiffnessMap.from_regressor(
        Linear([[0.01, 0.0, 0.0], [0.0, -0.01, 0.02]], [1.0, 1.0, 1.0]), 2, pressure_unit="kPa"
    )
    np.testing.assert_allclose(one(p), [[1.0, 1.0, 1.0], [1.2, 0.9, 1.2]], atol=ROUND_OFF)
    three = StiffnessMap.from_regressor(
        [Linear([0.01, 0.0], 1.0), Linear([0.0, -0.01], 1.0), Linear([0.0, 0.02], 1.0)],
        2,
        pressure_unit="kPa",
    )
    np.testing.assert_allclose(three(p), one(p), atol=ROUND_OFF)
    assert "kPa" in repr(three)
    with pytest.raises(InputError, match="predict"):
        StiffnessMap.from_regressor(object(), 2)
    with pytest.raises(InputError, match="pressure_unit"):
        StiffnessMap.from_regressor(one, 2, pressure_unit="mm")
    falling = StiffnessMap.from_regressor(Linear([[-1e-4, 0, 0], [0, 0, 0]], [1, 1, 1]), 2)
    with pytest.raises(InputError, match=r"sigma\[1\].*20000\.0, 10000\.0"):
        falling(p)


def test_map_is_immutable_and_has_a_repr():
    smap = StiffnessMap.constant((1.0, 2.0, 3.0), 3)
    with pytest.raises(AttributeError):
        smap.foo = 1
    assert smap.n_channels == 3 and smap.kind == "constant"
    assert "constant sigma=(1, 2, 3)" in repr(smap)
    axes, values = smooth_table()
    table = StiffnessMap.from_table(axes, values)
    with pytest.raises(ValueError):
        table.values[0, 0, 0, 0] = 5.0
    with pytest.raises(InputError, match="n_channels"):
        StiffnessMap.from_callable(lambda p: p, -1)
    with pytest.raises(InputError, match=r"sigma\[1\]"):
        StiffnessMap.constant((1.0, 0.0, 1.0), 3)
