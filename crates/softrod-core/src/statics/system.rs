//! A system of rods whose tips hold one rigid platform: a parallel continuum robot (Black,
//! Till & Rucker, "Parallel continuum robots: modeling, analysis, and actuation-based force
//! sensing", IEEE T-RO 2018, doi 10.1109/TRO.2017.2753829). docs/model.md "Systems of
//! rods".
//!
//! Each rod is clamped at its own base (its design's mounting) and clamped at its tip to
//! the platform at an attachment: an offset o_i and a rotation A_i of the rod's tip frame,
//! both in the platform frame. Unknowns: each rod's scaled base wrench x_i = (n_i(0)/F_s,
//! m_i(0)/(F_s L)) and the platform pose (position p / L_s, rotation R_p = exp(phi) R_0
//! from its nominal rotation R_0, updated on the group: R_p <- exp(psi) R_p). Residual,
//! per rod: (r_i(L) - p - R_p o_i)/L_s and e((R_p A_i)^T R_i(L)) (`constraint::orientation_error`); then the platform's balance:
//! F + m_p g - sum F_i = 0 and M + (R_p c) x m_p g - sum (M_i + (r_i(L) - p) x F_i) = 0
//! about p, with (F_i, M_i) the wrench the platform applies to rod i's tip (its tip
//! reaction), scaled by the sums of the rods' force and moment scales.
//!
//! Exact Jacobian: each rod is integrated in `Jet<6>` (its own unknowns), and the rows it
//! enters are formed in `Jet<12>` (its unknowns and the platform's six increments), so the
//! block-sparse Jacobian is exact at the cost of one dual integration per rod. Newton and
//! continuation as `constraint::follow_path`: loads and the platform load ramped from zero,
//! the attachments moved from where the unloaded rods' tips are (relative to the platform's
//! nominal pose) to the given ones, kept on the stable path and on the side of each rod's
//! obstacles that the unloaded rods are on (docs/contact.md, "The side an obstacle is on").
//!
//! Stability (`Level::stable`): the second variation of the system's energy (the rods' and
//! the platform load's potential) over variations that keep every tip on its attachment.
//! Those that hold the platform still are each rod's with both ends clamped: no point
//! conjugate to its base in (0, L_i] (`constraint::Conjugate`). The rest are the Jacobi
//! fields that follow a platform increment xi = (dp, psi): the linearised rod rows
//! A_i dx_i + C_i xi = 0 give dx_i = -A_i^-1 C_i xi, and the second variation is
//! -xi^T S xi with S = B_xi - sum_i B_i A_i^-1 C_i, the Schur complement of the Jacobian's
//! rod blocks: the linearised platform balance (the rods' tip reactions and the platform
//! load's change; the balance is a sum of forces on the platform, hence the sign). The
//! equilibrium is stable iff every rod passes its test and sym(-S) is positive definite,
//! S taken in forces and moments per metre and radian (the scales removed, so that the
//! form is congruent to the Hessian). Assessed for conservative loads (no follower load
//! on any rod).

use super::constraint::{
    check_half_turn, check_rotation, checked_shape, exp_so3, follow_path, log_so3, matmul,
    on_quarter_turn, orientation_error, reference_tip, slerp, tmatmul, Chord, Conjugate,
    ConstrainedSolution, Equations, PathOk,
};
use super::friction::{self, FrictionPath, FrictionState, Leg};
use super::{Problem, Solution, SolverOptions};
use crate::error::{Result, SoftrodError};
use crate::jet::{Jet, RodScalar};
use crate::ode::{integrate, Loads, State};
use crate::rod::Rod;
use nalgebra::{DMatrix, Matrix6};
use std::sync::Arc;

/// Most rods in one system.
pub const MAX_RODS: usize = 64;

/// One rod of a system and where its tip holds the platform.
#[derive(Debug, Clone)]
pub struct SystemRod<'a> {
    pub rod: &'a Rod,
    /// Its loads (pressures, tensions, tip loads of its own tip body).
    pub loads: Loads,
    /// Tip position in the platform frame, m.
    pub attachment: [f64; 3],
    /// Tip frame in the platform frame (row-major rotation).
    pub attachment_rotation: [[f64; 3]; 3],
}

/// The rigid platform the rods' tips hold.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Platform {
    /// Nominal pose (world): where the platform starts; the unloaded rods' tips are
    /// attached there at the start of continuation.
    pub position: [f64; 3],
    pub rotation: [[f64; 3]; 3],
    /// External force on the platform (world, N) and moment about its origin (world, N m).
    pub force: [f64; 3],
    pub moment: [f64; 3],
    /// Mass (kg), centre of mass in the platform frame (m) and gravity (m/s^2, world).
    pub mass: f64,
    pub com_offset: [f64; 3],
    pub gravity: [f64; 3],
}

