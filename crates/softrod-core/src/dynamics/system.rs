//! Dynamics of a system of rods whose tips hold one rigid platform (a parallel continuum
//! robot; the statics: `crate::statics::system`, docs/model.md "Systems of rods";
//! docs/dynamics.md "Systems of rods").
//!
//! Every rod is the single rod's time step with its tip clamped (`Simulator`, "Held tip")
//! at its attachment on the platform: position p + R o_i, rotation R A_i. The platform is a
//! rigid body (mass m, centre of mass c and inertia J about it, both in the platform frame)
//! under gravity, its external force F (at p) and moment M and the wrenches the rods' tips
//! apply to it, minus each rod's tip reaction (F_i, M_i):
//!
//!   m a_c = F + m g - sum F_i,
//!   (R c) x m a_c + R (J W_t + W x J W) = M + (R c) x m g - sum (M_i + (R o_i) x F_i),
//!
//! (moments about p; W the body angular velocity, a_c = A + R (W_t x c + W x (W x c)) the
//! centre of mass's acceleration). In time the platform takes the rods' formula
//! X_t = c0 X + X_h (BDF-alpha) for p, its velocity V and W; the rotation is carried in the
//! Cayley chart about the last step's R_n: R = cay(phi) R_n with
//! cay(phi) = I + 4 / (4 + |phi|^2) (phi^ + phi^2 / 2), whose time derivative is the world
//! angular velocity w = 4 / (4 + |phi|^2) (phi_t + phi x phi_t / 2) (Iserles, Munthe-Kaas,
//! Norsett, Zanna, "Lie-group methods", Acta Numerica 9, 2000, doi
//! 10.1017/S0962492900002154), so the chart's formula needs only the history of phi
//! (phi_n = 0, phi_{n-1} = cay^-1(R_{n-1} R_n^T), phi_t(t_n) = w_n).
//!
//! One Newton per step on every rod's unknowns and the platform's 6 (p / L_s, phi), exact
//! Jacobian: the rods' blocks A_i are their held-tip step matrices; the platform enters a
//! rod's equations only through its tip pose (6 columns B_i), and a rod enters the
//! platform's only through its tip reaction, a function of its tip node (rows C_i). The
//! bordered system is solved by the Schur complement on the platform's 6 unknowns:
//! S = D - sum C_i A_i^-1 B_i with each rod's banded factorization reused for 7 right-hand
//! sides (its residual and B_i), so a step costs what the rods' steps cost, linear in the
//! nodes. The factored matrix is kept across iterations and steps while Newton contracts
//! with it (modified Newton by `collocation::newton_with`'s rules, shared through
//! `collocation::Contraction`), as the single rod keeps its own. The energy books add the
//! platform's kinetic and potential energy to the rods'; the work of each tip reaction on
//! its rod (its books) and on the platform cancel.
//!
//! A rod's follower tip load (`[tip] frame = "body"`: world force R_tip f_b and moment
//! R_tip m_b, R_tip its tip node's rotation, which the clamp holds at R A_i) is part of
//! its tip reaction (the free tip's balance, `Problem::tip_reaction`), as in the statics:
//! C_i (`Problem::reaction_jacobian`) carries its exact derivative with respect to the
//! tip node's rotation, and the rod's books take its power as a free rod's do.

use super::{
    check_energy, drive, reaction_work, rename_field, to_scaled, unknown_scales, Bdf, Books,
    Candidate, DynOptions, DynStats, Energy, Initial, Prep, Reader, Scheme, SigmaMap, Simulator,
    Stepping, Writer,
};
use crate::collocation::{self, inf_norm, Contraction, Judged, Problem, NY};
use crate::error::{Result, SoftrodError};
use crate::jet::{Jet, RodScalar};
use crate::ode::Loads;
use crate::rod::Rod;
use crate::statics::constraint::{matmul, orientation_error, tmatmul, TipConstraint};
use crate::statics::system::{self as statics_system, solve_system, Platform, SystemRod};
use crate::statics::SolverOptions;
use nalgebra::{Matrix6, Vector3, Vector6};

mod sensitivity;

/// One rod of a simulated system: the rod, its inputs at t = 0 and where its tip holds the
/// platform (offset and rotation of its tip frame in the platform frame, as
/// [`SystemRod`]).
#[derive(Debug, Clone)]
pub struct DynRod {
    pub rod: Rod,
    /// Chamber pressures (Pa) and tendon tensions (N) at t = 0.
    pub pressures: Vec<f64>,
    pub tensions: Vec<f64>,
    pub sigma_map: SigmaMap,
    pub attachment: [f64; 3],
    pub attachment_rotation: [[f64; 3]; 3],
}

/// The platform's motion at one instant: pose, world velocity of its origin, body angular
/// velocity, and their rates.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Motion {
    p: [f64; 3],
    rot: [[f64; 3]; 3],
    v: [f64; 3],
    w: [f64; 3],
    a: [f64; 3],
    wt: [f64; 3],
}

impl Motion {
    fn at_rest(p: [f64; 3], rot: [[f64; 3]; 3]) -> Self {
        let z = [0.0; 3];
        Motion {
            p,
            rot,
            v: z,
            w: z,
            a: z,
            wt: z,
        }
    }

    fn numbers(&self) -> [f64; 24] {
        let mut x = [0.0; 24];
        x[..3].copy_from_slice(&self.p);
        for i in 0..3 {
            x[3 + 3 * i..6 + 3 * i].copy_from_slice(&self.rot[i]);
        }
        for (k, v) in [self.v, self.w, self.a, self.wt].iter().enumerate() {
            x[12 + 3 * k..15 + 3 * k].copy_from_slice(v);
        }
        x
    }

    fn from_numbers(x: &[f64; 24]) -> Self {
        let v3 = |o: usize| [x[o], x[o + 1], x[o + 2]];
        Motion {
            p: v3(0),
            rot: std::array::from_fn(|i| v3(3 + 3 * i)),
            v: v3(12),
            w: v3(15),
            a: v3(18),
            wt: v3(21),
        }
    }
}

/// The platform's own data (fixed for a run) and loads (changeable).
#[derive(Debug, Clone, PartialEq)]
struct Body {
    mass: f64,
    com: [f64; 3],
    inertia: [[f64; 3]; 3],
    gravity: [f64; 3],
    force: [f64; 3],
    moment: [f64; 3],
    attach: Vec<([f64; 3], [[f64; 3]; 3])>,
    /// Length, force and moment scales of the unknowns and rows (as the statics').
    ls: f64,
    fs: f64,
    ms: f64,
}

/// The platform's equations in one step: its body and the step's terms.
struct PlatformEq<'a> {
    body: &'a Body,
    t: StepTerms,
}

/// What a step's platform equations depend on besides the body: the time formula's c0 and
/// history terms (position, chart, velocity, angular velocity), the chart's base R_n.
/// (In any scalar: the parameter sensitivities carry their derivatives, `sensitivity`.)
#[derive(Debug, Clone, Copy, PartialEq)]
struct StepTerms<D = f64> {
    c0: f64,
    hp: [D; 3],
    hphi: [D; 3],
    hv: [D; 3],
    hw: [D; 3],
    r_n: [[D; 3]; 3],
}

impl StepTerms {
    /// These terms in the scalar D (no derivatives).
    fn lift<D: RodScalar>(&self) -> StepTerms<D> {
        StepTerms {
            c0: self.c0,
            hp: self.hp.map(D::from),
            hphi: self.hphi.map(D::from),
            hv: self.hv.map(D::from),
            hw: self.hw.map(D::from),
            r_n: self.r_n.map(|row| row.map(D::from)),
        }
    }
}

/// The step terms of a step with time formula `bdf` from the motion `now` and `prev` (one
/// step before) in [`Motion::numbers`]' layout, in any scalar: [`PlatformEq::step`]'s
/// formulas, for the parameter sensitivities (dual motions carry dH/dtheta).
fn terms_of<D: RodScalar>(bdf: &Bdf, now: &[D; 24], prev: &[D; 24]) -> StepTerms<D> {
    let Bdf { c0, c1, c2, d1 } = *bdf;
    let v3 = |x: &[D; 24], o: usize| -> [D; 3] { [x[o], x[o + 1], x[o + 2]] };
    let rot = |x: &[D; 24]| -> [[D; 3]; 3] { std::array::from_fn(|i| v3(x, 3 + 3 * i)) };
    let h3 = |x1: &[D; 3], x2: &[D; 3], xt: &[D; 3]| -> [D; 3] {
        std::array::from_fn(|k| x1[k] * c1 + x2[k] * c2 + xt[k] * d1)
    };
    let (r_now, r_prev) = (rot(now), rot(prev));
    let rel: [[D; 3]; 3] = std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            r_prev[i][0] * r_now[j][0] + r_prev[i][1] * r_now[j][1] + r_prev[i][2] * r_now[j][2]
        })
    });
    let phi_prev = cayley_inverse_of(&rel);
    let w_n = rotate(&r_now, &v3(now, 15));
    let zero = [D::from(0.0); 3];
    StepTerms {
        c0,
        hp: h3(&v3(now, 0), &v3(prev, 0), &v3(now, 12)),
        hphi: h3(&zero, &phi_prev, &w_n),
        hv: h3(&v3(now, 12), &v3(prev, 12), &v3(now, 18)),
        hw: h3(&v3(now, 15), &v3(prev, 15), &v3(now, 21)),
        r_n: r_now,
    }
}

