//! The one error type of the core. Every variant carries structured fields so that the
//! Python binding can map it to `DesignError`, `ConvergenceError` or `ValueError` without
//! parsing strings.

use thiserror::Error;

#[derive(Debug, Clone, PartialEq, Error)]
pub enum SoftrodError {
    /// A design or input value breaks a rule. `field` is a dotted path such as
    /// `sections[1].chambers[0].radius`.
    #[error("{field} = {value}: {rule}")]
    InvalidParameter {
        field: String,
        value: String,
        rule: String,
    },
    /// The shooting solve did not reach its tolerance.
    #[error(
        "static solve did not converge after {iterations} iterations (scaled residual {residual:.3e}, load factor reached {load_factor:.4}): {reason}"
    )]
    NotConverged {
        iterations: usize,
        residual: f64,
        load_factor: f64,
        reason: String,
    },
    /// A state breaks a rule of `crate::validity` (a rotation that is not one, stretch <= 0,
    /// a collapsed chamber, strains or pressures outside the validity range). `node` is the
    /// integration node (0 = base) and `s` its arc length in m, when the rule concerns a
    /// node; `time` the simulation time in s, when a dynamic run broke it; `value` the
    /// offending number.
    #[error("{}{}rule {}: {message}", .time.map_or(String::new(), |t| format!("at t = {t} s, ")), .node.map_or(String::new(), |n| format!("node {n} (s = {s:.6} m), ")), .rule.name())]
    InvalidState {
        rule: Rule,
        node: Option<usize>,
        s: f64,
        time: Option<f64>,
        value: f64,
        message: String,
    },
    /// A bug: a panic inside the core, caught at the boundary. Please report it.
    #[error("internal error (a bug in softrod; please report it): {0}")]
    Internal(String),
}

impl SoftrodError {
    pub fn invalid(
        field: impl Into<String>,
        value: impl ToString,
        rule: impl Into<String>,
    ) -> Self {
        SoftrodError::InvalidParameter {
            field: field.into(),
            value: value.to_string(),
            rule: rule.into(),
        }
    }
}

impl SoftrodError {
    /// The same error, stamped with the simulation time at which a state broke a rule.
    pub fn at_time(self, t: f64) -> Self {
        match self {
            SoftrodError::InvalidState {
                rule,
                node,
                s,
                value,
                message,
                ..
            } => SoftrodError::InvalidState {
                rule,
                node,
                s,
                time: Some(t),
                value,
                message,
            },
            other => other,
        }
    }

    /// An invalid-state error with its message rewritten by `f` (other errors unchanged).
    pub fn map_message(self, f: impl FnOnce(String) -> String) -> Self {
        match self {
            SoftrodError::InvalidState {
                rule,
                node,
                s,
                time,
                value,
                message,
            } => SoftrodError::InvalidState {
                rule,
                node,
                s,
                time,
                value,
                message: f(message),
            },
            other => other,
        }
    }
}

pub type Result<T> = std::result::Result<T, SoftrodError>;

/// The rule a state broke.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rule {
    /// Every entry of the state is a finite number.
    Finite,
    /// R is a rotation: orthonormal to the rotation tolerance of the validity rules, det R > 0.
    Rotation,
    /// The centreline stretch v3 is positive (v3 <= 0: the rod is turned inside out).
    PositiveStretch,
    /// The centreline stretch v3 is at most the stretch limit of the validity rules (the material would have torn).
    StretchLimit,
    /// Every chamber's stretch is positive (its volume element has not vanished).
    ChamberCollapse,
    /// Fibre stretch across the section within the model's validity range.
    StrainRange,
    /// Pressures within the design's operating range.
    OperatingRange,
    /// A dynamic run's energy balance E - E(0) - W_in + D does not grow beyond the
    /// integrator's tolerance (energy does not appear without input).
    EnergyBalance,
    /// The rod's surface penetrates an obstacle deeper than the obstacle's tolerance
    /// (`crate::contact`).
    Penetration,
}

impl Rule {
    /// The rule's name in messages and in Python (`InvalidStateError.rule`).
    pub fn name(self) -> &'static str {
        match self {
            Rule::Finite => "finite_state",
            Rule::Rotation => "rotation",
            Rule::PositiveStretch => "positive_stretch",
            Rule::StretchLimit => "stretch_limit",
            Rule::ChamberCollapse => "chamber_collapse",
            Rule::StrainRange => "strain_range",
            Rule::OperatingRange => "operating_range",
            Rule::EnergyBalance => "energy_balance",
            Rule::Penetration => "penetration",
        }
    }

    /// A physical rule (always an error), as opposed to a validity range.
    pub fn is_physical(self) -> bool {
        !matches!(self, Rule::StrainRange | Rule::OperatingRange)
    }
}
