"""softrod: Cosserat-rod models of soft pneumatic actuators.

Public API (everything inside is SI: m, N, Pa, kg, s, rad):

- :func:`load_design` -> :class:`Design`
- :func:`solve_statics` -> :class:`StaticSolution`
- :func:`solve_statics_batch` -> :class:`BatchSolution`
- :func:`simulate` -> :class:`Trajectory`: motion under a :class:`PressureSchedule`
  (paper 000's viscoelastic rod); :class:`Simulation`: the same, step by step
- :func:`list_presets`: named published models (``load_design("paper002_M3_vertical")``)
- :func:`compare_models`: models on paper 002's experiments -> pandas DataFrame
- :class:`SolverOptions`
- :func:`solve_inverse` / :class:`InverseProblem`: pressures within bounds that bring the tip
  to a target; :func:`linearise` (M, D, K, B and modes), :func:`workspace`,
  :func:`run_closed_loop` (:mod:`softrod.control`, docs/control.md)
- :class:`StiffnessMap`: pressure-dependent stiffness scaling sigma(p) (paper 001 eq. 13)
- :func:`load_dataset` / :func:`write_dataset` -> :class:`Dataset` (CSV, Parquet; docs/datasets.md)
- :func:`synthesize_dataset`: synthetic datasets from the model, marked as such
- :func:`calibrate` -> :class:`CalibrationResult`: fit parameters to measured tip positions
  (``dynamic=True``: to tip trajectories, e.g. tau and A_eff of paper 000)
- :func:`calibrate_system` -> :class:`SystemCalibrationResult`: fit a system of rods (a
  parallel continuum robot) to its platform's positions and markers
  (:func:`synthesize_system_dataset` makes such data from the model)
- :func:`identify_stiffness` -> :class:`StiffnessIdentification`: sigma per sample (paper 001)
- :func:`fit_stiffness_map` -> :class:`HybridStiffnessModel`, :func:`compare_hybrid`: the
  hybrid neural stiffness map of paper 001 and its tip errors
- :mod:`softrod.pcc`: paper 003's piecewise-constant-curvature model (``run_pcc``,
  ``pcc_shape``, identification, ``compare_pcc``); statics via
  ``solve_statics(..., model="pcc")``
- :func:`view` -> :class:`~softrod.viewer.Viewer`: the interactive 3-D viewer in the browser
  (``pip install 'softrod[viewer]'``; docs/viewer.md); :func:`view_system` for a system of
  rods
- ``executor=`` (a ``distributed.Client``) on ``solve_statics_batch``, ``identify_stiffness``
  and ``calibrate(restarts=...)``: the work runs on a Dask cluster (docs/cluster.md)
- exceptions :class:`DesignError`, :class:`InputError`, :class:`ConvergenceError` (and its
  :class:`InvalidStateError`), :class:`InternalError`; warnings :class:`StabilityWarning`,
  :class:`ValidityWarning`
"""

import importlib
import logging
from typing import TYPE_CHECKING

from ._core import __version__ as _core_version

__version__ = _core_version

# softrod reports what it does on the standard logging module, logger "softrod" (INFO: the
# steps of long calls; DEBUG: details such as files written). A library adds no handler of
# its own: applications configure logging (the CLI does with -v/-q).
logging.getLogger(__name__).addHandler(logging.NullHandler())

# Public name -> the module that defines it. Importing softrod imports none of them (PEP 562):
# `softrod --help` and `import softrod` stay fast, and numpy, pandas, scipy, pyarrow and
# matplotlib load only when a name that needs them is first used.
_EXPORTS = {
    "CalibrationResult": ".calibration",
    "HybridStiffnessModel": ".calibration",
    "StiffnessIdentification": ".calibration",
    "calibrate": ".calibration",
    "calibrate_system": ".calibration",
    "SystemCalibrationResult": ".calibration",
    "compare_hybrid": ".calibration",
    "fit_stiffness_map": ".calibration",
    "identify_stiffness": ".calibration",
    "bundled_designs": ".catalog",
    "read_mesh": ".mesh_io",
    "write_stl": ".mesh_io",
    "load_design": ".catalog",
    "compare_models": ".compare",
    "TipConstraint": ".constraints",
    "InverseProblem": ".control",
    "InverseSolution": ".control",
    "LinearSystem": ".control",
    "SystemLinearSystem": ".control",
    "TargetPath": ".control",
    "TrackingController": ".control",
    "Workspace": ".control",
    "linearise": ".control",
    "run_closed_loop": ".control",
    "solve_inverse": ".control",
    "workspace": ".control",
    "Dataset": ".datasets",
    "example_datasets": ".datasets",
    "load_dataset": ".datasets",
    "synthesize_dataset": ".synthetic",
    "synthesize_system_dataset": ".synthetic",
    "write_dataset": ".datasets",
    "Design": ".design",
    "designs_dir": ".design",
    "PressureSchedule": ".dynamics",
    "Simulation": ".dynamics",
    "SimulationState": ".dynamics",
    "Trajectory": ".dynamics",
    "simulate": ".dynamics",
    "CalibrationWarning": ".errors",
    "ConvergenceError": ".errors",
    "DesignError": ".errors",
    "InputError": ".errors",
    "InternalError": ".errors",
    "InvalidStateError": ".errors",
    "SoftrodError": ".errors",
    "StabilityWarning": ".errors",
    "ValidityWarning": ".errors",
    "Preset": ".presets",
    "list_presets": ".presets",
    "BatchSolution": ".statics",
    "Contact": ".statics",
    "SolverOptions": ".statics",
    "StaticSolution": ".statics",
    "Jacobian": ".solution",
    "SystemJacobian": ".solution",
    "solve_statics": ".statics",
    "solve_statics_batch": ".statics",
    "StiffnessMap": ".stiffness_map",
    "Platform": ".system",
    "System": ".system",
    "SystemRod": ".system",
    "SystemSolution": ".system",
    "SystemBatchSolution": ".system",
    "bundled_systems": ".system",
    "load_system": ".system",
    "solve_system": ".system",
    "solve_system_batch": ".system",
    "SystemSimulation": ".system_dynamics",
    "SystemSimulationState": ".system_dynamics",
    "SystemTrajectory": ".system_dynamics",
    "simulate_system": ".system_dynamics",
    "system_trajectory_sensitivities": ".sensitivities",
    "trajectory_sensitivities": ".sensitivities",
    "plot_system": ".system_plots",
    "plot_system_motion": ".system_plots",
    "view": ".viewer",
    "view_system": ".viewer",
}
_SUBMODULES = ("pcc", "calibration", "control", "dynamics")


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is not None:
        value = getattr(importlib.import_module(module, __name__), name)
    elif name in _SUBMODULES:
        value = importlib.import_module(f".{name}", __name__)
    else:
        raise AttributeError(f"module 'softrod' has no attribute {name!r}")
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


