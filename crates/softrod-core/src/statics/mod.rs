//! Static equilibrium by shooting (docs/model.md, "Solver"; paper 001 section II-D), with
//! the equilibrium's stability and validity checked before it is returned.
//!
//! When all loads are dead (gravity, dead tip and line loads, the tip body's weight; tendon
//! tensions and pressures are internal, see `crate::tendon`), the force balance n' = -f is
//! statically determinate: n(0) = F_tip + m_t g + int_0^L f ds exactly, and only the base
//! moment m(0) is unknown (3 unknowns instead of the usual 6). It is scaled by M_s = F_s L
//! with F_s = EI_min / L^2. Residual: the tip moment balance m(L) = M_tip + (R(L) c) x
//! (m_t g), scaled the same way; n(L) = F_tip + m_t g holds by construction. With a follower
//! load (tip or line load in the body frame, which turns with the rod) n(0) depends on the
//! shape: the base force is unknown too (6 unknowns, n(0)/F_s and m(0)/M_s) and the residual
//! is the full tip wrench balance. The solver picks the 3- or 6-unknown problem per solve.
//! Newton with the exact Jacobian from forward-mode dual numbers (one integration in
//! `Jet<3>` or `Jet<6>` gives residual and Jacobian), a backtracking line search and a
//! Levenberg-Marquardt step when the Jacobian is singular.
//!
//! A cold start follows the natural path: loads (pressures, gravity, tip and line loads)
//! ramped from zero with a tangent predictor (dx/dlambda = -J^-1 dR/dlambda, exact by dual
//! numbers, see `Problem::tangent`) and adaptive steps, the first step going straight to the
//! full load. Each level's equilibrium must be stable while the path is (else the step is
//! cut), so the path does not jump to another branch. See docs/model.md "Solver" and
//! "Validity and stability".
//!
//! Stability (`Jacobi`): the second variation of the energy is positive definite iff there is
//! no point conjugate to the clamp in (0, L] (det of the Jacobi fields' rotations,
//! d theta(s)/dx, keeps its sign) and the tip form sym(Theta(L)^T J) is positive definite.
//! The test needs a potential energy: follower loads are not conservative (they do work
//! along closed paths), so their equilibria are reported with `stable = None`, not assessed.
//! Contact has one (the obstacles' penalty): with its six unknowns the test is that of
//! all six Jacobi fields from the clamp (`constraint::Conjugate::stable_free`).
//! Collocation solutions run the same test with the Jacobi fields carried by the
//! linearised collocation equations (`collocation::stability`).

pub mod collocation;
pub mod constraint;
pub mod contact;
pub mod friction;
pub mod system;
pub(crate) mod tangent;

use crate::error::{Result, SoftrodError};
use crate::jet::{Jet, RodScalar};
use crate::ode::{
    integrate, integrate_remembering, strains, strains_with, Coeffs, LawMemory, Loads, Scratch,
    SectionKnobs, State,
};
use crate::rod::Rod;
use crate::spec::Frame;
use crate::validity::{self, Node, Policy, StrainLimits};
use nalgebra::{Matrix3, Matrix6, SMatrix, SVector};

/// Solver settings (a validated value object with defaults).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverOptions {
    /// Convergence tolerance on the scaled residual (infinity norm), relative to
    /// max(1, |x|_inf). 1e-10 puts the tip-wrench error far below what moves the tip
    /// by 1e-9 of the length.
    pub tol: f64,
    /// Newton iterations per load level.
    pub max_iter: usize,
    /// Ramp loads from zero (the natural path) when Newton fails from the initial guess or
    /// lands on an unstable equilibrium.
    pub continuation: bool,
    /// Most load levels continuation may take.
    pub max_load_steps: usize,
    /// Validity range of the fibre stretch (`crate::validity`).
    pub strain_limits: StrainLimits,
    /// What a solution outside a validity range (strains, the design's operating range)
    /// gives: an error, a solution listing the violations, or no check.
    pub on_invalid: Policy,
}

impl Default for SolverOptions {
    fn default() -> Self {
        SolverOptions {
            tol: 1e-10,
            max_iter: 25,
            continuation: true,
            max_load_steps: 200,
            strain_limits: StrainLimits::default(),
            on_invalid: Policy::Raise,
        }
    }
}

impl SolverOptions {
    pub fn validate(&self) -> Result<()> {
        if !(self.tol.is_finite() && self.tol > 0.0 && self.tol < 1.0) {
            return Err(SoftrodError::invalid("tol", self.tol, "must be in (0, 1)"));
        }
        if self.max_iter == 0 || self.max_iter > MAX_ITER {
            return Err(SoftrodError::invalid(
                "max_iter",
                self.max_iter,
                format!("must be in 1..={MAX_ITER}"),
            ));
        }
        if self.max_load_steps == 0 || self.max_load_steps > MAX_LOAD_STEPS {
            return Err(SoftrodError::invalid(
                "max_load_steps",
                self.max_load_steps,
                format!("must be in 1..={MAX_LOAD_STEPS}"),
            ));
        }
        self.strain_limits.validate()
    }
}

/// Most Newton iterations per load level a caller may ask for.
pub const MAX_ITER: usize = 100_000;
/// Most continuation load levels a caller may ask for.
pub const MAX_LOAD_STEPS: usize = 100_000;

/// A converged static equilibrium (the shape is recovered with [`shape`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// Scaled shooting unknowns: m(0)/(F_s L) (3, dead loads) or n(0)/F_s then m(0)/(F_s L)
    /// (6, with follower loads); reuse as a warm start.
    pub x: Vec<f64>,
    /// Total internal force at the base, world frame, N.
    pub base_force: [f64; 3],
    /// Total internal moment at the base, world frame, N m.
    pub base_moment: [f64; 3],
    /// State at the tip.
    pub tip: State<f64>,
    /// Newton iterations, all load levels together.
    pub iterations: usize,
    /// Final scaled residual (infinity norm).
    pub residual: f64,
    /// Load levels used (1 when the first step reached the full load).
    pub load_steps: usize,
    /// The equilibrium is stable: the second variation of the energy is positive definite
    /// (no conjugate point, positive tip form; docs/model.md "Validity and stability").
    /// None where it is not assessed: under follower loads, which have no potential.
    pub stable: Option<bool>,
    /// Validity-range violations (with `Policy::Warn`; empty otherwise): the worst fibre
    /// stretch outside `strain_limits`, pressures outside the design's operating range.
    pub violations: Vec<SoftrodError>,
    /// The shape and unknowns, when the solve used collocation (`crate::collocation`):
    /// re-integrating from `x` by shooting is what that rod's conditioning forbids.
    pub collocation: Option<std::sync::Arc<Collocated>>,
    /// The frictional statics' path state at this equilibrium (`friction`): its loads and
    /// every contact point's friction memory, from which a further path may start. None
    /// for a frictionless solve.
    pub friction: Option<std::sync::Arc<friction::FrictionPath>>,
}

/// An equilibrium solved by collocation: its shape, and its scaled collocation unknowns,
/// from which its exact derivatives are taken (`collocation::implicit`).
#[derive(Debug, Clone, PartialEq)]
pub struct Collocated {
    pub shape: Shape,
    pub z: Vec<f64>,
}

/// The rod's shape at every integration node.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Shape {
    pub s: Vec<f64>,
    pub section: Vec<usize>,
    pub position: Vec<[f64; 3]>,
    pub rotation: Vec<[[f64; 3]; 3]>,
    pub force: Vec<[f64; 3]>,
    pub moment: Vec<[f64; 3]>,
    /// Shear/stretch strain v (body frame).
    pub v: Vec<[f64; 3]>,
    /// Curvature/twist u (body frame).
    pub u: Vec<[f64; 3]>,
}

impl Shape {
    fn push(&mut self, node: Node, y: &State<f64>, v: [f64; 3], u: [f64; 3]) {
        self.s.push(node.s);
        self.section.push(node.section);
        self.position.push(y.r);
        self.rotation.push(y.rot);
        self.force.push(y.n);
        self.moment.push(y.m);
        self.v.push(v);
        self.u.push(u);
    }
}

/// One load level of one problem: coefficients and scales.
pub(crate) struct Problem<'a> {
    rod: &'a Rod,
    loads: &'a Loads,
    factor: f64,
    pub(crate) coeffs: Vec<Coeffs<f64>>,
    /// Base force of the 3-unknown problem, known exactly from the force balance.
    n0: [f64; 3],
    /// Its derivative with respect to the load factor (it is linear in the factor).
    dn0: [f64; 3],
    /// Force and moment scales of the unknowns and residuals.
    fs: f64,
    ms: f64,
    /// Some load follows the body: 6 unknowns (base force and moment).
    follower: bool,
    /// The tendon law's solutions of the last pass, the next pass's starts.
    memory: std::cell::RefCell<LawMemory>,
    /// The frictional statics' rounded-end contact point from the last converged
    /// increment (`friction`); its stage points ride in `coeffs`. None: frictionless.
    friction_end: Option<crate::contact::StickPoint>,
}

fn inf_norm(r: &[f64]) -> f64 {
    r.iter().fold(
        0.0,
        |a: f64, x| if x.is_nan() { f64::NAN } else { a.max(x.abs()) },
    )
}

/// Broyden's rank-one update of J after the step dx changed the residual by dr.
fn broyden<const N: usize>(
    jac: &mut SMatrix<f64, N, N>,
    dx: &SVector<f64, N>,
    dr: &SVector<f64, N>,
) {
    let d2 = dx.norm_squared();
    if d2 > 0.0 && d2.is_finite() {
        let update = (dr - *jac * dx) * dx.transpose() / d2;
        if update.iter().all(|v| v.is_finite()) {
            *jac += update;
        }
    }
}

