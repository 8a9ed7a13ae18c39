"""The 45-degree bend (Bathe and Bolourchi 1979): a cantilever moulded as an eighth of a
circle of radius R = 100, unit square section, E = 1e7, nu = 0, loaded at the tip by a dead
force perpendicular to the plane of the arc (300 and 600), solved by softrod and by an
independent solver written here: the same Cosserat rod (extension, shear, bending, torsion,
precurvature) integrated by scipy's adaptive DOP853 and shot on the base moment with
MINPACK's root finder, which shares no code with softrod. softrod's RK4 shooting converges
to it at fourth order in the step (issue 17, "Tests": precurvature). Its tips, world frame
(base at the origin, tangent +z, arc curling towards +x, load along +y): (22.113, 40.480,
58.536) at 300 and (15.558, 53.608, 46.892) at 600.

Units are consistent (any length unit L, force unit F: E in F/L^2); SI is used as is.
"""

import math

import numpy as np
import pytest
from softrod import SolverOptions, load_design, solve_statics

RADIUS = 100.0  # m
LENGTH = RADIUS * math.pi / 4  # an eighth of a circle
E, G = 1e7, 0.5e7  # Pa; nu = 0, G = E / (2 (1 + nu))
AREA = 1.0  # m^2, unit square
I_BEND = 1.0 / 12.0  # m^4
# Saint-Venant torsion constant of a square of side a: J = 0.1406 a^4 (beta = 0.1406 for a
# square; Timoshenko and Goodier, Theory of Elasticity, Sec. 109).
J_TORSION = 0.1406
KAPPA_SHEAR = 5.0 / 6.0  # shear coefficient of a rectangle
K_SE = np.array([KAPPA_SHEAR * G * AREA, KAPPA_SHEAR * G * AREA, E * AREA])
K_BT = np.array([E * I_BEND, E * I_BEND, G * J_TORSION])
U_STAR = np.array([0.0, 1.0 / RADIUS, 0.0])  # bends d3 towards d1 (about d2)


def design(steps: int) -> dict:
    """The bend as a softrod design: upright (d3 = +z at the base), curling towards +x, so the
    load perpendicular to the arc's plane is along y."""
    return {
        "design": {"name": "bend_45", "citation": "Bathe and Bolourchi 1979, 45-degree bend"},
        "mounting": {"orientation": "upright", "gravity": "0 m/s^2"},
        "sections": [
            {
                "name": "arc",
                "length": f"{LENGTH} m",
                "outer_radius": "0.5 m",
                "mass": "1 kg",
                "EA": f"{K_SE[2]} N",
                "GA": f"{K_SE[0]} N",
                "EI": f"{K_BT[0]} N*m^2",
                "GJ": f"{K_BT[2]} N*m^2",
                "curvature": [0, f"{U_STAR[1]} 1/m", 0],
                "steps": steps,
            }
        ],
    }


def reference_tips(forces: list[float]) -> list[np.ndarray]:
    """Tip positions from the independent solver: shooting on the base moment m(0) with
    scipy's adaptive eighth-order Dormand-Prince integrator (DOP853, rtol 1e-13) and MINPACK's
    hybrid root finder, by continuation in the load from the unloaded arc. Without line
    loads the internal force is the tip force everywhere (n' = 0, n = F e_y), so the state is
    y = (r, R row-major, m) in the world frame with the body strains of the linear law
    v = v* + K_se^-1 R^T n, u = u* + K_bt^-1 R^T m and r' = R v, R' = R [u]x, m' = -r' x n;
    clamped base (r = 0, R = I) and a free tip, m(L) = 0."""
    from scipy.integrate import solve_ivp
    from scipy.optimize import root

    def tip_moment(m0: np.ndarray, n: np.ndarray, full: bool = False):
        def rhs(_s, y):
            rot = y[3:12].reshape(3, 3)
            v = rot.T @ n / K_SE + np.array([0.0, 0.0, 1.0])
            u = rot.T @ y[12:15] / K_BT + U_STAR
            dr = rot @ v
            hat_u = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
            return np.concatenate([dr, (rot @ hat_u).ravel(), -np.cross(dr, n)])

        y0 = np.concatenate([np.zeros(3), np.eye(3).ravel(), m0])
        out = solve_ivp(rhs, (0.0, LENGTH), y0, method="DOP853", rtol=1e-13, atol=1e-12)
        assert out.success, out.message
        return out.y[:, -1] if full else out.y[12:15, -1]

    tips, m0 = [], np.zeros(3)
    for force in forces:
        for level in np.linspace(0.0, force, 7)[1:]:  # six load steps per load
            n = np.array([0.0, level, 0.0])
            # MINPACK may report "no further improvement" at round-off: what counts is the
            # tip moment it leaves, checked below.
            m0 = root(tip_moment, m0, args=(n,), method="hybr", tol=1e-14).x
        # The tip moment left by the root finder, against the base moment's scale F L.
        tip = tip_moment(m0, n, full=True)
        assert np.abs(tip[12:15]).max() < 1e-9 * force * LENGTH
        tips.append(tip[0:3].copy())
    return tips


@pytest.fixture(scope="module")
def references() -> dict[float, np.ndarray]:
    forces = [300.0, 600.0]
    return dict(zip(forces, reference_tips(forces), strict=True))


@pytest.mark.parametrize("force", [300.0, 600.0])
def test_45_degree_bend_converges_at_fourth_order_to_the_independent_solver(references, force):
    ref = references[force]
    # The reference's own error: DOP853 at rtol 1e-13 over a 79 m rod and a tip moment left
    # below 1e-9 F L give tips to ~1e-9 m, far below softrod's errors at these step counts
    # (> 1e-6 m), which the order check below needs (1e-8 m would bend a slope by < 1 %).
    errors = []
    for steps in (8, 16, 32):
        d = load_design(design(steps))
        sol = solve_statics(d, [], tip_force=[0.0, force, 0.0], options=SolverOptions(tol=1e-12))
        assert sol.converged and sol.stable
        errors.append(float(np.linalg.norm(sol.tip_position - ref)))
    # RK4: the error falls by 2^4 = 16 per halving of h; 11-22 allows the O(h^5) terms still
    # present at 8 steps over a large deflection (the slope between 16 and 32 steps, closer
    # to the asymptote, must be within 14-18).
    assert 11 < errors[0] / errors[1] < 22, errors
    assert 14 < errors[1] / errors[2] < 18, errors
    # At 32 steps (one step per 1.4 degrees of arc) the tip agrees to 1e-6 of the length.
    assert errors[2] < 1e-6 * LENGTH, errors


def test_45_degree_bend_deflects_out_of_plane_as_published(references):
    """Shape sanity against the literature's picture of the problem (not its digits, which
    come from coarse 8-element meshes): the load lifts the tip out of the arc's plane and
    pulls it back towards the base; more load, more of both."""
    unloaded = np.array([RADIUS * (1 - math.cos(math.pi / 4)), 0.0, RADIUS * math.sin(math.pi / 4)])
    t300, t600 = references[300.0], references[600.0]
    assert 0 < t300[1] < t600[1] < LENGTH
    assert t600[2] < t300[2] < unloaded[2]
    assert t600[0] < t300[0] < unloaded[0]
