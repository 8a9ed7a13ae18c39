# Type stub of the compiled extension softrod._core (crates/softrod-py), written by hand.
# tests/test_typing.py checks it against the built module with mypy's stubtest: a method or
# argument added, renamed or removed in the binding fails there until this file follows.
# Everything is SI; the binding holds no physics (softrod's Python API wraps these classes).

from collections.abc import Sequence
from typing import Any, final

__all__ = [
    "FrictionState",
    "GridPchip",
    "InverseSolver",
    "PccModel",
    "Rod",
    "Simulator",
    "SystemFrictionState",
    "SystemSimulator",
    "__version__",
    "_debug_assertions",
    "_panic_inside_guard",
    "linearise_at",
    "point_jacobian_of",
    "solve_constrained_tip",
    "solve_constrained_tip_batch",
    "solve_rod_system",
    "solve_rod_system_batch",
    "rod_system_sensitivity_batch",
    "system_jacobian_of",
    "system_linearise_of",
]
__version__: str
_debug_assertions: bool

# numpy arrays in and out; the stub names no numpy types so that checking it stays fast
# (the Python layer above states the shapes and units).
_ArrayLike = Any
_Array = Any
_Vec3 = Sequence[float]
# A system's rod for the binding: (rod, pressures, tensions, tip force, tip moment,
# attachment offset, attachment rotation); and its platform: (position, rotation, force,
# moment, mass, com offset, gravity).
_SystemRodEntry = tuple[
    Rod, Sequence[float], Sequence[float], _Vec3, _Vec3, _Vec3, Sequence[Sequence[float]]
]
_PlatformEntry = tuple[_Vec3, Sequence[Sequence[float]], _Vec3, _Vec3, float, _Vec3, _Vec3]

@final
class FrictionState:
    """Where a frictional static load path stands: its loads and every contact point's
    friction memory (opaque; it belongs to the design it was solved with)."""

    @property
    def max_elastic_slip(self) -> float: ...
    @property
    def pressures(self) -> list[float]: ...
    @property
    def tip_force(self) -> list[float]: ...
    @property
    def tip_moment(self) -> list[float]: ...
    @property
    def tensions(self) -> list[float]: ...
    @property
    def tip_constraint(self) -> str: ...

@final
class SystemFrictionState:
    """Where a system's frictional static load path stands: every rod's loads and contact
    memory, the attachments and the platform's load (opaque; it belongs to the system it
    was solved with)."""

    @property
    def max_elastic_slip(self) -> float: ...
    @property
    def pressures(self) -> list[list[float]]: ...
    @property
    def tensions(self) -> list[list[float]]: ...
    @property
    def platform_force(self) -> list[float]: ...
    @property
    def platform_moment(self) -> list[float]: ...

@final
class Rod:
    """A validated, compiled design (immutable)."""

    def __new__(cls, spec_json: str) -> Rod: ...
    @property
    def n_channels(self) -> int: ...
    @property
    def n_tendons(self) -> int: ...
    @property
    def length(self) -> float: ...
    @property
    def mass(self) -> float: ...
    def sections(self) -> list[dict[str, Any]]: ...
    def solve(
        self,
        pressures: Sequence[float],
        tip_force: _Vec3,
        tip_moment: _Vec3,
        guess: Sequence[float] | None = None,
        tol: float = 1e-10,
        max_iter: int = 25,
        continuation: bool = True,
        max_load_steps: int = 200,
        stretch_range: tuple[float, float] = ...,
        stiffness_scale: _Vec3 | None = None,
        on_invalid: str = "raise",
        tensions: Sequence[float] | None = None,
        friction_steps: int = ...,
        history: FrictionState | None = None,
    ) -> dict[str, Any]: ...
    def solve_batch(
        self,
        pressures: _ArrayLike,
        tip_force: _Vec3,
        tip_moment: _Vec3,
        threads: int = 0,
        tol: float = 1e-10,
        max_iter: int = 25,
        continuation: bool = True,
        max_load_steps: int = 200,
        stretch_range: tuple[float, float] = ...,
        stiffness_scale: _ArrayLike | None = None,
        on_invalid: str = "raise",
        tensions: _ArrayLike | None = None,
        friction_steps: int = ...,
    ) -> dict[str, Any]: ...
    def sensitivity_batch(
        self,
        pressures: _ArrayLike,
        tip_force: _Vec3,
        tip_moment: _Vec3,
        params: Sequence[tuple[str, Sequence[int]]],
        stiffness_scale: _ArrayLike | None = None,
        x0: _ArrayLike | None = None,
        threads: int = 0,
        tol: float = 1e-10,
        max_iter: int = 25,
        continuation: bool = True,
        max_load_steps: int = 200,
        stretch_range: tuple[float, float] = ...,
        on_invalid: str = "ignore",
        tensions: _ArrayLike | None = None,
        markers: Sequence[tuple[float, Sequence[float]]] = ...,
        tip_kind: str = "free",
        tip_position: _Vec3 | None = None,
        tip_rotation: Sequence[Sequence[float]] | None = None,
    ) -> dict[str, Any]:
        """solve_batch's keys plus "x", "d_tip_position" (m, 3, P), "d_tip_rotation"
        (m, 3, 3, P), "marker_position" (m, K, 3) and "d_marker_position" (m, K, 3, P); with
        a held tip (tip_kind "pinned" or "clamped") also "tip_reaction_force",
        "tip_reaction_moment" (m, 3) and their derivatives "d_tip_reaction_force",
        "d_tip_reaction_moment" (m, 3, P). NaN on failed rows."""

