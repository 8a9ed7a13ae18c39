"""softrod: Cosserat-rod models of soft pneumatic actuators.

Public API (everything inside is SI: m, N, Pa, kg, s, rad):

- :func:`load_design` -> :class:`Design`
- :func:`solve_statics` -> :class:`StaticSolution`
- :func:`solve_statics_batch` -> :class:`BatchSolution`
- :class:`SolverOptions`
- exceptions :class:`DesignError`, :class:`InputError`, :class:`ConvergenceError`
"""

from ._core import __version__ as _core_version
from .design import Design, bundled_designs, designs_dir, load_design
from .errors import ConvergenceError, DesignError, InputError, SoftrodError
from .statics import (
    BatchSolution,
    SolverOptions,
    StaticSolution,
    solve_statics,
    solve_statics_batch,
)

__version__ = _core_version

__all__ = [
    "BatchSolution",
    "ConvergenceError",
    "Design",
    "DesignError",
    "InputError",
    "SoftrodError",
    "SolverOptions",
    "StaticSolution",
    "__version__",
    "bundled_designs",
    "designs_dir",
    "load_design",
    "solve_statics",
    "solve_statics_batch",
]