/// A converged system.
#[derive(Debug, Clone, PartialEq)]
pub struct SystemSolution {
    /// Per rod: its equilibrium and shape, and the wrench the platform applies to its tip.
    pub rods: Vec<ConstrainedSolution>,
    pub platform_position: [f64; 3],
    pub platform_rotation: [[f64; 3]; 3],
    /// Unknowns (6 per rod, then p / L_s and the rotation vector phi of the platform's
    /// rotation from its nominal one, R_p = exp(phi) R_0); warm start.
    pub x: Vec<f64>,
    pub iterations: usize,
    pub residual: f64,
    pub load_steps: usize,
    /// The whole system's equilibrium is stable (module docs); None where it is not
    /// assessed (a follower load on some rod, friction). Every rod's `solution.stable`
    /// says the same.
    pub stable: Option<bool>,
    /// The frictional path's state at this equilibrium (`solve_system_friction`), from
    /// which a further path may start. None for a frictionless solve.
    pub friction: Option<Arc<SystemFrictionPath>>,
}

/// Where a system's frictional path stands at a converged equilibrium: every rod's loads
/// and friction state (None: a rod without obstacles), the attachments and the platform
/// (its loads) reached, and the unknowns there. A further path (unloading, say) starts
/// from it (`solve_system_friction`'s `history`).
#[derive(Debug, Clone, PartialEq)]
pub struct SystemFrictionPath {
    pub rods: Vec<RodPath>,
    pub platform: Platform,
    pub x: Vec<f64>,
}

/// One rod's part of a [`SystemFrictionPath`].
#[derive(Debug, Clone, PartialEq)]
pub struct RodPath {
    pub loads: Loads,
    pub state: Option<FrictionState>,
    pub attachment: [f64; 3],
    pub attachment_rotation: [[f64; 3]; 3],
    spec: crate::spec::DesignSpec,
}

impl SystemFrictionPath {
    /// Largest |e| over every rod's contact points (m; 0: no tangential load held).
    pub fn max_elastic_slip(&self) -> f64 {
        self.rods
            .iter()
            .filter_map(|r| r.state.as_ref())
            .map(FrictionState::max_elastic_slip)
            .fold(0.0, f64::max)
    }
}

fn finite3(field: String, v: &[f64; 3]) -> Result<()> {
    for (i, x) in v.iter().enumerate() {
        if !x.is_finite() {
            return Err(SoftrodError::invalid(
                format!("{field}[{i}]"),
                x,
                "must be a finite number",
            ));
        }
    }
    Ok(())
}

/// Stiffness scaling factors sigma (paper 001, eq. 13): finite and > 0.
pub(crate) fn check_sigma(field: &str, sigma: &[f64; 3]) -> Result<()> {
    for (k, s) in sigma.iter().enumerate() {
        if !(s.is_finite() && *s > 0.0) {
            return Err(SoftrodError::invalid(
                format!("{field}[{k}]"),
                s,
                "stiffness scaling factors must be finite and > 0",
            ));
        }
    }
    Ok(())
}

/// The first section of `rod` whose stiffnesses are scaled by sigma (`[sections.law]
/// stiffness_map`, paper 001 eq. 13), if any.
pub fn mapped_section(rod: &Rod) -> Option<usize> {
    rod.sections.iter().position(|s| s.law.stiffness_map)
}

/// A lone rod's sigma: `given` (checked: finite and > 0, named `field`), or, where none is
/// given, 1 for a rod without stiffness-mapped sections; a rod with a mapped section and no
/// sigma is refused: sigma is never assumed to be 1.
pub fn lone_sigma(field: &str, rod: &Rod, given: Option<[f64; 3]>) -> Result<[f64; 3]> {
    match (given, mapped_section(rod)) {
        (Some(s), _) => {
            check_sigma(field, &s)?;
            Ok(s)
        }
        (None, None) => Ok([1.0; 3]),
        (None, Some(k)) => Err(unmapped_sigma(field, k)),
    }
}

/// The refusal of a mapped rod (`sections[k]`) without its sigma.
fn unmapped_sigma(field: &str, k: usize) -> SoftrodError {
    SoftrodError::invalid(
        field,
        "None",
        format!(
            "sections[{k}] is stiffness-mapped ([sections.law] stiffness_map): give sigma (3 \
             factors > 0, from the stiffness map); sigma is never assumed to be 1"
        ),
    )
}

/// Rod `i`'s sigma in a system: `given` (checked: finite and > 0), or, where none is given,
/// 1 for a rod without stiffness-mapped sections, on which sigma acts nowhere. A rod with a
/// mapped section and no sigma is refused: sigma is never assumed to be 1.
pub fn rod_sigma(i: usize, rod: &Rod, given: Option<[f64; 3]>) -> Result<[f64; 3]> {
    lone_sigma(&format!("rods[{i}].stiffness_scale"), rod, given)
}

