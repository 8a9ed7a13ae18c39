//! Closed-form results every linear Cosserat rod must reproduce
//! (tests/data (copied from the shared validation set)/README.md).

use crate::common;
use common::*;
use softrod_core::statics::{shape, solve, SolverOptions};
use softrod_core::Rod;
use std::f64::consts::PI;

/// RK4 with 256 steps closes a full circle to 3e-9 L (measured: error x16 per halving of
/// h, fourth order); 1e-8 L bounds that with margin for all arcs up to 2 pi.
const ARC_TOL: f64 = 1e-8;
const ARC_STEPS: usize = 256;

#[test]
fn tip_moment_gives_circular_arc() {
    let (l, ei) = (0.2, 0.01);
    let rod = Rod::new(design(
        vec![direct_section("rod", l, 1e3, 1e3, ei, 0.02, 0.0, ARC_STEPS)],
        IDENTITY,
        0.0,
    ))
    .unwrap();
    for frac in [0.1, 0.5, 0.9] {
        let m = frac * 2.0 * PI * ei / l;
        let mut ld = loads(&[]);
        ld.tip_moment = [m, 0.0, 0.0];
        let sol = solve(&rod, &ld, None, &SolverOptions::default()).unwrap();
        let sh = shape(&rod, &ld, &sol);
        let kappa = m / ei;
        for (s, p) in sh.s.iter().zip(&sh.position) {
            // Bending about d1 with u1 = kappa > 0 turns d3 towards -d2 = -y.
            let want = [
                0.0,
                -(1.0 - (kappa * s).cos()) / kappa,
                (kappa * s).sin() / kappa,
            ];
            for k in 0..3 {
                assert!(
                    (p[k] - want[k]).abs() < ARC_TOL * l,
                    "s={s} k={k} got {} want {}",
                    p[k],
                    want[k]
                );
            }
        }
        for u in &sh.u {
            assert!((u[0] - kappa).abs() < 1e-9 * kappa);
        }
    }
}

#[test]
fn full_circle_returns_tip_to_base() {
    let (l, ei) = (0.2, 0.01);
    let rod = Rod::new(design(
        vec![direct_section("rod", l, 1e3, 1e3, ei, 0.02, 0.0, ARC_STEPS)],
        IDENTITY,
        0.0,
    ))
    .unwrap();
    let mut ld = loads(&[]);
    ld.tip_moment = [2.0 * PI * ei / l, 0.0, 0.0];
    let sol = solve(&rod, &ld, None, &SolverOptions::default()).unwrap();
    let r = sol.tip.r;
    assert!(
        r.iter().all(|x| x.abs() < ARC_TOL * l),
        "tip {r:?} should be back at the base"
    );
    // and the tangent is back to +z
    assert!((sol.tip.rot[2][2] - 1.0).abs() < 1e-8);
}

#[test]
fn axial_force_stretches_by_fl_over_ea() {
    let (l, ea) = (0.1, 50.0);
    let rod = Rod::new(design(
        vec![direct_section("rod", l, ea, 30.0, 1e-3, 1e-3, 0.0, 8)],
        IDENTITY,
        0.0,
    ))
    .unwrap();
    let f = 7.5;
    let mut ld = loads(&[]);
    ld.tip_force = [0.0, 0.0, f];
    let sol = solve(&rod, &ld, None, &SolverOptions::default()).unwrap();
    let want = l + f * l / ea;
    assert!(
        (sol.tip.r[2] - want).abs() < 1e-12,
        "{} vs {want}",
        sol.tip.r[2]
    );
    assert!(sol.tip.r[0].abs() < 1e-14 && sol.tip.r[1].abs() < 1e-14);
}