def _panic_inside_guard() -> None:
    """Panics inside the binding's guard (tests: a panic becomes softrod.InternalError)."""

@final
class GridPchip:
    """Tensor-product PCHIP on a regular grid (the interpolation of table stiffness maps)."""

    def __new__(
        cls, axes: Sequence[Sequence[float]], values: Sequence[float], width: int
    ) -> GridPchip: ...
    def eval(self, points: _ArrayLike) -> _Array: ...
    def gradient(self, points: _ArrayLike) -> _Array: ...

@final
class PccModel:
    """The compiled PCC model of a design (immutable)."""

    def __new__(cls, spec_json: str) -> PccModel: ...
    @property
    def n_channels(self) -> int: ...
    @property
    def ndof(self) -> int: ...
    @property
    def n_segments(self) -> int: ...
    @property
    def planar(self) -> bool: ...
    @property
    def length(self) -> float: ...
    def segments(self) -> list[dict[str, Any]]: ...
    def to_model(
        self, q: Sequence[float], q_dot: Sequence[float]
    ) -> tuple[list[float], list[float]]: ...
    def statics(
        self,
        pressures: Sequence[float],
        guess: Sequence[float] | None = None,
        tol: float = 1e-11,
        max_iter: int = 30,
    ) -> dict[str, Any]: ...
    def shape(self, x: Sequence[float], per_section: int) -> tuple[_Array, _Array, _Array]: ...
    def shapes(self, xs: _ArrayLike, per_section: int) -> tuple[_Array, _Array]: ...
    def energy(
        self, x: Sequence[float], v: Sequence[float], pressures: Sequence[float]
    ) -> tuple[float, float, float, float]: ...
    def mass_matrix(self, x: Sequence[float]) -> list[list[float]]: ...
    def simulate(
        self,
        dt: float,
        pressures: _ArrayLike,
        initial: str = "rest",
        q0: Sequence[float] | None = None,
        q_dot0: Sequence[float] | None = None,
        save_every: int = 1,
        tol: float = 1e-11,
        max_iter: int = 30,
    ) -> dict[str, Any]: ...
    def statics_sensitivity(
        self,
        pressures: _ArrayLike,
        params: Sequence[str],
        markers: Sequence[tuple[float, Sequence[float]]] = ...,
        guesses: _ArrayLike | None = None,
        threads: int = 0,
        tol: float = 1e-11,
        max_iter: int = 30,
    ) -> dict[str, Any]: ...
    def runs_sensitivity(
        self,
        runs: Sequence[tuple[_ArrayLike, str, int]],
        dt: float,
        params: Sequence[str],
        markers: Sequence[tuple[float, Sequence[float]]] = ...,
        threads: int = 0,
        tol: float = 1e-11,
        max_iter: int = 30,
    ) -> list[dict[str, Any]]: ...

