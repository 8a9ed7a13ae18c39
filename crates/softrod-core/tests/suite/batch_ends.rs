//! Batches of constrained tips (`solve_constrained_batch`) and of systems of rods
//! (`solve_system_batch`) against one single solve per row: bitwise equal whatever the
//! thread count or grouping of rows, failed rows kept, and bad inputs refused before any
//! work, naming the row and the field.

use crate::common;
use common::*;
use softrod_core::batch::{
    solve_constrained_batch, solve_system_batch, system_sensitivity_batch, BatchInputs, BatchRow,
    SystemBatchInputs, SystemBatchRow,
};
use softrod_core::spec::obstacle::ObstacleKind;
use softrod_core::statics::constraint::{solve_constrained, TipConstraint};
use softrod_core::statics::contact::report;
use softrod_core::statics::friction::DEFAULT_FRICTION_STEPS;
use softrod_core::statics::system::{rod_sigma, solve_system, Platform, SystemRod};
use softrod_core::statics::SolverOptions;
use softrod_core::{Rod, SoftrodError};

/// Paper 002's actuator, upright under gravity.
fn spa() -> Rod {
    Rod::new(p002_actuator(IDENTITY, 9.81, 16)).unwrap()
}

/// Pressure rows: LEVELS^3 from 0 to 40 kPa per channel.
fn grid() -> Vec<f64> {
    const LEVELS: usize = 3;
    let level = |i: usize| 40e3 * i as f64 / (LEVELS - 1) as f64;
    let mut out = vec![];
    for a in 0..LEVELS {
        for b in 0..LEVELS {
            for c in 0..LEVELS {
                out.extend([level(a), level(b), level(c)]);
            }
        }
    }
    out
}

fn inputs(p: &[f64]) -> BatchInputs<'_> {
    BatchInputs {
        pressures: p,
        tensions: None,
        stiffness_scale: None,
        tip_force: [0.0, 0.01, 0.0],
        tip_moment: [0.0; 3],
    }
}

fn constraints(l: f64) -> Vec<TipConstraint> {
    // A tip pushed sideways and down a little, then pinned; or clamped there, turned.
    let position = [0.004, -0.002, 0.97 * l];
    let c = 0.1f64.cos();
    let s = 0.1f64.sin();
    vec![
        TipConstraint::Pinned { position },
        TipConstraint::Clamped {
            position,
            rotation: [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]],
        },
    ]
}

/// Every row of the batch is `solve_constrained` of that row alone, cold: bitwise equal,
/// for 1, 2 and 4 threads and for other groupings of the rows.
#[test]
fn constrained_batch_equals_single_solves_bitwise() {
    let rod = spa();
    let p = grid();
    let opts = SolverOptions::default();
    for c in constraints(rod.length) {
        let single: Vec<_> = p
            .chunks(3)
            .map(|row| {
                let mut ld = loads(row);
                ld.tip_force = [0.0, 0.01, 0.0];
                solve_constrained(&rod, &ld, &c, None, &opts).unwrap()
            })
            .collect();
        let check = |rows: &[BatchRow], first: usize, what: &str| {
            for (k, row) in rows.iter().enumerate() {
                let s = &single[first + k];
                let what = format!("{} {what}: row {k}", c.name());
                assert!(row.converged, "{what} did not converge");
                assert_eq!(row.tip_position, s.solution.tip.r, "{what}");
                assert_eq!(row.tip_rotation, s.solution.tip.rot, "{what}");
                assert_eq!(row.base_force, s.solution.base_force, "{what}");
                assert_eq!(row.base_moment, s.solution.base_moment, "{what}");
                assert_eq!(row.x, s.solution.x, "{what}");
                assert_eq!(row.stable, s.solution.stable, "{what}");
                assert_eq!(row.iterations, s.solution.iterations, "{what}");
                assert_eq!(row.tip_reaction_force, s.tip_reaction_force, "{what}");
                assert_eq!(row.tip_reaction_moment, s.tip_reaction_moment, "{what}");
            }
        };
        // the rows really differ, and the constraint holds the tip
        let spread = single
            .iter()
            .map(|s| dist(&s.tip_reaction_force, &single[0].tip_reaction_force))
            .fold(0.0, f64::max);
        assert!(spread > 1e-3, "{}: reaction spread {spread}", c.name());
        for threads in [1, 2, 4] {
            let rows = solve_constrained_batch(&rod, &inputs(&p), &c, &opts, threads).unwrap();
            assert_eq!(rows.len(), p.len() / 3);
            check(&rows, 0, &format!("threads = {threads}"));
        }
        let rows = solve_constrained_batch(&rod, &inputs(&p[3 * 10..]), &c, &opts, 3).unwrap();
        check(&rows, 10, "from row 10");
        let rows = solve_constrained_batch(&rod, &inputs(&p[3 * 4..3 * 5]), &c, &opts, 1).unwrap();
        check(&rows, 4, "row 4 alone");
    }
}

