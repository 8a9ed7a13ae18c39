//! Spatial discretisation of the rod by Gauss-Legendre collocation (two stages, fourth
//! order) with a block-banded Newton: the discretisation of dynamics at every time step and
//! of statics wherever single shooting is ill-conditioned (docs/model.md, "Collocation").
//!
//! Why not single shooting. At a time step the balance laws become an ODE in s whose
//! solutions grow like exp(s c0 / c) (c: axial or shear wave speed, c0 ~ 2/dt) and
//! exp(s (rho A c0^2 / EI)^(1/4)); for a soft rod at a small step the product over the
//! length exceeds 1e16 and shooting from the base cannot be solved. Multiple shooting with
//! an explicit integrator (RK4) inside segments does not cure it: RK4 amplifies the
//! decaying solutions too once the step exceeds 2.8 / k. Gauss collocation is A-stable in
//! s (stiff solutions stay bounded: amplification (1 + z/2 + z^2/12) / (1 - z/2 + z^2/12)
//! per interval), and with every node and stage unknown the Newton system is almost block
//! diagonal; solved by banded LU with partial pivoting it costs O(N) and stays well
//! conditioned for any dt and stiffness. Gauss collocation also makes the semi-discrete
//! rod an ODE in the stage values with an exactly conserved quadratic energy in the
//! linear limit (2-point Gauss quadrature integrates the energy flux's cubic polynomials
//! exactly), so the trapezoidal rule in time conserves energy and BDF-alpha only damps;
//! the former RK4 stage histories made the coupled scheme grow (issue 14).
//!
//! Unknowns at every node and stage point: the rotation as a quaternion Q (its norm is a
//! quadratic invariant of Q' = Q (0, u) / 2, which Gauss collocation conserves, so
//! R = R(Q) / |Q|^2 is a rotation to round-off), the total internal force n and moment m
//! (world frame), and the body-frame velocities q, w. The centreline r is not an unknown:
//! nothing depends on it, so it is recovered afterwards by the same quadrature
//! (r_i = r_j + h sum_k a_ik R_k v_k). Per interval [s_j, s_j + h] with stages
//! Y_1, Y_2 at s_j + c_i h:
//!   Y_i     = Y_j + h sum_k a_ik f(Y_k)   (stage equations),
//!   Y_{j+1} = Y_j + h sum_k b_k  f(Y_k)   (node equation),
//! with c = 1/2 -+ sqrt(3)/6, a = [[1/4, 1/4 - sqrt(3)/6], [1/4 + sqrt(3)/6, 1/4]],
//! b = (1/2, 1/2). Base: Q, q = w = 0 known, n(0), m(0) unknown (6); tip: 6 balance
//! equations. f is the Cosserat ODE of `crate::dynamics` (inertia and Kelvin-Voigt terms
//! through the time integrator's c0 and history terms; c0 = 0 with zero histories is
//! statics).
//!
//! Newton's linear systems: each interval's stage block (32 x 32) is factored and
//! condensed, leaving the node recurrences dY_{j+1} = T_j dY_j + t_j; these, the base
//! unknowns and the tip equations form a banded matrix solved by `crate::banded`. The
//! Jacobian of f at each stage is exact: one evaluation in `Jet<16>` over the stage's own
//! unknowns.

mod contact;

pub use contact::Contact;
use contact::{full_to_residual, full_to_unknown, residual_to_full, unknown_to_full};

use crate::banded::{simd_dispatch, BandedLu};

use crate::jet::{Coeff, Jet, RodScalar, StateScalar};
use crate::law::{ogden_derivatives, ogden_force, AxialTable};
use crate::marker::NODE_SNAP;
use crate::ode::{AxialCoeffs, Coeffs, TendonCoeff};
use crate::rod::{inverse3, Rod};
use nalgebra::SMatrix;
use std::sync::Arc;

/// Unknowns per point: quaternion (4), n (3), m (3), q (3), w (3).
pub const NY: usize = 16;
/// Fields kept per stage for the time integrator: v, u, q, w (body frame).
pub const NF: usize = 12;
pub(crate) const IQ: usize = 0;
pub(crate) const IN: usize = 4;
pub(crate) const IM: usize = 7;
const IV: usize = 10;
const IW: usize = 13;

const SQRT3_6: f64 = 0.288_675_134_594_812_9; // sqrt(3) / 6
/// Gauss-Legendre nodes on [0, 1].
pub const GAUSS_C: [f64; 2] = [0.5 - SQRT3_6, 0.5 + SQRT3_6];
const GAUSS_A: [[f64; 2]; 2] = [[0.25, 0.25 - SQRT3_6], [0.25 + SQRT3_6, 0.25]];
/// Gauss-Legendre weights on [0, 1].
pub const GAUSS_B: [f64; 2] = [0.5, 0.5];

type Mat16 = SMatrix<f64, 16, 16>;

/// One collocation interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Interval {
    pub section: usize,
    pub s0: f64,
    pub h: f64,
    /// Arc length of the interval's start from its section's start (where the section's
    /// tendon routing is evaluated), m.
    pub s_local: f64,
    /// Index in [`Grid::models`] of each stage's section model.
    pub model: [usize; 2],
}

impl Interval {
    /// Arc length of stage `i` from the section's start.
    #[inline(always)]
    pub fn stage_local(&self, i: usize) -> f64 {
        self.s_local + GAUSS_C[i] * self.h
    }
}

/// Where a section model of the grid holds: its section and the arc length from the
/// section's start at which its law, loads and inertia are evaluated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelSlot {
    pub section: usize,
    /// Local arc length, m: 0 for a uniform section's one model (its law holds all along),
    /// the stage point's for a varying section.
    pub s: f64,
}

/// The intervals of a rod: each section's `steps` (a rigid section is one interval, exact
/// there: its integrands are polynomials of degree <= 2 in s), and the section models the
/// stages read: one per uniform section, one per stage point of a varying section (taper,
/// reference shape tabulated along s), whose coefficients are evaluated once at the stage's
/// arc length (the grid is fixed) and enter the stage Jacobians as constants.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    pub intervals: Vec<Interval>,
    pub models: Vec<ModelSlot>,
}

impl Grid {
    pub fn new(rod: &Rod) -> Self {
        let mut intervals = Vec::new();
        let mut models = Vec::new();
        for (i, sec) in rod.sections.iter().enumerate() {
            let h = sec.length / sec.steps as f64;
            let varying = sec.is_varying();
            if !varying {
                models.push(ModelSlot { section: i, s: 0.0 });
            }
            for k in 0..sec.steps {
                let s_local = h * k as f64;
                let model = if varying {
                    std::array::from_fn(|st| {
                        models.push(ModelSlot {
                            section: i,
                            s: s_local + GAUSS_C[st] * h,
                        });
                        models.len() - 1
                    })
                } else {
                    [models.len() - 1; 2]
                };
                intervals.push(Interval {
                    section: i,
                    s0: sec.s_start + h * k as f64,
                    h,
                    s_local,
                    model,
                });
            }
        }
        Grid { intervals, models }
    }

    /// One model per slot of [`Grid::models`] from the sections' coefficients `coeffs`:
    /// a varying section's law, pressure terms, reference strains and line force at the
    /// slot's arc length ([`Coeffs::at`]), in any coefficient scalar; `make` turns them
    /// into the model (with the slot, for its inertia).
    pub fn build_models<C: Coeff>(
        &self,
        rod: &Rod,
        coeffs: &[Coeffs<C>],
        mut make: impl FnMut(&Coeffs<C>, usize, &ModelSlot) -> SectionModel<C>,
    ) -> Vec<SectionModel<C>> {
        self.models
            .iter()
            .enumerate()
            .map(|(k, slot)| {
                let c = coeffs[slot.section].at(&rod.sections[slot.section], slot.s);
                make(&c, k, slot)
            })
            .collect()
    }

    /// The grid point at reference arc length `s` in [0, L] (checked by the caller): node j
    /// itself where s lies within `NODE_SNAP` of an interval's length of it (so that s = L
    /// is the tip node exactly), else the interval holding s and the fraction of it.
    pub fn locate(&self, s: f64) -> GridPoint {
        let last = self.len() - 1;
        let j = self
            .intervals
            .iter()
            .position(|iv| s < iv.s0 + iv.h)
            .unwrap_or(last);
        let iv = &self.intervals[j];
        let theta = ((s - iv.s0) / iv.h).clamp(0.0, 1.0);
        if theta <= NODE_SNAP {
            GridPoint {
                node: j,
                theta: 0.0,
            }
        } else if theta >= 1.0 - NODE_SNAP {
            GridPoint {
                node: j + 1,
                theta: 0.0,
            }
        } else {
            GridPoint { node: j, theta }
        }
    }

    /// Number of intervals N (N + 1 nodes, 2N stage points).
    pub fn len(&self) -> usize {
        self.intervals.len()
    }

    pub fn is_empty(&self) -> bool {
        self.intervals.is_empty()
    }

    /// Length of the unknown (and residual) vector: 6 base unknowns, then per interval its
    /// two stages and its end node.
    pub fn unknowns(&self) -> usize {
        6 + 48 * self.len()
    }

    /// Arc length of stage `i` of interval `j`.
    pub fn stage_s(&self, j: usize, i: usize) -> f64 {
        let iv = &self.intervals[j];
        iv.s0 + GAUSS_C[i] * iv.h
    }

    /// Arc length of node j (0..=N).
    pub fn node_s(&self, j: usize) -> f64 {
        if j < self.len() {
            self.intervals[j].s0
        } else {
            let iv = self.intervals[j - 1];
            iv.s0 + iv.h
        }
    }
}

/// A point of the body on the grid: node `node` itself (`theta` = 0), or the fraction
/// `theta` in (0, 1) of interval `node` (from node `node` towards node `node` + 1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridPoint {
    pub node: usize,
    pub theta: f64,
}

/// Gauss-Legendre collocation's continuous extension on an interval: the collocation
/// polynomial u(s_j + theta h) = Y_j + h sum_k b_k(theta) f(Y_k), with b_k(theta) the
/// integrals from 0 to theta of the Lagrange polynomials on the stage points c_1, c_2
/// (b_k(c_i) = a_ik, b_k(1) = b_k = 1/2). Its error is O(h^3) inside an interval (the
/// collocation polynomial's uniform order s + 1 for s = 2 stages; the nodes' own are
/// O(h^4)), with the factor theta (2 theta - 1) (theta - 1) / 6 in front: it vanishes at
/// the nodes and, superconvergent, at the interval's midpoint.
pub fn dense_weights(theta: f64) -> [f64; 2] {
    // l_1 = (tau - c_2) / (c_1 - c_2), l_2 = (tau - c_1) / (c_2 - c_1), c_2 - c_1 = 1/sqrt(3).
    let sqrt3 = 2.0 * 3.0 * SQRT3_6;
    [
        sqrt3 * (GAUSS_C[1] * theta - 0.5 * theta * theta),
        sqrt3 * (0.5 * theta * theta - GAUSS_C[0] * theta),
    ]
}

/// The position r + R o of the point with offset `o` (cross-section frame) at fraction
/// `theta` of an interval of length `h`, from its start node's position `r0` and
/// quaternion `q0`, and its stages' quaternions and fields (v, u, q, w) by the
/// continuous extension ([`dense_weights`]): r = r0 + h sum_k b_k R(Q_k) v_k (the
/// quadrature that recovers the nodes' r) and Q = Q0 + h sum_k b_k Q_k (0, u_k) / 2,
/// whose rotation R(Q) / |Q|^2 ([`rotation`]) normalises it. In any scalar: the same
/// numbers in dual numbers are the point's exact derivatives.
pub fn dense_point<D: RodScalar>(
    r0: &[D; 3],
    q0: &[D; 4],
    stages: [(&[D; 4], &[D; NF]); 2],
    h: f64,
    theta: f64,
    o: &[f64; 3],
) -> [D; 3] {
    let b = dense_weights(theta).map(|x| x * h);
    let mut r = *r0;
    let mut q = *q0;
    for ((qk, f), bk) in stages.iter().zip(b) {
        let dr = mat_vec(&rotation(&qk[..]), &[f[0], f[1], f[2]]);
        let dq = quaternion_rate(&qk[..], &[f[3], f[4], f[5]]);
        for a in 0..3 {
            r[a] += dr[a] * bk;
        }
        for a in 0..4 {
            q[a] += dq[a] * bk;
        }
    }
    offset_point(&r, &rotation(&q), o)
}

/// r + R o.
#[inline(always)]
pub fn offset_point<D: RodScalar>(r: &[D; 3], rot: &[[D; 3]; 3], o: &[f64; 3]) -> [D; 3] {
    std::array::from_fn(|i| r[i] + rot[i][0] * o[0] + rot[i][1] * o[1] + rot[i][2] * o[2])
}

#[inline(always)]
fn stage_index(j: usize, i: usize) -> usize {
    6 + 48 * j + 16 * i
}

#[inline(always)]
fn node_index(j: usize) -> usize {
    // node j >= 1 is the end of interval j - 1
    6 + 48 * (j - 1) + 32
}

/// Axial and shear law of a section at one time step (coefficients in `C`: f64, or a dual
/// number carrying parameter derivatives for `crate::dynamics`' sensitivities).
#[derive(Debug, Clone, PartialEq)]
pub enum Axial<C = f64> {
    /// (K_se + c0 B_se) v = n_m + K_se v* - B_se v_h with n_m = R^T n + P e3 (diagonal).
    Linear { a_se: [C; 3], g_se: [C; 3] },
    /// Ogden (paper 002 eq. 16) with shear stiffness k_s: n_og(v) + B (c0 v + v_h) = n_m.
    Ogden { k_e: C, alpha: C, k_s: C },
    /// EA(F) table: elastic axial force F with v3 = 1 + F / (scale EA(F)), and
    /// F + b3 (c0 v3 + h3) = n_m3; shear linear.
    Table {
        table: Arc<AxialTable>,
        scale: C,
        a_s: [C; 2],
    },
}

