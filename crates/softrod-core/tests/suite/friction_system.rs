//! Coulomb friction in the statics of a system of rods (docs/contact.md, "Friction in the
//! statics", "Systems of rods"): one rod on a massless platform against the lone rod's
//! path, mu = 0 on the path against the frictionless system, the global balance, a load
//! locked in by friction after the platform is released (against the rigid-plastic bar),
//! the exact Jacobian, batches, and hostile input.

// Index loops over 3-vectors read like the equations they check.
#![allow(clippy::needless_range_loop)]

use crate::bars;
use crate::common;

use bars::{bar_on_bed, pulled, round_bar, worst_central_difference_error, EA, G, K, L, Q, SINK};
use common::{chamber, loads, obstacle, HORIZONTAL, IDENTITY};
use softrod_core::batch::{solve_system_batch, SystemBatchInputs};
use softrod_core::spec::obstacle::ObstacleKind;
use softrod_core::statics::contact::report;
use softrod_core::statics::friction;
use softrod_core::statics::system::{
    frictional, solve_system, solve_system_friction, system_friction_residual_and_jacobian,
    system_retract, Platform, SystemFrictionPath, SystemRod, SystemSolution,
};
use softrod_core::statics::SolverOptions;
use softrod_core::{DesignSpec, Rod};

/// Increments of the paths below.
const STEPS: usize = 8;
/// Lateral distance between the two bars, m.
const GAP: f64 = 0.2;

/// The bar of tests/suite/friction.rs on its bed, its base moved to y = `y`.
fn bar_at(mu: f64, y: f64) -> DesignSpec {
    let mut d = bar_on_bed(mu);
    d.mounting.base_position = [0.0, y, 0.0];
    d
}

/// The bar with a second obstacle far above it (never touched) whose friction is
/// `far_mu`: with `far_mu` > 0 the system follows the frictional path whatever the bed's
/// friction `mu`.
fn bar_with_far_ball(mu: f64, far_mu: f64, y: f64) -> DesignSpec {
    let mut d = bar_at(mu, y);
    let mut ball = obstacle(ObstacleKind::Sphere, K, 1e-3);
    ball.center = Some([0.5, y, 10.0]);
    ball.radius = Some(0.1);
    ball.friction = far_mu;
    d.obstacles.push(ball);
    d
}

/// The platform over the tips of bars at y = 0 and y = GAP (or one bar at y = 0): at
/// x = L, in the bars' base frame, massless, under the force `force` (world, N).
fn platform(two: bool, force: [f64; 3]) -> Platform {
    Platform {
        position: [L, if two { 0.5 * GAP } else { 0.0 }, 0.0],
        rotation: HORIZONTAL,
        force,
        moment: [0.0; 3],
        mass: 0.0,
        com_offset: [0.0; 3],
        gravity: [0.0, 0.0, -G],
    }
}

/// The rods' tips held where the unloaded tips are: (with HORIZONTAL, the platform's y is
/// the world's -y) at -(y - GAP / 2).
fn system(rods: &[Rod]) -> Vec<SystemRod<'_>> {
    let two = rods.len() == 2;
    rods.iter()
        .map(|rod| {
            let y = rod.spec.mounting.base_position[1] - if two { 0.5 * GAP } else { 0.0 };
            SystemRod {
                rod,
                loads: loads(&[]),
                attachment: [0.0, -y, 0.0],
                attachment_rotation: IDENTITY,
            }
        })
        .collect()
}

fn opts() -> SolverOptions {
    SolverOptions::default()
}

fn solve(
    rods: &[SystemRod],
    pf: &Platform,
    history: Option<&SystemFrictionPath>,
) -> SystemSolution {
    solve_system_friction(rods, pf, history, STEPS, &opts()).unwrap()
}

fn max_diff(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).abs()).fold(0.0, f64::max)
}

/// Every increment is solved to the tolerance tol (scaled residual, relative to L and the
/// force scale); the friction state of the next increment is taken at that solution, so
/// two paths through the same increments with different unknowns (the system's and the
/// lone rod's) part by at most tol per increment: STEPS tol of L and of the force scale.
fn path_tolerance() -> f64 {
    STEPS as f64 * opts().tol * 10.0
}