/// The system's own inputs: 1..=MAX_RODS rods, finite attachments and platform, proper
/// rotations, mass >= 0, every rod's sigma finite and > 0 (named by its rod). A rod's
/// obstacles are its own (docs/contact.md): their penalty is a line load of its shooting
/// ODE and its rounded end's force enters its tip balance, so the tip reaction the
/// platform receives leaves that force out, as for a held tip.
pub(crate) fn validate(rods: &[SystemRod], platform: &Platform) -> Result<()> {
    if rods.is_empty() || rods.len() > MAX_RODS {
        return Err(SoftrodError::invalid(
            "rods",
            format!("{} rods", rods.len()),
            format!("a system has 1..={MAX_RODS} rods"),
        ));
    }
    for (i, r) in rods.iter().enumerate() {
        finite3(format!("rods[{i}].attachment"), &r.attachment)?;
        check_rotation(
            &format!("rods[{i}].attachment_orientation"),
            &r.attachment_rotation,
        )?;
        check_sigma(
            &format!("rods[{i}].stiffness_scale"),
            &r.loads.stiffness_scale,
        )?;
    }
    for (name, v) in [
        ("position", &platform.position),
        ("force", &platform.force),
        ("moment", &platform.moment),
        ("com_offset", &platform.com_offset),
        ("gravity", &platform.gravity),
    ] {
        finite3(format!("platform.{name}"), v)?;
    }
    check_rotation("platform.orientation", &platform.rotation)?;
    if !(platform.mass.is_finite() && platform.mass >= 0.0) {
        return Err(SoftrodError::invalid(
            "platform.mass",
            platform.mass,
            "must be a finite number >= 0",
        ));
    }
    Ok(())
}

/// One level of the continuation.
pub(crate) struct Level<'a> {
    pub(crate) problems: Vec<Problem<'a>>,
    /// Attachment offsets and rotations at this level (platform frame).
    attach: Vec<([f64; 3], [[f64; 3]; 3])>,
    force: [f64; 3],
    moment: [f64; 3],
    weight: [f64; 3],
    com: [f64; 3],
    /// Length, force and moment scales.
    pub(crate) ls: f64,
    fs: f64,
    ms: f64,
    /// The platform's nominal rotation, from which its unknown rotation vector turns it
    /// (R_p = exp(phi) R_0): phi stays near zero, away from the half turn where the
    /// rotation vector is singular (a platform set in a frame turned by pi, as
    /// horizontal rods' frames are, would otherwise sit on that singularity).
    nominal: [[f64; 3]; 3],
}

fn lift(s: &State<Jet<6>>) -> State<Jet<12>> {
    let l = |v: &Jet<6>| {
        let mut eps = [0.0; 12];
        eps[..6].copy_from_slice(&v.eps);
        Jet { re: v.re, eps }
    };
    State {
        r: s.r.each_ref().map(l),
        rot: s.rot.each_ref().map(|row| row.each_ref().map(l)),
        n: s.n.each_ref().map(l),
        m: s.m.each_ref().map(l),
        aux: s.aux.each_ref().map(l),
    }
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

impl Level<'_> {
    pub(crate) fn n_rods(&self) -> usize {
        self.problems.len()
    }

    /// The platform's position and rotation from the unknowns.
    pub(crate) fn platform(&self, x: &[f64]) -> ([f64; 3], [[f64; 3]; 3]) {
        let k = 6 * self.n_rods();
        (
            std::array::from_fn(|i| x[k + i] * self.ls),
            matmul(&exp_so3(&[x[k + 3], x[k + 4], x[k + 5]]), &self.nominal),
        )
    }

    /// Rod i's 6 rows and the wrench it applies to the platform (force; moment about p).
    #[allow(clippy::type_complexity)]
    pub(crate) fn rod_terms<D: RodScalar>(
        &self,
        i: usize,
        tip: &State<D>,
        p: &[D; 3],
        rp: &[[D; 3]; 3],
    ) -> ([D; 6], [D; 3], [D; 3]) {
        let (o, a) = &self.attach[i];
        let arm = rotate(rp, &o.map(D::from));
        let target_rot = matmul(rp, &a.map(|row| row.map(D::from)));
        let e = orientation_error(&tmatmul(&target_rot, &tip.rot));
        let rows = std::array::from_fn(|k| {
            if k < 3 {
                (tip.r[k] - p[k] - arm[k]) * (1.0 / self.ls)
            } else {
                e[k - 3]
            }
        });
        let pr = &self.problems[i];
        let b: [D; 6] = pr.residual_of_tip(tip);
        let f: [D; 3] = std::array::from_fn(|k| -(b[k] * pr.fs));
        let lever: [D; 3] = std::array::from_fn(|k| tip.r[k] - p[k]);
        let lxf = cross(&lever, &f);
        let m: [D; 3] = std::array::from_fn(|k| lxf[k] - b[k + 3] * pr.ms);
        (rows, f, m)
    }

    /// The platform's own load: external force and weight; moment about p.
    fn platform_terms<D: RodScalar>(&self, rp: &[[D; 3]; 3]) -> ([D; 3], [D; 3]) {
        self.platform_terms_weighing(rp, self.weight.map(D::from))
    }

    /// [`Self::platform_terms`] with the platform's weight `w` (world, N) given: a mass
    /// derivative carries it.
    pub(crate) fn platform_terms_weighing<D: RodScalar>(
        &self,
        rp: &[[D; 3]; 3],
        w: [D; 3],
    ) -> ([D; 3], [D; 3]) {
        let cw = rotate(rp, &self.com.map(D::from));
        let cxw = cross(&cw, &w);
        (
            std::array::from_fn(|k| w[k] + self.force[k]),
            std::array::from_fn(|k| cxw[k] + self.moment[k]),
        )
    }

    pub(crate) fn balance_rows<D: RodScalar>(&self, f: &[D; 3], m: &[D; 3]) -> [D; 6] {
        std::array::from_fn(|k| {
            if k < 3 {
                f[k] * (1.0 / self.fs)
            } else {
                m[k - 3] * (1.0 / self.ms)
            }
        })
    }
}

