//! Tendons: routing in the cross-section and the constitutive law with tendon tensions
//! (docs/scope.md, "Tendons"; Rucker and Webster, "Statics and dynamics of continuum robots
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
    /// The offset of a straight tendon (constant distance and angle).
    fixed: Option<[f64; 2]>,
}

impl Route {
    pub fn new(t: &TendonSpec, length: f64) -> Self {
        let (distance, angle) = t.ends();
        let fixed = (distance[0] == distance[1] && angle[0] == angle[1]).then(|| {
            let (sn, cs) = angle[0].sin_cos();
            [distance[0] * cs, distance[0] * sn]
        });
        Route {
            channel: t.channel,
            distance,
            angle,
            length,
            fixed,
        }
    }

    /// Whether the offset is the same all along the section (a straight tendon).
    #[inline]
    pub fn is_fixed(&self) -> bool {
        self.fixed.is_some()
    }

    /// Largest distance from the centreline along the section, m.
    pub fn max_distance(&self) -> f64 {
        self.distance[0].max(self.distance[1])
    }

    /// Offset r = (x, y) in (d1, d2), m, and its derivative dr/ds at the local arc length s.
    #[inline]
    pub fn at(&self, s: f64) -> ([f64; 2], [f64; 2]) {
        if let Some(r) = self.fixed {
            return (r, [0.0; 2]);
        }
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
    // One division for the three components (the law's inner loop).
    let inv = 1.0 / len;
    ([q[0] * inv, q[1] * inv, q[2] * inv], len)
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

/// J_K = K + sum_i (tau_i / |q_i|) B_i^T (I - t_i t_i^T) B_i for the linear law, K =
/// diag(K_se) + K_bt: symmetric positive definite (the Hessian of the convex potential).
/// Written as B^T B - g g^T with g = B^T t = (t, r x t) (the tendon's load per unit
/// tension) and, B's columns being e1, e2, e3, y e3, -x e3, (-y, x, 0), B^T B = [[I, -[r]x],
/// [[r]x, |r|^2 I - r r^T]]: its upper triangle is summed, then mirrored.
pub(crate) fn stiffness_with_tendons(
    k_se: &[f64; 3],
    k_bt: &[[f64; 3]; 3],
    tangents: &[([f64; 3], f64)],
    points: &[TendonPoint],
) -> [[f64; 6]; 6] {
    // The tendons' part (upper triangle), added to K below.
    let mut j = [[0.0; 6]; 6];
    for ((t, len), p) in tangents.iter().zip(points) {
        let c = p.tension / len;
        if c == 0.0 {
            continue;
        }
        let (x, y) = (p.r[0], p.r[1]);
        let g = [t[0], t[1], t[2], y * t[2], -x * t[2], x * t[1] - y * t[0]];
        // B^T B, upper triangle: I, the -[r]x block and |r|^2 I - r r^T.
        let mut btb = [[0.0; 6]; 6];
        btb[0][0] = 1.0;
        btb[1][1] = 1.0;
        btb[2][2] = 1.0;
        btb[0][5] = -y;
        btb[1][5] = x;
        btb[2][3] = y;
        btb[2][4] = -x;
        btb[3][3] = y * y;
        btb[3][4] = -x * y;
        btb[4][4] = x * x;
        btb[5][5] = x * x + y * y;
        for a in 0..6 {
            for b in a..6 {
                j[a][b] += c * (btb[a][b] - g[a] * g[b]);
            }
        }
    }
    for a in 0..6 {
        for b in 0..a {
            j[a][b] = j[b][a];
        }
    }
    for a in 0..3 {
        j[a][a] += k_se[a];
        for b in 0..3 {
            j[3 + a][3 + b] += k_bt[a][b];
        }
    }
    j
}

/// LDL^T factors of a symmetric positive definite 6 x 6 matrix.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Ldl6 {
    l: [[f64; 6]; 6],
    /// Reciprocal pivots 1 / d (a solve multiplies by them).
    d_inv: [f64; 6],
}

impl Ldl6 {
    /// None unless the matrix is positive definite (all pivots > 0 and finite).
    pub(crate) fn new(a: &[[f64; 6]; 6]) -> Option<Self> {
        let mut l = [[0.0; 6]; 6];
        let mut d = [0.0; 6];
        let mut d_inv = [0.0; 6];
        for j in 0..6 {
            let mut dj = a[j][j];
            for k in 0..j {
                dj -= l[j][k] * l[j][k] * d[k];
            }
            if !(dj > 0.0 && dj.is_finite()) {
                return None;
            }
            d[j] = dj;
            d_inv[j] = 1.0 / dj;
            l[j][j] = 1.0;
            for i in j + 1..6 {
                let mut v = a[i][j];
                for k in 0..j {
                    v -= l[i][k] * l[j][k] * d[k];
                }
                // One division per pivot, not per entry.
                l[i][j] = v * d_inv[j];
            }
        }
        Some(Ldl6 { l, d_inv })
    }

