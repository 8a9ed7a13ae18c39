//! The reference (stress-free) shape of a section: precurvature u*(s) and pre-strain v*(s)
//! (docs/scope.md, "Reference shape").
//!
//! Constant, or tabulated along the section and interpolated by a not-a-knot cubic spline:
//! the interpolant is C2, so the right-hand side of the rod ODE has a third derivative that
//! only jumps at the table's knots and classical RK4, evaluated at its stages (s, s + h/2,
//! s + h), keeps its fourth order (a jump in the third derivative costs O(h^5) per step that
//! contains a knot). The spline is scipy's `CubicSpline(bc_type="not-a-knot")`: two points
//! give a straight line, three the parabola through them.

use crate::spec::ReferenceSpec;
use std::sync::Arc;

/// A not-a-knot cubic spline of six values (u*, v*) over the section's local arc length.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceSpline {
    s: Vec<f64>,
    /// (u*, v*) at every knot.
    y: Vec<[f64; 6]>,
    /// Their derivatives d/ds at every knot.
    slope: Vec<[f64; 6]>,
}

/// The reference strains of a compiled section.
#[derive(Debug, Clone, PartialEq)]
pub enum Reference {
    /// v* = e3, u* = 0.
    Straight,
    /// Constant u* (1/m) and v*.
    Constant { u: [f64; 3], v: [f64; 3] },
    /// Tabulated along the section.
    Table(Arc<ReferenceSpline>),
}

impl Reference {
    /// Compile a validated reference spec.
    pub fn new(spec: &ReferenceSpec) -> Self {
        if spec.is_straight() {
            return Reference::Straight;
        }
        match &spec.table {
            None => Reference::Constant {
                u: spec.curvature,
                v: spec.strain,
            },
            Some(t) => {
                let y: Vec<[f64; 6]> = t
                    .curvature
                    .iter()
                    .zip(&t.strain)
                    .map(|(u, v)| [u[0], u[1], u[2], v[0], v[1], v[2]])
                    .collect();
                Reference::Table(Arc::new(ReferenceSpline::new(&t.s, y)))
            }
        }
    }

    /// (v*, u*) at local arc length `s` (from the section's start), m.
    #[inline]
    pub fn at(&self, s: f64) -> ([f64; 3], [f64; 3]) {
        match self {
            Reference::Straight => ([0.0, 0.0, 1.0], [0.0; 3]),
            Reference::Constant { u, v } => (*v, *u),
            Reference::Table(t) => {
                let w = t.eval(s);
                ([w[3], w[4], w[5]], [w[0], w[1], w[2]])
            }
        }
    }

    pub fn is_straight(&self) -> bool {
        matches!(self, Reference::Straight)
    }

    /// The reference changes along s.
    pub fn is_varying(&self) -> bool {
        matches!(self, Reference::Table(_))
    }
}

impl ReferenceSpline {
    /// The spline through the points (s_k, y_k): s strictly increasing, at least two.
    pub fn new(s: &[f64], y: Vec<[f64; 6]>) -> Self {
        let n = s.len();
        let dx: Vec<f64> = s.windows(2).map(|w| w[1] - w[0]).collect();
        let mut slope = vec![[0.0; 6]; n];
        for c in 0..6 {
            let d: Vec<f64> = (0..n - 1)
                .map(|k| (y[k + 1][c] - y[k][c]) / dx[k])
                .collect();
            let m = not_a_knot_slopes(s, &dx, &d);
            for k in 0..n {
                slope[k][c] = m[k];
            }
        }
        ReferenceSpline {
            s: s.to_vec(),
            y,
            slope,
        }
    }

    /// The six values at `q` (the end cubics extend beyond the knots).
    pub fn eval(&self, q: f64) -> [f64; 6] {
        let k = crate::interp::interval(&self.s, q);
        let h = self.s[k + 1] - self.s[k];
        let t = (q - self.s[k]) / h;
        let u = 1.0 - t;
        // Cubic Hermite basis.
        let h00 = (1.0 + 2.0 * t) * u * u;
        let h10 = t * u * u * h;
        let h01 = t * t * (3.0 - 2.0 * t);
        let h11 = -t * t * u * h;
        std::array::from_fn(|c| {
            h00 * self.y[k][c]
                + h10 * self.slope[k][c]
                + h01 * self.y[k + 1][c]
                + h11 * self.slope[k + 1][c]
        })
    }
}

/// Knot slopes of the not-a-knot cubic spline with interval widths `dx` and secant slopes
/// `d` (scipy's `CubicSpline` construction: a tridiagonal system whose first and last rows
/// impose a continuous third derivative at the second and second-to-last knots).
fn not_a_knot_slopes(x: &[f64], dx: &[f64], d: &[f64]) -> Vec<f64> {
    let n = x.len();
    if n == 2 {
        return vec![d[0], d[0]];
    }
    if n == 3 {
        // The parabola through three points: a 3x3 system.
        let a = [
            [1.0, 1.0, 0.0],
            [dx[1], 2.0 * (dx[0] + dx[1]), dx[0]],
            [0.0, 1.0, 1.0],
        ];
        let b = [2.0 * d[0], 3.0 * (dx[0] * d[1] + dx[1] * d[0]), 2.0 * d[1]];
        let m = nalgebra::Matrix3::from_fn(|i, j| a[i][j]);
        let v = nalgebra::Vector3::from_column_slice(&b);
        let s = m.lu().solve(&v).unwrap_or_else(nalgebra::Vector3::zeros);
        return vec![s[0], s[1], s[2]];
    }
    let mut lower = vec![0.0; n]; // lower[i]: row i, column i - 1
    let mut diag = vec![0.0; n];
    let mut upper = vec![0.0; n]; // upper[i]: row i, column i + 1
    let mut rhs = vec![0.0; n];
    for i in 1..n - 1 {
        lower[i] = dx[i];
        diag[i] = 2.0 * (dx[i - 1] + dx[i]);
        upper[i] = dx[i - 1];
        rhs[i] = 3.0 * (dx[i] * d[i - 1] + dx[i - 1] * d[i]);
    }
    let w = x[2] - x[0];
    diag[0] = dx[1];
    upper[0] = w;
    rhs[0] = ((dx[0] + 2.0 * w) * dx[1] * d[0] + dx[0] * dx[0] * d[1]) / w;
    let w = x[n - 1] - x[n - 3];
    diag[n - 1] = dx[n - 3];
    lower[n - 1] = w;
    rhs[n - 1] =
        (dx[n - 2] * dx[n - 2] * d[n - 3] + (2.0 * w + dx[n - 2]) * dx[n - 3] * d[n - 2]) / w;
    tridiagonal_solve(lower, diag, upper, rhs)
}

