//! Inverse statics: the chamber pressures and tendon tensions, within per-input bounds, that
//! bring a point of the rod (the tip by default) to a target position and optionally
//! orientation.
//!
//! The inputs p are the pressure channels (Pa) followed by the tendon channels (N); a tendon
//! only pulls, so its bounds lie in [0, inf) and a slack tendon is the lower bound 0 (its
//! derivative there is one-sided, which the box constraint respects). Below, "pressures"
//! stands for all inputs.
//!
//! Problem (inputs p in the box [lo, hi], shooting unknowns x):
//!   minimise  1/2 |e(x, p)|^2 + eps/2 |S (p - p_ref)|^2   subject to  g(x, p) = 0,
//! with g the scaled shooting residual of `crate::statics` (the equilibrium), S = diag(1 /
//! (hi - lo)) and the task residual e: w_i (r_i - r*_i) / L for the position and
//! w_R (R - R*)_jk / sqrt(2) for the orientation (|R - R*|_F^2 / 2 = 2 (1 - cos theta), which
//! is theta^2 for small angles and grows monotonically up to 180 deg).
//!
//! Method: projected Levenberg-Marquardt (Gauss-Newton with an adaptive damping mu) solved
//! jointly with the equilibrium. At each iterate one dual pass (`crate::jacobian`) gives g,
//! e and their exact partial derivatives in x and p; the implicit function theorem on g = 0
//! turns them into the tip Jacobian J = de/dp = e_p - e_x g_x^-1 g_p. The step is the box-
//! constrained least-squares problem (scaled pressures z = S p)
//!   min_dz 1/2 |e + J dz|^2 + eps/2 |z + dz - z_ref|^2 + mu/2 |dz|^2,  lo <= z + dz <= hi,
//! solved exactly by a primal active-set method; x follows the linearised equilibrium
//! x + dx with dx = -g_x^-1 (g + g_p dp), corrected by chord Newton steps with the same
//! g_x (f64 passes only) until g is within the statics tolerance. A step that does not lower
//! the cost is refused and mu raised. Near a reachable target the steps are Newton steps on
//! the joint system (quadratic convergence), so a warm start a small move away costs two or
//! three dual passes.
//!
//! Redundancy: with more free channels than task dimensions the minimisers form a manifold.
//! The solver first converges with eps = `regularisation` (least pressure: p_ref = the lower
//! bounds clipped to 0, or closest to the previous command: p_ref = the warm start), then
//! sets eps = 0 and continues with minimum-norm steps, which reach the target exactly while
//! staying next to the regularised point. Without redundancy eps is 0 throughout.
//!
//! Unreachable targets: the iteration stops at a first-order stationary point of the cost
//! in the box and the solution says `reached = false` with the distance left. The test, at
//! exact Jacobians, is the box's Frank-Wolfe gap of the gradient g = J^T e (+ eps (z - z_ref)) in
//! scaled pressures z: gap = sum_c max(g_c z_c, -g_c (1 - z_c), 0), the most
//! the linearised cost can fall in the box. Where the cost is locally convex,
//! cost - cost* <= gap, and a fall of gap moves |e| by gap / |e|: the iteration stops at
//! gap <= tol |e| (closer poses are below the reach resolution), or when the step or its
//! predicted decrease vanishes or no step lowers the cost (the solves' noise floor).
//! Far out of reach |e| stays large and J^T J misjudges the Hessian J^T J + sum_i e_i
//! d2e_i/dz2 (the point moves on an arc whose centre lies near the target: the distance
//! barely changes along it, and Gauss-Newton converges linearly at a rate near 1). The step
//! then adds a structured secant estimate M of the second-order term (Dennis, Gay and
//! Welsch's NL2SOL update from the exact Jacobians of successive passes: M s = (J - J0)^T
//! e), used while the residual is large (the last step lowered the cost by less than a
//! fifth: Fletcher and Xu) and J^T J + M predicted the last decrease better than J^T J, as a
//! projected Newton step (Bertsekas): the inputs held at a bound by the gradient stay, the
//! others step with J^T J + M on their face where it is positive definite.
//!
//! Long, soft rods that statics solves by collocation (`statics::solved_by_collocation`,
//! which depends on the dead loads only) have no three unknowns x to iterate on jointly:
//! there every iterate is a converged collocation equilibrium (a solve started from the
//! last iterate's unknowns z), its Jacobian J = de/dp comes from the collocation equations
//! at that solution (`crate::jacobian::collocation`, the implicit function theorem with the
//! banded G_z), so each one is fresh and each cost exact; the LM loop is the same.
//!
//! The returned equilibrium is always converged and concluded as a static solve's answer (`statics::conclude_at`): checked
//! against the validity rules (`crate::validity`), with its stability (`Solution::stable`)
//! for the caller to refuse an unstable one.

use crate::error::{Result, SoftrodError};
use crate::jacobian::{pass_with, total_derivatives, unknowns3, value_with, Input, Pass, Probe};
use crate::ode::{Loads, State};
use crate::rod::Rod;
use crate::statics::{self, Problem, Solution, SolverOptions};
use crate::validity::{self, Policy};
use nalgebra::{DMatrix, DVector, Vector3};

/// Most channels the inverse works with (its step is a dense problem in the channels).
pub const MAX_INVERSE_CHANNELS: usize = 64;

/// What the rod should reach.
#[derive(Debug, Clone, PartialEq)]
pub struct InverseTarget {
    /// Arc length of the point that should reach the target, m (the tip: the length L).
    pub s: f64,
    /// Target position (world frame), m.
    pub position: [f64; 3],
    /// Target rotation [d1 d2 d3] (world frame, row-major), if the orientation matters.
    pub orientation: Option<[[f64; 3]; 3]>,
    /// Weight of each position component's error measured in rod lengths L (0 ignores
    /// that component).
    pub position_weight: [f64; 3],
    /// Weight of the orientation error measured in rad (used with `orientation`).
    pub orientation_weight: f64,
}

/// Settings of the inverse solver.
#[derive(Debug, Clone, PartialEq)]
pub struct InverseOptions {
    /// [lo, hi] per input: gauge pressure per pressure channel, Pa, then tension per
    /// tendon channel, N (lo == hi pins an input).
    pub bounds: Vec<[f64; 2]>,
    /// The regularisation's centre p_ref (one per input, inside the bounds).
    pub reference: Vec<f64>,
    /// eps of the regularisation (dimensionless; the task error is measured in L and rad,
    /// the pressures in fractions of their range). Used only with redundant channels.
    pub regularisation: f64,
    /// The target counts as reached when every weighted position component is within
    /// tol L and the orientation within tol rad; the iteration stops there.
    pub tol: f64,
    /// Most Levenberg-Marquardt iterations.
    pub max_iter: usize,
    /// Options of the equilibrium solves: the equilibrium's tolerance, and the validity
    /// ranges (`strain_limits`, `on_invalid`) the answer is checked against.
    pub statics: SolverOptions,
}

