//! Static equilibrium by shooting (docs/model.md, "Solver"; paper 001 section II-D).
//!
//! All loads are dead (gravity, dead tip and line loads, the tip body's weight), so the force
//! balance n' = -f is statically determinate: n(0) = F_tip + m_t g + int_0^L f ds exactly,
//! and only the base moment m(0) is unknown (3 unknowns instead of the usual 6). It is
//! scaled by M_s = F_s L with F_s = EI_min / L^2. Residual: the tip moment balance
//! m(L) = M_tip + (R(L) c) x (m_t g), scaled the same way; n(L) = F_tip + m_t g holds by
//! construction. Newton with the exact Jacobian from forward-mode dual numbers (one
//! integration in `Jet<3>` gives residual and Jacobian), a backtracking line search, a
//! Levenberg-Marquardt fallback when the Jacobian is singular, and automatic load
//! continuation (ramping pressures, gravity and loads together) when Newton fails from
//! the initial guess.

use crate::error::{Result, SoftrodError};
use crate::jet::{Jet, RodScalar};
use crate::ode::{integrate, strains, Coeffs, Loads, State};
use crate::rod::Rod;
use nalgebra::{Matrix3, Vector3};

/// Solver settings (a validated value object with defaults).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverOptions {
    /// Convergence tolerance on the scaled residual (infinity norm), relative to
    /// max(1, |x|_inf). 1e-10 puts the tip-wrench error far below what moves the tip
    /// by 1e-9 of the length.
    pub tol: f64,
    /// Newton iterations per load level.
    pub max_iter: usize,
    /// Ramp loads from zero when Newton fails from the initial guess.
    pub continuation: bool,
    /// Most load levels continuation may take.
    pub max_load_steps: usize,
}

impl Default for SolverOptions {
    fn default() -> Self {
        SolverOptions {
            tol: 1e-10,
            max_iter: 25,
            continuation: true,
            max_load_steps: 200,
        }
    }
}

impl SolverOptions {
    pub fn validate(&self) -> Result<()> {
        if !(self.tol.is_finite() && self.tol > 0.0 && self.tol < 1.0) {
            return Err(SoftrodError::invalid("tol", self.tol, "must be in (0, 1)"));
        }
        if self.max_iter == 0 {
            return Err(SoftrodError::invalid(
                "max_iter",
                self.max_iter,
                "must be >= 1",
            ));
        }
        if self.max_load_steps == 0 {
            return Err(SoftrodError::invalid(
                "max_load_steps",
                self.max_load_steps,
                "must be >= 1",
            ));
        }
        Ok(())
    }
}

/// A converged static equilibrium (the shape is recovered with [`shape`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// Scaled shooting unknowns m(0)/(F_s L); reuse as a warm start.
    pub x: [f64; 3],
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
    /// Load levels used (1 without continuation).
    pub load_steps: usize,
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

/// One load level of one problem: coefficients and scales.
pub(crate) struct Problem<'a> {
    rod: &'a Rod,
    loads: &'a Loads,
    factor: f64,
    pub(crate) coeffs: Vec<Coeffs<f64>>,
    /// Base force, known exactly from the force balance.
    n0: [f64; 3],
    ms: f64,
}

fn inf_norm(r: &[f64; 3]) -> f64 {
    r.iter().fold(
        0.0,
        |a: f64, x| if x.is_nan() { f64::NAN } else { a.max(x.abs()) },
    )
}

