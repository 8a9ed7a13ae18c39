//! Large-deflection cantilevers against the published tables in tests/data (copied from the shared validation set):
//! the elastica under a dead tip load (elliptic-integral closed form) and under a dead
//! distributed load.
//!
//! The tables describe the inextensible, unshearable rod. A Cosserat rod approximates it
//! with EA = GA = STIFF * EI / L^2: the axial and shear strains are then at most
//! |n| / EA <= 10 EI/L^2 / EA = 1e-7, which moves the tip by less than 1e-7 L. (Measured:
//! the deflection exceeds the elastica by alpha * 1e-8 L, the shear compliance P/GA. With
//! 1e6 it would be alpha * 1e-6 L = 1e-5 L at alpha = 10: the README's "1e6 is enough for
//! 1e-6" holds only for alpha <= 1.)

use crate::common;
use common::*;
use softrod_core::ode::Loads;
use softrod_core::spec::LineLoadSpec;
use softrod_core::statics::{solve, SolverOptions};
use softrod_core::Rod;

/// Table values must be matched to this (absolute, on quantities of order 1). Measured
/// worst deviations: 1.0e-7 (deflection at alpha = 10: the shear compliance above) and
/// 7e-8 (distributed table, which is rounded to 7 decimals).
const TABLE_TOL: f64 = 1e-6;
/// EA and GA in units of EI / L^2 (the README's 1e6 would leave alpha * 1e-6 L, see above).
const STIFF: f64 = 1e8;
/// RK4 steps along the rod. Measured: going from 256 to 512 steps changes the results by
/// at most 1.5e-10 (lambda = 10; 9e-11 at alpha = 10, error /16 per doubling), so the RK4
/// error at 256 steps is about 1e-10, negligible against TABLE_TOL. (At 16 steps, alpha = 10
/// moves by 3e-6 when doubled.)
const STEPS: usize = 256;
/// The RK4 error check: doubling the steps must change the results by less than this.
const STEP_DOUBLING_TOL: f64 = 1e-8;
/// A tight Newton tolerance so that the solver adds nothing measurable.
const SOLVER_TOL: f64 = 1e-12;

const L: f64 = 1.0;
const EI: f64 = 1.0;

/// A horizontal cantilever (d3 = +x, d1 = +z) with line mass `mass / L` under gravity `g`.
fn cantilever(steps: usize, mass: f64, g: f64) -> softrod_core::DesignSpec {
    let k = STIFF * EI / (L * L);
    design(
        vec![direct_section("beam", L, k, k, EI, EI, mass, steps)],
        HORIZONTAL,
        g,
    )
}

fn opts() -> SolverOptions {
    SolverOptions {
        tol: SOLVER_TOL,
        ..Default::default()
    }
}

/// (tip_x / L, deflection / L, tip angle) of a horizontal cantilever bending towards -z.
fn tip_measures(rod: &Rod, ld: &Loads) -> [f64; 3] {
    let sol = solve(rod, ld, None, &opts()).unwrap();
    let t = column(&sol.tip.rot, 2);
    [sol.tip.r[0] / L, -sol.tip.r[2] / L, (-t[2]).atan2(t[0])]
}

fn tip_load_measures(alpha: f64, steps: usize) -> [f64; 3] {
    let rod = Rod::new(cantilever(steps, 0.0, 0.0)).unwrap();
    let mut ld = loads(&[]);
    ld.tip_force = [0.0, 0.0, -alpha * EI / (L * L)];
    tip_measures(&rod, &ld)
}

#[test]
fn tip_load_matches_elastica() {
    let table = validation_table("cantilever_tip_load.csv");
    assert_eq!(table.len(), 6);
    for row in &table {
        let (alpha, deflection, shortening, angle) = (row[0], row[1], row[2], row[3]);
        let [x, d, phi] = tip_load_measures(alpha, STEPS);
        let got = [d, 1.0 - x, phi];
        let want = [deflection, shortening, angle];
        for (name, g, w) in [
            ("deflection", got[0], want[0]),
            ("shortening", got[1], want[1]),
            ("angle", got[2], want[2]),
        ] {
            assert!(
                (g - w).abs() < TABLE_TOL,
                "alpha = {alpha}: {name} {g:.10} vs table {w:.10}"
            );
        }
    }
}

fn distributed_measures(lambda: f64, steps: usize, by_gravity: bool) -> [f64; 3] {
    let q = lambda * EI / L.powi(3);
    let ld = loads(&[]);
    if by_gravity {
        // q = (mass / L) g
        let g = 9.81;
        let rod = Rod::new(cantilever(steps, q * L / g, g)).unwrap();
        tip_measures(&rod, &ld)
    } else {
        let mut spec = cantilever(steps, 0.0, 0.0);
        spec.loads = vec![LineLoadSpec {
            frame: Default::default(),
            section: 0,
            force_per_length: [0.0, 0.0, -q],
            moment_per_length: [0.0; 3],
        }];
        tip_measures(&Rod::new(spec).unwrap(), &ld)
    }
}

#[test]
fn distributed_load_matches_table() {
    let table = validation_table("cantilever_distributed_load.csv");
    assert_eq!(table.len(), 4);
    for row in &table {
        let lambda = row[0];
        for by_gravity in [false, true] {
            let got = distributed_measures(lambda, STEPS, by_gravity);
            for (k, name) in ["tip_x/L", "deflection/L", "angle"].iter().enumerate() {
                assert!(
                    (got[k] - row[k + 1]).abs() < TABLE_TOL,
                    "lambda = {lambda}, gravity = {by_gravity}: {name} {:.8} vs table {:.8}",
                    got[k],
                    row[k + 1]
                );
            }
        }
    }
}

/// The step count above is enough: doubling it changes nothing that matters, for the
/// hardest row of each table.
#[test]
fn step_count_resolves_the_tables() {
    let a = tip_load_measures(10.0, STEPS);
    let b = tip_load_measures(10.0, 2 * STEPS);
    let c = distributed_measures(10.0, STEPS, false);
    let d = distributed_measures(10.0, 2 * STEPS, false);
    for k in 0..3 {
        assert!(
            (a[k] - b[k]).abs() < STEP_DOUBLING_TOL,
            "tip load, measure {k}: {} vs {}",
            a[k],
            b[k]
        );
        assert!(
            (c[k] - d[k]).abs() < STEP_DOUBLING_TOL,
            "line load, measure {k}: {} vs {}",
            c[k],
            d[k]
        );
    }
}