    /// Solve A x = b for a right-hand side in any scalar (f64 factors).
    #[inline]
    pub(crate) fn solve<D: crate::jet::RodScalar>(&self, b: &[D; 6]) -> [D; 6] {
        let mut x = *b;
        for i in 0..6 {
            for k in 0..i {
                x[i] -= x[k] * self.l[i][k];
            }
        }
        for i in 0..6 {
            x[i] = x[i] * self.d_inv[i];
        }
        for i in (0..6).rev() {
            for k in i + 1..6 {
                x[i] -= x[k] * self.l[k][i];
            }
        }
        x
    }
}

/// The tendons' force and moment (F_t, M_t) = sum tau_i B_i^T t_i in any scalar: the
/// tensions `taus` (one per point) in that scalar, the unit tangents t_i at the f64 strains
/// `w` (their dependence on the strains is carried by the Jacobian of [`solve_implicit`]).
#[inline]
pub(crate) fn load_with<D: crate::jet::RodScalar>(
    taus: impl Iterator<Item = D>,
    points: &[TendonPoint],
    w: &[f64; 6],
) -> [D; 6] {
    let zero = D::from(0.0);
    let mut ft = [zero; 6];
    for (tau, p) in taus.zip(points) {
        let (t, _) = tangent(w, p);
        let (x, y) = (p.r[0], p.r[1]);
        ft[0] += tau * t[0];
        ft[1] += tau * t[1];
        ft[2] += tau * t[2];
        ft[3] += tau * (y * t[2]);
        ft[4] -= tau * (x * t[2]);
        ft[5] += tau * (x * t[1] - y * t[0]);
    }
    ft
}

/// Newton's method in f64 on the implicit tendon law R(w) = w - S(F_t(w)) = 0, where
/// `law(ft)` gives the strains S of the section's law without tendons from the body-frame
/// force and moment less `ft` = (F_t, M_t), and `law_jacobian(ft)` its exact derivative S'
/// with respect to that force and moment. The Jacobian is J = I + S' dT/dw
/// ([`load_jacobian`]); steps are backtracked on the residual (for the linear law R is the
/// gradient of a strictly convex function up to a positive definite factor, so a short
/// enough Newton step always reduces it). Starts from `start`, else from straight tendons
/// (t = e3). `rho` scales curvatures to strains in the convergence test (the section's
/// outermost fibre radius); `plain` (f64 results only) accepts one step earlier, where the
/// next step's size is below round-off. Returns the strains and J at them (for the
/// implicit-function step of dual parts, [`implicit_step`]), None if Newton fails.
/// Shared by the statics (`crate::ode`) and the collocation of dynamics
/// (`crate::collocation`, where S is the Kelvin-Voigt law of a time step).
pub(crate) fn solve_implicit(
    points: &[TendonPoint],
    tangents: &mut Vec<([f64; 3], f64)>,
    start: Option<[f64; 6]>,
    rho: f64,
    plain: bool,
    law: impl Fn(&[f64; 6]) -> [f64; 6],
    law_jacobian: impl Fn(&[f64; 6]) -> Mat6,
) -> Option<([f64; 6], Mat6)> {
    let size = |d: &[f64; 6]| -> f64 {
        let mut m: f64 = 0.0;
        for k in 0..6 {
            let x = if k < 3 { d[k] } else { rho * d[k] };
            m = if x.is_nan() { f64::NAN } else { m.max(x.abs()) };
        }
        m
    };
    let residual = |w: &[f64; 6], tangents: &mut Vec<([f64; 3], f64)>| -> [f64; 6] {
        tangents.clear();
        tangents.extend(points.iter().map(|p| tangent(w, p)));
        let wn = law(&load(tangents, points));
        std::array::from_fn(|k| w[k] - wn[k])
    };
    let mut w = match start {
        Some(w) => w,
        None => {
            tangents.clear();
            tangents.extend(points.iter().map(|_| ([0.0, 0.0, 1.0], 1.0)));
            law(&load(tangents, points))
        }
    };
    let mut r = residual(&w, tangents);
    let mut rn = size(&r);
    // Newton converges quadratically: a step of 1e-8 leaves ~1e-16.
    const TOL: f64 = 1e-13;
    for _ in 0..60 {
        if !rn.is_finite() {
            break;
        }
        // J = I + S' dT/dw at w.
        let dt = load_jacobian(tangents, points);
        let ft = load(tangents, points);
        let sp = law_jacobian(&ft);
        let jac = Mat6::identity() + sp * dt;
        let step = jac.lu().solve(&(-Vec6::from_column_slice(&r)))?;
        let d: [f64; 6] = std::array::from_fn(|k| step[k]);
        let dn = size(&d);
        if dn <= TOL || (plain && dn * dn <= 1e-2 * TOL) {
            return Some((std::array::from_fn(|k| w[k] + d[k]), jac));
        }
        let mut alpha = 1.0;
        loop {
            let wt: [f64; 6] = std::array::from_fn(|k| w[k] + alpha * d[k]);
            let rt = residual(&wt, tangents);
            let rtn = size(&rt);
            if rtn < rn || alpha < 1e-6 {
                w = wt;
                r = rt;
                rn = rtn;
                break;
            }
            alpha *= 0.5;
        }
    }
    None
}

/// Exact first derivatives of the implicit law's solution by the implicit function
/// theorem: w_D = w* - J^-1 R_D(w*) with R_D = w* - `wd`, where `wd` is the law without
/// tendons evaluated in the dual scalar at the force and moment less the tendons' load at
/// w* ([`load_with`]). None if J is singular.
pub(crate) fn implicit_step<D: crate::jet::RodScalar>(
    ws: &[f64; 6],
    jac: &Mat6,
    wd: &[D; 6],
) -> Option<[D; 6]> {
    let inv = jac.try_inverse()?;
    let rd: [D; 6] = std::array::from_fn(|k| D::from(0.0) + ws[k] - wd[k]);
    Some(std::array::from_fn(|i| {
        let mut acc = D::from(ws[i]);
        for k in 0..6 {
            acc -= rd[k] * inv[(i, k)];
        }
        acc
    }))
}

/// The tendons' stored energy per unit length at strains w: sum tau_i (|q_i(w)| - |q_i0|),
/// the work of the constant tensions on the tendons' extension relative to the straight
/// rod (q_i0 = e3 + r_i'). Its gradient in w is (F_t, M_t), so with the elastic energy it
/// is the potential whose gradient is the total internal force and moment (the dynamics'
/// energy books).
pub(crate) fn energy(w: &[f64; 6], points: &[TendonPoint]) -> f64 {
    let straight = [0.0, 0.0, 1.0, 0.0, 0.0, 0.0];
    points
        .iter()
        .map(|p| p.tension * (tangent(w, p).1 - tangent(&straight, p).1))
        .sum()
}
