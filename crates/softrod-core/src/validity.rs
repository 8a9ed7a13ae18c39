//! The rules a rod state must satisfy before any solver returns it (docs/model.md, "Validity
//! and stability"), and the size limits of a design.
//!
//! Small pure functions, shared by statics and dynamics: each checks one rule at one node and
//! returns [`SoftrodError::InvalidState`] naming the rule, the node, its arc length, the
//! offending value and what it had to satisfy. Two kinds of rule:
//! * physical rules ([`Rule::is_physical`]): a state that breaks one is not a state of any
//!   rod (a rotation that is not one, a rod or chamber turned inside out, NaN). Solvers
//!   always raise.
//! * validity ranges: the state is a rod's, but outside the range where the model describes
//!   the actuator (fibre stretch beyond [`StrainLimits`], pressures beyond the design's
//!   `operating_range`). Solvers raise, warn or ignore as [`Policy`] says.

use crate::error::{Result, SoftrodError};

/// Most pressure channels a design may use (channel indices 0..MAX_CHANNELS). Checked before
/// anything is sized by the channel count. The limits here equal the Python boundary's
/// (`python/softrod/_limits.py`, docs/errors.md), so Rust users get the same rules.
pub const MAX_CHANNELS: usize = 64;
/// Most sections in a design.
pub const MAX_SECTIONS: usize = 1000;
/// Most chambers in one section (the overlap check is quadratic in this number).
pub const MAX_CHAMBERS_PER_SECTION: usize = 64;
/// Most integration steps in one section.
pub const MAX_STEPS_PER_SECTION: usize = 100_000;
/// Most integration steps over the whole rod: a shape holds about 30 numbers per node, so
/// this bounds a solution at about 240 MB.
pub const MAX_TOTAL_STEPS: usize = 1_000_000;
/// Most distributed line loads in a design.
pub const MAX_LINE_LOADS: usize = 1000;
/// Most points in an EA(F) or reference-shape table.
pub const MAX_TABLE_POINTS: usize = 10_000;
/// Most tendon channels, and most tendons in one section.
pub const MAX_TENDONS: usize = 64;

/// Largest entry of |R^T R - I| accepted at a node (and det R > 0). The integrator
/// re-projects R onto SO(3) after every step, which squares the step's orthonormality
/// error, so a correct solution sits at round-off (~1e-15). 1e-6 after re-projection means
/// about 1e-3 before it: a step far too coarse for the curvature. The cure is more steps.
pub const ROTATION_TOLERANCE: f64 = 1e-6;

/// Largest centreline stretch v3 of any state: no silicone elastomer of soft robotics
/// stretches to 10 times its length before it tears (elongation at break, manufacturers'
/// data sheets: Ecoflex 00-30 900 %, Dragon Skin 30 364 %). A larger stretch (e.g. 1e9 Pa
/// in a chamber) is not a state of the actuator, whatever the validity range allows.
pub const MAX_STRETCH: f64 = 10.0;

/// What a solver does when a state leaves a validity range (physical rules always raise).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Policy {
    /// Return an error (the default: an answer outside the model's range is not returned).
    #[default]
    Raise,
    /// Return the result with the violations listed (the caller warns).
    Warn,
    /// Do not check the validity ranges.
    Ignore,
}

impl Policy {
    /// "raise", "warn" or "ignore".
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "raise" => Some(Policy::Raise),
            "warn" => Some(Policy::Warn),
            "ignore" => Some(Policy::Ignore),
            _ => None,
        }
    }
}

pub use crate::error::Rule;

/// The validity range of the fibre stretch: along every material fibre of the cross-section
/// the axial stretch lambda = v3 + u1 y - u2 x must lie in [stretch_min, stretch_max].
/// The default [1/3, 3] is a judgement, not a material law: the papers' laws are fitted to
/// data with fibre stretches up to about 2.3 (STIFF-FLOP, paper 003, at 1.5 bar on three
/// chambers: 84 % elongation plus bending), and a fibre compressed to a third or stretched
/// to three times its length is far outside any of them, where the cross-section no longer
/// stays the rigid disc the rod model assumes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StrainLimits {
    pub stretch_min: f64,
    pub stretch_max: f64,
}

