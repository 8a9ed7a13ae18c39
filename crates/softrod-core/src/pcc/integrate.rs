//! Statics and time stepping of the PCC model.
//!
//! Dynamics: implicit midpoint rule on (q, q_t): with v_m = (v0 + v1)/2,
//!   q1 = q0 + h v_m,  M(q_m) (v1 - v0)/h + C(q_m, v_m) v_m - Q(q_m, v_m, p_m) = 0,
//! q_m = (q0 + q1)/2, p_m = (p0 + p1)/2, solved for v_m by Newton with the exact Jacobian
//! (one vector-dual evaluation of the equations of motion). The rule is A-stable and
//! second order, and adds no numerical damping, so energy is kept to O(h^2) without
//! damping or input. The Newton matrix is kept across steps while it contracts (and at
//! most `MAX_AGE` steps), and a cubic predictor of v_m makes most steps converge after
//! one update; the stopping rule (last update below `tol`) is unchanged.
//! Statics: Newton with backtracking on Q(q) = 0 (the matrix kept while full steps with it
//! contract), pressure continuation if needed.

use super::jet::Grad;
use super::kinematics::Pose;
use super::lagrangian::Energy;
use super::{LinkKind, PccModel};
use crate::error::{Result, SoftrodError};

/// Newton settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepOptions {
    /// Converged when every Newton update, as a displacement, is below tol times the
    /// coordinate's scale (L0 for lengths, 1 rad for angles).
    pub tol: f64,
    pub max_iter: usize,
}

impl Default for StepOptions {
    fn default() -> Self {
        StepOptions {
            tol: 1e-11,
            max_iter: 30,
        }
    }
}

/// Where a simulation starts (model coordinates).
#[derive(Debug, Clone, PartialEq)]
pub enum InitialState {
    /// At rest in the static equilibrium under zero pressure.
    Rest,
    /// At rest in the static equilibrium under the first pressures.
    Static,
    /// Given coordinates and rates.
    Given { x: Vec<f64>, v: Vec<f64> },
}

/// A static equilibrium.
#[derive(Debug, Clone, PartialEq)]
pub struct PccStatic {
    /// Model coordinates.
    pub x: Vec<f64>,
    pub iterations: usize,
    /// Largest generalised force left, N or N m.
    pub residual: f64,
}

/// A simulated trajectory at the saved steps.
#[derive(Debug, Clone, PartialEq)]
pub struct PccTrajectory {
    pub time: Vec<f64>,
    /// Model coordinates and rates, one row per saved step.
    pub x: Vec<Vec<f64>>,
    pub v: Vec<Vec<f64>>,
    pub tip_position: Vec<[f64; 3]>,
    pub tip_rotation: Vec<[[f64; 3]; 3]>,
    /// Tip velocity, m/s (the exact derivative of the tip position along v).
    pub tip_velocity: Vec<[f64; 3]>,
    /// Chamber pressures after the supply's lag and rate limit, Pa.
    pub pressure: Vec<Vec<f64>>,
    /// Kinetic + gravitational + elastic energy, J.
    pub energy: Vec<f64>,
    /// Newton iterations over all steps.
    pub newton_iterations: usize,
    /// Exact Jacobians computed (the Newton matrix is kept while it works).
    pub jacobian_evaluations: usize,
}

pub(crate) type Dn<const N: usize> = Grad<f64, N>;

/// A sampled shape: reference arc length s, positions and rotations.
pub type Shape = (Vec<f64>, Vec<[f64; 3]>, Vec<[[f64; 3]; 3]>);

/// Solve A z = b by Gaussian elimination with partial pivoting; None if singular.
pub(crate) fn solve_dense<const N: usize>(
    mut a: [[f64; N]; N],
    mut b: [f64; N],
) -> Option<[f64; N]> {
    let norm = a.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
    for c in 0..N {
        let piv = (c..N).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        // A NaN pivot is singular too.
        if a[piv][c].abs().is_nan() || a[piv][c].abs() <= 1e-14 * norm {
            return None;
        }
        a.swap(c, piv);
        b.swap(c, piv);
        for r in c + 1..N {
            let f = a[r][c] / a[c][c];
            for k in c..N {
                a[r][k] -= f * a[c][k];
            }
            b[r] -= f * b[c];
        }
    }
    let mut z = [0.0; N];
    for c in (0..N).rev() {
        let s: f64 = (c + 1..N).map(|k| a[c][k] * z[k]).sum();
        z[c] = (b[c] - s) / a[c][c];
    }
    Some(z)
}