/// The platform's pose and motion as functions of its unknowns.
struct Kin<D> {
    p: [D; 3],
    rot: [[D; 3]; 3],
    v: [D; 3],
    w: [D; 3],
    a: [D; 3],
    wt: [D; 3],
}

fn cross<D: RodScalar>(a: &[D; 3], b: &[D; 3]) -> [D; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn rotate<D: RodScalar>(rot: &[[D; 3]; 3], v: &[D; 3]) -> [D; 3] {
    std::array::from_fn(|i| rot[i][0] * v[0] + rot[i][1] * v[1] + rot[i][2] * v[2])
}

fn rotate_t<D: RodScalar>(rot: &[[D; 3]; 3], v: &[D; 3]) -> [D; 3] {
    std::array::from_fn(|i| rot[0][i] * v[0] + rot[1][i] * v[1] + rot[2][i] * v[2])
}

/// The Cayley map cay(phi) = I + 4 / (4 + |phi|^2) (phi^ + phi^2 / 2) (module docs).
pub fn cayley<D: RodScalar>(phi: &[D; 3]) -> [[D; 3]; 3] {
    let n2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2];
    let f = (n2 + 4.0).recip() * 4.0;
    let hat = [
        [D::from(0.0), -phi[2], phi[1]],
        [phi[2], D::from(0.0), -phi[0]],
        [-phi[1], phi[0], D::from(0.0)],
    ];
    let hat2 = matmul(&hat, &hat);
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let id = if i == j { 1.0 } else { 0.0 };
            (hat[i][j] + hat2[i][j] * 0.5) * f + id
        })
    })
}

/// The world angular velocity of R(t) = cay(phi(t)) R_n:
/// w = 4 / (4 + |phi|^2) (phi_t + phi x phi_t / 2).
pub fn cayley_rate<D: RodScalar>(phi: &[D; 3], phi_t: &[D; 3]) -> [D; 3] {
    let n2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2];
    let f = (n2 + 4.0).recip() * 4.0;
    let c = cross(phi, phi_t);
    std::array::from_fn(|k| (phi_t[k] + c[k] * 0.5) * f)
}

/// [`cayley_inverse`] in any scalar.
fn cayley_inverse_of<D: RodScalar>(q: &[[D; 3]; 3]) -> [D; 3] {
    let f = (q[0][0] + q[1][1] + q[2][2] + 1.0).recip() * 2.0;
    [
        (q[2][1] - q[1][2]) * f,
        (q[0][2] - q[2][0]) * f,
        (q[1][0] - q[0][1]) * f,
    ]
}

/// The inverse of [`cayley`] (a rotation of less than a half turn): 2 vee(Q - Q^T) /
/// (1 + tr Q).
pub fn cayley_inverse(q: &[[f64; 3]; 3]) -> [f64; 3] {
    let d = 1.0 + q[0][0] + q[1][1] + q[2][2];
    [
        (q[2][1] - q[1][2]) / d * 2.0,
        (q[0][2] - q[2][0]) / d * 2.0,
        (q[1][0] - q[0][1]) / d * 2.0,
    ]
}

impl<'a> PlatformEq<'a> {
    /// The equations of a step with time formula `bdf` from the motion `now` (and `prev`,
    /// one step before).
    fn step(body: &'a Body, bdf: &Bdf, now: &Motion, prev: &Motion) -> Self {
        let Bdf { c0, c1, c2, d1 } = *bdf;
        let h3 = |x1: &[f64; 3], x2: &[f64; 3], xt: &[f64; 3]| -> [f64; 3] {
            std::array::from_fn(|k| c1 * x1[k] + c2 * x2[k] + d1 * xt[k])
        };
        // The chart about R_n: phi_n = 0, phi_{n-1} = cay^-1(R_{n-1} R_n^T), phi_t(t_n) =
        // the world angular velocity R_n W_n.
        let rel: [[f64; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|j| (0..3).map(|k| prev.rot[i][k] * now.rot[j][k]).sum())
        });
        let phi_prev = cayley_inverse(&rel);
        let w_n = rotate(&now.rot, &now.w);
        PlatformEq {
            body,
            t: StepTerms {
                c0,
                hp: h3(&now.p, &prev.p, &now.v),
                hphi: h3(&[0.0; 3], &phi_prev, &w_n),
                hv: h3(&now.v, &prev.v, &now.a),
                hw: h3(&now.w, &prev.w, &now.wt),
                r_n: now.rot,
            },
        }
    }

    /// The equations at rest (c0 = 0, no history): the platform's static balance about the
    /// chart's base `r_n`.
    fn rest(body: &'a Body, r_n: [[f64; 3]; 3]) -> Self {
        let z = [0.0; 3];
        PlatformEq {
            body,
            t: StepTerms {
                c0: 0.0,
                hp: z,
                hphi: z,
                hv: z,
                hw: z,
                r_n,
            },
        }
    }

    fn kin<D: RodScalar>(&self, xi: &[D; 6]) -> Kin<D> {
        kin_of(self.body.ls, &self.t.lift::<D>(), xi)
    }

    /// The pose where rod i's tip is held with the platform at `xi`.
    fn target(&self, i: usize, xi: &[f64; 6]) -> TipConstraint {
        let k = self.kin(xi);
        let (o, a) = &self.body.attach[i];
        let arm = rotate(&k.rot, o);
        TipConstraint::Clamped {
            position: std::array::from_fn(|j| k.p[j] + arm[j]),
            rotation: matmul(&k.rot, a),
        }
    }

    /// The platform's 6 scaled balance rows with the platform at `xi` and the rods' tip
    /// reactions (force, moment; world) `reactions`.
    fn rows<D: RodScalar>(&self, xi: &[D; 6], reactions: &[([D; 3], [D; 3])]) -> [D; 6] {
        rows_of(
            self.body,
            D::from(self.body.mass),
            &self.t.lift::<D>(),
            xi,
            reactions,
        )
    }

    /// The rows and their exact derivatives: with respect to the platform's unknowns (D)
    /// and to each rod's reaction (6 x 6 per rod, force then moment).
    fn rows_jacobian(
        &self,
        xi: &[f64; 6],
        reactions: &[([f64; 3], [f64; 3])],
    ) -> ([f64; 6], Matrix6<f64>, Vec<Matrix6<f64>>) {
        let x: [Jet<12>; 6] = std::array::from_fn(|k| Jet::variable(xi[k], k));
        let mut d = Matrix6::zeros();
        let mut g = [0.0; 6];
        let mut per = Vec::with_capacity(reactions.len());
        for i in 0..reactions.len() {
            let re: Vec<([Jet<12>; 3], [Jet<12>; 3])> = reactions
                .iter()
                .enumerate()
                .map(|(j, (f, m))| {
                    let var = |v: f64, slot: usize| {
                        if j == i {
                            Jet::variable(v, slot)
                        } else {
                            Jet::from(v)
                        }
                    };
                    (
                        std::array::from_fn(|k| var(f[k], 6 + k)),
                        std::array::from_fn(|k| var(m[k], 9 + k)),
                    )
                })
                .collect();
            let rows = self.rows(&x, &re);
            if i == 0 {
                for r in 0..6 {
                    g[r] = rows[r].re;
                    for c in 0..6 {
                        d[(r, c)] = rows[r].eps[c];
                    }
                }
            }
            per.push(Matrix6::from_fn(|r, c| rows[r].eps[6 + c]));
        }
        (g, d, per)
    }
}

/// The platform's pose and motion at unknowns `xi` under step terms `t` (length scale
/// `ls`), in any scalar.
fn kin_of<D: RodScalar>(ls: f64, t: &StepTerms<D>, xi: &[D; 6]) -> Kin<D> {
    let c0 = t.c0;
    let p: [D; 3] = std::array::from_fn(|k| xi[k] * ls);
    let phi = [xi[3], xi[4], xi[5]];
    let rot = matmul(&cayley(&phi), &t.r_n);
    let v: [D; 3] = std::array::from_fn(|k| p[k] * c0 + t.hp[k]);
    let phi_t: [D; 3] = std::array::from_fn(|k| phi[k] * c0 + t.hphi[k]);
    let w = rotate_t(&rot, &cayley_rate(&phi, &phi_t));
    let a = std::array::from_fn(|k| v[k] * c0 + t.hv[k]);
    let wt = std::array::from_fn(|k| w[k] * c0 + t.hw[k]);
    Kin {
        p,
        rot,
        v,
        w,
        a,
        wt,
    }
}