/// The law, loads and inertia of one section at one time step (or a static solve).
#[derive(Debug, Clone, PartialEq)]
pub struct SectionModel<C = f64> {
    pub rigid: bool,
    pub axial: Axial<C>,
    /// Diagonal of K_se (N) and its damping B_se (N s); for a nonlinear law the
    /// small-strain stiffness.
    pub k_se: [C; 3],
    pub b_se: [C; 3],
    /// K_bt, its damping B_bt and (K_bt + c0 B_bt)^-1.
    pub k_bt: [[C; 3]; 3],
    pub b_bt: [[C; 3]; 3],
    a_bt: [[C; 3]; 3],
    /// K_bt u_p = K_bt u* + M_p (the pressure moment, body frame).
    pub g_bt: [C; 3],
    /// Pressure-shifted stress-free strains of the linear law.
    pub v_p: [C; 3],
    pub u_p: [C; 3],
    /// Reference strains v*, u* at this point (docs/laws.md: every law acts on the strain
    /// relative to the reference, v - v* + e3 and u - u*).
    pub v_star: [f64; 3],
    pub u_star: [f64; 3],
    /// Pressure force P = sum_k p_k A_k, N.
    pub p_force: C,
    /// Bending stiffness times the stretch v3 (paper 004 eq. 29).
    pub stretch_bending: bool,
    pub rho_a: C,
    pub rho_j: [C; 3],
    /// Line force (weight included) and moment, world frame.
    pub f: [C; 3],
    pub l: [C; 3],
    /// Follower line force and moment (body frame), N/m and N m/m; `follower` when either
    /// is not zero.
    pub f_body: [C; 3],
    pub l_body: [C; 3],
    pub follower: bool,
    /// The section's tendons under tension (`crate::tendon`): their tensions fold into the
    /// law, solved implicitly at every stage ([`SectionModel::strains`]).
    pub tendons: Vec<TendonCoeff<C>>,
    /// Radius scaling curvatures to strains in the tendon law's convergence test, m.
    pub tendon_radius: f64,
}

impl<C: Coeff> SectionModel<C> {
    /// From the static law's coefficients `c` (pressures, swelling and stiffness scale
    /// already applied), the section's line mass and rotary inertia, its damping (given
    /// diagonals, or B = tau K with K the law's small-strain stiffness) and the time
    /// integrator's c0 (0 for statics).
    pub fn new(
        c: &Coeffs<C>,
        rigid: bool,
        rho_a: C,
        rho_j: [C; 3],
        damping: Option<([f64; 3], [f64; 3])>,
        tau: C,
        c0: f64,
    ) -> Self {
        let zero = C::from(0.0);
        let z3 = [zero; 3];
        let z33 = [[zero; 3]; 3];
        let mut out = SectionModel {
            rigid,
            axial: Axial::Linear { a_se: z3, g_se: z3 },
            k_se: z3,
            b_se: z3,
            k_bt: z33,
            b_bt: z33,
            a_bt: z33,
            g_bt: z3,
            v_p: c.v_shift,
            u_p: c.u_shift,
            v_star: c.v_star,
            u_star: c.u_star,
            p_force: c.p_force,
            stretch_bending: c.stretch_bending,
            rho_a,
            rho_j,
            f: c.f,
            l: c.l,
            f_body: c.f_body,
            l_body: c.l_body,
            follower: c.follower,
            tendons: if rigid { Vec::new() } else { c.tendons.clone() },
            tendon_radius: c.tendon_radius,
        };
        if rigid {
            return out;
        }
        let mut k_se = c.c_se.map(|x| x.recip());
        // The small-strain stiffness of the nonlinear axial laws (their tangent at the
        // stress-free state): W1''(1) = k_e for Ogden, scale EA(0) for a table.
        match &c.axial {
            AxialCoeffs::Ogden { k_e, k_s, .. } => k_se = [*k_s, *k_s, *k_e],
            AxialCoeffs::Table { table, scale } => k_se[2] = *scale * table.eval(0.0),
            AxialCoeffs::Linear => {}
        }
        let nan = C::from(f64::NAN);
        let k_bt = inverse3(&c.c_bt).unwrap_or([[nan; 3]; 3]);
        let (b_se, b_bt) = match damping {
            Some((se, bt)) => (
                se.map(C::from),
                std::array::from_fn(|i| {
                    std::array::from_fn(|j| C::from(if i == j { bt[i] } else { 0.0 }))
                }),
            ),
            None => (k_se.map(|k| k * tau), k_bt.map(|row| row.map(|k| k * tau))),
        };
        let eff: [[C; 3]; 3] =
            std::array::from_fn(|i| std::array::from_fn(|j| k_bt[i][j] + b_bt[i][j] * c0));
        out.a_bt = inverse3(&eff).unwrap_or([[nan; 3]; 3]);
        out.g_bt = std::array::from_fn(|i| {
            k_bt[i][0] * c.u_shift[0] + k_bt[i][1] * c.u_shift[1] + k_bt[i][2] * c.u_shift[2]
        });
        out.axial = match &c.axial {
            AxialCoeffs::Linear => Axial::Linear {
                a_se: std::array::from_fn(|k| (k_se[k] + b_se[k] * c0).recip()),
                g_se: std::array::from_fn(|k| k_se[k] * c.v_shift[k]),
            },
            AxialCoeffs::Ogden { k_e, alpha, k_s } => Axial::Ogden {
                k_e: *k_e,
                alpha: *alpha,
                k_s: *k_s,
            },
            AxialCoeffs::Table { table, scale } => Axial::Table {
                table: table.clone(),
                scale: *scale,
                a_s: [
                    (k_se[0] + b_se[0] * c0).recip(),
                    (k_se[1] + b_se[1] * c0).recip(),
                ],
            },
        };
        out.k_se = k_se;
        out.b_se = b_se;
        out.k_bt = k_bt;
        out.b_bt = b_bt;
        out
    }

    /// Body-frame strains (v, u) from the body-frame total force and moment `nb`, `mb`,
    /// with the time integrator's c0 and this point's history terms `h` (v_h, u_h first).
    /// Nonlinear laws are solved in f64 and linearised in the state's scalar type
    /// (implicit function theorem), so dual numbers carry exact first derivatives in the
    /// state, and with dual coefficients (`crate::dynamics::sensitivity`) in the
    /// parameters and histories too.
    /// With tendons under tension the law is implicit (`crate::tendon`): the strains w
    /// solve w = S(nb - F_t(w), mb - M_t(w)) with S this damped law at the stage's local
    /// arc length `s` (where the routing is evaluated), by [`crate::tendon::solve_implicit`]
    /// (the statics' solver) in f64 with S' exact (a `Jet<6>` evaluation of S), and dual
    /// parts by the implicit function theorem.
    #[inline(always)]
    pub fn strains<D: StateScalar<C>>(
        &self,
        nb: &[D; 3],
        mb: &[D; 3],
        h: &[C; NF],
        c0: f64,
        s: f64,
    ) -> ([D; 3], [D; 3]) {
        if self.tendons.is_empty() {
            self.plain_strains(nb, mb, h, c0)
        } else {
            self.tendon_strains(nb, mb, h, c0, s)
        }
    }

    /// The law without tendons (see [`SectionModel::strains`]).
    #[inline(always)]
    fn plain_strains<D: StateScalar<C>>(
        &self,
        nb: &[D; 3],
        mb: &[D; 3],
        h: &[C; NF],
        c0: f64,
    ) -> ([D; 3], [D; 3]) {
        let zero = D::from(0.0);
        if self.rigid {
            return ([zero, zero, D::from(1.0)], [zero; 3]);
        }
        let b = &self.b_se;
        let v: [D; 3] = match &self.axial {
            Axial::Linear { a_se, g_se } => {
                std::array::from_fn(|k| (nb[k] + (g_se[k] - b[k] * h[k])) * a_se[k])
            }
            // The nonlinear laws act on w = v - v* + e3 (as the statics' `ode::law_strains`);
            // their damping on the rate of v: B (c0 v + h) = B (c0 w + h + c0 (v* - e3)).
            Axial::Table { table, scale, a_s } => {
                let nm3 = nb[2] + self.p_force;
                let dv = self.v_star[2] - 1.0;
                let hv = h[2] + C::from(c0 * dv);
                let w3 = table_stretch(table, *scale, b[2], c0, hv, nm3);
                let ks = &self.k_se;
                [
                    (nb[0] + (ks[0] * self.v_star[0] - b[0] * h[0])) * a_s[0],
                    (nb[1] + (ks[1] * self.v_star[1] - b[1] * h[1])) * a_s[1],
                    w3 + dv,
                ]
            }
            Axial::Ogden { k_e, alpha, k_s } => {
                let nm = [nb[0], nb[1], nb[2] + self.p_force];
                let dv = [self.v_star[0], self.v_star[1], self.v_star[2] - 1.0];
                let hv: [C; 3] = std::array::from_fn(|k| h[k] + C::from(c0 * dv[k]));
                let w = ogden_strain(*k_e, *alpha, *k_s, b, c0, &hv, &nm);
                std::array::from_fn(|k| w[k] + dv[k])
            }
        };
        let hu = [h[3], h[4], h[5]];
        let bb = &self.b_bt;
        let t: [C; 3] = std::array::from_fn(|i| {
            self.g_bt[i] - (bb[i][0] * hu[0] + bb[i][1] * hu[1] + bb[i][2] * hu[2])
        });
        let tm: [D; 3] = std::array::from_fn(|k| mb[k] + t[k]);
        let u: [D; 3] = if self.stretch_bending {
            // rho K_b (u_b - u*_b) + B_b (c0 u_b + u_h) = m_b + M_p (paper 004 eq. 29 with
            // the stretch relative to the reference, rho = v3 - v3* + 1, as the statics'
            // `ode::bending`), i.e. (rho K_b + c0 B_b) u_b = m_b + K_b u_p - B_b u_h
            // + (rho - 1) K_b u*_b; K_bt is block diagonal, so torsion stays linear.
            let kb = &self.k_bt;
            let rho = v[2] + D::from(1.0 - self.v_star[2]);
            let (us, mut tm) = (&self.u_star, tm);
            if us[0] != 0.0 || us[1] != 0.0 {
                for i in 0..2 {
                    let ku = kb[i][0] * us[0] + kb[i][1] * us[1];
                    tm[i] += (rho - D::from(1.0)) * ku;
                }
            }
            let a = rho * kb[0][0] + bb[0][0] * c0;
            let bm = rho * kb[0][1] + bb[0][1] * c0;
            let cm = rho * kb[1][0] + bb[1][0] * c0;
            let d = rho * kb[1][1] + bb[1][1] * c0;
            let inv = (a * d - bm * cm).recip();
            [
                (d * tm[0] - bm * tm[1]) * inv,
                (a * tm[1] - cm * tm[0]) * inv,
                tm[2] * (kb[2][2] + bb[2][2] * c0).recip(),
            ]
        } else {
            std::array::from_fn(|i| {
                tm[0] * self.a_bt[i][0] + tm[1] * self.a_bt[i][1] + tm[2] * self.a_bt[i][2]
            })
        };
        (v, u)
    }

    /// [`SectionModel::strains`] with tendons under tension.
    fn tendon_strains<D: StateScalar<C>>(
        &self,
        nb: &[D; 3],
        mb: &[D; 3],
        h: &[C; NF],
        c0: f64,
        s: f64,
    ) -> ([D; 3], [D; 3]) {
        use crate::tendon::{implicit_step, load_with, solve_implicit, Mat6, TendonPoint};
        let nan = D::from(f64::NAN);
        // The law's values in f64 (the model itself when its coefficients are f64).
        let owned;
        let mv: &SectionModel<f64> =
            match (self as &dyn std::any::Any).downcast_ref::<SectionModel<f64>>() {
                Some(m) => m,
                None => {
                    owned = self.value_model();
                    &owned
                }
            };
        let hf: [f64; NF] = h.map(|x| x.value());
        let nbf = nb.map(|x| x.value());
        let mbf = mb.map(|x| x.value());
        let points: Vec<TendonPoint> = self
            .tendons
            .iter()
            .map(|t| {
                let (r, dr) = t.route.at(s);
                TendonPoint {
                    tension: t.tension.value(),
                    r,
                    dr,
                }
            })
            .collect();
        let law = |ft: &[f64; 6]| -> [f64; 6] {
            let nm = [nbf[0] - ft[0], nbf[1] - ft[1], nbf[2] - ft[2]];
            let mm = [mbf[0] - ft[3], mbf[1] - ft[4], mbf[2] - ft[5]];
            let (v, u) = mv.plain_strains::<f64>(&nm, &mm, &hf, c0);
            [v[0], v[1], v[2], u[0], u[1], u[2]]
        };
        // S' exactly: the law in Jet<6> over the material force and moment.
        let law_jacobian = |ft: &[f64; 6]| -> Mat6 {
            let nm: [Jet<6>; 3] = std::array::from_fn(|k| Jet::variable(nbf[k] - ft[k], k));
            let mm: [Jet<6>; 3] = std::array::from_fn(|k| Jet::variable(mbf[k] - ft[3 + k], 3 + k));
            let (v, u) = mv.plain_strains::<Jet<6>>(&nm, &mm, &hf, c0);
            Mat6::from_fn(|r, c| if r < 3 { v[r].eps[c] } else { u[r - 3].eps[c] })
        };
        let plain = std::any::TypeId::of::<D>() == std::any::TypeId::of::<f64>();
        let mut tangents = Vec::with_capacity(points.len());
        let Some((ws, jac)) = solve_implicit(
            &points,
            &mut tangents,
            None,
            self.tendon_radius,
            plain,
            law,
            law_jacobian,
        ) else {
            return ([nan; 3], [nan; 3]);
        };
        if plain {
            return (
                [ws[0], ws[1], ws[2]].map(D::from),
                [ws[3], ws[4], ws[5]].map(D::from),
            );
        }
        let zero = D::from(0.0);
        let ft: [D; 6] = load_with(self.tendons.iter().map(|t| zero + t.tension), &points, &ws);
        let nm = [nb[0] - ft[0], nb[1] - ft[1], nb[2] - ft[2]];
        let mm = [mb[0] - ft[3], mb[1] - ft[4], mb[2] - ft[5]];
        let (v, u) = self.plain_strains(&nm, &mm, h, c0);
        match implicit_step(&ws, &jac, &[v[0], v[1], v[2], u[0], u[1], u[2]]) {
            Some(o) => ([o[0], o[1], o[2]], [o[3], o[4], o[5]]),
            None => ([nan; 3], [nan; 3]),
        }
    }

