//! `solve_friction_batch` (docs/contact.md, "Friction in the statics"): every row is its
//! own frictional load path from the unloaded rod, bitwise equal to one
//! `friction::solve` of that row whatever the thread count; what it refuses by name.

use crate::common;

use common::finger;
use softrod_core::batch::{
    constrained_sensitivity_batch, sensitivity_batch, solve_batch, solve_constrained_batch,
    solve_friction_batch, BatchInputs, BatchRow,
};
use softrod_core::ode::Loads;
use softrod_core::statics::constraint::TipConstraint;
use softrod_core::statics::contact::report;
use softrod_core::statics::friction::{self, DEFAULT_FRICTION_STEPS, MAX_FRICTION_STEPS};
use softrod_core::statics::SolverOptions;
use softrod_core::Rod;

const MU: f64 = 0.5;
/// Load increments per row: few, to keep the test short (the increments' size changes
/// the answer, not whether batch and single agree).
const STEPS: usize = 20;

/// Rows of (pressure, tension): the finger off the table, touching, pressed harder, and
/// pulled back by its tendon.
const ROWS: [(f64, f64); 6] = [
    (0.0, 0.0),
    (15e3, 0.0),
    (25e3, 0.0),
    (35e3, 0.0),
    (45e3, 0.0),
    (35e3, 0.05),
];

fn inputs<'a>(p: &'a [f64], t: &'a [f64]) -> BatchInputs<'a> {
    BatchInputs {
        pressures: p,
        tensions: Some(t),
        stiffness_scale: None,
        tip_force: [0.0; 3],
        tip_moment: [0.0; 3],
    }
}

fn columns() -> (Vec<f64>, Vec<f64>) {
    ROWS.iter().map(|&(p, t)| (p, t)).unzip()
}

fn bits3(v: &[f64; 3]) -> [u64; 3] {
    v.map(f64::to_bits)
}

/// Every field of a converged row bitwise equal to the single solve of its loads (and
/// the single solve's contact report).
fn assert_row_is_single(rod: &Rod, row: &BatchRow, loads: &Loads, what: &str) {
    let opts = SolverOptions::default();
    let sol = friction::solve(rod, loads, None, STEPS, &opts).unwrap();
    let rep = report(rod, loads, &sol).unwrap().unwrap();
    assert!(row.converged, "{what}");
    assert_eq!(bits3(&row.tip_position), bits3(&sol.tip.r), "{what}");
    for k in 0..3 {
        assert_eq!(
            bits3(&row.tip_rotation[k]),
            bits3(&sol.tip.rot[k]),
            "{what}"
        );
    }
    assert_eq!(bits3(&row.base_force), bits3(&sol.base_force), "{what}");
    assert_eq!(bits3(&row.base_moment), bits3(&sol.base_moment), "{what}");
    assert_eq!(row.iterations, sol.iterations, "{what}");
    assert_eq!(row.residual.to_bits(), sol.residual.to_bits(), "{what}");
    let xb = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(xb(&row.x), xb(&sol.x), "{what}");
    assert_eq!(row.x.len(), 6, "{what}");
    // Friction has no potential: stability is not assessed.
    assert_eq!(row.stable, None, "{what}");
    for (a, b) in [
        (&row.contact_force, &rep.force),
        (&row.friction_force, &rep.friction),
    ] {
        let (a, b): (Vec<_>, Vec<_>) =
            (a.iter().map(bits3).collect(), b.iter().map(bits3).collect());
        assert_eq!(a, b, "{what}");
    }
}

