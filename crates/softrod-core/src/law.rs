//! Nonlinear axial laws: the inverse maps from the material axial force to the strains.
//!
//! The linear law needs no inversion (v = K_se^-1 n_m + e3); the table law is explicit. The
//! Ogden law is implicit in v. Rather than solving n_m(v) = n at every right-hand-side
//! evaluation (a Newton loop of transcendental functions), the integrator carries the stretch
//! lambda and lambda^alpha as two extra states: at the start of an Ogden section they are set
//! by solving the law once ([`ogden_inverse`]), then linearised so dual numbers carry exact
//! first derivatives (at the solution v* of n_m(v) = n, v = v* + K(v*)^-1 (n - n(v*)) has the
//! value v* and the derivative K^-1 dn, which is dv/dn by the implicit function theorem);
//! along the section they follow d lambda/ds = (v^T K^-1 / lambda) dn_m/ds and
//! d(lambda^alpha)/ds = alpha lambda^(alpha - 1) d lambda/ds. Every evaluation is then
//! algebraic ([`ogden_from_stretch`]). The law holds exactly at the section start and along
//! it to the integrator's O(h^4) (tested as a convergence order).
//!
//! * Ogden (paper 002 eqs. 14-16): W = W1(lambda) + (k_s/2)(v1^2 + v2^2) with lambda = |v|,
//!   W1 = (2/3)(k_e/alpha^2)(lambda^alpha + 2 lambda^(-alpha/2) - 3). Its contact force is
//!   n_m = dW/dv = k_s (v1, v2, 0) + g(lambda) v with g = W1'(lambda)/lambda. W1''(1) = k_e,
//!   so near lambda = 1 it is the linear law.
//! * Table (paper 004 Sec. 3.1): n_m3 = EA(F) (v3 - 1) with F = n_m3, EA(F) from a monotone
//!   cubic (Fritsch-Carlson) interpolation of a table, constant beyond the table's ends.
//!   Explicit: v3 = 1 + F / EA(F).

use crate::interp::pchip_slopes;
use crate::jet::{Coeff, RodScalar, StateScalar};

/// W1 of paper 002 eq. 16 at stretch `lam`.
pub fn ogden_energy(k_e: f64, alpha: f64, lam: f64) -> f64 {
    let l = lam.ln();
    // lambda^a + 2 lambda^(-a/2) - 3 = expm1(a l) + 2 expm1(-a l / 2): no cancellation.
    2.0 / 3.0 * k_e / (alpha * alpha) * ((alpha * l).exp_m1() + 2.0 * (-0.5 * alpha * l).exp_m1())
}

/// W1'(lambda) and W1''(lambda).
#[inline]
pub fn ogden_derivatives(k_e: f64, alpha: f64, lam: f64) -> (f64, f64) {
    // a = lambda^alpha - 1 and b = lambda^(-alpha/2) - 1 from one expm1 and one sqrt,
    // both free of cancellation near lambda = 1: b = -a / (s (1 + s)), s = sqrt(1 + a).
    let a = (alpha * lam.ln()).exp_m1();
    let s = (1.0 + a).sqrt();
    let b = -a / (s * (1.0 + s));
    let c = 2.0 / 3.0 * k_e / alpha;
    let d1 = c * (a - b) / lam;
    // d/dlam [(lambda^a - lambda^(-a/2)) / lam]
    //   = (alpha lambda^a + (alpha/2) lambda^(-a/2) - (lambda^a - lambda^(-a/2))) / lam^2
    let d2 = c * (alpha * (1.0 + a) + 0.5 * alpha * (1.0 + b) - (a - b)) / (lam * lam);
    (d1, d2)
}

/// Contact force n_m(v) of the Ogden law with shear stiffness k_s (body frame).
pub fn ogden_force(k_e: f64, alpha: f64, k_s: f64, v: &[f64; 3]) -> [f64; 3] {
    let lam = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let g = ogden_derivatives(k_e, alpha, lam).0 / lam;
    [(k_s + g) * v[0], (k_s + g) * v[1], g * v[2]]
}