impl Equations for Level<'_> {
    fn eval(&self, x: &[f64]) -> Vec<f64> {
        let n = self.n_rods();
        let (p, rp) = self.platform(x);
        let (mut f, mut m) = self.platform_terms(&rp);
        let mut out = vec![0.0; 6 * n + 6];
        for (i, pr) in self.problems.iter().enumerate() {
            let tip = integrate(
                pr.rod,
                &pr.coeffs,
                pr.base_state(&x[6 * i..6 * i + 6]),
                None,
            );
            let (rows, fi, mi) = self.rod_terms(i, &tip, &p, &rp);
            out[6 * i..6 * i + 6].copy_from_slice(&rows);
            for k in 0..3 {
                f[k] += fi[k];
                m[k] += mi[k];
            }
        }
        out[6 * n..].copy_from_slice(&self.balance_rows(&f, &m));
        out
    }

    fn eval_jac(&self, x: &[f64]) -> (Vec<f64>, DMatrix<f64>) {
        self.jacobian(x, None)
    }

    fn retract(&self, x: &[f64], dx: &[f64]) -> Vec<f64> {
        system_retract(self.n_rods(), x, dx)
    }

    fn difference(&self, a: &[f64], b: &[f64]) -> Vec<f64> {
        let k = 6 * self.n_rods() + 3;
        let mut out: Vec<f64> = a.iter().zip(b).map(|(p, q)| p - q).collect();
        let ra = exp_so3(&[a[k], a[k + 1], a[k + 2]]);
        let rb = exp_so3(&[b[k], b[k + 1], b[k + 2]]);
        // exp(d) = Ra Rb^T
        let rel: [[f64; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|j| (0..3).map(|q| ra[i][q] * rb[j][q]).sum())
        });
        out[k..k + 3].copy_from_slice(&log_so3(&rel));
        out
    }

    fn on_branch(&self, x: &[f64]) -> bool {
        let (_, rp) = self.platform(x);
        self.problems.iter().enumerate().all(|(i, pr)| {
            let tip = integrate(
                pr.rod,
                &pr.coeffs,
                pr.base_state(&x[6 * i..6 * i + 6]),
                None,
            );
            let target = matmul(&rp, &self.attach[i].1);
            on_quarter_turn(&tmatmul(&target, &tip.rot))
        })
    }

    const SYSTEM: bool = true;

    fn rods<'s>(&'s self, x: &'s [f64]) -> Vec<(&'s Problem<'s>, &'s [f64])> {
        self.problems
            .iter()
            .enumerate()
            .map(|(i, p)| (p, &x[6 * i..6 * i + 6]))
            .collect()
    }

    fn stable(&self, x: &[f64]) -> Option<bool> {
        if self.problems.iter().any(|p| !p.assessed()) {
            return None;
        }
        let n = self.n_rods();
        let mut held = vec![Conjugate::default(); n];
        let (_, jac) = self.jacobian(x, Some(&mut held));
        if !held.iter().all(|c| c.stable_clamped()) {
            return Some(false);
        }
        let k = 6 * n;
        let block = |r: usize, c: usize| Matrix6::from_fn(|a, b| jac[(r + a, c + b)]);
        let mut s = block(k, k);
        for i in 0..n {
            // A rod whose tip rows are singular has a conjugate point at L: a neutral mode.
            let Some(dx) = block(6 * i, 6 * i).lu().solve(&block(6 * i, k)) else {
                return Some(false);
            };
            s -= block(k, 6 * i) * dx;
        }
        // Rows back to N and N m, columns to m and rad.
        let h = Matrix6::from_fn(|a, b| {
            let row = if a < 3 { self.fs } else { self.ms };
            let col = if b < 3 { self.ls } else { 1.0 };
            -s[(a, b)] * row / col
        });
        let q = (h + h.transpose()) * 0.5;
        Some(q.iter().all(|v| v.is_finite()) && q.cholesky().is_some())
    }
}

