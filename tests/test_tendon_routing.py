"""Helical tendon routing against an independent solver of Rucker and Webster's original
formulation (issue 17, "Tests": tendons).

softrod carries the tendons inside the balance laws (docs/scope.md, "Tendons": the tension
crossing a cut is part of the cut's force, which makes the constitutive law implicit). The
reference here is the formulation of D. C. Rucker and R. J. Webster III, "Statics and
Dynamics of Continuum Robots With General Tendon Routing and External Loading", IEEE T-RO
27(6), 2011, written again from its physics: the tendons are *external* to the rod, pressing
on it with the distributed force tau t_i' along their paths p_i = r + R r_i and pulling its
tip back with -tau t_i at their terminations; the elastic wrench is n = R K_se (v - v*),
m = R K_bt (u - u*), the state carries the strains, and each right-hand side solves the 6x6
linear system for (v', u') that the tendons' curvature couples (their eqs. 13-14). It is
integrated by scipy's DOP853 and shot on the six base strains with MINPACK's root finder:
no code and no formulation step is shared with softrod, so the two agree only if both are
right. softrod's RK4 converges to it at fourth order.
"""

import numpy as np
import pytest
from softrod import SolverOptions, load_design, solve_statics

L = 0.1  # m
K_SE = np.array([50.0, 50.0, 100.0])  # GA, GA, EA (N)
K_BT = np.array([0.01, 0.01, 0.008])  # EI, EI, GJ (N m^2)
DISTANCE = 6e-3  # m, tendon offset
TURNS = 1.0  # the helical tendon's angle runs from 0 to 360 degrees along the rod
TENSIONS = np.array([3.0, 5.0])  # N: the helical tendon, a straight one at 90 degrees
TIP_FORCE = np.array([0.0, 0.05, -0.1])  # N, dead, couples the tendons with an external load


def design(steps: int) -> dict:
    """Upright rod (d3 = +z, d1 = +x at the base), no gravity, two tendons ending at the tip."""
    return {
        "design": {"name": "helical_tendon_rod", "citation": "Rucker and Webster 2011"},
        "mounting": {"orientation": "upright", "gravity": "0 m/s^2"},
        "sections": [
            {
                "name": "rod",
                "length": f"{L * 1e3} mm",
                "mass": "10 g",
                "outer_radius": "10 mm",
                "EA": f"{K_SE[2]} N",
                "GA": f"{K_SE[0]} N",
                "EI": f"{K_BT[0]} N*m^2",
                "GJ": f"{K_BT[2]} N*m^2",
                "steps": steps,
                "tendons": [
                    {
                        "channel": 0,
                        "distance": f"{DISTANCE * 1e3} mm",
                        "angle": "0 deg",
                        "angle_end": f"{360 * TURNS} deg",
                    },
                    {"channel": 1, "distance": f"{DISTANCE * 1e3} mm", "angle": "90 deg"},
                ],
            }
        ],
    }