/// With an obstacle (docs/contact.md, "A held tip with obstacles"): a wall 0.5 mm inside
/// the pinned tip's surface, which every row presses against, some harder as the pressures
/// bend the body towards it. Every row is bitwise the single solve, whatever the thread
/// count; an obstacle with friction is refused before any row (the statics is
/// frictionless), naming it.
#[test]
fn constrained_batch_with_an_obstacle_equals_single_solves_bitwise() {
    let mut spec = p002_actuator(IDENTITY, 9.81, 16);
    let mut wall = obstacle(ObstacleKind::Plane, 1e4, 2e-3);
    wall.point = Some([0.004 + P002_RO - 5e-4, 0.0, 0.0]);
    wall.normal = Some([-1.0, 0.0, 0.0]);
    spec.obstacles = vec![wall];
    let rod = Rod::new(spec.clone()).unwrap();
    let p = grid();
    let opts = SolverOptions::default();
    let c = constraints(rod.length)[0];
    let single: Vec<_> = p
        .chunks(3)
        .map(|row| {
            let mut ld = loads(row);
            ld.tip_force = [0.0, 0.01, 0.0];
            let s = solve_constrained(&rod, &ld, &c, None, &opts).unwrap();
            let rep = report(&rod, &ld, &s.solution).unwrap().unwrap();
            assert!(rep.max_penetration > 0.0 && rep.max_penetration <= 2e-3);
            s
        })
        .collect();
    let spread = single
        .iter()
        .map(|s| dist(&s.tip_reaction_force, &single[0].tip_reaction_force))
        .fold(0.0, f64::max);
    assert!(spread > 1e-3, "the rows differ: reaction spread {spread}");
    for threads in [1, 3] {
        let rows = solve_constrained_batch(&rod, &inputs(&p), &c, &opts, threads).unwrap();
        for (k, (row, s)) in rows.iter().zip(&single).enumerate() {
            assert!(row.converged, "row {k}");
            assert_eq!(row.x, s.solution.x, "row {k}, {threads} threads");
            assert_eq!(row.tip_reaction_force, s.tip_reaction_force, "row {k}");
            assert_eq!(row.stable, s.solution.stable, "row {k}");
        }
    }
    spec.obstacles[0].friction = 0.3;
    let rough = Rod::new(spec).unwrap();
    match solve_constrained_batch(&rough, &inputs(&p), &c, &opts, 2) {
        Err(e) => assert_eq!(field_of(e), "obstacles[0].friction"),
        Ok(_) => panic!("friction accepted"),
    }
}