impl Level<'_> {
    /// Residual and exact Jacobian (`Equations::eval_jac`); with `held`, each rod's
    /// conjugate-point test from the same dual integration.
    pub(crate) fn jacobian(
        &self,
        x: &[f64],
        mut held: Option<&mut Vec<Conjugate>>,
    ) -> (Vec<f64>, DMatrix<f64>) {
        let n = self.n_rods();
        let dim = 6 * n + 6;
        let mut jac = DMatrix::zeros(dim, dim);
        let mut r = vec![0.0; dim];
        let (p0, r0) = self.platform(x);
        // Platform unknowns in directions 6..12: position p/L_s and the increment psi of
        // R_p = exp(psi) R0 (first order is exact for the Jacobian at psi = 0).
        let p: [Jet<12>; 3] = std::array::from_fn(|k| {
            let mut v = Jet::variable(p0[k], 6 + k);
            v.eps[6 + k] = self.ls;
            v
        });
        let psi: [Jet<12>; 3] = std::array::from_fn(|k| Jet::variable(0.0, 9 + k));
        let one = Jet::<12>::from(1.0);
        let w = [
            [one, -psi[2], psi[1]],
            [psi[2], one, -psi[0]],
            [-psi[1], psi[0], one],
        ];
        let rp = matmul(&w, &r0.map(|row| row.map(Jet::from)));
        let (mut f, mut m) = self.platform_terms(&rp);
        // Rod columns of the balance rows go straight to the matrix; f, m carry the
        // platform's.
        let strip =
            |f: &mut [Jet<12>; 3], m: &mut [Jet<12>; 3], i: usize, jac: &mut DMatrix<f64>| {
                let rows = self.balance_rows(f, m);
                for (k, v) in rows.iter().enumerate() {
                    for j in 0..6 {
                        jac[(6 * n + k, 6 * i + j)] += v.eps[j];
                    }
                }
                for v in f.iter_mut().chain(m.iter_mut()) {
                    v.eps[..6].fill(0.0);
                }
            };
        for (i, pr) in self.problems.iter().enumerate() {
            let xd: [Jet<6>; 6] = std::array::from_fn(|j| Jet::variable(x[6 * i + j], j));
            let tip = match held.as_deref_mut() {
                Some(tests) => {
                    let (test, length) = (&mut tests[i], pr.rod.length);
                    let mut visit = |_: usize, _: f64, y: &State<Jet<6>>| test.visit(y, length);
                    integrate(pr.rod, &pr.coeffs, pr.base_state(&xd), Some(&mut visit))
                }
                None => integrate(pr.rod, &pr.coeffs, pr.base_state(&xd), None),
            };
            let tip = lift(&tip);
            let (rows, fi, mi) = self.rod_terms(i, &tip, &p, &rp);
            for (k, v) in rows.iter().enumerate() {
                r[6 * i + k] = v.re;
                for j in 0..6 {
                    jac[(6 * i + k, 6 * i + j)] = v.eps[j];
                    jac[(6 * i + k, 6 * n + j)] = v.eps[6 + j];
                }
            }
            let (mut fr, mut mr) = (fi, mi);
            strip(&mut fr, &mut mr, i, &mut jac);
            for k in 0..3 {
                f[k] += fr[k];
                m[k] += mr[k];
            }
        }
        let rows = self.balance_rows(&f, &m);
        for (k, v) in rows.iter().enumerate() {
            r[6 * n + k] = v.re;
            for j in 0..6 {
                jac[(6 * n + k, 6 * n + j)] = v.eps[6 + j];
            }
        }
        (r, jac)
    }
}

impl<'a> Level<'a> {
    /// The level of the whole load (the path's end): the given attachments and the
    /// platform's full load, the rods' `problems` given.
    pub(crate) fn full(
        rods: &[SystemRod],
        platform: &Platform,
        problems: Vec<Problem<'a>>,
    ) -> Self {
        let n = rods.len();
        Level {
            problems,
            attach: rods
                .iter()
                .map(|r| (r.attachment, r.attachment_rotation))
                .collect(),
            force: platform.force,
            moment: platform.moment,
            weight: platform.gravity.map(|g| platform.mass * g),
            com: platform.com_offset,
            ls: rods.iter().map(|r| r.rod.length).sum::<f64>() / n as f64,
            fs: rods.iter().map(|r| r.rod.force_scale).sum(),
            ms: rods.iter().map(|r| r.rod.force_scale * r.rod.length).sum(),
            nominal: platform.rotation,
        }
    }
}

/// Where a system's path goes: each rod's attachment from where the path starts to the
/// given one, the platform's load from its start (None: from rest, the load and the
/// platform's weight coming on with the path) to the given one, and the scales.
struct Course {
    attach: Vec<Span>,
    from: Option<([f64; 3], [f64; 3])>,
    platform: Platform,
    ls: f64,
    fs: f64,
    ms: f64,
}

/// An attachment (offset, rotation; platform frame) at the path's start and end.
type Span = (([f64; 3], [[f64; 3]; 3]), ([f64; 3], [[f64; 3]; 3]));

impl Course {
    fn new(rods: &[SystemRod], platform: &Platform, start: Vec<([f64; 3], [[f64; 3]; 3])>) -> Self {
        let n = rods.len();
        Course {
            attach: start
                .into_iter()
                .zip(rods)
                .map(|(a, r)| (a, (r.attachment, r.attachment_rotation)))
                .collect(),
            from: None,
            platform: *platform,
            ls: rods.iter().map(|r| r.rod.length).sum::<f64>() / n as f64,
            fs: rods.iter().map(|r| r.rod.force_scale).sum(),
            ms: rods.iter().map(|r| r.rod.force_scale * r.rod.length).sum(),
        }
    }

