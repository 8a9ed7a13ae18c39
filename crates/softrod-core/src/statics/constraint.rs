//! End constraints at the tip in statics: a pinned tip (position prescribed, moment free)
//! and a clamped tip (position and orientation prescribed), beside today's free tip.
//! docs/model.md "End constraints"; Till, Black & Rucker (IJRR 2019, doi
//! 10.1177/0278364919842269) and Black, Till & Rucker (IEEE T-RO 2018, doi
//! 10.1109/TRO.2017.2753829) use the same shooting formulation for the rods of parallel
//! continuum robots.
//!
//! Shooting with 6 unknowns x = (n(0)/F_s, m(0)/(F_s L)) as under follower loads. The
//! residual replaces the free tip's wrench balance by the constraint:
//! - pinned: (r(L) - r_c)/L = 0 and the tip moment balance (m(L) - (R(L) c) x W - M)/(F_s L)
//!   = 0 (the pin carries a force, no moment);
//! - clamped: (r(L) - r_c)/L = 0 and the orientation error e(R_c^T R(L)) = 0 with
//!   e(A) = vee(A - A^T)/2 (sin of the angle times the axis; A = I is checked at the end,
//!   since e also vanishes at a half turn).
//!
//! The exact Jacobian comes from one integration in `Jet<6>`. The tip reaction (the
//! wrench the constraint applies to the rod's tip body) is what is left of the tip wrench
//! balance: F_r = n(L) - W - F, M_r = m(L) - (R(L) c) x W - M (zero moment when pinned).
//!
//! Obstacles (docs/contact.md, "A held tip with obstacles"): the penalty is a line load of
//! the shooting ODE (`crate::ode`) and the rounded end's contact force enters the tip
//! balance (`Problem::residual_of_tip`), so the same equations carry them, the reaction
//! leaves that force out (F_r = n(L) - W - F - F_end), every node is checked for
//! penetration (`checked_shape`) and `super::contact::report` reports the contacts.
//!
//! Continuation: a path from the unloaded reference shape (x = 0 at load factor 0, where
//! the constraint is set at the reference tip pose) to the full loads and the prescribed
//! pose, the loads ramped and the pose interpolated along the geodesic. With obstacles no
//! node may pass through one on the way (`follow_path`; docs/contact.md, "The side an
//! obstacle is on").
//!
//! Stability (`Conjugate`, docs/model.md "End constraints"): the second variation with
//! both ends' positions held. The six Jacobi fields that start at the clamp (columns: the
//! derivatives with respect to the six base unknowns, carried by the `Jet<6>` pass) have
//! position and rotation parts Y(s) = [dr(s)/L; dtheta(s)] (6x6). The equilibrium is stable
//! iff Y stays non-singular on (0, L] (no point conjugate to the clamp: a Jacobi field that
//! vanishes at s* < L, continued by zero, is an admissible variation of zero energy that is
//! not smooth, so some nearby one lowers the energy; one that vanishes at L is a neutral
//! mode) and, for a pinned tip, the tip form is positive definite: the Jacobi fields that
//! reach the pin with dr(L) = 0 and dtheta(L) = xi are c = Y(L)^-1 [0; xi], their second
//! variation (M_s / 2) xi^T J_m c with J_m the x-derivative of the scaled tip moment balance
//! (the free tip's form restricted to dr(L) = 0), so sym(J_m Y(L)^-1 [0; I]) > 0. A
//! clamped tip has no tip form (both ends' variations vanish). Assessed for conservative
//! loads: not under follower line loads, nor with a follower tip moment on a pin (a
//! follower tip force on a pin, or any tip load on a clamp, does no work). The obstacles'
//! penalty is conservative (f_c = -grad Phi): it enters the Jacobi fields Y through the
//! dual numbers, and the rounded end's force acts at the held point (dr(L) = 0), where it
//! does no work and adds nothing to the tip form.

use super::contact::{crossing_error, Sides};
// A step that leaves the stable path is cut down to the free tip's shortest step (its
// doc says why so short); the levels here are solved to LEVEL_TOL = 1e-6, close enough
// for the stability test.
use super::SolverOptions;
use super::MIN_STABLE_STEP;
use super::{eigenvalues_right_half_plane, inf_norm, rotation_field, Problem, Shape, Solution};
use crate::error::{Result, SoftrodError};
use crate::jet::{Jet, RodScalar};
use crate::ode::{integrate, Loads, State};
use crate::rod::Rod;
use crate::spec::Frame;
use crate::validity::{Node, Policy};
use nalgebra::{DMatrix, DVector, Matrix3, Matrix6, SMatrix};

/// How the tip is held.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TipConstraint {
    /// Free (the tip loads act on it): the solve of [`super::solve`].
    Free,
    /// Position prescribed (world frame, m); moment free.
    Pinned { position: [f64; 3] },
    /// Position (m) and orientation (row-major rotation, tip frame d1 d2 d3 as columns, in
    /// the world) prescribed.
    Clamped {
        position: [f64; 3],
        rotation: [[f64; 3]; 3],
    },
}

/// How far from orthonormal (max |R^T R - I|, |det R - 1|) a given rotation may be: a
/// matrix written out to 10 significant digits passes; a typo does not.
pub const ROTATION_TOL: f64 = 1e-9;

fn finite3(field: &str, v: &[f64; 3]) -> Result<()> {
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

/// A rotation given as input: finite, orthonormal and proper to `ROTATION_TOL`.
pub fn check_rotation(field: &str, r: &[[f64; 3]; 3]) -> Result<()> {
    for (i, row) in r.iter().enumerate() {
        finite3(&format!("{field}[{i}]"), row)?;
    }
    let mut worst: f64 = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            let dot: f64 = (0..3).map(|k| r[k][i] * r[k][j]).sum();
            worst = worst.max((dot - if i == j { 1.0 } else { 0.0 }).abs());
        }
    }
    let det = det3(r);
    if worst > ROTATION_TOL || (det - 1.0).abs() > ROTATION_TOL {
        return Err(SoftrodError::invalid(
            field,
            format!("{r:?}"),
            format!(
                "must be a rotation matrix (orthonormal with det +1 to {ROTATION_TOL:e}; \
                 max |R^T R - I| is {worst:.3e}, det is {det:.6}); give a rotation vector \
                 instead to avoid rounding"
            ),
        ));
    }
    Ok(())
}