/// [`PlatformEq::rows`] of a body of mass `mass` under step terms `t`, in any scalar (the
/// parameter sensitivities carry the mass's and the terms' derivatives).
fn rows_of<D: RodScalar>(
    b: &Body,
    mass: D,
    t: &StepTerms<D>,
    xi: &[D; 6],
    reactions: &[([D; 3], [D; 3])],
) -> [D; 6] {
    let k = kin_of(b.ls, t, xi);
    let com = b.com.map(D::from);
    let wxc = cross(&k.w, &com);
    let wxwxc = cross(&k.w, &wxc);
    let wtxc = cross(&k.wt, &com);
    let rel: [D; 3] = std::array::from_fn(|j| wtxc[j] + wxwxc[j]);
    let rel_w = rotate(&k.rot, &rel);
    // m (g - a_c): gravity less the inertial force, at the centre of mass.
    let net: [D; 3] = std::array::from_fn(|j| (-(k.a[j] + rel_w[j]) + b.gravity[j]) * mass);
    let cw = rotate(&k.rot, &com);
    let cxn = cross(&cw, &net);
    let jw: [D; 3] = std::array::from_fn(|i| {
        k.w[0] * b.inertia[i][0] + k.w[1] * b.inertia[i][1] + k.w[2] * b.inertia[i][2]
    });
    let jwt: [D; 3] = std::array::from_fn(|i| {
        k.wt[0] * b.inertia[i][0] + k.wt[1] * b.inertia[i][1] + k.wt[2] * b.inertia[i][2]
    });
    let wxjw = cross(&k.w, &jw);
    let euler = rotate(&k.rot, &std::array::from_fn(|j| jwt[j] + wxjw[j]));
    let mut f: [D; 3] = std::array::from_fn(|j| net[j] + b.force[j]);
    let mut m: [D; 3] = std::array::from_fn(|j| cxn[j] - euler[j] + b.moment[j]);
    for (i, (fi, mi)) in reactions.iter().enumerate() {
        let arm = rotate(&k.rot, &b.attach[i].0.map(D::from));
        let axf = cross(&arm, fi);
        for j in 0..3 {
            f[j] -= fi[j];
            m[j] -= mi[j] + axf[j];
        }
    }
    std::array::from_fn(|j| {
        if j < 3 {
            f[j] * (1.0 / b.fs)
        } else {
            m[j - 3] * (1.0 / b.ms)
        }
    })
}

/// Rod i's held-tip rows (scaled, as `collocation`'s: (r(L) - r_c) / L and
/// e(R_c^T R(L))) and their derivatives with respect to the platform's unknowns.
fn tip_rows_jacobian(
    eq: &PlatformEq,
    i: usize,
    p: &Problem,
    z: &[f64],
    xi: &[f64; 6],
) -> [[f64; 6]; 6] {
    let (r, rot) = p.tip_pose(z);
    let x: [Jet<6>; 6] = std::array::from_fn(|k| Jet::variable(xi[k], k));
    let k = eq.kin(&x);
    held_rows(&k, &eq.body.attach[i], &r, &rot, 1.0 / p.rod.length).map(|v| v.eps)
}

/// The held-tip rows of a rod attached at `attach` (offset, rotation in the platform
/// frame) whose tip is at (`r`, `rot`) with the platform's pose `k` in any scalar:
/// ((r - r_c) il, e(R_c^T rot)), r_c = p + R o, R_c = R A.
fn held_rows<D: RodScalar>(
    k: &Kin<D>,
    attach: &([f64; 3], [[f64; 3]; 3]),
    r: &[f64; 3],
    rot: &[[f64; 3]; 3],
    il: f64,
) -> [D; 6] {
    let (o, a) = attach;
    let arm = rotate(&k.rot, &o.map(D::from));
    let target = matmul(&k.rot, &a.map(|row| row.map(D::from)));
    let e = orientation_error(&tmatmul(&target, &rot.map(|row| row.map(D::from))));
    std::array::from_fn(|row| {
        if row < 3 {
            (-(k.p[row] + arm[row]) + r[row]) * il
        } else {
            e[row - 3]
        }
    })
}

/// The coupled equations of one step (or of the rest state): the rods' problems (their tip
/// poses set from the platform's unknowns) and the platform's equations.
struct Coupled<'a> {
    problems: Vec<Problem<'a>>,
    eq: PlatformEq<'a>,
}

impl Coupled<'_> {
    /// Hold every rod's tip where the platform at `xi` holds it.
    fn place(&mut self, xi: &[f64; 6]) {
        for (i, p) in self.problems.iter_mut().enumerate() {
            p.end = super::end_target(&self.eq.target(i, xi));
        }
    }

    /// The rods' tip reactions at `zs` (world; the wrench the platform applies to each tip).
    fn reactions(&self, zs: &[Vec<f64>]) -> Vec<([f64; 3], [f64; 3])> {
        self.problems
            .iter()
            .zip(zs)
            .map(|(p, z)| p.tip_reaction(z))
            .collect()
    }

    /// Every residual (rods', then the platform's rows) and the largest |entry|.
    fn residual(&mut self, zs: &[Vec<f64>], xi: &[f64; 6], rs: &mut [Vec<f64>]) -> ([f64; 6], f64) {
        self.place(xi);
        let mut norm: f64 = 0.0;
        for ((p, z), r) in self.problems.iter().zip(zs).zip(rs.iter_mut()) {
            r.resize(z.len(), 0.0);
            p.residual(z, r, None);
            norm = norm.max(inf_norm(r));
        }
        let g = self.eq.rows(xi, &self.reactions(zs));
        let ng = inf_norm(&g);
        if ng.is_nan() || norm.is_nan() {
            return (g, f64::NAN);
        }
        (g, norm.max(ng))
    }

    /// Newton on all unknowns together from `zs` (scaled) and `xi` (in place); the
    /// bordered matrix solved by the Schur complement on the platform's 6 unknowns (module
    /// docs). `matrix` (every rod's factorization, B_i's solves, the Schur complement's
    /// LU), possibly kept from an earlier step, serves while it contracts and is refreshed
    /// otherwise, by `collocation::newton_with`'s rules (`collocation::Contraction`, with
    /// `theta` the rate of the matrix's last use): converged when the correction, or the
    /// error it leaves at contraction rate theta < 1/2 (theta / (1 - theta) of it), is
    /// below `tol` relative to max(1, |unknowns|), always measured with the true residual.
    /// On return `matrix` holds the last matrix (None if discarded). Err((iterations,
    /// residual)).
    #[allow(clippy::too_many_arguments)]
    fn newton(
        &mut self,
        zs: &mut [Vec<f64>],
        xi: &mut [f64; 6],
        matrix: &mut Option<Bordered>,
        theta: &mut f64,
        tol: f64,
        max_iter: usize,
        stats: &mut DynStats,
    ) -> std::result::Result<(), (usize, f64)> {
        let n = self.problems.len();
        let mut rs: Vec<Vec<f64>> = vec![vec![]; n];
        let mut rt: Vec<Vec<f64>> = vec![vec![]; n];
        let (mut g, mut norm) = self.residual(zs, xi, &mut rs);
        let mut rate = Contraction::new(theta);
        // The unknowns plus alpha times the correction.
        let trial =
            |zs: &[Vec<f64>], xi: &[f64; 6], dzs: &[Vec<f64>], dxi: &[f64; 6], alpha: f64| {
                let zt: Vec<Vec<f64>> = zs
                    .iter()
                    .zip(dzs)
                    .map(|(z, dz)| z.iter().zip(dz).map(|(a, d)| a + alpha * d).collect())
                    .collect();
                let xt: [f64; 6] = std::array::from_fn(|k| xi[k] + alpha * dxi[k]);
                (zt, xt)
            };
        for it in 0..max_iter {
            stats.newton_iterations += 1;
            // Only the start's residual can be NaN (a trial is accepted only where finite):
            // no matrix helps there.
            if !norm.is_finite() {
                return Err((it + 1, norm));
            }
            if matrix.is_none() {
                *matrix = Some(self.factor(zs, xi).ok_or((it + 1, norm))?);
                stats.jacobians += 1;
                rate.factored();
            }
            let m = matrix.as_ref().expect("matrix");
            let correction = m.correction(&rs, &g).and_then(|(dzs, dxi)| {
                let mut step = inf_norm(&dxi) / inf_norm(xi).max(1.0);
                for (z, dz) in zs.iter().zip(&dzs) {
                    step = step.max(inf_norm(dz) / inf_norm(z).max(1.0));
                }
                step.is_finite().then_some((dzs, dxi, step))
            });
            let Some((dzs, dxi, step)) = correction else {
                if rate.fresh() {
                    return Err((it + 1, norm));
                }
                *matrix = None;
                continue;
            };
            match rate.judge(it, step, tol) {
                Judged::Converged => {
                    for (z, dz) in zs.iter_mut().zip(&dzs) {
                        z.iter_mut().zip(dz).for_each(|(a, d)| *a += d);
                    }
                    xi.iter_mut().zip(&dxi).for_each(|(a, d)| *a += d);
                    self.place(xi);
                    return Ok(());
                }
                Judged::Predicted => {
                    let (zt, xt) = trial(zs, xi, &dzs, &dxi, 1.0);
                    let (_, nt) = self.residual(&zt, &xt, &mut rt);
                    if rate.confirms(nt, norm) {
                        zs.iter_mut().zip(zt).for_each(|(z, t)| *z = t);
                        *xi = xt;
                        return Ok(());
                    }
                }
                Judged::Iterate => {}
            }
            // Backtracking on the largest residual entry (a kept matrix is refreshed
            // first where its full correction does not reduce it).
            let mut alpha = 1.0;
            let mut accepted = false;
            while alpha >= 1.0 / 256.0 {
                let (zt, xt) = trial(zs, xi, &dzs, &dxi, alpha);
                let (gt, nt) = self.residual(&zt, &xt, &mut rt);
                if nt.is_finite() && nt < (1.0 - 1e-4 * alpha) * norm {
                    if !rate.accepted(alpha, step) {
                        *matrix = None; // refresh at the new iterate
                    }
                    zs.iter_mut().zip(zt).for_each(|(z, t)| *z = t);
                    *xi = xt;
                    std::mem::swap(&mut rs, &mut rt);
                    (g, norm) = (gt, nt);
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
                    if step <= 100.0 * tol {
                        // At round-off already.
                        self.place(xi);
                        return Ok(());
                    }
                    return Err((it + 1, norm));
                }
                *matrix = None;
                rate.stale_failed();
            }
        }
        Err((max_iter, norm))
    }

    /// The Newton matrix at (zs, xi) (the problems placed at xi): per rod its
    /// factorization, Y_i = -A_i^-1 B_i and C_i, and the Schur complement
    /// S = D + sum C_i Y_i, factored: the exact Jacobian at (zs, xi). None where a matrix
    /// is singular.
    fn factor(&mut self, zs: &[Vec<f64>], xi: &[f64; 6]) -> Option<Bordered> {
        // The rods' tips where the platform at xi holds them (a rejected trial point may
        // have moved them; a clamped tip's rotation enters the rods' blocks).
        self.place(xi);
        let reactions = self.reactions(zs);
        let (_, d, dg) = self.eq.rows_jacobian(xi, &reactions);
        let mut s = d;
        let mut rods = Vec::with_capacity(zs.len());
        for (i, (p, z)) in self.problems.iter().zip(zs).enumerate() {
            let fac = p.factorize(z)?;
            let n = z.len();
            let mut scratch = vec![0.0; fac.scratch_len()];
            let b = tip_rows_jacobian(&self.eq, i, p, z, xi);
            let (row0, col0) = (p.tip_rows(), p.tip_offset());
            let mut ys = Vec::with_capacity(6);
            let mut col = vec![0.0; n];
            for c in 0..6 {
                col.fill(0.0);
                for (r, br) in b.iter().enumerate() {
                    col[row0 + r] = br[c];
                }
                let mut y = vec![0.0; n];
                fac.solve(&col, &mut y, &mut scratch);
                ys.push(y);
            }
            // C_i = dG/d(reaction_i) d(reaction_i)/d(tip node, tip position), the reaction
            // being the scaled free balance (the rounded end's contact included) times
            // (F_s, M_s).
            let (ci, cr) = reaction_blocks(p, z, &dg[i]);
            let pos0 = p.tip_position_offset();
            for (c, y) in ys.iter().enumerate() {
                let cy = ci * tip_of(y, col0) + cr * position_of(y, pos0);
                for r in 0..6 {
                    s[(r, c)] += cy[r];
                }
            }
            rods.push(RodBlock {
                fac,
                ys,
                ci,
                cr,
                col0,
                pos0,
                scratch,
            });
        }
        let lu = s.lu();
        lu.is_invertible().then(|| Bordered {
            rods,
            schur: lu,
            at: zs.to_vec(),
            at_xi: *xi,
        })
    }
}