pub(crate) fn arr<const N: usize>(x: &[f64]) -> [f64; N] {
    std::array::from_fn(|i| x[i])
}

/// Coordinate scales: L0 for lengths, 1 rad for angles.
fn scales<const N: usize>(m: &PccModel) -> [f64; N] {
    let mut s = [1.0; N];
    for l in &m.links {
        if let LinkKind::Segment { offset, .. } = l.kind {
            s[offset] = l.length;
        }
    }
    s
}

/// Residual and Jacobian with respect to a variable z of `residual`, evaluated on vector
/// duals over z.
pub(crate) fn eval_jac<const N: usize>(
    z: &[f64; N],
    residual: impl Fn(&[Dn<N>; N]) -> [Dn<N>; N],
) -> ([f64; N], [[f64; N]; N]) {
    let zd: [Dn<N>; N] = std::array::from_fn(|i| Dn::<N>::variable(z[i], i));
    let r = residual(&zd);
    (r.map(|x| x.re), r.map(|x| x.eps))
}

/// Statics keeps its Newton matrix while each update is below this fraction of the one
/// before.
const STATIC_REFRESH_RATIO: f64 = 0.1;

pub(crate) fn statics_n<const N: usize>(
    m: &PccModel,
    p: &[f64],
    guess: &[f64],
    opts: &StepOptions,
) -> Result<PccStatic> {
    let sc = scales::<N>(m);
    let merit = |r: &[f64; N]| (0..N).map(|i| (r[i] * sc[i]).powi(2)).sum::<f64>();
    let valid = |x: &[f64; N]| m.segments().all(|(_, o, _)| x[o] > 0.0);
    let residual = |x: &[f64; N], p: &[f64]| m.static_forces(x, p).residual();
    // Newton with the exact Jacobian (dual numbers) and backtracking; the matrix is kept for
    // the next iterations while full steps with it contract fast (simplified Newton, as in
    // the dynamics): a residual costs about 1/4 (one segment) to 1/17 (three) of a Jacobian.
    let solve = |x0: [f64; N], p: &[f64]| -> std::result::Result<([f64; N], usize, f64), f64> {
        let mut x = x0;
        let mut jac: Option<[[f64; N]; N]> = None;
        let mut r = [0.0; N];
        let mut prev = f64::INFINITY;
        for it in 0..opts.max_iter {
            let fresh = jac.is_none();
            if fresh {
                let (r0, j) = eval_jac(&x, |z| m.static_forces(z, p).residual());
                r = r0;
                jac = Some(j);
                prev = f64::INFINITY;
            }
            let f0 = merit(&r);
            let Some(lu) = solve_dense(jac.expect("set above"), r) else {
                if fresh {
                    return Err(f0.sqrt());
                }
                jac = None;
                continue;
            };
            let mut step = 1.0;
            let mut xn = x;
            let mut rn = r;
            if fresh {
                // Backtracking: accept the first step that lowers the work-scaled residual.
                for _ in 0..30 {
                    xn = std::array::from_fn(|i| x[i] - step * lu[i]);
                    if valid(&xn) {
                        rn = residual(&xn, p);
                        if merit(&rn) <= f0 || step < 1e-3 {
                            break;
                        }
                    }
                    step *= 0.5;
                }
            } else {
                // Kept matrix: the full step, if it lowers the residual; else a fresh
                // Jacobian at x (this iteration does not move).
                xn = std::array::from_fn(|i| x[i] - lu[i]);
                let ok = valid(&xn) && {
                    rn = residual(&xn, p);
                    merit(&rn) <= f0
                };
                if !ok {
                    jac = None;
                    continue;
                }
            }
            if !valid(&xn) {
                // Backtracking found no admissible point: recompute there as before.
                rn = residual(&xn, p);
            }
            x = xn;
            r = rn;
            let upd = (0..N).fold(0.0f64, |a, i| a.max((step * lu[i]).abs() / sc[i]));
            if upd <= opts.tol {
                let res = r.iter().fold(0.0f64, |a, b| a.max(b.abs()));
                return Ok((x, it + 1, res));
            }
            if upd > STATIC_REFRESH_RATIO * prev {
                jac = None;
            }
            prev = upd;
        }
        Err(f64::NAN)
    };
    let x0: [f64; N] = arr(guess);
    let mut total = 0;
    match solve(x0, p) {
        Ok((x, it, res)) => {
            return Ok(PccStatic {
                x: x.to_vec(),
                iterations: it,
                residual: res,
            })
        }
        Err(_) => {
            // Continuation in the pressures from the guess.
            let mut x = x0;
            let steps = 20;
            for k in 1..=steps {
                let lam = k as f64 / steps as f64;
                let pk: Vec<f64> = p.iter().map(|v| v * lam).collect();
                match solve(x, &pk) {
                    Ok((xn, it, res)) => {
                        x = xn;
                        total += it;
                        if k == steps {
                            return Ok(PccStatic {
                                x: x.to_vec(),
                                iterations: total,
                                residual: res,
                            });
                        }
                    }
                    Err(res) => {
                        return Err(SoftrodError::NotConverged {
                            iterations: total,
                            residual: res,
                            load_factor: lam,
                            reason: "PCC static Newton failed during pressure continuation".into(),
                        })
                    }
                }
            }
        }
    }
    unreachable!("continuation returns from its last step")
}

