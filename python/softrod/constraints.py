"""How the tip of a rod is held: free, pinned or clamped (docs/model.md, "End constraints").

A :class:`TipConstraint` is given to ``solve_statics(..., tip_constraint=...)`` (and
``solve_statics_batch``) or written in the design file's ``[tip]`` table::

    [tip]
    constraint = "clamped"                      # "free" (default), "pinned" or "clamped"
    position = ["0 mm", "0 mm", "-130 mm"]      # world frame (pinned and clamped)
    orientation = ["0 deg", "0 deg", "0 deg"]   # clamped only: rotation vector of the tip
                                                # frame [d1 d2 d3] in the world, or a 3x3
                                                # rotation matrix (list of rows)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import _validate as V
from .errors import DesignError, InputError

KINDS = ("free", "pinned", "clamped")
#: How far from orthonormal (max |R^T R - I|, |det R - 1|) a given rotation matrix may be:
#: one written out to 10 significant digits passes, a typo does not (the core checks the same).
ROTATION_TOL = 1e-9


def rotation_from_vector(w) -> np.ndarray:
    """exp of the rotation vector w (rad): Rodrigues' formula."""
    w = np.asarray(w, dtype=float)
    t = float(np.linalg.norm(w))
    k = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    if t < 1e-8:
        return np.eye(3) + k + 0.5 * k @ k
    return np.eye(3) + math.sin(t) / t * k + (1.0 - math.cos(t)) / t**2 * k @ k


def orientation(value: Any, field: str, cls: type[DesignError] = InputError) -> np.ndarray:
    """A rotation from a rotation vector (3 angles: numbers in rad or strings with units)
    or a 3x3 rotation matrix (list of rows, or an array), checked to ``ROTATION_TOL``."""
    arr = value
    if isinstance(value, np.ndarray):
        arr = value.tolist()
    if not isinstance(arr, (list, tuple)) or len(arr) != 3:
        raise V.fail(
            field,
            value,
            "must be a rotation vector (3 angles) or a 3x3 rotation matrix (list of rows)",
            cls,
        )
    if all(isinstance(r, (list, tuple)) for r in arr):
        if not all(len(r) == 3 for r in arr):
            raise V.fail(field, value, "a rotation matrix has 3 rows of 3 numbers", cls)
        m = np.array(
            [
                [V.real(x, f"{field}[{i}][{j}]", cls=cls) for j, x in enumerate(r)]
                for i, r in enumerate(arr)
            ]
        )
        rule = "must be a rotation matrix"
        if not np.abs(m).max() <= 1.0 + ROTATION_TOL:  # before R^T R could overflow
            raise V.fail(field, value, f"{rule} (entries within [-1, 1])", cls)
    else:
        w = [V.quantity(x, "angle", f"{field}[{i}]", cls) for i, x in enumerate(arr)]
        if math.hypot(*w) > 1e3:  # hypot: no overflow on huge angles
            raise V.fail(
                field,
                value,
                "a rotation vector's angle must be at most 1000 rad (one turn is 2 pi)",
                cls,
            )
        m = rotation_from_vector(w)
        rule = "must give a rotation matrix"
    worst = float(np.abs(m.T @ m - np.eye(3)).max())
    det = float(np.linalg.det(m))
    if not (worst <= ROTATION_TOL and abs(det - 1.0) <= ROTATION_TOL):
        raise V.fail(
            field,
            value,
            f"{rule} (orthonormal with det +1 to {ROTATION_TOL:g}; max |R^T R - I| is "
            f"{worst:.3g}, det is {det:.6g}); give a rotation vector to avoid rounding",
            cls,
        )
    return m


def _position(value: Any, field: str, cls: type[DesignError]) -> tuple[float, float, float]:
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise V.fail(field, value, "must be 3 length values (world frame)", cls)
    x, y, z = (V.quantity(v, "length", f"{field}[{i}]", cls) for i, v in enumerate(value))
    return (x, y, z)


@dataclass(frozen=True)
class TipConstraint:
    """How the tip is held (SI, world frame).

    kind: "free" (the tip loads act on it), "pinned" (``position`` prescribed, moment
    free) or "clamped" (``position`` and ``rotation``, the tip frame [d1 d2 d3], prescribed).
    Build with :meth:`free`, :meth:`pinned` or :meth:`clamped`, which accept units.
    """

    kind: str = "free"
    position: tuple[float, float, float] | None = None
    rotation: tuple[tuple[float, float, float], ...] | None = None

    def __post_init__(self):
        V.choice(self.kind, KINDS, "tip_constraint.type")
        if self.kind == "free":
            for name in ("position", "rotation"):
                if getattr(self, name) is not None:
                    raise V.fail(
                        f"tip_constraint.{name}",
                        getattr(self, name),
                        "a free tip takes no position or orientation",
                    )
            return
        if self.position is None:
            raise V.fail(
                "tip_constraint.position",
                "(missing)",
                f"a {self.kind} tip needs its position (3 lengths, world frame)",
            )
        object.__setattr__(
            self, "position", _position(self.position, "tip_constraint.position", InputError)
        )
        if self.kind == "pinned":
            if self.rotation is not None:
                raise V.fail(
                    "tip_constraint.orientation",
                    self.rotation,
                    "a pinned tip turns freely; leave the orientation out (or clamp it)",
                )
            return
        if self.rotation is None:
            raise V.fail(
                "tip_constraint.orientation",
                "(missing)",
                "a clamped tip needs its orientation (a rotation vector or matrix)",
            )
        m = orientation(self.rotation, "tip_constraint.orientation")
        object.__setattr__(self, "rotation", tuple(tuple(float(v) for v in r) for r in m))

    @classmethod
    def free(cls) -> TipConstraint:
        return cls("free")

    @classmethod
    def pinned(cls, position: Sequence[Any]) -> TipConstraint:
        """Tip position (3 lengths, world) prescribed; moment free."""
        return cls("pinned", position=position)

    @classmethod
    def clamped(cls, position: Sequence[Any], orientation: Any) -> TipConstraint:
        """Tip position and orientation (rotation vector of 3 angles, or a 3x3 matrix)."""
        return cls("clamped", position=position, rotation=orientation)

    def core_args(self) -> tuple[str, list | None, list | None]:
        """(kind, position, rotation) for the binding."""
        return (
            self.kind,
            None if self.position is None else list(self.position),
            None if self.rotation is None else [list(r) for r in self.rotation],
        )