    /// The model's values (derivatives of dual coefficients dropped).
    pub fn value_model(&self) -> SectionModel<f64> {
        let v3 = |x: &[C; 3]| x.map(|c| c.value());
        let v33 = |x: &[[C; 3]; 3]| x.map(|r| r.map(|c| c.value()));
        SectionModel {
            rigid: self.rigid,
            axial: match &self.axial {
                Axial::Linear { a_se, g_se } => Axial::Linear {
                    a_se: v3(a_se),
                    g_se: v3(g_se),
                },
                Axial::Ogden { k_e, alpha, k_s } => Axial::Ogden {
                    k_e: k_e.value(),
                    alpha: alpha.value(),
                    k_s: k_s.value(),
                },
                Axial::Table { table, scale, a_s } => Axial::Table {
                    table: table.clone(),
                    scale: scale.value(),
                    a_s: a_s.map(|c| c.value()),
                },
            },
            k_se: v3(&self.k_se),
            b_se: v3(&self.b_se),
            k_bt: v33(&self.k_bt),
            b_bt: v33(&self.b_bt),
            a_bt: v33(&self.a_bt),
            g_bt: v3(&self.g_bt),
            v_p: v3(&self.v_p),
            u_p: v3(&self.u_p),
            v_star: self.v_star,
            u_star: self.u_star,
            p_force: self.p_force.value(),
            stretch_bending: self.stretch_bending,
            rho_a: self.rho_a.value(),
            rho_j: v3(&self.rho_j),
            f: v3(&self.f),
            l: v3(&self.l),
            f_body: v3(&self.f_body),
            l_body: v3(&self.l_body),
            follower: self.follower,
            tendons: self
                .tendons
                .iter()
                .map(|t| TendonCoeff {
                    tension: t.tension.value(),
                    route: t.route,
                })
                .collect(),
            tendon_radius: self.tendon_radius,
        }
    }
}

/// The table law with damping: solve F + b (c0 v3(F) + h) = n_m3 for the elastic axial
/// force F, v3(F) = 1 + F / (s EA(F)), in f64; exact first derivatives through the implicit
/// function theorem (d/dF of the left side is > 0 while v3 grows with F): in the state
/// through n_m3, and with dual coefficients in the parameters and histories through the
/// scale s, the damping b and the history h (the dynamics' parameter sensitivities).
#[inline(always)]
fn table_stretch<C: Coeff, D: StateScalar<C>>(
    table: &AxialTable,
    scale: C,
    damping: C,
    c0: f64,
    history: C,
    nm3: D,
) -> D {
    let target = nm3.value();
    let (s, b, h) = (scale.value(), damping.value(), history.value());
    let v3 = |f: f64| 1.0 + f / (s * table.eval(f));
    let dv3 = |f: f64| {
        let j = table.eval(Jet::<1>::variable(f, 0));
        (j.re - f * j.eps[0]) / (s * j.re * j.re)
    };
    let bc = b * c0;
    let mut f = target - b * (c0 + h);
    // phi sums terms up to this size: its round-off floor (relative 1e-13 leaves room for
    // a few ulps of each).
    let size = 1.0 + target.abs() + bc.abs() * 2.0 + (b * h).abs();
    let mut ok = false;
    for _ in 0..60 {
        let phi = f + bc * v3(f) + b * h - target;
        let dphi = 1.0 + bc * dv3(f);
        if !(phi.is_finite() && dphi.is_finite() && dphi > 0.0) {
            break;
        }
        f -= phi / dphi;
        if phi.abs() <= 1e-13 * size {
            ok = true;
            break;
        }
    }
    if !ok {
        return D::from(f64::NAN);
    }
    let dphi = 1.0 + bc * dv3(f);
    // dF = (dn_m3 - d_theta phi) / phi'(F): d_theta phi is the dual part of the left side
    // at the solution with the coefficients' dual parts (zero for f64 coefficients).
    let v3c = (scale * table.eval(f)).recip() * f + 1.0;
    let phi = damping * (v3c * c0 + history) + f;
    let fj = (nm3 - target + -(phi - phi.value())) * (1.0 / dphi) + f;
    (fj * (table.eval(fj) * scale).recip()) + 1.0
}

/// The Ogden law with damping B = diag(b): solve n_og(v) + B (c0 v + h) = n_m in f64 by
/// Newton from the linear law, then v = v* + (K_t + c0 B)^-1 (n_m - n_m* - d_theta r) in
/// the scalar type (exact first derivatives, by the implicit function theorem on
/// r(v) = n_og(v) + B (c0 v + h) - n_m = 0; d_theta r, the residual's dual part in the
/// coefficients k_e, alpha, k_s, B and the history h, is there only with dual
/// coefficients: the dynamics' parameter sensitivities). NaN when the law cannot be
/// inverted.
#[inline(always)]
fn ogden_strain<C: Coeff, D: StateScalar<C>>(
    k_e: C,
    alpha: C,
    k_s: C,
    damping: &[C; 3],
    c0: f64,
    history: &[C; 3],
    nm: &[D; 3],
) -> [D; 3] {
    let (law, damping_c, history_c) = ((k_e, alpha, k_s), damping, history);
    let (k_e, alpha, k_s) = (k_e.value(), alpha.value(), k_s.value());
    let b = &damping.map(|x| x.value());
    let h = &history.map(|x| x.value());
    let target = nm.map(|x| x.value());
    let k0 = [k_s, k_s, k_e];
    let mut v: [f64; 3] = std::array::from_fn(|k| {
        let shift = if k == 2 { k0[2] } else { 0.0 };
        (target[k] + shift - b[k] * h[k]) / (k0[k] + c0 * b[k])
    });
    let resid = |v: &[f64; 3]| -> [f64; 3] {
        let n = ogden_force(k_e, alpha, k_s, v);
        std::array::from_fn(|k| n[k] + b[k] * (c0 * v[k] + h[k]) - target[k])
    };
    let tangent = |v: &[f64; 3]| -> [[f64; 3]; 3] {
        let lam = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let (d1, d2) = ogden_derivatives(k_e, alpha, lam);
        let g = d1 / lam;
        let c = (d2 - g) / (lam * lam);
        std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                let diag = if i == j {
                    (if i < 2 { k_s + g } else { g }) + c0 * b[i]
                } else {
                    0.0
                };
                diag + c * v[i] * v[j]
            })
        })
    };
    // The residual sums terms up to this size (its round-off floor).
    let bmax = b.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    let hmax = h.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    let scale =
        1.0 + target.iter().fold(0.0f64, |a, x| a.max(x.abs())) + k_e + bmax * (2.0 * c0 + hmax);
    let mut r = resid(&v);
    let norm = |r: &[f64; 3]| r.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    let mut ok = false;
    for _ in 0..60 {
        if !(norm(&r).is_finite()) {
            break;
        }
        if norm(&r) <= 1e-13 * scale {
            ok = true;
            break;
        }
        let Some(ki) = inverse3(&tangent(&v)) else {
            break;
        };
        let dv: [f64; 3] = std::array::from_fn(|i| -(0..3).map(|j| ki[i][j] * r[j]).sum::<f64>());
        // Keep lambda positive: halve the step until the residual falls.
        let mut t = 1.0;
        let mut accepted = false;
        while t > 1e-6 {
            let vt: [f64; 3] = std::array::from_fn(|k| v[k] + t * dv[k]);
            if vt[2] > 0.0 {
                let rt = resid(&vt);
                if norm(&rt).is_finite() && norm(&rt) < norm(&r) {
                    v = vt;
                    r = rt;
                    accepted = true;
                    break;
                }
            }
            t *= 0.5;
        }
        if !accepted {
            ok = norm(&r) <= 1e-10 * scale;
            break;
        }
    }
    if !ok {
        return [D::from(f64::NAN); 3];
    }
    let Some(ki) = inverse3(&tangent(&v)) else {
        return [D::from(f64::NAN); 3];
    };
    let mut dn: [D; 3] = std::array::from_fn(|k| nm[k] - target[k]);
    if std::any::TypeId::of::<C>() != std::any::TypeId::of::<f64>() {
        let n_og = crate::law::ogden_force_with(law.0, law.1, law.2, &v);
        for (k, d) in dn.iter_mut().enumerate() {
            let r = n_og[k] + damping_c[k] * (history_c[k] + c0 * v[k]);
            *d = *d + -(r - r.value());
        }
    }
    std::array::from_fn(|i| dn[0] * ki[i][0] + dn[1] * ki[i][1] + dn[2] * ki[i][2] + v[i])
}

#[inline(always)]
fn cross<D: RodScalar>(a: &[D; 3], b: &[D; 3]) -> [D; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline(always)]
fn mat_vec<D: RodScalar>(r: &[[D; 3]; 3], x: &[D; 3]) -> [D; 3] {
    std::array::from_fn(|i| r[i][0] * x[0] + r[i][1] * x[1] + r[i][2] * x[2])
}

#[inline(always)]
pub(crate) fn mat_t_vec<D: RodScalar>(r: &[[D; 3]; 3], x: &[D; 3]) -> [D; 3] {
    std::array::from_fn(|i| r[0][i] * x[0] + r[1][i] * x[1] + r[2][i] * x[2])
}

/// Rotation matrix (row-major, columns d1 d2 d3) of a quaternion (w, x, y, z) of any norm:
/// R(Q) / |Q|^2, a rotation for every Q != 0.
#[inline(always)]
pub fn rotation<D: RodScalar>(q: &[D]) -> [[D; 3]; 3] {
    let (w, x, y, z) = (q[0], q[1], q[2], q[3]);
    let inv = (w * w + x * x + y * y + z * z).recip();
    let two = inv * 2.0;
    [
        [
            (w * w + x * x - y * y - z * z) * inv,
            (x * y - w * z) * two,
            (x * z + w * y) * two,
        ],
        [
            (x * y + w * z) * two,
            (w * w - x * x + y * y - z * z) * inv,
            (y * z - w * x) * two,
        ],
        [
            (x * z - w * y) * two,
            (y * z + w * x) * two,
            (w * w - x * x - y * y + z * z) * inv,
        ],
    ]
}

/// Unit quaternion (w, x, y, z) of a rotation matrix (Shepperd's method).
pub fn quaternion(r: &[[f64; 3]; 3]) -> [f64; 4] {
    let tr = r[0][0] + r[1][1] + r[2][2];
    let q = if tr > 0.0 {
        let s = (tr + 1.0).sqrt() * 2.0;
        [
            0.25 * s,
            (r[2][1] - r[1][2]) / s,
            (r[0][2] - r[2][0]) / s,
            (r[1][0] - r[0][1]) / s,
        ]
    } else if r[0][0] > r[1][1] && r[0][0] > r[2][2] {
        let s = (1.0 + r[0][0] - r[1][1] - r[2][2]).sqrt() * 2.0;
        [
            (r[2][1] - r[1][2]) / s,
            0.25 * s,
            (r[0][1] + r[1][0]) / s,
            (r[0][2] + r[2][0]) / s,
        ]
    } else if r[1][1] > r[2][2] {
        let s = (1.0 + r[1][1] - r[0][0] - r[2][2]).sqrt() * 2.0;
        [
            (r[0][2] - r[2][0]) / s,
            (r[0][1] + r[1][0]) / s,
            0.25 * s,
            (r[1][2] + r[2][1]) / s,
        ]
    } else {
        let s = (1.0 + r[2][2] - r[0][0] - r[1][1]).sqrt() * 2.0;
        [
            (r[1][0] - r[0][1]) / s,
            (r[0][2] + r[2][0]) / s,
            (r[1][2] + r[2][1]) / s,
            0.25 * s,
        ]
    };
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    q.map(|x| x / n)
}

/// Q' = Q (0, u) / 2: the quaternion's rate along s with body curvature `u`.
#[inline(always)]
fn quaternion_rate<D: RodScalar>(q: &[D], u: &[D; 3]) -> [D; 4] {
    let (qw, qx, qy, qz) = (q[0], q[1], q[2], q[3]);
    [
        (qx * u[0] + qy * u[1] + qz * u[2]) * -0.5,
        (qw * u[0] + qy * u[2] - qz * u[1]) * 0.5,
        (qw * u[1] + qz * u[0] - qx * u[2]) * 0.5,
        (qw * u[2] + qx * u[1] - qy * u[0]) * 0.5,
    ]
}