def helical_routing(s: float) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(r_i, r_i', r_i'') of each tendon in the body frame at arc length s."""
    out = []
    for theta, dtheta in ((2 * np.pi * TURNS * s / L, 2 * np.pi * TURNS / L), (np.pi / 2, 0.0)):
        c, sn = np.cos(theta), np.sin(theta)
        out.append(
            (
                DISTANCE * np.array([c, sn, 0.0]),
                DISTANCE * dtheta * np.array([-sn, c, 0.0]),
                -DISTANCE * dtheta**2 * np.array([c, sn, 0.0]),
            )
        )
    return out


def hat(w: np.ndarray) -> np.ndarray:
    return np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


class RuckerWebster:
    """The reference: a uniform rod of length ``length`` with the linear law (``k_se``,
    ``k_bt``, v* = e3, u* = 0), clamped at the origin with rotation ``base``, tendons with
    body-frame ``routing(s) -> [(r_i, r_i', r_i'')]`` and ``tensions``, a dead ``tip_force``
    and a dead world-frame ``line_load`` (N/m, e.g. the weight per length)."""

    def __init__(self, length, k_se, k_bt, routing, tensions, tip_force, line_load, base):
        self.length, self.k_se, self.k_bt = length, k_se, k_bt
        self.routing, self.tensions = routing, np.asarray(tensions, dtype=float)
        self.tip_force, self.line_load = np.asarray(tip_force), np.asarray(line_load)
        self.base = np.asarray(base, dtype=float)

    def rhs(self, s: float, y: np.ndarray) -> np.ndarray:
        """y = (r, R row-major, v, u). Body-frame balance, tendons as external loads:
        K_se v' + u x K_se (v - v*) + R^T f + sum tau (u x t + P q' / |q|) = 0,
        K_bt u' + u x K_bt u + v x K_se (v - v*) + sum tau r_i x (u x t + P q' / |q|) = 0,
        with q = v + u x r_i + r_i' (the tendon's tangent, body frame), t = q / |q|,
        P = I - t t^T and q' = v' + u' x r_i + u x r_i' + r_i''. Linear in (v', u')."""
        rot = y[3:12].reshape(3, 3)
        v, u = y[12:15], y[15:18]
        ne = self.k_se * (v - [0.0, 0.0, 1.0])
        a = np.zeros((6, 6))
        b = np.concatenate(
            [
                -np.cross(u, ne) - rot.T @ self.line_load,
                -np.cross(u, self.k_bt * u) - np.cross(v, ne),
            ]
        )
        a[0:3, 0:3] += np.diag(self.k_se)
        a[3:6, 3:6] += np.diag(self.k_bt)
        for tau, (ri, dri, ddri) in zip(self.tensions, self.routing(s), strict=True):
            q = v + np.cross(u, ri) + dri
            nq = np.linalg.norm(q)
            t = q / nq
            proj = (np.eye(3) - np.outer(t, t)) / nq
            # q' = v' - [r_i]x u' + (u x r_i' + r_i''): its (v', u') part and the rest.
            dq = np.hstack([np.eye(3), -hat(ri)])
            rest = np.cross(u, dri) + ddri
            force_lin = tau * proj @ dq  # the tendon's force per length, linear part
            force_0 = tau * (np.cross(u, t) + proj @ rest)
            a[0:3] += force_lin
            a[3:6] += hat(ri) @ force_lin
            b[0:3] -= force_0
            b[3:6] -= np.cross(ri, force_0)
        dw = np.linalg.solve(a, b)
        return np.concatenate([rot @ v, (rot @ hat(u)).ravel(), dw])

    def tip_state(self, w0: np.ndarray) -> np.ndarray:
        from scipy.integrate import solve_ivp

        y0 = np.concatenate([np.zeros(3), self.base.ravel(), w0])
        out = solve_ivp(self.rhs, (0.0, self.length), y0, method="DOP853", rtol=1e-13, atol=1e-14)
        assert out.success, out.message
        return out.y[:, -1]

    def tip_residual(self, w0: np.ndarray) -> np.ndarray:
        """The free tip's wrench balance: elastic n(L) = F - sum tau R t_i(L) and
        m(L) = -sum (R r_i) x tau R t_i(L) (the terminations pull back along the
        tendons), scaled by the largest tension (and the length for moments)."""
        y = self.tip_state(w0)
        rot = y[3:12].reshape(3, 3)
        v, u = y[12:15], y[15:18]
        n, m = rot @ (self.k_se * (v - [0.0, 0.0, 1.0])), rot @ (self.k_bt * u)
        pull_n, pull_m = np.zeros(3), np.zeros(3)
        for tau, (ri, dri, _) in zip(self.tensions, self.routing(self.length), strict=True):
            q = v + np.cross(u, ri) + dri
            t = rot @ (q / np.linalg.norm(q))
            pull_n -= tau * t
            pull_m -= np.cross(rot @ ri, tau * t)
        scale = max(self.tensions.max(), 1.0)
        return np.concatenate([n - self.tip_force - pull_n, (m - pull_m) / self.length]) / scale

    def tip(self) -> np.ndarray:
        """The tip position, shot from the straight rod on the six base strains."""
        from scipy.optimize import root

        w0 = root(
            self.tip_residual, np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0]), method="hybr", tol=1e-14
        ).x
        # MINPACK may stop at round-off; what counts is the residual it leaves (N, scaled).
        assert np.abs(self.tip_residual(w0)).max() < 1e-10
        return self.tip_state(w0)[0:3]