impl Default for StrainLimits {
    fn default() -> Self {
        StrainLimits {
            stretch_min: 1.0 / 3.0,
            stretch_max: 3.0,
        }
    }
}

impl StrainLimits {
    pub fn validate(&self) -> Result<()> {
        let (lo, hi) = (self.stretch_min, self.stretch_max);
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo < 1.0 && hi > 1.0) {
            return Err(SoftrodError::invalid(
                "stretch_range",
                format!("({lo}, {hi})"),
                "must be finite with 0 < min < 1 < max (stretch 1 is the reference state)",
            ));
        }
        Ok(())
    }
}

/// Where a node is: its index along the rod (0 = base), arc length and section.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Node {
    pub index: usize,
    pub s: f64,
    pub section: usize,
}

fn broken(rule: Rule, node: Option<Node>, value: f64, message: String) -> SoftrodError {
    SoftrodError::InvalidState {
        rule,
        node: node.map(|n| n.index),
        s: node.map_or(f64::NAN, |n| n.s),
        time: None,
        value,
        message,
    }
}

/// Every number of a node's state is finite.
pub fn check_finite(node: Node, values: &[f64]) -> Result<()> {
    match values.iter().find(|v| !v.is_finite()) {
        None => Ok(()),
        Some(&v) => Err(broken(
            Rule::Finite,
            Some(node),
            v,
            format!(
                "the state in sections[{}] holds {v} (the solution diverged)",
                node.section
            ),
        )),
    }
}

/// Largest entry of |R^T R - I| (R row-major, columns the directors).
pub fn orthonormality_error(rot: &[[f64; 3]; 3]) -> f64 {
    let mut worst: f64 = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            let dot: f64 = (0..3).map(|k| rot[k][i] * rot[k][j]).sum();
            let want = if i == j { 1.0 } else { 0.0 };
            worst = worst.max((dot - want).abs());
        }
    }
    worst
}

fn det3(m: &[[f64; 3]; 3]) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

/// R is orthonormal to [`ROTATION_TOLERANCE`] with det R > 0.
pub fn check_rotation(node: Node, rot: &[[f64; 3]; 3]) -> Result<()> {
    let err = orthonormality_error(rot);
    let det = det3(rot);
    if err <= ROTATION_TOLERANCE && det > 0.0 {
        return Ok(());
    }
    Err(broken(
        Rule::Rotation,
        Some(node),
        err,
        format!(
            "the rotation is not one: max |R^T R - I| = {err:.3e} (tolerance {ROTATION_TOLERANCE:e}), det R = {det:.6} in sections[{}]; the integration steps are too coarse for this curvature (raise the section's steps or lower numerics.step_length)",
            node.section
        ),
    ))
}

/// The centreline stretch v3 is positive and at most [`MAX_STRETCH`].
pub fn check_stretch(node: Node, v: &[f64; 3]) -> Result<()> {
    if v[2] > MAX_STRETCH {
        return Err(broken(
            Rule::StretchLimit,
            Some(node),
            v[2],
            format!(
                "stretch v3 = {:.4e} in sections[{}] exceeds {MAX_STRETCH}: no elastomer stretches that far before it tears; the pressures or loads are beyond anything the actuator survives",
                v[2], node.section
            ),
        ));
    }
    if v[2] > 0.0 {
        return Ok(());
    }
    Err(broken(
        Rule::PositiveStretch,
        Some(node),
        v[2],
        format!(
            "stretch v3 = {:.4} <= 0 in sections[{}]: the rod would be compressed through zero length and turned inside out; the loads exceed what the rod model can represent",
            v[2], node.section
        ),
    ))
}