impl InverseOptions {
    /// Bounds for every channel with the default settings.
    pub fn new(bounds: Vec<[f64; 2]>) -> Self {
        let reference = bounds.iter().map(|b| 0f64.clamp(b[0], b[1])).collect();
        InverseOptions {
            bounds,
            reference,
            regularisation: 1e-6,
            tol: 1e-10,
            max_iter: 100,
            statics: SolverOptions::default(),
        }
    }
}

/// The answer of [`solve_inverse`].
#[derive(Debug, Clone, PartialEq)]
pub struct InverseSolution {
    /// Gauge pressure per channel, Pa, within the bounds.
    pub pressures: Vec<f64>,
    /// Tension per tendon channel, N, within the bounds.
    pub tensions: Vec<f64>,
    /// The converged equilibrium under those pressures, checked as a static solve's answer
    /// (`stable`, validity-range `violations`; `x` is a warm start).
    pub solution: Solution,
    /// Position and rotation of the target point.
    pub point: State<f64>,
    /// Whether the target was reached to `tol`.
    pub reached: bool,
    /// Distance from the target point to the target position, m (all three components).
    pub distance: f64,
    /// Angle between the point's rotation and the target orientation, rad (NaN without).
    pub angle: f64,
    /// Least-squares cost 1/2 |e|^2 (without the regularisation).
    pub cost: f64,
    /// -1 at the lower bound, +1 at the upper, 0 inside, per input (pressures, then
    /// tensions).
    pub active: Vec<i8>,
    /// Levenberg-Marquardt iterations and dual passes.
    pub iterations: usize,
    pub passes: usize,
    /// The last linearisation used (a warm start keeps it: [`InverseSolution::warm_start`]).
    pub linearisation: Option<Linearisation>,
}

/// The field's name is built only on failure (validation runs on every warm call).
fn finite(field: impl FnOnce() -> String, v: f64) -> Result<()> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(SoftrodError::invalid(field(), v, "must be a finite number"))
    }
}

fn validate(rod: &Rod, loads: &Loads, target: &InverseTarget, opts: &InverseOptions) -> Result<()> {
    let (nc, nt) = (rod.n_channels, rod.n_tendons);
    let nu = nc + nt;
    if nu == 0 {
        return Err(SoftrodError::invalid(
            "design",
            &rod.spec.name,
            "has neither pressure channels nor tendons, so there is nothing to invert",
        ));
    }
    if nu > MAX_INVERSE_CHANNELS {
        return Err(SoftrodError::invalid(
            "design",
            format!("{nc} pressure channels and {nt} tendons"),
            format!("the inverse handles at most {MAX_INVERSE_CHANNELS} inputs"),
        ));
    }
    if rod.sections.iter().any(|s| s.law.stiffness_map) {
        return Err(SoftrodError::invalid(
            "design",
            &rod.spec.name,
            "has sections with law.stiffness_map: sigma(p) is evaluated outside the core, so the inverse cannot differentiate it; solve with fixed sigma instead",
        ));
    }
    opts.statics.validate()?;
    // Field names of input u: pressure channels first, then tendon channels.
    let name = |u: usize| {
        if u < nc {
            format!("pressure_bounds[{u}]")
        } else {
            format!("tension_bounds[{}]", u - nc)
        }
    };
    if opts.bounds.len() != nu {
        return Err(SoftrodError::invalid(
            "bounds",
            format!("{} pairs", opts.bounds.len()),
            format!("give one [lo, hi] per pressure channel ({nc}), then per tendon ({nt})"),
        ));
    }
    for (u, b) in opts.bounds.iter().enumerate() {
        finite(|| format!("{}[0]", name(u)), b[0])?;
        finite(|| format!("{}[1]", name(u)), b[1])?;
        if b[0] > b[1] {
            return Err(SoftrodError::invalid(
                name(u),
                format!("[{}, {}]", b[0], b[1]),
                "lo must be <= hi",
            ));
        }
        if u < nc && b[0] < -crate::spec::ATMOSPHERE {
            return Err(SoftrodError::invalid(
                format!("{}[0]", name(u)),
                b[0],
                "a gauge pressure cannot lie below -1 atm (vacuum)",
            ));
        }
        if u >= nc && b[0] < 0.0 {
            return Err(SoftrodError::invalid(
                format!("{}[0]", name(u)),
                b[0],
                "a tendon can only pull: tension must be >= 0 (0 is a slack tendon)",
            ));
        }
    }
    if opts.reference.len() != nu {
        return Err(SoftrodError::invalid(
            "reference",
            format!("{} values", opts.reference.len()),
            format!("give one value per input ({nc} pressures, then {nt} tensions)"),
        ));
    }
    for (u, (&r, b)) in opts.reference.iter().zip(&opts.bounds).enumerate() {
        finite(|| format!("reference[{u}]"), r)?;
        if r < b[0] || r > b[1] {
            return Err(SoftrodError::invalid(
                format!("reference[{u}]"),
                r,
                format!(
                    "must lie inside the bounds [{}, {}] of {}",
                    b[0],
                    b[1],
                    name(u)
                ),
            ));
        }
    }
    if loads.pressures.len() != nc || loads.pressures.iter().any(|p| !p.is_finite()) {
        return Err(SoftrodError::invalid(
            "initial",
            format!("{:?}", loads.pressures),
            format!("the start needs {nc} finite pressures"),
        ));
    }
    if loads.tensions.len() != nt || loads.tensions.iter().any(|t| !t.is_finite()) {
        return Err(SoftrodError::invalid(
            "initial",
            format!("{:?}", loads.tensions),
            format!("the start needs {nt} finite tensions"),
        ));
    }
    if !(opts.regularisation.is_finite() && opts.regularisation >= 0.0) {
        return Err(SoftrodError::invalid(
            "regularisation",
            opts.regularisation,
            "must be finite and >= 0",
        ));
    }
    if !(opts.tol.is_finite() && opts.tol > 0.0 && opts.tol < 1.0) {
        return Err(SoftrodError::invalid("tol", opts.tol, "must be in (0, 1)"));
    }
    if opts.max_iter == 0 {
        return Err(SoftrodError::invalid("max_iter", 0, "must be >= 1"));
    }
    for (k, v) in target.position.iter().enumerate() {
        finite(|| format!("target[{k}]"), *v)?;
    }
    for (k, w) in target.position_weight.iter().enumerate() {
        finite(|| format!("weights.position[{k}]"), *w)?;
        if *w < 0.0 {
            return Err(SoftrodError::invalid(
                format!("weights.position[{k}]"),
                w,
                "must be >= 0",
            ));
        }
    }
    finite(|| "weights.orientation".into(), target.orientation_weight)?;
    if target.orientation_weight < 0.0 {
        return Err(SoftrodError::invalid(
            "weights.orientation",
            target.orientation_weight,
            "must be >= 0",
        ));
    }
    if let Some(r) = &target.orientation {
        for row in r {
            for v in row {
                finite(|| "orientation".into(), *v)?;
            }
        }
        let err = validity::orthonormality_error(r);
        let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
            - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
            + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
        if err > 1e-9 || det <= 0.0 {
            return Err(SoftrodError::invalid(
                "orientation",
                format!("{r:?}"),
                format!("must be a rotation matrix (max |R^T R - I| = {err:.2e}, det = {det:.6})"),
            ));
        }
    }
    let weighted = target.position_weight.iter().any(|w| *w > 0.0)
        || (target.orientation.is_some() && target.orientation_weight > 0.0);
    if !weighted {
        return Err(SoftrodError::invalid(
            "weights",
            "all zero",
            "at least one position component or the orientation must carry weight",
        ));
    }
    Ok(())
}