impl TipConstraint {
    /// Finite position, a proper rotation (fields named `tip_constraint.*`).
    pub fn validate(&self) -> Result<()> {
        match self {
            TipConstraint::Free => Ok(()),
            TipConstraint::Pinned { position } => finite3("tip_constraint.position", position),
            TipConstraint::Clamped { position, rotation } => {
                finite3("tip_constraint.position", position)?;
                check_rotation("tip_constraint.orientation", rotation)
            }
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            TipConstraint::Free => "free",
            TipConstraint::Pinned { .. } => "pinned",
            TipConstraint::Clamped { .. } => "clamped",
        }
    }
}

/// A static equilibrium with a constrained tip.
#[derive(Debug, Clone, PartialEq)]
pub struct ConstrainedSolution {
    /// The equilibrium (`x`: the 6 scaled base unknowns; `stable`: the conjugate-point test
    /// of `Conjugate`, None under follower loads that do work).
    pub solution: Solution,
    pub shape: Shape,
    /// Force the constraint applies to the tip (world frame), N; zero for a free tip.
    pub tip_reaction_force: [f64; 3],
    /// Moment the constraint applies to the tip (world frame), N m; zero unless clamped.
    pub tip_reaction_moment: [f64; 3],
}

// ---- rotations (row-major 3x3) ----

pub(crate) fn det3(r: &[[f64; 3]; 3]) -> f64 {
    r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
        - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
        + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0])
}

/// a b.
pub(crate) fn matmul<D: RodScalar>(a: &[[D; 3]; 3], b: &[[D; 3]; 3]) -> [[D; 3]; 3] {
    std::array::from_fn(|i| {
        std::array::from_fn(|j| a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j])
    })
}

/// a^T b.
pub(crate) fn tmatmul<D: RodScalar>(a: &[[D; 3]; 3], b: &[[D; 3]; 3]) -> [[D; 3]; 3] {
    std::array::from_fn(|i| {
        std::array::from_fn(|j| a[0][i] * b[0][j] + a[1][i] * b[1][j] + a[2][i] * b[2][j])
    })
}

/// e(A) = vee(A - A^T)/2: sin(angle) times the axis of the rotation A (zero at A = I and at
/// a half turn).
pub(crate) fn orientation_error<D: RodScalar>(a: &[[D; 3]; 3]) -> [D; 3] {
    [
        (a[2][1] - a[1][2]) * 0.5,
        (a[0][2] - a[2][0]) * 0.5,
        (a[1][0] - a[0][1]) * 0.5,
    ]
}

/// exp of the rotation vector w (Rodrigues, with the series near zero).
pub fn exp_so3(w: &[f64; 3]) -> [[f64; 3]; 3] {
    let t2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
    let t = t2.sqrt();
    let (a, b) = if t < 1e-4 {
        (1.0 - t2 / 6.0, 0.5 - t2 / 24.0)
    } else {
        (t.sin() / t, (1.0 - t.cos()) / t2)
    };
    let k = [[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]];
    let k2 = matmul(&k, &k);
    std::array::from_fn(|i| {
        std::array::from_fn(|j| (if i == j { 1.0 } else { 0.0 }) + a * k[i][j] + b * k2[i][j])
    })
}

/// The rotation vector of a rotation R (log), angle in [0, pi].
pub fn log_so3(r: &[[f64; 3]; 3]) -> [f64; 3] {
    let c = (0.5 * (r[0][0] + r[1][1] + r[2][2] - 1.0)).clamp(-1.0, 1.0);
    let theta = c.acos();
    let s = [
        0.5 * (r[2][1] - r[1][2]),
        0.5 * (r[0][2] - r[2][0]),
        0.5 * (r[1][0] - r[0][1]),
    ];
    if theta < 1e-6 {
        return s;
    }
    if std::f64::consts::PI - theta > 1e-6 {
        let f = theta / theta.sin();
        return s.map(|v| v * f);
    }
    // Near a half turn: R ~ 2 a a^T - I; the largest diagonal gives the axis.
    let k = (0..3)
        .max_by(|&i, &j| r[i][i].total_cmp(&r[j][j]))
        .unwrap_or(0);
    let mut a = [0.0; 3];
    a[k] = (0.5 * (r[k][k] + 1.0)).max(0.0).sqrt();
    for i in 0..3 {
        if i != k {
            a[i] = 0.25 * (r[i][k] + r[k][i]) / a[k];
        }
    }
    let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    a.map(|v| v / n * theta)
}

/// R0 exp(t log(R0^T R1)): the geodesic from R0 (t = 0) to R1 (t = 1).
pub(crate) fn slerp(r0: &[[f64; 3]; 3], r1: &[[f64; 3]; 3], t: f64) -> [[f64; 3]; 3] {
    let w = log_so3(&tmatmul(r0, r1));
    matmul(r0, &exp_so3(&w.map(|v| v * t)))
}

// ---- a small Newton/continuation engine over dynamic sizes ----

/// A square system of equations F(x) = 0 on unknowns that may include rotations (updated
/// through `retract`).
pub(crate) trait Equations {
    fn eval(&self, x: &[f64]) -> Vec<f64>;
    /// Residual and exact Jacobian with respect to the increments of `retract`.
    fn eval_jac(&self, x: &[f64]) -> (Vec<f64>, DMatrix<f64>);
    /// x moved by the increment dx (additive unless overridden).
    fn retract(&self, x: &[f64], dx: &[f64]) -> Vec<f64> {
        x.iter().zip(dx).map(|(a, b)| a + b).collect()
    }
    /// The increment from b to a (a = retract(b, difference(a, b))).
    fn difference(&self, a: &[f64], b: &[f64]) -> Vec<f64> {
        a.iter().zip(b).map(|(p, q)| p - q).collect()
    }
    /// Whether the solution x of these equations is a stable equilibrium (None: not
    /// assessed). `follow_path` keeps to the stable path where it is known.
    fn stable(&self, _x: &[f64]) -> Option<bool> {
        None
    }
    /// Whether the solution x holds every clamped tip on the branch of its prescribed
    /// orientation (`on_quarter_turn`): the orientation error e(A) = vee(A - A^T) / 2
    /// vanishes at a half turn too, and Newton may land there from a far predictor.
    /// `newton` does not accept a solution off it (a path halves the step instead).
    fn on_branch(&self, _x: &[f64]) -> bool {
        true
    }
    /// Whether the rods are a system's (a crossing names the rod).
    const SYSTEM: bool = false;
    /// The rods' problems and each one's unknowns in x, for the crossing check
    /// (`contact::Sides`); none by default.
    fn rods<'s>(&'s self, _x: &'s [f64]) -> Vec<(&'s Problem<'s>, &'s [f64])> {
        Vec::new()
    }
}

