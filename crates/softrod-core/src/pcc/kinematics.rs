//! Constant-curvature kinematics of one segment (paper 003, eqs. 1-4), written in the regular
//! bending-vector coordinates (L, theta_x, theta_y) = (L, theta cos phi, theta sin phi).
//!
//! The paper's (L, theta, phi) are singular at theta = 0 (phi is undefined there and the
//! phi row of the mass matrix vanishes). Every entry of eq. 1 is a polynomial in
//! theta_x, theta_y times one of the two even functions
//!   f1(t) = sin(x)/x,  f2(t) = (1 - cos x)/x^2,  t = x^2 = theta_x^2 + theta_y^2,
//! which are entire in t: their Taylor series (the series of eq. 3, divided by theta) are
//! used below `SERIES_SWITCH`, the closed forms above it. The code is generic over the
//! scalar, so dual numbers give exact derivatives of any order.

pub use crate::jet::Real;

/// Below t = theta^2 = 0.25 (|theta| < 0.5 rad) the series are used.
pub const SERIES_SWITCH: f64 = 0.25;
/// Terms kept: the first omitted term of f1 is t^10/21! < 0.25^10 / 5.1e19 = 1.9e-26, far
/// below round-off, and so are its derivatives (each t-derivative loses one power of t but
/// keeps the factorial).
pub const SERIES_TERMS: usize = 10;

fn factorial(n: usize) -> f64 {
    (1..=n).map(|k| k as f64).product()
}

const fn factorial_c(n: usize) -> f64 {
    let mut acc = 1.0;
    let mut k = 1;
    while k <= n {
        acc *= k as f64;
        k += 1;
    }
    acc
}

/// Table of (-1)^n C(n, k) / (2n + offset)!: row k holds the coefficients of the k-th
/// Taylor coefficient f^(k)(t0)/k! as a polynomial in t0 (computed once, at compile time,
/// with the same operations as a run-time evaluation would use).
const fn taylor_table(offset: usize) -> [[f64; SERIES_TERMS]; SERIES_TERMS] {
    let mut tab = [[0.0; SERIES_TERMS]; SERIES_TERMS];
    let mut k = 0;
    while k < SERIES_TERMS {
        let mut n = k;
        while n < SERIES_TERMS {
            let mut binom = 1.0;
            let mut j = n - k + 1;
            while j <= n {
                binom *= j as f64;
                j += 1;
            }
            binom /= factorial_c(k);
            let sign = if n % 2 == 0 { 1.0 } else { -1.0 };
            tab[k][n] = sign * binom / factorial_c(2 * n + offset);
            n += 1;
        }
        k += 1;
    }
    tab
}

const TAYLOR: [[[f64; SERIES_TERMS]; SERIES_TERMS]; 2] = [taylor_table(1), taylor_table(2)];

/// Horner evaluation of sum_n c_n (-t)^n with c_n = 1/(2n + offset)!.
fn alternating_series<S: Real>(t: S, offset: usize) -> S {
    let mut acc = S::from(1.0 / factorial(2 * (SERIES_TERMS - 1) + offset));
    for n in (0..SERIES_TERMS - 1).rev() {
        acc = acc * (-t) + 1.0 / factorial(2 * n + offset);
    }
    acc
}

/// The series at a dual argument t = t0 + h, evaluated as its Taylor polynomial in h: h has
/// no real part, so h^(NDERIV + 1) = 0 and the polynomial of degree NDERIV is exact for the
/// dual type. Its coefficients f^(k)(t0)/k! are plain numbers (from the table `TAYLOR`), so
/// this costs NDERIV dual products instead of the SERIES_TERMS of Horner's rule on duals.
fn alternating_series_taylor<S: Real>(t: S, offset: usize) -> S {
    let t0 = t.re();
    let order = S::NDERIV;
    if order == 0 {
        return S::from(alternating_series(t0, offset));
    }
    let tab = &TAYLOR[offset - 1];
    // coefficient k: sum_{n >= k} c_n (-1)^n C(n, k) t0^(n - k)
    let coef = |k: usize| -> f64 {
        if k >= SERIES_TERMS {
            return 0.0;
        }
        let mut acc = 0.0;
        for n in (k..SERIES_TERMS).rev() {
            acc = acc * t0 + tab[k][n];
        }
        acc
    };
    let h = t - S::from(t0);
    let mut acc = S::from(coef(order));
    for k in (0..order).rev() {
        acc = acc * h + coef(k);
    }
    acc
}

/// f1(t) = sin(x)/x with t = x^2 (paper 003's B = sin(theta)/theta).
pub fn sinc_t<S: Real>(t: S) -> S {
    if t.re() < SERIES_SWITCH {
        alternating_series_taylor(t, 1)
    } else {
        let x = t.sqrt();
        x.sin() / x
    }
}

/// f2(t) = (1 - cos x)/x^2 with t = x^2 (paper 003's A = (1 - cos theta)/theta = theta f2).
pub fn cosc_t<S: Real>(t: S) -> S {
    if t.re() < SERIES_SWITCH {
        alternating_series_taylor(t, 2)
    } else {
        let x = t.sqrt();
        (S::from(1.0) - x.cos()) / t
    }
}

/// Closed forms (for tests): sin(x)/x and (1 - cos x)/x^2, singular at x = 0.
pub fn sinc_closed<S: Real>(t: S) -> S {
    let x = t.sqrt();
    x.sin() / x
}
pub fn cosc_closed<S: Real>(t: S) -> S {
    let x = t.sqrt();
    (S::from(1.0) - x.cos()) / t
}

/// A pose: position and rotation (rows of [d1 d2 d3]).
pub type Pose<S> = ([S; 3], [[S; 3]; 3]);