/// Rows of the task residual e and its derivative from the probe's values y and dy.
struct Task<'a> {
    target: &'a InverseTarget,
    length: f64,
}

impl Task<'_> {
    fn rows(&self) -> usize {
        if self.target.orientation.is_some() {
            12
        } else {
            3
        }
    }

    /// Number of task dimensions that carry weight.
    fn dof(&self) -> usize {
        let pos = self
            .target
            .position_weight
            .iter()
            .filter(|w| **w > 0.0)
            .count();
        let rot = if self.target.orientation.is_some() && self.target.orientation_weight > 0.0 {
            3
        } else {
            0
        };
        pos + rot
    }

    /// e_i = (scale_i) (y_i - y*_i), or with `delta` the linear map of a change of y.
    fn residual(&self, y: &[f64; 12], delta: bool) -> Vec<f64> {
        let t = self.target;
        let mut e = Vec::with_capacity(self.rows());
        for i in 0..3 {
            let d = if delta { y[i] } else { y[i] - t.position[i] };
            e.push(t.position_weight[i] * d / self.length);
        }
        if let Some(r) = &t.orientation {
            let w = t.orientation_weight / std::f64::consts::SQRT_2;
            for j in 0..3 {
                for k in 0..3 {
                    let v = y[3 + 3 * j + k];
                    e.push(w * if delta { v } else { v - r[j][k] });
                }
            }
        }
        e
    }

    /// Reached: every weighted position component within tol L, the angle within tol.
    fn reached(&self, y: &[f64; 12], tol: f64) -> bool {
        let t = self.target;
        let pos_ok = (0..3).all(|i| {
            t.position_weight[i] == 0.0 || (y[i] - t.position[i]).abs() <= tol * self.length
        });
        let angle = self.angle(y);
        let rot_ok = t.orientation_weight == 0.0 || angle.is_nan() || angle <= tol;
        pos_ok && rot_ok
    }

    fn angle(&self, y: &[f64; 12]) -> f64 {
        match &self.target.orientation {
            None => f64::NAN,
            Some(r) => {
                // cos theta = (tr(R*^T R) - 1) / 2; sin theta from |R - R*|_F for accuracy
                // near 0: |R - R*|_F^2 = 8 sin^2(theta / 2).
                let f2: f64 = (0..3)
                    .flat_map(|j| (0..3).map(move |k| (j, k)))
                    .map(|(j, k)| (y[3 + 3 * j + k] - r[j][k]).powi(2))
                    .sum();
                2.0 * ((f2 / 8.0).sqrt().min(1.0)).asin()
            }
        }
    }
}

/// min 1/2 z^T H z - b^T z subject to lo <= z <= hi (lo <= 0 <= hi), H symmetric positive
/// definite: a primal active-set method from the feasible start z = 0. Exact after finitely
/// many changes of the active set (at most a few per channel in practice).
pub(crate) fn box_qp(h: &DMatrix<f64>, b: &DVector<f64>, lo: &[f64], hi: &[f64]) -> DVector<f64> {
    let n = b.len();
    let mut z = DVector::zeros(n);
    // 0: free, -1: at lo, +1: at hi
    let mut state: Vec<i8> = (0..n)
        .map(|i| if lo[i] == hi[i] { -1 } else { 0 })
        .collect();
    for _ in 0..(10 * n + 10) {
        let free: Vec<usize> = (0..n).filter(|&i| state[i] == 0).collect();
        // Minimiser over the free variables with the others held at their bounds.
        let mut target = z.clone();
        if !free.is_empty() {
            let hf = DMatrix::from_fn(free.len(), free.len(), |a, c| h[(free[a], free[c])]);
            let rhs = DVector::from_fn(free.len(), |a, _| {
                let i = free[a];
                b[i] - (0..n)
                    .filter(|&j| state[j] != 0)
                    .map(|j| h[(i, j)] * z[j])
                    .sum::<f64>()
            });
            let sol = match hf.clone().cholesky() {
                Some(ch) => ch.solve(&rhs),
                None => hf
                    .lu()
                    .solve(&rhs)
                    .unwrap_or_else(|| DVector::zeros(free.len())),
            };
            for (a, &i) in free.iter().enumerate() {
                target[i] = sol[a];
            }
        }
        // Step towards it until a bound blocks.
        let mut alpha = 1.0;
        let mut block = None;
        for &i in &free {
            let d = target[i] - z[i];
            if d < 0.0 && target[i] < lo[i] {
                let a = (lo[i] - z[i]) / d;
                if a < alpha {
                    alpha = a;
                    block = Some((i, -1));
                }
            } else if d > 0.0 && target[i] > hi[i] {
                let a = (hi[i] - z[i]) / d;
                if a < alpha {
                    alpha = a;
                    block = Some((i, 1));
                }
            }
        }
        for &i in &free {
            z[i] += alpha.max(0.0) * (target[i] - z[i]);
        }
        if let Some((i, side)) = block {
            z[i] = if side < 0 { lo[i] } else { hi[i] };
            state[i] = side;
            continue;
        }
        // At the minimiser of this face: release the bound whose multiplier has the wrong
        // sign (the gradient H z - b points into the box there).
        let grad = h * &z - b;
        let mut worst = None;
        let mut worst_val = 0.0;
        for i in 0..n {
            if lo[i] == hi[i] {
                continue;
            }
            let v = match state[i] {
                -1 => -grad[i], // at lo the cost must rise inwards: grad >= 0
                1 => grad[i],   // at hi: grad <= 0
                _ => 0.0,
            };
            if v > worst_val {
                worst_val = v;
                worst = Some(i);
            }
        }
        match worst {
            Some(i) => state[i] = 0,
            None => return z,
        }
    }
    z
}

/// Where an iterate stands: pressures, unknowns, residual, probe values.
struct Iterate {
    p: Vec<f64>,
    /// The shooting unknowns (a collocation iterate: its base moment z[3..6], as in
    /// `Solution::x`).
    x: [f64; 3],
    g: [f64; 3],
    y: [f64; 12],
    point: State<f64>,
    /// The probe's values corrected to first order for the equilibrium defect g (equal to
    /// `y` when the iterate is exact: g within the statics tolerance).
    y_corr: [f64; 12],
    exact: bool,
    /// A collocation iterate's converged solution (its unknowns z: the next solve's start).
    sol: Option<Solution>,
}