/// The rods of `eq` at the solution x as seen from `from` (`contact::Sides`), and the first
/// node path between them that passes through an obstacle. Nothing is computed where no
/// rod is checked.
fn sides_at<E: Equations>(
    eq: &E,
    from: &Sides,
    x: &[f64],
) -> (Sides, Option<super::contact::Crossing>) {
    if from.unchecked() {
        return (Sides::start(&[]), None);
    }
    let rods = eq.rods(x);
    let to = from.at(&rods);
    let crossed = from.crossing(&to, &rods, E::SYSTEM);
    (to, crossed)
}

pub(crate) struct NewtonOk {
    pub x: Vec<f64>,
    pub residual: f64,
    pub iterations: usize,
}

fn norm2(v: &[f64]) -> f64 {
    v.iter().map(|a| a * a).sum::<f64>().sqrt()
}

/// Damped Newton with the exact Jacobian at every iterate, a backtracking line search and
/// a Levenberg-Marquardt step where J is singular. Err((iterations, residual)).
pub(crate) fn newton(
    eq: &impl Equations,
    x0: Vec<f64>,
    tol: f64,
    max_iter: usize,
) -> std::result::Result<NewtonOk, (usize, f64)> {
    let mut x = x0;
    let (mut r, mut jac) = eq.eval_jac(&x);
    for it in 0..max_iter {
        if let Some(out) = stop(eq, &mut x, &r, tol, it + 1) {
            return out;
        }
        let norm = inf_norm(&r);
        let rv = DVector::from_column_slice(&r);
        let step = jac
            .clone()
            .lu()
            .solve(&(-&rv))
            .filter(|s| s.iter().all(|v| v.is_finite()))
            .unwrap_or_else(|| {
                let jt = jac.transpose();
                let mut a = &jt * &jac;
                let mu = 1e-6 * a.diagonal().max().max(1e-300);
                for i in 0..a.nrows() {
                    a[(i, i)] += mu;
                }
                a.lu()
                    .solve(&(-(jt * &rv)))
                    .unwrap_or_else(|| DVector::zeros(r.len()))
            });
        let r2 = norm2(&r);
        let mut alpha = 1.0;
        let mut accepted = false;
        while alpha >= 1.0 / 1024.0 {
            let dx: Vec<f64> = step.iter().map(|v| alpha * v).collect();
            let xt = eq.retract(&x, &dx);
            let rt = eq.eval(&xt);
            let r2t = norm2(&rt);
            if r2t.is_finite() && r2t < (1.0 - 1e-4 * alpha) * r2 {
                x = xt;
                accepted = true;
                break;
            }
            alpha *= 0.5;
        }
        if !accepted {
            if norm <= 100.0 * tol * inf_norm(&x).max(1.0) {
                return on_branch(eq, x, norm, it + 1);
            }
            return Err((it + 1, norm));
        }
        (r, jac) = eq.eval_jac(&x);
    }
    let norm = inf_norm(&r);
    if norm <= tol * inf_norm(&x).max(1.0) {
        on_branch(eq, x, norm, max_iter)
    } else {
        Err((max_iter, norm))
    }
}

/// Newton's method that keeps its matrix from one solve to the next (a chord method), for
/// a sequence of nearby problems such as the increments of a frictional load path
/// (`super::friction`): the exact Jacobian is factored where there is none yet and again
/// wherever a step with the kept one contracts the residual by less than half; a step
/// that does not reduce the residual is retried with a fresh matrix, and where even that
/// one fails, or max_iter steps do not converge, the damped [`newton`] takes over. Convergence is judged as [`newton`] judges
/// it (on the true residual, and on the prescribed orientation's branch), so the answer
/// is an equilibrium to the same tolerance; only the matrices factored differ.
#[derive(Default)]
pub(crate) struct Chord {
    lu: Option<nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>>,
    /// Exact Jacobians factored so far.
    pub(crate) factored: usize,
}

impl Chord {
    pub(crate) fn solve(
        &mut self,
        eq: &impl Equations,
        x0: Vec<f64>,
        tol: f64,
        max_iter: usize,
    ) -> std::result::Result<NewtonOk, (usize, f64)> {
        let mut x = x0;
        let mut r = eq.eval(&x);
        let mut refresh = self.lu.is_none();
        let mut fresh = false;
        for it in 0..max_iter {
            if let Some(out) = stop(eq, &mut x, &r, tol, it + 1) {
                return out;
            }
            let norm = inf_norm(&r);
            if refresh {
                let (rj, jac) = eq.eval_jac(&x);
                r = rj;
                self.lu = Some(jac.lu());
                self.factored += 1;
                fresh = true;
            }
            let rv = DVector::from_column_slice(&r);
            let step = self
                .lu
                .as_ref()
                .and_then(|lu| lu.solve(&(-&rv)))
                .filter(|s| s.iter().all(|v| v.is_finite()));
            let Some(step) = step else {
                self.lu = None;
                return newton(eq, x, tol, max_iter - it);
            };
            let dx: Vec<f64> = step.iter().copied().collect();
            let xt = eq.retract(&x, &dx);
            let rt = eq.eval(&xt);
            let nt = inf_norm(&rt);
            if nt.is_nan() || nt >= norm {
                if fresh {
                    // Not even the exact step reduces it: damped Newton from here.
                    self.lu = None;
                    return newton(eq, x, tol, max_iter - it);
                }
                refresh = true;
                continue;
            }
            refresh = nt > 0.5 * norm;
            fresh = false;
            x = xt;
            r = rt;
        }
        // The kept matrices did not get there in max_iter steps: damped Newton from here,
        // with its own budget, so that the chord never fails where Newton would not.
        self.lu = None;
        newton(eq, x, tol, max_iter).map(|ok| NewtonOk {
            iterations: ok.iterations + max_iter,
            ..ok
        })
    }
}