fn cross<D: RodScalar>(a: &[D; 3], b: &[D; 3]) -> [D; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Solve a x = b by Gaussian elimination with partial pivoting (nalgebra's LU needs
/// type-level sizes); None if a is singular or the result is not finite.
fn solve_linear<const N: usize>(
    a: &SMatrix<f64, N, N>,
    b: &SVector<f64, N>,
) -> Option<SVector<f64, N>> {
    let mut m = *a;
    let mut x = *b;
    for k in 0..N {
        let p = (k..N).max_by(|&i, &j| m[(i, k)].abs().total_cmp(&m[(j, k)].abs()))?;
        if m[(p, k)] == 0.0 || !m[(p, k)].is_finite() {
            return None;
        }
        m.swap_rows(k, p);
        x.swap_rows(k, p);
        for i in k + 1..N {
            let f = m[(i, k)] / m[(k, k)];
            for j in k..N {
                m[(i, j)] -= f * m[(k, j)];
            }
            x[i] -= f * x[k];
        }
    }
    for k in (0..N).rev() {
        let mut acc = x[k];
        for j in k + 1..N {
            acc -= m[(k, j)] * x[j];
        }
        x[k] = acc / m[(k, k)];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// R v for a row-major rotation R.
fn rotate<D: RodScalar>(rot: &[[D; 3]; 3], v: &[D; 3]) -> [D; 3] {
    std::array::from_fn(|i| rot[i][0] * v[0] + rot[i][1] * v[1] + rot[i][2] * v[2])
}

/// Where a final pass concludes: a point the solver's Newton converged (its residual is
/// known), or unknowns given by a caller (the pass checks that they are an equilibrium).
enum At<'a, const N: usize> {
    Converged(&'a Converged<N>),
    Unchecked(&'a [f64; N]),
}

/// A Newton solve that reached the tolerance.
struct Converged<const N: usize> {
    x: [f64; N],
    /// Residual at x.
    r: [f64; N],
    /// Its infinity norm.
    residual: f64,
    iterations: usize,
}

/// How Newton starts.
#[derive(Clone, Copy)]
enum Start<const N: usize> {
    /// From a guess, with the exact Jacobian there.
    Guess,
    /// From a predicted point (load continuation), with a Jacobian from nearby and the
    /// residual at the point. With `fail_fast` it gives up at once when its first full
    /// step fails even with the exact Jacobian: the prediction lies outside Newton's basin,
    /// and a shorter load step is cheaper than a line search far from the solution.
    Predicted {
        jac: SMatrix<f64, N, N>,
        r: [f64; N],
        fail_fast: bool,
    },
}

/// Number of shooting unknowns of a solve: 6 with follower loads, else 3.
pub fn n_unknowns(rod: &Rod, loads: &Loads) -> usize {
    if loads.base_force_unknown(rod) {
        6
    } else {
        3
    }
}

impl<'a> Problem<'a> {
    pub(crate) fn new(rod: &'a Rod, loads: &'a Loads, factor: f64) -> Self {
        let coeffs = (0..rod.sections.len())
            .map(|i| {
                Coeffs::build(
                    rod,
                    i,
                    &loads.pressures,
                    &loads.tensions,
                    &rod.gravity,
                    factor,
                    &loads.stiffness_scale,
                )
            })
            .collect();
        let mut p = Problem {
            rod,
            loads,
            factor,
            coeffs,
            n0: [0.0; 3],
            dn0: [0.0; 3],
            fs: rod.force_scale,
            ms: rod.force_scale * rod.length,
            follower: loads.base_force_unknown(rod),
            memory: Default::default(),
            friction_end: None,
        };
        let w = p.tip_weight();
        let mt = rod.spec.tip.mass;
        let dead_tip = if p.follower { 0.0 } else { 1.0 };
        for k in 0..3 {
            p.n0[k] = dead_tip * factor * loads.tip_force[k] + w[k];
            p.dn0[k] = dead_tip * loads.tip_force[k] + mt * rod.gravity[k];
        }
        for sec in &rod.sections {
            // int f ds over the section: the mean line mass (exact for a tapered one).
            for k in 0..3 {
                let f = sec.line_mass * rod.gravity[k] + sec.line_force[k];
                p.n0[k] += factor * f * sec.length;
                p.dn0[k] += f * sec.length;
            }
        }
        p
    }

    /// The full-load problem of a solution `sol` of `loads`: with the friction state it
    /// carries (the frictional statics), whose contact loads are then those it converged
    /// with (to round-off: the state after the return map at the same shape).
    pub(crate) fn for_solution(rod: &'a Rod, loads: &'a Loads, sol: &Solution) -> Self {
        match &sol.friction {
            Some(f) => Problem::with_friction(rod, loads, 1.0, &f.state),
            None => Problem::new(rod, loads, 1.0),
        }
    }

    /// [`Problem::new`] whose contact carries elastic-slip friction from the points'
    /// state `state` of the last converged increment (`friction`).
    pub(crate) fn with_friction(
        rod: &'a Rod,
        loads: &'a Loads,
        factor: f64,
        state: &friction::FrictionState,
    ) -> Self {
        let mut p = Problem::new(rod, loads, factor);
        for (c, points) in p.coeffs.iter_mut().zip(&state.sections) {
            c.friction = Some(points.clone());
        }
        p.friction_end = Some(state.end.clone());
        p
    }

    /// Force scale of the unknowns n(0) / F_s (6 unknowns), N.
    pub(crate) fn force_scale(&self) -> f64 {
        self.fs
    }

    /// The loads have a potential, so stability is assessed: no follower load. (Contact
    /// with obstacles has one, the penalty's; it only makes the base force unknown.)
    pub(crate) fn assessed(&self) -> bool {
        !self.loads.has_follower(self.rod) && self.friction_end.is_none()
    }

    /// Unknowns of this problem (3 or 6).
    pub(crate) fn unknowns(&self) -> usize {
        if self.follower {
            6
        } else {
            3
        }
    }

    /// Tip-body weight (world), scaled by the load factor.
    pub(crate) fn tip_weight(&self) -> [f64; 3] {
        let mt = self.rod.spec.tip.mass;
        self.rod.gravity.map(|g| self.factor * mt * g)
    }

    /// The base state of the scaled unknowns x (3: m(0); 6: n(0) and m(0)).
    pub(crate) fn base_state<D: RodScalar>(&self, x: &[D]) -> State<D> {
        let c = |v: f64| D::from(v);
        let (n, m) = if x.len() == 6 {
            (
                [x[0] * self.fs, x[1] * self.fs, x[2] * self.fs],
                [x[3] * self.ms, x[4] * self.ms, x[5] * self.ms],
            )
        } else {
            (
                self.n0.map(c),
                [x[0] * self.ms, x[1] * self.ms, x[2] * self.ms],
            )
        };
        State {
            r: self.rod.base_position.map(c),
            rot: self.rod.base_rotation.map(|row| row.map(c)),
            n,
            m,
            aux: [c(1.0), c(1.0)],
        }
    }

    pub(crate) fn residual_of_tip<D: RodScalar, const N: usize>(&self, tip: &State<D>) -> [D; N] {
        let w = self.tip_weight().map(D::from);
        let f_tip = self.loads.tip_force.map(|f| D::from(self.factor * f));
        let m_tip = self.loads.tip_moment.map(|m| D::from(self.factor * m));
        self.tip_balance(tip, &w, &f_tip, &m_tip)
    }

    /// Scaled tip balance for a tip weight W and tip loads F, M (in the solve's tip frame;
    /// any of them may carry a load derivative): the moment m(L) - (R(L) c) x W - M, and
    /// with 6 unknowns first the force n(L) - W - F.
    pub(crate) fn tip_balance<D: RodScalar, const N: usize>(
        &self,
        tip: &State<D>,
        w: &[D; 3],
        f_tip: &[D; 3],
        m_tip: &[D; 3],
    ) -> [D; N] {
        let com = self.rod.spec.tip.com_offset;
        // centre of mass offset in the world frame: R(L) c
        let cw = rotate(&tip.rot, &com.map(D::from));
        let cxw = cross(&cw, w);
        let body = self.loads.tip_frame == Frame::Body;
        let (f, m) = if body {
            (rotate(&tip.rot, f_tip), rotate(&tip.rot, m_tip))
        } else {
            (*f_tip, *m_tip)
        };
        // The rod's rounded end presses on obstacles too (through the tip: no moment, but
        // for the frictional statics' friction at its surface point).
        let (end, end_moment) = match &self.friction_end {
            Some(old) => friction::end_load(self.rod, &tip.r, &tip.rot, old),
            None => (contact::end_force(self.rod, &tip.r), [D::from(0.0); 3]),
        };
        let moment: [D; 3] =
            std::array::from_fn(|k| (tip.m[k] - cxw[k] - m[k] - end_moment[k]) * (1.0 / self.ms));
        if N == 6 {
            std::array::from_fn(|k| {
                if k < 3 {
                    (tip.n[k] - w[k] - f[k] - end[k]) * (1.0 / self.fs)
                } else {
                    moment[k - 3]
                }
            })
        } else {
            std::array::from_fn(|k| moment[k])
        }
    }

    /// [`integrate`] of this problem's coefficients from `y0`, with the tendon law
    /// started from the last pass's solutions (`LawMemory`).
    fn pass<C: crate::jet::Coeff, D: crate::jet::StateScalar<C>>(
        &self,
        coeffs: &[Coeffs<C>],
        y0: State<D>,
        visit: Option<crate::ode::Visitor<'_, D>>,
    ) -> State<D> {
        let mut memory = self.memory.borrow_mut();
        integrate_remembering(self.rod, coeffs, y0, visit, &mut memory)
    }

    fn eval<const N: usize>(&self, x: &[f64; N]) -> [f64; N] {
        let tip = self.pass(&self.coeffs, self.base_state(x), None);
        self.residual_of_tip(&tip)
    }

    /// Residual and exact Jacobian by forward-mode AD (N directions).
    fn eval_jac<const N: usize>(&self, x: &[f64; N]) -> ([f64; N], SMatrix<f64, N, N>) {
        let xd: [Jet<N>; N] = std::array::from_fn(|i| Jet::variable(x[i], i));
        let tip = self.pass(&self.coeffs, self.base_state(&xd), None);
        let rd: [Jet<N>; N] = self.residual_of_tip(&tip);
        let jac = SMatrix::<f64, N, N>::from_fn(|i, j| rd[i].eps[j]);
        (rd.map(|r| r.re), jac)
    }

    /// The path's tangent dx/dlambda = -J^-1 dR/dlambda at a point x of this load level,
    /// with J and the point's stability: one integration in `Jet<M>` (M = N + 1), the
    /// unknowns seeded in directions 0..N and the load factor in direction N (through the
    /// coefficients, the base force and the tip loads). None if J is singular. Stability is
    /// assessed (Some) for conservative loads only.
    fn tangent<const N: usize, const M: usize>(
        &self,
        x: &[f64; N],
    ) -> Option<([f64; N], SMatrix<f64, N, N>, Option<bool>)> {
        debug_assert_eq!(M, N + 1);
        let lam = Jet::<M>::variable(self.factor, N);
        let sigma = self.loads.stiffness_scale.map(Jet::from);
        let coeffs: Vec<Coeffs<Jet<M>>> = (0..self.rod.sections.len())
            .map(|i| {
                let knobs = SectionKnobs::of(&self.rod.sections[i]).lift();
                Coeffs::build_with(
                    self.rod,
                    i,
                    &self.loads.pressures,
                    &self.loads.tensions,
                    &self.rod.gravity,
                    lam,
                    &sigma,
                    &knobs,
                )
            })
            .collect();
        let xs: [Jet<M>; N] = std::array::from_fn(|i| Jet::variable(x[i], i));
        let mut y0: State<Jet<M>> = self.base_state(&xs);
        if N == 3 {
            for k in 0..3 {
                y0.n[k].eps[N] = self.dn0[k];
            }
        }
        let mut jacobi = Jacobi::default();
        let mut conj = constraint::Conjugate::default();
        let assess = self.assessed();
        let length = self.rod.length;
        let mut visit = |_: usize, _: f64, y: &State<Jet<M>>| {
            if assess && N == 3 {
                jacobi.visit(y)
            } else if assess {
                conj.visit(y, length)
            }
        };
        let tip = self.pass(&coeffs, y0, Some(&mut visit));
        let mt = self.rod.spec.tip.mass;
        let w: [Jet<M>; 3] = std::array::from_fn(|k| lam * (mt * self.rod.gravity[k]));
        let f_tip: [Jet<M>; 3] = std::array::from_fn(|k| lam * self.loads.tip_force[k]);
        let m_tip: [Jet<M>; 3] = std::array::from_fn(|k| lam * self.loads.tip_moment[k]);
        let rd: [Jet<M>; N] = self.tip_balance(&tip, &w, &f_tip, &m_tip);
        let jac = SMatrix::<f64, N, N>::from_fn(|i, j| rd[i].eps[j]);
        let r_lam = SVector::<f64, N>::from_fn(|i, _| -rd[i].eps[N]);
        let t = solve_linear(&jac, &r_lam)?;
        let stable = assess.then(|| {
            if N == 3 {
                jacobi.stable(&Matrix3::from_fn(|i, j| jac[(i, j)]))
            } else {
                conj.stable_free(&Matrix6::from_fn(|i, j| jac[(i, j)]))
            }
        });
        t.iter()
            .all(|v| v.is_finite())
            .then(|| (std::array::from_fn(|i| t[i]), jac, stable))
    }

    /// Equilibrium of the straight, undeformed rod under the dead loads: a cheap cold-start
    /// guess of the 3-unknown problem. It equals the path's tangent at zero load times the
    /// load factor (at zero load J = I, and dR/dlambda is minus the loads' moment about the
    /// base on the straight rod) for a rod whose reference shape is straight.
    fn straight_guess(&self) -> [f64; 3] {
        let t = [
            self.rod.base_rotation[0][2],
            self.rod.base_rotation[1][2],
            self.rod.base_rotation[2][2],
        ];
        let w = self.tip_weight();
        let com = self.rod.spec.tip.com_offset;
        let mut f_tip = [0.0; 3];
        let mut cw = [0.0; 3];
        for k in 0..3 {
            f_tip[k] = self.factor * self.loads.tip_force[k] + w[k];
            cw[k] = (0..3)
                .map(|j| self.rod.base_rotation[k][j] * com[j])
                .sum::<f64>()
                + t[k] * self.rod.length;
        }
        // n(0) = F + int f;  int_0^L n ds = F L + int s f ds
        let mut int_n = f_tip.map(|f| f * self.rod.length);
        let mut l_tot = [0.0; 3];
        for (sec, c) in self.rod.sections.iter().zip(&self.coeffs) {
            let (a, b) = (sec.s_start, sec.s_start + sec.length);
            // int s f(s) ds by Simpson's rule: exact, f is at most quadratic in s.
            let [ma, mm, mb] = sec.line_mass_profile;
            let mid = 0.5 * (a + b);
            let int_sm = sec.length / 6.0 * (a * ma + 4.0 * mid * mm + b * mb);
            for k in 0..3 {
                int_n[k] += self.factor
                    * (self.rod.gravity[k] * int_sm + sec.line_force[k] * 0.5 * (b * b - a * a));
                l_tot[k] += c.l[k] * sec.length;
            }
        }
        // m(0) = M_tip + (c_w x W measured from the tip) + t x int n + int l, about the base
        let tip_arm = [
            cw[0] - t[0] * self.rod.length,
            cw[1] - t[1] * self.rod.length,
            cw[2] - t[2] * self.rod.length,
        ];
        let cxw = cross(&tip_arm, &w);
        let txn = cross(&t, &int_n);
        std::array::from_fn(|k| {
            (self.factor * self.loads.tip_moment[k] + cxw[k] + txn[k] + l_tot[k]) / self.ms
        })
    }

    /// `x` as Newton's answer where it is an equilibrium already: Newton's first test
    /// (`newton`, which stops there after one iteration) from an f64 pass, without the dual
    /// pass for a Jacobian it would not use. None where Newton has work to do.
    fn converged_at<const N: usize>(
        &self,
        x: &[f64; N],
        opts: &SolverOptions,
    ) -> Option<Converged<N>> {
        let r = self.eval(x);
        let norm = inf_norm(&r);
        (norm <= opts.tol * inf_norm(x).max(1.0)).then_some(Converged {
            x: *x,
            r,
            residual: norm,
            iterations: 1,
        })
    }

    /// Damped Newton from `x0`. Err((iterations, residual)) when it fails.
    ///
    /// Trial points are evaluated with the cheap f64 pass. The exact Jacobian (a dual pass,
    /// about 9 f64 passes) is computed at the start (`Start::Guess`) and whenever a step
    /// needs the line search or contracts the residual by less than `REFRESH_CONTRACTION`;
    /// after the other steps it gets Broyden's rank-one update (J += (dr - J dx) dx^T /
    /// |dx|^2), which keeps it accurate along the path of the iterates. Convergence is
    /// always judged on the true residual, and the final pass (`conclude`) evaluates the
    /// exact Jacobian at the solution for the stability test.
    fn newton<const N: usize>(
        &self,
        x0: [f64; N],
        start: Start<N>,
        opts: &SolverOptions,
    ) -> std::result::Result<Converged<N>, (usize, f64)> {
        const REFRESH_CONTRACTION: f64 = 0.5;
        let mut x = x0;
        let (mut r, mut jac, mut fresh, fail_fast) = match start {
            Start::Guess => {
                let (r, j) = self.eval_jac(&x);
                (r, j, true, false)
            }
            Start::Predicted { jac, r, fail_fast } => (r, jac, false, fail_fast),
        };
        let mut norm = inf_norm(&r);
        if !norm.is_finite() {
            return Err((1, norm));
        }
        let done = |x: [f64; N], r: [f64; N], norm: f64, iterations: usize| Converged {
            x,
            r,
            residual: norm,
            iterations,
        };
        for it in 0..opts.max_iter {
            let xmax = inf_norm(&x).max(1.0);
            if norm <= opts.tol * xmax {
                return Ok(done(x, r, norm, it + 1));
            }
            let rv = SVector::<f64, N>::from_column_slice(&r);
            let step = solve_linear(&jac, &(-rv)).unwrap_or_else(|| {
                // Levenberg-Marquardt step when J is singular.
                let jt = jac.transpose();
                let mut a = jt * jac;
                let mu = 1e-6 * a.diagonal().max().max(1e-300);
                for i in 0..N {
                    a[(i, i)] += mu;
                }
                solve_linear(&a, &(-(jt * rv))).unwrap_or_else(SVector::<f64, N>::zeros)
            });
            let r2 = rv.norm();
            let mut alpha = 1.0;
            let mut accepted = false;
            while alpha >= 1.0 / 1024.0 {
                let xt: [f64; N] = std::array::from_fn(|i| x[i] + alpha * step[i]);
                let rt = self.eval(&xt);
                let r2t = SVector::<f64, N>::from_column_slice(&rt).norm();
                if r2t.is_finite() && r2t < (1.0 - 1e-4 * alpha) * r2 {
                    let dx = SVector::<f64, N>::from_fn(|i, _| xt[i] - x[i]);
                    let dr = SVector::<f64, N>::from_fn(|i, _| rt[i] - r[i]);
                    x = xt;
                    r = rt;
                    norm = inf_norm(&r);
                    accepted = true;
                    if r2t > REFRESH_CONTRACTION * r2 || alpha < 1.0 {
                        (r, jac) = self.eval_jac(&x);
                        fresh = true;
                    } else {
                        broyden(&mut jac, &dx, &dr);
                        fresh = false;
                    }
                    break;
                }
                if !fresh {
                    // An inexact Jacobian may be the problem: refresh it and retry the full
                    // step.
                    (r, jac) = self.eval_jac(&x);
                    fresh = true;
                    break;
                }
                if fail_fast && it == 0 {
                    return Err((it + 1, norm));
                }
                alpha *= 0.5;
            }
            if !accepted && fresh && alpha < 1.0 / 1024.0 {
                // Converged to round-off already? Accept if within 100x the tolerance.
                if norm <= 100.0 * opts.tol * xmax {
                    return Ok(done(x, r, norm, it + 1));
                }
                return Err((it + 1, norm));
            }
        }
        if norm <= opts.tol * inf_norm(&x).max(1.0) {
            Ok(done(x, r, norm, opts.max_iter))
        } else {
            Err((opts.max_iter, norm))
        }
    }

    /// The final pass at a converged x of the full load: one integration (in `Jet<3>` or
    /// `Jet<6>` for conservative loads, giving J and the Jacobi fields of the stability
    /// test; in f64 under follower loads, whose stability is not assessed) and at every node the validity
    /// rules are checked (and the shape kept, if wanted). A broken physical rule is an
    /// error; a validity range broken under `Policy::Raise` too. At an `Unchecked` x the
    /// pass itself measures the residual, and an x that is not an equilibrium to `opts.tol`
    /// is `NotConverged` (this saves the separate f64 pass that checking first would cost;
    /// `conclude_at`).
    fn conclude<const N: usize>(
        &self,
        at: At<'_, N>,
        iterations: usize,
        load_steps: usize,
        opts: &SolverOptions,
        mut violations: Vec<SoftrodError>,
        want_shape: bool,
    ) -> Result<(Solution, Option<Shape>)> {
        let (x, known_residual) = match at {
            At::Converged(c) => (&c.x, Some(c.residual)),
            At::Unchecked(x) => (x, None),
        };
        let mut shape = want_shape.then(Shape::default);
        let mut broken: Option<SoftrodError> = None;
        let mut worst: Option<(f64, SoftrodError)> = None;
        let mut index = 0;
        // The nodes are checked after the pass, with the tendon law at each started from the
        // pass's own solution there (a node is the first stage of the next step; a section's
        // end node is near the last step's last stage).
        let mut nodes: Vec<(usize, f64, State<f64>)> = Vec::new();
        let mut last = None;
        let mut check = |i: usize, s: f64, y: &State<f64>, memory: &LawMemory| {
            let node = Node {
                index,
                s,
                section: i,
            };
            index += 1;
            let sec = &self.rod.sections[i];
            let h = sec.length / sec.steps as f64;
            let k = (((s - sec.s_start) / h).round() as usize).min(sec.steps);
            let stage = if k < sec.steps { 4 * k } else { 4 * k - 1 };
            let mut scratch = memory.seeded(i, stage);
            let (v, u) = match self.check_node(node, y, opts, &mut worst, &mut scratch, &mut last) {
                Ok(vu) => vu,
                Err(e) => {
                    broken.get_or_insert(e);
                    return;
                }
            };
            if let Some(sh) = shape.as_mut() {
                sh.push(node, y, v, u);
            }
        };
        let (tip, stable, r) = if N == 3 {
            let xd: [Jet<3>; 3] = std::array::from_fn(|i| Jet::variable(x[i], i));
            let mut jacobi = Jacobi::default();
            let mut visit = |i: usize, s: f64, y: &State<Jet<3>>| {
                jacobi.visit(y);
                nodes.push((i, s, y.re()));
            };
            let tip = self.pass(&self.coeffs, self.base_state(&xd), Some(&mut visit));
            let rd: [Jet<3>; 3] = self.residual_of_tip(&tip);
            let jac = Matrix3::from_fn(|i, j| rd[i].eps[j]);
            let r: Vec<f64> = rd.iter().map(|v| v.re).collect();
            (tip.re(), Some(jacobi.stable(&jac)), r)
        } else if self.assessed() {
            // Six unknowns under conservative loads (contact): the Jacobi fields of all six
            // base unknowns, tested as a free tip (`constraint::Conjugate::stable_free`).
            let xd: [Jet<6>; 6] = std::array::from_fn(|i| Jet::variable(x[i], i));
            let mut conj = constraint::Conjugate::default();
            let length = self.rod.length;
            let mut visit = |i: usize, s: f64, y: &State<Jet<6>>| {
                conj.visit(y, length);
                nodes.push((i, s, y.re()));
            };
            let tip = self.pass(&self.coeffs, self.base_state(&xd), Some(&mut visit));
            let rd: [Jet<6>; 6] = self.residual_of_tip(&tip);
            let jac = Matrix6::from_fn(|i, j| rd[i].eps[j]);
            let r: Vec<f64> = rd.iter().map(|v| v.re).collect();
            (tip.re(), Some(conj.stable_free(&jac)), r)
        } else {
            let mut visit = |i: usize, s: f64, y: &State<f64>| nodes.push((i, s, *y));
            let tip = self.pass(&self.coeffs, self.base_state(x), Some(&mut visit));
            let r: [f64; N] = self.residual_of_tip(&tip);
            (tip, None, r.to_vec())
        };
        {
            let memory = self.memory.borrow();
            for (i, s, y) in &nodes {
                check(*i, *s, y, &memory);
            }
        }
        let residual = match known_residual {
            Some(norm) => norm,
            None => {
                let norm = inf_norm(&r);
                if norm.is_nan() || norm > opts.tol * inf_norm(x).max(1.0) {
                    return Err(SoftrodError::NotConverged {
                        iterations,
                        residual: norm,
                        load_factor: 1.0,
                        reason: "the given unknowns are not an equilibrium to the tolerance".into(),
                    });
                }
                norm
            }
        };
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
        let y0 = self.base_state(x);
        Ok((
            Solution {
                x: x.to_vec(),
                base_force: y0.n,
                base_moment: y0.m,
                tip,
                iterations,
                residual,
                load_steps,
                stable,
                violations,
                collocation: None,
                friction: None,
            },
            shape,
        ))
    }

    /// The rules of `crate::validity` at one node; the strains (v, u) there. With obstacles
    /// also the penetration rule between this node and the last one checked, `last` (the
    /// penalty acts at the integration points only: `crate::contact::check_between`).
    fn check_node(
        &self,
        node: Node,
        y: &State<f64>,
        opts: &SolverOptions,
        worst: &mut Option<(f64, SoftrodError)>,
        scratch: &mut Scratch,
        last: &mut Option<crate::contact::Sample>,
    ) -> Result<([f64; 3], [f64; 3])> {
        let flat: [f64; 18] = std::array::from_fn(|k| match k {
            0..3 => y.r[k],
            3..12 => y.rot[(k - 3) / 3][(k - 3) % 3],
            12..15 => y.n[k - 12],
            _ => y.m[k - 15],
        });
        validity::check_finite(node, &flat)?;
        validity::check_rotation(node, &y.rot)?;
        let sec = &self.rod.sections[node.section];
        if let Some(obstacles) = &self.rod.obstacles {
            let rho = sec.surface_radius(node.s - sec.s_start);
            crate::contact::check_penetration(obstacles, node, &y.r, rho)?;
        }
        let between =
            |v: &[f64; 3], last: &mut Option<crate::contact::Sample>| match &self.rod.obstacles {
                Some(obstacles) => {
                    let rho = sec.surface_radius(node.s - sec.s_start);
                    let here = crate::contact::Sample::of(node, &y.r, &y.rot, v, rho);
                    let seen = last.replace(here);
                    seen.map_or(Ok(()), |a| {
                        crate::contact::check_after(obstacles, &a, &here)
                    })
                }
                None => Ok(()),
            };
        if sec.rigid {
            between(&[0.0, 0.0, 1.0], last)?;
            return Ok(([0.0, 0.0, 1.0], [0.0; 3]));
        }
        let s = node.s - sec.s_start;
        let coeffs = &self.coeffs[node.section];
        let (v, u) = strains_with(sec, y, coeffs, s, scratch);
        validity::check_finite(node, &[v[0], v[1], v[2], u[0], u[1], u[2]])?;
        validity::check_stretch(node, &v)?;
        between(&v, last)?;
        let t = if sec.tapered { s / sec.length } else { 0.0 };
        for (k, c) in sec.chambers.iter().enumerate() {
            let (_, _, centroid) = c.at(t);
            validity::check_chamber(node, k, &v, &u, centroid)?;
        }
        if opts.on_invalid != Policy::Ignore {
            let radius = match &sec.law.geometry {
                Some(g) => g.outer_at(t),
                None => sec.fibre_radius,
            };
            let (v_ref, u_ref) = sec.reference.at(s);
            if let Err(e) = validity::check_strain_range(
                node,
                &v,
                &u,
                (&v_ref, &u_ref),
                radius,
                &opts.strain_limits,
            ) {
                // Keep the node furthest out (in log stretch, symmetric in compression and
                // extension).
                let far = match &e {
                    SoftrodError::InvalidState { value, .. } => value.ln().abs(),
                    _ => 0.0,
                };
                if worst.as_ref().is_none_or(|(w, _)| far > *w) {
                    *worst = Some((far, e));
                }
            }
        }
        Ok((v, u))
    }
}

/// The conjugate-point test along s (docs/model.md "Validity and stability"). The columns of
/// Theta(s) are the rotation fields d theta(s)/dx_j of the three Jacobi fields that start
/// at the clamp (theta(0) = 0, dm(0) = M_s e_j), in the world frame: delta R R^T =
/// [d theta]x. Near the clamp Theta ~ s R0 K_bt^-1 R0^T M_s (positive definite). A point
/// where Theta is singular is conjugate to the clamp; between two nodes, one is crossed
/// when T = Theta(s_k+1)^-1 Theta(s_k) has an eigenvalue with negative real part (without
/// a crossing, T = I + O(h)). This counts the double crossings of symmetric rods (a
/// round column buckles in two planes at once), which leave det Theta positive.
#[derive(Default)]
struct Jacobi {
    /// An elastic step has been taken (Theta = 0 on leading rigid sections).
    elastic: bool,
    conjugate: bool,
    theta: Matrix3<f64>,
}

/// Component a of the rotation field d theta/dx_j (world frame, dR R^T = [d theta]x) that
/// the dual number direction j of a rotation carries.
fn rotation_component<const N: usize>(rot: &[[Jet<N>; 3]; 3], a: usize, j: usize) -> f64 {
    // Omega = dR R^T (row-major R): Omega[p][q] = sum_k dR[p][k] R[q][k].
    let om = |p: usize, q: usize| -> f64 { (0..3).map(|k| rot[p][k].eps[j] * rot[q][k].re).sum() };
    match a {
        0 => 0.5 * (om(2, 1) - om(1, 2)),
        1 => 0.5 * (om(0, 2) - om(2, 0)),
        _ => 0.5 * (om(1, 0) - om(0, 1)),
    }
}

/// [`rotation_component`] of the state y's rotation.
pub(crate) fn rotation_field<const N: usize>(y: &State<Jet<N>>, a: usize, j: usize) -> f64 {
    rotation_component(&y.rot, a, j)
}

/// The rotation variations d theta (world frame) of a rotation carrying derivatives in 3 of
/// its N >= 3 directions: column j is d theta / d x_j.
fn rotation_variations<const N: usize>(rot: &[[Jet<N>; 3]; 3]) -> Matrix3<f64> {
    Matrix3::from_fn(|a, j| rotation_component(rot, a, j))
}

impl Jacobi {
    fn visit<const N: usize>(&mut self, y: &State<Jet<N>>) {
        self.visit_theta(rotation_variations(&y.rot));
    }

    /// The next node's Theta (columns in the basis of the last one's).
    fn visit_theta(&mut self, th: Matrix3<f64>) {
        if self.elastic {
            if !self.conjugate && th != self.theta {
                self.conjugate = match th.try_inverse() {
                    Some(inv) => !right_half_plane(&(inv * self.theta)),
                    None => true,
                };
            }
        } else {
            self.elastic = th.determinant() > 0.0;
        }
        self.theta = th;
    }

    /// Stable: no conjugate point in (0, L] and the tip form sym(Theta(L)^T J) positive
    /// definite (the second variation on the Jacobi field reaching the tip with
    /// d theta(L) = Theta(L) xi is (M_s / 2) xi^T Theta(L)^T J xi). A rod without an elastic
    /// step cannot deform and is stable.
    fn stable(&self, jac: &Matrix3<f64>) -> bool {
        if !self.elastic {
            return true;
        }
        if self.conjugate {
            return false;
        }
        let a = self.theta.transpose() * jac;
        let q = (a + a.transpose()) * 0.5;
        q.iter().all(|v| v.is_finite()) && q.cholesky().is_some()
    }
}

/// Every eigenvalue of the 3x3 matrix t has a positive real part: by the Routh-Hurwitz
/// criterion for the characteristic polynomial of -t, tr t > 0, det t > 0 and
/// tr t * c2 > det t, with c2 the sum of the principal 2x2 minors.
fn right_half_plane(t: &Matrix3<f64>) -> bool {
    let tr = t.trace();
    let det = t.determinant();
    let c2 = t[(0, 0)] * t[(1, 1)] - t[(0, 1)] * t[(1, 0)] + t[(0, 0)] * t[(2, 2)]
        - t[(0, 2)] * t[(2, 0)]
        + t[(1, 1)] * t[(2, 2)]
        - t[(1, 2)] * t[(2, 1)];
    tr > 0.0 && det > 0.0 && tr * c2 > det
}

/// Every eigenvalue of the 6x6 matrix t has a positive real part (the test of
/// `constraint::Conjugate`): at once where Gershgorin's discs say so ([`gershgorin_right`]),
/// else from the eigenvalues of the real Schur form. Should the QR iteration not converge
/// (not seen on such small matrices), det t > 0, which still catches a single crossing.
pub(crate) fn eigenvalues_right_half_plane(t: &nalgebra::Matrix6<f64>) -> bool {
    if !t.iter().all(|v| v.is_finite()) {
        return false;
    }
    gershgorin_right(t) || schur_right(t)
}

/// [`eigenvalues_right_half_plane`] from the eigenvalues of the real Schur form.
fn schur_right(t: &nalgebra::Matrix6<f64>) -> bool {
    match nalgebra::linalg::Schur::try_new(*t, f64::EPSILON, 10_000) {
        Some(schur) => schur.complex_eigenvalues().iter().all(|z| z.re > 0.0),
        None => t.determinant() > 0.0,
    }
}

/// Whether every Gershgorin disc of t, balanced, lies in the right half-plane: every
/// eigenvalue lies in a disc about some diagonal entry of radius the sum of |.| over its
/// row's other entries, for t and for its diagonal similarity D^-1 t D alike, which a few
/// sweeps of Osborne's balancing (each row's radius made its column's) chooses; without it
/// the fields' ill-scaled columns (forces and moments, positions and rotations) spread the
/// discs of T = I + O(h) far beyond its eigenvalues. The discs must clear the imaginary
/// axis by 1e-6 of the largest, far above the round-off of the Schur form's eigenvalues,
/// so that test agrees wherever this one answers. It answers on most steps of the
/// conjugate-point test and saves the Schur form there, most of that test's cost.
fn gershgorin_right(t: &nalgebra::Matrix6<f64>) -> bool {
    let mut a = *t;
    let radius = |a: &nalgebra::Matrix6<f64>, i: usize| -> (f64, f64) {
        (0..6).filter(|&j| j != i).fold((0.0, 0.0), |(r, c), j| {
            (r + a[(i, j)].abs(), c + a[(j, i)].abs())
        })
    };
    for _ in 0..3 {
        for i in 0..6 {
            let (r, c) = radius(&a, i);
            if r > 0.0 && c > 0.0 {
                let f = (c / r).sqrt();
                for j in (0..6).filter(|&j| j != i) {
                    a[(i, j)] *= f;
                    a[(j, i)] /= f;
                }
            }
        }
    }
    let discs: [(f64, f64); 6] = std::array::from_fn(|i| (a[(i, i)], radius(&a, i).0));
    let scale = discs.iter().map(|(c, r)| c.abs() + r).fold(0.0, f64::max);
    discs.iter().all(|(c, r)| c - r > 1e-6 * scale)
}

/// The best of two attempts: a stable solution, else a broken validity rule, else an
/// unstable solution, else non-convergence. A broken rule outranks an unstable
/// equilibrium: where the stable path ends outside the model's validity range (a finger
/// buckled so far that its fibres stretch below the range), the unstable equilibrium met
/// on the way (the straight column) is not what the rod does, and returning it would hide
/// the reason. Ties go to `b`.
type Attempt = Result<(Solution, Option<Shape>)>;

fn rank(a: &Attempt) -> u8 {
    match a {
        // (Equilibria under follower loads are not assessed: no attempt does better.)
        Ok((s, _)) if s.stable != Some(false) => 3,
        Err(SoftrodError::InvalidState { .. }) => 2,
        Ok(_) => 1,
        Err(_) => 0,
    }
}

/// An equilibrium found unstable.
fn is_unstable(a: &Attempt) -> bool {
    matches!(a, Ok((s, _)) if s.stable == Some(false))
}

fn better(a: Option<Attempt>, b: Attempt) -> Attempt {
    match a {
        Some(a) if rank(&a) > rank(&b) => a,
        _ => b,
    }
}

/// Solve the static equilibrium. `guess` is a previous solution's `x` (warm start; ignored
/// unless it has this solve's number of unknowns and is finite), or for a rod that
/// collocation solves ([`solved_by_collocation`]) a previous solution's collocation
/// unknowns `z` (`Solution::collocation`).
pub fn solve(
    rod: &Rod,
    loads: &Loads,
    guess: Option<&[f64]>,
    opts: &SolverOptions,
) -> Result<Solution> {
    solve_inner(rod, loads, guess, opts, false).map(|(s, _)| s)
}

/// [`solve`] and the shape at every integration node, from the same final pass.
pub fn solve_with_shape(
    rod: &Rod,
    loads: &Loads,
    guess: Option<&[f64]>,
    opts: &SolverOptions,
) -> Result<(Solution, Shape)> {
    solve_inner(rod, loads, guess, opts, true).map(|(s, sh)| (s, sh.unwrap_or_default()))
}

/// Check a solve's loads (pressures, tensions, stiffness scale, tip loads) and options;
/// returns the operating-range violations to report (with `Policy::Warn`).
pub fn check_inputs(rod: &Rod, loads: &Loads, opts: &SolverOptions) -> Result<Vec<SoftrodError>> {
    contact::frictionless(rod)?;
    check_inputs_any_friction(rod, loads, opts)
}

/// [`check_inputs`] for the frictional statics (`friction::solve`), which carries friction.
pub(crate) fn check_inputs_any_friction(
    rod: &Rod,
    loads: &Loads,
    opts: &SolverOptions,
) -> Result<Vec<SoftrodError>> {
    opts.validate()?;
    rod.check_loads(&loads.pressures, &loads.stiffness_scale)?;
    rod.check_tensions(&loads.tensions)?;
    contact::clear_at_rest(rod, loads)?;
    for (name, v) in [
        ("tip_force", &loads.tip_force),
        ("tip_moment", &loads.tip_moment),
    ] {
        for (i, x) in v.iter().enumerate() {
            if !x.is_finite() {
                return Err(SoftrodError::invalid(
                    format!("{name}[{i}]"),
                    x,
                    "must be a finite number",
                ));
            }
        }
    }
    let mut violations = vec![];
    if let (Some(range), true) = (rod.spec.operating_range, opts.on_invalid != Policy::Ignore) {
        if let Err(e) = validity::check_operating_range(&loads.pressures, &loads.tensions, &range) {
            if opts.on_invalid == Policy::Raise {
                return Err(e);
            }
            violations.push(e);
        }
    }
    Ok(violations)
}

/// Whether statics solves `rod` under `loads` by collocation rather than single shooting.
/// Single shooting's sensitivity grows like exp(int sqrt(|n| / EI) ds): long, soft rods
/// under their own weight go to collocation (docs/model.md, "Collocation"), which carries
/// reference shapes (constant or tabulated) and tapers; rods with tendons or follower loads
/// stay with shooting (`scope::check_statics_only_with`). Contact needs the position in the
/// state, which collocation does not carry: rods with obstacles are shot (docs/contact.md).
/// The growth depends on the dead loads only (not on pressures or tensions), so an inverse
/// problem keeps one method for all its iterates.
pub fn solved_by_collocation(rod: &Rod, loads: &Loads) -> bool {
    collocation::shooting_ill_conditioned(rod, loads)
        && !loads.base_force_unknown(rod)
        && rod.obstacles.is_none()
        && crate::scope::check_statics_only_with(rod, "collocation", true, false).is_ok()
}

fn solve_inner(
    rod: &Rod,
    loads: &Loads,
    guess: Option<&[f64]>,
    opts: &SolverOptions,
    want_shape: bool,
) -> Attempt {
    let violations = check_inputs(rod, loads, opts)?;
    if solved_by_collocation(rod, loads) {
        return by_collocation(rod, loads, guess, opts, violations);
    }
    if loads.base_force_unknown(rod) {
        let start = match guess {
            None => contact::free_guess(rod, loads, opts),
            Some(_) => None,
        };
        let guess = match guess {
            Some(g) => Some(Guess::Given(g)),
            None => start.as_deref().map(Guess::Free),
        };
        solve_n::<6, 7>(rod, loads, guess, opts, violations, want_shape)
    } else {
        let guess = guess.map(Guess::Given);
        solve_n::<3, 4>(rod, loads, guess, opts, violations, want_shape)
    }
}

/// Where a solve's first Newton start comes from.
#[derive(Clone, Copy)]
enum Guess<'a> {
    /// The caller's (a warm start).
    Given(&'a [f64]),
    /// The equilibrium without the obstacles (`contact::free_guess`): where that shape
    /// touches nothing, the penalty adds exactly zero to the residual (and to its
    /// derivatives), so it is the contact problem's equilibrium already, and Newton's first
    /// test is all there is to do (`Problem::converged_at`).
    Free(&'a [f64]),
}

impl<'a> Guess<'a> {
    fn x(self) -> &'a [f64] {
        match self {
            Guess::Given(x) | Guess::Free(x) => x,
        }
    }
}

/// The solve with N unknowns (M = N + 1 dual directions for the path's tangent).
fn solve_n<const N: usize, const M: usize>(
    rod: &Rod,
    loads: &Loads,
    guess: Option<Guess>,
    opts: &SolverOptions,
    violations: Vec<SoftrodError>,
    want_shape: bool,
) -> Attempt {
    let mut iterations = 0;
    let mut first: Option<Attempt> = None;
    let free = matches!(guess, Some(Guess::Free(_)));
    let guess = guess
        .map(Guess::x)
        .filter(|g| g.len() == N && g.iter().all(|v| v.is_finite()))
        .map(|g| -> [f64; N] { std::array::from_fn(|i| g[i]) });
    // With obstacles: the unloaded rod's nodes, from which an equilibrium must be
    // reachable without passing through an obstacle (`contact::crossing`); None where
    // nothing is to be checked (planes only: not even the unloaded problem is built).
    let unloaded = rod
        .obstacles
        .as_deref()
        .filter(|o| contact::crossable(o))
        .and_then(|o| {
            contact::start_nodes(&contact::unloaded_problem(rod, loads), &[0.0; N]).map(|s| (o, s))
        });
    if let Some(g) = guess {
        let full = Problem::new(rod, loads, 1.0);
        // The free equilibrium is accepted on Newton's own test (the residual, judged as
        // Newton judges it, so the answer is Newton's), without its Jacobian: where the
        // shape touches nothing, the answer is then concluded at once (the stability test
        // of all six unknowns in `conclude`). Its crossing is checked below as any start's:
        // a free shape beyond an obstacle touches nothing too.
        let newton = match free.then(|| full.converged_at(&g, opts)).flatten() {
            Some(c) => Ok(c),
            None => full.newton(g, Start::Guess, opts),
        };
        match newton {
            Ok(c) => {
                let out = full.conclude(
                    At::Converged(&c),
                    c.iterations,
                    1,
                    opts,
                    violations.clone(),
                    want_shape,
                );
                // An equilibrium beyond an obstacle (a rod hanging below the pin it would
                // rest on, as the shape without obstacles may be) is not the answer: the
                // natural path from the unloaded rod finds the one on its side.
                let crossed = unloaded.as_ref().and_then(|(obstacles, shape)| {
                    contact::crossing(obstacles, shape, &contact::node_points(&full, &c.x))
                });
                if rank(&out) == 3 && crossed.is_none() {
                    return out;
                }
                iterations = c.iterations;
                // Never kept as a fallback: the path's own failure says more.
                first = Some(match crossed {
                    Some(c) => Err(contact::crossing_error(contact::Crossing::lone(c), None)),
                    None => out,
                });
            }
            Err((it, res)) => {
                iterations = it;
                first = Some(Err(SoftrodError::NotConverged {
                    iterations: it,
                    residual: res,
                    load_factor: 0.0,
                    reason: "Newton failed from the initial guess and continuation is off".into(),
                }));
            }
        }
        if !opts.continuation {
            return first.unwrap_or_else(unreachable_attempt);
        }
    }
    let path = natural_path::<N, M>(
        rod, loads, opts, violations, want_shape, iterations, unloaded,
    );
    better(first, path)
}

/// A static solve by collocation (`collocation::solve_static`), for rods whose
/// single-shooting problem is ill-conditioned (docs/model.md, "Collocation"). Every node
/// passes the same validity rules as a shooting solution's, and the solution carries the
/// same conjugate-point test, its Jacobi fields carried along the collocation solution
/// interval by interval in a re-orthonormalised basis (`collocation::stability`); its
/// continuation cuts steps that leave the stable path as the shooting solver's does.
fn by_collocation(
    rod: &Rod,
    loads: &Loads,
    guess: Option<&[f64]>,
    opts: &SolverOptions,
    violations: Vec<SoftrodError>,
) -> Attempt {
    // A shooting `x` as the guess has the wrong length and is ignored there.
    let sol = collocation::solve_static(rod, loads, guess, opts)?;
    conclude_collocated(rod, loads, sol, opts, violations)
}

/// The equilibrium a caller holds, from its unknowns, to take its derivatives: a
/// collocation solution's unknowns z as they are (`collocation::at_unknowns`: no Newton
/// step, so its values are the solution's own, and no cold collocation solve, which its
/// shooting unknowns alone would start), else a solve warm-started from `unknowns`.
/// Either is checked as a solve's answer is.
pub fn solution_at(
    rod: &Rod,
    loads: &Loads,
    unknowns: &[f64],
    opts: &SolverOptions,
) -> Result<Solution> {
    if solved_by_collocation(rod, loads) {
        let violations = check_inputs(rod, loads, opts)?;
        if let Some(sol) = collocation::at_unknowns(rod, loads, unknowns, opts.tol) {
            return conclude_collocated(rod, loads, sol, opts, violations).map(|(s, _)| s);
        }
    }
    solve(rod, loads, Some(unknowns), opts)
}

/// A collocation solution concluded as a solve's answer: every node through the validity
/// rules, the shape, the base wrench.
fn conclude_collocated(
    rod: &Rod,
    loads: &Loads,
    sol: collocation::StaticSolution,
    opts: &SolverOptions,
    violations: Vec<SoftrodError>,
) -> Attempt {
    let mut violations = violations;
    let (base_force, base_moment) = collocation::base_wrench(rod, &sol.z);
    let ev = &sol.evaluated;
    let grid = crate::collocation::Grid::new(rod);
    let p = Problem::new(rod, loads, 1.0);
    let mut shape = Shape::default();
    let mut worst: Option<(f64, SoftrodError)> = None;
    for (j, y) in ev.nodes.iter().enumerate() {
        let node = Node {
            index: j,
            s: grid.node_s(j),
            section: if j == 0 {
                0
            } else {
                grid.intervals[j - 1].section
            },
        };
        let state = State {
            r: ev.node_r[j],
            rot: crate::collocation::rotation(&y[..4]),
            n: [y[4], y[5], y[6]],
            m: [y[7], y[8], y[9]],
            aux: [1.0, 1.0],
        };
        let (v, u) = p.check_node(
            node,
            &state,
            opts,
            &mut worst,
            &mut Scratch::default(),
            &mut None, // no obstacles on the collocation path (docs/contact.md)
        )?;
        shape.push(node, &state, v, u);
    }
    if let Some((_, e)) = worst {
        match opts.on_invalid {
            Policy::Raise => return Err(e),
            Policy::Warn => violations.push(e),
            Policy::Ignore => {}
        }
    }
    let last = shape.s.len() - 1;
    let tip = State {
        r: shape.position[last],
        rot: shape.rotation[last],
        n: shape.force[last],
        m: shape.moment[last],
        aux: [1.0, 1.0],
    };
    let x = vec![sol.z[3], sol.z[4], sol.z[5]];
    let collocated = std::sync::Arc::new(Collocated {
        shape: shape.clone(),
        z: sol.z,
    });
    Ok((
        Solution {
            x,
            base_force,
            base_moment,
            tip,
            iterations: sol.iterations,
            residual: sol.residual,
            load_steps: sol.load_steps,
            stable: sol.stable,
            violations,
            collocation: Some(collocated),
            friction: None,
        },
        Some(shape),
    ))
}

/// An error in place of a branch the logic never takes (the core never panics).
fn unreachable_attempt() -> Attempt {
    Err(SoftrodError::Internal(
        "static solve ended without an outcome".into(),
    ))
}

/// Smallest load step continuation tries before giving up.
const MIN_LOAD_STEP: f64 = 1e-5;
/// A step that leaves the stable path (lands on an unstable equilibrium while the last level
/// was stable) is cut until it is this short; a path that still loses stability then does
/// so itself (a bifurcation or limit point on the path, e.g. a perfect column above its
/// buckling load) and is followed. A small imperfection eps (a lateral force eps times the
/// axial one) turns the path away from the straight branch within about eps^(2/3) of the
/// buckling load (Koiter's imperfection law for a symmetric stable bifurcation), so the
/// cut must reach below that: 1/4096 resolves eps down to about 1e-6 (the straight finger
/// of tests/test_statics_validity.py; at 1/64 it returned the straight, unstable branch
/// for lateral forces up to 1e-4 of the axial one). Cheap: only a step that lands on an
/// unstable equilibrium is halved.
const MIN_STABLE_STEP: f64 = 1.0 / 4096.0;
/// A level whose rod passes through an obstacle is retried in half the load step, down to
/// this one: below it the load pushes the rod through the penalty (its stiffness is too
/// low for the load), not a too-long step.
pub(crate) const MIN_CROSSING_STEP: f64 = 1e-4;
/// How far (infinity norm of the scaled unknowns, about the rod's rotation in rad) the
/// first load step moves the solution along the tangent before its prediction is measured
/// (`FIRST_ERROR`); the full load is tried at once when its tangent prediction moves less.
const FIRST_REACH: f64 = 2.0;
/// The first step is lengthened until its tangent prediction's error (the residual at the
/// predicted point) is about this fraction of the move it predicts.
const FIRST_ERROR: f64 = 0.25;
/// At most this many times longer.
const MAX_FIRST_GROWTH: f64 = 4.0;
/// Tolerance of the intermediate load levels (relative, as `SolverOptions::tol`): they are
/// stepping stones, and the predictor does not need them exact.
const LEVEL_TOL: f64 = 1e-2;

/// The natural path: loads ramped from zero (where x = 0 is the exact, stable solution: the
/// reference shape), predicted along the exact tangent (for a straight reference and dead
/// loads: the straight-rod guess, with J = I) and corrected by Newton. The step moves the
/// predicted solution by a set reach, adapted to Newton's effort; Newton starts from the
/// last level's exact Jacobian, updated by Broyden along the prediction. The first step is
/// lengthened when its prediction turns out good (`FIRST_ERROR`).
/// With obstacles (`unloaded`: the obstacles and the unloaded rod's nodes) no node may
/// pass through an obstacle between two levels (`contact::crossing`): a level that does is
/// retried in half the step.
fn natural_path<const N: usize, const M: usize>(
    rod: &Rod,
    loads: &Loads,
    opts: &SolverOptions,
    violations: Vec<SoftrodError>,
    want_shape: bool,
    spent: usize,
    unloaded: Option<(&[crate::contact::Obstacle], contact::NodePoints)>,
) -> Attempt {
    let (obstacles, mut last_shape) = match unloaded {
        Some((o, shape)) => (Some(o), shape),
        None => (None, Vec::new()),
    };
    let mut iterations = spent;
    let mut last_res = f64::NAN;
    let not_converged = |iterations, residual, load_factor, reason: String| {
        Err(SoftrodError::NotConverged {
            iterations,
            residual,
            load_factor,
            reason,
        })
    };
    // The last level on the path: load factor, solution, its residual, tangent, exact
    // Jacobian, stability (None: not assessed).
    let mut lam = 0.0;
    let mut x = [0.0; N];
    let mut r = [0.0; N];
    let straight = rod.is_straight();
    let (mut tangent, mut jac) = if N == 3 && straight {
        let t = Problem::new(rod, loads, 1.0).straight_guess();
        (
            std::array::from_fn(|i| t[i]),
            SMatrix::<f64, N, N>::identity(),
        )
    } else {
        match Problem::new(rod, loads, 0.0).tangent::<N, M>(&x) {
            Some((t, j, _)) => (t, j),
            None => {
                return not_converged(
                    0,
                    f64::NAN,
                    0.0,
                    "the shooting Jacobian is singular at zero load".into(),
                )
            }
        }
    };
    let mut stable = (!loads.has_follower(rod)).then_some(true);
    let mut step: f64 = (FIRST_REACH / inf_norm(&tangent)).min(1.0);
    if !step.is_finite() || !opts.continuation {
        step = 1.0;
    }
    let mut levels = 0;
    // An equilibrium that left the stable path at full load, kept in case no stable one is
    // reached.
    let mut unstable_end: Option<Attempt> = None;
    loop {
        if levels >= opts.max_load_steps {
            let out = not_converged(
                iterations,
                last_res,
                lam,
                if opts.continuation {
                    format!(
                        "load continuation used all {} load steps",
                        opts.max_load_steps
                    )
                } else {
                    "Newton failed from the initial guess and continuation is off".into()
                },
            );
            return better(unstable_end, out);
        }
        levels += 1;
        let mut target = (lam + step).min(1.0);
        let mut h = target - lam;
        let mut guess: [f64; N] = std::array::from_fn(|i| x[i] + tangent[i] * h);
        let mut p = Problem::new(rod, loads, target);
        let mut r0 = p.eval(&guess);
        if levels == 1 && target < 1.0 {
            // A longer first step where the tangent predicts well: the prediction's error
            // (measured by the residual there; J = I at zero load for a straight rod)
            // grows like the square of the step, so the step whose error is FIRST_ERROR
            // of its move is FIRST_ERROR rho / |r0| times this one (rho: its move). The
            // residual at the longer step's prediction is then evaluated afresh.
            let rho = h * inf_norm(&tangent);
            let err = inf_norm(&r0);
            let grow = (FIRST_ERROR * rho / err).min(MAX_FIRST_GROWTH);
            if err.is_finite() && grow > 1.0 {
                target = (lam + h * grow).min(1.0);
                h = target - lam;
                guess = std::array::from_fn(|i| x[i] + tangent[i] * h);
                p = Problem::new(rod, loads, target);
                r0 = p.eval(&guess);
            }
        }
        let level_opts = SolverOptions {
            tol: if target < 1.0 {
                opts.tol.max(LEVEL_TOL)
            } else {
                opts.tol
            },
            ..*opts
        };
        // The augmented Jacobian [J, dR/dlambda] of the last level, updated by Broyden
        // along the prediction (dx, h): dR/dlambda = -J t, so the linear model predicts
        // r + J (dx - t h) at the guess.
        let dx = SVector::<f64, N>::from_fn(|i, _| guess[i] - x[i]);
        let t = SVector::<f64, N>::from_column_slice(&tangent);
        let miss = SVector::<f64, N>::from_column_slice(&r0)
            - SVector::<f64, N>::from_column_slice(&r)
            - jac * (dx - t * h);
        let mut j = jac;
        let update = miss * dx.transpose() / (dx.norm_squared() + h * h);
        if update.iter().all(|v| v.is_finite()) {
            j += update;
        }
        let start = Start::Predicted {
            jac: j,
            r: r0,
            // Straight to the full load: an ordinary Newton solve, with its line search.
            fail_fast: !(levels == 1 && target >= 1.0),
        };
        let attempt = p.newton(guess, start, &level_opts);
        match attempt {
            Ok(mut c) => {
                iterations += c.iterations;
                last_res = c.residual;
                // The level's nodes reached without passing through an obstacle.
                let shape = obstacles.map(|o| (o, contact::node_points(&p, &c.x)));
                if let Some((o, shape)) = &shape {
                    if let Some(cr) = contact::crossing(o, &last_shape, shape) {
                        if h <= MIN_CROSSING_STEP || !opts.continuation {
                            return better(
                                unstable_end,
                                Err(contact::crossing_error(
                                    contact::Crossing::lone(cr),
                                    opts.continuation.then_some(h),
                                )),
                            );
                        }
                        step = 0.5 * h;
                        continue;
                    }
                }
                if target >= 1.0 {
                    let out = p.conclude(
                        At::Converged(&c),
                        iterations,
                        levels,
                        opts,
                        violations.clone(),
                        want_shape,
                    );
                    let left_path = stable == Some(true) && is_unstable(&out);
                    if !(left_path && h > MIN_STABLE_STEP && opts.continuation) {
                        return better(unstable_end, out);
                    }
                    unstable_end = Some(out);
                    step = 0.5 * h;
                    continue;
                }
                let Some((mut t, mut j, mut st)) = p.tangent::<N, M>(&c.x) else {
                    step = 0.5 * h;
                    continue;
                };
                let mut shape = shape;
                // A level's residual bounds its error only where J is well conditioned. Near
                // a critical load (J nearly singular) a residual of LEVEL_TOL can leave x far
                // from the path (a column just past its Euler load, 0.3 rad off: the next
                // prediction then lands on the unstable straight branch), and the stability
                // test turns on small differences there: where the Newton correction
                // J^-1 r says the level is further than LEVEL_TOL from its equilibrium, or
                // the level seems to leave the stable path, solve it to the solve's own
                // tolerance and look again.
                let off = solve_linear(&j, &SVector::<f64, N>::from_column_slice(&c.r))
                    .map_or(f64::INFINITY, |d| d.amax());
                let doubtful = off > LEVEL_TOL * inf_norm(&c.x).max(1.0)
                    || (stable == Some(true) && st == Some(false));
                if doubtful && level_opts.tol > opts.tol {
                    let polish = Start::Predicted {
                        jac: j,
                        r: c.r,
                        fail_fast: false,
                    };
                    if let Ok(c2) = p.newton(c.x, polish, opts) {
                        iterations += c2.iterations;
                        if let Some((t2, j2, st2)) = p.tangent::<N, M>(&c2.x) {
                            if clear_of(obstacles, &last_shape, &p, &c2.x) {
                                shape = obstacles.map(|o| (o, contact::node_points(&p, &c2.x)));
                                (c, t, j, st) = (c2, t2, j2, st2);
                            }
                        }
                    }
                }
                if stable == Some(true) && st == Some(false) && h > MIN_STABLE_STEP {
                    step = 0.5 * h;
                    continue;
                }
                // The next step moves the prediction as far as this one did, more or less
                // as Newton found it easy or hard.
                let reach = next_reach(h * inf_norm(&tangent), c.iterations);
                lam = target;
                x = c.x;
                if let Some((_, shape)) = shape {
                    last_shape = shape;
                }
                r = c.r;
                tangent = t;
                jac = j;
                stable = st;
                step = reach / inf_norm(&tangent);
                if !(step.is_finite() && step > 0.0) {
                    step = 1.0;
                }
            }
            Err((it, res)) => {
                iterations += it;
                last_res = res;
                if !opts.continuation {
                    return not_converged(
                        iterations,
                        res,
                        lam,
                        "Newton failed from the initial guess and continuation is off".into(),
                    );
                }
                step = 0.5 * h;
                if step < MIN_LOAD_STEP {
                    let out = not_converged(
                        iterations,
                        last_res,
                        lam,
                        "load step fell below 1e-5 (the load may exceed a limit point such as snap-through)".into(),
                    );
                    return better(unstable_end, out);
                }
            }
        }
    }
}

/// Whether the nodes at `x` were reached from the last level's (`last`) without passing
/// through an obstacle (always, without obstacles).
fn clear_of<const N: usize>(
    obstacles: Option<&[crate::contact::Obstacle]>,
    last: &contact::NodePoints,
    p: &Problem,
    x: &[f64; N],
) -> bool {
    obstacles.is_none_or(|o| contact::crossing(o, last, &contact::node_points(p, x)).is_none())
}

/// The next step's reach from the last one and the Newton iterations it needed: longer
/// when the prediction was good, shorter when Newton worked hard.
fn next_reach(reach: f64, iterations: usize) -> f64 {
    match iterations {
        0..=3 => 2.0 * reach,
        4..=5 => 1.25 * reach,
        _ => 0.7 * reach,
    }
}

/// The checked solution at unknowns `x` that the caller has converged for `loads` (e.g.
/// inverse statics, which solves the equilibrium jointly with the pressures): the same
/// conclusion as [`solve`]'s, one dual pass giving the validity checks and the stability
/// test. Errors when the residual at `x` is not within `opts.tol` (the caller did not
/// converge), or as [`solve`] for a state that breaks a rule.
pub fn conclude_at(
    rod: &Rod,
    loads: &Loads,
    x: [f64; 3],
    iterations: usize,
    opts: &SolverOptions,
) -> Result<Solution> {
    crate::scope::dead_loads_only(rod, loads, "conclude_at")?;
    let violations = check_inputs(rod, loads, opts)?;
    let p = Problem::new(rod, loads, 1.0);
    p.conclude(At::Unchecked(&x), iterations, 1, opts, violations, false)
        .map(|(s, _)| s)
}

/// The shape of a converged solution at every integration node.
pub fn shape(rod: &Rod, loads: &Loads, sol: &Solution) -> Shape {
    if let Some(c) = &sol.collocation {
        return c.shape.clone();
    }
    let p = Problem::for_solution(rod, loads, sol);
    let mut out = Shape::default();
    let mut index = 0;
    let mut visit = |i: usize, s: f64, y: &State<f64>| {
        let sec = &rod.sections[i];
        let (v, u) = if sec.rigid {
            ([0.0, 0.0, 1.0], [0.0; 3])
        } else {
            strains(sec, y, &p.coeffs[i], s - sec.s_start)
        };
        out.push(
            Node {
                index,
                s,
                section: i,
            },
            y,
            v,
            u,
        );
        index += 1;
    };
    integrate(rod, &p.coeffs, p.base_state(&sol.x), Some(&mut visit));
    out
}

fn check_unknowns(p: &Problem, x: &[f64]) -> Result<()> {
    if x.len() == p.unknowns() {
        Ok(())
    } else {
        Err(SoftrodError::invalid(
            "x",
            format!("{} values", x.len()),
            format!(
                "this solve has {} shooting unknowns ({})",
                p.unknowns(),
                if p.follower {
                    "follower loads: base force and moment"
                } else {
                    "dead loads: base moment"
                }
            ),
        ))
    }
}

/// Jacobian of the scaled residual with respect to the scaled unknowns x (3: m(0)/(F_s L);
/// 6 with follower loads: n(0)/F_s, m(0)/(F_s L)), exposed for tests against finite
/// differences.
pub fn residual_and_jacobian(
    rod: &Rod,
    loads: &Loads,
    x: &[f64],
) -> Result<(Vec<f64>, Vec<Vec<f64>>)> {
    let p = Problem::new(rod, loads, 1.0);
    check_unknowns(&p, x)?;
    fn go<const N: usize>(p: &Problem, x: &[f64]) -> (Vec<f64>, Vec<Vec<f64>>) {
        let x: [f64; N] = std::array::from_fn(|i| x[i]);
        let (r, j) = p.eval_jac(&x);
        (
            r.to_vec(),
            (0..N)
                .map(|i| (0..N).map(|k| j[(i, k)]).collect())
                .collect(),
        )
    }
    Ok(if x.len() == 6 {
        go::<6>(&p, x)
    } else {
        go::<3>(&p, x)
    })
}

/// Scaled residual at `x` (f64 only).
pub fn residual(rod: &Rod, loads: &Loads, x: &[f64]) -> Result<Vec<f64>> {
    let p = Problem::new(rod, loads, 1.0);
    check_unknowns(&p, x)?;
    Ok(if x.len() == 6 {
        p.eval::<6>(&std::array::from_fn(|i| x[i])).to_vec()
    } else {
        p.eval::<3>(&std::array::from_fn(|i| x[i])).to_vec()
    })
}

/// Scaled residuals at the unknowns `xs`, one f64 pass each, in order, by one problem (as
/// the shooting Newton's passes: each pass starts the tendon law at every stage from the
/// last pass's solution there, when closer), with the tendon law's evaluations and Newton
/// steps in each pass. A cost counter for profiling, and for tests of that memory.
#[doc(hidden)]
pub fn residual_passes(
    rod: &Rod,
    loads: &Loads,
    xs: &[Vec<f64>],
) -> Result<Vec<(Vec<f64>, usize, usize)>> {
    let p = Problem::new(rod, loads, 1.0);
    let mut out = Vec::with_capacity(xs.len());
    for x in xs {
        check_unknowns(&p, x)?;
        let before = p.memory.borrow().newton_steps();
        let r = if x.len() == 6 {
            p.eval::<6>(&std::array::from_fn(|i| x[i])).to_vec()
        } else {
            p.eval::<3>(&std::array::from_fn(|i| x[i])).to_vec()
        };
        let m = p.memory.borrow();
        out.push((r, m.evaluations(), m.newton_steps() - before));
    }
    Ok(out)
}

/// The path tangent dx/dlambda, the Jacobian and the stability flag (None: not assessed)
/// at a solution x of the loads scaled by `factor` (exposed for tests against finite
/// differences).
#[allow(clippy::type_complexity)]
pub fn load_tangent(
    rod: &Rod,
    loads: &Loads,
    factor: f64,
    x: &[f64],
) -> Result<Option<(Vec<f64>, Vec<Vec<f64>>, Option<bool>)>> {
    let p = Problem::new(rod, loads, factor);
    check_unknowns(&p, x)?;
    fn go<const N: usize, const M: usize>(
        p: &Problem,
        x: &[f64],
    ) -> Option<(Vec<f64>, Vec<Vec<f64>>, Option<bool>)> {
        let (t, j, st) = p.tangent::<N, M>(&std::array::from_fn(|i| x[i]))?;
        Some((
            t.to_vec(),
            (0..N)
                .map(|i| (0..N).map(|k| j[(i, k)]).collect())
                .collect(),
            st,
        ))
    }
    Ok(if x.len() == 6 {
        go::<6, 7>(&p, x)
    } else {
        go::<3, 4>(&p, x)
    })
}

#[cfg(test)]
mod tests {
    use super::{gershgorin_right, schur_right};
    use nalgebra::Matrix6;

    /// Uniform numbers in [-1, 1) (a fixed linear congruential sequence).
    fn numbers(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        }
    }

    /// The balanced discs answer for matrices like the conjugate-point test's steps (near
    /// a multiple of I, in bases scaled over six decades), and wherever they answer the
    /// Schur form agrees, also for matrices with eigenvalues within 1e-3 of the imaginary
    /// axis on either side of it (a complex pair in a random basis), where they must not
    /// answer for those in the left half-plane.
    #[test]
    fn balanced_gershgorin_discs_agree_with_the_schur_form() {
        let mut u = numbers(7);
        for case in 0..2000 {
            let s =
                Matrix6::from_diagonal(&nalgebra::Vector6::from_fn(|_, _| 10f64.powf(3.0 * u())));
            let inv = s.try_inverse().unwrap();
            let near = case % 2 == 0;
            let a = if near {
                Matrix6::identity() * (0.6 + 0.3 * u()) + Matrix6::from_fn(|_, _| 0.02 * u())
            } else {
                let mut a = Matrix6::from_fn(|_, _| 0.3 * u());
                let (re, im) = (1e-3 * u(), 1.0 + u());
                a[(0, 0)] = re;
                a[(1, 1)] = re;
                a[(0, 1)] = im;
                a[(1, 0)] = -im;
                for i in 2..6 {
                    a[(i, i)] = 2.0 + u();
                    for j in 0..2 {
                        a[(i, j)] = 0.0;
                    }
                }
                let q = Matrix6::identity() + Matrix6::from_fn(|_, _| 0.2 * u());
                q.try_inverse().unwrap() * a * q
            };
            let t = inv * a * s;
            let fast = gershgorin_right(&t);
            if near {
                assert!(fast, "case {case}: {t}");
            }
            if fast {
                assert!(schur_right(&t), "case {case}: {t}");
            }
            if !near && a[(0, 0)] < 0.0 {
                assert!(!fast, "case {case}: {t}");
            }
        }
    }
}