/// Largest equilibrium defect (scaled residual, relative to max(1, |x|)) an intermediate
/// iterate may keep: its probe values are corrected to first order (error ~1e-6 times the
/// step), the cost comparisons stay meaningful, and the answer is made exact at the end.
const LOOSE: f64 = 1e-6;

fn inf(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |a: f64, x| a.max(x.abs()))
}

/// A warm start: the shooting unknowns of the start pressures (e.g. the previous answer's
/// `solution.x`) and, from a previous answer of the same problem, its linearisation.
#[derive(Debug, Clone, PartialEq)]
pub struct WarmStart {
    pub x: [f64; 3],
    /// On a rod that collocation solves, the previous answer's solution: its collocation
    /// unknowns z start the first solve (`x` alone does not determine them).
    pub solution: Option<Solution>,
    /// The converged equilibrium this warm start describes: inputs (pressures, then
    /// tensions) and the probe's state
    /// (when the start pressures equal these, no pass is needed to begin).
    pub equilibrium: Option<(Vec<f64>, State<f64>)>,
    pub linearisation: Option<Linearisation>,
}

/// A linearisation of the equilibrium and the probe: the pass (partial derivatives at some
/// iterate) and the reduced Jacobian dy/dp, refined by Broyden updates as steps are taken.
#[derive(Debug, Clone, PartialEq)]
pub struct Linearisation {
    /// The shooting pass (None at a collocation iterate: its dy/dp comes from the
    /// collocation equations, and every iterate is a converged equilibrium).
    pub pass: Option<Pass>,
    /// Arc length of the probe, m.
    pub s: f64,
    pub dy: Vec<[f64; 12]>,
}

impl WarmStart {
    /// The `solution` of a warm start at the start `loads` from collocation unknowns `z`
    /// (a `StaticSolution`'s, for a rod that collocation solves): the equilibrium there,
    /// taken as it is where the solver's convergence test passes (`statics::solution_at`).
    /// None for a rod that shooting solves, or a `z` that does not fit its grid (a cold
    /// start then). Errors are those of the inputs.
    pub fn collocation_start(
        rod: &Rod,
        loads: &Loads,
        z: &[f64],
        statics_opts: &SolverOptions,
    ) -> Result<Option<Solution>> {
        if !statics::solved_by_collocation(rod, loads)
            || z.len() != crate::collocation::Grid::new(rod).unknowns()
        {
            return Ok(None);
        }
        let inner = SolverOptions {
            on_invalid: Policy::Ignore,
            ..*statics_opts
        };
        statics::solution_at(rod, loads, z, &inner).map(Some)
    }
}

impl InverseSolution {
    /// A warm start for the next target of the same problem.
    pub fn warm_start(&self) -> WarmStart {
        WarmStart {
            x: std::array::from_fn(|i| self.solution.x[i]),
            solution: self
                .solution
                .collocation
                .is_some()
                .then(|| self.solution.clone()),
            equilibrium: Some((
                [&self.pressures[..], &self.tensions[..]].concat(),
                self.point,
            )),
            linearisation: self.linearisation.clone(),
        }
    }
}

