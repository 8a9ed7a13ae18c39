//! Issue 17 items 1 and 6 in dynamics: tapered sections (outer radius, chamber distances and
//! radii linear in s) and reference shapes tabulated along s. Every stage point of such a
//! section has its own section model (stiffness, damping B = tau K, line mass, rotary
//! inertia, pressure force and moment, stress-free strains at the stage's arc length;
//! `collocation::Grid::models`). With Kelvin-Voigt damping a run settles on collocation
//! statics (the same discretisation at rest) to 1e-9 L; the step Jacobian matches central
//! differences; an undamped midpoint run keeps its energy balance, whose books read the
//! same s-dependent properties.

use crate::common;
use common::*;
use softrod_core::dynamics::{DynOptions, Initial, Scheme, Simulator};
use softrod_core::spec::{LawSpec, ReferenceSpec};
use softrod_core::statics::collocation::solve_static;
use softrod_core::statics::{solve, SolverOptions};
use softrod_core::Rod;

const P: [f64; 3] = [40e3, 10e3, 0.0];

fn settle(rod: &Rod, p: &[f64], n: usize) -> (f64, f64) {
    let opts = DynOptions {
        dt: 5e-3,
        tol: 1e-12,
        ..Default::default()
    };
    let mut sim = Simulator::new(rod.clone(), &vec![0.0; p.len()], Initial::Static, opts).unwrap();
    let start = sim.tip().r;
    for _ in 0..n {
        sim.step(p).unwrap();
    }
    let tight = SolverOptions {
        tol: 1e-12,
        ..Default::default()
    };
    let st = solve_static(rod, &loads(p), None, &tight).unwrap();
    let tip = st.evaluated.node_r.last().unwrap();
    let shooting = solve(rod, &loads(p), None, &tight).unwrap();
    eprintln!(
        "moved {:.4e} m; off collocation statics by {:.3e} m, off shooting statics by {:.3e} m",
        dist(&sim.tip().r, &start),
        dist(&sim.tip().r, tip),
        dist(&sim.tip().r, &shooting.tip.r)
    );
    (dist(&sim.tip().r, tip), dist(&sim.tip().r, &start))
}

#[test]
fn damped_tapered_actuator_settles_on_the_collocation_statics() {
    // As tests/suite/dynamics_laws.rs (tau = 0.05 s, 3 s at P): the rest state of the dynamic
    // discretisation is collocation statics, solved independently: 1e-9 L.
    // The linear law and stretch-dependent bending (statics refuses a taper with the Ogden
    // law or an EA(F) table already: Rod::new).
    let length = 0.134;
    let laws = [
        LawSpec::default(),
        LawSpec {
            stretch_bending: true,
            ..Default::default()
        },
    ];
    for law in laws {
        let mut spec = tapered(8, 0.05);
        spec.sections[1].law = law.clone();
        let rod = Rod::new(spec).unwrap();
        let (d, moved) = settle(&rod, &P, 600);
        assert!(moved > 1e-3, "the pressures move the tip");
        assert!(d < 1e-9 * length, "{law:?}: {d}");
    }
    let rod = Rod::new(tapered(8, 0.05)).unwrap();
    // The taper matters: the uniform actuator's statics lies elsewhere.
    let uniform = Rod::new({
        let mut d = p002_actuator(HANGING, 9.81, 8);
        d.dynamics.damping_time = 0.05;
        d
    })
    .unwrap();
    let a = solve(&rod, &loads(&P), None, &SolverOptions::default()).unwrap();
    let b = solve(&uniform, &loads(&P), None, &SolverOptions::default()).unwrap();
    assert!(dist(&a.tip.r, &b.tip.r) > 1e-3);
}

#[test]
fn damped_tabulated_arms_settle_on_the_collocation_statics() {
    // As tests/suite/dynamics_scope.rs: the slowest mode decays as exp(-5.8 t); after 5 s the
    // run sits on the discretisation's own statics to 1e-9 L.
    let p = [150e3, 0.0, 60e3];
    for helix in [true, false] {
        let rod = Rod::new(tabulated_arm(helix)).unwrap();
        let (d, moved) = settle(&rod, &p, 1000);
        assert!(moved > 0.05, "the pressure moves the arm");
        assert!(d < 1e-9 * 0.22, "helix {helix}: {d}");
    }
}

