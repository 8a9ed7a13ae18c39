//! softrod-core: Cosserat-rod models of soft pneumatic multi-chamber actuators.
//!
//! Pure Rust, no Python. A [`spec::DesignSpec`] (SI units) is validated and compiled into a
//! [`rod::Rod`]; [`statics::solve`] finds its static equilibrium under chamber pressures,
//! gravity and loads by shooting with an exact (dual-number) Jacobian;
//! [`batch::solve_batch`] does many in parallel; [`sensitivity`] gives exact derivatives
//! of the tip pose with respect to design parameters for calibration; [`jacobian`] those
//! with respect to pressures and tip loads; [`inverse`] finds the pressures that bring the
//! tip to a target; [`linearise`] gives M, D, K and B of the dynamics at an equilibrium.

// Index loops over 3-vectors read like the equations they implement.
#![allow(clippy::needless_range_loop)]

pub mod batch;
pub mod dynamics;
pub mod error;
pub mod interp;
pub mod inverse;
pub mod jacobian;
pub mod jet;
pub mod law;
pub mod linearise;
pub mod ode;
pub mod pcc;
pub mod rod;
pub mod section;
pub mod sensitivity;
pub mod spec;
pub mod statics;
pub mod validity;

pub use error::{Result, SoftrodError};
pub use rod::Rod;
pub use spec::DesignSpec;