/// dY/ds at one point and its fields (v, u, q, w), given the point's history terms `h`
/// (X_t = c0 X + X_h for X in v, u, q, w):
///   Q' = Q (0, u) / 2,
///   n' = R rho A (q_t + w x q) - f - R f_b,               (paper 000 eq. 7)
///   m' = R (rho J w_t + w x rho J w) - (R v) x n - l - R l_b,
/// with f_b, l_b the follower (body-frame) line loads and `s` the point's arc length from
/// its section's start (the tendon routing's argument),
///   q' = v_t + w x v - u x q,   w' = u_t + w x u          (compatibility, eq. 13).
#[inline(always)]
pub fn rhs<C: Coeff, D: StateScalar<C>>(
    y: &[D; NY],
    m: &SectionModel<C>,
    h: &[C; NF],
    c0: f64,
    s: f64,
) -> ([D; NY], [D; NF]) {
    let rot = rotation(&y[IQ..IQ + 4]);
    let n = [y[IN], y[IN + 1], y[IN + 2]];
    let mo = [y[IM], y[IM + 1], y[IM + 2]];
    let q = [y[IV], y[IV + 1], y[IV + 2]];
    let w = [y[IW], y[IW + 1], y[IW + 2]];
    let nb = mat_t_vec(&rot, &n);
    let mb = mat_t_vec(&rot, &mo);
    let (v, u) = m.strains(&nb, &mb, h, c0, s);
    let zero = D::from(0.0);
    let (vt, ut) = if m.rigid {
        ([zero; 3], [zero; 3])
    } else {
        (
            std::array::from_fn(|k| v[k] * c0 + h[k]),
            std::array::from_fn(|k| u[k] * c0 + h[3 + k]),
        )
    };
    let qt: [D; 3] = std::array::from_fn(|k| q[k] * c0 + h[6 + k]);
    let wt: [D; 3] = std::array::from_fn(|k| w[k] * c0 + h[9 + k]);
    let mut dy = [zero; NY];
    dy[..4].copy_from_slice(&quaternion_rate(&y[IQ..IQ + 4], &u));
    let wxq = cross(&w, &q);
    let acc: [D; 3] = std::array::from_fn(|k| (qt[k] + wxq[k]) * m.rho_a);
    let acc_w = mat_vec(&rot, &acc);
    let jw: [D; 3] = std::array::from_fn(|k| w[k] * m.rho_j[k]);
    let wxjw = cross(&w, &jw);
    let ang: [D; 3] = std::array::from_fn(|k| wt[k] * m.rho_j[k] + wxjw[k]);
    let ang_w = mat_vec(&rot, &ang);
    let dr = mat_vec(&rot, &v);
    let rxn = cross(&dr, &n);
    let wxv = cross(&w, &v);
    let uxq = cross(&u, &q);
    let wxu = cross(&w, &u);
    for k in 0..3 {
        dy[IN + k] = acc_w[k] + -m.f[k];
        dy[IM + k] = ang_w[k] - rxn[k] + -m.l[k];
        dy[IV + k] = vt[k] + wxv[k] - uxq[k];
        dy[IW + k] = ut[k] + wxu[k];
    }
    if m.follower {
        // Follower line loads (body frame) turned by R: n' = ... - R f_body, m' = ... - R l_body.
        let fw = mat_vec(&rot, &m.f_body.map(|c| zero + c));
        let lw = mat_vec(&rot, &m.l_body.map(|c| zero + c));
        for k in 0..3 {
            dy[IN + k] -= fw[k];
            dy[IM + k] -= lw[k];
        }
    }
    let fields = [
        v[0], v[1], v[2], u[0], u[1], u[2], q[0], q[1], q[2], w[0], w[1], w[2],
    ];
    (dy, fields)
}

/// Rigid tip body and tip loads: dead (world frame) and follower (body frame, turned with
/// the tip's rotation R: R F_b, R M_b).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TipBody {
    pub mass: f64,
    pub com: [f64; 3],
    pub inertia: [f64; 3],
    pub force: [f64; 3],
    pub moment: [f64; 3],
    pub force_body: [f64; 3],
    pub moment_body: [f64; 3],
}

/// One time step's (or a static solve's) collocation problem.
#[derive(Debug, Clone)]
pub struct Problem<'a> {
    pub rod: &'a Rod,
    pub grid: &'a Grid,
    /// One model per slot of [`Grid::models`] (per section, or per stage point of a
    /// varying section).
    pub models: &'a [SectionModel],
    pub c0: f64,
    /// History terms: 2 per interval (stage order), then the tip node's.
    pub hist: &'a [[f64; NF]],
    pub tip: TipBody,
    pub gravity: [f64; 3],
    /// Scales of a point's unknowns (and of its equations).
    pub scale: [f64; NY],
    pub fs: f64,
    pub ms: f64,
    pub base_q: [f64; 4],
    /// Contact with the rod's obstacles (dynamics: [`Problem::with_contact`]); None: the
    /// centreline is no unknown.
    pub contact: Option<Contact>,
    /// A pinned or clamped tip (dynamics: [`Problem::with_end`]); None: a free tip.
    pub end: Option<EndTarget>,
}

/// The pose a constrained tip is held at (docs/model.md, "End constraints"): its position
/// (world, m) and, for a clamped tip, its rotation (row-major, tip frame as columns). The
/// tip's force balance becomes (r(L) - r_c)/L = 0 (the node positions join the unknowns,
/// as with contact); a clamped tip's moment balance becomes e(R_c^T R(L)) = 0 with
/// e(A) = vee(A - A^T)/2, as in the statics (`crate::statics::constraint`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EndTarget {
    pub position: [f64; 3],
    pub rotation: Option<[[f64; 3]; 3]>,
}

/// The scales of a point's unknowns for a rod and a time integrator's c0: quaternion 1,
/// force F_s = EI_min / L^2, moment F_s L, velocities L w_s and w_s with
/// w_s = max(c0, 1/s) (a velocity error dq moves the rod by dq / c0 in one step).
pub fn point_scale(rod: &Rod, c0: f64) -> [f64; NY] {
    let fs = force_scale(rod);
    let ms = fs * rod.length;
    let ws = c0.max(1.0);
    let vs = rod.length * ws;
    [
        1.0, 1.0, 1.0, 1.0, fs, fs, fs, ms, ms, ms, vs, vs, vs, ws, ws, ws,
    ]
}

/// The force scale of the unknowns and equations: the geometric mean of the bending force
/// scale EI/L^2 (a force that bends the rod by ~L) and the smallest axial or shear
/// stiffness K (one that strains it by ~1), capped at 100 EI/L^2. With EI/L^2 alone, a
/// uniform change of the axial force barely moves a long arm (strain fs / K), and Newton's
/// matrix grows ill-conditioned in that direction (paper 000's arm at 1 m: its smallest
/// equilibrated singular value fell to 6e-8 and steps stopped converging); the geometric
/// mean balances the two sensitivities (each off by sqrt(K L^2 / EI)).
pub fn force_scale(rod: &Rod) -> f64 {
    let bend = rod.force_scale;
    let k = rod
        .sections
        .iter()
        .filter(|s| !s.rigid)
        .map(|s| s.k_se[0].min(s.k_se[1]).min(s.k_se[2]))
        .fold(f64::INFINITY, f64::min);
    if !(k.is_finite() && k > 0.0 && bend > 0.0) {
        return bend;
    }
    bend * (k / bend).sqrt().clamp(1.0, 100.0)
}

impl<'a> Problem<'a> {
    /// A problem on `grid` with section `models`, c0 and histories.
    pub fn new(
        rod: &'a Rod,
        grid: &'a Grid,
        models: &'a [SectionModel],
        c0: f64,
        hist: &'a [[f64; NF]],
        tip: TipBody,
    ) -> Self {
        Problem {
            rod,
            grid,
            models,
            c0,
            hist,
            tip,
            gravity: rod.gravity,
            scale: point_scale(rod, c0),
            fs: force_scale(rod),
            ms: force_scale(rod) * rod.length,
            base_q: quaternion(&rod.base_rotation),
            contact: None,
            end: None,
        }
    }

    /// This problem with the tip held at `end` (None: free, unchanged).
    pub fn with_end(mut self, end: Option<EndTarget>) -> Self {
        self.end = end;
        self
    }

    /// The node positions are unknowns: with contact or a constrained tip.
    pub fn has_positions(&self) -> bool {
        self.contact.is_some() || self.end.is_some()
    }

    /// The free tip's balance (force N, moment N m, world) at the solution `z`: the wrench
    /// the constraint applies to the tip (zero for a free tip; the moment is zero for a
    /// pinned tip, whose moment balance is one of the equations).
    pub fn tip_reaction(&self, z: &[f64]) -> ([f64; 3], [f64; 3]) {
        let Some(end) = self.end else {
            return ([0.0; 3], [0.0; 3]);
        };
        let n = self.grid.len();
        let y = self.node(z, n);
        let r = self.position(z, n);
        let t = self.free_tip(self.contact.as_ref(), &y, &r);
        let force = std::array::from_fn(|k| t[k] * self.fs);
        let moment = std::array::from_fn(|k| {
            if end.rotation.is_some() {
                t[3 + k] * self.ms
            } else {
                0.0
            }
        });
        (force, moment)
    }

    /// This problem with contact against the rod's obstacles (none: unchanged): the node
    /// positions join the unknowns (docs/model.md, "Collocation").
    pub fn with_contact(mut self) -> Self {
        self.contact = Contact::of(self.rod, self.grid);
        self
    }

    /// Length of the unknown (and residual) vector: [`Grid::unknowns`], then with contact
    /// or a constrained tip the 3 N node positions r_1 .. r_N.
    pub fn unknowns(&self) -> usize {
        self.grid.unknowns()
            + if self.has_positions() {
                3 * self.grid.len()
            } else {
                0
            }
    }

    /// The physical state of node j (0..=N) from the scaled unknowns.
    pub fn node(&self, z: &[f64], j: usize) -> [f64; NY] {
        if j == 0 {
            let mut y = [0.0; NY];
            y[..4].copy_from_slice(&self.base_q);
            for k in 0..3 {
                y[IN + k] = z[k] * self.fs;
                y[IM + k] = z[3 + k] * self.ms;
            }
            y
        } else {
            let o = node_index(j);
            std::array::from_fn(|k| z[o + k] * self.scale[k])
        }
    }

    fn stage(&self, z: &[f64], j: usize, i: usize) -> [f64; NY] {
        let o = stage_index(j, i);
        std::array::from_fn(|k| z[o + k] * self.scale[k])
    }

    /// Scaled tip residual: n(L) = F + R F_b + m_t (g - a_c), m(L) = M + R M_b +
    /// c_w x m_t (g - a_c) - R (J w_t + w x J w), with a_c the acceleration of the tip
    /// body's centre of mass and F_b, M_b the follower loads (body frame).
    fn tip_residual<D: StateScalar<f64>>(&self, y: &[D; NY]) -> [D; 6] {
        self.tip_residual_with(y, self.hist.last().expect("tip slot"))
    }

    /// [`Problem::tip_residual`] with the tip node's history terms `th` in any scalar.
    // Inlined into the sensitivities' AVX2 step (`dynamics::sensitivity`).
    #[inline(always)]
    fn tip_residual_with<C: Coeff, D: StateScalar<C>>(&self, y: &[D; NY], th: &[C; NF]) -> [D; 6] {
        let t = &self.tip;
        let c0 = self.c0;
        let rot = rotation(&y[IQ..IQ + 4]);
        let q = [y[IV], y[IV + 1], y[IV + 2]];
        let w = [y[IW], y[IW + 1], y[IW + 2]];
        let qt: [D; 3] = std::array::from_fn(|k| q[k] * c0 + th[6 + k]);
        let wt: [D; 3] = std::array::from_fn(|k| w[k] * c0 + th[9 + k]);
        let com = t.com.map(D::from);
        let wxq = cross(&w, &q);
        let wtxc = cross(&wt, &com);
        let wxc = cross(&w, &com);
        let wxwxc = cross(&w, &wxc);
        let ab: [D; 3] = std::array::from_fn(|k| qt[k] + wxq[k] + wtxc[k] + wxwxc[k]);
        let a = mat_vec(&rot, &ab);
        let body: [D; 3] = std::array::from_fn(|k| (-a[k] + self.gravity[k]) * t.mass);
        let cw = mat_vec(&rot, &com);
        let cxb = cross(&cw, &body);
        let jw: [D; 3] = std::array::from_fn(|k| w[k] * t.inertia[k]);
        let wxjw = cross(&w, &jw);
        let torque: [D; 3] = std::array::from_fn(|k| wt[k] * t.inertia[k] + wxjw[k]);
        let torque_w = mat_vec(&rot, &torque);
        let fb = mat_vec(&rot, &t.force_body.map(D::from));
        let mb = mat_vec(&rot, &t.moment_body.map(D::from));
        std::array::from_fn(|k| {
            if k < 3 {
                (y[IN + k] - body[k] - fb[k] - t.force[k]) * (1.0 / self.fs)
            } else {
                let j = k - 3;
                (y[IM + j] - cxb[j] + torque_w[j] - mb[j] - t.moment[j]) * (1.0 / self.ms)
            }
        })
    }

