//! The fast paths of the PCC model (paper 003) against the direct ones:
//!
//! - `forces` evaluates each link's mass points in the link's own frame and projects their
//!   sums on the earlier coordinates; `forces_direct` evaluates every point in world
//!   coordinates with the gradient over all coordinates. Same numbers to round-off, for
//!   chains with rigid links, rotary inertia, line forces and moments, a tilted base, the
//!   planar model and both pressure models, in f64 and in the Jacobian's dual numbers.
//! - `static_forces` (value and gradient only, no time derivatives) equals `forces` at
//!   v = a = 0.
//! - The exact Jacobians (statics: `static_forces` on vector duals; dynamics: `forces` on
//!   vector duals over x, v and a) against central finite differences.
//! - Statics with a kept Newton matrix converges to the full-Newton solution, and time
//!   stepping with the cubic predictor (mostly one Newton update per step) stays within
//!   Newton's tolerance of a run with a 100x tighter tolerance.

// Index loops over coordinates read like the equations they check.
#![allow(clippy::needless_range_loop)]

use crate::common;

use common::{chamber, design, direct_section, rigid_section, tilted, Lcg, IDENTITY};
use softrod_core::pcc::jet::Grad;
use softrod_core::pcc::lagrangian::Forces;
use softrod_core::pcc::{InitialState, PccModel, PccSpec, PressureModel, StepOptions};
use softrod_core::spec::{DesignSpec, LineLoadSpec};

/// Same forces by two evaluation orders: sums of a few hundred products of O(1) numbers
/// (relative to the part's largest entry); measured up to 2e-15, so 1e-12 leaves room for
/// other platforms' rounding and still catches any wrong term above 1e-12 of a part.
const SAME_TOL: f64 = 1e-12;
/// Central differences with h = 1e-6 (relative): truncation h^2 ~ 1e-12, round-off
/// eps |r| / h ~ 2e-9 for residuals up to ~10 N (accelerations up to 20 1/s^2 below);
/// measured up to 2.2e-8 of the column's norm (at least 1e-3 of the Jacobian's largest
/// entry), so 1e-7 leaves a 4x margin and still catches any wrong or missing derivative
/// term larger than 1e-7 of its column.
const FD_TOL: f64 = 1e-7;
const FD_STEP: f64 = 1e-6;
/// The residual is quadratic in v and linear in a, so central differences are exact there
/// up to round-off, and a large step keeps the round-off (eps |r| / h, with |r| up to
/// ~10 N against mass-matrix columns of ~1e-4 kg m) small.
const FD_STEP_RATES: f64 = 1e-2;
/// Statics with a kept Newton matrix vs three more full-Newton iterations from its
/// solution: it stops when its last update is below 1e-11 of the scale (L0, 1 rad) and
/// contracts by at least 10x per update, so it is within ~1e-12; 1e-10 is 10x Newton's own
/// tolerance.
const STATICS_TOL: f64 = 1e-10;
/// Time stepping at tol = 1e-11 vs tol = 1e-13 over 500 steps of 1 ms: each step keeps an
/// error below the contraction (<= 0.05) times its last update (<= 1e-11 of the scale), and
/// the damped arm does not amplify it: measured 1.2e-11 of the scale; 1e-9 bounds 500
/// steps' worth of 1e-11 plus margin.
const TRAJ_TOL: f64 = 1e-9;

fn line_load(section: usize, f: [f64; 3], m: [f64; 3]) -> LineLoadSpec {
    LineLoadSpec {
        frame: Default::default(),
        section,
        force_per_length: f,
        moment_per_length: m,
    }
}

/// Cap, segment, rigid joint, segment, segment: every kind of link, rotary inertia, line
/// force and moment on the middle segment, tip body with offset and inertia, tip force and
/// moment, tilted base.
fn chain(model: PressureModel) -> DesignSpec {
    let mut segs = vec![];
    for (k, (len, ang)) in [(0.05, 0.0), (0.04, 90.0), (0.06, 200.0)]
        .iter()
        .enumerate()
    {
        let mut s = direct_section(&format!("s{k}"), *len, 27.0, 9.0, 6.6e-3, 4.4e-3, 0.03, 8);
        s.chambers = vec![
            chamber(2.5e-3, 7e-3, *ang, k),
            chamber(2.5e-3, 7e-3, ang + 150.0, 3),
        ];
        s.rotary_inertia = Some([2e-6 * (k as f64 + 1.0), 3e-6, 4e-6]);
        segs.push(s);
    }
    let mut cap = rigid_section("cap", 0.01, 0.005);
    cap.rotary_inertia = Some([1e-6, 1e-6, 2e-6]);
    let mut sections = vec![cap, segs.remove(0), rigid_section("joint", 0.008, 0.004)];
    sections.extend(segs);
    let mut d = design(sections, tilted(), 9.81);
    d.loads = vec![line_load(3, [0.2, -0.1, 0.3], [0.01, 0.02, -0.015])];
    d.tip.mass = 0.01;
    d.tip.com_offset = [0.002, -0.001, 0.005];
    d.tip.inertia = [2e-6, 3e-6, 1e-6];
    d.tip.force = [0.05, 0.02, -0.03];
    d.tip.moment = [0.002, -0.001, 0.003];
    d.pcc = Some(PccSpec {
        pressure_force: model,
        quadrature: 5,
        ..Default::default()
    });
    d
}