/// A one-rod system whose massless platform sits on the tip and carries the pull F is the
/// lone bar pulled by F on its frictional bed: the same path (gravity and the pull ramped
/// together in the same increments), the same equilibrium and friction, and the platform
/// applies F to the tip.
#[test]
fn one_rod_system_on_a_frictional_bed_is_the_lone_pulled_bar() {
    let f = 0.3;
    let rod = Rod::new(bar_at(0.5, 0.0)).unwrap();
    let rods = [rod];
    let pf = platform(false, [f, 0.0, 0.0]);
    let sys = solve(&system(&rods), &pf, None);
    let lone = friction::solve(&rods[0], &pulled(f), None, STEPS, &opts()).unwrap();
    let got = &sys.rods[0];
    let tol = path_tolerance();
    let dr = max_diff(&got.solution.tip.r, &lone.tip.r);
    let dp = max_diff(&sys.platform_position, &lone.tip.r);
    let dn = max_diff(&got.tip_reaction_force, &[f, 0.0, 0.0]);
    println!("tip {dr:.2e} m, platform {dp:.2e} m, reaction {dn:.2e} N (bound {tol:.1e})");
    assert!(dr <= tol * L && dp <= tol * L, "{dr:e} {dp:e}");
    assert!(dn <= tol * rods[0].force_scale, "{dn:e}");
    // The same friction: the bed's tangential force on the bar, against the lone bar's.
    let rep = report(&rods[0], &loads(&[]), &got.solution)
        .unwrap()
        .unwrap();
    let lone_rep = report(&rods[0], &pulled(f), &lone).unwrap().unwrap();
    let df = max_diff(&rep.friction[0], &lone_rep.friction[0]);
    println!(
        "friction {:?} N, lone {:?} N",
        rep.friction[0], lone_rep.friction[0]
    );
    assert!(rep.friction[0][0] < -0.1 * f, "{:?}", rep.friction[0]);
    assert!(df <= tol * rods[0].force_scale, "{df:e}");
    assert_eq!(sys.stable, None);
    assert!(sys.rods[0].solution.friction.is_some());
    assert!(sys.friction.as_ref().unwrap().max_elastic_slip() > 0.0);
}

/// mu = 0 on the frictional path (a far, untouched obstacle with friction sends the system
/// there) is the frictionless system: the same equilibrium to the solvers' tolerances.
#[test]
fn two_bars_without_friction_on_the_path_are_the_frictionless_system() {
    let force = [0.3, 0.05, 0.0];
    let on_path = [
        Rod::new(bar_with_far_ball(0.0, 0.5, 0.0)).unwrap(),
        Rod::new(bar_with_far_ball(0.0, 0.5, GAP)).unwrap(),
    ];
    let plain = [
        Rod::new(bar_with_far_ball(0.0, 0.0, 0.0)).unwrap(),
        Rod::new(bar_with_far_ball(0.0, 0.0, GAP)).unwrap(),
    ];
    let pf = platform(true, force);
    let path = solve(&system(&on_path), &pf, None);
    let want = solve_system(&system(&plain), &pf, None, &opts()).unwrap();
    let tol = path_tolerance();
    let dp = max_diff(&path.platform_position, &want.platform_position);
    println!("platform {dp:.2e} m (bound {tol:.1e})");
    assert!(dp <= tol * L, "{dp:e}");
    for i in 0..2 {
        let dn = max_diff(
            &path.rods[i].tip_reaction_force,
            &want.rods[i].tip_reaction_force,
        );
        assert!(dn <= tol * on_path[i].force_scale, "rod {i}: {dn:e}");
    }
    // The lateral load bends the bars in the bed's plane: a real test of the two paths.
    assert!(want.platform_position[1] - pf.position[1] > 1e-3);
    // The frictionless system refuses friction by name; the frictional path a system
    // without any.
    let err = solve_system(&system(&on_path), &pf, None, &opts()).unwrap_err();
    assert!(err.to_string().contains("obstacles[1].friction"), "{err}");
    let err = solve_system_friction(&system(&plain), &pf, None, STEPS, &opts()).unwrap_err();
    assert!(err.to_string().contains("rods"), "{err}");
}