    simd_dispatch! { Problem<'_>:
        /// Scaled residual at scaled unknowns `z` into `out`; the stage fields (v, u, q, w)
        /// into `fields` when given (2 per interval).
        pub fn residual(&self, z: &[f64], out: &mut [f64], fields: Option<&mut [[f64; NF]]>) => residual_impl
    }

    #[inline(always)]
    fn residual_impl(&self, z: &[f64], out: &mut [f64], mut fields: Option<&mut [[f64; NF]]>) {
        if self.has_positions() {
            return self.contact_residual(self.contact.as_ref(), z, out, fields);
        }
        let inv: [f64; NY] = self.scale.map(|s| 1.0 / s);
        let mut yj = self.node(z, 0);
        for (j, iv) in self.grid.intervals.iter().enumerate() {
            let model = [&self.models[iv.model[0]], &self.models[iv.model[1]]];
            let y1 = self.stage(z, j, 0);
            let y2 = self.stage(z, j, 1);
            let (f1, fl1) = rhs(&y1, model[0], &self.hist[2 * j], self.c0, iv.stage_local(0));
            let (f2, fl2) = rhs(
                &y2,
                model[1],
                &self.hist[2 * j + 1],
                self.c0,
                iv.stage_local(1),
            );
            if let Some(fl) = fields.as_mut() {
                fl[2 * j] = fl1;
                fl[2 * j + 1] = fl2;
            }
            let yn = self.node(z, j + 1);
            let o = 48 * j;
            let hh = iv.h;
            for k in 0..NY {
                out[o + k] =
                    (y1[k] - yj[k] - hh * (GAUSS_A[0][0] * f1[k] + GAUSS_A[0][1] * f2[k])) * inv[k];
                out[o + 16 + k] =
                    (y2[k] - yj[k] - hh * (GAUSS_A[1][0] * f1[k] + GAUSS_A[1][1] * f2[k])) * inv[k];
                out[o + 32 + k] =
                    (yn[k] - yj[k] - hh * (GAUSS_B[0] * f1[k] + GAUSS_B[1] * f2[k])) * inv[k];
            }
            yj = yn;
        }
        let r = self.tip_residual(&yj);
        let o = 48 * self.grid.len();
        out[o..o + 6].copy_from_slice(&r);
    }

    /// Exact Jacobian of f at a point, in scaled variables and scaled rows.
    /// The exact Jacobians of f at interval j's two stages (each with its own section model
    /// and arc length).
    fn stage_jacobians(&self, z: &[f64], j: usize) -> (Mat16, Mat16) {
        let iv = &self.grid.intervals[j];
        let at = |k: usize| {
            self.point_jacobian(
                &self.stage(z, j, k),
                &self.models[iv.model[k]],
                &self.hist[2 * j + k],
                iv.stage_local(k),
            )
        };
        (at(0), at(1))
    }

    fn point_jacobian(&self, y: &[f64; NY], model: &SectionModel, h: &[f64; NF], s: f64) -> Mat16 {
        let yj: [Jet<NY>; NY] = std::array::from_fn(|k| {
            let mut e = [0.0; NY];
            e[k] = self.scale[k];
            Jet { re: y[k], eps: e }
        });
        let (f, _) = rhs(&yj, model, h, self.c0, s);
        Mat16::from_fn(|r, c| f[r].eps[c] / self.scale[r])
    }

    /// The dense Jacobian of the scaled residual with respect to the scaled unknowns (for
    /// tests against finite differences; the solver never forms it).
    pub fn dense_jacobian(&self, z: &[f64]) -> Vec<Vec<f64>> {
        let n = z.len();
        let mut jac = vec![vec![0.0; n]; n];
        if self.has_positions() {
            let n_int = self.grid.len();
            self.contact_jacobian(self.contact.as_ref(), z, |row, col, v| {
                jac[full_to_residual(n_int, row)][full_to_unknown(n_int, col)] += v;
            });
            return jac;
        }
        for (j, iv) in self.grid.intervals.iter().enumerate() {
            let model = [&self.models[iv.model[0]], &self.models[iv.model[1]]];
            let js = [
                self.point_jacobian(
                    &self.stage(z, j, 0),
                    model[0],
                    &self.hist[2 * j],
                    iv.stage_local(0),
                ),
                self.point_jacobian(
                    &self.stage(z, j, 1),
                    model[1],
                    &self.hist[2 * j + 1],
                    iv.stage_local(1),
                ),
            ];
            let o = 48 * j;
            // Columns of node j: the base unknowns for j = 0 (slots IN..IN + 6).
            let node_col = |k: usize| -> Option<usize> {
                if j == 0 {
                    (IN..IN + 6).contains(&k).then(|| k - IN)
                } else {
                    Some(node_index(j) + k)
                }
            };
            for k in 0..NY {
                for row in [o + k, o + 16 + k, o + 32 + k] {
                    if let Some(c) = node_col(k) {
                        jac[row][c] -= 1.0;
                    }
                }
                jac[o + 32 + k][node_index(j + 1) + k] += 1.0;
            }
            for (si, jk) in js.iter().enumerate() {
                let col0 = stage_index(j, si);
                for r in 0..NY {
                    jac[o + 16 * si + r][col0 + r] += 1.0;
                    for c in 0..NY {
                        for (ri, a) in [(0usize, GAUSS_A[0][si]), (1, GAUSS_A[1][si])] {
                            jac[o + 16 * ri + r][col0 + c] -= iv.h * a * jk[(r, c)];
                        }
                        jac[o + 32 + r][col0 + c] -= iv.h * GAUSS_B[si] * jk[(r, c)];
                    }
                }
            }
        }
        let n_int = self.grid.len();
        let yn = self.node(z, n_int);
        let yjet: [Jet<NY>; NY] = std::array::from_fn(|k| {
            let mut e = [0.0; NY];
            e[k] = self.scale[k];
            Jet { re: yn[k], eps: e }
        });
        let rt = self.tip_residual(&yjet);
        for r in 0..6 {
            for c in 0..NY {
                let col = if n_int == 0 {
                    continue;
                } else {
                    node_index(n_int) + c
                };
                jac[48 * n_int + r][col] = rt[r].eps[c];
            }
        }
        jac
    }

    /// The linearised one-interval map of the collocation equations applied to a set of
    /// node perturbations: dY_{j+1} = T_j dY_j for the columns of `b` (scaled variables),
    /// with T_j = I + G M^-1 [I; I] as in [`Problem::factorize`], from the exact stage
    /// Jacobians at `z`. None if the stage matrix is singular or the result not finite.
    /// Used by the stability test of collocation statics (`crate::statics::collocation`),
    /// which carries three Jacobi fields along the rod this way.
    pub fn transfer<const K: usize>(
        &self,
        z: &[f64],
        j: usize,
        b: &SMatrix<f64, NY, K>,
    ) -> Option<SMatrix<f64, NY, K>> {
        let iv = &self.grid.intervals[j];
        let (j1, j2) = self.stage_jacobians(z, j);
        let hh = iv.h;
        // M = I - h (A (x) I) diag(J1, J2); the stages follow M dS = [dY_j; dY_j].
        let mut m = SMatrix::<f64, 32, 32>::identity();
        for r in 0..NY {
            for c in 0..NY {
                let (a, bb) = (j1[(r, c)], j2[(r, c)]);
                m[(r, c)] -= hh * GAUSS_A[0][0] * a;
                m[(NY + r, c)] -= hh * GAUSS_A[1][0] * a;
                m[(r, NY + c)] -= hh * GAUSS_A[0][1] * bb;
                m[(NY + r, NY + c)] -= hh * GAUSS_A[1][1] * bb;
            }
        }
        let mut rhs = SMatrix::<f64, 32, K>::zeros();
        rhs.fixed_view_mut::<NY, K>(0, 0).copy_from(b);
        rhs.fixed_view_mut::<NY, K>(NY, 0).copy_from(b);
        let s = m.lu().solve(&rhs)?;
        let s1 = s.fixed_view::<NY, K>(0, 0);
        let s2 = s.fixed_view::<NY, K>(NY, 0);
        let out = b + (j1 * s1) * (hh * GAUSS_B[0]) + (j2 * s2) * (hh * GAUSS_B[1]);
        out.iter().all(|v| v.is_finite()).then_some(out)
    }

    /// Offset in the unknowns of the tip node's 16 scaled values.
    pub fn tip_offset(&self) -> usize {
        node_index(self.grid.len())
    }

    /// Offset in the residual of the tip's 6 rows (its balance, or its pose when held).
    pub fn tip_rows(&self) -> usize {
        48 * self.grid.len()
    }

    /// The tip's position (m) and rotation at scaled unknowns `z` of a problem whose node
    /// positions are unknowns ([`Problem::has_positions`]).
    pub fn tip_pose(&self, z: &[f64]) -> ([f64; 3], [[f64; 3]; 3]) {
        let n = self.grid.len();
        (self.position(z, n), rotation(&self.node(z, n)[..4]))
    }

    /// Jacobian of the scaled tip residual (6 rows: force, moment) with respect to the
    /// tip node's scaled unknowns, at `z`.
    pub fn tip_jacobian(&self, z: &[f64]) -> SMatrix<f64, 6, NY> {
        let yn = self.node(z, self.grid.len());
        let yjet: [Jet<NY>; NY] = std::array::from_fn(|k| {
            let mut e = [0.0; NY];
            e[k] = self.scale[k];
            Jet { re: yn[k], eps: e }
        });
        let rt = self.tip_residual(&yjet);
        SMatrix::<f64, 6, NY>::from_fn(|r, c| rt[r].eps[c])
    }

    simd_dispatch! { Problem<'_>:
        /// Factor Newton's matrix at `z`: per interval the condensed stage block, then the
        /// banded node system. None if a block is singular.
        pub fn factorize(&self, z: &[f64]) -> Option<Factorization> => factorize_impl
    }

    #[inline(always)]
    fn factorize_impl(&self, z: &[f64]) -> Option<Factorization> {
        if self.has_positions() {
            return self.contact_factorize(z);
        }
        let n_int = self.grid.len();
        let mut blocks = Vec::with_capacity(n_int);
        let n = 6 + 16 * n_int;
        // Row block j (interval j: dY_{j+1} - T_j dY_j) spans the columns of node j (16 from
        // 16 j - 10, or the 6 base unknowns) to node j + 1's identity 6 right of the
        // diagonal: 25 sub- and 6 super-diagonals (the tip rows lie inside).
        let (kl, ku) = (25, 6);
        let mut band = BandedLu::zeros(n, kl, ku);
        for (j, iv) in self.grid.intervals.iter().enumerate() {
            let (j1, j2) = self.stage_jacobians(z, j);
            let hh = iv.h;
            // Column-major M = I - h (A (x) I) diag(J1, J2) (32 x 32) and
            // G = h [b1 J1, b2 J2] (16 x 32).
            let mut m = [0.0; 32 * 32];
            let mut g = [0.0; 16 * 32];
            for c in 0..16 {
                for r in 0..16 {
                    let (a, b) = (j1[(r, c)], j2[(r, c)]);
                    m[c * 32 + r] = -hh * GAUSS_A[0][0] * a;
                    m[c * 32 + 16 + r] = -hh * GAUSS_A[1][0] * a;
                    m[(16 + c) * 32 + r] = -hh * GAUSS_A[0][1] * b;
                    m[(16 + c) * 32 + 16 + r] = -hh * GAUSS_A[1][1] * b;
                    g[c * 16 + r] = hh * GAUSS_B[0] * a;
                    g[(16 + c) * 16 + r] = hh * GAUSS_B[1] * b;
                }
            }
            for k in 0..32 {
                m[k * 32 + k] += 1.0;
            }
            // M^-1 from M's LU (inlined here, so it shares this function's AVX2 copy),
            // and G M^-1.
            let mut piv = [0u8; 32];
            if !lu_dense::<32>(&mut m, &mut piv) {
                return None;
            }
            let mut f = IntervalFactor {
                minv: vec![0.0; 32 * 32],
                gminv: vec![0.0; 16 * 32],
            };
            let mut x = [0.0; 32 * 32];
            lu_dense_inverse::<32>(&m, &piv, &mut x);
            for c in 0..32 {
                // Column c of M^-1 (X holds it in row-major order).
                let col: [f64; 32] = std::array::from_fn(|r| x[32 * r + c]);
                f.minv[32 * c..32 * c + 32].copy_from_slice(&col);
                let mut y = [0.0; 16];
                gemv_add(&mut y, &g, &col);
                f.gminv[16 * c..16 * c + 16].copy_from_slice(&y);
            }
            if !f.minv.iter().all(|x| x.is_finite()) {
                return None;
            }
            // T = I + G M^-1 [I; I], t[c][r] = T(r, c).
            let mut t = [[0.0; 16]; 16];
            for c in 0..16 {
                for r in 0..16 {
                    t[c][r] = f.gminv[16 * c + r] + f.gminv[16 * (16 + c) + r];
                }
                t[c][c] += 1.0;
            }
            // Rows of interval j: dY_{j+1} - T_j dY_j = t_j.
            let row0 = 16 * j;
            let col_next = 6 + 16 * j;
            for r in 0..16 {
                band.set(row0 + r, col_next + r, 1.0);
                if j == 0 {
                    // dY_0 = E dx0: the base unknowns n(0)/F_s, m(0)/(F_s L) are the
                    // scaled slots IN..IN + 6 of node 0.
                    for c in 0..6 {
                        band.set(row0 + r, c, -t[IN + c][r]);
                    }
                } else {
                    let col = 6 + 16 * (j - 1);
                    for c in 0..16 {
                        band.set(row0 + r, col + c, -t[c][r]);
                    }
                }
            }
            blocks.push(f);
        }
        // Tip rows: C dY_N = -r_tip.
        let yn = self.node(z, n_int);
        let yjet: [Jet<NY>; NY] = std::array::from_fn(|k| {
            let mut e = [0.0; NY];
            e[k] = self.scale[k];
            Jet { re: yn[k], eps: e }
        });
        let rt = self.tip_residual(&yjet);
        let col = 6 + 16 * (n_int - 1);
        for r in 0..6 {
            for c in 0..16 {
                band.set(16 * n_int + r, col + c, rt[r].eps[c]);
            }
        }
        if !band.factor() {
            return None;
        }
        Some(Factorization {
            blocks,
            band,
            contact: false,
            at: z.to_vec(),
        })
    }
}