/// Newton's stopping test at x with residual r after `iterations`: a residual that is not
/// finite fails, one within tol (relative to the unknowns' size) is the answer where it is
/// on the prescribed orientation's branch ([`on_branch`]); None: go on.
fn stop(
    eq: &impl Equations,
    x: &mut Vec<f64>,
    r: &[f64],
    tol: f64,
    iterations: usize,
) -> Option<std::result::Result<NewtonOk, (usize, f64)>> {
    let norm = inf_norm(r);
    if !norm.is_finite() {
        return Some(Err((iterations, norm)));
    }
    (norm <= tol * inf_norm(x).max(1.0)).then(|| on_branch(eq, std::mem::take(x), norm, iterations))
}

/// Newton's converged solution x, unless it is off the prescribed orientation's branch
/// (`Equations::on_branch`): then a failure, whose residual is the half turn's (the
/// error's size there is 0, so the path's message reports the step, not a residual).
fn on_branch(
    eq: &impl Equations,
    x: Vec<f64>,
    residual: f64,
    iterations: usize,
) -> std::result::Result<NewtonOk, (usize, f64)> {
    if eq.on_branch(&x) {
        Ok(NewtonOk {
            x,
            residual,
            iterations,
        })
    } else {
        Err((iterations, residual))
    }
}

/// Whether the rotation `a` (prescribed^T actual) is within a quarter turn of the identity
/// (trace > 1), the branch on which the orientation error e(a) has the prescribed pose as
/// its zero; `check_half_turn` refuses an answer off it.
pub(crate) fn on_quarter_turn(a: &[[f64; 3]; 3]) -> bool {
    a[0][0] + a[1][1] + a[2][2] > 1.0
}

/// The outcome of `follow_path`: the solution at load factor 1 and the effort.
pub(crate) struct PathOk {
    pub x: Vec<f64>,
    pub residual: f64,
    pub iterations: usize,
    pub load_steps: usize,
}

/// Smallest continuation step before giving up.
const MIN_STEP: f64 = 1e-5;
/// Tolerance of intermediate levels (relative, as `SolverOptions::tol`): stepping stones.
const LEVEL_TOL: f64 = 1e-6;

/// Continuation in the load factor lambda from x = `x0` at lambda = 0 (an exact solution
/// there) to lambda = 1: first the whole step, then halved on failure, or when it leaves
/// the stable path (`Equations::stable`, down to `MIN_STABLE_STEP`); a secant predictor
/// from the last two levels. `at(lambda)` builds the equations of a level. A warm start
/// `guess` of the full problem is tried first; if it lands on an unstable equilibrium the
/// path is followed too, and that one is kept in case the path ends no better.
/// With obstacles (docs/contact.md, "The side an obstacle is on") the answer must be
/// reached from x0 (the unloaded rods, or a shape reached from them) without a node's path
/// passing through an obstacle: each level is checked against the last and retried in
/// half the step where it crosses (down to `super::MIN_CROSSING_STEP`); a warm start's
/// equilibrium is checked against x0 and never kept when it crosses.
pub(crate) fn follow_path<E: Equations>(
    at: impl Fn(f64) -> E,
    x0: Vec<f64>,
    guess: Option<Vec<f64>>,
    opts: &SolverOptions,
) -> Result<PathOk> {
    let mut iterations = 0;
    // An equilibrium at lambda = 1 off the stable path, kept in case no stable one is reached.
    let mut unstable_end: Option<PathOk> = None;
    let origin = at(0.0);
    let start = Sides::start(&origin.rods(&x0));
    if let Some(g) = guess {
        let full = at(1.0);
        match newton(&full, g, opts.tol, opts.max_iter) {
            Ok(c) => {
                iterations += c.iterations;
                // An equilibrium beyond an obstacle is not the answer, nor a fallback: the
                // path from x0 finds the one on its side.
                if let (_, Some(crossed)) = sides_at(&full, &start, &c.x) {
                    if !opts.continuation {
                        return Err(crossing_error(crossed, None));
                    }
                } else {
                    let out = PathOk {
                        x: c.x,
                        residual: c.residual,
                        iterations: c.iterations,
                        load_steps: 1,
                    };
                    if !opts.continuation || full.stable(&out.x) != Some(false) {
                        return Ok(out);
                    }
                    unstable_end = Some(out);
                }
            }
            Err((it, res)) => {
                iterations += it;
                if !opts.continuation {
                    return Err(not_converged(
                        iterations,
                        res,
                        1.0,
                        "Newton failed from the initial guess and continuation is off".into(),
                    ));
                }
            }
        }
    }
    let mut lam = 0.0;
    let mut stable = origin.stable(&x0);
    // The last level's rods, from which the next level's nodes must not cross an obstacle.
    let mut last = start;
    let mut x = x0;
    let mut prev: Option<(f64, Vec<f64>)> = None;
    let mut step: f64 = 1.0;
    let mut levels = 0;
    // A failed path returns the unstable end it kept, if any.
    let fallback = |unstable_end: Option<PathOk>, e: SoftrodError| unstable_end.ok_or(e);
    loop {
        if levels >= opts.max_load_steps {
            return fallback(
                unstable_end,
                not_converged(
                    iterations,
                    f64::NAN,
                    lam,
                    format!(
                        "load continuation used all {} load steps",
                        opts.max_load_steps
                    ),
                ),
            );
        }
        levels += 1;
        let target = (lam + step).min(1.0);
        let h = target - lam;
        let predicted = match &prev {
            Some((lp, xp)) => {
                let d = at(target).difference(&x, xp);
                let f = h / (lam - lp);
                at(target).retract(&x, &d.iter().map(|v| v * f).collect::<Vec<_>>())
            }
            None => x.clone(),
        };
        let tol = if target < 1.0 {
            opts.tol.max(LEVEL_TOL)
        } else {
            opts.tol
        };
        let level = at(target);
        match newton(&level, predicted, tol, opts.max_iter) {
            Ok(c) => {
                iterations += c.iterations;
                let (sides, crossed) = sides_at(&level, &last, &c.x);
                if let Some(crossed) = crossed {
                    if h <= super::MIN_CROSSING_STEP || !opts.continuation {
                        return fallback(
                            unstable_end,
                            crossing_error(crossed, opts.continuation.then_some(h)),
                        );
                    }
                    step = 0.5 * h;
                    continue;
                }
                let st = level.stable(&c.x);
                let left_path = stable == Some(true) && st == Some(false);
                if target >= 1.0 {
                    let out = PathOk {
                        x: c.x,
                        residual: c.residual,
                        iterations,
                        load_steps: levels,
                    };
                    if !(left_path && h > MIN_STABLE_STEP && opts.continuation) {
                        return Ok(out);
                    }
                    unstable_end = Some(out);
                    step = 0.5 * h;
                    continue;
                }
                if left_path && h > MIN_STABLE_STEP {
                    step = 0.5 * h;
                    continue;
                }
                stable = st;
                last = sides;
                prev = Some((lam, std::mem::replace(&mut x, c.x)));
                lam = target;
                step = match c.iterations {
                    0..=4 => 2.0 * h,
                    5..=7 => h,
                    _ => 0.5 * h,
                };
            }
            Err((it, res)) => {
                iterations += it;
                if !opts.continuation {
                    return fallback(
                        unstable_end,
                        not_converged(
                            iterations,
                            res,
                            lam,
                            "Newton failed from the initial guess and continuation is off".into(),
                        ),
                    );
                }
                step = 0.5 * h;
                if step < MIN_STEP {
                    return fallback(
                        unstable_end,
                        not_converged(
                            iterations,
                            res,
                            lam,
                            "load step fell below 1e-5 (a limit point, or a prescribed pose the \
                         rod cannot reach)"
                                .into(),
                        ),
                    );
                }
            }
        }
    }
}

