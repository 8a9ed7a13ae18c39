//! The stability test (conjugate points and the tip form), the natural path of load
//! continuation, its exact tangent, and the validity rules of a returned solution.
//!
//! References are closed forms or independent computations: the Euler load of the
//! clamped-free column P_cr = pi^2 EI / (4 L^2); Greenhill's self-weight load
//! (q L^3 / EI)_cr = 7.8373 (Timoshenko & Gere, "Theory of Elastic Stability", 2nd ed.,
//! Sec. 2.10); the planar elastica under a tip load integrated here in its angle form.

use crate::common;
use common::*;
use softrod_core::ode::Loads;
use softrod_core::spec::{DesignSpec, OperatingRangeSpec};
use softrod_core::statics::{load_tangent, solve, SolverOptions};
use softrod_core::validity::{Policy, Rule};
use softrod_core::{Rod, SoftrodError};
use std::f64::consts::PI;

const L: f64 = 1.0;
const EI: f64 = 1.0;
/// Extension and shear 1e10 times stiffer than bending (EA L^2 / EI): the extensible rod's
/// tip moves less than 1e-9 L from the inextensible elastica's at these loads.
const STIFF: f64 = 1e10;

/// P_cr = pi^2 EI / (4 L^2) of the clamped-free column.
fn p_cr() -> f64 {
    PI * PI * EI / (4.0 * L * L)
}

/// An upright column (d3 = +z), clamped at the base, no gravity unless `line_mass` > 0.
fn column(steps: usize, line_mass: f64, g: f64) -> Rod {
    Rod::new(design(
        vec![direct_section(
            "column",
            L,
            STIFF,
            STIFF,
            EI,
            2.0 * EI,
            line_mass * L,
            steps,
        )],
        IDENTITY,
        g,
    ))
    .unwrap()
}

fn tip_loaded(force: [f64; 3]) -> Loads {
    let mut ld = loads(&[]);
    ld.tip_force = force;
    ld
}

fn opts() -> SolverOptions {
    SolverOptions {
        tol: 1e-12,
        ..Default::default()
    }
}

/// The straight column is stable below the Euler load and unstable above it: just above,
/// the tip form fails (kL just past pi/2); at 5 P_cr (kL = 3.51 > pi) the tip form is
/// positive again and only the conjugate point at kL = pi flags it. A round column
/// buckles in two planes at once (a double conjugate point, det Theta touching zero
/// without changing sign), which the test must still see.
#[test]
fn euler_column_changes_stability_at_the_buckling_load() {
    let rod = column(200, 0.0, 0.0);
    for (ratio, want) in [
        (0.5, true),
        (0.97, true),
        (1.03, false),
        (1.5, false),
        (2.0, false),
        (5.0, false),
    ] {
        let sol = solve(
            &rod,
            &tip_loaded([0.0, 0.0, -ratio * p_cr()]),
            None,
            &opts(),
        )
        .unwrap_or_else(|e| panic!("P = {ratio} P_cr: {e}"));
        // the perfect column has no reason to leave the straight branch
        assert!(
            sol.tip.r[0].abs() < 1e-12 && sol.tip.r[1].abs() < 1e-12,
            "P = {ratio} P_cr: tip {:?}",
            sol.tip.r
        );
        assert_eq!(sol.stable, Some(want), "P = {ratio} P_cr");
    }
}

/// Greenhill's heavy column: a straight upright column under its own weight buckles at
/// q L^3 / EI = 7.8373.
#[test]
fn heavy_column_changes_stability_at_greenhills_load() {
    const Q_CR: f64 = 7.8373;
    for (ratio, want) in [(0.97, true), (1.03, false)] {
        let q = ratio * Q_CR * EI / (L * L * L);
        let rod = column(200, q / 9.81, 9.81);
        let sol = solve(&rod, &loads(&[]), None, &opts()).unwrap();
        assert!(sol.tip.r[0].abs() < 1e-12, "tip {:?}", sol.tip.r);
        assert_eq!(sol.stable, Some(want), "q = {ratio} q_cr");
    }
}

