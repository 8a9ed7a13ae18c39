//! What the implicit differentiation of a converged equilibrium starts from, shared by the
//! exact Jacobians (`crate::jacobian`), the linearisation (`crate::linearise`) and the
//! parameter sensitivities (`crate::sensitivity`): the tangent solve J dx = rhs with its
//! error at a limit point, and a system's unknowns, level and LU factors.

use super::system::{validate, Level, Platform, SystemRod, SystemSolution};
use super::Problem;
use crate::error::{Result, SoftrodError};
use nalgebra::linalg::LU;
use nalgebra::{DVector, Dyn};

/// Error for a singular Jacobian (`what`) at an equilibrium Newton converged on in
/// `iterations` to `residual`: a limit point, where its `derivatives` are undefined.
pub(crate) fn singular_jacobian(
    iterations: usize,
    residual: f64,
    what: &str,
    derivatives: &str,
) -> SoftrodError {
    SoftrodError::NotConverged {
        iterations,
        residual,
        load_factor: 1.0,
        reason: format!(
            "{what} is singular at this equilibrium (a limit point), so its {derivatives} are \
             undefined"
        ),
    }
}

/// The implicit function theorem's step: dx with J dx = rhs for J's LU factors `lu`, or
/// `singular()` where J is singular (no solution, or one that is not finite).
pub(crate) fn solve_tangent(
    lu: &LU<f64, Dyn, Dyn>,
    rhs: &DVector<f64>,
    singular: impl FnOnce() -> SoftrodError,
) -> Result<DVector<f64>> {
    lu.solve(rhs)
        .filter(|d| d.iter().all(|v| v.is_finite()))
        .ok_or_else(singular)
}

/// The unknowns of `sol` checked against the system.
pub(crate) fn system_unknowns<'s>(
    rods: &[SystemRod],
    sol: &'s SystemSolution,
) -> Result<&'s [f64]> {
    let n = rods.len();
    if sol.x.len() != 6 * n + 6 || sol.rods.len() != n {
        return Err(SoftrodError::invalid(
            "solution",
            format!("{} unknowns", sol.x.len()),
            format!("is not a solution of this system of {n} rods (6 unknowns per rod and the platform's 6)"),
        ));
    }
    Ok(&sol.x)
}

/// What the implicit differentiation of a converged frictionless system starts from: its
/// level under the full loads, its unknowns and the LU factors of the exact Jacobian Newton
/// uses. A frictional equilibrium is refused (`why`: what its derivatives would depend on).
#[allow(clippy::type_complexity)]
pub(crate) fn system_tangent<'a, 's>(
    rods: &'a [SystemRod<'_>],
    platform: &Platform,
    sol: &'s SystemSolution,
    why: &str,
) -> Result<(Level<'a>, &'s [f64], LU<f64, Dyn, Dyn>)> {
    validate(rods, platform)?;
    let x = system_unknowns(rods, sol)?;
    if sol.friction.is_some() {
        return Err(SoftrodError::invalid(
            "solution",
            "a frictional equilibrium",
            format!("friction makes the equilibrium depend on its load path, {why}"),
        ));
    }
    let level = Level::full(
        rods,
        platform,
        rods.iter()
            .map(|r| Problem::new(r.rod, &r.loads, 1.0))
            .collect(),
    );
    let (_, jac) = level.jacobian(x, None);
    Ok((level, x, jac.lu()))
}
