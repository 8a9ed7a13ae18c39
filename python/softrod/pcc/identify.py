"""Visco-elastic identification of the PCC parameters (paper 003, Sec. V).

- :func:`fit_longitudinal_stiffness`: Hookean fit F = k_L d of equal-pressure elongation
  (Sec. V-B), F = n p A.
- :func:`fit_bending_stiffness`: k_theta(theta) = M / theta from one-side pressurisation
  (Sec. V-C), M the chamber moment of the design, as a polynomial and a table.
- :func:`fit_longitudinal_damping`: two-exponential fit of an overdamped step response
  (Sec. V-D), b_L from its two poles.
- :func:`fit_bending_damping`: logarithmic decrement of a free decay (Sec. V-E, eq. 15).
- :func:`bending_angle_from_tip`: theta of the arc through the tip (paper eq. 14 corrected).

Every fit returns a :class:`PccFit` with the values, their standard errors and the fit
residual; ``fit.to_design(design)`` writes them into the design's ``[pcc]`` table.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import curve_fit, least_squares

from ..design import Design, load_design
from ..errors import ConvergenceError, InputError, design_error
from ..units import SI_UNIT

__all__ = [
    "PccFit",
    "bending_angle_from_tip",
    "chamber_moment",
    "fit_bending_damping",
    "fit_bending_stiffness",
    "fit_longitudinal_damping",
    "fit_longitudinal_stiffness",
]

_UNITS = {
    "k_L": "force_per_length",
    "b_L": "damping_linear",
    "k_theta": "moment",
    "b_theta": "damping_rotational",
}


@dataclass(frozen=True)
class PccFit:
    """Result of one identification.

    values: the fitted [pcc] parameters (SI), e.g. {"k_L": 246.0}.
    stderr: their standard errors (same keys).
    residual: RMS of the fit residual, in the unit of the fitted data (``residual_unit``).
    details: other fitted quantities (poles, damping ratio, polynomial, ...).
    table: for k_theta(theta), (angles rad, stiffness N m/rad) to write as a table.
    """

    values: dict[str, float]
    stderr: dict[str, float]
    residual: float
    residual_unit: str
    details: dict = field(default_factory=dict)
    table: tuple[np.ndarray, np.ndarray] | None = None

    def to_design(self, design) -> Design:
        """A copy of ``design`` with the fitted values in its ``[pcc]`` table."""
        design = load_design(design)
        changes = {}
        for key, val in self.values.items():
            if key == "k_theta" and self.table is not None:
                angles, stiff = self.table
                changes["pcc.k_theta"] = {
                    "angle": [float(a) for a in angles],
                    "stiffness": [float(k) for k in stiff],
                }
            else:
                changes[f"pcc.{key}"] = f"{float(val)!r} {SI_UNIT[_UNITS[key]]}"
        return design.replace(changes)


def _arrays(*named) -> list[np.ndarray]:
    out = []
    n = None
    for name, value in named:
        arr = np.asarray(value, dtype=float).ravel()
        if arr.size < 3 or not np.all(np.isfinite(arr)):
            raise design_error(name, f"{arr.size} values", "needs >= 3 finite samples", InputError)
        if n is not None and arr.size != n:
            raise design_error(
                name,
                f"{arr.size} values",
                f"must have as many samples as the first ({n})",
                InputError,
            )
        n = arr.size
        out.append(arr)
    return out


def _positive(name: str, value) -> float:
    x = float(value)
    if not (np.isfinite(x) and x > 0):
        raise design_error(name, value, "must be a finite number > 0", InputError)
    return x


def fit_longitudinal_stiffness(pressure, elongation, *, area, n_chambers: int = 3) -> PccFit:
    """Hookean fit k_L d = n p A (paper 003 Sec. V-B) through the origin.

    pressure (Pa) on ``n_chambers`` chambers of area ``area`` (m^2) each; elongation d (m).
    """
    p, d = _arrays(("pressure", pressure), ("elongation", elongation))
    force = n_chambers * _positive("area", area) * p
    popt, pcov = curve_fit(lambda f, c: f * c, force, d, p0=[d.max() / max(force.max(), 1e-30)])
    compliance = popt[0]
    if not compliance > 0:
        raise ConvergenceError(
            f"elongation does not grow with pressure (compliance {compliance:.3e} m/N)",
            0,
            float("nan"),
            1.0,
            "Hookean fit",
        )
    k = 1.0 / compliance
    se = float(np.sqrt(pcov[0, 0])) * k * k
    res = d - force * compliance
    return PccFit({"k_L": k}, {"k_L": se}, float(np.sqrt(np.mean(res**2))), "m")


def chamber_moment(design, pressures) -> np.ndarray:
    """Magnitude of the bending moment |sum_k p_k A_k rho_k| (N m) of the first segment's
    chambers for each row of ``pressures`` (m, channels), Pa: the generalised force on the
    bending vector (virtual work of p A delta(chamber length), docs/pcc.md)."""
    design = load_design(design)
    p = np.atleast_2d(np.asarray(pressures, dtype=float))
    sec = next(s for s in design.sections() if not s["rigid"] and s["chambers"])
    m = np.zeros((p.shape[0], 2))
    for area, cx, cy, ch in sec["chambers"]:
        m[:, 0] += p[:, ch] * area * cx
        m[:, 1] += p[:, ch] * area * cy
    return np.hypot(m[:, 0], m[:, 1])


def bending_angle_from_tip(x, z) -> np.ndarray:
    """Bending angle of the arc from base to tip (x in the bending plane, z along the base
    axis): theta = 2 atan2(x, z), since x/z = (1 - cos theta)/sin theta = tan(theta/2).
    Paper 003 eq. 14 writes asin(2 x z / (x^2 + z^2)) = asin(sin theta), which folds angles
    above 90 deg back (its Fig. 5 reaches 140 deg)."""
    return 2.0 * np.arctan2(np.asarray(x, dtype=float), np.asarray(z, dtype=float))


def fit_bending_stiffness(
    theta, moment, *, degree: int = 2, n_table: int = 8, min_angle: float = 0.05
) -> PccFit:
    """k_theta(theta) = M / theta (paper 003 Sec. V-C, Fig. 5c) from bending angles theta
    (rad) and chamber moments M (N m, see :func:`chamber_moment`).

    Fits M = theta * poly(theta) with a polynomial of ``degree`` by least squares; samples
    below ``min_angle`` rad carry no information on k and are dropped. ``values["k_theta"]``
    is k at the smallest angle; ``table`` holds k at ``n_table`` angles over the data.
    """
    th, m = _arrays(("theta", theta), ("moment", moment))
    keep = np.abs(th) >= min_angle
    if keep.sum() < degree + 2:
        raise design_error(
            "theta",
            f"{keep.sum()} samples >= {min_angle} rad",
            f"need at least {degree + 2} bent samples for a degree-{degree} fit",
            InputError,
        )
    th, m = np.abs(th[keep]), np.abs(m[keep])

    def model(t, *c):
        return t * np.polyval(c, t)

    p0 = [0.0] * degree + [float(np.median(m / th))]
    popt, pcov = curve_fit(model, th, m, p0=p0)
    grid = np.linspace(th.min(), th.max(), n_table)
    k = np.polyval(popt, grid)
    if np.any(k <= 0):
        raise ConvergenceError(
            "fitted k_theta(theta) is not positive over the data; lower the degree",
            0,
            float("nan"),
            1.0,
            "bending stiffness fit",
        )
    # Standard error of k at the smallest angle from the coefficient covariance.
    basis = grid[0] ** np.arange(degree, -1, -1)
    se = float(np.sqrt(basis @ pcov @ basis))
    res = m - model(th, *popt)
    return PccFit(
        {"k_theta": float(k[0])},
        {"k_theta": se},
        float(np.sqrt(np.mean(res**2))),
        "N*m",
        details={"coefficients": popt, "covariance": pcov},
        table=(grid, k),
    )


def fit_longitudinal_damping(time, elongation, *, k_L: float, mass: float | None = None) -> PccFit:
    """Two-exponential fit Z(t) = Z_inf + A e^(B t) + C e^(D t) of an overdamped step
    response (paper 003 Sec. V-D) and b_L from its poles.

    The poles of m s^2 + b s + k are B and D: B D = k/m and B + D = -b/m, so
    b_L = -k_L (1/B + 1/D) and the mass m = k_L/(B D) follows. With ``mass`` (kg) given,
    b_L = -(k_L + m B^2)/B is also reported from the slow pole B alone (details
    ``b_L_slow_pole``), which is the usable one when the fast pole is too fast to sample.
    """
    t, z = _arrays(("time", time), ("elongation", elongation))
    k = _positive("k_L", k_L)
    t = t - t[0]
    span = t[-1]
    if not span > 0:
        raise design_error("time", "constant", "must increase", InputError)

    def amplitudes(rates):
        basis = np.column_stack([np.ones_like(t), np.exp(rates[0] * t), np.exp(rates[1] * t)])
        coef, *_ = np.linalg.lstsq(basis, z, rcond=None)
        return coef, basis @ coef - z

    # Variable projection on the log-rates, then one joint fit for the covariance.
    def resid(lr):
        return amplitudes(-np.exp(lr))[1]

    best = None
    for slow in np.log(np.geomspace(0.5 / span, 20.0 / span, 6)):
        for ratio in (3.0, 10.0, 30.0):
            sol = least_squares(resid, [slow, slow + np.log(ratio)])
            if best is None or sol.cost < best.cost:
                best = sol
    rates = -np.exp(best.x)
    coef, _ = amplitudes(rates)

    def full(tt, zi, a, b, c, d):
        return zi + a * np.exp(b * tt) + c * np.exp(d * tt)

    p0 = [coef[0], coef[1], rates[0], coef[2], rates[1]]
    try:
        popt, pcov = curve_fit(full, t, z, p0=p0, maxfev=20000)
    except RuntimeError as exc:
        raise ConvergenceError(
            f"two-exponential fit failed: {exc}", 0, float("nan"), 1.0, "step response fit"
        ) from None
    zi, a, bb, c, dd = popt
    if not (bb < 0 and dd < 0):
        raise ConvergenceError(
            f"fitted poles {bb:.4g}, {dd:.4g} 1/s are not both negative: not an overdamped decay",
            0,
            float("nan"),
            1.0,
            "step response fit",
        )
    slow, fast = (bb, dd) if bb > dd else (dd, bb)
    b = -k * (1.0 / bb + 1.0 / dd)
    # Error propagation through b(B, D).
    grad = np.zeros(5)
    grad[2] = k / bb**2
    grad[4] = k / dd**2
    se = float(np.sqrt(grad @ pcov @ grad))
    res = z - full(t, *popt)
    details = {
        "poles": (float(slow), float(fast)),
        "amplitudes": (float(a), float(c)),
        "final": float(zi),
        "mass": float(k / (bb * dd)),
        "damping_ratio": float(b / (2.0 * np.sqrt(k * k / (bb * dd)))),
    }
    if mass is not None:
        m = _positive("mass", mass)
        details["b_L_slow_pole"] = float(-(k + m * slow**2) / slow)
    return PccFit({"b_L": float(b)}, {"b_L": se}, float(np.sqrt(np.mean(res**2))), "m", details)


def _half_cycle_peaks(x: np.ndarray, threshold: float) -> list[int]:
    """Index of the largest |x| in each half cycle; half cycles change when x crosses
    -h or +h after the other, h = threshold * max|x|."""
    h = threshold * np.abs(x).max()
    peaks, start, sign = [], 0, 0
    for i, v in enumerate(x):
        s = 1 if v > h else (-1 if v < -h else 0)
        if s and s != sign:
            if sign:
                peaks.append(start + int(np.argmax(np.abs(x[start:i]))))
            start, sign = i, s
    return peaks


def fit_bending_damping(
    time,
    theta,
    *,
    k_theta: float,
    inertia: float | None = None,
    min_peaks: int = 3,
    threshold: float = 0.05,
) -> PccFit:
    """Logarithmic decrement of a free bending decay (paper 003 Sec. V-E, eq. 15).

    delta = (1/n) ln(theta(t)/theta(t + n T)) over the peaks of |theta - theta_final|,
    zeta = delta / sqrt(4 pi^2 + delta^2), b_theta = 2 zeta sqrt(k_theta J). J (kg m^2) is
    ``inertia`` when given (the paper's J_theta), else k_theta / omega_n^2 with omega_n
    from the measured period (omega_n = omega_d / sqrt(1 - zeta^2)). Extrema are taken
    once per half cycle (sign changes with a hysteresis of ``threshold`` times the largest
    deflection), so measurement noise does not add spurious peaks; smaller ones are ignored.
    """
    t, th = _arrays(("time", time), ("theta", theta))
    k = _positive("k_theta", k_theta)
    x = th - np.mean(th[-max(3, len(th) // 20) :])
    peaks = _half_cycle_peaks(x, threshold)
    if len(peaks) < min_peaks:
        raise design_error(
            "theta",
            f"{len(peaks)} extrema above {threshold:.0%} of the largest",
            f"a free decay with at least {min_peaks} extrema is needed for the logarithmic "
            "decrement (is the motion overdamped?)",
            InputError,
        )
    # Extrema alternate about the rest angle c: e_i = c + A (-r)^i with r the amplitude
    # ratio per half cycle, fitted together so that c need not be known (the decay may not
    # have settled by the end of the record).
    e = th[peaks]
    tp = t[peaks]
    i = np.arange(len(e), dtype=float)
    amp = np.abs(x[peaks])
    r0 = float(np.exp(np.polyfit(i, np.log(amp), 1)[0]))

    def extrema(ii, c, a, r):
        return c + a * (-r) ** ii

    popt, pcov = curve_fit(extrema, i, e, p0=[float(np.mean(th[-5:])), float(e[0]), r0])
    c, a, r = popt
    if not 0 < r < 1:
        raise ConvergenceError(
            f"amplitude ratio per half cycle {r:.4g} is not in (0, 1): not a decay",
            0,
            float("nan"),
            1.0,
            "logarithmic decrement",
        )
    delta = -2.0 * np.log(r)  # per full period (eq. 15 with n = 1)
    period = 2.0 * float(np.mean(np.diff(tp)))
    zeta = delta / np.sqrt(4 * np.pi**2 + delta**2)
    wd = 2 * np.pi / period
    wn = wd / np.sqrt(1 - zeta**2)
    j = float(inertia) if inertia is not None else k / wn**2
    b = 2 * zeta * np.sqrt(k * j)
    res = e - extrema(i, *popt)
    # b is nearly proportional to delta = -2 ln r: relative error 2 se(r) / (r delta).
    se = float(b * 2.0 * np.sqrt(pcov[2, 2]) / (r * delta))
    return PccFit(
        {"b_theta": float(b)},
        {"b_theta": se},
        float(np.sqrt(np.mean(res**2))),
        "rad",
        details={
            "log_decrement": float(delta),
            "damping_ratio": float(zeta),
            "period": period,
            "omega_n": float(wn),
            "inertia": j,
            "peaks": len(e),
            "rest_angle": float(c),
        },
    )