/// Two planar segments (bending plane at 0.4 rad) with a joint between them.
fn planar_chain() -> DesignSpec {
    let mut a = direct_section("a", 0.05, 27.0, 9.0, 6.6e-3, 4.4e-3, 0.03, 8);
    a.chambers = vec![chamber(2.5e-3, 7e-3, 20.0, 0)];
    a.rotary_inertia = Some([2e-6, 3e-6, 4e-6]);
    let mut b = direct_section("b", 0.06, 20.0, 9.0, 5.0e-3, 4.4e-3, 0.03, 8);
    b.chambers = vec![chamber(2.5e-3, 7e-3, 200.0, 1)];
    let mut d = design(
        vec![a, rigid_section("joint", 0.008, 0.005), b],
        IDENTITY,
        9.81,
    );
    d.loads = vec![line_load(2, [0.0, 0.1, 0.0], [0.0, 0.0, 0.01])];
    d.tip.mass = 0.01;
    d.pcc = Some(PccSpec {
        plane: Some(0.4),
        ..Default::default()
    });
    d
}

/// One segment as in the bundled arm (three chambers), upright with a rigid cap.
fn single() -> DesignSpec {
    let mut body = direct_section("body", 0.11, 27.06, 9.02, 6.6e-3, 4.4e-3, 0.059, 16);
    body.outer_radius = Some(0.016);
    body.chambers = vec![
        chamber(4e-3, 9e-3, 0.0, 0),
        chamber(4e-3, 9e-3, 120.0, 1),
        chamber(4e-3, 9e-3, 240.0, 2),
    ];
    let mut d = design(vec![body, rigid_section("cap", 0.01, 0.01)], IDENTITY, 9.81);
    d.tip.mass = 0.005;
    d.pcc = Some(PccSpec {
        k_l: Some(246.0),
        b_l: Some(119.0),
        k_theta: Some(0.06),
        b_theta: Some(0.02),
        ..Default::default()
    });
    d
}

/// A configuration, rates and accelerations with bending up to ~1.5 rad per segment
/// (both branches of the series) and lengths within 30 % of the reference.
fn state<const N: usize>(m: &PccModel, rng: &mut Lcg) -> ([f64; N], [f64; N], [f64; N]) {
    let rest = m.rest();
    let x = std::array::from_fn(|i| {
        if rest[i] > 0.0 {
            rest[i] * (1.0 + 0.3 * rng.uniform())
        } else {
            1.5 * rng.uniform()
        }
    });
    let v = std::array::from_fn(|_| 2.0 * rng.uniform());
    let a = std::array::from_fn(|_| 20.0 * rng.uniform());
    (x, v, a)
}

fn parts<D: Copy, const N: usize>(f: &Forces<D, N>) -> [[D; N]; 4] {
    [f.inertial, f.external, f.pressure, f.viscoelastic]
}

fn assert_same<const N: usize>(what: &str, a: &[[f64; N]; 4], b: &[[f64; N]; 4]) -> f64 {
    let mut worst: f64 = 0.0;
    for (k, (pa, pb)) in a.iter().zip(b).enumerate() {
        let scale = pb.iter().fold(1e-3f64, |s, z| s.max(z.abs()));
        for i in 0..N {
            let e = (pa[i] - pb[i]).abs() / scale;
            worst = worst.max(e);
            assert!(
                e <= SAME_TOL,
                "{what}: part {k}[{i}] {} vs {}",
                pa[i],
                pb[i]
            );
        }
    }
    worst
}

