"""Tip-error tables: how far predicted tip positions lie from measured ones.

Errors are taken sample by sample between measured and predicted tip positions (m, world
frame) and reported in mm:

- the Euclidean tip error |r_measured - r_predicted| (paper 002's cost K, Table V), also in %
  of the reference length L (paper 001 Fig. 7 gives errors "in relation to the initial
  actuator length") and in % of the tip deflection |r_measured - r_reference|;
- the radial and height errors of paper 001 Fig. 7. With the undeformed axis a (unit vector,
  base towards tip) through the base point r0, a tip r has the height h = (r - r0) . a and
  the radial distance rho = |(r - r0) - h a| from the axis. The errors are measured minus
  predicted, as in the paper: dh = h_measured - h_predicted, drho = rho_measured -
  rho_predicted.

Failed predictions (rows of ``predicted`` holding NaN, e.g. a solve that did not converge)
are kept: they are counted in the ``failed`` column and left out of every statistic.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError, design_error
from ..units import to_si

# Below this tip deflection (m) the error in % of the deflection is meaningless (it grows
# without bound at the unpressurised sample), so such samples are left out of that column.
MIN_DEFLECTION = 1e-3

ALL = "all"  # the set label of the row over every sample

SAMPLE_COLUMNS = (
    "set",
    "failed",
    "error_mm",
    "error_pct_L",
    "deflection_mm",
    "error_pct_deflection",
    "radial_error_mm",
    "height_error_mm",
)

TABLE_COLUMNS = (
    "set",
    "n",
    "failed",
    "mean_error_mm",
    "median_error_mm",
    "max_error_mm",
    "rms_error_mm",
    "mean_error_pct_L",
    "median_error_pct_L",
    "max_error_pct_L",
    "n_deflection",
    "mean_error_pct_deflection",
    "median_error_pct_deflection",
    "mean_abs_radial_error_mm",
    "max_abs_radial_error_mm",
    "mean_abs_height_error_mm",
    "max_abs_height_error_mm",
)


def _float_array(value, field: str) -> np.ndarray:
    try:
        return np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise design_error(
            field, type(value).__name__, f"must be an array of numbers: {exc}", InputError
        ) from None


def _positions(value, field: str) -> np.ndarray:
    """An (m, 3) float array with m >= 1 and no infinite entry (NaN is checked by callers)."""
    arr = _float_array(value, field)
    if arr.ndim != 2 or arr.shape[1] != 3 or arr.shape[0] == 0:
        raise design_error(
            field,
            f"shape {arr.shape}",
            "must be an (m, 3) array of tip positions in m with m >= 1",
            InputError,
        )
    rows = np.flatnonzero(np.isinf(arr).any(axis=1))
    if rows.size:
        raise design_error(
            field, f"inf in row {rows[0]}", "tip positions must be finite (or NaN)", InputError
        )
    return arr


def _point(value, field: str) -> np.ndarray:
    arr = _float_array(value, field)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise design_error(
            field, f"{arr.tolist()}", "must be 3 finite numbers (m, world frame)", InputError
        )
    return arr


def _unit_axis(value) -> np.ndarray:
    arr = _point(value, "axis")
    norm = float(np.linalg.norm(arr))
    if norm == 0.0:
        raise design_error("axis", arr.tolist(), "must be a non-zero vector", InputError)
    return arr / norm


def _reference(value, m: int) -> np.ndarray:
    arr = _float_array(value, "reference")
    if arr.shape not in ((3,), (m, 3)) or not np.all(np.isfinite(arr)):
        raise design_error(
            "reference",
            f"shape {arr.shape}",
            f"must be a finite (3,) tip position or an ({m}, 3) array of them, in m",
            InputError,
        )
    return np.broadcast_to(arr, (m, 3))


def _labels(value, m: int) -> np.ndarray:
    if value is None:
        return np.full(m, ALL, dtype=object)
    arr = np.asarray(value, dtype=object)
    if arr.shape != (m,):
        raise design_error(
            "labels", f"shape {arr.shape}", f"must hold one set name per sample ({m})", InputError
        )
    bad = [x for x in arr if not isinstance(x, str) or not x]
    if bad:
        raise design_error(
            "labels", bad[0], "set names must be non-empty strings (e.g. 'train')", InputError
        )
    names = set(arr)
    if ALL in names and len(names) > 1:
        raise design_error(
            "labels", ALL, f"{ALL!r} names the row over every sample; rename that set", InputError
        )
    return arr


def _length(value, field: str, positive: bool = True) -> float:
    if isinstance(value, np.generic):  # numpy scalars: to_si takes Python numbers
        value = value.item()
    x = to_si(value, "length", field, InputError)
    if x < 0.0 or (positive and x == 0.0):
        rule = "must be a positive length" if positive else "must be a length >= 0"
        raise design_error(field, value, rule, InputError)
    return x


def _axial_radial(points: np.ndarray, base: np.ndarray, axis: np.ndarray):
    """Height along the axis and distance from it, of every row of ``points`` (m)."""
    rel = points - base
    height = rel @ axis
    radial = np.linalg.norm(rel - height[:, None] * axis, axis=1)
    return height, radial


def per_sample_errors(
    measured,
    predicted,
    *,
    length=None,
    reference=None,
    base_position=None,
    axis=None,
    labels=None,
    min_deflection=MIN_DEFLECTION,
):
    """Tip errors of every sample; a pandas DataFrame with the columns of
    :data:`SAMPLE_COLUMNS`, one row per sample in the input order.

    measured, predicted: (m, 3) tip positions in m (world frame). ``measured`` must be
        finite; a row of ``predicted`` holding NaN is a failed prediction (``failed`` True,
        NaN errors).
    length: the reference length L (m, or a string such as "130 mm") for ``error_pct_L``
        (NaN without it).
    reference: the unloaded tip position, (3,) or one per sample (m, 3), in m. The
        deflection is |measured - reference|; ``error_pct_deflection`` is NaN where it is
        below ``min_deflection`` (m, default :data:`MIN_DEFLECTION`) or without a reference.
    base_position, axis: the base point r0 (m) and the undeformed axis a (from base
        towards tip; normalised here), both or neither. Signed radial and height errors
        (measured minus predicted, paper 001 Fig. 7; NaN without them).
    labels: the set of each sample ("train", "test", ...); default "all" for every sample.
    """
    meas = _positions(measured, "measured")
    pred = _positions(predicted, "predicted")
    m = meas.shape[0]
    if pred.shape != meas.shape:
        raise design_error(
            "predicted",
            f"shape {pred.shape}",
            f"must have the shape of measured {meas.shape}",
            InputError,
        )
    rows = np.flatnonzero(np.isnan(meas).any(axis=1))
    if rows.size:
        raise design_error(
            "measured",
            f"NaN in row {rows[0]} ({rows.size} row(s))",
            "measured tip positions must be finite: drop the samples without a measurement",
            InputError,
        )
    if (axis is None) != (base_position is None):
        raise design_error(
            "axis" if axis is None else "base_position",
            None,
            "radial and height errors need both base_position and axis",
            InputError,
        )
    sets = _labels(labels, m)
    length_m = np.nan if length is None else _length(length, "length")
    min_defl = _length(min_deflection, "min_deflection", positive=False)

    failed = np.isnan(pred).any(axis=1)
    error = np.linalg.norm(meas - pred, axis=1)  # NaN on failed rows
    nan = np.full(m, np.nan)
    deflection, pct_deflection = nan, nan.copy()
    if reference is not None:
        deflection = np.linalg.norm(meas - _reference(reference, m), axis=1)
        np.divide(100.0 * error, deflection, out=pct_deflection, where=deflection >= min_defl)
    radial, height = nan, nan
    if axis is not None:
        a = _unit_axis(axis)
        r0 = _point(base_position, "base_position")
        h_meas, rho_meas = _axial_radial(meas, r0, a)
        h_pred, rho_pred = _axial_radial(pred, r0, a)
        radial, height = rho_meas - rho_pred, h_meas - h_pred

    import pandas as pd

    return pd.DataFrame(
        {
            "set": sets,
            "failed": failed,
            "error_mm": 1e3 * error,
            "error_pct_L": 100.0 * error / length_m,
            "deflection_mm": 1e3 * deflection,
            "error_pct_deflection": pct_deflection,
            "radial_error_mm": 1e3 * radial,
            "height_error_mm": 1e3 * height,
        },
        columns=list(SAMPLE_COLUMNS),
    )


def _stat(fn, values: np.ndarray) -> float:
    return float(fn(values)) if values.size else float("nan")


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values**2)))


def _row(name: str, samples) -> dict:
    ok = samples[~samples["failed"]]
    err = ok["error_mm"].to_numpy()
    pct_l = ok["error_pct_L"].to_numpy()
    pct_d = ok["error_pct_deflection"].dropna().to_numpy()
    radial = np.abs(ok["radial_error_mm"].to_numpy())
    height = np.abs(ok["height_error_mm"].to_numpy())
    return {
        "set": name,
        "n": len(samples),
        "failed": int(samples["failed"].sum()),
        "mean_error_mm": _stat(np.mean, err),
        "median_error_mm": _stat(np.median, err),
        "max_error_mm": _stat(np.max, err),
        "rms_error_mm": _stat(_rms, err),
        "mean_error_pct_L": _stat(np.mean, pct_l),
        "median_error_pct_L": _stat(np.median, pct_l),
        "max_error_pct_L": _stat(np.max, pct_l),
        "n_deflection": pct_d.size,
        "mean_error_pct_deflection": _stat(np.mean, pct_d),
        "median_error_pct_deflection": _stat(np.median, pct_d),
        "mean_abs_radial_error_mm": _stat(np.mean, radial),
        "max_abs_radial_error_mm": _stat(np.max, radial),
        "mean_abs_height_error_mm": _stat(np.mean, height),
        "max_abs_height_error_mm": _stat(np.max, height),
    }


def tip_error_table(
    measured,
    predicted,
    *,
    length,
    reference=None,
    base_position=None,
    axis=None,
    labels=None,
    min_deflection=MIN_DEFLECTION,
):
    """Tip-error statistics per set (paper 002 Table V: training and test errors); a pandas
    DataFrame with the columns of :data:`TABLE_COLUMNS`.

    Arguments as in :func:`per_sample_errors`, except that ``length`` (L, in m or a string
    with units) is required. One row per set label in order of first appearance, then a row
    "all" when there are several sets (one row "all" without labels).

    Columns: ``n`` samples in the set, of which ``failed`` have no prediction; every
    statistic is over the other ``n - failed``. Euclidean tip error in mm (mean, median,
    max, RMS) and in % of L (mean, median, max); mean and median error in % of the tip
    deflection over the ``n_deflection`` samples whose deflection is at least
    ``min_deflection`` (0 without ``reference``); mean and max absolute radial and height
    errors in mm (NaN without ``base_position`` and ``axis``). A statistic over no sample is
    NaN.
    """
    if length is None:
        raise design_error("length", None, "the reference length L is required", InputError)
    samples = per_sample_errors(
        measured,
        predicted,
        length=length,
        reference=reference,
        base_position=base_position,
        axis=axis,
        labels=labels,
        min_deflection=min_deflection,
    )
    names = list(dict.fromkeys(samples["set"]))
    rows = [_row(name, samples[samples["set"] == name]) for name in names]
    if len(names) > 1:
        rows.append(_row(ALL, samples))

    import pandas as pd

    return pd.DataFrame(rows, columns=list(TABLE_COLUMNS))
