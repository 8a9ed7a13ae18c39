//! Collocation statics (crate::collocation): fourth order, against single shooting, the
//! elastica, and on the long soft rods where single shooting fails.

mod common;

use common::*;
use softrod_core::spec::MaterialSpec;
use softrod_core::statics::collocation::{shooting_growth, solve_static, SHOOTING_GROWTH_LIMIT};
use softrod_core::statics::{shape, solve, SolverOptions};
use softrod_core::validity::{Policy, Rule};
use softrod_core::{Rod, SoftrodError};

fn pam_arm(steps: usize) -> Rod {
    let mut sec = direct_section("arm", 0.22, 262.8, 87.6, 0.04466, 0.02977, 0.165, steps);
    sec.chambers = [0.0, 120.0, 240.0]
        .iter()
        .enumerate()
        .map(|(k, a)| {
            let mut c = chamber(6.02e-3, 0.0175, *a, k);
            c.area = 113.88e-6;
            c
        })
        .collect();
    let hanging = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];
    Rod::new(design(vec![sec], hanging, 9.81)).unwrap()
}

fn tight() -> SolverOptions {
    SolverOptions {
        tol: 1e-12,
        ..Default::default()
    }
}

#[test]
fn collocation_and_shooting_converge_together_at_fourth_order() {
    // Paper 000's arm bent by 1.5 and 0.6 bar: the two discretisations differ by their
    // O(h^4) errors, so the difference must fall 16x per halving of h (orders in
    // [3.5, 4.5]); at 32 steps it is below 1e-7 L (measured 2.8e-8 L).
    let p = [150e3, 0.0, 60e3];
    let diffs: Vec<f64> = [8, 16, 32]
        .iter()
        .map(|&steps| {
            let rod = pam_arm(steps);
            let a = solve(&rod, &loads(&p), None, &tight()).unwrap();
            let b = solve_static(&rod, &loads(&p), None, &tight()).unwrap();
            dist(&a.tip.r, b.evaluated.node_r.last().unwrap())
        })
        .collect();
    let orders = [(diffs[0] / diffs[1]).log2(), (diffs[1] / diffs[2]).log2()];
    eprintln!("tip differences {diffs:?} m, orders {orders:?}");
    for q in orders {
        assert!(q > 3.5 && q < 4.5, "order {q}");
    }
    assert!(diffs[2] < 1e-7 * 0.22);
}

#[test]
fn collocation_matches_the_elastica() {
    // The tip-load table (elliptic integrals) with EA = GA = 1e8 EI/L^2 (tests/published.rs
    // explains why that leaves < 1e-7 L), 64 intervals: Gauss collocation errs by ~(h/L)^4
    // alpha^2 / 4320 ~ 1e-11 here.
    let table = validation_table("cantilever_tip_load.csv");
    let k = 1e8;
    let rod = Rod::new(design(
        vec![direct_section("beam", 1.0, k, k, 1.0, 1.0, 0.0, 64)],
        HORIZONTAL,
        0.0,
    ))
    .unwrap();
    for row in &table {
        let mut ld = loads(&[]);
        ld.tip_force = [0.0, 0.0, -row[0]];
        let sol = solve_static(&rod, &ld, None, &tight()).unwrap();
        let tip = sol.evaluated.node_r.last().unwrap();
        let (x, d) = (tip[0], -tip[2]);
        eprintln!(
            "alpha {}: deflection {d:.10} vs {:.10}, shortening {:.10} vs {:.10}",
            row[0],
            row[1],
            1.0 - x,
            row[2]
        );
        assert!((d - row[1]).abs() < 1e-6 && (1.0 - x - row[2]).abs() < 1e-6);
    }
}

fn soft_rod(length: f64, rotation: [[f64; 3]; 3], steps: usize) -> Rod {
    let mat = MaterialSpec {
        youngs_modulus: 100e3,
        shear_modulus: 100e3 / 3.0,
        density: 1000.0,
    };
    let sec = geometry_section("rod", length, 0.0125, 0.0, mat, vec![], steps);
    Rod::new(design(vec![sec], rotation, 9.81)).unwrap()
}

#[test]
fn long_soft_rods_are_solved_by_collocation() {
    // A soft rod (E = 100 kPa, r = 12.5 mm) clamped horizontally under its own weight.
    // At 0.22 m single shooting is well conditioned (growth exp(3.4)) and keeps solving
    // it. At 1 m the growth is exp(33): shooting's continuation returned a coiled
    // equilibrium (tip 0.23 m below the base, behind it) and at 2 m it failed; statics now
    // routes both to collocation, which finds the hanging shape. Its accuracy: the same
    // solve with twice the intervals moves the tip by 15/16 of the 32-interval error
    // (fourth order): below 1e-3 L (measured 2e-4 L at 1 m).
    let short = soft_rod(0.22, HORIZONTAL, 16);
    assert!(shooting_growth(&short, &loads(&[])) < SHOOTING_GROWTH_LIMIT);
    assert!(solve(&short, &loads(&[]), None, &SolverOptions::default())
        .unwrap()
        .collocation
        .is_none());
    // Hanging from a horizontal clamp, these rods bend at the clamp far beyond the model's
    // default fibre-stretch range (stretch 0.16 at 1 m against [1/3, 3]): collocation
    // solutions pass the same validity rules as shooting ones, so the default policy
    // refuses them and `Policy::Warn` returns them with the violation listed.
    let warn = SolverOptions {
        on_invalid: Policy::Warn,
        ..SolverOptions::default()
    };
    for length in [1.0, 2.0] {
        let rod = soft_rod(length, HORIZONTAL, 32);
        let growth = shooting_growth(&rod, &loads(&[]));
        match solve(&rod, &loads(&[]), None, &SolverOptions::default()) {
            Err(SoftrodError::InvalidState {
                rule: Rule::StrainRange,
                ..
            }) => {}
            other => panic!("expected the strain-range error, got {other:?}"),
        }
        let sol = solve(&rod, &loads(&[]), None, &warn).unwrap();
        assert!(sol.collocation.is_some(), "routed to collocation");
        assert!(
            matches!(
                sol.violations.as_slice(),
                [SoftrodError::InvalidState {
                    rule: Rule::StrainRange,
                    ..
                }]
            ),
            "{:?}",
            sol.violations
        );
        let fine = solve(&soft_rod(length, HORIZONTAL, 64), &loads(&[]), None, &warn).unwrap();
        let sh = shape(&rod, &loads(&[]), &sol);
        eprintln!(
            "L = {length} m: growth exp({growth:.1}); tip {:?}, 64 intervals {:?}; {} Newton iterations, {} load levels",
            sol.tip.r, fine.tip.r, sol.iterations, sol.load_steps
        );
        assert!(growth > SHOOTING_GROWTH_LIMIT);
        // It hangs: the tip below the base by more than 0.9 L, in front of it.
        assert!(sol.tip.r[2] < -0.9 * length && sol.tip.r[0] > 0.0);
        assert!(dist(&sol.tip.r, &fine.tip.r) < 1e-3 * length);
        // The shape comes from the solve itself (shooting from x would diverge).
        assert_eq!(sh.position.last().unwrap(), &sol.tip.r);
        assert_eq!(sh.s.len(), 33);
    }
}