/// A rod's tip node's 16 scaled unknowns in a vector of its unknowns.
fn tip_of(v: &[f64], col0: usize) -> nalgebra::SVector<f64, NY> {
    nalgebra::SVector::<f64, NY>::from_column_slice(&v[col0..col0 + NY])
}

/// A rod's tip position's 3 scaled unknowns in a vector of its unknowns.
fn position_of(v: &[f64], pos0: usize) -> Vector3<f64> {
    Vector3::from_column_slice(&v[pos0..pos0 + 3])
}

/// The platform rows' derivatives through rod `p`'s tip reaction: with respect to its tip
/// node's scaled unknowns and to its tip position's (the rounded end's contact reads it),
/// from `dg`, the rows' derivatives with respect to the reaction (force, moment).
fn reaction_blocks(
    p: &Problem,
    z: &[f64],
    dg: &Matrix6<f64>,
) -> (nalgebra::SMatrix<f64, 6, NY>, nalgebra::SMatrix<f64, 6, 3>) {
    let (ty, tr) = p.reaction_jacobian(z);
    let unscale = |r: usize| if r < 3 { p.fs } else { p.ms };
    let dy = nalgebra::SMatrix::<f64, 6, NY>::from_fn(|r, c| ty[(r, c)] * unscale(r));
    let dr = nalgebra::SMatrix::<f64, 6, 3>::from_fn(|r, c| tr[(r, c)] * unscale(r));
    (dg * dy, dg * dr)
}

/// One rod's part of the bordered Newton matrix.
#[derive(Debug, Clone)]
struct RodBlock {
    fac: collocation::Factorization,
    ys: Vec<Vec<f64>>,
    ci: nalgebra::SMatrix<f64, 6, NY>,
    cr: nalgebra::SMatrix<f64, 6, 3>,
    col0: usize,
    pos0: usize,
    scratch: Vec<f64>,
}

/// The bordered Newton matrix of a step, factored ([`Coupled::factor`]), and the
/// unknowns it was factored at.
#[derive(Debug, Clone)]
struct Bordered {
    rods: Vec<RodBlock>,
    schur: nalgebra::LU<f64, nalgebra::U6, nalgebra::U6>,
    at: Vec<Vec<f64>>,
    at_xi: [f64; 6],
}

/// What a kept bordered matrix was computed from, so that a restored state recomputes it
/// bit for bit: the step's c0, the platform's history terms and chart base, and per rod
/// the inputs and history terms of its problem (its tip pose follows from `at_xi`); the
/// unknowns are the matrix's own (`Bordered::at`, `at_xi`).
#[derive(Debug, Clone, PartialEq)]
struct SysKey {
    platform: StepTerms,
    rods: Vec<RodKey>,
}

#[derive(Debug, Clone, PartialEq)]
struct RodKey {
    pressures: Vec<f64>,
    tensions: Vec<f64>,
    sigma: [f64; 3],
    hist: Vec<[f64; super::FIELDS]>,
}

/// The bordered Newton matrix kept across steps, with its key.
#[derive(Debug, Clone)]
struct Kept {
    matrix: Bordered,
    key: SysKey,
}

impl Bordered {
    /// The correction for residuals `rs`, `g`: w_i = -A_i^-1 r_i, then
    /// S dxi = -g - sum C_i w_i and dz_i = w_i + Y_i dxi. None if not finite.
    fn correction(&self, rs: &[Vec<f64>], g: &[f64; 6]) -> Option<(Vec<Vec<f64>>, [f64; 6])> {
        let mut rhs = Vector6::from_fn(|k, _| -g[k]);
        let mut ws = Vec::with_capacity(rs.len());
        for (b, r) in self.rods.iter().zip(rs) {
            let mut w = vec![0.0; r.len()];
            let mut scratch = b.scratch.clone();
            b.fac.solve(r, &mut w, &mut scratch);
            rhs -= b.ci * tip_of(&w, b.col0) + b.cr * position_of(&w, b.pos0);
            ws.push(w);
        }
        let dxi = self.schur.solve(&rhs)?;
        let dxi: [f64; 6] = std::array::from_fn(|k| dxi[k]);
        if !dxi.iter().all(|v| v.is_finite()) {
            return None;
        }
        let dzs = ws
            .into_iter()
            .zip(&self.rods)
            .map(|(mut w, b)| {
                for (y, d) in b.ys.iter().zip(&dxi) {
                    w.iter_mut().zip(y).for_each(|(a, b)| *a += b * d);
                }
                w
            })
            .collect();
        Some((dzs, dxi))
    }
}

/// The candidate result of a system step.
pub(super) struct SystemCandidate {
    h: f64,
    rods: Vec<Candidate>,
    motion: Motion,
    books: Books,
    work: f64,
    moved: f64,
    rate: f64,
    error: Option<f64>,
    /// The platform's converged unknowns and the step's terms (for the parameter
    /// sensitivities, `sensitivity`).
    xi: [f64; 6],
    terms: StepTerms,
}

/// A running simulation of a system of rods and their platform (module docs). Clone it to
/// branch; `save`/`restore` round-trip it exactly.
#[derive(Debug, Clone)]
pub struct SystemSimulator {
    rods: Vec<Simulator>,
    body: Body,
    opts: DynOptions,
    time: f64,
    h_prev: f64,
    h_next: f64,
    /// The platform's motion now and one step before.
    now: Motion,
    prev: Motion,
    /// The platform's force of the last step taken (a changed one does work).
    step_force: [f64; 3],
    /// The platform's share of the books: work done on it so far (the rods' wrenches and
    /// its moment), that work's magnitude, and its moment's power now.
    work: f64,
    moved: f64,
    rate: f64,
    books: Books,
    /// The bordered Newton matrix kept across steps (as the single rod keeps its own,
    /// `Simulator`) and Newton's contraction rate with it at the last step.
    kept: Option<Kept>,
    theta: f64,
    /// The start's stability verdict (`solve_system`'s test of the whole system's
    /// equilibrium; None where not assessed): a fixed step may hold an unstable start.
    start_stable: Option<bool>,
    /// Forward parameter sensitivities, when tracked (`sensitivity`).
    sens: Option<Box<sensitivity::SysTracker>>,
    /// The points read as markers (`SystemSimulator::set_markers`; a rod's are its
    /// simulator's markers too, in this order).
    markers: Vec<crate::sensitivity::system::SystemMarker>,
    pub stats: DynStats,
}