/// The planar elastica under a dead tip load (H along +x, P down), angle form:
/// EI theta'' = -(H cos theta + P sin theta), theta(0) = 0, theta'(L) = 0, theta from +z
/// towards +x. Shooting on theta'(0) with classical RK4 at 20000 steps (error ~1e-15) and
/// bisection on the bracket [lo, hi] of theta'(0). Returns the tip (x, z).
fn elastica_tip(p: f64, h: f64, lo: f64, hi: f64) -> [f64; 2] {
    const N: usize = 20_000;
    let run = |k0: f64| -> ([f64; 2], f64) {
        let f = |y: [f64; 4]| {
            [
                y[1],
                -(h * y[0].cos() + p * y[0].sin()) / EI,
                y[0].sin(),
                y[0].cos(),
            ]
        };
        let mut y = [0.0, k0, 0.0, 0.0]; // theta, theta', x, z
        let dt = L / N as f64;
        for _ in 0..N {
            let k1 = f(y);
            let k2 = f(std::array::from_fn(|i| y[i] + 0.5 * dt * k1[i]));
            let k3 = f(std::array::from_fn(|i| y[i] + 0.5 * dt * k2[i]));
            let k4 = f(std::array::from_fn(|i| y[i] + dt * k3[i]));
            y = std::array::from_fn(|i| {
                y[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
            });
        }
        ([y[2], y[3]], y[1])
    };
    let (mut a, mut b) = (lo, hi);
    let fa = run(a).1;
    assert!(fa * run(b).1 < 0.0, "bracket [{lo}, {hi}] holds no root");
    for _ in 0..200 {
        let m = 0.5 * (a + b);
        if run(m).1 * fa > 0.0 {
            a = m;
        } else {
            b = m;
        }
        if b - a < 1e-15 {
            break;
        }
    }
    run(0.5 * (a + b)).0
}

/// Above the Euler load with a small lateral force, the cold start follows the natural path
/// (loads ramped from zero), which bends towards the force and stays stable, and agrees
/// with the elastica. Today's direct Newton from the straight guess went the other way.
#[test]
fn column_above_the_buckling_load_bends_with_the_lateral_force() {
    let rod = column(400, 0.0, 0.0);
    for ratio in [1.5, 2.0] {
        let p = ratio * p_cr();
        let h = 1e-3 * p;
        // the stable, with-force branch: theta'(0) > 0 and large (the buckled shape)
        let reference = elastica_tip(p, h, 0.05, 5.0);
        for (axis, sign) in [(0, 1.0), (0, -1.0), (1, 1.0)] {
            let mut f = [0.0, 0.0, -p];
            f[axis] = sign * h;
            let sol = solve(&rod, &tip_loaded(f), None, &opts()).unwrap();
            assert_eq!(
                sol.stable,
                Some(true),
                "P = {ratio} P_cr, force {f:?}: unstable"
            );
            let lateral = sol.tip.r[axis] * sign;
            assert!(
                lateral > 0.1 * L,
                "P = {ratio} P_cr, force {f:?}: tip {:?} does not deflect with the force",
                sol.tip.r
            );
            // 1e-6 L: the discretisation error of 400 RK4 steps (~1e-10 L) and the
            // extensibility (P / EA ~ 5e-10) are far below it.
            let err = (lateral - reference[0])
                .abs()
                .max((sol.tip.r[2] - reference[1]).abs());
            assert!(
                err < 1e-6 * L,
                "P = {ratio} P_cr, force {f:?}: tip {:?}, elastica {reference:?}, error {err:e}",
                sol.tip.r
            );
        }
    }
}

/// The exact load tangent dx/dlambda against central differences of converged solutions.
#[test]
fn load_tangent_matches_finite_differences() {
    let base = |g: f64| {
        let mut spec = p002_actuator(HORIZONTAL, g, 16);
        spec.tip = Default::default();
        Rod::new(spec).unwrap()
    };
    let rod = base(9.81);
    let mut ld = loads(&[40e3, 10e3, 0.0]);
    ld.tip_force = [0.0, 0.02, -0.03];
    ld.tip_moment = [1e-3, 0.0, 2e-4];
    let tight = SolverOptions {
        tol: 1e-14,
        ..Default::default()
    };
    // a solution at load factor lambda: scale every load (pressures, gravity through the
    // design, tip loads) by solving the problem whose loads are lambda times the loads.
    let scaled = |lam: f64| -> Vec<f64> {
        let rod = base(9.81 * lam);
        let mut l = ld.clone();
        l.pressures = ld.pressures.iter().map(|p| p * lam).collect();
        l.tip_force = ld.tip_force.map(|f| f * lam);
        l.tip_moment = ld.tip_moment.map(|m| m * lam);
        solve(&rod, &l, None, &tight).unwrap().x
    };
    let lam = 0.6;
    let x = scaled(lam);
    let (t, _, stable) = load_tangent(&rod, &ld, lam, &x).unwrap().unwrap();
    assert_eq!(stable, Some(true));
    let eps = 1e-5;
    let (xp, xm) = (scaled(lam + eps), scaled(lam - eps));
    for i in 0..3 {
        let fd = (xp[i] - xm[i]) / (2.0 * eps);
        // central differences: truncation ~eps^2 |x'''| ~1e-10, round-off ~1e-14 / eps
        assert!(
            (t[i] - fd).abs() < 1e-7 * (1.0 + fd.abs()),
            "component {i}: exact {} vs finite differences {fd}",
            t[i]
        );
    }
}

fn rule_of<T: std::fmt::Debug>(r: Result<T, SoftrodError>) -> (Rule, Option<usize>, f64) {
    match r {
        Err(SoftrodError::InvalidState {
            rule, node, value, ..
        }) => (rule, node, value),
        other => panic!("expected InvalidState, got {other:?}"),
    }
}

/// A soft column squeezed beyond zero length: the linear law would return v3 < 0 (the rod
/// turned inside out) and a tip below the base; the solve names the rule and the node.
#[test]
fn stretch_through_zero_is_an_error_naming_the_node() {
    // EA = 1 N, a 1.5 N compressive tip force: v3 = 1 - 1.5 = -0.5 if it stayed straight
    let rod = Rod::new(design(
        vec![direct_section("soft", 0.1, 1.0, 1.0, 1.0, 1.0, 0.0, 10)],
        IDENTITY,
        0.0,
    ))
    .unwrap();
    let (rule, node, value) = rule_of(solve(
        &rod,
        &tip_loaded([0.0, 0.0, -1.5]),
        None,
        &SolverOptions::default(),
    ));
    assert_eq!(rule, Rule::PositiveStretch);
    assert!(
        node.is_some() && value <= 0.0,
        "node {node:?}, value {value}"
    );
}

fn p002_with_range() -> DesignSpec {
    let mut spec = p002_actuator(IDENTITY, 9.81, 16);
    spec.operating_range = Some(OperatingRangeSpec {
        pressure: Some([0.0, 60e3]),
        tension: None,
    });
    spec
}

/// Pressures beyond the design's operating range: an error before any work with
/// `Policy::Raise` (the default), a listed violation with `Policy::Warn`, nothing with
/// `Policy::Ignore`.
#[test]
fn operating_range_is_checked_by_policy() {
    let rod = Rod::new(p002_with_range()).unwrap();
    let ok = solve(
        &rod,
        &loads(&[50e3, 0.0, 0.0]),
        None,
        &SolverOptions::default(),
    )
    .unwrap();
    assert!(ok.violations.is_empty() && ok.stable == Some(true));
    let (rule, node, value) = rule_of(solve(
        &rod,
        &loads(&[5e5, 0.0, 0.0]),
        None,
        &SolverOptions::default(),
    ));
    assert_eq!((rule, node, value), (Rule::OperatingRange, None, 5e5));
    let warn = SolverOptions {
        on_invalid: Policy::Warn,
        ..Default::default()
    };
    let sol = solve(&rod, &loads(&[0.0, 1e5, 0.0]), None, &warn).unwrap();
    assert_eq!(sol.violations.len(), 1, "{:?}", sol.violations);
    let ignore = SolverOptions {
        on_invalid: Policy::Ignore,
        ..Default::default()
    };
    assert!(solve(&rod, &loads(&[0.0, 1e5, 0.0]), None, &ignore)
        .unwrap()
        .violations
        .is_empty());
}

/// Absurd pressures (1e9 to 1e19 Pa on paper 002's actuator) never come back as a
/// converged shape: the strain range (or a physical rule, or non-convergence) stops them.
#[test]
fn absurd_pressures_never_converge_to_a_shape() {
    let rod = Rod::new(p002_actuator(IDENTITY, 9.81, 16)).unwrap();
    for p in [1e9, 1e12, 1e15, 1e19] {
        for ld in [loads(&[p, 0.0, 0.0]), loads(&[p, p, p])] {
            match solve(&rod, &ld, None, &SolverOptions::default()) {
                Err(SoftrodError::InvalidState { .. }) | Err(SoftrodError::NotConverged { .. }) => {
                }
                other => panic!("p = {p}: {other:?}"),
            }
        }
    }
    // not even when the validity ranges are not checked: the stretch limit is physical
    let ignore = SolverOptions {
        on_invalid: Policy::Ignore,
        ..Default::default()
    };
    for p in [1e9, 1e12, 1e19] {
        match solve(&rod, &loads(&[p, p, p]), None, &ignore) {
            Err(SoftrodError::InvalidState { rule, .. }) => {
                assert!(rule.is_physical(), "p = {p}: {rule:?}")
            }
            Err(SoftrodError::NotConverged { .. }) => {}
            other => panic!("p = {p}: {other:?}"),
        }
    }
    // and within the range a strong pressure gives a stretch inside the validity range
    // or the named rule
    let warn = SolverOptions {
        on_invalid: Policy::Warn,
        ..Default::default()
    };
    let sol = solve(&rod, &loads(&[1e6, 1e6, 1e6]), None, &warn);
    match sol {
        Ok(s) => assert!(
            s.violations.iter().all(|e| matches!(
                e,
                SoftrodError::InvalidState {
                    rule: Rule::StrainRange,
                    ..
                }
            )),
            "{:?}",
            s.violations
        ),
        Err(SoftrodError::InvalidState { .. }) | Err(SoftrodError::NotConverged { .. }) => {}
        Err(e) => panic!("{e}"),
    }
}

/// One RK4 step over a long, strongly bent section cannot represent the rotation: the
/// result is refused by the rotation rule (or fails to converge), never returned.
#[test]
fn too_coarse_steps_break_the_rotation_rule() {
    let rod = Rod::new(design(
        vec![direct_section("coarse", 1.0, 1e6, 1e6, 1.0, 1.0, 0.0, 1)],
        HORIZONTAL,
        0.0,
    ))
    .unwrap();
    let mut ld = loads(&[]);
    ld.tip_moment = [0.0, 1.5, 0.0]; // u = 1.5 rad over one step
    match solve(&rod, &ld, None, &SolverOptions::default()) {
        Err(SoftrodError::InvalidState { rule, .. }) => assert_eq!(rule, Rule::Rotation),
        Err(SoftrodError::NotConverged { .. }) => {}
        Ok(s) => panic!(
            "one step of 1.5 rad returned as a solution: tip {:?}",
            s.tip.r
        ),
        Err(e) => panic!("{e}"),
    }
    // the same with 64 steps is a valid, stable solution
    let fine = Rod::new(design(
        vec![direct_section("fine", 1.0, 1e6, 1e6, 1.0, 1.0, 0.0, 64)],
        HORIZONTAL,
        0.0,
    ))
    .unwrap();
    assert_eq!(
        solve(&fine, &ld, None, &SolverOptions::default())
            .unwrap()
            .stable,
        Some(true)
    );
}

/// Issue 14's soft cantilever (0.22 m, r 12.5 mm, E 100 kPa, nu 0.5, 1000 kg/m^3, clamped
/// horizontally, 20 steps; its tip sags by 0.88 L): the tangent predicts the first load
/// step well, so that step is lengthened and the cold solve takes 2 load levels (3 with the
/// first step at its trial reach), and it lands on the equilibrium that a gentle path
/// reaches: gravity raised in eighths, each Newton solve warm-started from the last one.
#[test]
fn soft_cantilever_takes_a_longer_first_step_to_the_same_equilibrium() {
    let rod_at = |g: f64| {
        let mat = softrod_core::spec::MaterialSpec {
            youngs_modulus: 100e3,
            shear_modulus: 100e3 / 3.0,
            density: 1000.0,
        };
        let sec = geometry_section("rod", 0.22, 0.0125, 0.0, mat, vec![], 20);
        Rod::new(design(vec![sec], HORIZONTAL, g)).unwrap()
    };
    let opts = SolverOptions::default();
    let cold = solve(&rod_at(9.81), &loads(&[]), None, &opts).unwrap();
    assert_eq!(cold.load_steps, 2, "load levels of the cold solve");
    assert_eq!(cold.stable, Some(true));
    let newton_only = SolverOptions {
        continuation: false,
        ..opts
    };
    let mut x: Option<Vec<f64>> = None;
    let mut tip = [0.0; 3];
    for k in 1..=8 {
        let s = solve(
            &rod_at(9.81 * k as f64 / 8.0),
            &loads(&[]),
            x.as_deref(),
            &newton_only,
        )
        .unwrap();
        tip = s.tip.r;
        x = Some(s.x);
    }
    // Both solves meet tol = 1e-10 on the scaled residual, which moves the tip far less
    // than 1e-9 L (`SolverOptions::tol`); another equilibrium would be centimetres away.
    let d = (0..3)
        .map(|k| (cold.tip.r[k] - tip[k]).abs())
        .fold(0.0, f64::max);
    assert!(d < 1e-9 * 0.22, "tips differ by {d:e} m");
}

/// The column of `column` with spheres of radius `r_s` beside its tip: four (on +-x and
/// +-y) whose surfaces reach `delta` into the straight rod's tip (its centreline: the
/// section has no surface radius), or, with `delta` < 0, one 10 L away that never
/// touches. Contact makes the base force an unknown (six shooting unknowns).
fn column_beside_spheres(steps: usize, r_s: f64, delta: f64, k: f64) -> Rod {
    use softrod_core::spec::obstacle::ObstacleKind;
    let mut spec = column(steps, 0.0, 0.0).spec.clone();
    let sphere = |center: [f64; 3]| {
        // A tolerance 10 delta; a ramp a tenth of delta, so the penalty is linear at the
        // pre-pressed depth.
        let mut s = obstacle(ObstacleKind::Sphere, k, 10.0 * delta.abs());
        s.smoothing = Some(0.1 * delta.abs());
        s.center = Some(center);
        s.radius = Some(r_s);
        s
    };
    spec.obstacles = if delta > 0.0 {
        let c = r_s - delta;
        vec![
            sphere([c, 0.0, L]),
            sphere([-c, 0.0, L]),
            sphere([0.0, c, L]),
            sphere([0.0, -c, L]),
        ]
    } else {
        vec![sphere([10.0 * L, 0.0, 0.0])]
    };
    Rod::new(spec).unwrap()
}

/// Contact has a potential (the penalty's), so its equilibria are assessed with all six
/// Jacobi fields of the base unknowns. An obstacle that never touches only turns the
/// 3-unknown solve into the 6-unknown one: the verdicts and the shapes must not change,
/// across the Euler load (the tip form, just above it) and past kL = pi (the conjugate
/// point, at 5 P_cr).
#[test]
fn distant_obstacle_keeps_the_euler_columns_stability() {
    let free = column(200, 0.0, 0.0);
    let far = column_beside_spheres(200, 0.1, -1.0, 1e3);
    for (ratio, want) in [(0.97, true), (1.03, false), (5.0, false)] {
        let l = tip_loaded([0.0, 0.0, -ratio * p_cr()]);
        let a = solve(&free, &l, None, &opts()).unwrap();
        let b = solve(&far, &l, None, &opts()).unwrap();
        assert_eq!(b.x.len(), 6, "the obstacle makes the base force unknown");
        assert_eq!(a.stable, Some(want), "P = {ratio} P_cr, no obstacle");
        assert_eq!(b.stable, Some(want), "P = {ratio} P_cr, distant obstacle");
        // Both straight: the same equilibrium to the solves' tolerance.
        assert!(
            dist(&a.tip.r, &b.tip.r) < 1e-10 * L,
            "{:?} {:?}",
            a.tip.r,
            b.tip.r
        );
    }
}

/// With six unknowns the natural path is kept on the stable branch too: above the Euler
/// load with a small lateral force, the column with a distant obstacle bends towards the
/// force as the one without does (same tip to 1e-9 L: both solves converge to 1e-12).
#[test]
fn distant_obstacle_keeps_the_buckled_column_on_its_stable_branch() {
    let free = column(400, 0.0, 0.0);
    let far = column_beside_spheres(400, 0.1, -1.0, 1e3);
    for ratio in [1.5, 2.0] {
        let p = ratio * p_cr();
        for sign in [1.0, -1.0] {
            let l = tip_loaded([sign * 1e-3 * p, 0.0, -p]);
            let a = solve(&free, &l, None, &opts()).unwrap();
            let b = solve(&far, &l, None, &opts()).unwrap();
            assert_eq!(b.stable, Some(true), "P = {ratio} P_cr, sign {sign}");
            assert!(sign * b.tip.r[0] > 0.1 * L, "tip {:?}", b.tip.r);
            assert!(
                dist(&a.tip.r, &b.tip.r) < 1e-9 * L,
                "{:?} {:?}",
                a.tip.r,
                b.tip.r
            );
        }
    }
}

/// Spheres pressed lightly against the tip from four sides hold it like a lateral spring
/// k_s: the straight column then stays stable above the free column's Euler load (the
/// critical load rises towards the clamped-pinned one, (kL)^2 = 20.19, as k_s L^3 / EI
/// grows; here k_s ~ 2 k sqrt(2 r_s delta) ~ 2e4 EI / L^3), and no tip support can hold it
/// beyond the clamped-clamped load 4 pi^2 EI / L^2 (the contact patch, 1e-2 L, adds no
/// rotational restraint to speak of). Without the assessment these were all None.
#[test]
fn spheres_at_the_tip_raise_the_columns_buckling_load() {
    let held = column_beside_spheres(1000, 0.5, 1e-4, 1e6);
    let free = column(1000, 0.0, 0.0);
    for (p, want_held, want_free) in [
        (0.5 * p_cr(), true, true),
        (1.5 * p_cr(), true, false),
        (4.0 * p_cr(), true, false),
        (1.2 * 4.0 * PI * PI * EI / (L * L), false, false),
    ] {
        let l = tip_loaded([0.0, 0.0, -p]);
        let h = solve(&held, &l, None, &opts()).unwrap_or_else(|e| panic!("P = {p}: {e}"));
        let f = solve(&free, &l, None, &opts()).unwrap();
        assert!(
            h.tip.r[0].abs() < 1e-12 && h.tip.r[1].abs() < 1e-12,
            "{:?}",
            h.tip.r
        );
        assert_eq!(h.stable, Some(want_held), "P = {p} N, held by the spheres");
        assert_eq!(f.stable, Some(want_free), "P = {p} N, free tip");
    }
}