fn not_converged(
    iterations: usize,
    residual: f64,
    load_factor: f64,
    reason: String,
) -> SoftrodError {
    SoftrodError::NotConverged {
        iterations,
        residual,
        load_factor,
        reason,
    }
}

// ---- one rod with a constrained tip ----

/// The reference tip pose: the tip of the unloaded rod (x = 0 at load factor 0), without
/// its obstacles: a bed the rod lies on within its tolerance already pushes on it at zero
/// load, and integrating that push from a zero base wrench is not the rod's reference
/// shape.
pub(crate) fn reference_tip(rod: &Rod, loads: &Loads) -> State<f64> {
    let mut p = Problem::new(rod, loads, 0.0);
    for c in &mut p.coeffs {
        c.obstacles = None;
    }
    integrate(rod, &p.coeffs, p.base_state(&[0.0; 6]), None)
}

/// A held tip's prescribed pose at one level of a path: the position, and for a clamped
/// tip the rotation.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Pose {
    clamped: bool,
    position: [f64; 3],
    rotation: [[f64; 3]; 3],
}

impl Pose {
    /// The pose at path parameter `lam` in [0, 1] from (`r0`, `rot0`) (lam = 0) to the
    /// constraint's (lam = 1, exactly): the position on the straight line, the rotation on
    /// the geodesic (`slerp`). A pinned tip's rotation is not prescribed (kept at `rot0`).
    pub(crate) fn along(
        constraint: &TipConstraint,
        r0: &[f64; 3],
        rot0: &[[f64; 3]; 3],
        lam: f64,
    ) -> Pose {
        let (clamped, position, rotation) = match *constraint {
            TipConstraint::Pinned { position } => (false, position, *rot0),
            TipConstraint::Clamped { position, rotation } => (
                true,
                position,
                if lam >= 1.0 {
                    rotation
                } else {
                    slerp(rot0, &rotation, lam)
                },
            ),
            TipConstraint::Free => (false, *r0, *rot0),
        };
        let position = if lam >= 1.0 {
            position
        } else {
            std::array::from_fn(|k| r0[k] + lam * (position[k] - r0[k]))
        };
        Pose {
            clamped,
            position,
            rotation,
        }
    }
}

/// The equations of a held tip: problem `p` (its loads, and the friction state of the last
/// converged increment where it carries one) with the tip at `pose` ([`held_residual`]).
/// The frictional statics (`super::friction`) solves its increments with these.
pub(crate) struct Held<'p, 'a> {
    pub(crate) p: &'p Problem<'a>,
    pub(crate) pose: Pose,
}

impl Held<'_, '_> {
    fn residual<D: RodScalar>(&self, x: &[D]) -> [D; 6] {
        let tip = integrate(self.p.rod, &self.p.coeffs, self.p.base_state(x), None);
        let pose = &self.pose;
        held_residual(self.p, pose.clamped, &pose.position, &pose.rotation, &tip)
    }
}

impl Equations for Held<'_, '_> {
    fn eval(&self, x: &[f64]) -> Vec<f64> {
        self.residual(x).to_vec()
    }

    fn on_branch(&self, x: &[f64]) -> bool {
        if !self.pose.clamped {
            return true;
        }
        let tip = integrate(self.p.rod, &self.p.coeffs, self.p.base_state(x), None);
        on_quarter_turn(&tmatmul(&self.pose.rotation, &tip.rot))
    }

    fn eval_jac(&self, x: &[f64]) -> (Vec<f64>, DMatrix<f64>) {
        let xd: [Jet<6>; 6] = std::array::from_fn(|i| Jet::variable(x[i], i));
        let r = self.residual(&xd);
        (
            r.map(|v| v.re).to_vec(),
            DMatrix::from_fn(6, 6, |i, j| r[i].eps[j]),
        )
    }
}

/// One load level of a constrained solve.
struct Level<'a> {
    p: Problem<'a>,
    constraint: TipConstraint,
    /// The prescribed tip pose at this level.
    pose: Pose,
}

impl Level<'_> {
    /// The level at path parameter `lam`: the prescribed pose moved from `reference` (at
    /// lam = 0) to the constraint's (at 1), the loads scaled by `load_factor`.
    fn new<'a>(
        rod: &'a Rod,
        loads: &'a Loads,
        constraint: TipConstraint,
        reference: &State<f64>,
        lam: f64,
        load_factor: f64,
    ) -> Level<'a> {
        Level {
            p: Problem::new(rod, loads, load_factor),
            constraint,
            pose: Pose::along(&constraint, &reference.r, &reference.rot, lam),
        }
    }

    fn held(&self) -> Held<'_, '_> {
        Held {
            p: &self.p,
            pose: self.pose,
        }
    }
}