@final
class Simulator:
    """A running simulation of a design (see ``softrod.dynamics``)."""

    def __new__(
        cls,
        spec_json: str,
        pressures: Sequence[float],
        initial: str = "static",
        dt: float = 2e-3,
        alpha: float = ...,  # -0.2 (pyo3 does not render a negative default)
        tol: float = 1e-9,
        max_iter: int = 25,
        scheme: str = "bdf-alpha",
        error_tol: float | None = None,
        energy_tol: float = ...,  # softrod_core::dynamics::DEFAULT_ENERGY_TOL (0.02)
        sigma_const: _Vec3 | None = None,
        sigma_grid: tuple[Sequence[Sequence[float]], Sequence[float], bool] | None = None,
        tip_force: _Vec3 | None = None,
        tip_moment: _Vec3 | None = None,
        tensions: Sequence[float] | None = None,
        tip_kind: str = "free",
        tip_position: _Vec3 | None = None,
        tip_rotation: Sequence[Sequence[float]] | None = None,
    ) -> Simulator: ...
    def save(self) -> _Array: ...
    def restore(self, state: _ArrayLike) -> None: ...
    def copy(self) -> Simulator: ...
    def track_sensitivities(self, params: list[tuple[str, list[int]]]) -> None: ...
    def set_markers(self, markers: Sequence[tuple[float, _Vec3]]) -> None: ...
    @property
    def time(self) -> float: ...
    @property
    def start_stable(self) -> bool | None: ...
    @property
    def dt(self) -> float: ...
    @property
    def n_channels(self) -> int: ...
    @property
    def pressures(self) -> list[float]: ...
    @property
    def tensions(self) -> list[float]: ...
    def set_tensions(self, tensions: Sequence[float]) -> None: ...
    @property
    def stats(self) -> dict[str, int]: ...
    def set_tip_loads(self, force: _Vec3, moment: _Vec3) -> None: ...
    def set_tip_pose(
        self,
        kind: str,
        position: _Vec3 | None = None,
        rotation: Sequence[Sequence[float]] | None = None,
    ) -> None: ...
    def snapshot(self) -> dict[str, Any]: ...
    def run(
        self,
        commands: _ArrayLike,
        keep: _ArrayLike,
        energy: bool = True,
        tip_loads: _ArrayLike | None = None,
        schedule: tuple[Sequence[float], Sequence[Sequence[float]], bool] | None = None,
        tensions: _ArrayLike | None = None,
        tip_poses: _ArrayLike | None = None,
    ) -> dict[str, Any]: ...

@final
class SystemSimulator:
    """A running simulation of a system of rods and its platform (see
    ``softrod.SystemSimulation``)."""

    def __new__(
        cls,
        rods: Sequence[
            tuple[Rod, Sequence[float], Sequence[float], _Vec3, Sequence[Sequence[float]]]
        ],
        platform: _PlatformEntry,
        inertia: Sequence[Sequence[float]],
        dt: float,
        alpha: float,
        tol: float,
        max_iter: int,
        scheme: str,
        error_tol: float | None,
        energy_tol: float,
        sigma_maps: Sequence[
            tuple[_Vec3 | None, tuple[Sequence[Sequence[float]], Sequence[float], bool] | None]
        ]
        | None = None,
    ) -> SystemSimulator: ...
    def time(self) -> float: ...
    def track_sensitivities(
        self, params: Sequence[tuple[str, Sequence[tuple[int, Sequence[int]]]]]
    ) -> None: ...
    def set_markers(self, markers: Sequence[tuple[int | None, float, _Vec3]]) -> None: ...
    @property
    def start_stable(self) -> bool | None: ...
    def snapshot(self) -> dict[str, Any]: ...
    def run(
        self,
        commands: Sequence[Sequence[Sequence[float]]],
        tensions: Sequence[Sequence[Sequence[float]]] | None = None,
        platform_loads: Sequence[tuple[_Vec3, _Vec3]] | None = None,
    ) -> dict[str, Any]: ...
    def set_platform_loads(self, force: _Vec3, moment: _Vec3) -> None: ...
    def platform_loads(self) -> tuple[list[float], list[float]]: ...
    def stats(self) -> dict[str, int]: ...
    def save(self) -> _Array: ...
    def restore(self, state: _ArrayLike) -> None: ...
    def copy(self) -> SystemSimulator: ...

@final
class InverseSolver:
    """An inverse problem of one design (see ``softrod.control.inverse``)."""

    def __new__(
        cls,
        rod: Rod,
        bounds: Sequence[Sequence[float]],
        reference: Sequence[float],
        s: float,
        position_weight: _Vec3,
        orientation_weight: float,
        tip_force: _Vec3,
        tip_moment: _Vec3,
        regularisation: float = 1e-6,
        tol: float = 1e-10,
        max_iter: int = 100,
        statics_tol: float = 1e-10,
        statics_max_iter: int = 25,
        on_invalid: str = "raise",
        stretch_range: tuple[float, float] = ...,  # (0.5, 2.0)
    ) -> InverseSolver: ...
    def solve(
        self,
        position: _Vec3,
        pressures: Sequence[float],
        tensions: Sequence[float],
        orientation: Sequence[Sequence[float]] | None = None,
        x: _Vec3 | None = None,
        reference: Sequence[float] | None = None,
        z: Sequence[float] | None = None,
    ) -> dict[str, Any]: ...