impl<'a> Problem<'a> {
    pub(crate) fn new(rod: &'a Rod, loads: &'a Loads, factor: f64) -> Self {
        let coeffs = (0..rod.sections.len())
            .map(|i| {
                Coeffs::build(
                    rod,
                    i,
                    &loads.pressures,
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
            ms: rod.force_scale * rod.length,
        };
        let w = p.tip_weight();
        for k in 0..3 {
            p.n0[k] = factor * loads.tip_force[k] + w[k];
        }
        for (sec, c) in rod.sections.iter().zip(&p.coeffs) {
            for k in 0..3 {
                p.n0[k] += c.f[k] * sec.length;
            }
        }
        p
    }

    /// Tip-body weight (world), scaled by the load factor.
    fn tip_weight(&self) -> [f64; 3] {
        let mt = self.rod.spec.tip.mass;
        self.rod.gravity.map(|g| self.factor * mt * g)
    }

    pub(crate) fn base_state<D: RodScalar>(&self, x: &[D; 3]) -> State<D> {
        let c = |v: f64| D::from(v);
        State {
            r: self.rod.base_position.map(c),
            rot: self.rod.base_rotation.map(|row| row.map(c)),
            n: self.n0.map(c),
            m: [x[0] * self.ms, x[1] * self.ms, x[2] * self.ms],
            aux: [c(1.0), c(1.0)],
        }
    }

    pub(crate) fn residual_of_tip<D: RodScalar>(&self, tip: &State<D>) -> [D; 3] {
        let w = self.tip_weight();
        let com = self.rod.spec.tip.com_offset;
        // centre of mass offset in the world frame: R(L) c
        let mut cw = [D::from(0.0); 3];
        for (i, cwi) in cw.iter_mut().enumerate() {
            *cwi = tip.rot[i][0] * com[0] + tip.rot[i][1] * com[1] + tip.rot[i][2] * com[2];
        }
        let cxw = [
            cw[1] * w[2] - cw[2] * w[1],
            cw[2] * w[0] - cw[0] * w[2],
            cw[0] * w[1] - cw[1] * w[0],
        ];
        std::array::from_fn(|k| {
            (tip.m[k] - cxw[k] - self.factor * self.loads.tip_moment[k]) * (1.0 / self.ms)
        })
    }

    fn eval(&self, x: &[f64; 3]) -> [f64; 3] {
        let tip = integrate(self.rod, &self.coeffs, self.base_state(x), None);
        self.residual_of_tip(&tip)
    }

    /// Residual and exact Jacobian by forward-mode AD (3 directions).
    fn eval_jac(&self, x: &[f64; 3]) -> ([f64; 3], Matrix3<f64>) {
        let xd: [Jet<3>; 3] = std::array::from_fn(|i| Jet::variable(x[i], i));
        let tip = integrate(self.rod, &self.coeffs, self.base_state(&xd), None);
        let rd = self.residual_of_tip(&tip);
        let jac = Matrix3::from_fn(|i, j| rd[i].eps[j]);
        (rd.map(|r| r.re), jac)
    }

    /// Equilibrium of the straight, undeformed rod: a cheap cold-start guess.
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
        let mut n0 = f_tip;
        let mut int_n = f_tip.map(|f| f * self.rod.length);
        let mut l_tot = [0.0; 3];
        for (sec, c) in self.rod.sections.iter().zip(&self.coeffs) {
            let (a, b) = (sec.s_start, sec.s_start + sec.length);
            for k in 0..3 {
                n0[k] += c.f[k] * sec.length;
                int_n[k] += c.f[k] * 0.5 * (b * b - a * a);
                l_tot[k] += c.l[k] * sec.length;
            }
        }
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        // m(0) = M_tip + (c_w x W measured from the tip) + t x int n + int l, about the base
        let tip_arm = [
            cw[0] - t[0] * self.rod.length,
            cw[1] - t[1] * self.rod.length,
            cw[2] - t[2] * self.rod.length,
        ];
        let cxw = cross(tip_arm, w);
        let txn = cross(t, int_n);
        debug_assert!((0..3).all(|k| (n0[k] - self.n0[k]).abs() <= 1e-12 * (1.0 + n0[k].abs())));
        std::array::from_fn(|k| {
            (self.factor * self.loads.tip_moment[k] + cxw[k] + txn[k] + l_tot[k]) / self.ms
        })
    }

    /// Damped Newton from `x0`. Ok((x, residual, iterations)) or Err((iterations, residual)).
    ///
    /// Trial points are evaluated with the cheap f64 pass; the exact Jacobian (a dual pass,
    /// ~8x dearer) is refreshed only when the last step contracted the residual by less than
    /// `REUSE_CONTRACTION` (Shamanskii's variant of Newton's method). Near the solution the
    /// Jacobian barely changes, so this saves passes without changing what "converged" means.
    fn newton(
        &self,
        x0: [f64; 3],
        opts: &SolverOptions,
    ) -> std::result::Result<([f64; 3], f64, usize), (usize, f64)> {
        const REUSE_CONTRACTION: f64 = 0.05;
        let mut x = x0;
        let (mut r, mut jac) = self.eval_jac(&x);
        let mut norm = inf_norm(&r);
        if !norm.is_finite() {
            return Err((1, norm));
        }
        let mut fresh = true;
        for it in 0..opts.max_iter {
            let xmax = inf_norm(&x).max(1.0);
            if norm <= opts.tol * xmax {
                return Ok((x, norm, it + 1));
            }
            let rv = Vector3::from_column_slice(&r);
            let step = jac
                .lu()
                .solve(&(-rv))
                .filter(|d| d.iter().all(|v| v.is_finite()))
                .unwrap_or_else(|| {
                    // Levenberg-Marquardt step when J is singular.
                    let jt = jac.transpose();
                    let mut a = jt * jac;
                    let mu = 1e-6 * a.diagonal().max().max(1e-300);
                    for i in 0..3 {
                        a[(i, i)] += mu;
                    }
                    a.lu().solve(&(-(jt * rv))).unwrap_or_else(Vector3::zeros)
                });
            let r2 = rv.norm();
            let mut alpha = 1.0;
            let mut accepted = false;
            while alpha >= 1.0 / 1024.0 {
                let xt: [f64; 3] = std::array::from_fn(|i| x[i] + alpha * step[i]);
                let rt = self.eval(&xt);
                let r2t = Vector3::from_column_slice(&rt).norm();
                if r2t.is_finite() && r2t < (1.0 - 1e-4 * alpha) * r2 {
                    x = xt;
                    r = rt;
                    norm = inf_norm(&r);
                    accepted = true;
                    if r2t > REUSE_CONTRACTION * r2 || alpha < 1.0 {
                        (r, jac) = self.eval_jac(&x);
                        fresh = true;
                    } else {
                        fresh = false;
                    }
                    break;
                }
                if !fresh {
                    // A stale Jacobian may be the problem: refresh it and retry the full step.
                    (r, jac) = self.eval_jac(&x);
                    fresh = true;
                    break;
                }
                alpha *= 0.5;
            }
            if !accepted && fresh && alpha < 1.0 / 1024.0 {
                // Converged to round-off already? Accept if within 100x the tolerance.
                if norm <= 100.0 * opts.tol * xmax {
                    return Ok((x, norm, it + 1));
                }
                return Err((it + 1, norm));
            }
        }
        if norm <= opts.tol * inf_norm(&x).max(1.0) {
            Ok((x, norm, opts.max_iter))
        } else {
            Err((opts.max_iter, norm))
        }
    }
}

fn finish(
    p: &Problem,
    x: [f64; 3],
    residual: f64,
    iterations: usize,
    load_steps: usize,
) -> Solution {
    let y0 = p.base_state(&x);
    let tip = integrate(p.rod, &p.coeffs, y0, None);
    Solution {
        x,
        base_force: y0.n,
        base_moment: y0.m,
        tip,
        iterations,
        residual,
        load_steps,
    }
}

/// Solve the static equilibrium. `guess` is a previous solution's `x` (warm start).
pub fn solve(
    rod: &Rod,
    loads: &Loads,
    guess: Option<&[f64; 3]>,
    opts: &SolverOptions,
) -> Result<Solution> {
    opts.validate()?;
    rod.check_loads(&loads.pressures, &loads.stiffness_scale)?;
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
    let full = Problem::new(rod, loads, 1.0);
    let x0 = match guess {
        Some(g) if g.iter().all(|v| v.is_finite()) => *g,
        _ => full.straight_guess(),
    };
    let (mut iterations, mut last_res) = match full.newton(x0, opts) {
        Ok((x, res, it)) => return Ok(finish(&full, x, res, it, 1)),
        Err(failed) => failed,
    };
    if !opts.continuation {
        return Err(SoftrodError::NotConverged {
            iterations,
            residual: last_res,
            load_factor: 0.0,
            reason: "Newton failed from the initial guess and continuation is off".into(),
        });
    }
    // Load continuation from the unloaded straight rod (x = 0 solves it exactly).
    let mut lam = 0.0;
    let mut x = [0.0; 3];
    let mut prev: Option<(f64, [f64; 3])> = None;
    let mut dlam: f64 = 0.25;
    let mut levels = 0;
    while lam < 1.0 {
        if levels >= opts.max_load_steps {
            return Err(SoftrodError::NotConverged {
                iterations,
                residual: last_res,
                load_factor: lam,
                reason: format!(
                    "load continuation used all {} load steps",
                    opts.max_load_steps
                ),
            });
        }
        levels += 1;
        let target = (lam + dlam).min(1.0);
        let p = Problem::new(rod, loads, target);
        // Secant predictor from the last two converged levels.
        let guess: [f64; 3] = match prev {
            Some((lp, xp)) if lam > lp => {
                std::array::from_fn(|i| x[i] + (x[i] - xp[i]) * (target - lam) / (lam - lp))
            }
            _ => x,
        };
        match p.newton(guess, opts) {
            Ok((xn, res, it)) => {
                iterations += it;
                last_res = res;
                prev = Some((lam, x));
                x = xn;
                lam = target;
                if lam >= 1.0 {
                    return Ok(finish(&p, x, res, iterations, levels));
                }
                dlam = (dlam * 1.5).min(0.5);
            }
            Err((it, res)) => {
                iterations += it;
                last_res = res;
                dlam *= 0.5;
                if dlam < 1e-5 {
                    return Err(SoftrodError::NotConverged {
                        iterations,
                        residual: last_res,
                        load_factor: lam,
                        reason: "load step fell below 1e-5 (the load may exceed a limit point such as buckling)".into(),
                    });
                }
            }
        }
    }
    unreachable!("the continuation loop returns at load factor 1")
}

/// The shape of a converged solution at every integration node.
pub fn shape(rod: &Rod, loads: &Loads, sol: &Solution) -> Shape {
    let p = Problem::new(rod, loads, 1.0);
    let mut out = Shape::default();
    let mut visit = |i: usize, s: f64, y: &State<f64>| {
        let (v, u) = if rod.sections[i].rigid {
            ([0.0, 0.0, 1.0], [0.0; 3])
        } else {
            strains(y, &p.coeffs[i])
        };
        out.s.push(s);
        out.section.push(i);
        out.position.push(y.r);
        out.rotation.push(y.rot);
        out.force.push(y.n);
        out.moment.push(y.m);
        out.v.push(v);
        out.u.push(u);
    };
    integrate(rod, &p.coeffs, p.base_state(&sol.x), Some(&mut visit));
    out
}

/// Jacobian of the scaled tip-moment residual with respect to the scaled unknowns
/// x = m(0)/(F_s L) (exposed for tests against finite differences).
pub fn residual_and_jacobian(rod: &Rod, loads: &Loads, x: &[f64; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
    let p = Problem::new(rod, loads, 1.0);
    let (r, j) = p.eval_jac(x);
    (
        r,
        std::array::from_fn(|i| std::array::from_fn(|k| j[(i, k)])),
    )
}

/// Scaled tip-moment residual at `x` (f64 only).
pub fn residual(rod: &Rod, loads: &Loads, x: &[f64; 3]) -> [f64; 3] {
    Problem::new(rod, loads, 1.0).eval(x)
}