/// The held tip's scaled shooting residual (module docs) for the prescribed pose
/// (`position`; `rotation`, read only when `clamped`): (r(L) - r_c)/L, then for a clamped
/// tip the orientation error e(R_c^T R(L)), for a pinned one the tip moment balance of
/// `Problem::residual_of_tip`. Generic over the scalar: the solve's Newton steps and its
/// `Jet<6>` Jacobian, and the parameter sensitivities (`crate::sensitivity`, dual-valued
/// parameters), evaluate this one function.
pub(crate) fn held_residual<D: RodScalar>(
    p: &Problem,
    clamped: bool,
    position: &[f64; 3],
    rotation: &[[f64; 3]; 3],
    tip: &State<D>,
) -> [D; 6] {
    let l = p.rod.length;
    let second: [D; 3] = if clamped {
        orientation_error(&tmatmul(&rotation.map(|r| r.map(D::from)), &tip.rot))
    } else {
        let b: [D; 6] = p.residual_of_tip(tip);
        [b[3], b[4], b[5]]
    };
    std::array::from_fn(|k| {
        if k < 3 {
            (tip.r[k] - position[k]) * (1.0 / l)
        } else {
            second[k - 3]
        }
    })
}

/// The shooting residual of an equilibrium under the full loads `p` whose tip is held by
/// `constraint` at its prescribed pose ([`held_residual`]), or free (the tip wrench
/// balance, `Problem::residual_of_tip`, with N = 3 or 6 unknowns). A held tip has N = 6.
pub(crate) fn tip_residual<D: RodScalar, const N: usize>(
    p: &Problem,
    constraint: &TipConstraint,
    tip: &State<D>,
) -> [D; N] {
    let held = match constraint {
        TipConstraint::Free => return p.residual_of_tip(tip),
        TipConstraint::Pinned { position } => held_residual(p, false, position, &IDENTITY, tip),
        TipConstraint::Clamped { position, rotation } => {
            held_residual(p, true, position, rotation, tip)
        }
    };
    debug_assert_eq!(N, 6, "a held tip has 6 shooting unknowns");
    std::array::from_fn(|k| held[k])
}

/// [`tip_residual`] with 6 unknowns under the tip loads `f_tip` and `m_tip` (the design's
/// tip frame, unscaled: the problem's load factor must be 1) in any scalar, so that they
/// can carry derivatives (`crate::jacobian::point_jacobian6`). A pinned tip's moment rows
/// are the tip's moment balance; a clamped tip's residual has no load in it.
pub(crate) fn tip_residual_under<D: RodScalar>(
    p: &Problem,
    constraint: &TipConstraint,
    tip: &State<D>,
    f_tip: &[D; 3],
    m_tip: &[D; 3],
) -> [D; 6] {
    let w = p.tip_weight().map(D::from);
    let balance = || -> [D; 6] { p.tip_balance(tip, &w, f_tip, m_tip) };
    let l = p.rod.length;
    let held = |position: &[f64; 3], second: [D; 3]| -> [D; 6] {
        std::array::from_fn(|k| {
            if k < 3 {
                (tip.r[k] - position[k]) * (1.0 / l)
            } else {
                second[k - 3]
            }
        })
    };
    match constraint {
        TipConstraint::Free => balance(),
        TipConstraint::Pinned { position } => {
            let b = balance();
            held(position, [b[3], b[4], b[5]])
        }
        TipConstraint::Clamped { position, rotation } => held(
            position,
            orientation_error(&tmatmul(&rotation.map(|r| r.map(D::from)), &tip.rot)),
        ),
    }
}

/// [`reaction`] under the tip loads `f_tip` and `m_tip` in any scalar (as
/// [`tip_residual_under`]).
pub(crate) fn reaction_under<D: RodScalar>(
    p: &Problem,
    tip: &State<D>,
    f_tip: &[D; 3],
    m_tip: &[D; 3],
) -> ([D; 3], [D; 3]) {
    let w = p.tip_weight().map(D::from);
    let b: [D; 6] = p.tip_balance(tip, &w, f_tip, m_tip);
    (
        std::array::from_fn(|k| b[k] * p.fs),
        std::array::from_fn(|k| b[k + 3] * p.ms),
    )
}

pub(crate) const IDENTITY: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

impl Equations for Level<'_> {
    fn eval(&self, x: &[f64]) -> Vec<f64> {
        self.held().eval(x)
    }

    fn eval_jac(&self, x: &[f64]) -> (Vec<f64>, DMatrix<f64>) {
        self.held().eval_jac(x)
    }

    fn stable(&self, x: &[f64]) -> Option<bool> {
        constrained_stability(&self.p, x, &self.constraint)
    }

    fn on_branch(&self, x: &[f64]) -> bool {
        self.held().on_branch(x)
    }

    fn rods<'s>(&'s self, x: &'s [f64]) -> Vec<(&'s Problem<'s>, &'s [f64])> {
        vec![(&self.p, x)]
    }
}

/// The tip wrench the constraint applies (world frame): what is left of the tip balance.
/// Generic over the scalar: the parameter sensitivities (`crate::sensitivity`) take its
/// derivatives through the same function.
pub(crate) fn reaction<D: RodScalar>(p: &Problem, tip: &State<D>) -> ([D; 3], [D; 3]) {
    let b: [D; 6] = p.residual_of_tip(tip);
    (
        std::array::from_fn(|k| b[k] * p.fs),
        std::array::from_fn(|k| b[k + 3] * p.ms),
    )
}

/// The validity rules of `Problem::check_node` at every node of the solution x (the shape
/// kept); the tip state. Shared with `super::system`.
pub(crate) fn checked_shape(
    p: &Problem,
    x: &[f64],
    opts: &SolverOptions,
    violations: &mut Vec<SoftrodError>,
) -> Result<(State<f64>, Shape)> {
    let mut shape = Shape::default();
    let mut broken: Option<SoftrodError> = None;
    let mut worst: Option<(f64, SoftrodError)> = None;
    let mut index = 0;
    let mut last = None;
    let mut visit = |i: usize, s: f64, y: &State<f64>| {
        let node = Node {
            index,
            s,
            section: i,
        };
        index += 1;
        match p.check_node(
            node,
            y,
            opts,
            &mut worst,
            &mut crate::ode::Scratch::default(),
            &mut last,
        ) {
            Ok((v, u)) => shape.push(node, y, v, u),
            Err(e) => {
                broken.get_or_insert(e);
            }
        }
    };
    let tip = integrate(p.rod, &p.coeffs, p.base_state(x), Some(&mut visit));
    if let Some(e) = broken {
        return Err(e);
    }
    if let Some((_, e)) = worst {
        match opts.on_invalid {
            Policy::Raise => return Err(e),
            Policy::Warn => violations.push(e),
            Policy::Ignore => {}
        }
    }
    Ok((tip, shape))
}

