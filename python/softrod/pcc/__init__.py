"""Paper 003's piecewise-constant-curvature (PCC) Lagrangian model on softrod designs.

- :func:`run_pcc`: dynamics (implicit midpoint, exact Jacobian) under sampled pressures
- :func:`pcc_shape`: the arcs of a configuration q = (L, theta, phi) per segment
- :func:`pcc_parameters`: the visco-elastic parameters in use, after defaults
- ``softrod.solve_statics(design, p, model="pcc")``: statics as a ``StaticSolution``
- identification (paper 003 Sec. V): :func:`fit_longitudinal_stiffness`,
  :func:`fit_bending_stiffness`, :func:`fit_longitudinal_damping`,
  :func:`fit_bending_damping`, with :func:`chamber_moment` and
  :func:`bending_angle_from_tip`; each returns a :class:`PccFit`
- the same on a :class:`~softrod.Dataset`: :func:`identify_pcc`, also
  ``softrod.calibrate(design, dataset, params, model="pcc")``; synthetic experiments from
  the model: :func:`synthesize_pcc_experiments`
- :func:`compare_pcc`, :func:`plot_pcc_comparison`: PCC vs Cosserat tip positions;
  :func:`plot_pcc_step_response`: step responses (paper 003 Figs. 8-9)
"""

from .compare import compare_pcc, plot_pcc_comparison, plot_pcc_step_response
from .experiments import EXPERIMENTS, PCC_PARAMETERS, identify_pcc, synthesize_pcc_experiments
from .identify import (
    PccFit,
    bending_angle_from_tip,
    chamber_moment,
    fit_bending_damping,
    fit_bending_stiffness,
    fit_longitudinal_damping,
    fit_longitudinal_stiffness,
)
from .model import pcc_model, pcc_parameters, pcc_shape, run_pcc

__all__ = [
    "EXPERIMENTS",
    "PCC_PARAMETERS",
    "PccFit",
    "bending_angle_from_tip",
    "chamber_moment",
    "compare_pcc",
    "fit_bending_damping",
    "fit_bending_stiffness",
    "fit_longitudinal_damping",
    "fit_longitudinal_stiffness",
    "identify_pcc",
    "pcc_model",
    "pcc_parameters",
    "pcc_shape",
    "plot_pcc_comparison",
    "plot_pcc_step_response",
    "run_pcc",
    "synthesize_pcc_experiments",
]