/// The value-level inverse of the Ogden law: v with n_m(v) = n, or None.
///
/// Reduced to one equation in lambda: v_perp = n_perp / (k_s + g), v3 = sqrt(lambda^2 -
/// |v_perp|^2), F(lambda) = g v3 - n3 = W1'(lambda) sqrt(1 - w) - n3 with
/// w = |n_perp|^2 / ((k_s + g)^2 lambda^2). Newton from `guess` (the previous solution on
/// the integration path, or the linear law), kept inside a bracket of the root (bisection
/// or doubling when a step leaves it). Newton converges quadratically, so once a step is
/// below 1e-9 lambda the error after it is ~1e-18 lambda and the loop stops without
/// another evaluation.
pub fn ogden_inverse(k_e: f64, alpha: f64, k_s: f64, n: &[f64; 3], guess: f64) -> Option<[f64; 3]> {
    let q = n[0] * n[0] + n[1] * n[1];
    let eval = |lam: f64| -> (f64, f64) {
        let (d1, d2) = ogden_derivatives(k_e, alpha, lam);
        if q == 0.0 {
            return (d1 - n[2], d2);
        }
        let g = d1 / lam;
        let s = k_s + g;
        let w = q / (s * s * lam * lam);
        let c = (1.0 - w).max(0.0).sqrt();
        let sp = (d2 - g) / lam;
        let wp = -2.0 * w * (sp / s + 1.0 / lam);
        (d1 * c - n[2], d2 * c - d1 * wp / (2.0 * c.max(1e-300)))
    };
    let (mut lo, mut hi) = (0.0, f64::INFINITY);
    let mut lam = if guess.is_finite() && guess > 0.0 {
        guess
    } else {
        (1.0 + n[2] / k_e).max(0.1)
    };
    for _ in 0..200 {
        let (f, df) = eval(lam);
        if !f.is_finite() {
            return None;
        }
        if f < 0.0 {
            lo = lam;
        } else {
            hi = lam;
        }
        let step = f / df;
        let mut next = lam - step;
        let newton_ok = df > 0.0 && next >= lo && next <= hi;
        if newton_ok && step.abs() <= 1e-9 * lam {
            lam = next;
            let g = ogden_derivatives(k_e, alpha, lam).0 / lam;
            let (v1, v2) = (n[0] / (k_s + g), n[1] / (k_s + g));
            let v3 = (lam * lam - v1 * v1 - v2 * v2).max(0.0).sqrt();
            return Some([v1, v2, v3]);
        }
        if !newton_ok {
            next = if hi.is_finite() {
                0.5 * (lo + hi)
            } else {
                2.0 * lam
            };
        }
        if hi.is_finite() && hi - lo <= 4.0 * f64::EPSILON * hi {
            return None; // bracket collapsed without a Newton-quality step
        }
        lam = next;
    }
    None
}

/// Solve K z = b for the Ogden tangent K = diag(k_s + g, k_s + g, g) + c v v^T (symmetric),
/// by Cramer's rule, in any scalar type.
#[inline(always)]
fn solve_tangent<D: RodScalar>(d12: D, d3: D, c: D, v: &[D; 3], b: &[D; 3]) -> [D; 3] {
    let k: [[D; 3]; 3] = std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let cv = c * v[i] * v[j];
            if i != j {
                cv
            } else if i < 2 {
                cv + d12
            } else {
                cv + d3
            }
        })
    });
    let det3 = |m: &dyn Fn(usize, usize) -> D| -> D {
        m(0, 0) * (m(1, 1) * m(2, 2) - m(1, 2) * m(2, 1))
            - m(0, 1) * (m(1, 0) * m(2, 2) - m(1, 2) * m(2, 0))
            + m(0, 2) * (m(1, 0) * m(2, 1) - m(1, 1) * m(2, 0))
    };
    let inv_det = det3(&|r, q| k[r][q]).recip();
    // Cramer: column j of K replaced by b.
    std::array::from_fn(|j| det3(&|r, q| if q == j { b[r] } else { k[r][q] }) * inv_det)
}