fn split_vs_direct<const N: usize>(name: &str, d: &DesignSpec, seed: u64) {
    let m = PccModel::new(d).unwrap();
    assert_eq!(m.ndof, N);
    let p: Vec<f64> = (0..m.n_channels).map(|k| 3e4 * (k as f64 + 1.0)).collect();
    let mut rng = Lcg(seed);
    let mut worst: f64 = 0.0;
    for _ in 0..4 {
        let (x, v, a) = state::<N>(&m, &mut rng);
        let fast = parts(&m.forces(&x, &v, &a, &p));
        let direct = parts(&m.forces_direct(&x, &v, &a, &p));
        worst = worst.max(assert_same(name, &fast, &direct));
        // In the Jacobian's scalar (vector duals over x): values and every derivative.
        let xd: [Grad<f64, N>; N] = std::array::from_fn(|i| Grad::variable(x[i], i));
        let vd = v.map(Grad::<f64, N>::from);
        let ad = a.map(Grad::<f64, N>::from);
        let fast = parts(&m.forces(&xd, &vd, &ad, &p));
        let direct = parts(&m.forces_direct(&xd, &vd, &ad, &p));
        for j in 0..N {
            let col = |f: &[[Grad<f64, N>; N]; 4]| f.map(|q| q.map(|g| g.eps[j]));
            worst = worst.max(assert_same(name, &col(&fast), &col(&direct)));
        }
        // Statics: no time derivatives, no inertial term.
        let st = parts(&m.static_forces(&x, &p));
        let zero = [0.0; N];
        let at_rest = parts(&m.forces(&x, &zero, &zero, &p));
        assert!(at_rest[0].iter().all(|&z| z == 0.0) && st[0].iter().all(|&z| z == 0.0));
        worst = worst.max(assert_same(name, &st, &at_rest));
    }
    println!("{name}: largest relative difference {worst:.1e}");
}

#[test]
fn link_frame_forces_equal_direct_forces() {
    split_vs_direct::<9>("chain, chamber", &chain(PressureModel::Chamber), 1);
    split_vs_direct::<9>("chain, tip_force", &chain(PressureModel::TipForce), 2);
    split_vs_direct::<4>("planar chain", &planar_chain(), 3);
    split_vs_direct::<3>("single", &single(), 4);
}

/// Exact Jacobian columns (from `f` on vector duals) against central differences of `g`.
fn check_fd<const N: usize>(
    what: &str,
    step: f64,
    z: &[f64; N],
    exact: &[[f64; N]; N],
    g: impl Fn(&[f64; N]) -> [f64; N],
) -> f64 {
    let big = exact.iter().flatten().fold(0.0f64, |s, e| s.max(e.abs()));
    let mut worst: f64 = 0.0;
    for j in 0..N {
        let h = step * z[j].abs().max(1.0);
        let (mut zp, mut zm) = (*z, *z);
        zp[j] += h;
        zm[j] -= h;
        let (rp, rm) = (g(&zp), g(&zm));
        let norm = (0..N).fold(1e-3 * big, |s, i| s.max(exact[i][j].abs()));
        for i in 0..N {
            let fd = (rp[i] - rm[i]) / (2.0 * h);
            let e = (exact[i][j] - fd).abs() / norm;
            worst = worst.max(e);
            assert!(
                e <= FD_TOL,
                "{what}: d r[{i}] / d z[{j}] = {} vs {fd}",
                exact[i][j]
            );
        }
    }
    worst
}

fn jacobians_vs_fd<const N: usize>(name: &str, d: &DesignSpec, seed: u64) {
    let m = PccModel::new(d).unwrap();
    let p: Vec<f64> = (0..m.n_channels).map(|k| 2e4 * (k as f64 + 1.0)).collect();
    let mut rng = Lcg(seed);
    let mut worst: f64 = 0.0;
    let var =
        |z: &[f64; N]| -> [Grad<f64, N>; N] { std::array::from_fn(|i| Grad::variable(z[i], i)) };
    let cst = |z: &[f64; N]| -> [Grad<f64, N>; N] { z.map(Grad::from) };
    let jac = |r: [Grad<f64, N>; N]| -> [[f64; N]; N] { r.map(|g| g.eps) };
    for _ in 0..3 {
        let (x, v, a) = state::<N>(&m, &mut rng);
        // Statics: d Q / d x.
        let exact = jac(m.static_forces(&var(&x), &p).residual());
        let st = |z: &[f64; N]| m.static_forces(z, &p).residual();
        worst = worst.max(check_fd(name, FD_STEP, &x, &exact, st));
        // Dynamics: the residual M a + C v - Q with respect to x, v and a.
        let exact = jac(m.forces(&var(&x), &cst(&v), &cst(&a), &p).residual());
        let rx = |z: &[f64; N]| m.forces(z, &v, &a, &p).residual();
        worst = worst.max(check_fd(name, FD_STEP, &x, &exact, rx));
        let exact = jac(m.forces(&cst(&x), &var(&v), &cst(&a), &p).residual());
        let rv = |z: &[f64; N]| m.forces(&x, z, &a, &p).residual();
        worst = worst.max(check_fd(name, FD_STEP_RATES, &v, &exact, rv));
        let exact = jac(m.forces(&cst(&x), &cst(&v), &var(&a), &p).residual());
        let ra = |z: &[f64; N]| m.forces(&x, &v, z, &p).residual();
        worst = worst.max(check_fd(name, FD_STEP_RATES, &a, &exact, ra));
    }
    println!("{name}: largest column error {worst:.1e}");
}

