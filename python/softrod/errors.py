"""softrod's exception hierarchy. The Rust binding raises these classes too."""

from __future__ import annotations


class SoftrodError(Exception):
    """Base class of every error softrod raises on purpose."""


class DesignError(SoftrodError, ValueError):
    """A design breaks a rule. ``field`` names the offending entry (dotted path),
    ``value`` is what was given and ``rule`` what it must satisfy."""

    def __init__(self, message: str, field: str = "", value: object = "", rule: str = ""):
        super().__init__(message)
        self.field = field
        self.value = value
        self.rule = rule


class InputError(DesignError):
    """A per-call input (pressures, loads, options) breaks a rule."""


class CalibrationWarning(UserWarning):
    """A calibration result to be read with care (unidentifiable or correlated parameters,
    samples that did not converge)."""


class ConvergenceError(SoftrodError, RuntimeError):
    """A solver did not converge; no shape is returned."""

    def __init__(
        self,
        message: str,
        iterations: int = 0,
        residual: float = float("nan"),
        load_factor: float = 0.0,
        reason: str = "",
    ):
        super().__init__(message)
        self.iterations = iterations
        self.residual = residual
        self.load_factor = load_factor
        self.reason = reason


def design_error(field: str, value: object, rule: str, cls: type[DesignError] = DesignError):
    """Build a DesignError whose message reads ``field = value: rule``."""
    return cls(f"{field} = {value!r}: {rule}", field, value, rule)