/// A row is bitwise the single frictional solve of its pressure and tension, on 1, 2
/// and 4 threads; some rows press on the table with friction (else the test would not
/// exercise it) and the lifted finger has no contact force at all.
#[test]
fn friction_batch_equals_single_solves_bitwise() {
    let rod = Rod::new(finger(MU)).unwrap();
    let (p, t) = columns();
    let opts = SolverOptions::default();
    let mut reference: Option<Vec<BatchRow>> = None;
    for threads in [1, 2, 4] {
        let rows = solve_friction_batch(&rod, &inputs(&p, &t), STEPS, &opts, threads).unwrap();
        assert_eq!(rows.len(), ROWS.len());
        match &reference {
            None => {
                for (r, row) in rows.iter().enumerate() {
                    let mut loads = common::loads(&p[r..r + 1]);
                    loads.tensions = vec![t[r]];
                    assert_row_is_single(&rod, row, &loads, &format!("row {r}"));
                }
                reference = Some(rows);
            }
            Some(first) => assert_eq!(&rows, first, "threads = {threads}"),
        }
    }
    let rows = reference.unwrap();
    assert_eq!(
        rows[0].contact_force,
        vec![[0.0; 3]],
        "the unloaded finger hangs clear"
    );
    let pressing = rows
        .iter()
        .filter(|r| r.friction_force[0].iter().any(|f| f.abs() > 1e-4))
        .count();
    // 0.1 mN: far above the solver's resolution of a friction force of tens of mN.
    assert!(pressing >= 3, "{pressing} rows carry friction: {rows:?}");
}

/// A failed row is kept (converged false, NaN, its contact forces NaN) while the others
/// converge, as in every batch: one Newton iteration per increment cannot converge a
/// row in contact, but does the row that stays off the table (linear until it touches).
#[test]
fn failed_friction_row_is_kept_failed() {
    let rod = Rod::new(finger(MU)).unwrap();
    let (p, t) = columns();
    let opts = SolverOptions {
        max_iter: 1,
        ..Default::default()
    };
    let rows = solve_friction_batch(&rod, &inputs(&p, &t), STEPS, &opts, 2).unwrap();
    let failed: Vec<&BatchRow> = rows.iter().filter(|r| !r.converged).collect();
    assert!(!failed.is_empty(), "{rows:?}");
    for row in failed {
        assert!(row.tip_position.iter().all(|v| v.is_nan()));
        assert!(row.contact_force[0].iter().all(|v| v.is_nan()));
        assert!(row.friction_force[0].iter().all(|v| v.is_nan()));
        assert_eq!(row.x.len(), 6);
    }
}

/// Bad input is refused by name before any row: the number of increments, a design
/// without friction, a malformed row; the batches that do not follow a frictional path
/// (free and held tips, sensitivities with or without warm starts) keep refusing a
/// frictional design by its obstacle's friction.
#[test]
fn friction_batch_refuses_bad_input_by_name() {
    let rod = Rod::new(finger(MU)).unwrap();
    let (p, t) = columns();
    let opts = SolverOptions::default();
    let rows = inputs(&p, &t);
    for steps in [0, MAX_FRICTION_STEPS + 1] {
        let err = solve_friction_batch(&rod, &rows, steps, &opts, 1).unwrap_err();
        assert!(err.to_string().contains("friction_steps"), "{err}");
    }
    let smooth = Rod::new(finger(0.0)).unwrap();
    let err = solve_friction_batch(&smooth, &rows, DEFAULT_FRICTION_STEPS, &opts, 1).unwrap_err();
    assert!(err.to_string().contains("obstacles"), "{err}");
    let bad = [0.0, f64::NAN, 35e3, 0.0, 0.0, 0.0];
    let err = solve_friction_batch(&rod, &inputs(&bad, &t), STEPS, &opts, 1).unwrap_err();
    assert!(err.to_string().contains("row 1: pressures[0]"), "{err}");
    let err = solve_friction_batch(&rod, &inputs(&p[..5], &t), STEPS, &opts, 1).unwrap_err();
    assert!(err.to_string().contains("tensions"), "{err}");

    let by_friction = |e: softrod_core::SoftrodError| {
        assert!(e.to_string().contains("obstacles[0].friction"), "{e}");
    };
    by_friction(solve_batch(&rod, &rows, &opts, 1).unwrap_err());
    let pinned = TipConstraint::Pinned {
        position: [0.02, 0.0, -0.08],
    };
    by_friction(solve_constrained_batch(&rod, &rows, &pinned, &opts, 1).unwrap_err());
    let guesses = vec![0.0; 6 * ROWS.len()];
    by_friction(sensitivity_batch(&rod, &rows, Some(&guesses), &[], &[], &opts, 1).unwrap_err());
    by_friction(
        constrained_sensitivity_batch(&rod, &rows, &pinned, Some(&guesses), &[], &[], &opts, 1)
            .unwrap_err(),
    );
}

