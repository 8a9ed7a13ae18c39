//! `solve_batch` against one `solve` per row, and its input checks.

mod common;
use common::*;
use softrod_core::batch::solve_batch;
use softrod_core::statics::{solve, SolverOptions};
use softrod_core::{Rod, SoftrodError};

/// Batch rows warm-start from their neighbour, single solves start cold (with load
/// continuation where needed); both stop at the same scaled residual (<= 1e-10), which
/// moves the tip by ~1e-10 L (Newton stops at the first iterate below the tolerance, so
/// two runs from different starts can stop on different sides of it). Measured: 5.5e-11 L
/// at worst over the grid, for 1 and 2 threads.
const SAME_SOLUTION_TOL: f64 = 1e-9;
/// Pressure grid: LEVELS^3 rows from 0 to P_MAX in each of the three channels.
const LEVELS: usize = 5;
const P_MAX: f64 = 70e3;

/// Paper 002's actuator, horizontal under gravity, with its marker plate.
fn spa() -> Rod {
    let mut spec = p002_actuator(HORIZONTAL, 9.81, 16);
    spec.tip.mass = 17.25e-3;
    spec.tip.com_offset = [9.3e-3, 2.9e-3, -1.1e-3];
    Rod::new(spec).unwrap()
}

fn grid() -> Vec<f64> {
    let level = |i: usize| P_MAX * i as f64 / (LEVELS - 1) as f64;
    let mut out = Vec::with_capacity(3 * LEVELS.pow(3));
    for a in 0..LEVELS {
        for b in 0..LEVELS {
            for c in 0..LEVELS {
                out.extend([level(a), level(b), level(c)]);
            }
        }
    }
    out
}

#[test]
fn batch_equals_single_solves() {
    let rod = spa();
    let p = grid();
    let opts = SolverOptions::default();
    let tip_force = [0.0, 0.01, 0.0];
    let single: Vec<_> = p
        .chunks(3)
        .map(|row| {
            let mut ld = loads(row);
            ld.tip_force = tip_force;
            solve(&rod, &ld, None, &opts).unwrap()
        })
        .collect();
    let l = rod.length;
    // the grid really moves the tip around
    let spread = single
        .iter()
        .map(|s| dist(&s.tip.r, &single[0].tip.r))
        .fold(0.0, f64::max);
    assert!(spread > 0.2 * l, "tip spread {spread}");
    for threads in [1, 2] {
        let rows = solve_batch(&rod, &p, tip_force, [0.0; 3], None, &opts, threads).unwrap();
        assert_eq!(rows.len(), LEVELS.pow(3));
        for (k, (row, s)) in rows.iter().zip(&single).enumerate() {
            assert!(
                row.converged,
                "threads = {threads}, row {k} did not converge"
            );
            let e = dist(&row.tip_position, &s.tip.r);
            assert!(
                e < SAME_SOLUTION_TOL * l,
                "threads = {threads}, row {k}: tip {:?} vs {:?}",
                row.tip_position,
                s.tip.r
            );
            for i in 0..3 {
                assert!(dist(&row.tip_rotation[i], &s.tip.rot[i]) < SAME_SOLUTION_TOL);
            }
            let f = norm(&s.base_force);
            assert!(dist(&row.base_force, &s.base_force) < SAME_SOLUTION_TOL * f);
            assert!(dist(&row.base_moment, &s.base_moment) < SAME_SOLUTION_TOL * f * l);
            assert!(
                row.residual <= opts.tol * 100.0,
                "row {k}: residual {}",
                row.residual
            );
        }
    }
}

fn field_of(e: SoftrodError) -> String {
    match e {
        SoftrodError::InvalidParameter { field, .. } => field,
        other => panic!("expected InvalidParameter, got {other:?}"),
    }
}

#[test]
fn invalid_pressure_row_is_rejected_by_row_and_channel() {
    let rod = spa();
    let opts = SolverOptions::default();
    for bad in [f64::NAN, f64::INFINITY, -101_325.5, -2e5] {
        let mut p = grid();
        p[3 * 7 + 1] = bad; // row 7, channel 1
        let e = solve_batch(&rod, &p, [0.0; 3], [0.0; 3], None, &opts, 1).unwrap_err();
        let msg = e.to_string();
        let field = field_of(e);
        assert!(
            field.contains("row 7") && field.contains("pressures[1]"),
            "bad = {bad}: field '{field}' ({msg})"
        );
    }
    // exactly -1 atm (a perfect vacuum) is allowed
    let mut p = vec![0.0; 3];
    p[2] = -101_325.0;
    assert!(solve_batch(&rod, &p, [0.0; 3], [0.0; 3], None, &opts, 1).is_ok());
}

#[test]
fn wrong_number_of_columns_is_rejected() {
    let rod = spa();
    let opts = SolverOptions::default();
    for len in [1, 2, 4, 5, 3 * 4 + 2] {
        let e = solve_batch(&rod, &vec![1e3; len], [0.0; 3], [0.0; 3], None, &opts, 1).unwrap_err();
        assert_eq!(field_of(e), "pressures", "{len} values");
    }
    // no rows at all is a valid (empty) batch
    assert!(solve_batch(&rod, &[], [0.0; 3], [0.0; 3], None, &opts, 1)
        .unwrap()
        .is_empty());
}