/// Newton matrix kept between steps: the exact Jacobian (dual numbers) at the iterate where
/// it was last computed. It is recomputed when the iteration stops contracting quickly, and
/// after `MAX_AGE` steps (simplified Newton, as in stiff ODE codes): the converged step is
/// the same to the tolerance, and each iteration costs one residual (no derivatives in z).
struct NewtonMatrix<const N: usize> {
    jac: Option<[[f64; N]; N]>,
    evaluations: usize,
    /// Steps begun since it was computed.
    age: usize,
}

/// The kept Newton matrix is recomputed when an update is more than this fraction of the one
/// before (linear contraction slower than this). Right after a refresh the contraction is
/// about 1e-3 and it degrades slowly as the state moves on (by ~5e-4 per 1 ms step on the
/// bundled arm); 0.05 keeps most steps at 1-2 iterations (0.2 gave 17 % more iterations at
/// dt = 5 ms, for fewer Jacobians).
const REFRESH_RATIO: f64 = 0.05;

/// ... and in any case every this many steps. With the predictor below most steps converge
/// after one update, which measures no contraction, so a matrix could otherwise go stale
/// unnoticed; each accepted step keeps an error of about (contraction) x (its update), and
/// the predictor extrapolates those errors: with a stale matrix they can grow from step to
/// step up to the tolerance (seen as 1e-11 rad of spurious bending under six equal
/// pressures). Refreshed every 50 steps they stay at round-off.
const MAX_AGE: usize = 50;

/// Predictor for the midpoint velocity of the next step: the cubic through the last four
/// midpoint velocities, extrapolated one step (error O(h^4) on smooth motion, against O(h^2)
/// for the last velocity plus half a step of the last acceleration). The midpoint
/// velocities are smoother than the step velocities: a stiff component that the implicit
/// midpoint rule flips in sign at every step enters them damped by (1 - r)/2.
/// With the cubic, most 1 ms steps of the bundled arm converge in one Newton iteration.
fn extrapolate<const N: usize>(hist: &[[f64; N]; 4]) -> [f64; N] {
    std::array::from_fn(|i| 4.0 * hist[3][i] - 6.0 * hist[2][i] + 4.0 * hist[1][i] - hist[0][i])
}

/// One implicit midpoint step from (x0, v0) with guess vm for the midpoint velocity:
/// returns (x1, v1, iterations).
#[allow(clippy::too_many_arguments)]
fn step_n<const N: usize>(
    m: &PccModel,
    x0: &[f64; N],
    v0: &[f64; N],
    guess: [f64; N],
    pm: &[f64],
    h: f64,
    opts: &StepOptions,
    sc: &[f64; N],
    newton: &mut NewtonMatrix<N>,
) -> std::result::Result<([f64; N], [f64; N], usize), f64> {
    let build = |z: &[f64; N]| -> ([f64; N], [f64; N]) {
        (
            std::array::from_fn(|i| x0[i] + 0.5 * h * z[i]),
            std::array::from_fn(|i| (z[i] - v0[i]) * (2.0 / h)),
        )
    };
    let resid = |z: &[f64; N]| {
        let (x, a) = build(z);
        m.forces(&x, z, &a, pm).residual()
    };
    let refresh = |z: &[f64; N], newton: &mut NewtonMatrix<N>| {
        let (r, jac) = eval_jac(z, |zd| {
            let x = std::array::from_fn(|i| zd[i] * (0.5 * h) + x0[i]);
            let a = std::array::from_fn(|i| (zd[i] - v0[i]) * (2.0 / h));
            m.forces(&x, zd, &a, pm).residual()
        });
        newton.jac = Some(jac);
        newton.evaluations += 1;
        newton.age = 0;
        r
    };
    let mut vm = guess;
    let mut fresh = newton.jac.is_none();
    let mut r = if fresh {
        refresh(&vm, newton)
    } else {
        resid(&vm)
    };
    let mut prev = f64::INFINITY;
    let mut last = f64::NAN;
    for it in 0..opts.max_iter {
        let jac = newton.jac.expect("set above");
        let Some(d) = solve_dense(jac, r) else {
            if fresh {
                return Err(last);
            }
            r = refresh(&vm, newton);
            fresh = true;
            continue;
        };
        for i in 0..N {
            vm[i] -= d[i];
        }
        last = (0..N).fold(0.0f64, |a, i| a.max((d[i] * h / sc[i]).abs()));
        if !last.is_finite() {
            return Err(last);
        }
        if last <= opts.tol {
            let x1 = std::array::from_fn(|i| x0[i] + h * vm[i]);
            let v1 = std::array::from_fn(|i| 2.0 * vm[i] - v0[i]);
            return Ok((x1, v1, it + 1));
        }
        // Slow contraction with an old matrix: recompute it here.
        if last > REFRESH_RATIO * prev && !fresh {
            r = refresh(&vm, newton);
            fresh = true;
            prev = f64::INFINITY;
        } else {
            r = resid(&vm);
            fresh = false;
            prev = last;
        }
    }
    Err(last)
}