/// Two bars pulled by the platform along their beds (F = 0.6 N, below the 2 mu q L = 1 N
/// that would drag them), then released (F = 0, the path continued from the pulled
/// system): the forces balance at both, and the released bars keep a tension locked in by
/// the friction, each the lone rigid-plastic bar's F_i / 2 with F_i = F / 2 its share;
/// without friction the released system returns to where it lay.
#[test]
fn frictional_system_balances_and_keeps_a_locked_in_tension_after_release() {
    let f = 0.6;
    for mu in [0.5, 0.0] {
        let rods = [
            Rod::new(bar_with_far_ball(mu, 0.5, 0.0)).unwrap(),
            Rod::new(bar_with_far_ball(mu, 0.5, GAP)).unwrap(),
        ];
        let sr = system(&rods);
        let pulled_sys = solve(&sr, &platform(true, [f, 0.0, 0.0]), None);
        let released = solve(
            &sr,
            &platform(true, [0.0; 3]),
            pulled_sys.friction.as_deref(),
        );
        for (name, sys, load) in [("pulled", &pulled_sys, f), ("released", &released, 0.0)] {
            // sum_i n_i(0) = F + sum_i (W_i + C_i): the bases carry the platform's load,
            // the weights and the contact forces (the massless platform passes F on).
            let mut sum = [load, 0.0, 0.0];
            for (rod, s) in rods.iter().zip(&sys.rods) {
                let rep = report(rod, &loads(&[]), &s.solution).unwrap().unwrap();
                for k in 0..3 {
                    sum[k] -=
                        s.solution.base_force[k] - rep.force.iter().map(|c| c[k]).sum::<f64>();
                }
                sum[2] -= Q * L;
            }
            let scale = rods[0].force_scale;
            println!("mu {mu} {name}: balance error {sum:?} N");
            for k in 0..3 {
                assert!(sum[k].abs() <= 1e-9 * scale, "{name} [{k}]: {:e}", sum[k]);
            }
        }
        let share = 0.5 * f;
        for (i, s) in released.rods.iter().enumerate() {
            let locked = s
                .shape
                .force
                .iter()
                .map(|n| n[0])
                .fold(f64::NEG_INFINITY, f64::max);
            let dx = released.platform_position[0] - L;
            println!("mu {mu}, rod {i}: locked-in tension {locked:.4e} N, platform {dx:.3e} m");
            if mu > 0.0 {
                // The lone bar's bound (tests/suite/friction.rs): the elastic slip moves each
                // zone boundary by about ell = sqrt(EA / k_t), changing N by mu q ell.
                let ell = (EA / K).sqrt();
                assert!((locked - 0.5 * share).abs() <= mu * Q * ell, "{locked}");
                assert!(dx > 0.0);
            } else {
                assert!(
                    locked.abs() <= 1e-9 && dx.abs() <= 1e-9 * L,
                    "{locked} {dx}"
                );
            }
        }
    }
}

/// The system's residual with every rod's friction is differentiated exactly: two round
/// bars (surface radius 5 mm: the friction has a moment, the contact points roll) laid on
/// their plane, then pulled along and across by the platform: the dual-number Jacobian
/// at a trial point of that increment against central differences along the solver's
/// increments (the platform's rotation on the group). As for the lone rod
/// (tests/suite/friction.rs), the point is moved 1 % off the laid one so that every contact
/// point's trial state is strictly in stick or slip, away from the Coulomb cone's kink.
#[test]
fn frictional_system_jacobian_matches_central_differences() {
    let mut second = round_bar().spec;
    second.mounting.base_position = [0.0, 0.05, 0.0];
    let rods = [round_bar(), Rod::new(second).unwrap()];
    let len = rods[0].length;
    let sr: Vec<SystemRod> = rods
        .iter()
        .map(|rod| SystemRod {
            rod,
            loads: loads(&[]),
            attachment: [0.0, 0.025 - rod.spec.mounting.base_position[1], 0.0],
            attachment_rotation: IDENTITY,
        })
        .collect();
    let mut pf = platform(true, [0.0; 3]);
    pf.position = [len, 0.025, 0.0];
    let laid = solve(&sr, &pf, None);
    let path = laid.friction.as_deref().unwrap();
    pf.force = [0.02, 0.01, 0.0];
    let x: Vec<f64> = path.x.iter().map(|v| v * 1.01 + 1e-4).collect();
    let (_, jac) = system_friction_residual_and_jacobian(&sr, &pf, path, &x).unwrap();
    let worst = worst_central_difference_error(&jac, x.len(), |k, s| {
        let mut d = vec![0.0; x.len()];
        d[k] = s;
        let y = system_retract(2, &x, &d);
        system_friction_residual_and_jacobian(&sr, &pf, path, &y)
            .unwrap()
            .0
    });
    // Bound: bars::worst_central_difference_error says why.
    println!("worst Jacobian error {worst:.2e} of a row's scale");
    assert!(worst < 1e-6, "{worst:e}");
}

