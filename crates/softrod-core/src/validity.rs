//! Physical validity rules shared by every solver (DESIGN.md section 5b): a result is
//! returned only if its rotations are rotations and its stretch is positive. Small pure
//! functions; the caller says where (`location`, e.g. "node 12 (s = 0.1100 m)" or
//! "t = 1.25 s (step 250)") and gets a `SoftrodError::InvalidState` naming the quantity,
//! the value and the rule.

use crate::error::{Result, SoftrodError};

/// Largest entry of |R^T R - I| accepted for a rotation. Every solver rebuilds its
/// rotations from the base through at most a few hundred steps, each re-projected onto
/// SO(3) (Newton-Schulz in shooting, normalised quaternions in collocation), so a valid
/// result deviates by round-off, ~1e-14. 1e-9 leaves five orders of magnitude for that
/// and for solver tolerances while catching any rotation that is not one (issue 13 saw
/// deviations of 0.5 and det R = 0.74).
pub const ROTATION_TOL: f64 = 1e-9;

fn rotation_error(rot: &[[f64; 3]; 3]) -> (f64, f64) {
    let mut worst: f64 = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            let d: f64 =
                (0..3).map(|k| rot[k][i] * rot[k][j]).sum::<f64>() - if i == j { 1.0 } else { 0.0 };
            worst = if d.is_nan() {
                f64::NAN
            } else {
                worst.max(d.abs())
            };
        }
    }
    let det = rot[0][0] * (rot[1][1] * rot[2][2] - rot[1][2] * rot[2][1])
        - rot[0][1] * (rot[1][0] * rot[2][2] - rot[1][2] * rot[2][0])
        + rot[0][2] * (rot[1][0] * rot[2][1] - rot[1][1] * rot[2][0]);
    (worst, det)
}

/// Whether `rot` passes [`check_rotation`] (no allocation: hot loops test this first and
/// call the check only to build the error).
pub fn is_rotation(rot: &[[f64; 3]; 3], tol: f64) -> bool {
    let (worst, det) = rotation_error(rot);
    worst <= tol && det > 0.0
}

/// Whether `v3` passes [`check_stretch`].
pub fn is_valid_stretch(v3: f64) -> bool {
    v3.is_finite() && v3 > 0.0
}

/// `rot` (row-major, columns d1 d2 d3) is a proper rotation: finite, |R^T R - I| <= tol
/// entrywise and det R > 0.
pub fn check_rotation(rot: &[[f64; 3]; 3], tol: f64, location: &str) -> Result<()> {
    let (worst, det) = rotation_error(rot);
    if !(worst <= tol && det > 0.0) {
        return Err(SoftrodError::invalid_state(
            "max |R^T R - I|",
            location,
            format!("{worst:.3e} (det R = {det:.6})"),
            format!(
                "a rotation must be orthonormal to {tol:.0e} with det R = +1; the solve is not a valid rod state"
            ),
        ));
    }
    Ok(())
}

/// The stretch v3 = d3 . r' must be positive (the rod may not turn inside out) and finite.
pub fn check_stretch(v3: f64, location: &str) -> Result<()> {
    if !is_valid_stretch(v3) {
        return Err(SoftrodError::invalid_state(
            "stretch v3",
            location,
            format!("{v3:.6e}"),
            "the stretch must be > 0 (v3 <= 0 turns the rod inside out): the loads or pressures are beyond what the model describes",
        ));
    }
    Ok(())
}

/// Every value finite.
pub fn check_finite(quantity: &str, values: &[f64], location: &str) -> Result<()> {
    if let Some(x) = values.iter().find(|x| !x.is_finite()) {
        return Err(SoftrodError::invalid_state(
            quantity,
            location,
            x,
            "must be finite",
        ));
    }
    Ok(())
}

/// "node k (s = ... m)", the location format of node-wise checks.
pub fn node_location(node: usize, s: f64) -> String {
    format!("node {node} (s = {s:.4} m)")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rules_accept_valid_and_name_invalid_states() {
        let (c, s) = (0.6f64, 0.8f64);
        let rot = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]];
        assert!(check_rotation(&rot, ROTATION_TOL, "node 1").is_ok());
        let mut bad = rot;
        bad[0][0] *= 1.5;
        let e = check_rotation(&bad, ROTATION_TOL, "node 3 (s = 0.1 m)").unwrap_err();
        assert!(e.to_string().contains("node 3"), "{e}");
        let flip = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]];
        assert!(check_rotation(&flip, ROTATION_TOL, "x").is_err());
        assert!(check_stretch(0.9, "x").is_ok());
        let e = check_stretch(-0.87, &node_location(7, 0.05)).unwrap_err();
        assert!(matches!(e, SoftrodError::InvalidState { .. }));
        assert!(e.to_string().contains("node 7 (s = 0.0500 m)"), "{e}");
        assert!(check_stretch(f64::NAN, "x").is_err());
        assert!(check_finite("tip", &[1.0, f64::INFINITY], "t = 1 s").is_err());
    }
}
