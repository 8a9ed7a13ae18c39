"""The one result of every calibration: values with standard errors, covariance and
correlation, identifiability warnings, train/test error tables of each measured quantity,
provenance in the calibrated design, ``to_toml``, ``to_frame`` and an HTML report."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from .. import _validate as V
from ..datasets import Dataset
from ..design import Design
from ..schema import DISPLAY_UNITS, display
from .diagnostics import warning_thresholds
from .metrics import TABLE_COLUMNS, tip_error_table
from .params import SIGMA_KINDS

if TYPE_CHECKING:
    from .._types import PathLike, Units
    from ..stiffness_map import StiffnessMap


@dataclass(frozen=True)
class CalibrationResult:
    """What :func:`softrod.calibrate` found, for any model (``model``: "cosserat" or "pcc";
    ``dynamic``: time series replayed). Values and standard errors in SI (see ``units``).

    design: the calibrated design (provenance in ``[design.provenance]``); predicted,
    predicted_markers: the calibrated model's positions of every row (tip (m, 3), markers
    (m, K, 3) or None), NaN where the model failed (``converged`` False); labels: "train" or
    "test" per row; error_table: the errors per measured quantity ("tip", "markers") and
    set (no rows without measured positions); reaction_error_table: the errors of a held
    tip's measured reaction per quantity ("reaction" in mN, "reaction_moment" in N mm) and
    set, or None; predicted_reaction, predicted_reaction_moment: the calibrated model's
    reaction of every row (m, 3) (N, N m), or None for a free tip; registration: the
    fitted measurement frame (``{"angle": rad, "offset": (3,) m}``) or None; scales: the
    residual scale of each quantity (SI: m, N, N m); cost: the weighted sum of squared
    training residuals, cost_m2 the plain sum of squared position errors (m^2).
    """

    design: Design
    initial_design: Design
    parameters: tuple
    initial: np.ndarray
    values: np.ndarray
    std_errors: np.ndarray
    covariance: np.ndarray
    correlation: np.ndarray
    warnings: tuple[str, ...]
    method: str
    success: bool
    message: str
    evaluations: int
    cost_m2: float
    dataset: Dataset
    predicted: np.ndarray
    converged: np.ndarray
    labels: np.ndarray
    error_table: pd.DataFrame
    elapsed_s: float
    reference: np.ndarray = field(repr=False)
    #: One row per start (start and final values, cost, success, evaluations) when
    #: ``restarts`` > 0, else None.
    starts: pd.DataFrame | None = field(default=None, repr=False)
    model: str = "cosserat"
    dynamic: bool = False
    predicted_markers: np.ndarray | None = field(default=None, repr=False)
    registration: dict | None = None
    scales: dict = field(default_factory=dict, repr=False)
    cost: float = math.nan
    #: A staged identification's stages (softrod.pcc.identify_pcc: per parameter its
    #: experiment, closed-form start and stage value), else None.
    stages: pd.DataFrame | None = field(default=None, repr=False)
    reaction_error_table: pd.DataFrame | None = None
    predicted_reaction: np.ndarray | None = field(default=None, repr=False)
    predicted_reaction_moment: np.ndarray | None = field(default=None, repr=False)

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.parameters]

    @property
    def units(self) -> list[str]:
        return [p.unit for p in self.parameters]

    @property
    def residuals(self) -> np.ndarray:
        """Predicted minus measured tip position, (m, 3) m (NaN where a solve failed or the
        dataset has no tip)."""
        if self.dataset.tip_position is None:
            return np.full((len(self.dataset), 3), np.nan)
        return self.predicted - self.dataset.tip_position

    @property
    def rms_error_mm(self) -> float:
        """RMS position error (mm) over the training observations (NaN without measured
        positions)."""
        table = self.error_table
        row = table[table.set.isin(["train", "all"])]
        n = row["n"].to_numpy() - row["failed"].to_numpy()
        rms = row["rms_error_mm"].to_numpy()
        keep = n > 0
        if not keep.any():
            return math.nan
        return float(np.sqrt(np.sum(n[keep] * rms[keep] ** 2) / np.sum(n[keep])))

    @property
    def stiffness_scale(self) -> np.ndarray | None:
        """The fitted constant sigma (3,), or None without sigma parameters."""
        idx = {p.kind: j for j, p in enumerate(self.parameters) if p.kind in SIGMA_KINDS}
        if not idx:
            return None
        return np.array([self.values[idx[k]] if k in idx else 1.0 for k in SIGMA_KINDS])

    @property
    def stiffness_map(self) -> StiffnessMap | None:
        """A constant :class:`~softrod.StiffnessMap` of the fitted sigma (or None), to pass
        as ``stiffness_map=`` with :attr:`design`."""
        from ..stiffness_map import StiffnessMap

        s = self.stiffness_scale
        return None if s is None else StiffnessMap.constant(s, self.design.n_channels)

    def _mountings(self) -> list:
        return [] if self.dataset.mounting is None else self.dataset.mounting.tolist()

    def parameter_table(self) -> pd.DataFrame:
        rel = np.abs(self.std_errors / np.where(self.values == 0, np.nan, self.values))
        return pd.DataFrame(
            {
                "parameter": self.names,
                "unit": self.units,
                "initial": self.initial,
                "value": self.values,
                "std_error": self.std_errors,
                "rel_std_error_pct": 100 * rel,
            }
        )

    def summary(self) -> str:
        what = "Dynamic calibration" if self.dynamic else "Calibration"
        model = " (PCC model)" if self.model == "pcc" else ""
        lines = [
            f"{what} of {self.initial_design.name}{model} on {dataset_name(self.dataset)} "
            f"({self.method}, {self.evaluations} model evaluations, {self.elapsed_s:.2f} s)",
            f"  {self.message}",
        ]
        for p, v0, v, s in zip(
            self.parameters, self.initial, self.values, self.std_errors, strict=True
        ):
            (v0, unit), (v, _), (s, _) = (display(x, p.unit) for x in (v0, v, s))
            unit = f" {unit}" if unit else ""
            rel = abs(s / v) if v != 0 and math.isfinite(s) else math.nan
            rel_text = f" ({100 * rel:.3g} %)" if math.isfinite(rel) else ""
            err = f"+- {s:.3g}{unit}{rel_text}" if math.isfinite(s) else unit.strip()
            lines.append(f"  {p.name:<18} {v0:>12.6g} -> {v:>12.6g} {err}".rstrip())
        cols = ["quantity", "set", "n", "failed", "mean_error_mm", "median_error_mm"]
        cols.append("max_error_mm")
        if len(self.error_table):
            lines.append(self.error_table[cols].to_string(index=False, float_format="%.3f"))
        if self.reaction_error_table is not None:
            cols = ["quantity", "set", "n", "failed", "unit", "mean_error", "median_error"]
            cols.append("max_error")
            lines.append(
                self.reaction_error_table[cols].to_string(index=False, float_format="%.3f")
            )
        lines += [f"  warning: {w}" for w in self.warnings]
        if not self.warnings:
            lines.append(f"  no warnings ({warning_thresholds()})")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def to_toml(self, path: PathLike) -> Path:
        """Write the calibrated design as a TOML design file (whole or not at all), with
        :meth:`Design.save`. Its name is the calibrated design's (``<name>_calibrated`` or
        the ``name`` given to :func:`calibrate`); ``[design.provenance]`` records the
        dataset, the fitted values with standard errors (SI, with their unit), the method,
        the softrod version and the date, and ``[design].assumptions`` says the same in a
        sentence. Registration parameters describe the measurement frame, not the design:
        they are recorded in the provenance only."""
        if self.stiffness_scale is not None:
            raise V.fail(
                "params",
                [p.name for p in self.parameters if p.kind in SIGMA_KINDS],
                "sigma factors are per-solve, not part of a design; use result.stiffness_map "
                "with result.design, or fit c_e and c_b instead",
            )
        return self.design.save(path)

    def to_frame(self, units: Units = None) -> pd.DataFrame:
        """The predictions, one row per sample, in the dataset schema (docs/datasets.md):
        the measured sample (``p0_kPa`` ..., ``tip_x_mm`` ..., markers and the dataset's
        other columns), then ``set`` (train or test), ``converged``, the calibrated model's
        tip ``model_tip_x_mm`` ... and markers ``model_marker0_x_mm`` ... (empty where its
        solve failed) and ``error_mm`` (Euclidean distance measured - model tip, or the
        mean over the seen markers without a tip; none without either); with a measured
        reaction force the model's ``model_tip_reaction_fx_N`` ... and ``reaction_error_N``
        (Euclidean over the measured components), with a measured moment
        ``model_tip_reaction_mx_Nmm`` .... The metadata block names the calibrated and the
        initial design, the dataset, the fitted values with standard errors and the softrod
        version; ``load_dataset`` reads the table back."""
        from ..schema import Extra, schema_frame

        ds = self.dataset
        ok = self.converged
        extras = [
            Extra("set", self.labels, "train or test"),
            Extra("converged", ok, "the calibrated model's solve converged"),
        ]
        if ds.tip_position is not None:
            predicted = np.where(ok[:, None], self.predicted, np.nan)
            extras += [
                Extra(f"model_tip_{a}", predicted[:, i], "calibrated model's tip", "length")
                for i, a in enumerate("xyz")
            ]
            error = np.linalg.norm(ds.tip_position - predicted, axis=1)
        if self.predicted_markers is not None:
            pm = np.where(ok[:, None, None], self.predicted_markers, np.nan)
            for k in range(pm.shape[1]):
                extras += [
                    Extra(
                        f"model_marker{k}_{a}",
                        pm[:, k, i],
                        f"calibrated model's marker {k}",
                        "length",
                    )
                    for i, a in enumerate("xyz")
                ]
            if ds.tip_position is None:
                with np.errstate(invalid="ignore"):
                    dist = np.linalg.norm(ds.markers - pm, axis=2)
                    error = np.nanmean(np.where(np.isfinite(dist), dist, np.nan), axis=1)
        if ds.tip_position is not None or self.predicted_markers is not None:
            label = (
                "|measured - model tip|"
                if ds.tip_position is not None
                else ("mean |measured - model marker|")
            )
            extras.append(Extra("error", error, label, "length"))
        for key, measured, model, kind in (
            ("f", ds.tip_reaction_force, self.predicted_reaction, "force"),
            ("m", ds.tip_reaction_moment, self.predicted_reaction_moment, "moment"),
        ):
            if measured is None:
                continue
            model = np.where(ok[:, None], model, np.nan)
            extras += [
                Extra(
                    f"model_tip_reaction_{key}{a}",
                    model[:, i],
                    f"calibrated model's tip reaction {kind}",
                    kind,
                )
                for i, a in enumerate("xyz")
            ]
            if key == "f":
                extras.append(
                    Extra(
                        "reaction_error",
                        _reaction_errors(measured, model),
                        "|measured - model tip reaction force| over the measured components",
                        "force",
                    )
                )
        meta = {
            "generator": "softrod.calibrate",
            "synthetic": ds.synthetic,  # the measured columns are the dataset's
            **(self.design.provenance or {}),
            "design": self.design.name,
        }
        return schema_frame(
            pressures=ds.pressures,
            tip_position=ds.tip_position,
            tip_rotation=ds.tip_rotation,
            base_force=ds.base_force,
            base_moment=ds.base_moment,
            time=ds.time,
            experiment=ds.experiment,
            mounting=ds.mounting,
            markers=ds.markers,
            marker_s=ds.marker_s,
            marker_offset=ds.marker_offset,
            tip_reaction_force=ds.tip_reaction_force,
            tip_reaction_moment=ds.tip_reaction_moment,
            extras=extras,
            units=units,
            metadata=meta,
        )

    def write_report(self, path: PathLike) -> Path:
        """An HTML report: parameters, correlations, error tables and figures."""
        from .report import write_report

        d = self.design
        one_mounting = len(set(self._mountings())) <= 1
        points = report_points(self.dataset, self.predicted, self.predicted_markers, self.labels)
        title = "softrod dynamic calibration" if self.dynamic else "softrod calibration"
        summary = {
            "design": self.initial_design.name,
            "model": self.model + (" (time series replayed)" if self.dynamic else ""),
            **fit_summary(self),
        }
        return write_report(
            path,
            title=f"{title}: {self.initial_design.name}",
            summary=summary,
            parameter_table=display_table(self.parameter_table()),
            error_table=self.error_table,
            reaction_table=self.reaction_error_table,
            **points,
            warnings=self.warnings,
            correlation=self.correlation,
            param_names=self.names,
            length=d.length,
            axis=_axis(d) if one_mounting and self.registration is None else None,
            base_position=_base_position(d) if one_mounting and self.registration is None else None,
            warning_rules=warning_thresholds(),
        )


def fit_summary(result) -> dict:
    """The report's summary lines that every fit has (a CalibrationResult's or a
    SystemCalibrationResult's): dataset, samples, method, evaluations, cost, status, time
    and the registration where one was fitted."""
    labels = result.labels
    summary = {
        "dataset": dataset_name(result.dataset),
        "synthetic data": result.dataset.synthetic,
        "samples (train / test)": f"{(labels == 'train').sum()} / {(labels == 'test').sum()}",
        "method": result.method,
        "model evaluations": result.evaluations,
        "final cost (sum of squared position errors)": f"{result.cost_m2 * 1e6:.4g} mm^2",
        "status": result.message,
        "time": f"{result.elapsed_s:.2f} s",
    }
    if result.registration is not None:
        angle = math.degrees(result.registration["angle"])
        offset = 1e3 * np.asarray(result.registration["offset"])
        summary["registration (measurement frame)"] = (
            f"{angle:.4g} deg about the base axis, offset "
            f"({offset[0]:.4g}, {offset[1]:.4g}, {offset[2]:.4g}) mm"
        )
    return summary


def report_points(dataset: Dataset, predicted, predicted_markers, labels, tip: str = "tip"):
    """The keywords of a report's figures (measured, predicted, labels, pressures, point):
    the tip (named ``tip``: a system's "platform") where the dataset measures it, else every
    seen marker; no figures without measured positions (a held tip's reaction only)."""
    ds = dataset
    if ds.tip_position is not None:
        return {
            "measured": ds.tip_position,
            "predicted": predicted,
            "labels": labels,
            "pressures": ds.pressures,
            "point": tip,
        }
    if ds.markers is None:
        return {"measured": None, "predicted": None}
    seen = np.isfinite(ds.markers).all(axis=2)
    rows = np.nonzero(seen)[0]
    return {
        "measured": ds.markers[seen],
        "predicted": predicted_markers[seen],
        "labels": labels[rows],
        "pressures": ds.pressures[rows],
        "point": "marker",
    }


def error_tables(
    dataset: Dataset,
    predicted: Prediction_like,
    converged: np.ndarray,
    reference,
    labels: np.ndarray | None,
    length: float,
    base_frame,
) -> pd.DataFrame:
    """The error table of every measured position ("tip", "markers": every seen marker of
    every row is one sample), with a first column ``quantity``; no rows without measured
    positions."""
    base, axis = base_frame if base_frame is not None else (None, None)
    tables = []
    if dataset.tip_position is not None:
        t = tip_error_table(
            dataset.tip_position,
            np.where(converged[:, None], predicted.tip, np.nan),
            length=length,
            reference=reference.tip,
            base_position=base,
            axis=axis,
            labels=labels,
        )
        t.insert(0, "quantity", "tip")
        tables.append(t)
    if dataset.markers is not None:
        seen = np.isfinite(dataset.markers).all(axis=2)
        rows = np.nonzero(seen)[0]
        pm = np.where(converged[:, None, None], predicted.markers, np.nan)
        t = tip_error_table(
            dataset.markers[seen],
            pm[seen],
            length=length,
            reference=reference.markers[seen],
            base_position=base,
            axis=axis,
            labels=None if labels is None else labels[rows],
        )
        t.insert(0, "quantity", "markers")
        tables.append(t)
    if not tables:
        return pd.DataFrame(columns=["quantity", *TABLE_COLUMNS])
    return pd.concat(tables, ignore_index=True)


#: Columns of the reaction error table: per quantity and set, the rows with a measured
#: component (``n``), of which ``failed`` have no prediction, and the Euclidean error over
#: the measured components (mean, median, max, RMS) in ``unit`` (mN, or N mm for moments).
REACTION_COLUMNS = (
    "quantity",
    "set",
    "n",
    "failed",
    "unit",
    "mean_error",
    "median_error",
    "max_error",
    "rms_error",
)


def _reaction_errors(measured: np.ndarray, predicted: np.ndarray) -> np.ndarray:
    """Euclidean error (m,) over each row's measured components (NaN: none measured, or
    no prediction)."""
    seen = np.isfinite(measured)
    diff = np.where(seen, predicted - np.where(seen, measured, 0.0), 0.0)
    err = np.sqrt(np.sum(diff**2, axis=1))
    return np.where(seen.any(axis=1), err, np.nan)


def reaction_error_table(
    dataset: Dataset, predicted: Prediction_like, converged: np.ndarray, labels
) -> pd.DataFrame | None:
    """The errors of a held tip's measured reaction (:data:`REACTION_COLUMNS`): one row per
    quantity ("reaction", "reaction_moment") and set (then "all" when there are several),
    or None when the dataset has no reaction."""
    rows = []
    m = len(dataset)
    sets = labels if labels is not None else np.full(m, "all")
    for quantity, measured, model, unit in (
        ("reaction", dataset.tip_reaction_force, predicted.reaction, "mN"),
        ("reaction_moment", dataset.tip_reaction_moment, predicted.reaction_moment, "N mm"),
    ):
        if measured is None:
            continue
        # mN and N mm: 1e3 times N and N m
        err = 1e3 * _reaction_errors(measured, np.where(converged[:, None], model, np.nan))
        has = np.isfinite(measured).any(axis=1)
        names = list(dict.fromkeys(sets[has].tolist()))
        groups = [(name, has & (sets == name)) for name in names]
        if len(names) > 1:
            groups.append(("all", has))
        for name, mask in groups:
            e = err[mask & converged]
            rows.append(
                {
                    "quantity": quantity,
                    "set": name,
                    "n": int(mask.sum()),
                    "failed": int((mask & ~converged).sum()),
                    "unit": unit,
                    "mean_error": float(np.mean(e)) if e.size else math.nan,
                    "median_error": float(np.median(e)) if e.size else math.nan,
                    "max_error": float(np.max(e)) if e.size else math.nan,
                    "rms_error": float(np.sqrt(np.mean(e**2))) if e.size else math.nan,
                }
            )
    return pd.DataFrame(rows, columns=list(REACTION_COLUMNS)) if rows else None


Prediction_like = object  # a softrod.calibration.problem.Prediction (tip, markers, reaction)


def display_table(table: pd.DataFrame) -> pd.DataFrame:
    """The parameter table in display units (offsets in mm, E in kPa, angles in deg; docs:
    one unit per quantity kind wherever people read it)."""
    out = table.copy()
    factors, units = [], []
    for unit in table["unit"]:
        shown = DISPLAY_UNITS.get(unit, (unit, 1.0))
        units.append(shown[0] or "1")
        factors.append(shown[1])
    for col in ("initial", "value", "std_error"):
        out[col] = table[col].to_numpy() * np.asarray(factors)
    out["unit"] = units
    return out


def _axis(design: Design) -> np.ndarray:
    """The undeformed axis d3 at the base (world)."""
    return np.asarray(design.spec["mounting"]["base_rotation"])[:, 2]


def _base_position(design: Design) -> np.ndarray:
    return np.asarray(design.spec["mounting"]["base_position"])


def dataset_name(dataset: Dataset) -> str:
    name = dataset.source.name if dataset.source is not None else "in-memory dataset"
    return f"{name} (SYNTHETIC)" if dataset.synthetic else name


def shown(value: float, std: float, unit: str) -> str:
    """'0.500126 +- 0.0078 mm': a value and its standard error in the display unit."""
    v, shown_unit = display(value, unit)
    s, _ = display(std, unit)
    return f"{v:.6g} +- {s:.2g}" + (f" {shown_unit}" if shown_unit else "")


def record(
    design,
    initial,
    name,
    params,
    values,
    std,
    method,
    dataset,
    n_train,
    what,
    tool: str = "softrod.calibrate",
) -> Design:
    """The calibrated design under its new name, with ``[design.provenance]`` (what was
    fitted to what, by which softrod, when) and a sentence in ``[design].assumptions``.
    ``what``: the model and data in words (e.g. "tip positions of equilibria"); ``tool``
    the fitting function."""
    import datetime

    from .. import __version__

    if name is None:
        name = f"{initial.name}_calibrated"
    if not isinstance(name, str) or not name.strip():
        raise V.fail("name", name, "must be a non-empty string (the calibrated design's name)")
    fitted = [
        (p, v, s) for p, v, s in zip(params, values, std, strict=True) if p.kind not in SIGMA_KINDS
    ]
    source = dataset.source
    provenance = {
        "tool": tool,
        "softrod_version": __version__,
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "initial_design": initial.name,
        "dataset": "in-memory dataset" if source is None else source.name,
        "synthetic_data": dataset.synthetic,
        "training_samples": int(n_train),
        "method": method,
        "parameters": [
            {
                "name": p.name,
                "value": float(v),
                "std_error": float(s) if math.isfinite(s) else "not determined",
                "unit": p.unit,
            }
            for p, v, s in fitted
        ],
    }
    changes: dict = {"design.name": name, "design.provenance": provenance}
    if fitted:
        parts = ", ".join(f"{p.name} = {shown(v, s, p.unit)}" for p, v, s in fitted)
        line = (
            f"Calibrated with {tool} ({method}) on {dataset_name(dataset)}, "
            f"{n_train} training samples ({what}): {parts} (standard errors from the "
            "Jacobian)."
        )
        changes["design.assumptions"] = list(design.document["design"].get("assumptions", []))
        changes["design.assumptions"].append(line)
    return design.replace(changes)


def result_json(result: CalibrationResult) -> str:
    """The parameter table and error table as standard JSON (non-finite numbers as null),
    for scripts and the CLI."""

    def finite(x):
        if isinstance(x, dict):
            return {k: finite(v) for k, v in x.items()}
        if isinstance(x, list):
            return [finite(v) for v in x]
        if isinstance(x, (float, np.floating)):
            return float(x) if math.isfinite(x) else None
        if isinstance(x, np.generic):
            return x.item()
        return x

    out = {
        "model": result.model,
        "dynamic": result.dynamic,
        "parameters": result.parameter_table().to_dict(orient="records"),
        "errors": result.error_table.to_dict(orient="records"),
        "warnings": list(result.warnings),
    }
    if result.reaction_error_table is not None:
        out["reaction_errors"] = result.reaction_error_table.to_dict(orient="records")
    if result.registration is not None:
        out["registration"] = {
            "angle_rad": result.registration["angle"],
            "offset_m": list(map(float, result.registration["offset"])),
        }
    return json.dumps(finite(out), indent=2, allow_nan=False)