#[test]
fn exact_jacobians_match_finite_differences() {
    jacobians_vs_fd::<9>("chain, chamber", &chain(PressureModel::Chamber), 5);
    jacobians_vs_fd::<9>("chain, tip_force", &chain(PressureModel::TipForce), 6);
    jacobians_vs_fd::<4>("planar chain", &planar_chain(), 7);
    jacobians_vs_fd::<3>("single", &single(), 8);
}

/// Full Newton (fresh exact Jacobian every iteration) from `x`, three iterations.
fn polish<const N: usize>(m: &PccModel, x: &[f64], p: &[f64]) -> [f64; N] {
    let mut x: [f64; N] = std::array::from_fn(|i| x[i]);
    for _ in 0..3 {
        let xd: [Grad<f64, N>; N] = std::array::from_fn(|i| Grad::variable(x[i], i));
        let r = m.static_forces(&xd, p).residual();
        let a = nalgebra::DMatrix::<f64>::from_fn(N, N, |i, j| r[i].eps[j]);
        let b = nalgebra::DVector::<f64>::from_fn(N, |i, _| r[i].re);
        let dx = a.lu().solve(&b).expect("regular Jacobian");
        for i in 0..N {
            x[i] -= dx[i];
        }
    }
    x
}

fn statics_converged<const N: usize>(name: &str, d: &DesignSpec, pressures: &[Vec<f64>]) {
    let m = PccModel::new(d).unwrap();
    let rest = m.rest();
    for p in pressures {
        let s = m.solve_statics(p, None, &StepOptions::default()).unwrap();
        let x: [f64; N] = polish(&m, &s.x, p);
        for i in 0..N {
            let sc = if rest[i] > 0.0 { rest[i] } else { 1.0 };
            assert!(
                (s.x[i] - x[i]).abs() <= STATICS_TOL * sc,
                "{name} at {p:?}: x[{i}] {} vs full Newton {}",
                s.x[i],
                x[i]
            );
        }
    }
}

#[test]
fn statics_with_kept_newton_matrix_converges_to_full_newton() {
    let ps = |n: usize, levels: &[[f64; 4]]| -> Vec<Vec<f64>> {
        levels.iter().map(|l| l[..n].to_vec()).collect()
    };
    let levels = [
        [0.0; 4],
        [5e4, 0.0, 0.0, 0.0],
        [1.5e5, 1.5e5, 0.0, 0.0],
        [3e4, 1e4, 5e4, 2e4],
    ];
    statics_converged::<9>("chain", &chain(PressureModel::Chamber), &ps(4, &levels));
    statics_converged::<4>("planar chain", &planar_chain(), &ps(2, &levels));
    statics_converged::<3>("single", &single(), &ps(3, &levels));
}

#[test]
fn predictor_steps_stay_within_newton_tolerance() {
    // 0.5 s of 1 ms steps: a pressure ramp to 1 bar on one chamber, then a hold.
    let m = PccModel::new(&single()).unwrap();
    let dt = 1e-3;
    let rows = 501;
    let p: Vec<f64> = (0..rows)
        .flat_map(|k| {
            let t = k as f64 * dt;
            [1e5 * (t / 0.2).min(1.0), 2e4 * (t / 0.3).min(1.0), 0.0]
        })
        .collect();
    let run = |tol: f64| {
        let opts = StepOptions { tol, max_iter: 30 };
        m.simulate(dt, &p, &InitialState::Rest, 1, &opts).unwrap()
    };
    let (a, b) = (run(1e-11), run(1e-13));
    let rest = m.rest();
    let mut worst: f64 = 0.0;
    for (xa, xb) in a.x.iter().zip(&b.x) {
        for i in 0..3 {
            let sc = if rest[i] > 0.0 { rest[i] } else { 1.0 };
            worst = worst.max((xa[i] - xb[i]).abs() / sc);
        }
    }
    println!(
        "largest difference {worst:.1e} of the scale; {:.2} Newton iterations per step",
        a.newton_iterations as f64 / (rows - 1) as f64
    );
    assert!(worst <= TRAJ_TOL, "{worst}");
    assert!(
        a.x[rows - 1][1].hypot(a.x[rows - 1][2]) > 0.1,
        "the arm bends"
    );
}
