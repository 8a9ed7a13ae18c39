"""What the data determine: covariance, standard errors, correlations and identifiability
from the residual Jacobian at the optimum, for any model and any parameter set.

The Gauss-Newton covariance is s^2 (J^T J)^-1 with s^2 = SSR / (n - P) (SSR and J of the
weighted residuals). Identifiability is read from the near-null space of the column-scaled
Jacobian (each column times the parameter's size: relative changes): a singular value below
1/:data:`UNIDENTIFIABLE_CONDITION` of the largest means that a combination of relative
parameter changes barely moves the predictions, and the right singular vector names that
combination. This is how a gauge freedom shows itself, whatever the model and the parameter
set: paper 000 Sec. II-G's effective area A_eff with the mass, stiffness and damping (scaling
A_eff, the stiffness and the mass together leaves every motion unchanged), a chamber area
with a stiffness in a weightless statics, a stiffness with a density under gravity alone.
No pair of parameter names is looked up anywhere.
"""

from __future__ import annotations

import math

import numpy as np

from ..schema import display

#: |r| above which a pair of parameters is reported as strongly correlated: at |r| = 0.9 the
#: data pin down one combination of the pair about 2.3 times (1 / sqrt(1 - r^2)) better than
#: either parameter alone, and each standard error is that much larger than it would be with
#: the other parameter fixed.
STRONG_CORRELATION = 0.9
#: Condition number of the column-scaled Jacobian above which the fit is reported as not
#: identifiable: a relative change of 1e-6 in the best-determined combination moves the
#: predictions as much as a change of 1 in the worst.
UNIDENTIFIABLE_CONDITION = 1e6
#: A parameter whose standard error exceeds this fraction of its value is reported as poorly
#: determined: at 20 % its 95 % interval spans +-40 % of the value, too wide to compare
#: actuators or to publish the value as a material property.
POOR_RELATIVE_ERROR = 0.2
#: Column scale of a parameter that may be zero or negative (offsets in m, angles in rad):
#: a change of 1 mm (or 1 mrad), the size of what such fits resolve.
ABSOLUTE_SCALE = 1e-3


def warning_thresholds() -> str:
    """The rules behind the calibration warnings, as reports and the CLI state them."""
    return (
        f"warnings when a relative standard error exceeds {100 * POOR_RELATIVE_ERROR:g} %, a "
        f"correlation |r| exceeds {STRONG_CORRELATION:g} or the singular values of the scaled "
        f"Jacobian span more than {UNIDENTIFIABLE_CONDITION:.0e}"
    )


def column_scales(params, values) -> np.ndarray:
    """Relative changes for positive parameters, ABSOLUTE_SCALE for the others."""
    return np.array(
        [abs(v) if p.positive else ABSOLUTE_SCALE for p, v in zip(params, values, strict=True)]
    )


def null_space(jac: np.ndarray, scale: np.ndarray) -> list[tuple[float, np.ndarray]]:
    """(singular value ratio, right singular vector) of every direction of the scaled
    Jacobian whose singular value lies below 1/UNIDENTIFIABLE_CONDITION of the largest."""
    js = jac * scale
    _, sv, vt = np.linalg.svd(js, full_matrices=False)
    if sv[0] == 0:
        return [(0.0, v) for v in vt]
    return [(sv[k] / sv[0], vt[k]) for k in np.flatnonzero(sv < sv[0] / UNIDENTIFIABLE_CONDITION)]


def diagnostics(params, values, jac, ssr, n_res, what: str = "the predictions"):
    """(covariance, standard errors, correlation, warnings) from the weighted residual
    Jacobian ``jac`` (n_res, P) per SI unit of each parameter at the optimum, and the
    weighted sum of squared residuals ``ssr``. ``what`` names what the residuals measure
    (for the messages)."""
    n_par = len(params)
    found: list[str] = []
    dof = n_res - n_par
    if dof <= 0:
        found.append(f"{n_res} residuals for {n_par} parameters: no standard errors")
        nan = np.full((n_par, n_par), np.nan)
        return nan, np.full(n_par, np.nan), nan, found
    scale = column_scales(params, values)
    js = jac * scale
    sv = np.linalg.svd(js, compute_uv=False)
    cond = sv[0] / sv[-1] if sv[-1] > 0 else math.inf
    s2 = ssr / dof
    if cond > UNIDENTIFIABLE_CONDITION:
        for ratio, null in null_space(jac, scale):
            involved = [
                f"{params[j].name} ({null[j]:+.2f})"
                for j in np.argsort(-np.abs(null))
                if abs(null[j]) > 0.1
            ]
            found.append(
                f"not identifiable: {what} barely change along the combination "
                f"{', '.join(involved)} of relative parameter changes (singular value ratio "
                f"{ratio:.1e} < 1/{UNIDENTIFIABLE_CONDITION:.0e}); fix some of these "
                "parameters"
            )
        cov = s2 * np.linalg.pinv(js.T @ js) * np.outer(scale, scale)
        std = np.full(n_par, np.inf)
        corr = np.full((n_par, n_par), np.nan)
        return cov, std, corr, found
    inv = np.linalg.inv(js.T @ js)
    cov = s2 * inv * np.outer(scale, scale)
    std = np.sqrt(np.diag(cov))
    # From (J^T J)^-1 alone, so that it is defined for a perfect fit (s = 0) too.
    d = np.sqrt(np.diag(inv))
    corr = inv / np.outer(d, d)
    for a in range(n_par):
        for b in range(a + 1, n_par):
            if abs(corr[a, b]) > STRONG_CORRELATION:
                found.append(
                    f"{params[a].name} and {params[b].name} are strongly correlated "
                    f"(r = {corr[a, b]:+.3f}, |r| > {STRONG_CORRELATION:g}): the data "
                    "determine mainly a combination"
                )
    # Offsets may be 0, so a relative error means nothing for them: correlations judge them.
    for p, v, s in zip(params, values, std, strict=True):
        if p.positive and s > POOR_RELATIVE_ERROR * abs(v):
            (vd, unit), (sd, _) = display(v, p.unit), display(s, p.unit)
            unit = f" {unit}" if unit else ""
            found.append(
                f"{p.name} is poorly determined: standard error {sd:.3g}{unit} on {vd:.3g}{unit} "
                f"({100 * s / abs(v):.3g} % > {100 * POOR_RELATIVE_ERROR:g} %)"
            )
    return cov, std, corr, found
