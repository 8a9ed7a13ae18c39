//! Cross-section properties from the geometry (paper 002, Table III, with its typos
//! corrected: I_3,pk = pi/4 r^4 + rho_2^2 A, and I_A,m^b = I_A,o - I_A,i - sum_k I_A,pk).
//!
//! Body axes: d1, d2 span the cross-section; a point of the section sits at (x, y).
//! The bending energy density is (E/2)(u1 y - u2 x)^2, so the bending stiffness matrix is
//! E [[I_11, I_12], [I_12, I_22]] with I_11 = int y^2 dA, I_22 = int x^2 dA and
//! I_12 = -int x y dA (the sign that makes K_bt the Hessian of the energy). A circular
//! hole of area A_k centred at (x_k, y_k) removes A_k, pi r_k^4/4 + y_k^2 A_k from I_11,
//! pi r_k^4/4 + x_k^2 A_k from I_22, and adds x_k y_k A_k to I_12 (Steiner).

use crate::jet::RodScalar;
use crate::spec::SectionSpec;
use std::f64::consts::PI;

/// Area and second moments of the material part of a cross-section, about the geometric
/// centre of the outer disc (the rod's centreline, as in paper 002). Generic over the
/// scalar so that parameter derivatives (chamber offset, swelling) pass through it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CrossSection<S = f64> {
    /// Material area A_m, m^2.
    pub area: S,
    /// int y^2 dA, m^4.
    pub i11: S,
    /// int x^2 dA, m^4.
    pub i22: S,
    /// -int x y dA, m^4.
    pub i12: S,
}

impl CrossSection<f64> {
    /// Outer disc minus bore minus chamber holes (centroids include the chamber offset).
    pub fn from_spec(s: &SectionSpec, outer_radius: f64) -> Self {
        Self::from_holes(
            outer_radius,
            s.bore_radius,
            s.chambers
                .iter()
                .enumerate()
                .map(|(k, c)| (c.hole_radius(), s.chamber_centroid(k))),
        )
    }
}

impl<S: RodScalar> CrossSection<S> {
    /// Outer disc of radius `outer` minus a central bore minus circular holes
    /// (radius, centroid (x, y)).
    pub fn from_holes(outer: f64, bore: f64, holes: impl Iterator<Item = (S, [S; 2])>) -> Self {
        let disc = |r: f64| (PI * r * r, PI / 4.0 * r.powi(4));
        let (ao, io) = disc(outer);
        let (ai, ii) = disc(bore);
        let mut cs = CrossSection {
            area: S::from(ao - ai),
            i11: S::from(io - ii),
            i22: S::from(io - ii),
            i12: S::from(0.0),
        };
        for (r, [x, y]) in holes {
            let r2 = r * r;
            let a = r2 * PI;
            let i0 = r2 * r2 * (PI / 4.0);
            cs.area -= a;
            cs.i11 -= i0 + y * y * a;
            cs.i22 -= i0 + x * x * a;
            cs.i12 += x * y * a;
        }
        cs
    }

    /// Polar moment J = I_11 + I_22 (paper 002, eq. 19).
    pub fn polar(&self) -> S {
        self.i11 + self.i22
    }
}
