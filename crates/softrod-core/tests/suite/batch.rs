//! `solve_batch` against one `solve` per row, and its input checks.

use crate::common;
use common::*;
use softrod_core::batch::{solve_batch, BatchInputs, BatchRow};
use softrod_core::statics::{solve, SolverOptions};
use softrod_core::{Rod, SoftrodError};

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

/// `solve_batch` of pressure rows with shared tip loads and optional sigma rows.
fn batch_of(
    rod: &Rod,
    p: &[f64],
    tip_force: [f64; 3],
    tip_moment: [f64; 3],
    sigma: Option<&[f64]>,
    opts: &SolverOptions,
    threads: usize,
) -> softrod_core::Result<Vec<BatchRow>> {
    let inputs = BatchInputs {
        pressures: p,
        tensions: None,
        stiffness_scale: sigma,
        tip_force,
        tip_moment,
    };
    solve_batch(rod, &inputs, opts, threads)
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

/// Every batch row is solved exactly as `solve` solves it alone (cold, no neighbour warm
/// start), so rows are bitwise equal to single solves for any thread count and whichever
/// rows are batched together.
#[test]
fn batch_equals_single_solves_bitwise() {
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
    let check = |rows: &[BatchRow], first: usize, what: &str| {
        for (k, row) in rows.iter().enumerate() {
            let s = &single[first + k];
            assert!(row.converged, "{what}: row {k} did not converge");
            assert_eq!(row.tip_position, s.tip.r, "{what}: row {k}");
            assert_eq!(row.tip_rotation, s.tip.rot, "{what}: row {k}");
            assert_eq!(row.base_force, s.base_force, "{what}: row {k}");
            assert_eq!(row.base_moment, s.base_moment, "{what}: row {k}");
            assert_eq!(row.x, s.x, "{what}: row {k}");
            assert_eq!(row.stable, s.stable, "{what}: row {k}");
        }
    };
    for threads in [1, 2, 4] {
        let rows = batch_of(&rod, &p, tip_force, [0.0; 3], None, &opts, threads).unwrap();
        assert_eq!(rows.len(), LEVELS.pow(3));
        check(&rows, 0, &format!("threads = {threads}"));
    }
    // other groupings of the same rows: the second half alone, and every row alone
    let half = LEVELS.pow(3) / 2;
    let rows = batch_of(&rod, &p[3 * half..], tip_force, [0.0; 3], None, &opts, 3).unwrap();
    check(&rows, half, "second half");
    for k in [0, 7, half, LEVELS.pow(3) - 1] {
        let rows = batch_of(
            &rod,
            &p[3 * k..3 * k + 3],
            tip_force,
            [0.0; 3],
            None,
            &opts,
            1,
        )
        .unwrap();
        check(&rows, k, "one row");
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
        let e = batch_of(&rod, &p, [0.0; 3], [0.0; 3], None, &opts, 1).unwrap_err();
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
    assert!(batch_of(&rod, &p, [0.0; 3], [0.0; 3], None, &opts, 1).is_ok());
}

#[test]
fn wrong_number_of_columns_is_rejected() {
    let rod = spa();
    let opts = SolverOptions::default();
    for len in [1, 2, 4, 5, 3 * 4 + 2] {
        let e = batch_of(&rod, &vec![1e3; len], [0.0; 3], [0.0; 3], None, &opts, 1).unwrap_err();
        assert_eq!(field_of(e), "pressures", "{len} values");
    }
    // no rows at all is a valid (empty) batch
    assert!(batch_of(&rod, &[], [0.0; 3], [0.0; 3], None, &opts, 1)
        .unwrap()
        .is_empty());
}
