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
    /// A computed state breaks a physical rule (see `crate::validity`): a rotation that is
    /// not one, a stretch <= 0, energy that grows without input. `location` says where
    /// (node and arc length, or time and step), `rule` what must hold and what to change.
    #[error("{quantity} = {value} at {location}: {rule}")]
    InvalidState {
        quantity: String,
        location: String,
        value: String,
        rule: String,
    },
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
    pub fn invalid_state(
        quantity: impl Into<String>,
        location: impl Into<String>,
        value: impl ToString,
        rule: impl Into<String>,
    ) -> Self {
        SoftrodError::InvalidState {
            quantity: quantity.into(),
            location: location.into(),
            value: value.to_string(),
            rule: rule.into(),
        }
    }
}

pub type Result<T> = std::result::Result<T, SoftrodError>;