/// Solve the inverse problem. `loads.pressures` is the start (clipped into the bounds);
/// `warm` a warm start for it (else a cold start: the equilibrium is solved from scratch
/// and the best of a few start candidates is taken).
pub fn solve_inverse(
    rod: &Rod,
    loads: &Loads,
    target: &InverseTarget,
    opts: &InverseOptions,
    warm: Option<&WarmStart>,
) -> Result<InverseSolution> {
    validate(rod, loads, target, opts)?;
    crate::scope::dead_loads_only(rod, loads, "inverse statics")?;
    let probe = Probe::at(rod, target.s)?;
    // The equilibria: single shooting (joint Newton on (x, p), chord steps), or for a long,
    // soft rod collocation, where every iterate is a converged equilibrium solved from the
    // last one's unknowns and differentiated through the collocation equations. The choice
    // depends on the dead loads only, so it holds for every iterate.
    let by_collocation = statics::solved_by_collocation(rod, loads);
    // Inputs: the pressure channels, then the tendon channels ("pressures" p below).
    let n_p = rod.n_channels;
    let nc = n_p + rod.n_tendons;
    let task = Task {
        target,
        length: rod.length,
    };
    let lo: Vec<f64> = opts.bounds.iter().map(|b| b[0]).collect();
    let hi: Vec<f64> = opts.bounds.iter().map(|b| b[1]).collect();
    // Scaled pressures z = (p - lo) / range; a pinned channel keeps range 1 Pa (its step is 0).
    let range: Vec<f64> = opts
        .bounds
        .iter()
        .map(|b| if b[1] > b[0] { b[1] - b[0] } else { 1.0 })
        .collect();
    let with_p = |p: &[f64]| Loads {
        pressures: p[..n_p].to_vec(),
        tensions: p[n_p..].to_vec(),
        ..loads.clone()
    };
    let inputs: Vec<Input> = (0..nc)
        .map(|u| {
            if u < n_p {
                Input::Pressure(u)
            } else {
                Input::Tension(u - n_p)
            }
        })
        .collect();
    let z_ref: Vec<f64> = (0..nc)
        .map(|c| (opts.reference[c] - lo[c]) / range[c])
        .collect();
    let free = (0..nc).filter(|&c| hi[c] > lo[c]).count();
    let mut eps = if free > task.dof() {
        opts.regularisation
    } else {
        0.0
    };

    let cost_of = |y: &[f64; 12], p: &[f64], eps: f64| -> f64 {
        let e = task.residual(y, false);
        let reg: f64 = (0..nc)
            .map(|c| ((p[c] - lo[c]) / range[c] - z_ref[c]).powi(2))
            .sum();
        0.5 * e.iter().map(|v| v * v).sum::<f64>() + 0.5 * eps * reg
    };
    let eq_tol = |x: &[f64; 3]| opts.statics.tol * inf(x).max(1.0);
    // Intermediate equilibria are not answers: only the physical rules apply to them.
    let inner = SolverOptions {
        on_invalid: Policy::Ignore,
        ..opts.statics
    };
    let exact_at = |p: Vec<f64>, x: [f64; 3], problem: &Problem| -> Iterate {
        let (g, point, _) = value_with(problem, rod, &x, &probe);
        let y = flatten(&point);
        Iterate {
            p,
            x,
            g,
            y,
            point,
            y_corr: y,
            exact: true,
            sol: None,
        }
    };
    // A collocation iterate's linearisation: the probe's state and dy/dp from the implicit
    // function theorem on the collocation equations (`jacobian::collocation`).
    let colloc_lin = |p: &[f64], sol: &Solution| -> Result<(State<f64>, Linearisation)> {
        let (point, jac) = crate::jacobian::collocation::point_state_jacobian(
            rod,
            &with_p(p),
            sol,
            &inputs,
            &probe,
        )?;
        let dy = (0..nc)
            .map(|c| {
                // dR = [d theta]x R, flattened as `flatten` does.
                let w = jac.d_rotation[c];
                let skew = [[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]];
                let mut d = [0.0; 12];
                d[..3].copy_from_slice(&jac.d_position[c]);
                for j in 0..3 {
                    for k in 0..3 {
                        d[3 + 3 * j + k] = (0..3).map(|l| skew[j][l] * point.rot[l][k]).sum();
                    }
                }
                d
            })
            .collect();
        Ok((
            point,
            Linearisation {
                pass: None,
                s: target.s,
                dy,
            },
        ))
    };
    // A collocation iterate: the equilibrium at p, Newton from `from`'s unknowns (else the
    // straight rod, then load continuation), with its linearisation.
    let colloc_at = |p: Vec<f64>, from: Option<&Solution>| -> Result<(Iterate, Linearisation)> {
        let ld = with_p(&p);
        let z = from
            .and_then(|s| s.collocation.as_ref())
            .map(|c| c.z.as_slice());
        let sol = statics::solve(rod, &ld, z, &inner)?;
        if sol.collocation.is_none() {
            return Err(SoftrodError::Internal(
                "a collocation rod's equilibrium solved by shooting".into(),
            ));
        }
        let (point, lin) = colloc_lin(&p, &sol)?;
        let y = flatten(&point);
        let it = Iterate {
            p,
            x: std::array::from_fn(|i| sol.x[i]),
            g: [0.0; 3],
            y,
            point,
            y_corr: y,
            exact: true,
            sol: Some(sol),
        };
        Ok((it, lin))
    };
    // The equilibrium at p from a warm start (shooting: the unknowns `guess`; collocation:
    // the solution `from`), with a collocation iterate's linearisation.
    let iterate_at = |p: Vec<f64>,
                      guess: Option<&[f64; 3]>,
                      from: Option<&Solution>|
     -> Result<(Iterate, Option<Linearisation>)> {
        if by_collocation {
            return colloc_at(p, from).map(|(it, lin)| (it, Some(lin)));
        }
        let ld = with_p(&p);
        let problem = Problem::new(rod, &ld, 1.0);
        if let Some(x) = guess {
            // A warm start is usually the equilibrium already: one f64 pass tells.
            let it = exact_at(p.clone(), *x, &problem);
            if inf(&it.g) <= eq_tol(x) {
                return Ok((it, None));
            }
        }
        let sol = statics::solve(rod, &ld, guess.map(|g| &g[..]), &inner)?;
        Ok((exact_at(p, unknowns3(&sol)?, &problem), None))
    };
    // Chord Newton on the equilibrium at fixed pressures with the LU of a nearby g_x
    // (f64 passes only); a full statics solve if that does not converge.
    let make_exact =
        |it: Iterate, lu: &nalgebra::LU<f64, nalgebra::U3, nalgebra::U3>| -> Result<Iterate> {
            if it.exact {
                return Ok(it);
            }
            let ld = with_p(&it.p);
            let problem = Problem::new(rod, &ld, 1.0);
            let mut x = it.x;
            let mut g = it.g;
            let mut last = f64::INFINITY;
            for _ in 0..8 {
                let n = inf(&g);
                if !n.is_finite() || n > 0.5 * last {
                    break;
                }
                let d = lu
                    .solve(&-Vector3::from_column_slice(&g))
                    .unwrap_or_else(Vector3::zeros);
                for k in 0..3 {
                    x[k] += d[k];
                }
                let next = exact_at(it.p.clone(), x, &problem);
                if inf(&next.g) <= eq_tol(&x) {
                    return Ok(next);
                }
                last = n;
                g = next.g;
            }
            let sol = statics::solve(rod, &ld, Some(&it.x), &inner)?;
            Ok(exact_at(it.p, unknowns3(&sol)?, &problem))
        };
    // A shooting iterate at the trial pressures p_t: the linearised equilibrium x + dx with
    // dx = -g_x^-1 (g + g_p dp), accepted when its defect is within LOOSE (probe values
    // corrected to first order), else chord Newton steps with this g_x, else (with a fresh
    // linearisation) a full solve. None: the step is too long for this linearisation.
    let shooting_trial = |it: &Iterate,
                          p_t: &[f64],
                          pass: &Pass,
                          lu: &nalgebra::LU<f64, nalgebra::U3, nalgebra::U3>,
                          fresh: bool|
     -> Result<Option<Iterate>> {
        let mut rhs = Vector3::from_column_slice(&it.g);
        for c in 0..nc {
            rhs += Vector3::from_column_slice(&pass.g_a[c]) * (p_t[c] - it.p[c]);
        }
        let dx = lu.solve(&-rhs).unwrap_or_else(Vector3::zeros);
        let mut x_t = [it.x[0] + dx[0], it.x[1] + dx[1], it.x[2] + dx[2]];
        let ld_t = with_p(p_t);
        let prob_t = Problem::new(rod, &ld_t, 1.0);
        let mut trial = None;
        let mut last = f64::INFINITY;
        for _ in 0..8 {
            let (g, point, _) = value_with(&prob_t, rod, &x_t, &probe);
            let n = inf(&g);
            if !n.is_finite() || n > 0.5 * last {
                break;
            }
            if n <= LOOSE * inf(&x_t).max(1.0) {
                trial = Some((g, point, n <= eq_tol(&x_t)));
                break;
            }
            last = n;
            let d = lu
                .solve(&-Vector3::from_column_slice(&g))
                .unwrap_or_else(Vector3::zeros);
            for k in 0..3 {
                x_t[k] += d[k];
            }
        }
        if trial.is_none() && fresh {
            // A long step: solve the equilibrium properly (Newton, continuation).
            if let Ok(sol) = statics::solve(rod, &ld_t, Some(&x_t), &inner) {
                x_t = unknowns3(&sol)?;
                let (g, point, _) = value_with(&prob_t, rod, &x_t, &probe);
                trial = Some((g, point, true));
            }
        }
        let Some((g, point, exact)) = trial else {
            return Ok(None);
        };
        let y = flatten(&point);
        let y_corr = if exact {
            y
        } else {
            let d = lu
                .solve(&-Vector3::from_column_slice(&g))
                .unwrap_or_else(Vector3::zeros);
            std::array::from_fn(|i| y[i] + (0..3).map(|j| pass.y_x[i][j] * d[j]).sum::<f64>())
        };
        Ok(Some(Iterate {
            p: p_t.to_vec(),
            x: x_t,
            g,
            y,
            point,
            y_corr,
            exact,
            sol: None,
        }))
    };
    // Start: the equilibrium at the clipped start pressures; from a cold start, the best of
    // it, the box's centre and (up to 4 channels) its corners, so that the local method
    // starts in the right basin of a non-convex distance.
    let p0: Vec<f64> = loads
        .pressures
        .iter()
        .chain(&loads.tensions)
        .enumerate()
        .map(|(c, v)| v.clamp(lo[c], hi[c]))
        .collect();
    let guess = warm.map(|w| &w.x);
    let warm_solution = warm.and_then(|w| w.solution.as_ref());
    let known = warm.and_then(|w| {
        w.equilibrium.as_ref().filter(|(p, _)| {
            *p == p0
                && w.x.iter().all(|v| v.is_finite())
                && (!by_collocation || w.solution.is_some())
        })
    });
    // A collocation iterate's linearisation comes with it (taken at the iterate itself).
    let mut start_lin = None;
    let mut it = match known {
        // The previous answer: converged and checked there, at these very pressures.
        Some((_, point)) => {
            let y = flatten(point);
            Iterate {
                p: p0,
                x: warm.expect("known comes from warm").x,
                g: [0.0; 3],
                y,
                point: *point,
                y_corr: y,
                exact: true,
                sol: warm_solution.cloned(),
            }
        }
        None => {
            let (it, lin) = iterate_at(p0, guess, warm_solution)?;
            start_lin = lin;
            it
        }
    };
    if guess.is_none() {
        let mut candidates: Vec<Vec<f64>> = vec![(0..nc).map(|c| 0.5 * (lo[c] + hi[c])).collect()];
        if nc <= 4 {
            for corner in 0..(1usize << nc) {
                candidates.push(
                    (0..nc)
                        .map(|c| if corner >> c & 1 == 1 { hi[c] } else { lo[c] })
                        .collect(),
                );
            }
        }
        let mut best = cost_of(&it.y, &it.p, eps);
        for cand in candidates {
            if let Ok((c, lin)) = iterate_at(cand, None, None) {
                let cost = cost_of(&c.y, &c.p, eps);
                if cost < best {
                    best = cost;
                    it = c;
                    start_lin = lin;
                }
            }
        }
    }
    // Dual passes (shooting) or implicit-function solves (collocation).
    let mut passes = usize::from(start_lin.is_some());
    let mut mu = 0.0f64;
    let mut iterations = 0;
    let mut stationary = false;
    // Structured secant estimate M of the part of the cost's Hessian that Gauss-Newton drops,
    // sum_i e_i d2e_i/dz2 (Dennis, Gay and Welsch's NL2SOL), learnt from the exact Jacobians
    // of successive fresh passes. Far out of reach it is not small: the point moves along a
    // curve whose centre of curvature lies near the target, the distance barely changes along
    // it, and J^T J overstates the curvature so much that Gauss-Newton crawls (linear
    // convergence at a rate near 1). `augmented` says whether the model J^T J + M predicted
    // the last steps' decrease better than J^T J alone (then the next step uses it).
    let mut s2 = DMatrix::<f64>::zeros(nc, nc);
    let mut augmented = false;
    // Fletcher and Xu's test for a large residual: the last accepted step lowered the cost
    // by less than a fifth. Near a reachable target Gauss-Newton converges quadratically
    // (each step removes far more) and a stale M would only spoil its steps.
    let mut large_residual = false;
    // The last fresh linearisation's (z, J, J^T e) and the actual and Gauss-Newton-predicted
    // decreases of the cost accepted since.
    let mut last_exact: Option<(DVector<f64>, DMatrix<f64>, DVector<f64>)> = None;
    let mut since = (0.0f64, 0.0f64);
    // The linearisation in use: fresh from a pass at the current iterate, or kept from an
    // earlier iterate (or the previous call) while its chord steps contract well.
    // A collocation iterate's linearisation is always taken at the iterate (fresh).
    let mut lin: Option<Linearisation> = match start_lin {
        Some(l) => Some(l),
        None => warm.and_then(|w| w.linearisation.clone()).filter(|l| {
            l.dy.len() == nc
                && l.s == target.s
                && l.pass.is_none() == by_collocation
                && (!by_collocation || known.is_some())
        }),
    };
    let mut fresh = by_collocation && lin.is_some();
    let mut need_fresh = lin.is_none();
    let mut moved = false;
    while iterations < opts.max_iter {
        if eps == 0.0 && task.reached(&it.y_corr, opts.tol) {
            if let Some(pass) = lin.as_ref().and_then(|l| l.pass.as_ref()) {
                it = make_exact(it, &pass.g_x.lu())?;
            }
            if task.reached(&it.y, opts.tol) {
                break;
            }
        }
        iterations += 1;
        if need_fresh || lin.is_none() {
            passes += 1;
            if let Some(sol) = it.sol.as_ref() {
                lin = Some(colloc_lin(&it.p, sol)?.1);
            } else {
                let ld = with_p(&it.p);
                let problem = Problem::new(rod, &ld, 1.0);
                let pass = pass_with(&problem, rod, &ld, &it.x, &inputs, &probe);
                let Some((dy, _)) = total_derivatives(&pass) else {
                    return Err(SoftrodError::NotConverged {
                        iterations,
                        residual: inf(&it.g),
                        load_factor: 1.0,
                        reason: "the shooting Jacobian became singular during the inverse (a limit point of the equilibrium)".into(),
                    });
                };
                lin = Some(Linearisation {
                    pass: Some(pass),
                    s: target.s,
                    dy,
                });
            }
            fresh = true;
            need_fresh = false;
        }
        let current = lin.as_ref().expect("a linearisation is set above");
        // The shooting pass and its g_x factored (none at a collocation iterate).
        let shooting = current.pass.as_ref().map(|pass| (pass, pass.g_x.lu()));
        let dy = current.dy.clone();
        // Value and Jacobian of e in scaled pressures; the equilibrium defect g of the
        // iterate is folded in through the linearised equilibrium (a collocation iterate
        // is converged).
        let y_lin: [f64; 12] = match &shooting {
            Some((pass, lu)) => {
                let dx0 = lu
                    .solve(&-Vector3::from_column_slice(&it.g))
                    .unwrap_or_else(Vector3::zeros);
                std::array::from_fn(|i| {
                    it.y[i] + (0..3).map(|j| pass.y_x[i][j] * dx0[j]).sum::<f64>()
                })
            }
            None => it.y,
        };
        let e = DVector::from_vec(task.residual(&y_lin, false));
        let m = e.len();
        let columns: Vec<Vec<f64>> = (0..nc)
            .map(|c| task.residual(&dy[c].map(|v| v * range[c]), true))
            .collect();
        let jac = DMatrix::from_fn(m, nc, |r, c| columns[c][r]);
        let cost = cost_of(&y_lin, &it.p, eps);
        let z: Vec<f64> = (0..nc).map(|c| (it.p[c] - lo[c]) / range[c]).collect();
        let jtj = jac.transpose() * &jac;
        if let Some(c) = (0..nc).find(|&c| !(jtj[(c, c)].is_finite())) {
            // The step works in fractions of each input's range: a range so wide that the
            // derivative per range overflows leaves no step to take, and the answer would
            // be the start, not the closest pose.
            let field = if c < n_p {
                format!("pressure_bounds[{c}]")
            } else {
                format!("tension_bounds[{}]", c - n_p)
            };
            return Err(SoftrodError::invalid(
                field,
                format!("[{}, {}]", lo[c], hi[c]),
                "the range is too wide for the inverse to scale (its derivative per range overflows); give the range the actuator can use",
            ));
        }
        let scale = jtj.diagonal().max().max(1e-300);
        let grad_reg = DVector::from_fn(nc, |c, _| eps * (z[c] - z_ref[c]));
        let grad_task = jac.transpose() * &e;
        let b = -&grad_task - &grad_reg;
        let zv = DVector::from_column_slice(&z);
        // First-order optimality, judged at exact Jacobians only.
        let mut first_order = false;
        // M lives on the inputs that may move: a pinned one or one held at a bound by the
        // gradient has no curvature to learn (M is part of the reduced Hessian).
        let grad = &grad_task + &grad_reg;
        let held: Vec<bool> = (0..nc)
            .map(|c| {
                hi[c] == lo[c] || (z[c] <= 0.0 && grad[c] > 0.0) || (z[c] >= 1.0 && grad[c] < 0.0)
            })
            .collect();
        if fresh {
            let free_only =
                |v: DVector<f64>| DVector::from_fn(nc, |c, _| if held[c] { 0.0 } else { v[c] });
            for c in (0..nc).filter(|&c| held[c]) {
                s2.row_mut(c).fill(0.0);
                s2.column_mut(c).fill(0.0);
            }
            if let Some((z0, j0, g0)) = &last_exact {
                let step = free_only(&zv - z0);
                if step.norm() > 0.0 {
                    // y# = (J - J0)^T e: M's secant condition M s = y#; y = grad - grad0.
                    let y_sharp = free_only((&jac - j0).transpose() * &e);
                    let y = free_only(&grad_task - g0);
                    let (actual, pred_gn) = since;
                    // Would J^T J + M (M updated) have predicted the decrease better?
                    if secant_update(&mut s2, &step, &y, &y_sharp) {
                        let pred_aug = pred_gn - 0.5 * step.dot(&y_sharp);
                        augmented = (actual - pred_aug).abs() < (actual - pred_gn).abs();
                    }
                }
            }
            last_exact = Some((zv.clone(), jac.clone(), grad_task.clone()));
            since = (0.0, 0.0);
            // The first-order decrease the linearisation offers anywhere in the box (the
            // Frank-Wolfe gap): max over feasible z' of grad . (z - z'). Where the cost is
            // locally convex it bounds the decrease left, cost - cost* <= gap, and a decrease
            // of the cost by gap moves |e| by gap / |e|: below tol (the reach resolution, in
            // L and rad) the closest pose is resolved.
            let gap: f64 = (0..nc)
                .filter(|&c| hi[c] > lo[c])
                .map(|c| (grad[c] * z[c]).max(-grad[c] * (1.0 - z[c])).max(0.0))
                .sum();
            first_order = gap <= opts.tol * (2.0 * cost).sqrt();
        }
        // The augmented model is a projected Newton step (Bertsekas): the held inputs stay
        // where they are, the others take the step of J^T J + M on their face, where that
        // is convex (the box QP needs a positive definite H). J^T J alone is singular with
        // more inputs than task rows, so convexity is judged on the free face only.
        let convex = || {
            let free_face: Vec<usize> = (0..nc).filter(|&c| !held[c]).collect();
            let k = free_face.len();
            let ridge = eps + mu + 1e-14 * scale;
            k > 0
                && DMatrix::from_fn(k, k, |a, b| {
                    let (i, j) = (free_face[a], free_face[b]);
                    jtj[(i, j)] + s2[(i, j)] + if a == b { ridge } else { 0.0 }
                })
                .cholesky()
                .is_some()
        };
        // (The Cholesky factorisation only when the model is wanted: warm calls stay cheap.)
        let curvature = if augmented && large_residual && convex() {
            Some(&s2)
        } else {
            None
        };
        let pin = |c: usize| curvature.is_some() && held[c];
        let zlo: Vec<f64> = (0..nc).map(|c| if pin(c) { 0.0 } else { -z[c] }).collect();
        let zhi: Vec<f64> = (0..nc)
            .map(|c| {
                if hi[c] > lo[c] && !pin(c) {
                    1.0 - z[c]
                } else {
                    0.0
                }
            })
            .collect();
        let mut accepted = false;
        if first_order {
            stationary = true;
        }
        for _attempt in 0..12 {
            if first_order {
                break;
            }
            let mut h = match curvature {
                Some(s2) => &jtj + s2,
                None => jtj.clone(),
            };
            let ridge = eps + mu + 1e-14 * scale;
            for c in 0..nc {
                h[(c, c)] += ridge;
            }
            let dz = box_qp(&h, &b, &zlo, &zhi);
            let step_size = inf(dz.as_slice());
            // Predicted decrease of the model (without the mu term).
            let model = |d: &DVector<f64>| -> f64 {
                let r = &e + &jac * d;
                let reg: f64 = (0..nc).map(|c| (z[c] + d[c] - z_ref[c]).powi(2)).sum();
                0.5 * r.dot(&r) + 0.5 * eps * reg
            };
            let pred_gn = cost - model(&dz);
            let pred = match curvature {
                Some(s2) => pred_gn - 0.5 * dz.dot(&(s2 * &dz)),
                None => pred_gn,
            };
            if step_size <= 1e-12 || pred <= 1e-15 * cost.max(1e-300) {
                stationary = true;
                break;
            }
            let p_t: Vec<f64> = (0..nc)
                .map(|c| (it.p[c] + dz[c] * range[c]).clamp(lo[c], hi[c]))
                .collect();
            let trial = match &shooting {
                Some((pass, lu)) => shooting_trial(&it, &p_t, pass, lu, fresh)?.map(|t| (t, None)),
                // The equilibrium at p_t from this iterate's unknowns: its linearisation
                // is the next iteration's, fresh.
                None => colloc_at(p_t.clone(), it.sol.as_ref())
                    .ok()
                    .map(|(t, lin)| (t, Some(lin))),
            };
            let Some((trial, trial_lin)) = trial else {
                if !fresh {
                    break; // the kept linearisation is too old: take a fresh one
                }
                mu = (mu * 4.0).max(1e-3 * scale);
                continue;
            };
            if trial_lin.is_some() {
                passes += 1;
            }
            let y_corr_t = trial.y_corr;
            let cost_t = cost_of(&y_corr_t, &p_t, eps);
            if cost_t.is_finite() && cost_t < cost {
                let rho = (cost - cost_t) / pred;
                since.0 += cost - cost_t;
                large_residual = cost - cost_t < 0.2 * cost;
                since.1 += pred_gn;
                mu = if rho > 0.75 {
                    mu / 3.0
                } else if rho < 0.25 {
                    (mu * 2.0).max(1e-6 * scale)
                } else {
                    mu
                };
                if mu < 1e-12 * scale {
                    mu = 0.0;
                }
                // Keep this linearisation for the next step while it contracts the cost
                // well (a chord step of the joint Newton method costs f64 passes only).
                need_fresh = cost_t > 0.0625 * cost;
                // Broyden's update of dy/dp with the observed change (scaled pressures).
                let sz: Vec<f64> = (0..nc).map(|c| (p_t[c] - it.p[c]) / range[c]).collect();
                let ss: f64 = sz.iter().map(|v| v * v).sum();
                if ss > 0.0 {
                    let miss: [f64; 12] = std::array::from_fn(|i| {
                        y_corr_t[i]
                            - y_lin[i]
                            - (0..nc).map(|c| dy[c][i] * sz[c] * range[c]).sum::<f64>()
                    });
                    if let Some(l) = lin.as_mut() {
                        for c in 0..nc {
                            for i in 0..12 {
                                l.dy[c][i] += miss[i] * sz[c] / (ss * range[c]);
                            }
                        }
                    }
                }
                it = trial;
                accepted = true;
                moved = true;
                fresh = false;
                if let Some(l) = trial_lin {
                    // Taken at the new iterate: exact there.
                    lin = Some(l);
                    fresh = true;
                    need_fresh = false;
                }
                break;
            }
            if !fresh {
                break;
            }
            mu = (mu * 4.0).max(1e-4 * scale);
        }
        if !accepted && !fresh {
            // A kept linearisation failed to make progress: retry with a fresh one.
            need_fresh = true;
            stationary = false;
            continue;
        }
        if !accepted {
            stationary = true;
        }
        // The regularised phase only picks a point among the redundant answers: it gets at
        // most a quarter of the iterations (it converges in a few where the target is
        // reachable; in a flat valley of an unreachable one it would crawl).
        if eps > 0.0 && iterations >= opts.max_iter / 4 {
            stationary = true;
        }
        if stationary {
            if eps > 0.0 {
                // The regularised problem has converged: now the task alone, with
                // minimum-norm steps from here.
                eps = 0.0;
                stationary = false;
                mu = 0.0;
                continue;
            }
            break;
        }
    }
    if let Some(pass) = lin.as_ref().and_then(|l| l.pass.as_ref()) {
        it = make_exact(it, &pass.g_x.lu())?;
    }
    if known.is_some() && !moved {
        // The answer is the warm start's own equilibrium: check it rather than trust it.
        let sol = it.sol.take();
        it = iterate_at(it.p.clone(), Some(&it.x), sol.as_ref())?.0;
    }
    let reached = task.reached(&it.y, opts.tol);
    if !reached && !stationary && eps == 0.0 && iterations >= opts.max_iter {
        return Err(SoftrodError::NotConverged {
            iterations,
            residual: cost_of(&it.y, &it.p, 0.0),
            load_factor: 1.0,
            reason: format!(
                "the inverse reached neither the target nor a stationary point in {} iterations (raise max_iter)",
                opts.max_iter
            ),
        });
    }
    // The answer as a static solve concludes it: validity rules and stability (a
    // collocation iterate: Newton from its converged unknowns, then the same checks).
    let solution = match &it.sol {
        Some(sol) => statics::solve(
            rod,
            &with_p(&it.p),
            sol.collocation.as_ref().map(|c| c.z.as_slice()),
            &opts.statics,
        )?,
        None => statics::conclude_at(rod, &with_p(&it.p), it.x, iterations, &opts.statics)?,
    };
    let distance = (0..3)
        .map(|i| (it.y[i] - target.position[i]).powi(2))
        .sum::<f64>()
        .sqrt();
    let tol_p = |c: usize| 1e-12 * range[c];
    Ok(InverseSolution {
        active: (0..nc)
            .map(|c| {
                if it.p[c] <= lo[c] + tol_p(c) {
                    -1
                } else if it.p[c] >= hi[c] - tol_p(c) {
                    1
                } else {
                    0
                }
            })
            .collect(),
        point: it.point,
        reached,
        distance,
        angle: task.angle(&it.y),
        cost: cost_of(&it.y, &it.p, 0.0),
        tensions: it.p[n_p..].to_vec(),
        pressures: it.p[..n_p].to_vec(),
        solution,
        iterations,
        passes,
        linearisation: lin,
    })
}

