"""Calibration: fit model parameters to measured tip positions and report the fit."""

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
from .dynamic import DynamicCalibrationResult, calibrate_dynamics, synthesize_trajectory_dataset
from .fit import CalibrationResult, CalibrationWarning, calibrate
from .hybrid import HybridStiffnessModel, compare_hybrid, fit_stiffness_map
from .metrics import per_sample_errors, tip_error_table
from .per_sample import StiffnessIdentification, identify_stiffness, stiffness_mapped_design
from .report import save_figures, write_report

__all__ = [
    "CalibrationResult",
    "CalibrationWarning",
    "calibrate",
    "calibrate_dynamics",
    "DynamicCalibrationResult",
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