/// Axial stretch of the material fibre at body position `rho` = (x, y) in the cross-section:
/// the d3 component of v + u x rho (shear and twist change it only at second order).
pub fn fibre_stretch(v: &[f64; 3], u: &[f64; 3], rho: [f64; 2]) -> f64 {
    v[2] + u[0] * rho[1] - u[1] * rho[0]
}

/// Chamber `chamber` of the node's section, centroid `rho` (body frame): its stretch is
/// positive. At zero stretch the chamber's volume element lambda A ds vanishes (it has
/// collapsed); below, it is inside out.
pub fn check_chamber(
    node: Node,
    chamber: usize,
    v: &[f64; 3],
    u: &[f64; 3],
    rho: [f64; 2],
) -> Result<()> {
    let lam = fibre_stretch(v, u, rho);
    if lam > 0.0 {
        return Ok(());
    }
    Err(broken(
        Rule::ChamberCollapse,
        Some(node),
        lam,
        format!(
            "sections[{}].chambers[{chamber}] has collapsed: its stretch v3 + u1 y - u2 x = {lam:.4} <= 0 (its volume would vanish); the loads or pressures exceed what the rod model can represent",
            node.section
        ),
    ))
}

/// The extremes of the fibre stretch over the section's outer circle of radius `radius`
/// (0 when unknown: only the centreline), measured relative to the reference shape: the
/// fibre at (x, y) has the stretch (v3 + u1 y - u2 x) / (v3* + u1* y - u2* x) (shear and
/// twist change it only at second order). For a straight reference the extremes are
/// v3 -/+ radius |(u1, u2)|. Otherwise the ratio of two affine functions of the point on
/// the circle (x, y) = radius (cos a, sin a) is extremal where
/// (c b - a d) . (-sin a, cos a) = radius (b2 d1 - b1 d2) (a, b: numerator, c, d:
/// denominator), solved in closed form; inside the disc it is monotone along every line,
/// so the extremes lie on the circle.
pub fn fibre_stretch_range(
    v: &[f64; 3],
    u: &[f64; 3],
    reference: (&[f64; 3], &[f64; 3]),
    radius: f64,
) -> (f64, f64) {
    let (vr, ur) = reference;
    if *vr == [0.0, 0.0, 1.0] && ur[0] == 0.0 && ur[1] == 0.0 {
        let spread = radius * u[0].hypot(u[1]);
        return (v[2] - spread, v[2] + spread);
    }
    // stretch(x, y) = (a + b . p) / (c + d . p), p = (x, y)
    let (a, b) = (v[2], [-u[1], u[0]]);
    let (c, d) = (vr[2], [-ur[1], ur[0]]);
    let at = |angle: f64| {
        let (sn, cs) = angle.sin_cos();
        let p = [radius * cs, radius * sn];
        (a + b[0] * p[0] + b[1] * p[1]) / (c + d[0] * p[0] + d[1] * p[1])
    };
    let w = [c * b[0] - a * d[0], c * b[1] - a * d[1]];
    let k = radius * (b[1] * d[0] - b[0] * d[1]);
    // w2 cos(angle) - w1 sin(angle) = |w| cos(angle + beta) = -k
    let norm = w[0].hypot(w[1]);
    let mut angles = vec![0.0];
    if norm > 0.0 && radius > 0.0 {
        let beta = w[0].atan2(w[1]);
        let q = (-k / norm).clamp(-1.0, 1.0).acos();
        angles.extend([q - beta, -q - beta]);
    }
    let values: Vec<f64> = angles.into_iter().map(at).collect();
    let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    (lo, hi)
}