/// The conjugate-point test of a rod whose tip position is held (module docs): Y(s) =
/// [dr(s)/L; dtheta(s)], the position and rotation parts of the six Jacobi fields that
/// start at the clamp. Near the clamp Y ~ s diag(R0 K_se^-1 R0^T F_s / L,
/// R0 K_bt^-1 R0^T M_s) + O(s^2) is non-singular; a crossing between two nodes shows as an
/// eigenvalue of T = Y(s_k+1)^-1 Y(s_k) with a non-positive real part (without one, T = I +
/// O(h)). The eigenvalues count the double crossings of symmetric rods (a round column
/// buckles in two planes at once), which leave det Y's sign unchanged, as the free tip's
/// `super::Jacobi` does.
#[derive(Default, Clone)]
pub(crate) struct Conjugate {
    /// An elastic step has been taken (Y = 0 on leading rigid sections).
    elastic: bool,
    conjugate: bool,
    y: Matrix6<f64>,
}

impl Conjugate {
    /// The node state y carries the six Jacobi fields in its first six dual directions
    /// (N > 6: the further ones, e.g. a load-factor direction, are not read).
    pub(crate) fn visit<const N: usize>(&mut self, y: &State<Jet<N>>, length: f64) {
        let m = Matrix6::from_fn(|a, j| {
            if a < 3 {
                y.r[a].eps[j] / length
            } else {
                rotation_field(y, a - 3, j)
            }
        });
        if self.elastic {
            if !self.conjugate && m != self.y {
                self.conjugate = match m.lu().solve(&self.y) {
                    Some(t) => !eigenvalues_right_half_plane(&t),
                    None => true,
                };
            }
        } else {
            self.elastic = m.iter().any(|v| *v != 0.0);
        }
        self.y = m;
    }

    /// Clamped tip: no conjugate point in (0, L]. A rod without an elastic step cannot
    /// deform and is stable.
    pub(crate) fn stable_clamped(&self) -> bool {
        !self.elastic || !self.conjugate
    }

    /// Pinned tip: no conjugate point in (0, L] and the tip form sym(J_m Y(L)^-1 [0; I])
    /// positive definite, `jm` the x-derivative of the scaled tip moment balance (3x6).
    pub(crate) fn stable_pinned(&self, jm: &SMatrix<f64, 3, 6>) -> bool {
        if !self.elastic {
            return true;
        }
        if self.conjugate {
            return false;
        }
        let e = SMatrix::<f64, 6, 3>::from_fn(|i, j| if i == j + 3 { 1.0 } else { 0.0 });
        let Some(c) = self.y.lu().solve(&e) else {
            return false;
        };
        let k: Matrix3<f64> = jm * c;
        let q = (k + k.transpose()) * 0.5;
        q.iter().all(|v| v.is_finite()) && q.cholesky().is_some()
    }

    /// Free tip with the base force unknown (contact, docs/contact.md "Stability"): no
    /// conjugate point in (0, L] and the tip form sym(J Y(L)^-1) positive definite, `jac`
    /// the x-derivative of the scaled tip wrench balance (6x6). The Jacobi field reaching
    /// the tip with (dr(L)/L, dtheta(L)) = xi is c = Y(L)^-1 xi, and its second variation is
    /// the tip's boundary term dr(L) . dF_res + dtheta(L) . dM_res = M_s xi^T J c (the force
    /// rows scaled by F_s, the moment rows by M_s = F_s L, dr by L): the pinned form with
    /// the tip position free too. Position-dependent loads (the obstacles' penalty, the
    /// rounded end's force in the tip balance) enter both Y and J through the dual numbers.
    pub(crate) fn stable_free(&self, jac: &Matrix6<f64>) -> bool {
        if !self.elastic {
            return true;
        }
        if self.conjugate {
            return false;
        }
        let Some(inv) = self.y.try_inverse() else {
            return false;
        };
        let k = jac * inv;
        let q = (k + k.transpose()) * 0.5;
        q.iter().all(|v| v.is_finite()) && q.cholesky().is_some()
    }
}

/// The loads of a constrained solve have a potential (stability is assessed): no follower
/// line loads, and no follower tip moment on a pin (module docs).
fn conservative(rod: &Rod, loads: &Loads, constraint: &TipConstraint) -> bool {
    let follower_moment =
        loads.tip_frame == Frame::Body && loads.tip_moment.iter().any(|m| *m != 0.0);
    !rod.spec.has_follower_line_loads()
        && match constraint {
            TipConstraint::Pinned { .. } => !follower_moment,
            TipConstraint::Clamped { .. } => true,
            TipConstraint::Free => false,
        }
}

/// The stability of the equilibrium x of a constrained tip under the full loads `p`: one
/// integration in `Jet<6>` (the Jacobi fields) and the test of `Conjugate`. None where it is
/// not assessed (non-conservative loads; a free tip has its own test).
pub(crate) fn constrained_stability(
    p: &Problem,
    x: &[f64],
    constraint: &TipConstraint,
) -> Option<bool> {
    // Friction (`super::friction`) has no potential: not assessed.
    if x.len() != 6 || !conservative(p.rod, p.loads, constraint) || p.friction_end.is_some() {
        return None;
    }
    let xd: [Jet<6>; 6] = std::array::from_fn(|i| Jet::variable(x[i], i));
    let mut conj = Conjugate::default();
    let length = p.rod.length;
    let mut visit = |_: usize, _: f64, y: &State<Jet<6>>| conj.visit(y, length);
    let tip = integrate(p.rod, &p.coeffs, p.base_state(&xd), Some(&mut visit));
    match constraint {
        TipConstraint::Clamped { .. } => Some(conj.stable_clamped()),
        TipConstraint::Pinned { .. } => {
            let b: [Jet<6>; 6] = p.residual_of_tip(&tip);
            Some(conj.stable_pinned(&SMatrix::<f64, 3, 6>::from_fn(|i, j| b[i + 3].eps[j])))
        }
        TipConstraint::Free => None,
    }
}