#[allow(clippy::too_many_arguments)]
fn simulate_n<const N: usize>(
    m: &PccModel,
    dt: f64,
    pressures: &[f64],
    n_steps: usize,
    initial: &InitialState,
    save_every: usize,
    opts: &StepOptions,
) -> Result<PccTrajectory> {
    let nc = m.n_channels;
    let row = |k: usize| &pressures[k * nc..(k + 1) * nc];
    let (x0, v0) = match initial {
        InitialState::Rest => {
            let s = statics_n::<N>(m, &vec![0.0; nc], &m.rest(), opts)?;
            (arr::<N>(&s.x), [0.0; N])
        }
        InitialState::Static => {
            let s = statics_n::<N>(m, row(0), &m.rest(), opts)?;
            (arr::<N>(&s.x), [0.0; N])
        }
        InitialState::Given { x, v } => (arr::<N>(x), arr::<N>(v)),
    };
    let sc = scales::<N>(m);
    let mut out = PccTrajectory {
        time: vec![],
        x: vec![],
        v: vec![],
        tip_position: vec![],
        tip_rotation: vec![],
        tip_velocity: vec![],
        pressure: vec![],
        energy: vec![],
        newton_iterations: 0,
        jacobian_evaluations: 0,
    };
    let save = |out: &mut PccTrajectory, k: usize, x: &[f64; N], v: &[f64; N]| {
        let (e, (p, r), tip_v) = m.observe(x, v, row(k));
        out.tip_velocity.push(tip_v);
        out.pressure.push(row(k).to_vec());
        out.time.push(k as f64 * dt);
        out.x.push(x.to_vec());
        out.v.push(v.to_vec());
        out.tip_position.push(p);
        out.tip_rotation.push(r);
        out.energy.push(e.kinetic + e.gravity + e.elastic);
    };
    let (mut x, mut v) = (x0, v0);
    let mut newton = NewtonMatrix::<N> {
        jac: None,
        evaluations: 0,
        age: 0,
    };
    let mut accel = [0.0; N];
    // The last four midpoint velocities, oldest first, and how many are known.
    let mut hist = [[0.0; N]; 4];
    let mut known = 0;
    save(&mut out, 0, &x, &v);
    for k in 0..n_steps {
        let pm: Vec<f64> = row(k)
            .iter()
            .zip(row(k + 1))
            .map(|(a, b)| 0.5 * (a + b))
            .collect();
        // Guess: the cubic predictor once four steps are known; before, the velocity with
        // half a step of the last step's acceleration.
        let simple: [f64; N] = std::array::from_fn(|i| v[i] + 0.5 * dt * accel[i]);
        let guess = if known >= 4 {
            extrapolate(&hist)
        } else {
            simple
        };
        if newton.age >= MAX_AGE {
            newton.jac = None;
        }
        newton.age += 1;
        let mut res = step_n::<N>(m, &x, &v, guess, &pm, dt, opts, &sc, &mut newton);
        if res.is_err() && known >= 4 {
            // Safety net: retry from the simple guess with a fresh Newton matrix.
            newton.jac = None;
            res = step_n::<N>(m, &x, &v, simple, &pm, dt, opts, &sc, &mut newton);
        }
        match res {
            Ok((x1, v1, it)) => {
                accel = std::array::from_fn(|i| (v1[i] - v[i]) / dt);
                hist.rotate_left(1);
                hist[3] = std::array::from_fn(|i| 0.5 * (v1[i] + v[i]));
                known += 1;
                x = x1;
                v = v1;
                out.newton_iterations += it;
            }
            Err(res) => {
                return Err(SoftrodError::NotConverged {
                    iterations: opts.max_iter,
                    residual: res,
                    load_factor: (k as f64 + 1.0) / n_steps as f64,
                    reason: format!(
                        "PCC implicit midpoint step {} (t = {:.6} s) did not converge; try a smaller dt",
                        k + 1,
                        (k + 1) as f64 * dt
                    ),
                });
            }
        }
        if m.segments().any(|(_, o, _)| x[o] <= 0.0) {
            return Err(SoftrodError::NotConverged {
                iterations: out.newton_iterations,
                residual: f64::NAN,
                load_factor: (k as f64 + 1.0) / n_steps as f64,
                reason: format!(
                    "a segment length became <= 0 at t = {:.6} s",
                    (k + 1) as f64 * dt
                ),
            });
        }
        if (k + 1) % save_every == 0 || k + 1 == n_steps {
            save(&mut out, k + 1, &x, &v);
        }
    }
    out.jacobian_evaluations = newton.evaluations;
    Ok(out)
}

