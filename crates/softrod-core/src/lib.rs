//! softrod-core: Cosserat-rod models of soft pneumatic multi-chamber actuators.
//!
//! Pure Rust, no Python. A [`spec::DesignSpec`] (SI units) is validated and compiled into a
//! [`rod::Rod`]; [`statics::solve`] finds its static equilibrium under chamber pressures,
//! gravity and loads by shooting with an exact (dual-number) Jacobian, or by collocation
//! where shooting is ill-conditioned; [`dynamics`] steps the rod in time;
//! [`batch::solve_batch`] does many statics in parallel; [`sensitivity`] gives exact
//! derivatives of the tip pose with respect to design parameters for calibration;
//! [`jacobian`] those with respect to pressures and tip loads; [`inverse`] finds the
//! pressures that bring the tip to a target; [`linearise`] gives M, D, K and B of the
//! dynamics at an equilibrium; [`pcc`] is the piecewise-constant-curvature model.
//!
//! Layers (each module uses only those on its own line or above; no module cycle):
//! - base: [`error`] (errors and the validity rules' names), [`jet`] (the one dual number
//!   and the scalar interfaces), [`interp`], [`validity`] (result checks);
//! - spec: [`spec`] (the design in SI, validated; the `[pcc]` table in [`spec::pcc`]);
//! - model: [`section`] (cross-sections), [`law`] (constitutive laws), [`rod`] (the
//!   compiled rod), [`contact`] (rigid obstacles and the penalty law);
//! - discretisation: [`ode`] (the Cosserat ODE and its RK4 shooting), [`collocation`]
//!   (Gauss-Legendre collocation) with [`banded`] (its linear algebra);
//! - scope: [`scope`] (which features each model carries: the refusals the solvers share);
//! - solvers: [`statics`] (shooting, and collocation in [`statics::collocation`]),
//!   [`dynamics`], [`sensitivity`], [`jacobian`], [`inverse`], [`linearise`], [`pcc`];
//! - [`batch`]: many statics in parallel.

// Index loops over 3-vectors read like the equations they implement.
#![allow(clippy::needless_range_loop)]

pub mod banded;
pub mod batch;
pub mod collocation;
pub mod contact;
pub mod dynamics;
pub mod error;
pub mod interp;
pub mod inverse;
pub mod jacobian;
pub mod jet;
pub mod law;
pub mod linearise;
pub mod marker;
pub mod mesh;
pub mod ode;
pub mod pcc;
pub mod reference;
pub mod rod;
pub mod scope;
pub mod section;
pub mod sensitivity;
pub mod spec;
pub mod statics;
pub mod tendon;
pub mod validity;

pub use error::{Result, SoftrodError};
pub use rod::Rod;
pub use spec::DesignSpec;