/// Ogden strains from the carried stretch `lam` and `lam_alpha` = lambda^alpha, for the
/// material force `n` (body frame): v, and the gradient d lambda / d n_m = K^-1 v / lambda
/// that drives the stretch along the rod. Algebraic (square roots only), any scalar type
/// for the state (`D`) and for the law's parameters (`P`).
#[inline(always)]
pub fn ogden_from_stretch<P: Coeff, D: StateScalar<P>>(
    k_e: P,
    alpha: P,
    k_s: P,
    lam: D,
    lam_alpha: D,
    n: &[D; 3],
) -> ([D; 3], [D; 3]) {
    let c0 = k_e * alpha.recip() * (2.0 / 3.0);
    let inv_lam = lam.recip();
    let b = lam_alpha.sqrt().recip(); // lambda^(-alpha/2)
    let p = lam_alpha - b; // lambda^a - lambda^(-a/2)
    let dp = (lam_alpha * alpha + b * (alpha * 0.5)) * inv_lam;
    let d1 = p * inv_lam * c0; // W1'
    let d2 = (dp - p * inv_lam) * inv_lam * c0; // W1''
    let g = d1 * inv_lam;
    let gp = (d2 - g) * inv_lam;
    let s_inv = (g + k_s).recip();
    let v1 = n[0] * s_inv;
    let v2 = n[1] * s_inv;
    let v3 = (lam * lam - v1 * v1 - v2 * v2).sqrt();
    let v = [v1, v2, v3];
    let z = solve_tangent(g + k_s, g, gp * inv_lam, &v, &v);
    (v, z.map(|x| x * inv_lam))
}

/// The Ogden contact force at the strain `v` (a value) with the parameters in scalar `P`:
/// the parameter derivatives of n_m at fixed strain.
pub(crate) fn ogden_force_with<P: Coeff>(k_e: P, alpha: P, k_s: P, v: &[f64; 3]) -> [P; 3] {
    let lam = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let l = P::from(lam.ln());
    let a = (alpha * l).exp(); // lambda^alpha
    let b = (alpha * l * -0.5).exp(); // lambda^(-alpha/2)
                                      // g = W1'(lambda) / lambda = (2/3)(k_e/alpha)(a - b) / lambda^2
    let g = k_e * alpha.recip() * (a - b) * (2.0 / (3.0 * lam * lam));
    [(k_s + g) * v[0], (k_s + g) * v[1], g * v[2]]
}

/// Initial (lambda, lambda^alpha) of an Ogden section for the material force `n` (body
/// frame): the value-level inverse, linearised in the scalar types (exact first
/// derivatives, see the module docs). With dual parameters the linearisation is the
/// implicit function theorem on n_m(v; theta) = n: dv = K^-1 (dn - d_theta n_m).
/// NaN when the law cannot be inverted.
pub fn ogden_initial_stretch<P: Coeff, D: StateScalar<P>>(
    k_e: P,
    alpha: P,
    k_s: P,
    n: &[D; 3],
) -> [D; 2] {
    let nv = n.map(|x| x.value());
    let (ke, al, ks) = (k_e.value(), alpha.value(), k_s.value());
    let Some(v) = ogden_inverse(ke, al, ks, &nv, f64::NAN) else {
        return [D::from(f64::NAN); 2];
    };
    let lam = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let la = lam.powf(al);
    let (_, grad) = ogden_from_stretch(ke, al, ks, lam, la, &nv);
    let nm = ogden_force_with(k_e, alpha, k_s, &v);
    // dn - d_theta n_m, both with zero value.
    let rhs: [D; 3] = std::array::from_fn(|i| (n[i] - nv[i]) - D::from(nm[i] - nm[i].value()));
    let dl = rhs[0] * grad[0] + rhs[1] * grad[1] + rhs[2] * grad[2];
    // d(lambda^alpha) = lambda^alpha (alpha / lambda d lambda + ln(lambda) d alpha)
    let dalpha = D::from(alpha - al);
    [
        dl + lam,
        dl * (al * la / lam) + dalpha * (la * lam.ln()) + la,
    ]
}