/// Layout version of [`SystemSimulator::save`]. 2: the kept Newton matrix's key and rate.
const SYSTEM_STATE_VERSION: f64 = 2.0;
/// First number of a saved system state ("softsys" in a number).
const SYSTEM_STATE_MAGIC: f64 = 50_770_219.0;

pub(crate) fn check_inertia(j: &[[f64; 3]; 3]) -> Result<()> {
    for (i, row) in j.iter().enumerate() {
        for (k, v) in row.iter().enumerate() {
            if !v.is_finite() {
                return Err(SoftrodError::invalid(
                    format!("platform_inertia[{i}][{k}]"),
                    v,
                    "must be a finite number",
                ));
            }
        }
    }
    let scale = j.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    // Symmetric to round-off of a tensor written out to ~12 digits.
    for (i, k) in [(0, 1), (0, 2), (1, 2)] {
        if (j[i][k] - j[k][i]).abs() > 1e-12 * scale {
            return Err(SoftrodError::invalid(
                format!("platform_inertia[{i}][{k}]"),
                j[i][k],
                format!("an inertia tensor is symmetric: [{k}][{i}] is {}", j[k][i]),
            ));
        }
    }
    let m = nalgebra::Matrix3::from_fn(|a, b| j[a][b]);
    let ev = m.symmetric_eigen().eigenvalues;
    let emin = ev.min();
    if emin < -1e-12 * scale {
        return Err(SoftrodError::invalid(
            "platform_inertia",
            format!("{j:?}"),
            format!("an inertia tensor about the centre of mass is positive semidefinite (smallest eigenvalue {emin:.3e} kg m^2)"),
        ));
    }
    Ok(())
}

/// `e` of rod `i` named by the rod: a field gets the prefix `rods[i].` (unless it has one),
/// a state's message `rods[i]: `.
fn on_rod(e: SoftrodError, i: usize) -> SoftrodError {
    match e {
        SoftrodError::InvalidParameter { field, value, rule } if !field.starts_with("rods[") => {
            SoftrodError::InvalidParameter {
                field: format!("rods[{i}].{field}"),
                value,
                rule,
            }
        }
        other => other.map_message(|m| format!("rods[{i}]: {m}")),
    }
}

impl SystemSimulator {
    /// Start a system at rest in its static equilibrium under the inputs at t = 0
    /// (`solve_system`'s, refined on the collocation grids). `platform`: as in the
    /// statics (its nominal pose seeds the equilibrium's search); `inertia`: the
    /// platform's inertia tensor about its centre of mass in the platform frame, kg m^2
    /// (zero: none). A rod's obstacles and its design's tip loads, dead or follower
    /// (`[tip] frame`), act on it as on a held tip (module docs). Refused by name: the
    /// midpoint scheme, an inertia that is not symmetric positive semidefinite, inputs that
    /// do not match a rod, a rod with a stiffness-mapped section and no map
    /// (`rods[i].sections[k].law.stiffness_map`), pressures its map refuses
    /// (`rods[i].pressures[k]`; at a step too). A rod's map is evaluated at every step's
    /// pressures, as a lone rod's.
    pub fn new(
        rods: Vec<DynRod>,
        platform: Platform,
        inertia: [[f64; 3]; 3],
        opts: DynOptions,
    ) -> Result<Self> {
        opts.validate()?;
        if opts.scheme == Scheme::Midpoint {
            return Err(SoftrodError::invalid(
                "scheme",
                opts.scheme.name(),
                "a system of rods is integrated with 'bdf-alpha' (its rods' tips are held, which the midpoint rule does not carry)",
            ));
        }
        check_inertia(&inertia)?;
        let mut loads = Vec::with_capacity(rods.len());
        for (i, r) in rods.iter().enumerate() {
            let name = format!("rods[{i}].");
            r.rod
                .check_pressures(&r.pressures)
                .map_err(|e| rename_field(e, "pressures", &format!("{name}pressures")))?;
            r.rod
                .check_tensions(&r.tensions)
                .map_err(|e| rename_field(e, "tensions", &format!("{name}tensions")))?;
            // A mapped section needs its map (sigma is never assumed to be 1): refused
            // before the statics, naming the rod.
            super::check_dynamic_laws(&r.rod, &r.sigma_map).map_err(|e| on_rod(e, i))?;
            let sigma = r.sigma_map.eval(&r.pressures).map_err(|e| on_rod(e, i))?;
            loads.push(Loads {
                pressures: r.pressures.clone(),
                tensions: r.tensions.clone(),
                tip_force: r.rod.spec.tip.force,
                tip_moment: r.rod.spec.tip.moment,
                tip_frame: r.rod.spec.tip.frame,
                stiffness_scale: sigma,
            });
        }
        // At rest the regularised friction carries no force: the start is the frictionless
        // system's equilibrium (`statics::contact::without_friction`).
        let smooth: Vec<Option<Rod>> = rods
            .iter()
            .map(|r| crate::statics::contact::without_friction(&r.rod))
            .collect();
        let sys: Vec<SystemRod> = rods
            .iter()
            .zip(&loads)
            .zip(&smooth)
            .map(|((r, l), s)| SystemRod {
                rod: s.as_ref().unwrap_or(&r.rod),
                loads: l.clone(),
                attachment: r.attachment,
                attachment_rotation: r.attachment_rotation,
            })
            .collect();
        statics_system::validate(&sys, &platform)?;
        let sol = solve_system(&sys, &platform, None, &SolverOptions::default()).map_err(|e| {
            e.map_message(|m| format!("the initial static state of the system: {m}"))
        })?;
        drop(sys);
        let start_stable = sol.stable;
        let n = rods.len();
        let body = Body {
            mass: platform.mass,
            com: platform.com_offset,
            inertia,
            gravity: platform.gravity,
            force: platform.force,
            moment: platform.moment,
            attach: rods
                .iter()
                .map(|r| (r.attachment, r.attachment_rotation))
                .collect(),
            ls: rods.iter().map(|r| r.rod.length).sum::<f64>() / n as f64,
            fs: rods.iter().map(|r| r.rod.force_scale).sum(),
            ms: rods.iter().map(|r| r.rod.force_scale * r.rod.length).sum(),
        };
        let r0 = sol.platform_rotation;
        let mut xi = [0.0; 6];
        for k in 0..3 {
            xi[k] = sol.platform_position[k] / body.ls;
        }
        let rest = PlatformEq::rest(&body, r0);
        let mut sims = Vec::with_capacity(n);
        for (i, r) in rods.into_iter().enumerate() {
            let (f, m) = (r.rod.spec.tip.force, r.rod.spec.tip.moment);
            let sim = Simulator::with_constraint(
                r.rod,
                &r.pressures,
                &r.tensions,
                Initial::Static,
                opts,
                r.sigma_map,
                f,
                m,
                rest.target(i, &xi),
            )
            .map_err(|e| on_rod(e, i))?;
            sims.push(sim);
        }
        // The rest state of this discretisation: the rods' collocation equilibria and the
        // platform's balance together (c0 = 0).
        let zero = [0.0; super::FIELDS];
        let models: Vec<Vec<collocation::SectionModel>> = sims
            .iter()
            .map(|s| s.models_at(&s.pressures, &s.tensions, &s.sigma, 0.0))
            .collect();
        let hist0: Vec<Vec<[f64; super::FIELDS]>> =
            sims.iter().map(|s| vec![zero; s.slots.len()]).collect();
        let mut stats = DynStats::default();
        let mut zs: Vec<Vec<f64>>;
        {
            let problems: Vec<Problem> = sims
                .iter()
                .zip(&models)
                .zip(&hist0)
                .map(|((s, m), h)| {
                    // With the rod's obstacles, as its step and `rest_at` carry them.
                    Problem::new(
                        &s.rod,
                        &s.grid,
                        m,
                        0.0,
                        h,
                        s.tip_body(s.tip_force, s.tip_moment),
                    )
                    .with_contact()
                    .with_end(super::end_target(&s.end))
                })
                .collect();
            zs = problems
                .iter()
                .zip(&sims)
                .map(|(p, s)| to_scaled(p, &s.z))
                .collect();
            let mut c = Coupled { problems, eq: rest };
            // The rest state's matrix (c0 = 0) does not serve the steps: not kept.
            let (mut matrix, mut theta) = (None, 1.0);
            c.newton(
                &mut zs,
                &mut xi,
                &mut matrix,
                &mut theta,
                opts.tol.min(1e-10),
                100,
                &mut stats,
            )
            .map_err(|(iterations, residual)| SoftrodError::NotConverged {
                iterations,
                residual,
                load_factor: 1.0,
                reason:
                    "the initial static state of the system did not solve on the collocation grids"
                        .into(),
            })?;
        }
        let rest = PlatformEq::rest(&body, r0);
        for (i, (s, z)) in sims.iter_mut().zip(&zs).enumerate() {
            s.end = rest.target(i, &xi);
            s.end_now = s.end;
            s.rest_at(z, Initial::Static)
                .map_err(|e| e.map_message(|m| format!("rods[{i}]: {m}")))?;
        }
        let k = rest.kin(&xi);
        let now = Motion::at_rest(k.p, k.rot);
        let mut out = SystemSimulator {
            rods: sims,
            step_force: body.force,
            body,
            opts,
            time: 0.0,
            h_prev: opts.dt,
            h_next: opts.dt,
            now,
            prev: now,
            work: 0.0,
            moved: 0.0,
            rate: 0.0,
            books: Books::default(),
            kept: None,
            theta: 1.0,
            start_stable,
            sens: None,
            markers: vec![],
            stats,
        };
        let (kinetic, potential) = out.platform_energy(&now);
        let mut e = out.rods_energy();
        e.kinetic += kinetic;
        e.potential += potential;
        out.books = Books {
            now: e,
            e0: e.total(),
            elastic0: e.elastic,
            potential0: e.potential,
            max_kinetic: e.kinetic,
            ..Books::default()
        };
        Ok(out)
    }

