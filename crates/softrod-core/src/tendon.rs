//! Tendons: routing in the cross-section and the constitutive law with tendon tensions
//! (docs/model.md, "Tendons"; Rucker and Webster, "Statics and dynamics of continuum robots
//! with general tendon routing and external loading", IEEE T-RO 27(6):1033-1044, 2011).
//!
//! A frictionless tendon i at the body-frame offset r_i(s) = (x_i, y_i, 0) carries the same
//! tension tau_i all along. Rucker and Webster put its pull on the rod as a distributed
//! load along the routing plus a point load at the termination. Here, as for the pressure
//! (paper 002 eqs. 6-7), the balance laws carry the total internal force and moment of the
//! rod *with* its tendons: the tendon crossing a cut at s adds its tension to the cut's
//! force,
//!   n = n_m - P d3 + sum_i tau_i R t_i,      m = m_m - sum_k rho_k x (p_k A_k d3)
//!                                              + sum_i R r_i x (tau_i R t_i),
//! with t_i = q_i / |q_i| the tendon's unit tangent in the body frame,
//! q_i = v + u x r_i + r_i'. The tendons' loads on the rod (the distributed one and the
//! one at the termination) are then internal: n' + f = 0 and m' + r' x n + l = 0 hold with
//! the external loads only, n(0) is still known from the dead loads, and n and m are
//! continuous where a tendon ends (its point load there is what removes its tension from
//! the cut). Both formulations give the same equilibria; this one keeps the balance laws and
//! the boundary conditions of the rod without tendons.
//!
//! The price is an implicit law: the tendon tangents depend on the strains. In body
//! coordinates, with w = (v, u) and B_i = [I, -[r_i]x] (so that q_i = B_i w + r_i'),
//!   w = S(nb - F_t(w), mb - M_t(w)),   (F_t, M_t) = sum_i tau_i B_i^T t_i(w),
//! where S is the section's law without tendons (strains from the material force and
//! moment, pressure and reference strains included). This is the stationarity condition of
//! a strictly convex function for the linear law (the elastic energy plus tau_i |q_i|, the
//! work of the tension on the tendon's length), so it has one solution. It is solved by
//! Newton's method in f64 with the exact Jacobian
//!   J = I + S' sum_i (tau_i / |q_i|) B_i^T (I - t_i t_i^T) B_i,
//! and dual parts (exact first derivatives) by one linearised step at the solution:
//! w_D = w* - J^-1 R_D(w*), the implicit function theorem.

use crate::spec::TendonSpec;
use nalgebra::{SMatrix, SVector};

/// Compiled routing of one tendon in one section: distance and angle linear in s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Route {
    pub channel: usize,
    distance: [f64; 2],
    angle: [f64; 2],
    length: f64,
}

impl Route {
    pub fn new(t: &TendonSpec, length: f64) -> Self {
        let (distance, angle) = t.ends();
        Route {
            channel: t.channel,
            distance,
            angle,
            length,
        }
    }

    /// Largest distance from the centreline along the section, m.
    pub fn max_distance(&self) -> f64 {
        self.distance[0].max(self.distance[1])
    }

    /// Offset r = (x, y) in (d1, d2), m, and its derivative dr/ds at the local arc length s.
    #[inline]
    pub fn at(&self, s: f64) -> ([f64; 2], [f64; 2]) {
        let t = s / self.length;
        let dd = (self.distance[1] - self.distance[0]) / self.length;
        let da = (self.angle[1] - self.angle[0]) / self.length;
        let d = self.distance[0] + t * (self.distance[1] - self.distance[0]);
        let a = self.angle[0] + t * (self.angle[1] - self.angle[0]);
        let (sn, cs) = a.sin_cos();
        (
            [d * cs, d * sn],
            [dd * cs - d * da * sn, dd * sn + d * da * cs],
        )
    }
}

/// One tendon at one arc length: tension (f64 value), offset and its derivative.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TendonPoint {
    pub tension: f64,
    pub r: [f64; 2],
    pub dr: [f64; 2],
}

pub(crate) type Mat6 = SMatrix<f64, 6, 6>;
pub(crate) type Vec6 = SVector<f64, 6>;

/// Tangent t = q / |q| of a tendon at strains w and |q|.
#[inline]
pub(crate) fn tangent(w: &[f64; 6], p: &TendonPoint) -> ([f64; 3], f64) {
    let (x, y) = (p.r[0], p.r[1]);
    // u x r with r = (x, y, 0): (-u3 y, u3 x, u1 y - u2 x)
    let q = [
        w[0] - w[5] * y + p.dr[0],
        w[1] + w[5] * x + p.dr[1],
        w[2] + w[3] * y - w[4] * x,
    ];
    let len = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
    ([q[0] / len, q[1] / len, q[2] / len], len)
}

/// The tendons' total force and moment in the body frame, (F_t, M_t) = sum tau B^T t,
/// for given unit tangents (B^T t = (t, r x t)).
#[inline]
pub(crate) fn load(tangents: &[([f64; 3], f64)], points: &[TendonPoint]) -> [f64; 6] {
    let mut out = [0.0; 6];
    for ((t, _), p) in tangents.iter().zip(points) {
        let (x, y) = (p.r[0], p.r[1]);
        let tau = p.tension;
        out[0] += tau * t[0];
        out[1] += tau * t[1];
        out[2] += tau * t[2];
        // r x t = (y t3, -x t3, x t2 - y t1)
        out[3] += tau * y * t[2];
        out[4] -= tau * x * t[2];
        out[5] += tau * (x * t[1] - y * t[0]);
    }
    out
}

/// dT/dw = sum_i (tau_i / |q_i|) B_i^T (I - t_i t_i^T) B_i at tangents t_i and |q_i|.
pub(crate) fn load_jacobian(tangents: &[([f64; 3], f64)], points: &[TendonPoint]) -> Mat6 {
    let mut m = Mat6::zeros();
    for ((t, len), p) in tangents.iter().zip(points) {
        let c = p.tension / len;
        if c == 0.0 {
            continue;
        }
        let (x, y) = (p.r[0], p.r[1]);
        // B = [I, -[r]x]: q = B w; -[r]x u = u x r = (-y u3, x u3, y u1 - x u2).
        let mut b = SMatrix::<f64, 3, 6>::zeros();
        for k in 0..3 {
            b[(k, k)] = 1.0;
        }
        b[(0, 5)] = -y;
        b[(1, 5)] = x;
        b[(2, 3)] = y;
        b[(2, 4)] = -x;
        let tv = nalgebra::Vector3::new(t[0], t[1], t[2]);
        let proj = nalgebra::Matrix3::identity() - tv * tv.transpose();
        m += (b.transpose() * proj * b) * c;
    }
    m
}