/// Gaussian elimination with partial pivoting on a tridiagonal system (LAPACK's dgtsv):
/// row swaps fill one extra superdiagonal.
fn tridiagonal_solve(
    mut dl: Vec<f64>,
    mut d: Vec<f64>,
    mut du: Vec<f64>,
    mut b: Vec<f64>,
) -> Vec<f64> {
    let n = d.len();
    let mut du2 = vec![0.0; n];
    // dl[i] is the entry (i, i - 1); shift to the LAPACK layout dl[i] = (i + 1, i).
    dl.remove(0);
    dl.push(0.0);
    for i in 0..n - 1 {
        if d[i].abs() >= dl[i].abs() {
            // No swap.
            if d[i] == 0.0 {
                return vec![f64::NAN; n];
            }
            let f = dl[i] / d[i];
            d[i + 1] -= f * du[i];
            b[i + 1] -= f * b[i];
            dl[i] = 0.0;
        } else {
            // Swap rows i and i + 1.
            let f = d[i] / dl[i];
            d[i] = dl[i];
            let tmp = d[i + 1];
            d[i + 1] = du[i] - f * tmp;
            if i + 1 < n - 1 {
                du2[i] = du[i + 1];
                du[i + 1] = -f * du2[i];
            }
            du[i] = tmp;
            b.swap(i, i + 1);
            b[i + 1] -= f * b[i];
        }
    }
    let mut x = b;
    x[n - 1] /= d[n - 1];
    if n > 1 {
        x[n - 2] = (x[n - 2] - du[n - 2] * x[n - 1]) / d[n - 2];
    }
    for i in (0..n.saturating_sub(2)).rev() {
        x[i] = (x[i] - du[i] * x[i + 1] - du2[i] * x[i + 2]) / d[i];
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A not-a-knot spline reproduces cubics exactly (its four conditions per interval
    /// and the end conditions are all satisfied by the cubic itself).
    #[test]
    fn spline_reproduces_cubics() {
        let s = [0.0, 0.013, 0.04, 0.05, 0.081, 0.1];
        let f = |x: f64| 3.0 - 20.0 * x + 500.0 * x * x - 4000.0 * x * x * x;
        let y: Vec<[f64; 6]> = s
            .iter()
            .map(|&x| [f(x), 0.0, 1.0, 0.0, 0.0, 2.0 * f(x)])
            .collect();
        let sp = ReferenceSpline::new(&s, y);
        for k in 0..=100 {
            let x = 0.1 * k as f64 / 100.0;
            let w = sp.eval(x);
            assert!((w[0] - f(x)).abs() < 1e-12, "{x}: {} vs {}", w[0], f(x));
            assert!((w[2] - 1.0).abs() < 1e-14);
            assert!((w[5] - 2.0 * f(x)).abs() < 2e-12);
        }
    }

    /// Two points: a line; three: the parabola through them.
    #[test]
    fn short_tables() {
        let sp = ReferenceSpline::new(&[0.0, 2.0], vec![[1.0; 6], [5.0; 6]]);
        assert!((sp.eval(0.5)[3] - 2.0).abs() < 1e-15);
        let p = |x: f64| 1.0 + x - 3.0 * x * x;
        let s = [0.0, 0.3, 1.0];
        let sp = ReferenceSpline::new(&s, s.iter().map(|&x| [p(x); 6]).collect());
        for x in [0.1, 0.5, 0.77] {
            assert!((sp.eval(x)[1] - p(x)).abs() < 1e-14);
        }
    }

    /// Values from scipy.interpolate.CubicSpline(s, y) (bc_type "not-a-knot", scipy 1.17.1)
    /// for data that no cubic fits: s = [0, 1, 2.5, 3, 4.2], y = [0, 2, -1, 0.5, 3].
    #[test]
    fn matches_scipy_not_a_knot() {
        let s = [0.0, 1.0, 2.5, 3.0, 4.2];
        let y = [0.0, 2.0, -1.0, 0.5, 3.0];
        let sp = ReferenceSpline::new(&s, y.iter().map(|&v| [v; 6]).collect());
        for (x, want) in SCIPY {
            assert!(
                (sp.eval(x)[0] - want).abs() < 1e-12,
                "{x}: {}",
                sp.eval(x)[0]
            );
        }
    }

    const SCIPY: [(f64, f64); 4] = [
        (0.5, 2.162_867_121_097_366_2),
        (1.7, 0.043_501_001_430_615_305),
        (2.8, -0.260_165_614_743_752_2),
        (3.9, 3.386_921_736_935_118_3),
    ];
}
