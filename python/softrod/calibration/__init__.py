"""Calibration: fit model parameters to measured positions and report the fit.

One engine for every model (:func:`calibrate`): a problem (:mod:`.problem`) of parameters,
a model adapter with exact parameter Jacobians (:mod:`.adapters`: rod statics and dynamics,
paper 003's PCC model), weighted residuals and a split; one solver layer (:mod:`.solve`);
identifiability from the Jacobian (:mod:`.diagnostics`); one result (:mod:`.result`) and
report (:mod:`.report`). Paper 001's per-sample identification and paper 004's axial
identification are their own procedures (:mod:`.per_sample`, :mod:`.axial`)."""

from .axial import (
    AxialData,
    AxialIdentification,
    axial_example_paths,
    calibrate_axial,
    identify_axial,
    load_axial_data,
    synthesize_axial_data,
    write_axial_data,
)
from .fit import CalibrationResult, CalibrationWarning, calibrate
from .hybrid import HybridStiffnessModel, compare_hybrid, fit_stiffness_map
from .metrics import per_sample_errors, tip_error_table
from .per_sample import StiffnessIdentification, identify_stiffness, stiffness_mapped_design
from .report import save_figures, write_report
from .synthetic import synthesize_trajectory_dataset
from .system import SystemCalibrationResult, calibrate_system

__all__ = [
    "CalibrationResult",
    "CalibrationWarning",
    "calibrate",
    "calibrate_system",
    "SystemCalibrationResult",
    "synthesize_trajectory_dataset",
    "AxialData",
    "AxialIdentification",
    "HybridStiffnessModel",
    "StiffnessIdentification",
    "axial_example_paths",
    "calibrate_axial",
    "compare_hybrid",
    "fit_stiffness_map",
    "identify_axial",
    "identify_stiffness",
    "load_axial_data",
    "per_sample_errors",
    "save_figures",
    "stiffness_mapped_design",
    "synthesize_axial_data",
    "tip_error_table",
    "write_axial_data",
    "write_report",
]