fn forces_n<const N: usize>(
    m: &PccModel,
    x: &[f64],
    v: &[f64],
    a: &[f64],
    p: &[f64],
) -> Result<[Vec<f64>; 4]> {
    let f = m.forces(&arr::<N>(x), &arr::<N>(v), &arr::<N>(a), p);
    Ok([
        f.inertial.to_vec(),
        f.external.to_vec(),
        f.pressure.to_vec(),
        f.viscoelastic.to_vec(),
    ])
}

fn mass_n<const N: usize>(m: &PccModel, x: &[f64]) -> Result<Vec<Vec<f64>>> {
    Ok(m.mass_matrix_n(&arr::<N>(x))
        .iter()
        .map(|r| r.to_vec())
        .collect())
}

fn energy_dispatch<const N: usize>(
    m: &PccModel,
    x: &[f64],
    v: &[f64],
    p: &[f64],
) -> Result<Energy> {
    Ok(m.energy_n(&arr::<N>(x), &arr::<N>(v), p))
}

impl PccModel {
    fn check_len(&self, field: &str, x: &[f64]) -> Result<()> {
        if x.len() != self.ndof {
            return Err(SoftrodError::invalid(
                field,
                format!("{} values", x.len()),
                format!("the PCC model has {} coordinates", self.ndof),
            ));
        }
        for (i, z) in x.iter().enumerate() {
            if !z.is_finite() {
                return Err(SoftrodError::invalid(
                    format!("{field}[{i}]"),
                    z,
                    "must be a finite number",
                ));
            }
        }
        Ok(())
    }

    /// The generalised forces [inertial, external, pressure, visco-elastic] at (x, v, a).
    pub fn force_terms(&self, x: &[f64], v: &[f64], a: &[f64], p: &[f64]) -> Result<[Vec<f64>; 4]> {
        self.check_len("x", x)?;
        self.check_len("v", v)?;
        self.check_len("a", a)?;
        self.check_pressures(p)?;
        dispatch!(self.ndof, forces_n(self, x, v, a, p))
    }

    /// Mass matrix M(x).
    pub fn mass_matrix(&self, x: &[f64]) -> Result<Vec<Vec<f64>>> {
        self.check_len("x", x)?;
        dispatch!(self.ndof, mass_n(self, x))
    }

    /// Energies at (x, v) under constant pressures p.
    pub fn energy(&self, x: &[f64], v: &[f64], p: &[f64]) -> Result<Energy> {
        self.check_len("x", x)?;
        self.check_len("v", v)?;
        self.check_pressures(p)?;
        dispatch!(self.ndof, energy_dispatch(self, x, v, p))
    }

    /// Pose of the tip (the end of the last section).
    pub fn tip_pose(&self, x: &[f64]) -> Pose<f64> {
        self.walk(x, None, |_, _| {})
    }