/// Every row of a frictional system batch is its own path from the unloaded rods: bitwise
/// the single frictional solve of that row, for 1 and 2 threads. The two bars with a pair
/// of opposed chambers each (lateral: pressure bends a bar in its bed's plane), dragged
/// sideways over the bed by the pressures and held by the platform.
#[test]
fn frictional_system_batch_rows_are_the_single_solves() {
    let bar = |y: f64| {
        let mut spec = bar_with_far_ball(0.5, 0.5, y);
        spec.sections[0].chambers =
            vec![chamber(3e-3, 0.01, 90.0, 0), chamber(3e-3, 0.01, 270.0, 1)];
        // The chambers' envelope (0.013 m) is the bar's surface now: the bed is lowered
        // by it, so the bar lies on it as before.
        spec.obstacles[0].point = Some([0.0, 0.0, SINK - 0.013]);
        Rod::new(spec).unwrap()
    };
    let rods = [bar(0.0), bar(GAP)];
    let mut sr = system(&rods);
    for r in &mut sr {
        r.loads.pressures = vec![0.0; 2];
    }
    let pf = platform(true, [0.0; 3]);
    // Each row: rod 0's two channels, then rod 1's.
    let rows = [[0.0; 4], [10e3, 0.0, 0.0, 0.0], [10e3, 0.0, 0.0, 5e3]];
    let flat: Vec<f64> = rows.iter().flatten().copied().collect();
    let inputs = SystemBatchInputs {
        pressures: &flat,
        tensions: None,
        stiffness_scale: None,
    };
    for threads in [1, 2] {
        let out = solve_system_batch(&sr, &pf, &inputs, STEPS, &opts(), threads).unwrap();
        for (row, p) in out.iter().zip(&rows) {
            let mut one = sr.clone();
            for (r, v) in one.iter_mut().zip(p.chunks(2)) {
                r.loads.pressures = v.to_vec();
            }
            let single = solve(&one, &pf, None);
            assert!(row.converged, "{}", row.violation);
            assert_eq!(row.x, single.x, "threads {threads}, row {p:?}");
            assert_eq!(row.platform_position, single.platform_position);
            assert_eq!(row.stable, None);
        }
        // The pressure drags the bars sideways: the rows differ.
        let dy = out[1].platform_position[1] - out[0].platform_position[1];
        println!("threads {threads}: platform moved {dy:.3e} m sideways by row 1");
        assert!(dy.abs() > 1e-4);
    }
}

/// Hostile input to the frictional system: increments out of range, a history of another
/// system, of another design or of another platform, a warm start on a path and a history
/// for a frictionless system are refused by name before any work.
#[test]
fn frictional_system_refuses_bad_input_by_name() {
    let rods = [
        Rod::new(bar_at(0.5, 0.0)).unwrap(),
        Rod::new(bar_at(0.5, GAP)).unwrap(),
    ];
    let sr = system(&rods);
    let pf = platform(true, [0.1, 0.0, 0.0]);
    for steps in [0, friction::MAX_FRICTION_STEPS + 1] {
        let err = solve_system_friction(&sr, &pf, None, steps, &opts()).unwrap_err();
        assert!(err.to_string().contains("friction_steps"), "{err}");
    }
    let done = solve(&sr, &pf, None);
    let history = done.friction.as_deref().unwrap();
    // One rod's history for two rods.
    let lone = [Rod::new(bar_at(0.5, 0.0)).unwrap()];
    let one = solve(&system(&lone), &platform(false, [0.1, 0.0, 0.0]), None);
    let err = solve_system_friction(&sr, &pf, one.friction.as_deref(), STEPS, &opts()).unwrap_err();
    assert!(err.to_string().contains("history"), "{err}");
    // Another design (a rod's friction changed: other obstacles).
    let other = [
        Rod::new(bar_at(0.6, 0.0)).unwrap(),
        Rod::new(bar_at(0.5, GAP)).unwrap(),
    ];
    let err =
        solve_system_friction(&system(&other), &pf, Some(history), STEPS, &opts()).unwrap_err();
    assert!(err.to_string().contains("history.rods[0]"), "{err}");
    // Another platform (its mass).
    let mut heavy = pf;
    heavy.mass = 0.1;
    let err = solve_system_friction(&sr, &heavy, Some(history), STEPS, &opts()).unwrap_err();
    assert!(err.to_string().contains("history"), "{err}");
    // What the binding refuses before choosing the solve.
    let err = frictional(&sr, false, true).unwrap_err();
    assert!(err.to_string().contains("initial"), "{err}");
    let smooth = [
        Rod::new(bar_at(0.0, 0.0)).unwrap(),
        Rod::new(bar_at(0.0, GAP)).unwrap(),
    ];
    let err = frictional(&system(&smooth), true, false).unwrap_err();
    assert!(err.to_string().contains("history"), "{err}");
    assert!(frictional(&sr, true, false).unwrap());
    assert!(!frictional(&system(&smooth), false, true).unwrap());
}