/// Pose of the cross-section at material fraction `sigma` in [0, 1] of a segment with
/// y = (L, theta_x, theta_y), relative to the segment's base frame (paper 003 eq. 1 with
/// theta -> sigma theta, L -> sigma L; the curve bends towards (cos phi, sin phi, 0)).
/// R = exp(hat(w)) with w = sigma (-theta_y, theta_x, 0) (Rodrigues:
/// R = I + f1 hat(w) + f2 hat(w)^2); p = sigma L (sigma theta_x f2, sigma theta_y f2, f1).
pub fn segment_pose<S: Real>(y: &[S; 3], sigma: f64) -> Pose<S> {
    let (p, [tx, ty, t, f1, f2]) = segment_position_parts(y, sigma);
    let one = S::from(1.0);
    let r = [
        [one - f2 * tx * tx, -(f2 * tx * ty), f1 * tx],
        [-(f2 * tx * ty), one - f2 * ty * ty, f1 * ty],
        [-(f1 * tx), -(f1 * ty), one - f2 * t],
    ];
    (p, r)
}

/// Position part of `segment_pose` (about half its cost).
pub fn segment_position<S: Real>(y: &[S; 3], sigma: f64) -> [S; 3] {
    segment_position_parts(y, sigma).0
}

/// Position and the intermediate (sigma theta_x, sigma theta_y, t, f1, f2).
#[inline]
fn segment_position_parts<S: Real>(y: &[S; 3], sigma: f64) -> ([S; 3], [S; 5]) {
    let tx = y[1] * sigma;
    let ty = y[2] * sigma;
    let t = tx * tx + ty * ty;
    let f1 = sinc_t(t);
    let f2 = cosc_t(t);
    let ls = y[0] * sigma;
    let lf2 = ls * f2;
    ([lf2 * tx, lf2 * ty, ls * f1], [tx, ty, t, f1, f2])
}

/// Paper 003's (L, theta, phi) from the bending vector: theta >= 0, phi in (-pi, pi]
/// (phi = 0 where theta = 0, where it is undefined).
pub fn to_paper(y: &[f64; 3]) -> [f64; 3] {
    let theta = y[1].hypot(y[2]);
    let phi = if theta > 0.0 { y[2].atan2(y[1]) } else { 0.0 };
    [y[0], theta, phi]
}

/// Rates (L_t, theta_t, phi_t) from the bending vector and its rate; phi_t = 0 at theta = 0.
pub fn rates_to_paper(y: &[f64; 3], yd: &[f64; 3]) -> [f64; 3] {
    let t2 = y[1] * y[1] + y[2] * y[2];
    if t2 > 0.0 {
        let theta = t2.sqrt();
        [
            yd[0],
            (y[1] * yd[1] + y[2] * yd[2]) / theta,
            (y[1] * yd[2] - y[2] * yd[1]) / t2,
        ]
    } else {
        [yd[0], yd[1].hypot(yd[2]), 0.0]
    }
}

/// Inverse of `to_paper` / `rates_to_paper`: regular for every (theta, phi), theta may be
/// negative (bending towards phi + pi).
pub fn from_paper(q: &[f64; 3], qd: &[f64; 3]) -> ([f64; 3], [f64; 3]) {
    let (s, c) = q[2].sin_cos();
    (
        [q[0], q[1] * c, q[1] * s],
        [
            qd[0],
            qd[1] * c - q[1] * s * qd[2],
            qd[1] * s + q[1] * c * qd[2],
        ],
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_dual::Dual64;

    #[test]
    fn taylor_form_equals_horner_on_nested_duals() {
        // Same polynomial, evaluated two ways: agreement to round-off in every part of a
        // second-order dual over a gradient (the PCC residual's scalar type).
        use num_dual::{Dual2, DualSVec};
        type K = Dual2<DualSVec<f64, 2>>;
        for &t0 in &[0.0, 1e-3, 0.1, 0.2449] {
            let inner = |v: f64, i: usize| DualSVec::<f64, 2>::from_re(v).derivative(i);
            let t = K::new(inner(t0, 0), inner(0.7, 1), inner(-0.3, 0));
            for off in [1, 2] {
                let (a, b) = (
                    alternating_series_taylor(t, off),
                    alternating_series(t, off),
                );
                let parts = |k: &K| {
                    let g = |d: &DualSVec<f64, 2>| {
                        let e = d.eps.0.map_or([0.0; 2], |e| [e[0], e[1]]);
                        [d.re, e[0], e[1]]
                    };
                    [g(&k.re), g(&k.v1), g(&k.v2)].concat()
                };
                for (x, y) in parts(&a).iter().zip(parts(&b)) {
                    assert!(
                        (x - y).abs() <= 1e-15 * (1.0 + y.abs()),
                        "{x} vs {y} at {t0}"
                    );
                }
            }
        }
    }

    #[test]
    fn series_match_closed_form_at_switch() {
        // Both branches at the switch agree to round-off, with their derivatives: at
        // t = 0.25 the closed forms lose ~1 digit to cancellation (1 - cos x with x = 0.5),
        // their t-derivative ~2, so 1e-15 and 1e-14.
        let t = Dual64::from_re(SERIES_SWITCH).derivative();
        for (a, b) in [
            (alternating_series(t, 1), sinc_closed(t)),
            (alternating_series(t, 2), cosc_closed(t)),
        ] {
            assert!((a.re - b.re).abs() < 1e-15, "{} vs {}", a.re, b.re);
            assert!((a.eps - b.eps).abs() < 1e-14, "{} vs {}", a.eps, b.eps);
        }
    }
}