    /// The level at path parameter `lam` with the rods' problems there.
    fn level<'a>(&self, problems: Vec<Problem<'a>>, lam: f64) -> Level<'a> {
        let pf = &self.platform;
        let (force, moment, weight) = match self.from {
            None => (
                pf.force.map(|v| lam * v),
                pf.moment.map(|v| lam * v),
                pf.gravity.map(|g| lam * pf.mass * g),
            ),
            Some((f0, m0)) => (
                std::array::from_fn(|k| f0[k] + lam * (pf.force[k] - f0[k])),
                std::array::from_fn(|k| m0[k] + lam * (pf.moment[k] - m0[k])),
                pf.gravity.map(|g| pf.mass * g),
            ),
        };
        Level {
            problems,
            attach: self
                .attach
                .iter()
                .map(|((o0, a0), (o, a))| {
                    (
                        std::array::from_fn(|k| o0[k] + lam * (o[k] - o0[k])),
                        slerp(a0, a, lam),
                    )
                })
                .collect(),
            force,
            moment,
            weight,
            com: pf.com_offset,
            ls: self.ls,
            fs: self.fs,
            ms: self.ms,
            nominal: pf.rotation,
        }
    }
}

/// Where the unloaded rods' tips are, in the platform's nominal frame: the attachments a
/// path from rest starts from.
fn rest_attachments(rods: &[SystemRod], platform: &Platform) -> Vec<([f64; 3], [[f64; 3]; 3])> {
    rods.iter()
        .map(|r| {
            let t = reference_tip(r.rod, &r.loads);
            let d: [f64; 3] = std::array::from_fn(|k| t.r[k] - platform.position[k]);
            let o = std::array::from_fn(|i| (0..3).map(|k| platform.rotation[k][i] * d[k]).sum());
            (o, tmatmul(&platform.rotation, &t.rot))
        })
        .collect()
}

/// The unknowns of the unloaded rods under the platform at its nominal pose (phi = 0).
fn rest_unknowns(n: usize, platform: &Platform, ls: f64) -> Vec<f64> {
    let mut x0 = vec![0.0; 6 * n + 6];
    for k in 0..3 {
        x0[6 * n + k] = platform.position[k] / ls;
    }
    x0
}

/// Solve the system's static equilibrium. `guess`: a previous solution's `x`. A rod with
/// an obstacle with friction is refused (naming it): `solve_system_friction` follows the
/// load path that friction needs.
pub fn solve_system(
    rods: &[SystemRod],
    platform: &Platform,
    guess: Option<&[f64]>,
    opts: &SolverOptions,
) -> Result<SystemSolution> {
    validate(rods, platform)?;
    let violations: Vec<Vec<SoftrodError>> = rods
        .iter()
        .map(|r| super::check_inputs(r.rod, &r.loads, opts))
        .collect::<Result<_>>()?;
    let n = rods.len();
    let course = Course::new(rods, platform, rest_attachments(rods, platform));
    let level = |lam: f64| {
        course.level(
            rods.iter()
                .map(|r| Problem::new(r.rod, &r.loads, lam))
                .collect(),
            lam,
        )
    };
    let x0 = rest_unknowns(n, platform, course.ls);
    let guess = guess
        .filter(|g| g.len() == 6 * n + 6 && g.iter().all(|v| v.is_finite()))
        .map(|g| g.to_vec());
    let path = follow_path(level, x0, guess, opts)?;
    let full = level(1.0);
    let stable = full.stable(&path.x);
    conclude(rods, &full, path, stable, violations, None, opts)
}