    /// The sum of the rods' books now.
    fn rods_energy(&self) -> Energy {
        let mut e = Energy::default();
        for r in &self.rods {
            let b = r.books.now;
            e.kinetic += b.kinetic;
            e.elastic += b.elastic;
            e.potential += b.potential;
            e.work_in += b.work_in;
            e.dissipated += b.dissipated;
        }
        e
    }

    /// The platform's kinetic and potential (gravity, its dead force at p) energy.
    fn platform_energy(&self, m: &Motion) -> (f64, f64) {
        let b = &self.body;
        let wxc = cross(&m.w, &b.com);
        let vc = rotate(&m.rot, &wxc);
        let v: [f64; 3] = std::array::from_fn(|k| m.v[k] + vc[k]);
        let jw = rotate(&b.inertia, &m.w);
        let kinetic = 0.5 * b.mass * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
            + 0.5 * (0..3).map(|k| m.w[k] * jw[k]).sum::<f64>();
        let cw = rotate(&m.rot, &b.com);
        let potential = -(0..3)
            .map(|k| b.mass * b.gravity[k] * (m.p[k] + cw[k]) + b.force[k] * m.p[k])
            .sum::<f64>();
        (kinetic, potential)
    }

    /// The power of the platform's moment at motion `m` (the force has a potential).
    fn moment_power(&self, m: &Motion) -> f64 {
        let w = rotate(&m.rot, &m.w);
        (0..3).map(|k| self.body.moment[k] * w[k]).sum()
    }

    /// One output step of dt with each rod's commanded pressures held over it (Pa, one
    /// list per rod): one step, substeps where Newton fails, or error-controlled steps
    /// (adaptive), as [`Simulator::step`].
    pub fn step(&mut self, commands: &[Vec<f64>]) -> Result<()> {
        if commands.len() != self.rods.len() {
            return Err(SoftrodError::invalid(
                "commands",
                format!("{} lists", commands.len()),
                format!(
                    "one list of pressures per rod: this system has {} rods",
                    self.rods.len()
                ),
            ));
        }
        for (i, (c, r)) in commands.iter().zip(&self.rods).enumerate() {
            crate::spec::validate_pressures(c, r.rod.n_channels)
                .map_err(|e| rename_field(e, "pressures", &format!("commands[{i}]")))?;
        }
        let flat: Vec<f64> = commands.iter().flatten().copied().collect();
        drive(self, &flat, None)?;
        for r in &mut self.rods {
            r.time = self.time;
            r.stats.steps = self.stats.steps;
        }
        Ok(())
    }

    /// Set up every rod's step and the platform's equations of a step of length h.
    fn prepare(&mut self, h: f64, command: &[f64]) -> Result<(Vec<Prep>, Bdf)> {
        let mut preps = Vec::with_capacity(self.rods.len());
        let mut o = 0;
        for (i, r) in self.rods.iter_mut().enumerate() {
            let nc = r.rod.n_channels;
            // A rod's stiffness map may refuse the step's pressures: name the rod.
            preps.push(
                r.prepare(h, &command[o..o + nc])
                    .map_err(|e| on_rod(e, i))?,
            );
            o += nc;
        }
        let bdf = preps[0].bdf;
        Ok((preps, bdf))
    }

    /// The predicted platform unknowns at a step of length h: linear extrapolation.
    fn guess(&self, h: f64) -> [f64; 6] {
        let ratio = h / self.h_prev;
        let rel: [[f64; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                (0..3)
                    .map(|k| self.prev.rot[i][k] * self.now.rot[j][k])
                    .sum()
            })
        });
        let back = cayley_inverse(&rel);
        std::array::from_fn(|k| {
            if k < 3 {
                (self.now.p[k] + ratio * (self.now.p[k] - self.prev.p[k])) / self.body.ls
            } else {
                -ratio * back[k - 3]
            }
        })
    }

    fn attempt_step(&mut self, h: f64, command: &[f64]) -> Result<SystemCandidate> {
        let (mut preps, bdf) = self.prepare(h, command)?;
        let eq = PlatformEq::step(&self.body, &bdf, &self.now, &self.prev);
        let mut xi = self.guess(h);
        let mut zs: Vec<Vec<f64>> = preps
            .iter()
            .zip(&self.rods)
            .map(|(p, r)| p.guess.iter().zip(&r.scales).map(|(a, b)| a / b).collect())
            .collect();
        let problems: Vec<Problem> = preps
            .iter()
            .zip(&self.rods)
            .map(|(p, r)| p.problem(&r.rod, &r.grid, r.scale_c0()))
            .collect();
        let mut c = Coupled { problems, eq };
        // The matrix kept from an earlier step serves a step whose c0 is within REUSE_C0
        // of its own (the single rod's rule, `Simulator::attempt`): a changed step length
        // (substeps, adaptive steps, a restored state of another dt) changes c0 and with
        // it every rod's inertia and damping blocks and the platform's; past that the
        // modified Newton would contract poorly, so the step refactors at once. The
        // matrix of the rest state (c0 = 0) is never kept, so the first step factors its
        // own. Smaller changes (c0, the history terms, the inputs) are left to the rate
        // test, which refreshes the matrix when it contracts by less than 1/4.
        let c0 = c.eq.t.c0;
        let old = self
            .kept
            .take()
            .filter(|k| (k.key.platform.c0 / c0 - 1.0).abs() <= super::REUSE_C0);
        let (mut matrix, old_key) = match old {
            Some(k) => (Some(k.matrix), Some(k.key)),
            None => (None, None),
        };
        let jacobians = self.stats.jacobians;
        let solved = c.newton(
            &mut zs,
            &mut xi,
            &mut matrix,
            &mut self.theta,
            self.opts.tol,
            self.opts.max_iter,
            &mut self.stats,
        );
        // Keep the matrix, and what it was computed from, for the next step: the old key
        // where this step factored none.
        self.kept = matrix.map(|matrix| {
            let key = match old_key {
                Some(k) if self.stats.jacobians == jacobians => k,
                _ => SysKey {
                    platform: c.eq.t,
                    rods: preps
                        .iter()
                        .map(|p| RodKey {
                            pressures: p.solve_p.clone(),
                            tensions: p.solve_t.clone(),
                            sigma: p.solve_sigma,
                            hist: p.hist.clone(),
                        })
                        .collect(),
                },
            };
            Kept { matrix, key }
        });
        let Coupled { problems, eq } = c;
        drop(problems);
        if let Err((it, res)) = solved {
            return Err(preps[0].not_converged(self.time, it, res));
        }
        let k = eq.kin(&xi);
        let terms = eq.t;
        let motion = Motion {
            p: k.p,
            rot: k.rot,
            v: k.v,
            w: k.w,
            a: k.a,
            wt: k.wt,
        };
        let targets: Vec<TipConstraint> = (0..self.rods.len()).map(|i| eq.target(i, &xi)).collect();
        let w_new = -self.opts.alpha_eff();
        let mut cands = Vec::with_capacity(self.rods.len());
        let mut reaction_on_rods = 0.0;
        for ((r, mut prep), (z, end)) in self
            .rods
            .iter_mut()
            .zip(preps.drain(..))
            .zip(zs.into_iter().zip(targets))
        {
            prep.end = end;
            let c = r.finish(prep, z, None)?;
            reaction_on_rods += reaction_work(&r.end_now, &c.end, r.reaction, c.reaction, w_new);
            cands.push(c);
        }
        // The platform's books: the rods' wrenches on it do minus their reactions' work
        // on the rods (the same quadrature, so the two cancel in the sum), its moment's by
        // the trapezoidal rule, a changed force -dF . p at the scheme's weights.
        let rate = self.moment_power(&motion);
        let df: [f64; 3] = std::array::from_fn(|j| self.body.force[j] - self.step_force[j]);
        let fin = -(0..3)
            .map(|j| df[j] * ((1.0 - w_new) * self.now.p[j] + w_new * motion.p[j]))
            .sum::<f64>();
        let dw = -reaction_on_rods + 0.5 * h * (self.rate + rate) + fin;
        let work = self.work + dw;
        let moved = self.moved + dw.abs();
        let (kinetic, potential) = self.platform_energy(&motion);
        let mut e = Energy::default();
        let mut moved_in = moved;
        for c in &cands {
            let b = c.books.now;
            e.kinetic += b.kinetic;
            e.elastic += b.elastic;
            e.potential += b.potential;
            e.work_in += b.work_in;
            e.dissipated += b.dissipated;
            moved_in += c.books.moved_in;
        }
        e.kinetic += kinetic;
        e.potential += potential;
        e.work_in += work;
        let mut books = self.books;
        books.now = e;
        books.moved_in = moved_in;
        books.max_kinetic = books.max_kinetic.max(e.kinetic);
        books.max_elastic = books.max_elastic.max((e.elastic - books.elastic0).abs());
        books.max_potential = books
            .max_potential
            .max((e.potential - books.potential0).abs());
        let floor = 1e-10
            * self
                .rods
                .iter()
                .map(|r| r.rod.force_scale * r.rod.length)
                .sum::<f64>();
        check_energy(
            &books,
            &self.opts,
            floor,
            self.time + h,
            h,
            self.stats.steps + 1,
        )?;
        let error = cands
            .iter()
            .map(|c| c.error)
            .try_fold(0.0f64, |m, e| e.map(|e| m.max(e)));
        Ok(SystemCandidate {
            h,
            rods: cands,
            motion,
            books,
            work,
            moved,
            rate,
            error,
            xi,
            terms,
        })
    }

    fn commit(&mut self, c: SystemCandidate) {
        for (r, rc) in self.rods.iter_mut().zip(c.rods) {
            r.commit(rc);
            r.end = r.end_now;
        }
        self.prev = self.now;
        self.now = c.motion;
        self.books = c.books;
        self.work = c.work;
        self.moved = c.moved;
        self.rate = c.rate;
        self.step_force = self.body.force;
        self.h_prev = c.h;
        self.time += c.h;
        self.stats.internal_steps += 1;
    }
}