/// Dennis, Gay and Welsch's update of the structured secant term M (NL2SOL): sized down by
/// min(1, |s^T y#| / |s^T M s|) (M fades where the residual's curvature does), then the
/// least change weighted by the Hessian that gives M s = y#. Skipped (false) unless the
/// step met positive curvature, y^T s > 0.
fn secant_update(
    s2: &mut DMatrix<f64>,
    s: &DVector<f64>,
    y: &DVector<f64>,
    y_sharp: &DVector<f64>,
) -> bool {
    let sy = s.dot(y);
    if !(sy > 0.0 && sy.is_finite() && y_sharp.iter().all(|v| v.is_finite())) {
        return false;
    }
    let sss = s.dot(&(&*s2 * s));
    if sss != 0.0 {
        *s2 *= (s.dot(y_sharp).abs() / sss.abs()).min(1.0);
    }
    let r = y_sharp - &*s2 * s;
    let rs = r.dot(s);
    *s2 += (&r * y.transpose() + y * r.transpose()) / sy - (y * y.transpose()) * (rs / (sy * sy));
    true
}

fn flatten(st: &State<f64>) -> [f64; 12] {
    let r = &st.rot;
    [
        st.r[0], st.r[1], st.r[2], r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0],
        r[2][1], r[2][2],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The secant update meets its condition M s = y# exactly (to rounding, 1e-14 of |y#|),
    /// stays symmetric, and is skipped where the step met no positive curvature (y^T s <= 0).
    #[test]
    fn secant_update_meets_the_secant_condition() {
        let mut s2 =
            DMatrix::from_row_slice(3, 3, &[0.3, 0.1, 0.0, 0.1, -0.2, 0.05, 0.0, 0.05, 0.4]);
        let s = DVector::from_column_slice(&[0.2, -0.1, 0.05]);
        let y = DVector::from_column_slice(&[0.5, -0.3, 0.2]);
        let y_sharp = DVector::from_column_slice(&[-0.04, 0.01, 0.03]);
        assert!(secant_update(&mut s2, &s, &y, &y_sharp));
        let miss = (&s2 * &s - &y_sharp).amax();
        assert!(miss <= 1e-14 * y_sharp.amax(), "{miss:e}");
        assert!((&s2 - s2.transpose()).amax() == 0.0);
        let before = s2.clone();
        assert!(!secant_update(&mut s2, &s, &(-&y), &y_sharp));
        assert_eq!(s2, before);
    }
}