#[test]
fn a_constant_table_is_the_constant_reference_in_dynamics() {
    // The helix given by a table of equal values and by constant values: the same run.
    let table = Rod::new(tabulated_arm(true)).unwrap();
    let mut spec = tabulated_arm(true);
    spec.sections[0].reference = ReferenceSpec {
        curvature: [0.0, 3.0, 0.5],
        strain: [0.0, 0.0, 1.02],
        ..Default::default()
    };
    let constant = Rod::new(spec).unwrap();
    let opts = DynOptions {
        dt: 5e-3,
        ..Default::default()
    };
    let p = [150e3, 0.0, 60e3];
    let mut a = Simulator::new(table, &[0.0; 3], Initial::Static, opts).unwrap();
    let mut b = Simulator::new(constant, &[0.0; 3], Initial::Static, opts).unwrap();
    for _ in 0..40 {
        a.step(&p).unwrap();
        b.step(&p).unwrap();
    }
    let d = dist(&a.tip().r, &b.tip().r);
    assert!(d < 1e-12, "{d}");
}

/// [`check_step_jacobian`] after ten steps under the pressures `p`.
fn step_jacobian_after_steps(name: &str, rod: Rod, p: &[f64]) {
    let mut sim = Simulator::new(
        rod,
        &vec![0.0; p.len()],
        Initial::Static,
        DynOptions::default(),
    )
    .unwrap();
    for _ in 0..10 {
        sim.step(p).unwrap();
    }
    check_step_jacobian(name, &sim);
}

#[test]
fn step_jacobian_matches_finite_differences_for_taper_and_tables() {
    // As tests/suite/dynamics_laws.rs: to 1e-6 of each row's scale.
    step_jacobian_after_steps("tapered", Rod::new(tapered(2, 0.05)).unwrap(), &P);
    let mut arm = tabulated_arm(false);
    arm.sections[0].steps = 3;
    step_jacobian_after_steps("tabulated arc", Rod::new(arm).unwrap(), &[150e3, 0.0, 60e3]);
}

/// Undamped, the midpoint rule conserves the linear law's energy; with gravity to second
/// order. A tapered actuator released under a pressure jump, then a ramp: |E - E(0) -
/// W_in| stays within 1 % of the energy moved at every step (the books read the
/// s-dependent stiffness, pressure terms, line mass and inertia of the stages).
#[test]
fn undamped_midpoint_run_of_a_tapered_rod_keeps_its_energy_balance() {
    let rod = Rod::new(tapered(4, 0.0)).unwrap();
    let opts = DynOptions {
        dt: 1e-3,
        scheme: Scheme::Midpoint,
        ..Default::default()
    };
    let mut sim = Simulator::new(rod, &[0.0; 3], Initial::Static, opts).unwrap();
    let mut worst: f64 = 0.0;
    let mut moved: f64 = 0.0;
    for k in 0..300 {
        let t = (k + 1) as f64 * 1e-3;
        let ramp = (t / 0.15).min(1.0);
        let p = [20e3, 20e3 * ramp, 0.0];
        sim.step(&p).unwrap();
        let b = sim.energy_books();
        moved = moved.max(b.work_in.abs() + b.dissipated + b.kinetic);
        worst = worst.max(sim.energy_balance().abs());
    }
    let b = sim.energy_books();
    eprintln!(
        "tapered midpoint: worst |balance| {worst:.3e} J of {moved:.3e} J moved; work in {:.3e} J, kinetic now {:.3e} J",
        b.work_in, b.kinetic
    );
    assert!(b.work_in.abs() > 1e-6, "the pressures do work");
    assert!(b.dissipated == 0.0);
    assert!(worst <= 1e-2 * moved, "balance {worst} of {moved}");
}

/// Long soft rods whose single shooting is ill-conditioned go to collocation statics
/// automatically, now also with taper and tabulated reference shapes: paper 000's 1 m arm
/// (40 steps, made heavier) with its chambers moving inwards along the arm (a taper of the chamber
/// distances) and a tabulated precurvature; `solve` answers with collocation's solution.
#[test]
fn long_tapered_tabulated_arm_goes_to_collocation_statics() {
    let rod = Rod::new(design(vec![long_tapered_tabulated_arm()], HANGING, 9.81)).unwrap();
    assert!(rod.sections[0].tapered && rod.sections[0].reference.is_varying());
    let p = [30e3, 0.0, 0.0];
    let tight = SolverOptions {
        tol: 1e-12,
        ..Default::default()
    };
    let auto = solve(&rod, &loads(&p), None, &tight).unwrap();
    assert!(auto.collocation.is_some(), "solved by collocation");
    let coll = solve_static(&rod, &loads(&p), None, &tight).unwrap();
    let d = dist(&auto.tip.r, coll.evaluated.node_r.last().unwrap());
    eprintln!(
        "1 m arm: automatic vs collocation statics {d:.3e} m; stable {:?}",
        auto.stable
    );
    assert!(d < 1e-9);
}