/// A pose the rod cannot reach: every row fails, and every row is kept, NaN, with the
/// single solve's iterations and residual, or the rule it broke.
#[test]
fn failed_constrained_rows_are_kept() {
    let rod = spa();
    let p = grid();
    let far = TipConstraint::Pinned {
        position: [0.0, 0.0, 3.0 * rod.length],
    };
    let opts = SolverOptions {
        max_load_steps: 8,
        ..Default::default()
    };
    let rows = solve_constrained_batch(&rod, &inputs(&p[..6]), &far, &opts, 2).unwrap();
    assert_eq!(rows.len(), 2);
    for (k, row) in rows.iter().enumerate() {
        assert!(!row.converged, "row {k}");
        assert!(row.tip_position.iter().all(|v| v.is_nan()));
        assert!(row.tip_reaction_force.iter().all(|v| v.is_nan()));
        assert_eq!(row.x.len(), 6);
        assert!(row.x.iter().all(|v| v.is_nan()));
        let mut ld = loads(&p[3 * k..3 * k + 3]);
        ld.tip_force = [0.0, 0.01, 0.0];
        // the single solve's failure: no convergence, or (stretched out towards the pose)
        // an invalid state whose rule the row names
        match solve_constrained(&rod, &ld, &far, None, &opts) {
            Err(SoftrodError::NotConverged {
                iterations,
                residual,
                ..
            }) => {
                assert_eq!(row.iterations, iterations);
                assert_eq!(row.residual.to_bits(), residual.to_bits());
            }
            Err(e @ SoftrodError::InvalidState { .. }) => {
                assert_eq!(row.violation, e.to_string(), "row {k}");
            }
            other => panic!("row {k}: expected a failure, got {other:?}"),
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
fn bad_constrained_batch_inputs_are_refused_by_name() {
    let rod = spa();
    let opts = SolverOptions::default();
    let pin = constraints(rod.length)[0];
    let mut p = grid();
    p[3 * 5 + 2] = f64::NAN;
    let e = solve_constrained_batch(&rod, &inputs(&p), &pin, &opts, 1).unwrap_err();
    assert_eq!(field_of(e), "row 5: pressures[2]");
    let e = solve_constrained_batch(&rod, &inputs(&[1.0; 4]), &pin, &opts, 1).unwrap_err();
    assert_eq!(field_of(e), "pressures");
    let bad = TipConstraint::Pinned {
        position: [0.0, f64::INFINITY, 0.1],
    };
    let e = solve_constrained_batch(&rod, &inputs(&grid()), &bad, &opts, 1).unwrap_err();
    assert_eq!(field_of(e), "tip_constraint.position[1]");
    let skew = TipConstraint::Clamped {
        position: [0.0; 3],
        rotation: [[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    };
    let e = solve_constrained_batch(&rod, &inputs(&grid()), &skew, &opts, 1).unwrap_err();
    assert_eq!(field_of(e), "tip_constraint.orientation");
    let mut tip = inputs(&[0.0; 3]);
    tip.tip_force[0] = f64::NAN;
    let e = solve_constrained_batch(&rod, &tip, &pin, &opts, 1).unwrap_err();
    assert_eq!(field_of(e), "tip_force[0]");
    let e = solve_constrained_batch(&rod, &inputs(&[0.0; 3]), &pin, &opts, 5000).unwrap_err();
    assert_eq!(field_of(e), "threads");
    // no rows: an empty batch
    let rows = solve_constrained_batch(&rod, &inputs(&[]), &pin, &opts, 1).unwrap();
    assert!(rows.is_empty());
}

/// Two actuators side by side holding a platform (as tests/suite/end_constraints.rs's).
fn system(rod: &Rod) -> (Vec<SystemRod<'_>>, Platform) {
    let gap = 0.02;
    let rods = [-gap, gap]
        .into_iter()
        .map(|x| SystemRod {
            rod,
            loads: loads(&[]),
            attachment: [x, 0.0, 0.0],
            attachment_rotation: IDENTITY,
        })
        .collect();
    let platform = Platform {
        position: [0.0, 0.0, rod.length],
        rotation: IDENTITY,
        force: [0.0, 0.05, 0.0],
        moment: [0.0; 3],
        mass: 0.005,
        com_offset: [0.0; 3],
        gravity: [0.0, 0.0, -9.81],
    };
    (rods, platform)
}

#[test]
fn system_batch_equals_single_solves_bitwise() {
    // Two rods with their own bases (2 cm either side of the origin).
    let left = Rod::new({
        let mut s = p002_actuator(IDENTITY, 9.81, 12);
        s.mounting.base_position = [-0.02, 0.0, 0.0];
        s
    })
    .unwrap();
    let right = Rod::new({
        let mut s = p002_actuator(IDENTITY, 9.81, 12);
        s.mounting.base_position = [0.02, 0.0, 0.0];
        s
    })
    .unwrap();
    let (mut rods, platform) = system(&left);
    rods[1].rod = &right;
    // rows: rod 0's three pressures, then rod 1's
    let rows_in: Vec<[f64; 6]> = vec![
        [0.0; 6],
        [30e3, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0, 25e3, 10e3],
        [20e3, 5e3, 0.0, 10e3, 0.0, 20e3],
        [35e3, 35e3, 0.0, 35e3, 35e3, 0.0],
    ];
    let flat: Vec<f64> = rows_in.iter().flatten().copied().collect();
    let opts = SolverOptions::default();
    let single: Vec<_> = rows_in
        .iter()
        .map(|row| {
            let mut rs = rods.clone();
            rs[0].loads.pressures = row[..3].to_vec();
            rs[1].loads.pressures = row[3..].to_vec();
            solve_system(&rs, &platform, None, &opts).unwrap()
        })
        .collect();
    let check = |out: &[SystemBatchRow], first: usize, what: &str| {
        for (k, row) in out.iter().enumerate() {
            let s = &single[first + k];
            let what = format!("{what}: row {k}");
            assert!(row.converged, "{what}");
            assert_eq!(row.platform_position, s.platform_position, "{what}");
            assert_eq!(row.platform_rotation, s.platform_rotation, "{what}");
            assert_eq!(row.x, s.x, "{what}");
            assert_eq!(row.iterations, s.iterations, "{what}");
            assert_eq!(row.load_steps, s.load_steps, "{what}");
            for (i, (a, b)) in row.rods.iter().zip(&s.rods).enumerate() {
                assert_eq!(a.tip_position, b.solution.tip.r, "{what} rod {i}");
                assert_eq!(a.tip_rotation, b.solution.tip.rot, "{what} rod {i}");
                assert_eq!(a.base_force, b.solution.base_force, "{what} rod {i}");
                assert_eq!(a.tip_reaction_force, b.tip_reaction_force, "{what} rod {i}");
                assert_eq!(
                    a.tip_reaction_moment, b.tip_reaction_moment,
                    "{what} rod {i}"
                );
            }
        }
    };
    let spread = dist(&single[0].platform_position, &single[3].platform_position);
    assert!(spread > 1e-3, "platform moved {spread}");
    for threads in [1, 2, 4] {
        let inputs = SystemBatchInputs {
            pressures: &flat,
            tensions: None,
            stiffness_scale: None,
        };
        let out = solve_system_batch(
            &rods,
            &platform,
            &inputs,
            DEFAULT_FRICTION_STEPS,
            &opts,
            threads,
        )
        .unwrap();
        assert_eq!(out.len(), rows_in.len());
        check(&out, 0, &format!("threads = {threads}"));
    }
    let inputs = SystemBatchInputs {
        pressures: &flat[6 * 2..],
        tensions: None,
        stiffness_scale: None,
    };
    let out =
        solve_system_batch(&rods, &platform, &inputs, DEFAULT_FRICTION_STEPS, &opts, 2).unwrap();
    check(&out, 2, "from row 2");

    // Bad inputs name the row and the rod, before any work.
    let mut bad = flat.clone();
    bad[6 * 3 + 4] = -2e5;
    let inputs = SystemBatchInputs {
        pressures: &bad,
        tensions: None,
        stiffness_scale: None,
    };
    let e = solve_system_batch(&rods, &platform, &inputs, DEFAULT_FRICTION_STEPS, &opts, 1)
        .unwrap_err();
    assert_eq!(field_of(e), "row 3: rods[1].pressures[1]");
    let inputs = SystemBatchInputs {
        pressures: &flat[..7],
        tensions: None,
        stiffness_scale: None,
    };
    let e = solve_system_batch(&rods, &platform, &inputs, DEFAULT_FRICTION_STEPS, &opts, 1)
        .unwrap_err();
    assert_eq!(field_of(e), "pressures");
    let inputs = SystemBatchInputs {
        pressures: &flat,
        tensions: Some(&[1.0]),
        stiffness_scale: None,
    };
    let e = solve_system_batch(&rods, &platform, &inputs, DEFAULT_FRICTION_STEPS, &opts, 1)
        .unwrap_err();
    assert_eq!(field_of(e), "tensions");

    // A row that cannot converge is kept failed, the others solved.
    let tight = SolverOptions {
        max_iter: 1,
        continuation: false,
        ..Default::default()
    };
    let inputs = SystemBatchInputs {
        pressures: &flat,
        tensions: None,
        stiffness_scale: None,
    };
    let out =
        solve_system_batch(&rods, &platform, &inputs, DEFAULT_FRICTION_STEPS, &tight, 2).unwrap();
    assert_eq!(out.len(), rows_in.len());
    let failed: Vec<_> = out.iter().filter(|r| !r.converged).collect();
    assert!(!failed.is_empty());
    for r in failed {
        assert!(r.platform_position.iter().all(|v| v.is_nan()));
        assert_eq!(r.rods.len(), 2);
        assert!(r.rods.iter().all(|k| k.tip_reaction_force[0].is_nan()));
        assert_eq!(r.x.len(), 18);
    }
}

#[test]
fn system_batch_carries_every_rows_sigma_per_rod() {
    // Rod 0's chambered section is stiffness-mapped (paper 001 eq. 13), rod 1 is plain.
    let mapped = Rod::new({
        let mut s = p002_actuator(IDENTITY, 9.81, 12);
        s.mounting.base_position = [-0.02, 0.0, 0.0];
        s.sections[1].law.stiffness_map = true;
        s
    })
    .unwrap();
    let plain = Rod::new({
        let mut s = p002_actuator(IDENTITY, 9.81, 12);
        s.mounting.base_position = [0.02, 0.0, 0.0];
        s
    })
    .unwrap();
    let (mut rods, platform) = system(&mapped);
    rods[1].rod = &plain;
    let rows_in: [[f64; 6]; 3] = [
        [30e3, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.0, 20e3, 10e3, 10e3, 0.0, 0.0],
        [35e3, 35e3, 0.0, 0.0, 0.0, 20e3],
    ];
    // Per row, rod 0's sigma then rod 1's (which acts nowhere: rod 1 has no mapped
    // section, so any valid value gives the same bits as 1).
    let sigma_in: [[f64; 6]; 3] = [
        [1.0, 1.0, 1.0, 1.0, 1.0, 1.0],
        [0.8, 1.3, 0.9, 2.0, 2.0, 2.0],
        [1.5, 0.7, 1.1, 0.5, 0.5, 0.5],
    ];
    let flat: Vec<f64> = rows_in.iter().flatten().copied().collect();
    let sigma: Vec<f64> = sigma_in.iter().flatten().copied().collect();
    let opts = SolverOptions::default();
    let single = |k: usize, sigma0: [f64; 3]| {
        let mut rs = rods.clone();
        rs[0].loads.pressures = rows_in[k][..3].to_vec();
        rs[1].loads.pressures = rows_in[k][3..].to_vec();
        rs[0].loads.stiffness_scale = sigma0;
        solve_system(&rs, &platform, None, &opts).unwrap()
    };
    let inputs = SystemBatchInputs {
        pressures: &flat,
        tensions: None,
        stiffness_scale: Some(&sigma),
    };
    for threads in [1, 2] {
        let out = solve_system_batch(
            &rods,
            &platform,
            &inputs,
            DEFAULT_FRICTION_STEPS,
            &opts,
            threads,
        )
        .unwrap();
        for (k, row) in out.iter().enumerate() {
            let s = single(
                k,
                rod_sigma(0, &mapped, Some(sigma_in[k][..3].try_into().unwrap())).unwrap(),
            );
            assert!(row.converged, "row {k}");
            assert_eq!(row.platform_position, s.platform_position, "row {k}");
            assert_eq!(row.platform_rotation, s.platform_rotation, "row {k}");
            assert_eq!(row.x, s.x, "row {k}");
        }
        // The sensitivity batch's rows are the same solves.
        let sens =
            system_sensitivity_batch(&rods, &platform, &inputs, None, &[], &[], &opts, threads)
                .unwrap();
        for (k, (a, b)) in sens.iter().zip(&out).enumerate() {
            assert_eq!(a.x, b.x, "row {k}");
        }
    }
    // sigma matters: a stiffer and softer rod 0 moves the platform (by millimetres here;
    // 1e-4 m is far above the solver's 1e-10 relative tolerance).
    let out =
        solve_system_batch(&rods, &platform, &inputs, DEFAULT_FRICTION_STEPS, &opts, 1).unwrap();
    for k in [1, 2] {
        let unit = single(k, [1.0; 3]);
        let moved = dist(&out[k].platform_position, &unit.platform_position);
        assert!(
            moved > 1e-4,
            "row {k}: sigma moved the platform by {moved} m"
        );
    }

    // Refusals, before any work, naming the row and the rod.
    let with = |s: &[f64]| {
        let inputs = SystemBatchInputs {
            pressures: &flat,
            tensions: None,
            stiffness_scale: Some(s),
        };
        field_of(
            solve_system_batch(&rods, &platform, &inputs, DEFAULT_FRICTION_STEPS, &opts, 1)
                .unwrap_err(),
        )
    };
    assert_eq!(with(&sigma[..17]), "stiffness_scale");
    for (at, bad, field) in [
        (6 * 2 + 1, f64::NAN, "row 2: rods[0].stiffness_scale[1]"),
        (6 + 2, 0.0, "row 1: rods[0].stiffness_scale[2]"),
        (3, -1.0, "row 0: rods[1].stiffness_scale[0]"),
        (
            6 * 2 + 5,
            f64::INFINITY,
            "row 2: rods[1].stiffness_scale[2]",
        ),
    ] {
        let mut s = sigma.clone();
        s[at] = bad;
        assert_eq!(with(&s), field, "sigma {bad}");
    }
    // No sigma for a system with a mapped rod: refused (never assumed to be 1), in both
    // batches; a system without mapped rods needs none.
    let none = SystemBatchInputs::pressures(&flat);
    let e =
        solve_system_batch(&rods, &platform, &none, DEFAULT_FRICTION_STEPS, &opts, 1).unwrap_err();
    assert_eq!(field_of(e), "rods[0].stiffness_scale");
    let e =
        system_sensitivity_batch(&rods, &platform, &none, None, &[], &[], &opts, 1).unwrap_err();
    assert_eq!(field_of(e), "rods[0].stiffness_scale");
    let mut unmapped = rods.clone();
    unmapped[0].rod = &plain;
    assert!(solve_system_batch(
        &unmapped,
        &platform,
        &none,
        DEFAULT_FRICTION_STEPS,
        &opts,
        1
    )
    .unwrap()
    .iter()
    .all(|r| r.converged));
    // A rod's sigma in the single solve: checked and named by its rod.
    assert_eq!(
        field_of(rod_sigma(0, &mapped, None).unwrap_err()),
        "rods[0].stiffness_scale"
    );
    assert_eq!(rod_sigma(1, &plain, None).unwrap(), [1.0; 3]);
    assert_eq!(
        field_of(rod_sigma(1, &plain, Some([1.0, f64::NAN, 1.0])).unwrap_err()),
        "rods[1].stiffness_scale[1]"
    );
    let mut rs = rods.clone();
    rs[1].loads.stiffness_scale = [1.0, 1.0, -0.5];
    let e = solve_system(&rs, &platform, None, &opts).unwrap_err();
    assert_eq!(field_of(e), "rods[1].stiffness_scale[2]");
}