impl Stepping for SystemSimulator {
    type Candidate = SystemCandidate;
    fn options(&self) -> DynOptions {
        self.opts
    }
    fn clock(&self) -> f64 {
        self.time
    }
    fn time_mut(&mut self) -> &mut f64 {
        &mut self.time
    }
    fn h_next(&mut self) -> &mut f64 {
        &mut self.h_next
    }
    fn counters(&mut self) -> &mut DynStats {
        &mut self.stats
    }
    fn attempt(&mut self, h: f64, command: &[f64]) -> Result<SystemCandidate> {
        self.attempt_step(h, command)
    }
    fn error(c: &SystemCandidate) -> Option<f64> {
        c.error
    }
    fn accept(&mut self, c: SystemCandidate) -> Result<()> {
        self.advance_sensitivity(&c)?;
        self.commit(c);
        Ok(())
    }
}

impl SystemSimulator {
    /// The start's stability verdict: Some(false) when the system started from an unstable
    /// equilibrium (a small disturbance grows; a coarse step may still hold it), None where
    /// `solve_system` did not assess it.
    pub fn start_stable(&self) -> Option<bool> {
        self.start_stable
    }

    pub fn time(&self) -> f64 {
        self.time
    }
    pub fn options(&self) -> &DynOptions {
        &self.opts
    }
    /// The rods' simulations (shape, tip, `tip_reaction`: the wrench the platform applies
    /// to the tip, energy books with that wrench's work).
    pub fn rods(&self) -> &[Simulator] {
        &self.rods
    }
    /// The platform's position (m, world) and rotation now.
    pub fn platform_pose(&self) -> ([f64; 3], [[f64; 3]; 3]) {
        (self.now.p, self.now.rot)
    }
    /// The platform's velocity (m/s, world, of its origin) and angular velocity (rad/s,
    /// world) now.
    pub fn platform_velocity(&self) -> ([f64; 3], [f64; 3]) {
        (self.now.v, rotate(&self.now.rot, &self.now.w))
    }
    /// Energies now (rods and platform) and the cumulative exchanges since t = 0, J.
    pub fn energy_books(&self) -> Energy {
        self.books.now
    }
    /// The energy balance E - E(0) - W_in + D now (zero for the exact motion), J.
    pub fn energy_balance(&self) -> f64 {
        self.books.balance()
    }
    /// The platform's external force (N, world, at its origin) and moment (N m, world) now.
    pub fn platform_loads(&self) -> ([f64; 3], [f64; 3]) {
        (self.body.force, self.body.moment)
    }

    /// Change a rod's tendon tensions from the next step on (checked first).
    pub fn set_tensions(&mut self, rod: usize, tensions: &[f64]) -> Result<()> {
        let n = self.rods.len();
        let r = self.rods.get_mut(rod).ok_or_else(|| {
            SoftrodError::invalid("rod", rod, format!("this system has rods 0..{n}"))
        })?;
        r.set_tensions(tensions)
            .map_err(|e| rename_field(e, "tensions", &format!("rods[{rod}].tensions")))
    }

    /// Change the platform's external force (N, world, at its origin) and moment (N m,
    /// world) from the next step on.
    pub fn set_platform_loads(&mut self, force: [f64; 3], moment: [f64; 3]) -> Result<()> {
        for (name, v) in [("platform.force", &force), ("platform.moment", &moment)] {
            if let Some(k) = v.iter().position(|x| !x.is_finite()) {
                return Err(SoftrodError::invalid(
                    format!("{name}[{k}]"),
                    v[k],
                    "must be a finite number",
                ));
            }
        }
        self.body.force = force;
        self.body.moment = moment;
        Ok(())
    }

    /// The unknowns now: every rod's physical unknowns (`Simulator::unknowns`), then the
    /// platform's position (m) and a zero rotation increment (rad).
    pub fn unknowns(&self) -> Vec<f64> {
        let mut x: Vec<f64> = self.rods.iter().flat_map(|r| r.z.iter().copied()).collect();
        x.extend_from_slice(&self.now.p);
        x.extend_from_slice(&[0.0; 3]);
        x
    }

    /// The coupled equations of a step of length dt from the current state at the current
    /// inputs: every residual (the rods' scaled ones, then the platform's 6 rows) at
    /// unknowns `x` (layout of [`SystemSimulator::unknowns`]; the rotation as the Cayley
    /// increment from the current rotation) and the dense exact Jacobian with respect to x
    /// (for tests against finite differences).
    pub fn step_residual_and_jacobian(&self, x: &[f64]) -> Result<(Vec<f64>, Vec<Vec<f64>>)> {
        let mut me = self.clone();
        let n: usize = me.rods.iter().map(|r| r.z.len()).sum::<usize>() + 6;
        if x.len() != n {
            return Err(SoftrodError::invalid(
                "x",
                format!("{} values", x.len()),
                format!("this system's step has {n} unknowns (SystemSimulator::unknowns)"),
            ));
        }
        let command: Vec<f64> = me.rods.iter().flat_map(|r| r.pressures.clone()).collect();
        let (preps, bdf) = me.prepare(self.opts.dt, &command)?;
        let eq = PlatformEq::step(&me.body, &bdf, &me.now, &me.prev);
        let problems: Vec<Problem> = preps
            .iter()
            .zip(&me.rods)
            .map(|(p, r)| p.problem(&r.rod, &r.grid, r.scale_c0()))
            .collect();
        let mut zs = Vec::new();
        let mut scales = Vec::new();
        let mut o = 0;
        for p in &problems {
            let n = p.unknowns();
            scales.push(unknown_scales(p, n));
            zs.push(to_scaled(p, &x[o..o + n]));
            o += n;
        }
        let xi: [f64; 6] = std::array::from_fn(|k| {
            if k < 3 {
                x[o + k] / me.body.ls
            } else {
                x[o + k]
            }
        });
        let dim = o + 6;
        let mut c = Coupled { problems, eq };
        let mut rs = vec![vec![]; zs.len()];
        let (g, _) = c.residual(&zs, &xi, &mut rs);
        let mut jac = vec![vec![0.0; dim]; dim];
        let reactions = c.reactions(&zs);
        let (_, d, dg) = c.eq.rows_jacobian(&xi, &reactions);
        // d/dx of the platform's unknowns: position in m (xi = p / L_s), rotation as is.
        let col_scale = |k: usize| if k < 3 { 1.0 / me.body.ls } else { 1.0 };
        let mut o = 0;
        for (i, (p, z)) in c.problems.iter().zip(&zs).enumerate() {
            let n = z.len();
            let dense = p.dense_jacobian(z);
            for (r, row) in dense.iter().enumerate() {
                for (k, v) in row.iter().enumerate() {
                    jac[o + r][o + k] = v / scales[i][k];
                }
            }
            let b = tip_rows_jacobian(&c.eq, i, p, z, &xi);
            for (r, br) in b.iter().enumerate() {
                for (k, v) in br.iter().enumerate() {
                    jac[o + p.tip_rows() + r][dim - 6 + k] = v * col_scale(k);
                }
            }
            let (ci, cr) = reaction_blocks(p, z, &dg[i]);
            let (t0, p0) = (p.tip_offset(), p.tip_position_offset());
            for r in 0..6 {
                for k in 0..NY {
                    jac[dim - 6 + r][o + t0 + k] = ci[(r, k)] / scales[i][t0 + k];
                }
                for k in 0..3 {
                    jac[dim - 6 + r][o + p0 + k] = cr[(r, k)] / scales[i][p0 + k];
                }
            }
            o += n;
        }
        for r in 0..6 {
            for k in 0..6 {
                jac[dim - 6 + r][dim - 6 + k] = d[(r, k)] * col_scale(k);
            }
        }
        let mut res: Vec<f64> = rs.into_iter().flatten().collect();
        res.extend_from_slice(&g);
        Ok((res, jac))
    }

