"""The pressure Jacobian of a design with a stiffness-mapped section: sigma(p) moves with the
pressures, so d pose / d p = the partial derivative at fixed sigma + d pose / d sigma
times the map's d sigma / d p (docs/stiffness-map.md, "Jacobians"). Checked in layers: each
kind of map's derivative against differences of the map itself, then whole Jacobians (free
and clamped tip, with the reaction) against central differences of whole mapped solves,
and the refusals where sigma has no derivative."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from softrod import (
    InputError,
    SolverOptions,
    StiffnessMap,
    TipConstraint,
    linearise,
    load_design,
    solve_statics,
)
from test_stiffness_map import _networks, smooth_table

OPTS = SolverOptions(tol=1e-13)
SPA = "spa_three_chamber_130mm"
P = np.array([30e3, 12e3, 41e3])  # inside every cell of smooth_table(), off its nodes


def mapped_spa():
    return load_design(SPA).replace({"sections[1].law": {"stiffness_map": True}})


def one_sided(smap: StiffnessMap, p: np.ndarray, h: float, side: float) -> np.ndarray:
    """(3, c): the three-point one-sided difference (-3 f0 + 4 f1 - f2) / 2h of sigma along
    each channel. It stays on one side of a node, where the interpolants are piecewise
    smooth; its error is O(h^2 |sigma'''|) + O(eps / h)."""
    out = np.empty((3, len(p)))
    for c in range(len(p)):
        e = np.zeros(len(p))
        e[c] = side * h
        f0, f1, f2 = smap(p), smap(p + e), smap(p + 2 * e)
        out[:, c] = side * (-3 * f0 + 4 * f1 - f2) / (2 * h)
    return out


# -- the maps' derivatives ----------------------------------------------------------------------

# sigma is O(1) over tens of kPa, so d sigma / d p is O(1e-5) per Pa and its second and third
# derivatives O(1e-10) and O(1e-15) per Pa^2, Pa^3 (a cubic per cell of ~1e4 Pa). With
# h = 1 Pa the one-sided difference is exact to ~1e-15 + 1e-16: atol 1e-11 per Pa (1e-6 of
# a derivative) is far above both and far below any mistake of a cell or a factor.
H_MAP = 1.0
ATOL_MAP = 1e-11


@pytest.mark.parametrize("method", ["pchip", "linear"])
def test_table_derivative_matches_differences_of_the_map(method):
    axes, values = smooth_table()
    smap = StiffnessMap.from_table(axes, values, method=method)
    rows = np.array([P, [5e3, 50e3, 3e3], [57e3, 1e3, 59e3]])
    d = smap.derivative(rows)
    assert d.shape == (3, 3, 3)
    for r, p in enumerate(rows):
        for side in (1.0, -1.0):
            np.testing.assert_allclose(d[r], one_sided(smap, p, H_MAP, side), atol=ATOL_MAP)
    np.testing.assert_array_equal(smap.derivative(P), d[0])  # one row: (3, c)


def test_pchip_derivative_is_continuous_across_a_node():
    """At a node of a PCHIP axis with 3 or more points the cubics of both cells share their
    slope: the derivative there matches differences taken on either side."""
    axes, values = smooth_table()
    smap = StiffnessMap.from_table(axes, values)
    p = np.array([25e3, 20e3, 36e3])  # a node along each of the three channels
    d = smap.derivative(p)
    for side in (1.0, -1.0):
        np.testing.assert_allclose(d, one_sided(smap, p, H_MAP, side), atol=ATOL_MAP)


@pytest.mark.parametrize("activation", ["tanh", "logistic", "relu"])
def test_network_derivative_matches_differences_of_the_map(activation):
    smap = StiffnessMap.from_networks(_networks(3, activation))
    rows = np.array([P, [5e3, 50e3, 3e3]])
    d = smap.derivative(rows)
    for r, p in enumerate(rows):
        # The networks are smooth (relu: piecewise linear, no hinge within 2 Pa here).
        np.testing.assert_allclose(d[r], one_sided(smap, p, H_MAP, 1.0), atol=ATOL_MAP)


def test_constant_and_clamped_maps_have_zero_derivative_where_sigma_is_flat():
    assert not StiffnessMap.constant((1.0, 0.8, 0.9), 3).derivative(P).any()
    axes, values = smooth_table()
    clamped = StiffnessMap.from_table(axes, values, outside="clamp")
    d = clamped.derivative([70e3, 12e3, 41e3])  # channel 0 beyond its axis (60 kPa)
    assert not d[:, 0].any() and d[:, 1:].any()


def test_callable_derivative_is_the_one_given():
    def fn(p):
        return np.column_stack([1 + p[:, 0] / 1e5, np.ones(len(p)), np.ones(len(p))])

    def dfn(p):
        d = np.zeros((len(p), 3, 3))
        d[:, 0, 0] = 1e-5
        return d

    smap = StiffnessMap.from_callable(fn, 3, derivative=dfn)
    np.testing.assert_array_equal(smap.derivative(P), dfn(P[None])[0])


def test_maps_refuse_where_sigma_has_no_derivative():
    axes, values = smooth_table()
    linear = StiffnessMap.from_table(axes, values, method="linear")
    with pytest.raises(InputError, match="node of the linear stiffness table") as info:
        linear.derivative([25e3, 12e3, 41e3])  # 25 kPa: a node of channel 0
    assert info.value.field == "pressures[0]"
    clamped = StiffnessMap.from_table(axes, values, outside="clamp")
    with pytest.raises(InputError, match="edge of the clamped") as info:
        clamped.derivative([60e3, 12e3, 41e3])
    assert info.value.field == "pressures[0]"
    # A relu unit exactly on its hinge: zero input and zero bias.
    nets = _networks(3, "relu")
    for net in nets:
        net["input_mean"] = [0.0, 0.0, 0.0]
        net["biases"][0][0] = 0.0
    with pytest.raises(InputError, match="hinge"):
        StiffnessMap.from_networks(nets).derivative([0.0, 0.0, 0.0])
    for smap in (
        StiffnessMap.from_callable(lambda p: np.ones((len(p), 3)), 3),
        StiffnessMap.from_callable(
            lambda p: np.ones((len(p), 3)), 3, derivative=lambda p: np.zeros((len(p), 3))
        ),
    ):
        with pytest.raises(InputError) as info:
            smap.derivative(P)
        assert info.value.field == "stiffness_map"
    with pytest.raises(InputError) as info:
        StiffnessMap.from_callable(lambda p: p, 3, derivative="d/dp")
    assert info.value.field == "derivative"


# -- whole Jacobians ----------------------------------------------------------------------------

# Central differences of solves converged to 1e-13 (scaled residual). sigma of
# smooth_table() changes by O(1) across cells of ~1e4 Pa, so the solution's third
# derivative in p is O(d / (1e4 Pa)^2) for a derivative d, and the truncation error
# h^2 / 6 times that: with h = 5 Pa about 4e-8 of d. Round-off: 1e-13 * 0.1 m / 5 Pa =
# 2e-15 m/Pa against derivatives of ~1e-7 m/Pa. rtol 1e-5 leaves room for both; atol covers
# entries that vanish. A Jacobian without the map's part is off by tens of percent.
H_P = 5.0


def _tip_fd(solve, h: float):
    """Central differences of the tip position and small rotation (6,) and of the tip's
    reaction wrench (6,), for solve(+-1) of the perturbed problem."""
    hi, lo = solve(+1), solve(-1)
    dp = (hi.tip_position - lo.tip_position) / (2 * h)
    r0 = 0.5 * (hi.tip_rotation + lo.tip_rotation)
    w = (hi.tip_rotation - lo.tip_rotation) / (2 * h) @ r0.T
    dth = 0.5 * np.array([w[2, 1] - w[1, 2], w[0, 2] - w[2, 0], w[1, 0] - w[0, 1]])
    df = (hi.tip_reaction_force - lo.tip_reaction_force) / (2 * h)
    dm = (hi.tip_reaction_moment - lo.tip_reaction_moment) / (2 * h)
    return np.concatenate([dp, dth]), np.concatenate([df, dm])


@pytest.mark.parametrize("tip", ["free", "clamped"])
def test_mapped_pressure_jacobian_matches_central_differences_of_solves(tip):
    design = mapped_spa()
    axes, values = smooth_table()
    smap = StiffnessMap.from_table(axes, values)
    held = None
    if tip == "clamped":
        free = solve_statics(design, P, stiffness_map=smap, options=OPTS)
        held = TipConstraint.clamped(
            free.tip_position + np.array([0.006, 0.0, 0.0]), free.tip_rotation
        )
    sol = solve_statics(design, P, stiffness_map=smap, tip_constraint=held, options=OPTS)
    jac = sol.jacobian()
    assert jac.stiffness_scale.shape == (6, 3)
    for c in range(3):

        def solve(sign, c=c):
            e = np.zeros(3)
            e[c] = sign * H_P
            return solve_statics(
                design, P + e, stiffness_map=smap, tip_constraint=held, options=OPTS
            )

        pose, wrench = _tip_fd(solve, H_P)
        if tip == "free":
            np.testing.assert_allclose(jac.pressures[:, c], pose, rtol=1e-5, atol=1e-12)
        else:
            # The clamped tip does not move; its reaction carries the pressures.
            np.testing.assert_allclose(jac.pressures[:, c], 0.0, atol=1e-12)
            np.testing.assert_allclose(
                jac.reaction["pressures"][:, c], wrench, rtol=1e-5, atol=1e-9
            )
    if tip == "free":
        # The map's part is no round-off: without it the pressures' block is far off.
        partial = jac.pressures - jac.stiffness_scale @ smap.derivative(P)
        assert np.abs(partial - jac.pressures).max() > 0.05 * np.abs(jac.pressures).max()


def test_stiffness_scale_block_matches_differences_in_sigma():
    """jac.stiffness_scale: the derivatives at fixed pressures with respect to each factor
    sigma, against central differences of solves under constant maps sigma +- h e_k."""
    design = mapped_spa()
    sigma = np.array([0.9, 1.2, 0.8])
    sol = solve_statics(design, P, stiffness_map=StiffnessMap.constant(sigma, 3), options=OPTS)
    jac = sol.jacobian()
    # sigma is O(1): h = 1e-5 gives truncation ~1e-10 and round-off 1e-13 * 0.1 / 1e-5 ~
    # 1e-9 of derivatives of ~1e-2 m: rtol 1e-5 as above.
    h = 1e-5
    for k in range(3):

        def solve(sign, k=k):
            s = sigma.copy()
            s[k] += sign * h
            return solve_statics(design, P, stiffness_map=StiffnessMap.constant(s, 3), options=OPTS)

        pose, _ = _tip_fd(solve, h)
        np.testing.assert_allclose(jac.stiffness_scale[:, k], pose, rtol=1e-5, atol=1e-10)
    # A constant map does not move with the pressures: the pressures' block is the partial.
    plain = solve_statics(load_design(SPA), P, options=OPTS).jacobian()
    assert plain.stiffness_scale is None


def test_mapped_jacobian_refuses_without_a_derivative_or_the_map():
    design = mapped_spa()
    smap = StiffnessMap.from_callable(lambda p: np.ones((len(p), 3)), 3)
    sol = solve_statics(design, P, stiffness_map=smap)
    with pytest.raises(InputError) as info:
        sol.jacobian()
    assert info.value.field == "stiffness_map"
    bare = dataclasses.replace(sol, stiffness_map=None)
    with pytest.raises(InputError) as info:
        bare.jacobian()
    assert info.value.field == "solution.stiffness_map"


@pytest.mark.parametrize("tip", ["free", "clamped"])
def test_mapped_linearisation_carries_the_maps_part(tip):
    """softrod.linearise of a mapped design: the static response K^-1 B at every node is the
    mapped equilibrium's pressure Jacobian there (with d sigma / d p; checked against whole
    solves above). Two exact derivatives of one equilibrium: 1e-6 of the column."""
    design = mapped_spa()
    axes, values = smooth_table()
    smap = StiffnessMap.from_table(axes, values)
    held = None
    if tip == "clamped":
        free = solve_statics(design, P, stiffness_map=smap, options=OPTS)
        held = TipConstraint.clamped(
            free.tip_position + np.array([0.006, 0.0, 0.0]), free.tip_rotation
        )
    sol = solve_statics(design, P, stiffness_map=smap, tip_constraint=held, options=OPTS)
    lin = linearise(sol, nodes=5)
    assert lin.input.shape[1] == len(lin.input_names)
    response = np.linalg.solve(lin.stiffness, lin.input)
    for k, s in enumerate(lin.nodes):
        jac = sol.jacobian(point=float(s))
        rows = lin.node_rows(response, k)
        for c in range(3):
            scale = np.linalg.norm(jac.pressures[:, c])
            assert np.linalg.norm(rows[:, c] - jac.pressures[:, c]) < 1e-6 * scale
    # The same from the design and its map.
    again = linearise(design, P, nodes=5, stiffness_map=smap, tip_constraint=held)
    np.testing.assert_allclose(
        again.input, lin.input, rtol=1e-6, atol=1e-9 * np.abs(lin.input).max()
    )


def test_mapped_linearisation_refuses_without_the_map():
    design = mapped_spa()
    axes, values = smooth_table()
    sol = solve_statics(design, P, stiffness_map=StiffnessMap.from_table(axes, values))
    with pytest.raises(InputError) as info:
        linearise(dataclasses.replace(sol, stiffness_map=None), nodes=4)
    assert info.value.field == "solution.stiffness_map"
    with pytest.raises(InputError) as info:
        linearise(design, P, nodes=4)  # a mapped design without a map: sigma is never 1
    assert info.value.field == "stiffness_map"