/// The system's frictional static solve (docs/contact.md, "Friction in the statics",
/// "Systems of rods"): the load path of `friction::solve` for every rod at once, from
/// `history` (a previous frictional solution of this system; None: the unloaded rods under
/// the platform at its nominal pose) to the rods' loads, the platform's load and the
/// attachments, in `steps` equal increments of one path parameter. Each increment is the
/// system's Newton solve (every rod's friction of the last converged increment in its
/// ODE and on its rounded end, the Jacobian exact), halved while it fails; after it
/// converges every rod's friction state is advanced. `stable` is None (friction has no
/// potential); each rod's solution carries its path as a clamped rod's (its tip held
/// where the platform holds it), and the system's solution the whole path.
pub fn solve_system_friction(
    rods: &[SystemRod],
    platform: &Platform,
    history: Option<&SystemFrictionPath>,
    steps: usize,
    opts: &SolverOptions,
) -> Result<SystemSolution> {
    validate(rods, platform)?;
    friction::check_steps(steps)?;
    let violations: Vec<Vec<SoftrodError>> = rods
        .iter()
        .map(|r| super::check_inputs_any_friction(r.rod, &r.loads, opts))
        .collect::<Result<_>>()?;
    if !rods.iter().any(|r| friction::has_friction(r.rod)) {
        return Err(SoftrodError::invalid(
            "rods",
            format!("{} rods", rods.len()),
            "no rod has an obstacle with friction > 0: a frictionless equilibrium does not depend on the load path (solve_system)",
        ));
    }
    let n = rods.len();
    let (course, states, x0) = match history {
        None => {
            let course = Course::new(rods, platform, rest_attachments(rods, platform));
            let states = rods
                .iter()
                .map(|r| {
                    let obstacles = r.rod.obstacles.as_deref()?;
                    Some(friction::unloaded_state(r.rod, &r.loads, obstacles).0)
                })
                .collect();
            let x0 = rest_unknowns(n, platform, course.ls);
            (course, states, x0)
        }
        Some(h) => {
            check_history(rods, platform, h)?;
            let start = h
                .rods
                .iter()
                .map(|r| (r.attachment, r.attachment_rotation))
                .collect();
            let mut course = Course::new(rods, platform, start);
            course.from = Some((h.platform.force, h.platform.moment));
            let states = h.rods.iter().map(|r| r.state.clone()).collect();
            (course, states, h.x.clone())
        }
    };
    let legs: Vec<Leg> = rods
        .iter()
        .enumerate()
        .map(|(i, r)| Leg {
            rod: r.rod,
            loads: &r.loads,
            start: history.map(|h| &h.rods[i].loads),
        })
        .collect();
    // One kept matrix along the path: consecutive increments are nearby problems.
    let mut chord = Chord::default();
    let end = friction::follow(
        &legs,
        states,
        x0,
        steps,
        true,
        friction::JUMPS,
        |problems, t, guess| {
            let level = course.level(std::mem::take(problems), t);
            let out = chord.solve(&level, guess, opts.tol, opts.max_iter);
            *problems = level.problems;
            out
        },
    )?;
    let full = course.level(
        rods.iter()
            .enumerate()
            .map(|(i, r)| end.problem(i, r.rod, &r.loads))
            .collect(),
        1.0,
    );
    let path = PathOk {
        x: end.x.clone(),
        residual: end.last.residual,
        iterations: end.iterations,
        load_steps: end.levels,
    };
    let mut out = conclude(rods, &full, path, None, violations, Some(&end.next), opts)?;
    out.friction = Some(Arc::new(SystemFrictionPath {
        rods: rods
            .iter()
            .zip(end.next)
            .map(|(r, state)| RodPath {
                loads: r.loads.clone(),
                state,
                attachment: r.attachment,
                attachment_rotation: r.attachment_rotation,
                spec: r.rod.spec.clone(),
            })
            .collect(),
        platform: *platform,
        x: out.x.clone(),
    }));
    Ok(out)
}

/// Whether the system of `rods` is solved on a frictional path (some rod's obstacle has
/// friction > 0), refusing what has no place there: a `history` (a friction state) for a
/// frictionless system, whose equilibrium does not depend on the path, and a warm start
/// (`guess`) for a frictional one, which follows its path from the unloaded rods or from
/// a history.
pub fn frictional(rods: &[SystemRod], history_given: bool, guess_given: bool) -> Result<bool> {
    let frictional = rods.iter().any(|r| friction::has_friction(r.rod));
    if history_given && !frictional {
        return Err(SoftrodError::invalid(
            "history",
            "a friction state",
            "no rod of this system has an obstacle with friction > 0: a frictionless equilibrium does not depend on the load path",
        ));
    }
    if guess_given && frictional {
        return Err(SoftrodError::invalid(
            "initial",
            "a previous solution",
            "a frictional system follows its load path from the unloaded rods or from history= (a warm start has no place on a path)",
        ));
    }
    Ok(frictional)
}

/// Check that `history` belongs to this system (the same designs and obstacles rod by
/// rod, the same platform but its loads) and that its rods' loads can be joined to these.
fn check_history(rods: &[SystemRod], platform: &Platform, h: &SystemFrictionPath) -> Result<()> {
    if h.rods.len() != rods.len() || h.x.len() != 6 * rods.len() + 6 {
        return Err(SoftrodError::invalid(
            "history",
            format!("a frictional solution of a system of {} rods", h.rods.len()),
            format!("this system has {} rods", rods.len()),
        ));
    }
    for (i, (r, hr)) in rods.iter().zip(&h.rods).enumerate() {
        let field = format!("history.rods[{i}]");
        friction::check_design(&field, &hr.spec, r.rod)?;
        friction::check_joinable(&field, &hr.loads, &r.loads)?;
    }
    let (a, b) = (&h.platform, platform);
    if a.mass != b.mass
        || a.com_offset != b.com_offset
        || a.gravity != b.gravity
        || a.position != b.position
        || a.rotation != b.rotation
    {
        return Err(SoftrodError::invalid(
            "history",
            "a frictional solution of another platform",
            "its platform's mass, centre of mass, gravity or nominal pose differ from this one's: a path changes the loads and the attachments, not the platform",
        ));
    }
    Ok(())
}

