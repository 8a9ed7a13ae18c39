//! The collocation discretisation (crate::collocation) against single shooting, closed
//! forms and finite differences.

mod common;

use common::*;
use softrod_core::collocation::{solve_static, Grid};
use softrod_core::statics::{solve, SolverOptions};
use softrod_core::Rod;

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

#[test]
fn explore_static_agreement() {
    for steps in [4, 8, 16, 32] {
        let rod = pam_arm(steps);
        let ld = loads(&[150e3, 0.0, 60e3]);
        let a = solve(&rod, &ld, None, &SolverOptions::default()).unwrap();
        let b = solve_static(&rod, &ld, None, &SolverOptions::default()).unwrap();
        let tip = b.evaluated.node_r.last().unwrap();
        eprintln!(
            "steps {steps}: shooting {:?} collocation {:?} diff {:.3e} it {} levels {}",
            a.tip.r,
            tip,
            dist(&a.tip.r, tip),
            b.iterations,
            b.load_steps
        );
        let _ = Grid::new(&rod);
    }
}