/// A clamped end that converged to a half turn from its target (e vanishes there too) is
/// no solution.
pub(crate) fn check_half_turn(field: &str, a: &[[f64; 3]; 3]) -> Result<()> {
    let tr = a[0][0] + a[1][1] + a[2][2];
    if on_quarter_turn(a) {
        Ok(())
    } else {
        Err(SoftrodError::NotConverged {
            iterations: 0,
            residual: tr,
            load_factor: 1.0,
            reason: format!(
                "{field}: the orientation converged to a rotation {:.1} degrees from the \
                 prescribed one, not to it",
                (0.5 * (tr - 1.0)).clamp(-1.0, 1.0).acos().to_degrees()
            ),
        })
    }
}

/// Static equilibrium with the tip held by `constraint` (a free tip: [`super::solve`] with
/// zero reaction). `guess`: a previous solution's 6 unknowns.
pub fn solve_constrained(
    rod: &Rod,
    loads: &Loads,
    constraint: &TipConstraint,
    guess: Option<&[f64]>,
    opts: &SolverOptions,
) -> Result<ConstrainedSolution> {
    constraint.validate()?;
    if let TipConstraint::Free = constraint {
        let (solution, shape) = super::solve_with_shape(rod, loads, guess, opts)?;
        return Ok(ConstrainedSolution {
            solution,
            shape,
            tip_reaction_force: [0.0; 3],
            tip_reaction_moment: [0.0; 3],
        });
    }
    let mut violations = super::check_inputs(rod, loads, opts)?;
    let c = *constraint;
    let guess = guess
        .filter(|g| g.len() == 6 && g.iter().all(|v| v.is_finite()))
        .map(|g| g.to_vec());
    // First path: the free equilibrium under the full loads (found on its natural path,
    // stable where assessed), then the tip moved from its pose there to the prescribed
    // one. If the free rod has no valid equilibrium (e.g. a soft beam that only the second
    // support keeps from sagging beyond its validity range), the loads are ramped from the
    // unloaded shape together with the pose.
    let from_free = super::solve(
        rod,
        loads,
        None,
        &SolverOptions {
            on_invalid: Policy::Ignore,
            ..*opts
        },
    )
    .ok()
    .map(|free| {
        let p = Problem::new(rod, loads, 1.0);
        let x0: Vec<f64> = (0..6)
            .map(|k| {
                if k < 3 {
                    free.base_force[k] / p.fs
                } else {
                    free.base_moment[k - 3] / p.ms
                }
            })
            .collect();
        (free.tip, x0)
    });
    let mut first_err = None;
    if let Some((start, x0)) = from_free {
        match follow_path(
            |lam| Level::new(rod, loads, c, &start, lam, 1.0),
            x0,
            guess.clone(),
            opts,
        ) {
            Ok(path) => return conclude(rod, loads, constraint, path, opts, &mut violations),
            Err(e) => first_err = Some(e),
        }
    }
    let reference = reference_tip(rod, loads);
    let path = follow_path(
        |lam| Level::new(rod, loads, c, &reference, lam, lam),
        vec![0.0; 6],
        guess,
        opts,
    )
    .map_err(|e| first_err.unwrap_or(e))?;
    conclude(rod, loads, constraint, path, opts, &mut violations)
}

/// The checked solution at the end of a path.
fn conclude(
    rod: &Rod,
    loads: &Loads,
    constraint: &TipConstraint,
    path: PathOk,
    opts: &SolverOptions,
    violations: &mut Vec<SoftrodError>,
) -> Result<ConstrainedSolution> {
    conclude_at(
        &Problem::new(rod, loads, 1.0),
        constraint,
        path,
        opts,
        violations,
    )
}

/// The checked solution at the end of a path whose last level is the full-load problem
/// `level` (with the frictional statics' friction state, `super::friction`, where it
/// carries one): the shape checked, a clamp's half turn refused, the tip reaction, and
/// the stability where assessed.
pub(crate) fn conclude_at(
    level: &Problem,
    constraint: &TipConstraint,
    path: PathOk,
    opts: &SolverOptions,
    violations: &mut Vec<SoftrodError>,
) -> Result<ConstrainedSolution> {
    let violations_out = violations;
    let (tip, shape) = checked_shape(level, &path.x, opts, violations_out)?;
    if let TipConstraint::Clamped { rotation, .. } = constraint {
        check_half_turn("tip_constraint.orientation", &tmatmul(rotation, &tip.rot))?;
    }
    let (force, moment) = reaction(level, &tip);
    let moment = match constraint {
        // The moment balance is a residual row: its leftover is round-off, not a reaction.
        TipConstraint::Pinned { .. } => [0.0; 3],
        _ => moment,
    };
    let y0 = level.base_state(&path.x);
    let stable = constrained_stability(level, &path.x, constraint);
    Ok(ConstrainedSolution {
        solution: Solution {
            x: path.x,
            base_force: y0.n,
            base_moment: y0.m,
            tip,
            iterations: path.iterations,
            residual: path.residual,
            load_steps: path.load_steps,
            stable,
            violations: std::mem::take(violations_out),
            collocation: None,
            friction: None,
        },
        shape,
        tip_reaction_force: force,
        tip_reaction_moment: moment,
    })
}

/// The scaled constraint residual and its exact Jacobian at 6 unknowns x under the full
/// loads (exposed for tests: finite differences, and the pinned-pinned column's Jacobian
/// vanishing at the Euler load). `constraint` must be pinned or clamped.
pub fn constraint_residual_and_jacobian(
    rod: &Rod,
    loads: &Loads,
    constraint: &TipConstraint,
    x: &[f64],
) -> Result<(Vec<f64>, Vec<Vec<f64>>)> {
    constraint.validate()?;
    if matches!(constraint, TipConstraint::Free) {
        return Err(SoftrodError::invalid(
            "constraint",
            "free",
            "must be pinned or clamped (a free tip: statics::residual_and_jacobian)",
        ));
    }
    if x.len() != 6 {
        return Err(SoftrodError::invalid(
            "x",
            format!("{} values", x.len()),
            "a constrained tip has 6 shooting unknowns (base force and moment)",
        ));
    }
    let reference = reference_tip(rod, loads);
    let level = Level::new(rod, loads, *constraint, &reference, 1.0, 1.0);
    let (r, j) = level.eval_jac(x);
    Ok((
        r,
        (0..6)
            .map(|i| (0..6).map(|k| j[(i, k)]).collect())
            .collect(),
    ))
}