/// The fibre stretch across a section of outer radius `radius` (0 when unknown: only the
/// centreline is checked), relative to the reference strains (v*, u*), within `limits`
/// (see [`fibre_stretch_range`]).
pub fn check_strain_range(
    node: Node,
    v: &[f64; 3],
    u: &[f64; 3],
    reference: (&[f64; 3], &[f64; 3]),
    radius: f64,
    limits: &StrainLimits,
) -> Result<()> {
    let (lo, hi) = fibre_stretch_range(v, u, reference, radius);
    let (value, what) = if lo < limits.stretch_min {
        (lo, "below")
    } else if hi > limits.stretch_max {
        (hi, "above")
    } else if lo.is_nan() || hi.is_nan() {
        (f64::NAN, "outside")
    } else {
        return Ok(());
    };
    Err(broken(
        Rule::StrainRange,
        Some(node),
        value,
        format!(
            "fibre stretch {value:.4} in sections[{}] (v3 = {:.4}, curvature {:.4} 1/m at radius {radius:.4e} m{}) is {what} the validity range [{}, {}] of the model (stretch_range)",
            node.section,
            v[2],
            u[0].hypot(u[1]),
            if *reference.0 == [0.0, 0.0, 1.0] && *reference.1 == [0.0; 3] {
                String::new()
            } else {
                ", relative to the reference shape".to_string()
            },
            limits.stretch_min,
            limits.stretch_max
        ),
    ))
}

