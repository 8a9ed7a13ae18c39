"""Dynamics: pressure schedules in, trajectories out (docs/dynamics.md).

- :class:`PressureSchedule`: commanded chamber pressures as a function of time (Pa, s).
- :class:`Trajectory`: a simulated motion; save/load (Parquet, NPZ), plots, animations.
- :func:`simulate`: a design's motion under a schedule; :class:`Simulation`: a stepper whose
  :class:`SimulationState` restores exactly.
- :func:`animation_plan`: how a run becomes a watchable clip (speed, frames, shape interval).
"""

from .schedule import VACUUM_PA, PressureSchedule
from .simulate import Simulation, SimulationState, simulate
from .trajectory import AnimationPlan, Trajectory, animation_plan

__all__ = [
    "VACUUM_PA",
    "AnimationPlan",
    "PressureSchedule",
    "Simulation",
    "SimulationState",
    "Trajectory",
    "animation_plan",
    "simulate",
]