/// One interval's condensed stage block: with M = I - h (A (x) I) diag(J1, J2) the
/// stage matrix and G = h [b1 J1, b2 J2], the stages follow dS = M^-1 (-r_S + [dY_j; dY_j])
/// and the end node dY_{j+1} = T dY_j + G M^-1 (-r_S) - r_N with T = I + G M^-1 [I; I].
/// Kept as explicit matrices (column-major) so that each Newton iteration is two
/// matrix-vector products per interval (the factors serve many iterations and steps).
#[derive(Debug, Clone)]
struct IntervalFactor {
    /// M^-1 (32 x 32).
    minv: Vec<f64>,
    /// G M^-1 (16 x 32).
    gminv: Vec<f64>,
}

/// LU factorisation with partial pivoting of a dense column-major N x N matrix in place
/// (right-looking, column axpy updates: vectorises). False if singular or not finite.
#[inline(always)]
fn lu_dense<const N: usize>(a: &mut [f64], piv: &mut [u8; N]) -> bool {
    for k in 0..N {
        let mut p = k;
        let mut best = a[k * N + k].abs();
        for i in k + 1..N {
            let v = a[k * N + i].abs();
            if v > best {
                best = v;
                p = i;
            }
        }
        if !(best.is_finite() && best > 0.0) {
            return false;
        }
        piv[k] = p as u8;
        if p != k {
            for c in 0..N {
                a.swap(c * N + k, c * N + p);
            }
        }
        let inv = 1.0 / a[k * N + k];
        for i in k + 1..N {
            a[k * N + i] *= inv;
        }
        let (left, right) = a.split_at_mut((k + 1) * N);
        let lk = &left[k * N + k + 1..k * N + N];
        for c in 0..N - k - 1 {
            let col = &mut right[c * N..(c + 1) * N];
            let u = col[k];
            if u != 0.0 {
                for (x, l) in col[k + 1..].iter_mut().zip(lk) {
                    *x -= l * u;
                }
            }
        }
    }
    true
}

/// The inverse of the matrix factored by [`lu_dense`], in row-major order in `x`: solves
/// P A X = I for all N columns at once, one row of X at a time, so that every update is an
/// N-wide axpy (vectorises, no dependency chain from one entry to the next). Each entry
/// sees the same operations in the same order as a forward and back substitution of a unit
/// vector that skips its zero entries (which change no value but the sign of a zero).
#[inline(always)]
fn lu_dense_inverse<const N: usize>(a: &[f64], piv: &[u8; N], x: &mut [f64]) {
    let x = &mut x[..N * N];
    // P I: the row exchanges applied to the identity's rows in order.
    let mut perm: [usize; N] = std::array::from_fn(|k| k);
    for k in 0..N {
        perm.swap(k, piv[k] as usize);
    }
    x.fill(0.0);
    for (r, &p) in perm.iter().enumerate() {
        x[r * N + p] = 1.0;
    }
    // Forward: X[i, :] -= L[i, k] X[k, :] for i > k. Row k is copied first: reading it
    // from a local array lets LLVM prove it distinct from the rows it updates, so the
    // updates vectorise (from two halves of `x` they stayed scalar).
    for k in 0..N {
        let xk: [f64; N] = std::array::from_fn(|c| x[k * N + c]);
        for (i, row) in x[(k + 1) * N..].chunks_exact_mut(N).enumerate() {
            let l = a[k * N + k + 1 + i];
            for (xi, v) in row.iter_mut().zip(&xk) {
                *xi -= l * v;
            }
        }
    }
    // Backward: X[k, :] /= U[k, k]; X[i, :] -= U[i, k] X[k, :] for i < k.
    for k in (0..N).rev() {
        let d = a[k * N + k];
        for v in x[k * N..(k + 1) * N].iter_mut() {
            *v /= d;
        }
        let xk: [f64; N] = std::array::from_fn(|c| x[k * N + c]);
        for (i, row) in x[..k * N].chunks_exact_mut(N).enumerate() {
            let u = a[k * N + i];
            for (xi, v) in row.iter_mut().zip(&xk) {
                *xi -= u * v;
            }
        }
    }
}

/// y += A x for a column-major A with R rows and C columns (axpy per column: vectorises).
#[inline(always)]
fn gemv_add<const R: usize, const C: usize>(y: &mut [f64; R], a: &[f64], x: &[f64; C]) {
    let a = &a[..R * C];
    for (c, xc) in x.iter().enumerate() {
        let col = &a[c * R..(c + 1) * R];
        for (yr, ar) in y.iter_mut().zip(col) {
            *yr += ar * xc;
        }
    }
}

/// Newton's matrix of a collocation problem, factored.
#[derive(Debug, Clone)]
pub struct Factorization {
    blocks: Vec<IntervalFactor>,
    /// The node system, or with contact (`blocks` empty) the whole banded system in the
    /// order of [`residual_to_full`] and [`unknown_to_full`].
    band: BandedLu,
    contact: bool,
    /// The scaled unknowns it was computed at.
    pub at: Vec<f64>,
}

impl Factorization {
    simd_dispatch! { Factorization:
        /// The Newton step: solves J dz = -r for the scaled residual `r`, with `rhs` (at
        /// least as long as the node system: [`Factorization::scratch_len`]) as scratch.
        pub fn solve(&self, r: &[f64], dz: &mut [f64], rhs: &mut [f64]) => solve_impl
    }

    simd_dispatch! { Factorization:
        /// [`Factorization::solve`] for two residuals at once: `r` holds them one after
        /// the other (2 n), `dz` receives the two steps likewise, `rhs` is scratch of twice
        /// [`Factorization::scratch_len`]. The same numbers as two solves (the band's
        /// substitutions run both sides together: [`BandedLu::solve2`]).
        pub fn solve2(&self, r: &[f64], dz: &mut [f64], rhs: &mut [f64]) => solve2_impl
    }

    /// The length of [`Factorization::solve`]'s scratch.
    pub fn scratch_len(&self) -> usize {
        self.band.n()
    }

    /// The implicit function theorem's step: the unknowns `z` with dz/da in the dual parts
    /// of their first `dirs` directions, dz/da = -G_z^-1 d_a G, from the residual's partial
    /// derivatives d_a G in the dual parts of `r` (evaluated at `z`, where this factors
    /// G_z). None when a derivative is not finite.
    pub fn implicit_step<const N: usize>(
        &self,
        z: &[f64],
        r: &[Jet<N>],
        dirs: usize,
    ) -> Option<Vec<Jet<N>>> {
        let mut zd: Vec<Jet<N>> = z.iter().map(|&x| Jet::<N>::from(x)).collect();
        let mut rhs = vec![0.0; z.len()];
        let mut dz = vec![0.0; z.len()];
        let mut scratch = vec![0.0; self.scratch_len()];
        for q in 0..dirs {
            for (x, ri) in rhs.iter_mut().zip(r) {
                *x = ri.eps[q];
            }
            // `solve` solves J dz = -r.
            self.solve(&rhs, &mut dz, &mut scratch);
            if !dz.iter().all(|x| x.is_finite()) {
                return None;
            }
            for (x, d) in zd.iter_mut().zip(&dz) {
                x.eps[q] = *d;
            }
        }
        Some(zd)
    }

    #[inline(always)]
    fn solve2_impl(&self, r: &[f64], dz: &mut [f64], rhs: &mut [f64]) {
        if self.contact {
            let n = r.len() / 2;
            let (dz0, dz1) = dz.split_at_mut(n);
            self.solve_full(&r[..n], dz0, rhs);
            self.solve_full(&r[n..], dz1, rhs);
            return;
        }
        let n_int = self.blocks.len();
        let nb = self.band.n();
        let n = r.len() / 2;
        let rhs = &mut rhs[..2 * nb];
        let (r0, r1) = r.split_at(n);
        for (c, r) in [r0, r1].into_iter().enumerate() {
            for (j, b) in self.blocks.iter().enumerate() {
                let o = 48 * j;
                let rs: [f64; 32] = std::array::from_fn(|k| -r[o + k]);
                let mut t: [f64; 16] = std::array::from_fn(|k| -r[o + 32 + k]);
                gemv_add(&mut t, &b.gminv, &rs);
                for (k, x) in t.iter().enumerate() {
                    rhs[2 * (16 * j + k) + c] = *x;
                }
            }
            let o = 48 * n_int;
            for k in 0..6 {
                rhs[2 * (16 * n_int + k) + c] = -r[o + k];
            }
        }
        self.band.solve2(rhs);
        let (dz0, dz1) = dz.split_at_mut(n);
        for (c, (r, dz)) in [(r0, dz0), (r1, dz1)].into_iter().enumerate() {
            let x = |i: usize| rhs[2 * i + c];
            for (k, d) in dz[..6].iter_mut().enumerate() {
                *d = x(k);
            }
            for (j, b) in self.blocks.iter().enumerate() {
                let dyj: [f64; 16] = if j == 0 {
                    std::array::from_fn(|k| {
                        if (IN..IN + 6).contains(&k) {
                            x(k - IN)
                        } else {
                            0.0
                        }
                    })
                } else {
                    std::array::from_fn(|k| x(6 + 16 * (j - 1) + k))
                };
                let o = 48 * j;
                let rs: [f64; 32] = std::array::from_fn(|k| dyj[k % 16] - r[o + k]);
                let mut st = [0.0; 32];
                gemv_add(&mut st, &b.minv, &rs);
                dz[6 + o..6 + o + 32].copy_from_slice(&st);
                for k in 0..16 {
                    dz[6 + o + 32 + k] = x(6 + 16 * j + k);
                }
            }
        }
    }

    /// The Newton step of a contact problem: one banded solve of the whole system.
    fn solve_full(&self, r: &[f64], dz: &mut [f64], rhs: &mut [f64]) {
        let n = r.len();
        let n_int = (n - 6) / 51;
        let rhs = &mut rhs[..n];
        for (i, x) in r.iter().enumerate() {
            rhs[residual_to_full(n_int, i)] = -x;
        }
        self.band.solve(rhs);
        for (i, d) in dz[..n].iter_mut().enumerate() {
            *d = rhs[unknown_to_full(n_int, i)];
        }
    }

    #[inline(always)]
    fn solve_impl(&self, r: &[f64], dz: &mut [f64], rhs: &mut [f64]) {
        if self.contact {
            return self.solve_full(r, dz, rhs);
        }
        let n_int = self.blocks.len();
        let rhs = &mut rhs[..self.band.n()];
        // The node recurrences' right sides G M^-1 (-r_S) - r_N.
        for (j, b) in self.blocks.iter().enumerate() {
            let o = 48 * j;
            let rs: [f64; 32] = std::array::from_fn(|k| -r[o + k]);
            let mut t: [f64; 16] = std::array::from_fn(|k| -r[o + 32 + k]);
            gemv_add(&mut t, &b.gminv, &rs);
            rhs[16 * j..16 * j + 16].copy_from_slice(&t);
        }
        let o = 48 * n_int;
        for k in 0..6 {
            rhs[16 * n_int + k] = -r[o + k];
        }
        self.band.solve(rhs);
        // Base unknowns, then per interval the stages M^-1 (-r_S + [dY_j; dY_j]) (one
        // product with M^-1 where s + P dY_j took two) and the end node.
        dz[..6].copy_from_slice(&rhs[..6]);
        for (j, b) in self.blocks.iter().enumerate() {
            let dyj: [f64; 16] = if j == 0 {
                // dY_0 in scaled point units: only n(0), m(0) move.
                std::array::from_fn(|k| {
                    if (IN..IN + 6).contains(&k) {
                        rhs[k - IN]
                    } else {
                        0.0
                    }
                })
            } else {
                std::array::from_fn(|k| rhs[6 + 16 * (j - 1) + k])
            };
            let o = 48 * j;
            let rs: [f64; 32] = std::array::from_fn(|k| dyj[k % 16] - r[o + k]);
            let mut st = [0.0; 32];
            gemv_add(&mut st, &b.minv, &rs);
            dz[6 + o..6 + o + 32].copy_from_slice(&st);
            dz[6 + o + 32..6 + o + 48].copy_from_slice(&rhs[6 + 16 * j..6 + 16 * j + 16]);
        }
    }
}

/// Newton settings of a collocation solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewtonOptions {
    /// Tolerance on the scaled residual (infinity norm), relative to max(1, |z|).
    pub tol: f64,
    pub max_iter: usize,
}

/// Counters of collocation solves.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NewtonStats {
    pub iterations: usize,
    pub jacobians: usize,
}