def coerce(value: Any) -> TipConstraint:
    """A TipConstraint from a TipConstraint, a kind name ("free") or a mapping with keys
    ``type``, ``position``, ``orientation`` (as the design file's)."""
    if isinstance(value, TipConstraint):
        return value
    if isinstance(value, str):
        return TipConstraint(value)
    if isinstance(value, dict):
        unknown = set(value) - {"type", "position", "orientation"}
        if unknown:
            raise V.fail(
                "tip_constraint",
                sorted(unknown),
                "unknown keys; known: type, position, orientation",
            )
        return TipConstraint(
            value.get("type", "free"), value.get("position"), value.get("orientation")
        )
    raise V.fail(
        "tip_constraint",
        type(value).__name__,
        "must be a softrod.TipConstraint, 'free', 'pinned', 'clamped' or a mapping",
    )


def from_tip_table(tip: dict, quantity, qvec) -> TipConstraint | None:
    """The constraint of a design file's ``[tip]`` table (None: free), with the file's own
    quantity readers (bare numbers as its ``units`` key says)."""
    kind = tip.get("constraint", "free")
    kind = V.choice(kind, KINDS, "tip.constraint", DesignError)
    has_pos, has_rot = "position" in tip, "orientation" in tip
    if kind == "free":
        if has_pos or has_rot:
            raise V.fail(
                "tip.position" if has_pos else "tip.orientation",
                tip.get("position", tip.get("orientation")),
                'is only used with constraint = "pinned" or "clamped"',
                DesignError,
            )
        return None
    if not has_pos:
        raise V.fail(
            "tip.position",
            "(missing)",
            f'constraint = "{kind}" needs the tip position (3 lengths, world frame)',
            DesignError,
        )
    pos = qvec(tip["position"], "length", "tip.position")
    if kind == "pinned":
        if has_rot:
            raise V.fail(
                "tip.orientation",
                tip["orientation"],
                'a pinned tip turns freely; leave it out (or use constraint = "clamped")',
                DesignError,
            )
        return TipConstraint("pinned", position=pos)
    if not has_rot:
        raise V.fail(
            "tip.orientation",
            "(missing)",
            'constraint = "clamped" needs the tip orientation (a rotation vector of '
            "3 angles or a 3x3 matrix)",
            DesignError,
        )
    rot = tip["orientation"]
    if (
        isinstance(rot, (list, tuple))
        and len(rot) == 3
        and not all(isinstance(r, (list, tuple)) for r in rot)
    ):
        rot = rotation_from_vector(
            [quantity(x, "angle", f"tip.orientation[{i}]") for i, x in enumerate(rot)]
        )
    m = orientation(rot, "tip.orientation", DesignError)
    return TipConstraint("clamped", position=pos, rotation=m)


def held_kwargs(constraint: TipConstraint | None) -> dict[str, Any]:
    """``Rod.sensitivity_batch``'s tip arguments (``tip_kind``, ``tip_position``,
    ``tip_rotation``) for a design's ``[tip]`` constraint; none for a free tip (or None)."""
    if constraint is None or constraint.kind == "free":
        return {}
    kind, position, rotation = constraint.core_args()
    return {"tip_kind": kind, "tip_position": position, "tip_rotation": rotation}


def require_free_tip(design: Any, entry: str) -> None:
    """Refuse a design whose file clamps or pins the tip in an entry point that solves a
    free tip only (every entry but ``solve_statics``, ``solve_statics_batch``,
    ``simulate``, the static ``calibrate``, ``synthesize_dataset`` and the systems'
    ``solve_system`` / ``solve_system_batch``): never a silent free-tip answer to a
    constrained design."""
    c = getattr(design, "tip_constraint", None)
    if c is not None:
        raise V.fail(
            "tip_constraint",
            c.kind,
            f"{entry} solves a free tip only; the design's [tip] constraint is honoured by "
            "solve_statics (or remove the constraint keys from [tip])",
            InputError,
        )