def point_jacobian_of(
    rod: Rod,
    pressures: Sequence[float],
    tip_force: _Vec3,
    tip_moment: _Vec3,
    stiffness_scale: _Vec3,
    x: Sequence[float],
    s: float,
    params: Sequence[tuple[str, Sequence[int]]],
    tensions: Sequence[float] | None = None,
    tip_kind: str = "free",
    tip_position: _Vec3 | None = None,
    tip_rotation: Sequence[Sequence[float]] | None = None,
) -> dict[str, Any]: ...
def linearise_at(
    rod: Rod,
    pressures: Sequence[float],
    tip_force: _Vec3,
    tip_moment: _Vec3,
    x: Sequence[float] | None,
    nodes: int,
    tensions: Sequence[float] | None = None,
    tip_kind: str = "free",
    tip_position: _Vec3 | None = None,
    tip_rotation: Sequence[Sequence[float]] | None = None,
    stiffness_scale: _Vec3 | None = None,
) -> dict[str, Any]: ...
def solve_constrained_tip(
    rod: Rod,
    pressures: Sequence[float],
    tip_force: _Vec3,
    tip_moment: _Vec3,
    kind: str,
    position: _Vec3 | None = None,
    rotation: Sequence[Sequence[float]] | None = None,
    guess: Sequence[float] | None = None,
    tol: float = 1e-10,
    max_iter: int = 25,
    continuation: bool = True,
    max_load_steps: int = 200,
    stretch_range: tuple[float, float] = ...,
    stiffness_scale: _Vec3 | None = None,
    on_invalid: str = "raise",
    tensions: Sequence[float] | None = None,
    friction_steps: int = ...,
    history: FrictionState | None = None,
) -> dict[str, Any]: ...
def system_jacobian_of(
    rods: Sequence[_SystemRodEntry],
    platform: _PlatformEntry,
    x: Sequence[float],
    inputs: Sequence[tuple[str, int, int]],
    stiffness_scale: Sequence[_Vec3 | None] | None = None,
) -> dict[str, Any]: ...
def system_linearise_of(
    rods: Sequence[_SystemRodEntry],
    platform: _PlatformEntry,
    x: Sequence[float],
    inputs: Sequence[tuple[str, int, int]],
    nodes: int,
    platform_inertia: Sequence[Sequence[float]],
    stiffness_scale: Sequence[_Vec3 | None] | None = None,
) -> dict[str, Any]: ...
def solve_rod_system(
    rods: Sequence[_SystemRodEntry],
    platform: _PlatformEntry,
    guess: Sequence[float] | None = None,
    tol: float = 1e-10,
    max_iter: int = 25,
    continuation: bool = True,
    max_load_steps: int = 200,
    stretch_range: tuple[float, float] = ...,
    on_invalid: str = "raise",
    friction_steps: int = ...,
    history: SystemFrictionState | None = None,
    stiffness_scale: Sequence[Sequence[float] | None] | None = None,
) -> dict[str, Any]: ...
def solve_constrained_tip_batch(
    rod: Rod,
    pressures: _ArrayLike,
    tip_force: _Vec3,
    tip_moment: _Vec3,
    kind: str,
    position: _Vec3 | None = None,
    rotation: Sequence[Sequence[float]] | None = None,
    threads: int = 0,
    tol: float = 1e-10,
    max_iter: int = 25,
    continuation: bool = True,
    max_load_steps: int = 200,
    stretch_range: tuple[float, float] = ...,
    stiffness_scale: _ArrayLike | None = None,
    on_invalid: str = "raise",
    tensions: _ArrayLike | None = None,
    friction_steps: int = ...,
) -> dict[str, Any]: ...
def solve_rod_system_batch(
    rods: Sequence[tuple[Rod, _Vec3, _Vec3, _Vec3, Sequence[Sequence[float]]]],
    platform: _PlatformEntry,
    pressures: _ArrayLike,
    tensions: _ArrayLike | None = None,
    threads: int = 0,
    tol: float = 1e-10,
    max_iter: int = 25,
    continuation: bool = True,
    max_load_steps: int = 200,
    stretch_range: tuple[float, float] = ...,
    on_invalid: str = "raise",
    friction_steps: int = ...,
    stiffness_scale: _ArrayLike | None = None,
) -> dict[str, Any]: ...
def rod_system_sensitivity_batch(
    rods: Sequence[tuple[Rod, _Vec3, _Vec3, _Vec3, Sequence[Sequence[float]]]],
    platform: _PlatformEntry,
    pressures: _ArrayLike,
    params: Sequence[tuple[str, Sequence[tuple[int, Sequence[int]]]]],
    tensions: _ArrayLike | None = None,
    markers: Sequence[tuple[int | None, float, _Vec3]] = ...,
    x0: _ArrayLike | None = None,
    threads: int = 0,
    tol: float = 1e-10,
    max_iter: int = 25,
    continuation: bool = True,
    max_load_steps: int = 200,
    stretch_range: tuple[float, float] = ...,
    on_invalid: str = "ignore",
    stiffness_scale: _ArrayLike | None = None,
) -> dict[str, Any]: ...