/// Largest |r_k|, NaN if any entry is NaN (4 lanes so that it vectorises).
pub(crate) fn inf_norm(r: &[f64]) -> f64 {
    let mut m = [0.0f64; 4];
    let mut nan = false;
    let chunks = r.chunks_exact(4);
    let rest = chunks.remainder();
    for c in chunks {
        for k in 0..4 {
            let a = c[k].abs();
            nan |= a.is_nan();
            m[k] = if a > m[k] { a } else { m[k] };
        }
    }
    for x in rest {
        let a = x.abs();
        nan |= a.is_nan();
        m[0] = if a > m[0] { a } else { m[0] };
    }
    if nan {
        f64::NAN
    } else {
        m[0].max(m[1]).max(m[2].max(m[3]))
    }
}

/// Buffers of [`newton_with`], kept between solves so that a time step allocates none,
/// and the stage fields of the residual last evaluated at the returned solution.
#[derive(Debug, Clone, Default)]
pub struct NewtonWork {
    r: Vec<f64>,
    rt: Vec<f64>,
    dz: Vec<f64>,
    zt: Vec<f64>,
    rhs: Vec<f64>,
    /// Stage fields (v, u, q, w) at the solution, valid when `fields_at_solution`.
    pub fields: Vec<[f64; NF]>,
    /// Whether `fields` belong to the returned solution (the last residual was evaluated
    /// there), so that [`Problem::evaluate_with_fields`] need not recompute them.
    pub fields_at_solution: bool,
}

impl NewtonWork {
    fn fit(&mut self, n: usize, n_stages: usize) {
        for v in [&mut self.r, &mut self.rt, &mut self.dz, &mut self.zt] {
            v.resize(n, 0.0);
        }
        self.fields.resize(n_stages, [0.0; NF]);
        self.fields_at_solution = false;
    }
}

/// Damped Newton on `p` from `z` (in place). Converged when a full Newton correction, or
/// the error it leaves (theta / (1 - theta) of it at contraction rate theta < 1/2), is below
/// `tol` (scaled unknowns, relative to max(1, |z|)): the correction measures
/// the error in the unknowns themselves, whose scales are physical (rotations in rad,
/// velocities in L c0, so a velocity error moves the rod by that fraction of L in one
/// step), where the residual's rows mix very different sensitivities. A factorization in
/// `cache` (from an earlier iterate or step) is reused while it contracts by at least
/// 1/4 per iteration and refreshed otherwise ([`Contraction`]). Ok(final scaled residual) or
/// Err((iterations, residual)); on return `cache` holds the last factorization (None if
/// it was discarded).
pub fn newton(
    p: &Problem,
    z: &mut [f64],
    cache: &mut Option<Factorization>,
    opts: &NewtonOptions,
    stats: &mut NewtonStats,
) -> std::result::Result<f64, (usize, f64)> {
    let mut theta = 1.0;
    let mut work = NewtonWork::default();
    newton_with(p, z, cache, opts, stats, &mut theta, &mut work)
}

/// [`newton`] with the contraction rate `theta` of the matrix's last use (updated on
/// return): a sequence of similar problems (time steps) with a kept matrix contracts at
/// about the same rate, so the first correction's remaining error can be estimated as
/// theta / (1 - theta) of it; when that is below tol, and the residual confirms the
/// contraction, the step ends after one correction (Hairer and Wanner's device in Radau5).
/// `work` holds the buffers (reused across calls) and, on that path, the stage fields at
/// the solution.
pub fn newton_with(
    p: &Problem,
    z: &mut [f64],
    cache: &mut Option<Factorization>,
    opts: &NewtonOptions,
    stats: &mut NewtonStats,
    theta_hint: &mut f64,
    work: &mut NewtonWork,
) -> std::result::Result<f64, (usize, f64)> {
    let n = z.len();
    work.fit(n, 2 * p.grid.len());
    let NewtonWork {
        r,
        rt,
        dz,
        zt,
        rhs,
        fields,
        fields_at_solution,
    } = work;
    p.residual(z, r, None);
    let mut norm = inf_norm(r);
    let mut rate = Contraction::new(theta_hint);
    for it in 0..opts.max_iter {
        stats.iterations += 1;
        if !norm.is_finite() && rate.fresh() {
            return Err((it + 1, norm));
        }
        if cache.is_none() {
            *cache = p.factorize(z);
            stats.jacobians += 1;
            rate.factored();
            if cache.is_none() {
                return Err((it + 1, norm));
            }
        }
        let fac = cache.as_ref().expect("factorization");
        rhs.resize(fac.scratch_len(), 0.0);
        fac.solve(r, dz, rhs);
        let scale = inf_norm(z).max(1.0);
        let step = inf_norm(dz) / scale;
        if !step.is_finite() {
            if rate.fresh() {
                return Err((it + 1, norm));
            }
            *cache = None;
            continue;
        }
        match rate.judge(it, step, opts.tol) {
            Judged::Converged => {
                // Converged: apply the (tiny) correction and finish (the residual reported
                // is the one before it).
                for (a, d) in z.iter_mut().zip(dz.iter()) {
                    *a += d;
                }
                return Ok(norm);
            }
            Judged::Predicted => {
                for k in 0..n {
                    zt[k] = z[k] + dz[k];
                }
                p.residual(zt, rt, Some(&mut fields[..]));
                let nt = inf_norm(rt);
                if rate.confirms(nt, norm) {
                    z.copy_from_slice(zt);
                    *fields_at_solution = true;
                    return Ok(nt);
                }
            }
            Judged::Iterate => {}
        }
        let mut alpha = 1.0;
        let mut accepted = false;
        while alpha >= 1.0 / 256.0 {
            for k in 0..n {
                zt[k] = z[k] + alpha * dz[k];
            }
            p.residual(zt, rt, None);
            let nt = inf_norm(rt);
            if nt.is_finite() && nt < (1.0 - 1e-4 * alpha) * norm {
                if !rate.accepted(alpha, step) {
                    *cache = None; // refresh at the new iterate
                }
                z.copy_from_slice(zt);
                std::mem::swap(r, rt);
                norm = nt;
                accepted = true;
                break;
            }
            if !rate.fresh() {
                break; // a stale matrix may be the problem: refresh and retry
            }
            alpha *= 0.5;
        }
        if !accepted {
            if rate.fresh() {
                if step <= 100.0 * opts.tol {
                    return Ok(norm); // at round-off already
                }
                return Err((it + 1, norm));
            }
            *cache = None;
            rate.stale_failed();
        }
    }
    Err((opts.max_iter, norm))
}

/// What [`Contraction::judge`] makes of a Newton correction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Judged {
    /// Below tol (or the error it leaves at the measured rate is): apply it and stop.
    Converged,
    /// A kept matrix's first correction whose remaining error, at the rate of the matrix's
    /// last use, is below tol: apply it in full and stop if the residual confirms the rate
    /// ([`Contraction::confirms`]); iterate on otherwise.
    Predicted,
    /// Take it (damped if need be) and iterate.
    Iterate,
}

/// The contraction bookkeeping of a modified Newton iteration whose factored matrix may
/// come from an earlier iterate or solve (`newton_with`; the systems of rods' bordered
/// Newton, `dynamics::system`, with the same rules): the rate theta from the last two
/// full corrections with the same matrix, convergence when a correction, or the error it
/// leaves (theta / (1 - theta) of it for theta < 1/2; Hairer and Wanner, Radau5), is
/// below tol, and a refresh when the matrix contracts by less than `REUSE` per iteration
/// or needed damping. `hint` is the rate of the matrix's last use (1 when unknown),
/// carried between solves by the caller.
pub(crate) struct Contraction<'h> {
    hint: &'h mut f64,
    /// Whether the matrix was factored at the current iterate.
    fresh: bool,
    /// The last full correction with the current matrix (infinite: none).
    last_step: f64,
    /// The rate of the correction last judged.
    theta: f64,
}

impl<'h> Contraction<'h> {
    /// A matrix kept while it contracts by at least this factor per iteration.
    const REUSE: f64 = 0.25;

    pub(crate) fn new(hint: &'h mut f64) -> Self {
        Contraction {
            hint,
            fresh: false,
            last_step: f64::INFINITY,
            theta: 1.0,
        }
    }

    /// A matrix was factored at the current iterate.
    pub(crate) fn factored(&mut self) {
        self.fresh = true;
    }

    /// Whether the matrix is the current iterate's (failures are then final).
    pub(crate) fn fresh(&self) -> bool {
        self.fresh
    }

    /// The correction of (finite, relative) size `step` at iteration `it`.
    pub(crate) fn judge(&mut self, it: usize, step: f64, tol: f64) -> Judged {
        // Contraction rate from the last two full corrections (1 when unknown).
        let theta = if self.last_step.is_finite() {
            step / self.last_step
        } else {
            1.0
        };
        self.theta = theta;
        // Remaining error after this correction: theta / (1 - theta) of it for a
        // contracting iteration (Hairer and Wanner, Radau5); the first correction itself.
        let remaining = if theta < 0.5 {
            step * theta / (1.0 - theta)
        } else {
            step
        };
        if step <= tol || (it > 0 && remaining <= tol) {
            if it > 0 && theta < 1.0 {
                *self.hint = theta;
            }
            return Judged::Converged;
        }
        // The kept matrix's last rate predicts the remaining error of its first correction.
        let th = *self.hint;
        if it == 0 && !self.fresh && th < 0.5 && step * th / (1.0 - th) <= tol {
            return Judged::Predicted;
        }
        Judged::Iterate
    }

    /// Whether a [`Judged::Predicted`] correction's residual `nt` (from `norm`) confirms
    /// the rate: it falls at least as the rate says (by 10x the predicted factor at worst,
    /// and by half).
    pub(crate) fn confirms(&self, nt: f64, norm: f64) -> bool {
        nt.is_finite() && nt <= norm * (10.0 * *self.hint).min(0.5)
    }

    /// The judged correction was taken with damping `alpha`: whether the matrix may be
    /// kept (false: refresh it at the new iterate; it needed damping or contracts by less
    /// than `REUSE`).
    pub(crate) fn accepted(&mut self, alpha: f64, step: f64) -> bool {
        let keep = !(alpha < 1.0 || (self.last_step.is_finite() && self.theta > Self::REUSE));
        self.fresh = false;
        self.last_step = if alpha == 1.0 { step } else { f64::INFINITY };
        if !keep {
            *self.hint = 1.0; // a new matrix: its rate is unknown
        }
        keep
    }

    /// A stale matrix's correction did not reduce the residual: it is refreshed.
    pub(crate) fn stale_failed(&mut self) {
        self.last_step = f64::INFINITY;
        *self.hint = 1.0;
    }
}