/// Every pressure (Pa) and tendon tension (N) within the design's operating range, where
/// it states one.
pub fn check_operating_range(
    pressures: &[f64],
    tensions: &[f64],
    range: &crate::spec::OperatingRangeSpec,
) -> Result<()> {
    let inputs = [
        ("pressures", "pressure", "Pa", pressures, range.pressure),
        ("tensions", "tension", "N", tensions, range.tension),
    ];
    for (name, key, unit, values, bounds) in inputs {
        let Some([lo, hi]) = bounds else { continue };
        for (i, &x) in values.iter().enumerate() {
            if x < lo || x > hi {
                return Err(broken(
                    Rule::OperatingRange,
                    None,
                    x,
                    format!(
                        "{name}[{i}] = {x} {unit} is outside the design's operating_range.{key} [{lo}, {hi}] {unit} (what the actuator is built and validated for)"
                    ),
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const NODE: Node = Node {
        index: 7,
        s: 0.05,
        section: 1,
    };

    fn rule_of(e: SoftrodError) -> Rule {
        match e {
            SoftrodError::InvalidState { rule, node, .. } => {
                assert!(node.is_none() || node == Some(7));
                rule
            }
            other => panic!("expected InvalidState, got {other:?}"),
        }
    }

    #[test]
    fn rotation_rule() {
        let id = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(check_rotation(NODE, &id).is_ok());
        let mut skew = id;
        skew[0][1] = 1e-3;
        assert_eq!(
            rule_of(check_rotation(NODE, &skew).unwrap_err()),
            Rule::Rotation
        );
        let reflection = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]];
        assert_eq!(
            rule_of(check_rotation(NODE, &reflection).unwrap_err()),
            Rule::Rotation
        );
    }

    #[test]
    fn stretch_chamber_and_range_rules() {
        assert!(check_stretch(NODE, &[0.0, 0.0, 0.3]).is_ok());
        assert_eq!(
            rule_of(check_stretch(NODE, &[0.0, 0.0, 3012.0]).unwrap_err()),
            Rule::StretchLimit
        );
        let e = check_stretch(NODE, &[0.0, 0.0, -0.87]).unwrap_err();
        assert!(e.to_string().contains("-0.87"), "{e}");
        assert_eq!(rule_of(e), Rule::PositiveStretch);
        // bending 1/(5 mm) puts the chamber 6 mm off-axis on the inside at stretch 1 - 1.2
        let (v, u) = ([0.0, 0.0, 1.0], [200.0, 0.0, 0.0]);
        assert!(check_chamber(NODE, 0, &v, &u, [0.0, 6e-3]).is_ok());
        assert_eq!(
            rule_of(check_chamber(NODE, 0, &v, &u, [0.0, -6e-3]).unwrap_err()),
            Rule::ChamberCollapse
        );
        let lim = StrainLimits::default();
        let straight = (&[0.0, 0.0, 1.0], &[0.0; 3]);
        assert!(check_strain_range(NODE, &v, &[0.0; 3], straight, 0.01, &lim).is_ok());
        assert_eq!(
            rule_of(check_strain_range(NODE, &v, &u, straight, 0.01, &lim).unwrap_err()),
            Rule::StrainRange
        );
        assert_eq!(
            rule_of(
                check_strain_range(NODE, &[0.0, 0.0, 3.5], &[0.0; 3], straight, 0.0, &lim)
                    .unwrap_err()
            ),
            Rule::StrainRange
        );
        // A rod bent to its own reference curvature has every fibre at stretch 1.
        let (lo, hi) = fibre_stretch_range(&v, &u, (&v, &u), 0.004);
        assert!(
            (lo - 1.0).abs() < 1e-14 && (hi - 1.0).abs() < 1e-14,
            "{lo} {hi}"
        );
        assert!(StrainLimits {
            stretch_min: 0.0,
            stretch_max: 2.0
        }
        .validate()
        .is_err());
    }

    /// The closed-form extremes of the relative fibre stretch against a dense sampling of
    /// the outer circle (the extremes lie on it).
    #[test]
    fn relative_fibre_stretch_extremes() {
        let (v, u) = ([0.01, -0.02, 1.1], [30.0, -12.0, 4.0]);
        let (vr, ur) = ([0.0, 0.0, 0.95], [-8.0, 15.0, 1.0]);
        let radius = 0.02;
        let (lo, hi) = fibre_stretch_range(&v, &u, (&vr, &ur), radius);
        let (mut slo, mut shi) = (f64::INFINITY, f64::NEG_INFINITY);
        for k in 0..100_000 {
            let a = k as f64 / 100_000.0 * std::f64::consts::TAU;
            let (x, y) = (radius * a.cos(), radius * a.sin());
            let f = (v[2] + u[0] * y - u[1] * x) / (vr[2] + ur[0] * y - ur[1] * x);
            slo = slo.min(f);
            shi = shi.max(f);
        }
        // Sampling at 6e-5 rad misses the extreme by O(6e-5^2) relative.
        assert!(lo <= slo + 1e-12 && lo > slo - 1e-8, "{lo} vs {slo}");
        assert!(hi >= shi - 1e-12 && hi < shi + 1e-8, "{hi} vs {shi}");
    }

    #[test]
    fn finite_and_operating_range_rules() {
        assert!(check_finite(NODE, &[1.0, 2.0]).is_ok());
        assert_eq!(
            rule_of(check_finite(NODE, &[1.0, f64::NAN]).unwrap_err()),
            Rule::Finite
        );
        let range = crate::spec::OperatingRangeSpec {
            pressure: Some([0.0, 7e4]),
            tension: Some([0.0, 20.0]),
        };
        assert!(check_operating_range(&[0.0, 7e4], &[20.0], &range).is_ok());
        let e = check_operating_range(&[0.0, 5e5], &[], &range).unwrap_err();
        assert!(e.to_string().contains("pressures[1]"), "{e}");
        assert_eq!(rule_of(e), Rule::OperatingRange);
        let e = check_operating_range(&[0.0], &[1.0, 25.0], &range).unwrap_err();
        assert!(e.to_string().contains("tensions[1] = 25 N"), "{e}");
        assert_eq!(rule_of(e), Rule::OperatingRange);
        // A range that states pressures only leaves tensions unchecked, and the reverse.
        let pressure_only = crate::spec::OperatingRangeSpec {
            tension: None,
            ..range
        };
        assert!(check_operating_range(&[1e4], &[1e3], &pressure_only).is_ok());
        assert!(!Rule::OperatingRange.is_physical() && Rule::PositiveStretch.is_physical());
    }
}
