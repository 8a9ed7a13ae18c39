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
residual; ``fit.to_design(design)`` writes them into the design's ``[pcc]`` table and
``fit.to_toml(path, design)`` writes that design to a file. The same fits on a
:class:`~softrod.Dataset` (tip positions, one experiment per parameter) are
``softrod.calibrate(design, dataset, params, model="pcc")`` (:mod:`softrod.pcc.experiments`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.optimize import curve_fit, least_squares

from .._validate import si_text
from ..catalog import load_design
from ..design import Design
from ..errors import ConvergenceError, InputError, design_error
from ..io import as_path, atomic_path
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
    details: other fitted quantities (poles, damping ratio, polynomial, ...); for a fit of
    several parameters (``softrod.calibrate(..., model="pcc")``) one dict per parameter,
    each with its own ``residual`` and ``residual_unit`` (``residual`` above is then NaN).
    table: for k_theta(theta), (angles rad, stiffness N m/rad) to write as a table.
    design: the design the fit was made for (``to_toml`` writes into it), or None.
    """

    values: dict[str, float]
    stderr: dict[str, float]
    residual: float
    residual_unit: str
    details: dict = field(default_factory=dict)
    table: tuple[np.ndarray, np.ndarray] | None = None
    design: Design | None = field(default=None, repr=False, compare=False)

    def unit(self, name: str) -> str:
        """The SI unit of parameter ``name``: "N/m", "N*s/m", "N*m", "N*m*s" (per rad)."""
        return SI_UNIT[_UNITS[name]]

    def summary(self) -> str:
        """One line per parameter: value, unit, standard error and fit residual."""
        lines = []
        for key, val in self.values.items():
            info = self.details.get(key) if isinstance(self.details.get(key), dict) else None
            res, res_unit = (
                (info["residual"], info["residual_unit"])
                if info is not None and "residual" in info
                else (self.residual, self.residual_unit)
            )
            lines.append(
                f"{key} = {val:.6g} {self.unit(key)} +- {self.stderr[key]:.3g} (1 s.e.), "
                f"fit residual (RMS) {res:.3g} {res_unit}"
            )
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def to_design(self, design) -> Design:
        """A copy of ``design`` with the fitted values in its ``[pcc]`` table."""
        design = load_design(design)
        changes = {}
        for key, val in self.values.items():
            if key == "k_theta" and self.table is not None:
                angles, stiff = self.table
                changes["pcc.k_theta"] = {
                    "angle": [si_text(a, "angle") for a in angles],
                    "stiffness": [si_text(k, "moment") for k in stiff],
                }
            else:
                changes[f"pcc.{key}"] = f"{float(val)!r} {SI_UNIT[_UNITS[key]]}"
        return design.replace(changes)

    def to_toml(self, path, design=None) -> Path:
        """Write ``design`` (default: the design the fit was made for) with the fitted values
        in ``[pcc]`` as a TOML design file, whole or not at all (a temporary file renamed
        into place). The values and standard errors are recorded in ``[design].assumptions``.
        Returns the path."""
        import tomli_w

        base = design if design is not None else self.design
        if base is None:
            raise design_error(
                "design", None, "name the design to write the fitted values into", InputError
            )
        path = as_path(path)
        if path.suffix.lower() != ".toml":
            raise design_error("path", str(path), "a design file must end in .toml", InputError)
        out = self.to_design(base)
        fitted = ", ".join(
            f"{k} = {v:.6g} +- {self.stderr[k]:.2g} {self.unit(k)}" for k, v in self.values.items()
        )
        line = (
            f"PCC parameters identified as in paper 003 Sec. V (softrod.pcc): {fitted} "
            "(1 standard error)."
        )
        assumptions = list(out.document["design"].get("assumptions", [])) + [line]
        out = out.replace({"design.assumptions": assumptions})
        header = (
            f"# Written by softrod from design {out.name!r} with PCC parameters identified as in\n"
            "# paper 003 Sec. V (see the last entry of [design].assumptions).\n"
        )
        text = header + tomli_w.dumps(_plain(out.document))
        with atomic_path(path) as tmp:
            tmp.write_text(text, encoding="utf-8")
        return path


def _plain(x):
    """Python scalars and lists for TOML (numpy types are not TOML types)."""
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple, np.ndarray)):
        return [_plain(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    return x


def _arrays(*named) -> list[np.ndarray]:
    out = []
    n = None
    for name, value in named:
        try:
            arr = np.asarray(value, dtype=float).ravel()
        except (TypeError, ValueError, OverflowError):
            raise design_error(
                name, type(value).__name__, "must be an array of numbers", InputError
            ) from None
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


def fit_longitudinal_stiffness(
    pressure, elongation, *, area, n_chambers: int = 3, offset: bool = False
) -> PccFit:
    """Hookean fit k_L d = n p A (paper 003 Sec. V-B) through the origin.

    pressure (Pa) on ``n_chambers`` chambers of area ``area`` (m^2) each; elongation d (m).
    With ``offset=True`` the line is n p A = k_L d + F_0 instead: F_0 (N) absorbs a constant
    axial load such as the arm's own weight on an upright or hanging arm, and an error in the
    reference length (details ``offset_force`` and ``rest_elongation`` = -F_0 / k_L, the
    elongation at zero pressure). Ordinary least squares of d on the force, k_L = 1/slope.
    """
    p, d = _arrays(("pressure", pressure), ("elongation", elongation))
    force = n_chambers * _positive("area", area) * p
    if offset:
        if np.ptp(force) <= 0:
            raise design_error(
                "pressure",
                f"one level ({p[0]:g} Pa)",
                "a fit with an offset needs at least two pressure levels",
                InputError,
            )
        basis = np.column_stack([force, np.ones_like(force)])
        coef, *_ = np.linalg.lstsq(basis, d, rcond=None)
        res = d - basis @ coef
        dof = d.size - 2
        cov = float(res @ res) / dof * np.linalg.inv(basis.T @ basis)
        compliance, rest = coef
    else:
        popt, pcov = curve_fit(lambda f, c: f * c, force, d, p0=[d.max() / max(force.max(), 1e-30)])
        compliance, rest = popt[0], 0.0
        cov = pcov
        res = d - force * compliance
    if not compliance > 0:
        raise ConvergenceError(
            f"elongation does not grow with pressure (compliance {compliance:.3e} m/N)",
            0,
            float("nan"),
            1.0,
            "Hookean fit",
        )
    k = 1.0 / compliance
    se = float(np.sqrt(cov[0, 0])) * k * k
    details = {}
    if offset:
        # F_0 = -rest k: gradient (d/dc, d/drest) of -rest / c.
        grad = np.array([rest / compliance**2, -1.0 / compliance])
        details = {
            "offset_force": float(-rest * k),
            "offset_force_stderr": float(np.sqrt(grad @ cov @ grad)),
            "rest_elongation": float(rest),
        }
    return PccFit({"k_L": k}, {"k_L": se}, float(np.sqrt(np.mean(res**2))), "m", details=details)


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


def fit_longitudinal_damping(
    time, elongation, *, k_L: float, mass: float | None = None, poles: str = "free"
) -> PccFit:
    """Two-exponential fit Z(t) = Z_inf + A e^(B t) + C e^(D t) of an overdamped step
    response (paper 003 Sec. V-D) and b_L from its poles.

    The poles of m s^2 + b s + k are B and D: B D = k/m and B + D = -b/m, so
    b_L = -k_L (1/B + 1/D) and the mass m = k_L/(B D) follows. With ``mass`` (kg) given,
    b_L = -(k_L + m B^2)/B is also reported from the slow pole B alone (details
    ``b_L_slow_pole``), which is the usable one when the fast pole is too fast to sample.

    ``poles="tied"`` (needs ``mass``) ties B and D to k_L, m and b_L by the paper's own
    relations B, D = -omega_n (xi -+ sqrt(xi^2 - 1)) and fits b_L alone (with Z_inf, A, C
    free and linear): the fast pole of a soft arm (-b/m, thousands of 1/s) cannot be sampled,
    and a free two-exponential fit leaves it undetermined (no covariance). It also covers the
    underdamped case (complex poles, Z_inf + e^(sigma t)(A cos + C sin)(omega_d t)).
    """
    t, z = _arrays(("time", time), ("elongation", elongation))
    k = _positive("k_L", k_L)
    t = t - t[0]
    span = t[-1]
    if not span > 0:
        raise design_error("time", "constant", "must increase", InputError)
    if poles not in ("free", "tied"):
        raise design_error("poles", poles, "must be 'free' or 'tied'", InputError)
    if poles == "tied":
        if mass is None:
            raise design_error("mass", None, "poles='tied' needs the mass (kg)", InputError)
        return _tied_step_fit(t, z, k, _positive("mass", mass))

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


def _tied_basis(t: np.ndarray, b: float, k: float, m: float) -> np.ndarray:
    """Columns 1 and the two modes of m s^2 + b s + k = 0 sampled at t (real poles,
    complex pair or the double pole at critical damping)."""
    disc = b * b - 4.0 * m * k
    sigma = -b / (2.0 * m)
    if disc > 1e-12 * b * b:
        root = np.sqrt(disc) / (2.0 * m)
        cols = [np.exp((sigma + root) * t), np.exp((sigma - root) * t)]
    elif disc < -1e-12 * b * b:
        wd = np.sqrt(-disc) / (2.0 * m)
        decay = np.exp(sigma * t)
        cols = [decay * np.cos(wd * t), decay * np.sin(wd * t)]
    else:
        cols = [np.exp(sigma * t), t * np.exp(sigma * t)]
    return np.column_stack([np.ones_like(t), *cols])


def _tied_step_fit(t: np.ndarray, z: np.ndarray, k: float, m: float) -> PccFit:
    """b_L of m z'' + b z' + k z = const from a step response, amplitudes free (variable
    projection on log b: a scan, then a bounded scalar search, no derivatives)."""
    from scipy.optimize import minimize_scalar

    if z.size < 5:
        raise design_error("elongation", f"{z.size} samples", "needs >= 5 samples", InputError)

    def fitted(logb):
        basis = _tied_basis(t, float(np.exp(logb)), k, m)
        coef, *_ = np.linalg.lstsq(basis, z, rcond=None)
        return coef, z - basis @ coef

    def cost(logb):
        return float(np.sum(fitted(logb)[1] ** 2))

    # b from 1e-3 to 1e5 times the critical damping 2 sqrt(k m).
    grid = np.log(2.0 * np.sqrt(k * m)) + np.linspace(np.log(1e-3), np.log(1e5), 161)
    costs = np.array([cost(g) for g in grid])
    i = int(np.argmin(costs))
    if i in (0, grid.size - 1):
        raise ConvergenceError(
            f"the best damping lies at the end of the searched range "
            f"({np.exp(grid[i]):.3g} N s/m): not a step response of k_L = {k:g} N/m and "
            f"m = {m:g} kg",
            0,
            float("nan"),
            1.0,
            "step response fit",
        )
    sol = minimize_scalar(
        cost, bounds=(grid[i - 1], grid[i + 1]), method="bounded", options={"xatol": 1e-12}
    )
    logb = float(sol.x)
    b = float(np.exp(logb))
    coef, res = fitted(logb)
    # Standard error (Kaufman's variable-projection Jacobian, central difference in log b).
    h = 1e-5
    jac = (fitted(logb + h)[1] - fitted(logb - h)[1]) / (2 * h)
    dof = max(z.size - 4, 1)
    s2 = float(res @ res) / dof
    jj = float(jac @ jac)
    se = b * float(np.sqrt(s2 / jj)) if jj > 0 else float("inf")
    disc = b * b - 4 * m * k
    if disc > 0:
        rates = ((-b + np.sqrt(disc)) / (2 * m), (-b - np.sqrt(disc)) / (2 * m))
    else:
        rates = (-b / (2 * m), -b / (2 * m))
    details = {
        "poles": tuple(float(r) for r in rates),
        "final": float(coef[0]),
        "amplitudes": (float(coef[1]), float(coef[2])),
        "mass": m,
        "damping_ratio": float(b / (2.0 * np.sqrt(k * m))),
        "poles_tied": True,
    }
    return PccFit({"b_L": b}, {"b_L": se}, float(np.sqrt(np.mean(res**2))), "m", details)


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


def _refined_extrema(t: np.ndarray, y: np.ndarray, peaks: list[int]):
    """Value and time of each extremum from a least-squares parabola through the samples
    within 1/16 of a period of it (at least the sample and its two neighbours).

    A sampled peak misses the true one by about (omega dt)^2 / 8 of the amplitude (0.5 % at
    40 Hz for a 3 Hz decay), and the largest of noisy samples is biased towards the noise:
    both bias the decrement, most at the small late peaks. The parabola's error is a fixed
    fraction of each amplitude (the cos shape over +-22.5 deg), which cancels in the ratio of
    peaks. An extremum whose parabola has its vertex outside the window keeps its sample."""
    vals, times = y[peaks].astype(float), t[peaks].astype(float)
    if len(peaks) < 2:
        return vals, times
    step = float(np.median(np.diff(t)))
    period = 2.0 * float(np.median(np.diff(t[peaks])))
    half = max(1, int(round(period / (16.0 * step))))
    for n, k in enumerate(peaks):
        lo, hi = max(0, k - half), min(len(y), k + half + 1)
        if hi - lo < 3:
            continue
        tt = t[lo:hi] - t[k]
        c2, c1, c0 = np.polyfit(tt, y[lo:hi], 2)
        if c2 == 0:
            continue
        vertex = -c1 / (2.0 * c2)
        if tt[0] <= vertex <= tt[-1]:
            vals[n] = c0 - c1 * c1 / (4.0 * c2)
            times[n] = t[k] + vertex
    return vals, times


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
    # An extremum at the first or last sample is where the record starts or ends, not
    # where the motion turns (the turn may lie outside the record): it is not used.
    peaks = [k for k in _half_cycle_peaks(x, threshold) if 0 < k < len(x) - 1]
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
    e, tp = _refined_extrema(t, th, peaks)
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
    # Extrema are half a damped period apart: t_i = t_0 + i T/2, a straight-line fit.
    basis = np.column_stack([np.ones_like(i), i])
    coef, *_ = np.linalg.lstsq(basis, tp, rcond=None)
    t_res = tp - basis @ coef
    period = 2.0 * float(coef[1])
    se_period = 2.0 * float(
        np.sqrt(t_res @ t_res / max(len(i) - 2, 1) * np.linalg.inv(basis.T @ basis)[1, 1])
    )
    zeta = delta / np.sqrt(4 * np.pi**2 + delta**2)
    wd = 2 * np.pi / period
    wn = wd / np.sqrt(1 - zeta**2)
    j = float(inertia) if inertia is not None else k / wn**2
    b = 2 * zeta * np.sqrt(k * j)
    res = e - extrema(i, *popt)
    # Relative standard errors: delta from r (d delta = -2 dr / r), zeta from delta
    # (d zeta / zeta = d delta / delta * 4 pi^2 / (4 pi^2 + delta^2)), omega_n from T; b
    # is proportional to zeta, and to 1/omega_n when J comes from k_theta / omega_n^2.
    rel_zeta = (
        2.0 * float(np.sqrt(pcov[2, 2])) / (r * delta) * 4 * np.pi**2 / (4 * np.pi**2 + delta**2)
    )
    rel_wn = se_period / period
    rel_b = np.hypot(rel_zeta, rel_wn) if inertia is None else rel_zeta
    se = float(b * rel_b)
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
            "damping_ratio_stderr": float(zeta * rel_zeta),
            "omega_n_stderr": float(wn * rel_wn),
            "inertia": j,
            "peaks": len(e),
            "rest_angle": float(c),
        },
    )