/// A clamped tip: every row is one `friction::solve_held` (its clamp moved along its own
/// path from the unloaded rod's tip), bitwise on 1 and 2 threads, tip reactions included;
/// a free constraint is the free frictional batch.
#[test]
fn held_friction_batch_equals_single_held_solves_bitwise() {
    use softrod_core::batch::solve_held_friction_batch;

    let rod = Rod::new(finger(MU)).unwrap();
    let opts = SolverOptions::default();
    // Clamped where the frictionless finger's tip rests at 35 kPa (on the table).
    let smooth = Rod::new(finger(0.0)).unwrap();
    let mut at_rest = common::loads(&[35e3]);
    at_rest.tensions = vec![0.0];
    let rest = softrod_core::statics::solve(&smooth, &at_rest, None, &opts).unwrap();
    let clamp = TipConstraint::Clamped {
        position: rest.tip.r,
        rotation: rest.tip.rot,
    };
    let (p, t) = columns();
    let (p, t) = (&p[1..5], &t[1..5]);
    let mut first: Option<Vec<BatchRow>> = None;
    for threads in [1, 2] {
        let rows =
            solve_held_friction_batch(&rod, &inputs(p, t), &clamp, STEPS, &opts, threads).unwrap();
        match &first {
            None => {
                for (r, row) in rows.iter().enumerate() {
                    let mut loads = common::loads(&p[r..r + 1]);
                    loads.tensions = vec![t[r]];
                    let c = friction::solve_held(&rod, &loads, &clamp, None, STEPS, &opts).unwrap();
                    let rep = report(&rod, &loads, &c.solution).unwrap().unwrap();
                    assert!(row.converged, "row {r}");
                    assert_eq!(
                        bits3(&row.tip_position),
                        bits3(&c.solution.tip.r),
                        "row {r}"
                    );
                    assert_eq!(
                        bits3(&row.base_force),
                        bits3(&c.solution.base_force),
                        "row {r}"
                    );
                    assert_eq!(bits3(&row.tip_reaction_force), bits3(&c.tip_reaction_force));
                    assert_eq!(
                        bits3(&row.tip_reaction_moment),
                        bits3(&c.tip_reaction_moment)
                    );
                    let f: Vec<_> = row.friction_force.iter().map(bits3).collect();
                    let g: Vec<_> = rep.friction.iter().map(bits3).collect();
                    assert_eq!(f, g, "row {r}");
                    assert_eq!(row.stable, None, "row {r}");
                }
                first = Some(rows);
            }
            Some(a) => assert_eq!(&rows, a, "threads = {threads}"),
        }
    }
    // Not vacuous: the clamp carries friction on pressed rows (tens of mN).
    let rows = first.unwrap();
    assert!(
        rows.iter()
            .filter(|r| r.friction_force[0][0].abs() > 1e-4)
            .count()
            >= 2
    );
    // Free: the free frictional batch, row for row.
    let free =
        solve_held_friction_batch(&rod, &inputs(p, t), &TipConstraint::Free, STEPS, &opts, 1)
            .unwrap();
    let plain = solve_friction_batch(&rod, &inputs(p, t), STEPS, &opts, 1).unwrap();
    assert_eq!(free, plain);
}
