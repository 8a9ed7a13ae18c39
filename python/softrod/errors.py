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
    """Build a DesignError whose message reads ``field = value: rule`` (a long value is
    shortened in the message; ``exc.value`` keeps it whole)."""
    shown = field if len(field) <= 200 else field[:150] + f"... ({len(field)} characters)"
    said = rule if len(rule) <= 1000 else rule[:900] + f"... ({len(rule)} characters)"
    return cls(f"{shown} = {brief(value)}: {said}", field, value, rule)


def brief(value: object) -> str:
    """``repr(value)`` for a message, shortened: a hostile input (a megabyte of text, a huge
    integer, a big container) never makes a huge message or a slow repr."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 100:
        return f"<an integer of {value.bit_length()} bits>"
    if isinstance(value, (str, bytes)) and len(value) > 120:
        return repr(value[:100])[:-1] + f"...' ({len(value)} characters)"
    try:
        n = len(value)  # type: ignore[arg-type]
    except Exception:
        n = None
    if n is not None and n > 20 and not isinstance(value, (str, bytes)):
        return f"<{type(value).__name__} of {n} items>"
    try:
        text = repr(value)
    except Exception:
        return f"<{type(value).__name__}>"
    return text if len(text) <= 300 else text[:200] + f"... ({type(value).__name__})"


class InvalidStateError(ConvergenceError):
    """A solution breaks a validity rule (docs/model.md, "Validity and stability"): a
    rotation that is not one, stretch <= 0, a collapsed chamber, strains or pressures outside
    the validity range, or (when asked to raise) an unstable equilibrium. ``rule`` names the
    rule, ``node`` the integration node (0 = base; None when the rule concerns no node),
    ``s`` its arc length in m, ``value`` the offending number and ``time`` the simulation
    time in s (None in statics)."""

    def __init__(
        self,
        message: str,
        rule: str = "",
        node: int | None = None,
        s: float = float("nan"),
        value: float = float("nan"),
        time: float | None = None,
    ):
        super().__init__(message, reason=rule)
        self.rule = rule
        self.node = node
        self.s = s
        self.value = value
        self.time = time


class InternalError(SoftrodError, RuntimeError):
    """A bug inside softrod (a panic in the Rust core, caught at the boundary). Please
    report it with the input that caused it."""


class StabilityWarning(UserWarning):
    """A static equilibrium is unstable (a small disturbance moves the rod away from it)."""


class ValidityWarning(UserWarning):
    """A solution lies outside the model's validity range (strains or the design's
    operating_range); returned because the caller asked for ``on_invalid="warn"``."""