/// The collocation equations with the section models and history terms in another scalar
/// `C` (a dual number carrying parameter derivatives) and the unknowns in `D`: what the
/// forward sensitivities of the dynamics (`crate::dynamics::sensitivity`) differentiate.
/// The grid, scales and tip body are the f64 problem's.
impl Problem<'_> {
    /// Physical state of node j (0..=N) from scaled unknowns in any scalar.
    // Inlined into the sensitivities' AVX2 step (`dynamics::sensitivity`).
    #[inline(always)]
    pub(crate) fn node_with<D: RodScalar>(&self, z: &[D], j: usize) -> [D; NY] {
        if j == 0 {
            let mut y = [D::from(0.0); NY];
            for k in 0..4 {
                y[k] = D::from(self.base_q[k]);
            }
            for k in 0..3 {
                y[IN + k] = z[k] * self.fs;
                y[IM + k] = z[3 + k] * self.ms;
            }
            y
        } else {
            let o = node_index(j);
            std::array::from_fn(|k| z[o + k] * self.scale[k])
        }
    }

    // Inlined into the sensitivities' AVX2 step (`dynamics::sensitivity`).
    #[inline(always)]
    fn stage_with<D: RodScalar>(&self, z: &[D], j: usize, i: usize) -> [D; NY] {
        let o = stage_index(j, i);
        std::array::from_fn(|k| z[o + k] * self.scale[k])
    }

    /// The scaled residual (the layout of [`Problem::residual`]) of scaled unknowns `z`
    /// under `models` (one per slot of `Grid::models`) and histories `hist` (2 per interval, then the tip).
    pub fn residual_with<C: Coeff, D: StateScalar<C>>(
        &self,
        models: &[SectionModel<C>],
        hist: &[[C; NF]],
        z: &[D],
    ) -> Vec<D> {
        self.residual_fields_with(models, hist, z, None)
    }

    /// [`Problem::residual_with`] and the stage fields (v, u, q, w; 2 per interval) of the
    /// same evaluation: what [`Problem::fields_and_tip_with`] returns first, without
    /// evaluating the rod equations again.
    // Inlined into the sensitivities' AVX2 step (`dynamics::sensitivity`).
    #[inline(always)]
    pub fn residual_and_fields_with<C: Coeff, D: StateScalar<C>>(
        &self,
        models: &[SectionModel<C>],
        hist: &[[C; NF]],
        z: &[D],
    ) -> (Vec<D>, Vec<[D; NF]>) {
        let mut fields = Vec::with_capacity(2 * self.grid.len());
        let r = self.residual_fields_with(models, hist, z, Some(&mut fields));
        (r, fields)
    }

    // Inlined into the sensitivities' AVX2 step (`dynamics::sensitivity`).
    #[inline(always)]
    fn residual_fields_with<C: Coeff, D: StateScalar<C>>(
        &self,
        models: &[SectionModel<C>],
        hist: &[[C; NF]],
        z: &[D],
        mut fields: Option<&mut Vec<[D; NF]>>,
    ) -> Vec<D> {
        let mut out = vec![D::from(0.0); z.len()];
        if self.has_positions() {
            let zero = [D::from(0.0); NF];
            let slots = fields.map(|f| {
                f.clear();
                f.resize(2 * self.grid.len(), zero);
                f.as_mut_slice()
            });
            self.contact_residual_with(models, hist, self.contact.as_ref(), z, &mut out, slots);
            return out;
        }
        let inv: [f64; NY] = self.scale.map(|s| 1.0 / s);
        let mut yj = self.node_with(z, 0);
        for (j, iv) in self.grid.intervals.iter().enumerate() {
            let model = [&models[iv.model[0]], &models[iv.model[1]]];
            let y1 = self.stage_with(z, j, 0);
            let y2 = self.stage_with(z, j, 1);
            let (f1, fl1) = rhs(&y1, model[0], &hist[2 * j], self.c0, iv.stage_local(0));
            let (f2, fl2) = rhs(&y2, model[1], &hist[2 * j + 1], self.c0, iv.stage_local(1));
            if let Some(fl) = fields.as_mut() {
                fl.push(fl1);
                fl.push(fl2);
            }
            let yn = self.node_with(z, j + 1);
            let o = 48 * j;
            let hh = iv.h;
            let comb = |a: f64, b: f64, k: usize| (f1[k] * a + f2[k] * b) * hh;
            for k in 0..NY {
                out[o + k] = (y1[k] - yj[k] - comb(GAUSS_A[0][0], GAUSS_A[0][1], k)) * inv[k];
                out[o + 16 + k] = (y2[k] - yj[k] - comb(GAUSS_A[1][0], GAUSS_A[1][1], k)) * inv[k];
                out[o + 32 + k] = (yn[k] - yj[k] - comb(GAUSS_B[0], GAUSS_B[1], k)) * inv[k];
            }
            yj = yn;
        }
        let r = self.tip_residual_with(&yj, hist.last().expect("tip slot"));
        let o = 48 * self.grid.len();
        out[o..o + 6].copy_from_slice(&r);
        out
    }

    /// The stage fields (v, u, q, w; 2 per interval), the tip node's state and the node
    /// positions of scaled unknowns `z` under `models` and `hist` (as [`Problem::evaluate`]:
    /// the centreline by the collocation quadrature).
    pub fn fields_and_positions_with<C: Coeff, D: StateScalar<C>>(
        &self,
        models: &[SectionModel<C>],
        hist: &[[C; NF]],
        z: &[D],
    ) -> (Vec<[D; NF]>, [D; NY], Vec<[D; 3]>) {
        let fields = self.fields_with(models, hist, z);
        let (node, r) = self.positions_of_fields(z, &fields);
        (fields, node, r)
    }

    /// The stage fields (v, u, q, w; 2 per interval) of scaled unknowns `z` under `models`
    /// and `hist`.
    // Inlined into the sensitivities' AVX2 step (`dynamics::sensitivity`).
    #[inline(always)]
    pub fn fields_with<C: Coeff, D: StateScalar<C>>(
        &self,
        models: &[SectionModel<C>],
        hist: &[[C; NF]],
        z: &[D],
    ) -> Vec<[D; NF]> {
        let mut fields = Vec::with_capacity(2 * self.grid.len());
        for (j, iv) in self.grid.intervals.iter().enumerate() {
            let models_of = [&models[iv.model[0]], &models[iv.model[1]]];
            for i in 0..2 {
                let y = self.stage_with(z, j, i);
                fields.push(
                    rhs(
                        &y,
                        models_of[i],
                        &hist[2 * j + i],
                        self.c0,
                        iv.stage_local(i),
                    )
                    .1,
                );
            }
        }
        fields
    }

    /// The positions of the body points `points` (grid point, offset in the cross-section
    /// frame) of scaled unknowns `z` whose stage fields `fields` and node positions
    /// `nodes_r` are known ([`Problem::positions_of_fields`]): [`body_points`].
    pub fn points_with<D: RodScalar>(
        &self,
        z: &[D],
        fields: &[[D; NF]],
        nodes_r: &[[D; 3]],
        points: &[(GridPoint, [f64; 3])],
    ) -> Vec<[D; 3]> {
        let quat = |y: [D; NY]| [y[0], y[1], y[2], y[3]];
        let states = PointStates {
            node_r: nodes_r,
            node_q: |j: usize| quat(self.node_with(z, j)),
            stage_q: |k: usize| quat(self.stage_with(z, k / 2, k % 2)),
            fields,
        };
        body_points(self.grid, &states, points)
    }

    /// The tip node's state and the node positions (base first, tip last) of scaled
    /// unknowns `z` whose stage fields `fields` are known (from
    /// [`Problem::residual_and_fields_with`] at the same `z`).
    // Inlined into the sensitivities' AVX2 step (`dynamics::sensitivity`).
    #[inline(always)]
    pub fn positions_of_fields<D: RodScalar>(
        &self,
        z: &[D],
        fields: &[[D; NF]],
    ) -> ([D; NY], Vec<[D; 3]>) {
        let mut r: [D; 3] = self.rod.base_position.map(D::from);
        let mut out = Vec::with_capacity(self.grid.len() + 1);
        out.push(r);
        for (j, iv) in self.grid.intervals.iter().enumerate() {
            let mut dr = [[D::from(0.0); 3]; 2];
            for (i, d) in dr.iter_mut().enumerate() {
                let y = self.stage_with(z, j, i);
                let fl = &fields[2 * j + i];
                let rot = rotation(&y[IQ..IQ + 4]);
                *d = mat_vec(&rot, &[fl[0], fl[1], fl[2]]);
            }
            r = std::array::from_fn(|k| {
                r[k] + (dr[0][k] * GAUSS_B[0] + dr[1][k] * GAUSS_B[1]) * iv.h
            });
            out.push(r);
        }
        (self.node_with(z, self.grid.len()), out)
    }
}

/// Node and stage states of a solution in physical units, with the centreline recovered
/// by the collocation quadrature (r_i = r_j + h sum_k a_ik R_k v_k).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Evaluated {
    /// Node states (N + 1).
    pub nodes: Vec<[f64; NY]>,
    /// Node positions, m.
    pub node_r: Vec<[f64; 3]>,
    /// Stage fields v, u, q, w (2 per interval).
    pub fields: Vec<[f64; NF]>,
    /// Stage positions, m.
    pub stage_r: Vec<[f64; 3]>,
    /// Stage rotations.
    pub stage_rot: Vec<[[f64; 3]; 3]>,
    /// Stage quaternions (of the norm the collocation gives them; `stage_rot` is their
    /// rotation): what the continuous extension between the nodes reads.
    pub stage_q: Vec<[f64; 4]>,
}

impl Evaluated {
    /// The positions of the body points `points` (grid point of `grid`, offset in the
    /// cross-section frame) of this state ([`body_points`]), from the nodes, stage
    /// quaternions and fields kept here.
    pub fn points(&self, grid: &Grid, points: &[(GridPoint, [f64; 3])]) -> Vec<[f64; 3]> {
        let states = PointStates {
            node_r: &self.node_r,
            node_q: |j: usize| {
                let y: &[f64; NY] = &self.nodes[j];
                [y[0], y[1], y[2], y[3]]
            },
            stage_q: |k: usize| self.stage_q[k],
            fields: &self.fields,
        };
        body_points(grid, &states, points)
    }
}

/// What [`body_points`] reads of a state: node positions, node quaternions (by node),
/// stage quaternions (by stage slot 2 j + i) and stage fields (v, u, q, w).
pub struct PointStates<'a, D, N, S> {
    pub node_r: &'a [[D; 3]],
    pub node_q: N,
    pub stage_q: S,
    pub fields: &'a [[D; NF]],
}

/// The positions r + R o of body points (grid point, offset o in the cross-section frame)
/// of a state, in any scalar: at a node the node's own position and rotation, between
/// nodes the continuous extension ([`dense_point`]).
pub fn body_points<D: RodScalar, N: Fn(usize) -> [D; 4], S: Fn(usize) -> [D; 4]>(
    grid: &Grid,
    states: &PointStates<'_, D, N, S>,
    points: &[(GridPoint, [f64; 3])],
) -> Vec<[D; 3]> {
    points
        .iter()
        .map(|(p, o)| {
            let j = p.node;
            let q0 = (states.node_q)(j);
            if p.theta == 0.0 {
                return offset_point(&states.node_r[j], &rotation(&q0), o);
            }
            let qs = [(states.stage_q)(2 * j), (states.stage_q)(2 * j + 1)];
            let stages = [
                (&qs[0], &states.fields[2 * j]),
                (&qs[1], &states.fields[2 * j + 1]),
            ];
            let h = grid.intervals[j].h;
            dense_point(&states.node_r[j], &q0, stages, h, p.theta, o)
        })
        .collect()
}

impl Problem<'_> {
    /// States, fields and positions of the solution `z`.
    pub fn evaluate(&self, z: &[f64]) -> Evaluated {
        self.evaluate_impl(z, None)
    }

    /// [`Problem::evaluate`] with the stage fields at `z` already known (from the residual
    /// at `z`, [`NewtonWork::fields`]): the same result without evaluating f again.
    pub fn evaluate_with_fields(&self, z: &[f64], fields: &[[f64; NF]]) -> Evaluated {
        self.evaluate_impl(z, Some(fields))
    }

    fn evaluate_impl(&self, z: &[f64], known: Option<&[[f64; NF]]>) -> Evaluated {
        let n_int = self.grid.len();
        let mut out = Evaluated {
            nodes: Vec::with_capacity(n_int + 1),
            node_r: Vec::with_capacity(n_int + 1),
            fields: Vec::with_capacity(2 * n_int),
            stage_r: Vec::with_capacity(2 * n_int),
            stage_rot: Vec::with_capacity(2 * n_int),
            stage_q: Vec::with_capacity(2 * n_int),
        };
        let mut r = self.rod.base_position;
        out.nodes.push(self.node(z, 0));
        out.node_r.push(r);
        for (j, iv) in self.grid.intervals.iter().enumerate() {
            let models_of = [&self.models[iv.model[0]], &self.models[iv.model[1]]];
            let mut dr = [[0.0; 3]; 2];
            for i in 0..2 {
                let y = self.stage(z, j, i);
                let fl = match known {
                    Some(f) => f[2 * j + i],
                    None => {
                        rhs(
                            &y,
                            models_of[i],
                            &self.hist[2 * j + i],
                            self.c0,
                            iv.stage_local(i),
                        )
                        .1
                    }
                };
                let rot = rotation(&y[IQ..IQ + 4]);
                dr[i] = mat_vec(&rot, &[fl[0], fl[1], fl[2]]);
                out.fields.push(fl);
                out.stage_rot.push(rot);
                out.stage_q.push([y[0], y[1], y[2], y[3]]);
            }
            for i in 0..2 {
                out.stage_r.push(std::array::from_fn(|k| {
                    r[k] + iv.h * (GAUSS_A[i][0] * dr[0][k] + GAUSS_A[i][1] * dr[1][k])
                }));
            }
            r = std::array::from_fn(|k| {
                r[k] + iv.h * (GAUSS_B[0] * dr[0][k] + GAUSS_B[1] * dr[1][k])
            });
            out.nodes.push(self.node(z, j + 1));
            out.node_r.push(r);
        }
        out
    }

    /// Scaled unknowns from physical node states (N + 1), the stages interpolated
    /// linearly between their nodes (quaternions normalised): a Newton start.
    pub fn unknowns_from_nodes(&self, nodes: &[[f64; NY]]) -> Vec<f64> {
        let mut z = vec![0.0; self.grid.unknowns()];
        for k in 0..3 {
            z[k] = nodes[0][IN + k] / self.fs;
            z[3 + k] = nodes[0][IM + k] / self.ms;
        }
        for j in 0..self.grid.len() {
            for i in 0..2 {
                let c = GAUSS_C[i];
                let mut y: [f64; NY] =
                    std::array::from_fn(|k| (1.0 - c) * nodes[j][k] + c * nodes[j + 1][k]);
                let qn = (y[0] * y[0] + y[1] * y[1] + y[2] * y[2] + y[3] * y[3]).sqrt();
                for v in &mut y[..4] {
                    *v /= qn;
                }
                let o = stage_index(j, i);
                for k in 0..NY {
                    z[o + k] = y[k] / self.scale[k];
                }
            }
            let o = node_index(j + 1);
            for k in 0..NY {
                z[o + k] = nodes[j + 1][k] / self.scale[k];
            }
        }
        self.with_positions(z)
    }

    /// Scaled unknowns `z` of a problem without contact ([`Grid::unknowns`]) completed
    /// for this problem: with contact the node positions by the collocation quadrature
    /// (which the position equations then hold exactly).
    pub fn with_positions(&self, mut z: Vec<f64>) -> Vec<f64> {
        z.truncate(self.grid.unknowns());
        if self.has_positions() {
            let eval = self.evaluate(&z);
            for r in &eval.node_r[1..] {
                z.extend(r.iter().map(|x| x / self.rod.length));
            }
        }
        z
    }

    /// The straight, unloaded rod at rest: the exact solution with no loads.
    pub fn straight_unknowns(&self) -> Vec<f64> {
        let mut y = [0.0; NY];
        y[..4].copy_from_slice(&self.base_q);
        self.unknowns_from_nodes(&vec![y; self.grid.len() + 1])
    }

    /// Scaled unknowns of the same physical state under another problem's scales.
    pub fn rescale_from(&self, other: &Problem, z: &[f64]) -> Vec<f64> {
        let mut out = z.to_vec();
        for j in 0..self.grid.len() {
            for o in [stage_index(j, 0), stage_index(j, 1), node_index(j + 1)] {
                for k in 0..NY {
                    out[o + k] = z[o + k] * other.scale[k] / self.scale[k];
                }
            }
        }
        out
    }
}