    /// Tip velocity at model coordinates and rates (x, v), m/s: the tip position's
    /// derivative along v, exact with one dual-number walk.
    pub fn tip_velocity(&self, x: &[f64], v: &[f64]) -> [f64; 3] {
        let xd: Vec<Grad<f64, 1>> = x
            .iter()
            .zip(v)
            .map(|(&a, &b)| Grad { re: a, eps: [b] })
            .collect();
        let (p, _) = self.walk_parts(&xd, None, |_| false, |_, _, _| {});
        p.map(|c| c.eps[0])
    }

    /// The shape sampled at `per_link` + 1 points along every section: reference arc
    /// length s, positions and rotations (rows of [d1 d2 d3]).
    pub fn shape(&self, x: &[f64], per_link: usize) -> Result<Shape> {
        self.check_len("x", x)?;
        if per_link == 0 {
            return Err(SoftrodError::invalid(
                "n_points",
                per_link,
                "need at least one interval per section",
            ));
        }
        let sig: Vec<f64> = (0..per_link).map(|j| j as f64 / per_link as f64).collect();
        let starts: Vec<f64> = self
            .links
            .iter()
            .scan(0.0, |acc, l| {
                let s = *acc;
                *acc += l.length;
                Some(s)
            })
            .collect();
        let (mut s, mut p, mut r) = (vec![], vec![], vec![]);
        let tip = self.walk(x, Some(&sig), |site, pose| {
            if let super::lagrangian::Site::Node { link, weight } = site {
                s.push(starts[link] + weight * self.links[link].length);
                p.push(pose.0);
                r.push(pose.1);
            }
        });
        s.push(self.length());
        p.push(tip.0);
        r.push(tip.1);
        Ok((s, p, r))
    }

    /// Static equilibrium under pressures p, from `guess` (default: the rest configuration).
    pub fn solve_statics(
        &self,
        p: &[f64],
        guess: Option<&[f64]>,
        opts: &StepOptions,
    ) -> Result<PccStatic> {
        self.check_pressures(p)?;
        let rest = self.rest();
        let g = guess.unwrap_or(&rest);
        self.check_len("guess", g)?;
        dispatch!(self.ndof, statics_n(self, p, g, opts))
    }

    /// Simulate with time step dt under commanded pressures sampled at every step time
    /// (row-major, (n_steps + 1) x n_channels, Pa), passed through the design's pressure
    /// supply (`[dynamics]` lag and rate limit; none by default); saves every `save_every`
    /// steps and the last.
    pub fn simulate(
        &self,
        dt: f64,
        pressures: &[f64],
        initial: &InitialState,
        save_every: usize,
        opts: &StepOptions,
    ) -> Result<PccTrajectory> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(SoftrodError::invalid(
                "dt",
                dt,
                "must be a finite time step > 0 s",
            ));
        }
        if save_every == 0 {
            return Err(SoftrodError::invalid("save_every", 0, "must be >= 1"));
        }
        let nc = self.n_channels.max(1);
        if self.n_channels == 0 || pressures.len() % nc != 0 || pressures.len() < nc {
            return Err(SoftrodError::invalid(
                "pressures",
                format!("{} values", pressures.len()),
                format!(
                    "give an array of shape (n_steps + 1, {}) with the chamber pressures (Pa) at every step time",
                    self.n_channels
                ),
            ));
        }
        let rows = pressures.len() / nc;
        for k in 0..rows {
            self.check_pressures(&pressures[k * nc..(k + 1) * nc])
                .map_err(|e| match e {
                    SoftrodError::InvalidParameter { field, value, rule } => {
                        SoftrodError::invalid(format!("{field} (row {k})"), value, rule)
                    }
                    other => other,
                })?;
        }
        if let InitialState::Given { x, v } = initial {
            self.check_len("initial.q", x)?;
            self.check_len("initial.q_dot", v)?;
            if self.segments().any(|(_, o, _)| x[o] <= 0.0) {
                return Err(SoftrodError::invalid(
                    "initial.q",
                    format!("{x:?}"),
                    "segment lengths L must be > 0",
                ));
            }
        }
        // The chamber pressures follow the commands through the design's supply (lag and
        // rate limit, as in the rod's dynamics), starting at the first command.
        let mut applied = pressures.to_vec();
        for k in 1..rows {
            let (done, rest) = applied.split_at_mut(k * nc);
            let now = &mut rest[..nc];
            let command = now.to_vec();
            now.copy_from_slice(&done[(k - 1) * nc..]);
            self.supply.advance_supply(dt, now, &command);
        }
        dispatch!(
            self.ndof,
            simulate_n(self, dt, &applied, rows - 1, initial, save_every, opts)
        )
    }
}