if TYPE_CHECKING:  # static analysers and IDEs see the eager imports
    from . import calibration, control, dynamics, pcc
    from .calibration import (
        CalibrationResult,
        HybridStiffnessModel,
        StiffnessIdentification,
        SystemCalibrationResult,
        calibrate,
        calibrate_system,
        compare_hybrid,
        fit_stiffness_map,
        identify_stiffness,
    )
    from .catalog import bundled_designs, load_design
    from .compare import compare_models
    from .constraints import TipConstraint
    from .control import (
        InverseProblem,
        InverseSolution,
        LinearSystem,
        SystemLinearSystem,
        TargetPath,
        TrackingController,
        Workspace,
        linearise,
        run_closed_loop,
        solve_inverse,
        workspace,
    )
    from .datasets import (
        Dataset,
        example_datasets,
        load_dataset,
        write_dataset,
    )
    from .design import Design, designs_dir
    from .dynamics import PressureSchedule, Simulation, SimulationState, Trajectory, simulate
    from .errors import (
        CalibrationWarning,
        ConvergenceError,
        DesignError,
        InputError,
        InternalError,
        InvalidStateError,
        SoftrodError,
        StabilityWarning,
        ValidityWarning,
    )
    from .mesh_io import read_mesh, write_stl
    from .presets import Preset, list_presets
    from .sensitivities import system_trajectory_sensitivities, trajectory_sensitivities
    from .solution import Jacobian, SystemJacobian
    from .statics import (
        BatchSolution,
        Contact,
        SolverOptions,
        StaticSolution,
        solve_statics,
        solve_statics_batch,
    )
    from .stiffness_map import StiffnessMap
    from .synthetic import synthesize_dataset, synthesize_system_dataset
    from .system import (
        Platform,
        System,
        SystemBatchSolution,
        SystemRod,
        SystemSolution,
        bundled_systems,
        load_system,
        solve_system,
        solve_system_batch,
    )
    from .system_dynamics import (
        SystemSimulation,
        SystemSimulationState,
        SystemTrajectory,
        simulate_system,
    )
    from .system_plots import plot_system, plot_system_motion
    from .viewer import view, view_system

__all__ = [
    "BatchSolution",
    "CalibrationResult",
    "CalibrationWarning",
    "Contact",
    "ConvergenceError",
    "Dataset",
    "Design",
    "DesignError",
    "HybridStiffnessModel",
    "InputError",
    "InternalError",
    "InvalidStateError",
    "InverseProblem",
    "InverseSolution",
    "Jacobian",
    "LinearSystem",
    "Preset",
    "SoftrodError",
    "SolverOptions",
    "StabilityWarning",
    "StaticSolution",
    "StiffnessIdentification",
    "StiffnessMap",
    "System",
    "SystemJacobian",
    "SystemLinearSystem",
    "SystemRod",
    "SystemSolution",
    "SystemBatchSolution",
    "SystemSimulation",
    "SystemSimulationState",
    "SystemTrajectory",
    "TargetPath",
    "TipConstraint",
    "TrackingController",
    "Platform",
    "PressureSchedule",
    "Simulation",
    "SimulationState",
    "Trajectory",
    "ValidityWarning",
    "Workspace",
    "__version__",
    "bundled_designs",
    "bundled_systems",
    "calibrate",
    "calibrate_system",
    "SystemCalibrationResult",
    "calibration",
    "compare_hybrid",
    "compare_models",
    "control",
    "designs_dir",
    "dynamics",
    "example_datasets",
    "fit_stiffness_map",
    "identify_stiffness",
    "linearise",
    "list_presets",
    "load_dataset",
    "pcc",
    "load_design",
    "load_system",
    "solve_statics",
    "simulate",
    "run_closed_loop",
    "solve_inverse",
    "solve_statics_batch",
    "solve_system",
    "solve_system_batch",
    "simulate_system",
    "system_trajectory_sensitivities",
    "trajectory_sensitivities",
    "plot_system",
    "plot_system_motion",
    "synthesize_dataset",
    "synthesize_system_dataset",
    "view",
    "view_system",
    "workspace",
    "write_dataset",
    "read_mesh",
    "write_stl",
]