/// EA(F): a monotone cubic (Fritsch-Carlson PCHIP) through the table points, constant
/// beyond the ends. Between nodes the curve stays within its neighbours' range, so a
/// table of positive stiffnesses interpolates to positive stiffnesses.
#[derive(Debug, Clone, PartialEq)]
pub struct AxialTable {
    force: Vec<f64>,
    stiffness: Vec<f64>,
    slope: Vec<f64>,
}

impl AxialTable {
    /// Build from validated points (>= 2, strictly increasing forces).
    pub fn new(force: &[f64], stiffness: &[f64]) -> Self {
        let mut slope = vec![0.0; force.len()];
        pchip_slopes(force, stiffness, &mut slope);
        AxialTable {
            force: force.to_vec(),
            stiffness: stiffness.to_vec(),
            slope,
        }
    }

    /// The table's forces (knots), N.
    pub fn knots(&self) -> &[f64] {
        &self.force
    }

    /// EA at axial force `f` (any scalar type: exact derivative dEA/dF inside the table).
    #[inline]
    pub fn eval<D: RodScalar>(&self, f: D) -> D {
        let x = f.value();
        let n = self.force.len();
        if x <= self.force[0] {
            return D::from(self.stiffness[0]);
        }
        if x >= self.force[n - 1] {
            return D::from(self.stiffness[n - 1]);
        }
        let k = self.force.partition_point(|&fk| fk <= x) - 1;
        let h = self.force[k + 1] - self.force[k];
        let t = (f - self.force[k]) * (1.0 / h);
        let t2 = t * t;
        let t3 = t2 * t;
        let h00 = t3 * 2.0 - t2 * 3.0 + 1.0;
        let h10 = t3 - t2 * 2.0 + t;
        let h01 = t3 * (-2.0) + t2 * 3.0;
        let h11 = t3 - t2;
        h00 * self.stiffness[k]
            + h10 * (h * self.slope[k])
            + h01 * self.stiffness[k + 1]
            + h11 * (h * self.slope[k + 1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::jet::Jet;

    const K_E: f64 = 30.0; // N, of the order of paper 002's body (c_e E A_m)
    const K_S: f64 = 7.0; // N

    /// The contact force is the gradient of the energy (eq. 14), by central differences.
    #[test]
    fn ogden_force_is_energy_gradient() {
        for alpha in [0.61, 2.0, 8.89] {
            let energy = |v: &[f64; 3]| {
                let lam = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                ogden_energy(K_E, alpha, lam) + 0.5 * K_S * (v[0] * v[0] + v[1] * v[1])
            };
            let v = [0.02, -0.015, 1.17];
            let n = ogden_force(K_E, alpha, K_S, &v);
            for i in 0..3 {
                let h = 1e-6; // central difference: error ~h^2 W''' ~ 1e-10 relative
                let (mut a, mut b) = (v, v);
                a[i] += h;
                b[i] -= h;
                let fd = (energy(&a) - energy(&b)) / (2.0 * h);
                assert!(
                    (fd - n[i]).abs() <= 1e-7 * (1.0 + n[i].abs()),
                    "alpha {alpha}, component {i}: {fd} vs {}",
                    n[i]
                );
            }
        }
    }

    /// Taylor limit: W1'(1) = 0, W1''(1) = k_e, so n3 = k_e (lambda - 1) + O((lambda-1)^2).
    #[test]
    fn ogden_reduces_to_linear_law() {
        for alpha in [0.61, 2.0, 8.89] {
            let (d1, d2) = ogden_derivatives(K_E, alpha, 1.0);
            assert!(d1.abs() < 1e-14 * K_E && (d2 - K_E).abs() < 1e-12 * K_E);
            let mut prev = f64::NAN;
            for eps in [1e-3, 5e-4, 2.5e-4] {
                let n3 = ogden_derivatives(K_E, alpha, 1.0 + eps).0;
                let rel = (n3 - K_E * eps).abs() / (K_E * eps);
                // The relative deviation halves with the strain (first order in eps).
                if prev.is_finite() {
                    assert!(
                        (rel / prev - 0.5).abs() < 0.02,
                        "alpha {alpha}: {rel} {prev}"
                    );
                }
                prev = rel;
            }
        }
    }

    #[test]
    fn ogden_inverse_round_trips() {
        for alpha in [0.61, 2.0, 8.89] {
            for v in [
                [0.0, 0.0, 1.0],
                [0.01, -0.02, 0.7],
                [0.003, 0.001, 1.25],
                [-0.05, 0.04, 1.6],
            ] {
                let n = ogden_force(K_E, alpha, K_S, &v);
                let w = ogden_inverse(K_E, alpha, K_S, &n, f64::NAN).expect("inverse");
                for i in 0..3 {
                    assert!((w[i] - v[i]).abs() < 1e-12, "alpha {alpha}: {w:?} vs {v:?}");
                }
            }
        }
    }

    /// The carried-stretch evaluation reproduces the inverse, and its stretch gradient and
    /// the linearised initial stretch match finite differences of the inverse.
    #[test]
    fn stretch_evaluation_matches_inverse() {
        let alpha = 8.89;
        let n = [0.4, -0.3, 5.0];
        let lam_of = |n: &[f64; 3]| {
            let v = ogden_inverse(K_E, alpha, K_S, n, f64::NAN).unwrap();
            (v, (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
        };
        let (v, lam) = lam_of(&n);
        let (w, grad) = ogden_from_stretch(K_E, alpha, K_S, lam, lam.powf(alpha), &n);
        for i in 0..3 {
            assert!((w[i] - v[i]).abs() < 1e-14, "{w:?} vs {v:?}");
        }
        let nd: [Jet<3>; 3] = std::array::from_fn(|i| Jet::variable(n[i], i));
        let init = ogden_initial_stretch(K_E, alpha, K_S, &nd);
        assert!((init[0].re - lam).abs() < 1e-15);
        assert!((init[1].re - lam.powf(alpha)).abs() < 1e-12);
        for j in 0..3 {
            // Central difference: truncation ~h^2 times the third derivative, ~1e-10.
            let h = 1e-5;
            let (mut a, mut b) = (n, n);
            a[j] += h;
            b[j] -= h;
            let fd = (lam_of(&a).1 - lam_of(&b).1) / (2.0 * h);
            assert!(
                (fd - grad[j]).abs() < 1e-8,
                "dlam/dn{j}: {fd} vs {}",
                grad[j]
            );
            assert!((fd - init[0].eps[j]).abs() < 1e-8);
        }
    }

    #[test]
    fn table_interpolates_monotonically_and_is_constant_outside() {
        let f = [0.0, 10.0, 20.0, 33.0];
        let ea = [250.0, 210.0, 190.0, 170.0];
        let t = AxialTable::new(&f, &ea);
        for (x, y) in f.iter().zip(&ea) {
            assert!((t.eval(*x) - y).abs() < 1e-12);
        }
        assert_eq!(t.eval(-5.0), 250.0);
        assert_eq!(t.eval(50.0), 170.0);
        let mut prev = f64::INFINITY;
        for k in 0..=330 {
            let y = t.eval(k as f64 * 0.1);
            assert!(y <= prev + 1e-12 && y > 0.0);
            prev = y;
        }
        // Exact derivative inside a segment.
        let x = 14.3;
        let d = t.eval(Jet::<1>::variable(x, 0)).eps[0];
        let fd = (t.eval(x + 1e-6) - t.eval(x - 1e-6)) / 2e-6;
        assert!((d - fd).abs() < 1e-6);
    }
}