@pytest.fixture(scope="module")
def reference_tip() -> np.ndarray:
    rw = RuckerWebster(L, K_SE, K_BT, helical_routing, TENSIONS, TIP_FORCE, np.zeros(3), np.eye(3))
    return rw.tip()


def test_helical_tendon_converges_at_fourth_order_to_rucker_webster(reference_tip):
    errors = []
    tips = []
    for steps in (8, 16, 32):
        sol = solve_statics(
            load_design(design(steps)),
            [],
            tensions=TENSIONS,
            tip_force=TIP_FORCE,
            options=SolverOptions(tol=1e-12),
        )
        assert sol.converged and sol.stable
        tips.append(sol.tip_position)
        errors.append(float(np.linalg.norm(sol.tip_position - reference_tip)))
    # The reference's error (DOP853 at rtol 1e-13 over a rod whose shooting amplifies errors
    # by e^(L sqrt(GA/EI)) ~ 1e3, and a residual of 1e-10 N) is ~1e-11 m, far below softrod's
    # at these steps; RK4 divides its error by 2^4 = 16 per halving of the step, 11-22 leaving
    # room for the O(h^5) terms of a full helical turn in 8 steps.
    assert 11 < errors[0] / errors[1] < 22, errors
    assert 13 < errors[1] / errors[2] < 19, errors
    assert errors[2] < 1e-6 * L, errors
    # A real 3-D deflection, not a near-straight rod: the tip moves by over 10 % of L.
    assert np.linalg.norm(tips[-1] - [0.0, 0.0, L]) > 0.1 * L


@pytest.mark.parametrize("tensions", [[15.0, 0.0, 0.0, 0.0], [10.0, 10.0, 0.0, 0.0]])
def test_till_tendon_robot_matches_rucker_webster(tensions):
    """The bundled tendon robot of Till, Aloi and Rucker's statics example (0.5 m steel
    rod, four tendons 15.06 mm off the axis, horizontal under gravity) against the same
    reference with its parameters read back from the loaded design."""
    design = load_design("till_tendon_robot")
    (sec,) = design.spec["sections"]
    k = sec["stiffness"]
    k_se = np.array([k["ga"], k["ga"], k["ea"]])
    k_bt = np.array([k["ei1"], k["ei2"], k["gj"]])
    weight = np.array(design.spec["mounting"]["gravity"]) * sec["mass"] / sec["length"]

    def routing(_s):
        return [
            (
                t["distance"] * np.array([np.cos(t["angle"]), np.sin(t["angle"]), 0.0]),
                np.zeros(3),
                np.zeros(3),
            )
            for t in sec["tendons"]
        ]

    rw = RuckerWebster(
        sec["length"],
        k_se,
        k_bt,
        routing,
        tensions,
        np.zeros(3),
        weight,
        design.spec["mounting"]["base_rotation"],
    )
    reference = rw.tip()
    sol = solve_statics(design, [], tensions=tensions, options=SolverOptions(tol=1e-12))
    assert sol.converged and sol.stable
    # At the design's 40 steps (12.5 mm) RK4's error C L (|u| h)^4 with |u| <= 1.5 1/m is
    # ~1e-9 m; 1e-6 of the length (0.5 um) bounds it with a wide margin.
    np.testing.assert_allclose(sol.tip_position, reference, rtol=0, atol=1e-6 * sec["length"])
    # The example's picture: tendon 0 (the lower side) pulls the tip down, tendon 1 sideways.
    assert sol.tip_position[2] < -0.1 and (tensions[1] == 0) == (abs(sol.tip_position[1]) < 1e-9)