    /// The complete state as a flat list of numbers (the rods' saved states, the
    /// platform's motion, books and counters); [`SystemSimulator::restore`] continues
    /// from it bit for bit.
    pub fn save(&self) -> Vec<f64> {
        let mut w = Writer(Vec::new());
        w.f(SYSTEM_STATE_MAGIC);
        w.f(SYSTEM_STATE_VERSION);
        w.n(self.rods.len());
        w.f(self.time);
        w.f(self.h_prev);
        w.f(self.h_next);
        w.all(&self.now.numbers());
        w.all(&self.prev.numbers());
        w.all(&self.body.force);
        w.all(&self.body.moment);
        w.all(&self.step_force);
        w.all(&[self.work, self.moved, self.rate]);
        w.all(&self.books.numbers());
        let st = &self.stats;
        for c in [
            st.steps,
            st.internal_steps,
            st.rejected,
            st.newton_iterations,
            st.jacobians,
        ] {
            w.n(c);
        }
        w.f(self.theta);
        match &self.kept {
            None => w.f(0.0),
            Some(Kept { matrix, key }) => {
                w.f(1.0);
                let t = &key.platform;
                w.f(t.c0);
                for v in [&t.hp, &t.hphi, &t.hv, &t.hw] {
                    w.all(v);
                }
                w.all(t.r_n.as_flattened());
                w.all(&matrix.at_xi);
                for (z, k) in matrix.at.iter().zip(&key.rods) {
                    w.vec(z);
                    w.vec(&k.pressures);
                    w.vec(&k.tensions);
                    w.all(&k.sigma);
                    w.arrays(&k.hist);
                }
            }
        }
        for r in &self.rods {
            w.vec(&r.save());
        }
        w.0
    }

    /// Continue from a state saved by [`SystemSimulator::save`] of the same system (same
    /// rods and discretisations).
    pub fn restore(&mut self, data: &[f64]) -> Result<()> {
        let bad = |rule: &str| {
            SoftrodError::invalid("state", format!("{} numbers", data.len()), rule.to_string())
        };
        let mut r = Reader { data, pos: 0 };
        if r.f()? != SYSTEM_STATE_MAGIC {
            return Err(bad("is not a state saved by SystemSimulator::save"));
        }
        if r.f()? != SYSTEM_STATE_VERSION {
            return Err(bad("has another layout version than this softrod's"));
        }
        if r.n()? != self.rods.len() {
            return Err(bad("was saved from a system with another number of rods"));
        }
        let mut next = self.clone();
        // A restored state tracks no sensitivities (as a rod's, `Simulator::restore`).
        next.sens = None;
        next.time = r.f()?;
        next.h_prev = r.f()?;
        next.h_next = r.f()?;
        next.now = Motion::from_numbers(&r.fixed()?);
        next.prev = Motion::from_numbers(&r.fixed()?);
        next.body.force = r.fixed()?;
        next.body.moment = r.fixed()?;
        next.step_force = r.fixed()?;
        let [work, moved, rate]: [f64; 3] = r.fixed()?;
        (next.work, next.moved, next.rate) = (work, moved, rate);
        next.books = Books::from_numbers(&r.fixed()?);
        next.stats = DynStats {
            steps: r.n()?,
            internal_steps: r.n()?,
            rejected: r.n()?,
            newton_iterations: r.n()?,
            jacobians: r.n()?,
        };
        next.theta = r.f()?;
        let kept = if r.f()? == 1.0 {
            let c0 = r.f()?;
            let (hp, hphi, hv, hw) = (r.fixed()?, r.fixed()?, r.fixed()?, r.fixed()?);
            let rn: [f64; 9] = r.fixed()?;
            let r_n = std::array::from_fn(|i| std::array::from_fn(|j| rn[3 * i + j]));
            let at_xi: [f64; 6] = r.fixed()?;
            let mut at = Vec::with_capacity(next.rods.len());
            let mut rods = Vec::with_capacity(next.rods.len());
            for rod in &next.rods {
                let z = r.vec()?;
                let k = RodKey {
                    pressures: r.vec()?,
                    tensions: r.vec()?,
                    sigma: r.fixed()?,
                    hist: r.arrays()?,
                };
                if z.len() != rod.z.len()
                    || k.pressures.len() != rod.rod.n_channels
                    || k.tensions.len() != rod.rod.n_tendons
                    || k.hist.len() != rod.slots.len()
                {
                    return Err(bad("does not match this system's discretisation"));
                }
                at.push(z);
                rods.push(k);
            }
            Some((
                SysKey {
                    platform: StepTerms {
                        c0,
                        hp,
                        hphi,
                        hv,
                        hw,
                        r_n,
                    },
                    rods,
                },
                at,
                at_xi,
            ))
        } else {
            None
        };
        for (i, rod) in next.rods.iter_mut().enumerate() {
            let v = r.vec()?;
            rod.restore(&v)
                .map_err(|e| e.map_message(|m| format!("rods[{i}]: {m}")))
                .map_err(|e| rename_field(e, "state", &format!("state.rods[{i}]")))?;
        }
        if r.pos != data.len() {
            return Err(bad(
                "has trailing numbers: not a state saved by SystemSimulator::save",
            ));
        }
        // The kept matrix is recomputed from what it was computed from (the same numbers,
        // so the run continues bit for bit; none where it is singular now, which cannot
        // happen for a state this system saved).
        next.kept = kept.and_then(|(key, at, at_xi)| {
            let matrix = next.factor_at(&key, &at, &at_xi)?;
            Some(Kept { matrix, key })
        });
        *self = next;
        Ok(())
    }

    /// The bordered matrix of the step described by `key`, factored at (`at`, `at_xi`).
    fn factor_at(&self, key: &SysKey, at: &[Vec<f64>], at_xi: &[f64; 6]) -> Option<Bordered> {
        let models: Vec<Vec<collocation::SectionModel>> = self
            .rods
            .iter()
            .zip(&key.rods)
            .map(|(s, k)| s.models_at(&k.pressures, &k.tensions, &k.sigma, key.platform.c0))
            .collect();
        let problems: Vec<Problem> = self
            .rods
            .iter()
            .zip(&models)
            .zip(&key.rods)
            .map(|((s, m), k)| {
                super::step_problem(
                    &s.rod,
                    &s.grid,
                    s.scale_c0(),
                    m,
                    key.platform.c0,
                    &k.hist,
                    s.tip_body(s.tip_force, s.tip_moment),
                )
            })
            .collect();
        let eq = PlatformEq {
            body: &self.body,
            t: key.platform,
        };
        // `factor` holds each rod's tip where the platform at at_xi holds it.
        Coupled { problems, eq }.factor(at, at_xi)
    }

    /// Drop the kept Newton matrix: the next step factors its own (a run that calls this
    /// before every step refactors at every step's start, as the system did before it
    /// kept its matrix; tests compare the two).
    pub fn forget_matrix(&mut self) {
        self.kept = None;
        self.theta = 1.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Cayley chart: cay^-1 inverts cay, and the rate formula is the derivative of
    /// cay(phi(t)) (central differences, truncation ~1e-10).
    #[test]
    fn cayley_chart() {
        let phi = [0.3, -0.2, 0.5];
        let back = cayley_inverse(&cayley(&phi));
        for k in 0..3 {
            assert!((back[k] - phi[k]).abs() < 1e-14, "{back:?}");
        }
        let dphi = [0.7, 0.1, -0.4];
        let h = 1e-6;
        let at = |t: f64| cayley(&std::array::from_fn(|k| phi[k] + t * dphi[k]));
        let (a, b, r) = (at(h), at(-h), at(0.0));
        // R_t R^T = w^
        let rt: [[f64; 3]; 3] =
            std::array::from_fn(|i| std::array::from_fn(|j| (a[i][j] - b[i][j]) / (2.0 * h)));
        let what: [[f64; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|j| (0..3).map(|k| rt[i][k] * r[j][k]).sum())
        });
        let w = cayley_rate(&phi, &dphi);
        let fd = [what[2][1], what[0][2], what[1][0]];
        for k in 0..3 {
            // Central differences at h = 1e-6: truncation ~h^2, round-off ~1e-16 / h.
            assert!((w[k] - fd[k]).abs() < 1e-8, "{w:?} vs {fd:?}");
        }
    }
}
