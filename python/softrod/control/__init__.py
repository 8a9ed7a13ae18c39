"""Control tools (docs/control.md): inverse statics with pressure bounds, exact Jacobians,
linearised dynamics and modes, the reachable workspace, and closed-loop simulation.

- :func:`solve_inverse` / :class:`InverseProblem` -> :class:`InverseSolution`
- :func:`jacobian` (also ``StaticSolution.jacobian()``) -> :class:`Jacobian`
- :func:`linearise` -> :class:`LinearSystem` (M, D, K, B), ``.modes()`` -> :class:`Modes`
- :func:`workspace` -> :class:`Workspace`
- :func:`run_closed_loop` -> :class:`ClosedLoopResult`; :class:`TrackingController`,
  :class:`TargetPath`, :class:`Measurement`; :func:`predicted_circle_error` (the linear
  model's prediction of the tracking error), :func:`tracking_frame`, :func:`tracking_plot`
"""

from .closed_loop import (
    ClosedLoopResult,
    Measurement,
    TargetPath,
    TrackingController,
    predicted_circle_error,
    run_closed_loop,
    tracking_frame,
    tracking_plot,
)
from .inverse import (
    InverseProblem,
    InverseSolution,
    pressure_bounds,
    solve_inverse,
    tension_bounds,
)
from .linear import Jacobian, LinearSystem, Modes, SystemLinearSystem, jacobian, linearise
from .workspace import Workspace, workspace

__all__ = [
    "ClosedLoopResult",
    "InverseProblem",
    "InverseSolution",
    "Jacobian",
    "LinearSystem",
    "Measurement",
    "Modes",
    "SystemLinearSystem",
    "TargetPath",
    "TrackingController",
    "Workspace",
    "jacobian",
    "linearise",
    "predicted_circle_error",
    "pressure_bounds",
    "run_closed_loop",
    "solve_inverse",
    "tension_bounds",
    "tracking_frame",
    "tracking_plot",
    "workspace",
]