/// The system's solution at the converged unknowns of `path` (`full`: the level at the
/// full loads), every rod's shape checked; with `friction` (each rod's state at the end
/// of a frictional path), each rod's solution carries its path as a clamped rod's.
fn conclude(
    rods: &[SystemRod],
    full: &Level,
    path: PathOk,
    stable: Option<bool>,
    mut violations: Vec<Vec<SoftrodError>>,
    friction: Option<&[Option<FrictionState>]>,
    opts: &SolverOptions,
) -> Result<SystemSolution> {
    let (pp, rp) = full.platform(&path.x);
    let mut out = Vec::with_capacity(rods.len());
    for (i, pr) in full.problems.iter().enumerate() {
        let xi = &path.x[6 * i..6 * i + 6];
        let mut v = std::mem::take(&mut violations[i]);
        let (tip, shape) = checked_shape(pr, xi, opts, &mut v)?;
        let target = matmul(&rp, &rods[i].attachment_rotation);
        check_half_turn(
            &format!("rods[{i}].attachment_orientation"),
            &tmatmul(&target, &tip.rot),
        )?;
        let b: [f64; 6] = pr.residual_of_tip(&tip);
        let y0 = pr.base_state(xi);
        let rod_path = friction.and_then(|f| f[i].clone()).map(|s| {
            Arc::new(FrictionPath::clamped_at(
                rods[i].rod,
                &rods[i].loads,
                s,
                xi,
                &tip,
            ))
        });
        out.push(ConstrainedSolution {
            solution: Solution {
                x: xi.to_vec(),
                base_force: y0.n,
                base_moment: y0.m,
                tip,
                iterations: path.iterations,
                residual: path.residual,
                load_steps: path.load_steps,
                stable,
                violations: v,
                collocation: None,
                friction: rod_path,
            },
            shape,
            tip_reaction_force: std::array::from_fn(|k| b[k] * pr.fs),
            tip_reaction_moment: std::array::from_fn(|k| b[k + 3] * pr.ms),
        });
    }
    Ok(SystemSolution {
        rods: out,
        platform_position: pp,
        platform_rotation: rp,
        x: path.x,
        iterations: path.iterations,
        residual: path.residual,
        load_steps: path.load_steps,
        stable,
        friction: None,
    })
}

/// The scaled residual and exact Jacobian at unknowns x under the full loads (exposed for
/// tests against finite differences).
pub fn system_residual_and_jacobian(
    rods: &[SystemRod],
    platform: &Platform,
    x: &[f64],
) -> Result<(Vec<f64>, Vec<Vec<f64>>)> {
    validate(rods, platform)?;
    let problems = rods
        .iter()
        .map(|r| Problem::new(r.rod, &r.loads, 1.0))
        .collect();
    full_residual_and_jacobian(rods, platform, problems, x)
}

/// [`system_residual_and_jacobian`] of the frictional system with every rod's friction
/// state of `path` as the last converged increment's (each rod's problem as
/// `solve_system_friction` solves an increment), for tests against finite differences.
#[doc(hidden)]
pub fn system_friction_residual_and_jacobian(
    rods: &[SystemRod],
    platform: &Platform,
    path: &SystemFrictionPath,
    x: &[f64],
) -> Result<(Vec<f64>, Vec<Vec<f64>>)> {
    validate(rods, platform)?;
    check_history(rods, platform, path)?;
    let problems = rods
        .iter()
        .zip(&path.rods)
        .map(|(r, h)| match &h.state {
            Some(s) => Problem::with_friction(r.rod, &r.loads, 1.0, s),
            None => Problem::new(r.rod, &r.loads, 1.0),
        })
        .collect();
    full_residual_and_jacobian(rods, platform, problems, x)
}

/// The residual and Jacobian of the level with the given attachments and the platform's
/// full load, the rods' `problems` given.
fn full_residual_and_jacobian(
    rods: &[SystemRod],
    platform: &Platform,
    problems: Vec<Problem>,
    x: &[f64],
) -> Result<(Vec<f64>, Vec<Vec<f64>>)> {
    let n = rods.len();
    if x.len() != 6 * n + 6 {
        return Err(SoftrodError::invalid(
            "x",
            format!("{} values", x.len()),
            format!(
                "this system has {} unknowns (6 per rod, 6 of the platform)",
                6 * n + 6
            ),
        ));
    }
    let level = Level::full(rods, platform, problems);
    let (r, j) = level.eval_jac(x);
    let dim = 6 * n + 6;
    Ok((
        r,
        (0..dim)
            .map(|i| (0..dim).map(|k| j[(i, k)]).collect())
            .collect(),
    ))
}

/// Step `x` by `dx` as the solver does (the platform's rotation on the group), for tests
/// of the Jacobian by finite differences along the solver's own increments.
pub fn system_retract(rods_count: usize, x: &[f64], dx: &[f64]) -> Vec<f64> {
    let k = 6 * rods_count + 3;
    let mut out: Vec<f64> = x.iter().zip(dx).map(|(a, b)| a + b).collect();
    let rot = matmul(
        &exp_so3(&[dx[k], dx[k + 1], dx[k + 2]]),
        &exp_so3(&[x[k], x[k + 1], x[k + 2]]),
    );
    out[k..k + 3].copy_from_slice(&log_so3(&rot));
    out
}
