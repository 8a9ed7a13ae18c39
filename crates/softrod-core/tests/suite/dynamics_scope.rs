//! Issue 17 part A in dynamics: a constant reference shape (precurvature, pre-strain)
//! enters the collocation dynamics through the laws, which act on the strains relative to
//! it (linear, Ogden and EA(F) table axial laws, with and without stretch-dependent
//! bending), as in the statics. (Tendons and follower loads are carried: tests/suite/dynamics_tendons.rs;
//! tapered sections and tabulated reference shapes: tests/suite/dynamics_taper.rs.)

use crate::common;
use common::*;
use softrod_core::dynamics::{DynOptions, Initial, Scheme, Simulator};
use softrod_core::spec::{AxialSpec, DesignSpec, LawSpec};
use softrod_core::statics::collocation::solve_static;
use softrod_core::statics::{solve, SolverOptions};
use softrod_core::Rod;

fn dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Paper 000's arm (as in tests/suite/dynamics.rs), moulded curved and twisted.
fn precurved_arm() -> DesignSpec {
    let mut sec = pam_arm_section(0.22, 0.165, 16);
    sec.reference.curvature = [0.0, 3.0, 0.5];
    sec.reference.strain = [0.0, 0.0, 1.02];
    let hanging = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];
    let mut spec = design(vec![sec], hanging, 9.81);
    spec.dynamics.damping_time = 0.19;
    spec
}

/// Every axial law, with and without stretch-dependent bending: the laws act on the strains
/// relative to the reference (docs/laws.md), in the dynamics as in the statics.
fn laws() -> Vec<(String, LawSpec)> {
    let table = AxialSpec::Table {
        force: vec![-20.0, 0.0, 20.0],
        stiffness: vec![300.0, 262.8, 220.0],
    };
    let mut out = vec![];
    for (name, axial) in [
        ("linear", AxialSpec::Linear),
        ("ogden", AxialSpec::Ogden { alpha: 4.0 }),
        ("table", table),
    ] {
        for sb in [false, true] {
            let law = LawSpec {
                axial: axial.clone(),
                stretch_bending: sb,
                ..Default::default()
            };
            let sb_name = if sb { ", stretch bending" } else { "" };
            out.push((format!("{name}{sb_name}"), law));
        }
    }
    out
}

#[test]
fn precurved_arm_settles_on_the_statics() {
    let p = [150e3, 0.0, 60e3];
    let opts = DynOptions {
        dt: 5e-3,
        tol: 1e-12,
        ..Default::default()
    };
    for (name, law) in laws() {
        let mut spec = precurved_arm();
        spec.sections[0].law = law;
        let rod = Rod::new(spec).unwrap();
        let mut sim = Simulator::new(rod.clone(), &[0.0; 3], Initial::Static, opts).unwrap();
        let start = sim.tip().r;
        for _ in 0..1000 {
            sim.step(&p).unwrap();
        }
        let coll = solve_static(&rod, &loads(&p), None, &SolverOptions::default()).unwrap();
        let tip = coll.evaluated.node_r.last().unwrap();
        let shooting = solve(&rod, &loads(&p), None, &SolverOptions::default()).unwrap();
        let d = dist(&sim.tip().r, tip);
        let ds = dist(&sim.tip().r, &shooting.tip.r);
        eprintln!(
            "{name}: tip after 5 s vs collocation statics {d:.3e} m, vs shooting {ds:.3e} m; moved {:.3e} m",
            dist(&start, tip)
        );
        // As tests/suite/dynamics.rs: the slowest mode decays as exp(-5.8 t), so after 5 s the
        // run sits on the discretisation's own statics to the solvers' tolerance (1e-9 L),
        // and on the shooting statics (an independent discretisation of the same law) to
        // their O(h^4) difference (1e-6 L). Bending that scaled the curvature instead of
        // its change from u* by the stretch put collocation 8e-3 m off the shooting.
        assert!(d < 1e-9 * 0.22, "{name}: {d}");
        assert!(ds < 1e-6 * 0.22, "{name}: {ds}");
        assert!(
            dist(&start, tip) > 0.05,
            "{name}: the pressure moves the arm"
        );
    }
}

/// The energy books read the laws relative to the reference too: an undamped midpoint run
/// of the precurved arm under a pressure ramp keeps its balance for every law (the books'
/// density is the potential of the law's force and moment, and stretch-dependent bending
/// books its non-potential part as input work, both with u - u* and v3 - v3* + 1; with the
/// absolute curvature the books were off by 1.5 % of the energy moved). The step Jacobian
/// against central differences at the run's end (for the nonlinear laws with
/// stretch-dependent bending: 13 s each in a test build).
fn law_is_nonlinear_with_stretch_bending(name: &str) -> bool {
    !name.starts_with("linear") && name.ends_with("stretch bending")
}

#[test]
fn undamped_precurved_arm_keeps_its_energy_balance_for_every_law() {
    let opts = DynOptions {
        dt: 1e-3,
        scheme: Scheme::Midpoint,
        ..Default::default()
    };
    for (name, law) in laws() {
        let mut spec = precurved_arm();
        spec.sections[0].law = law;
        spec.dynamics.damping_time = 0.0;
        let rod = Rod::new(spec).unwrap();
        let mut sim = Simulator::new(rod, &[0.0; 3], Initial::Static, opts).unwrap();
        let (mut worst, mut moved): (f64, f64) = (0.0, 0.0);
        for k in 0..200 {
            let ramp = ((k + 1) as f64 * 1e-3 / 0.1).min(1.0);
            sim.step(&[60e3 * ramp, 0.0, 20e3 * ramp]).unwrap();
            let b = sim.energy_books();
            moved = moved.max(b.work_in.abs() + b.kinetic);
            worst = worst.max(sim.energy_balance().abs());
        }
        eprintln!("{name}: worst |balance| {worst:.3e} J of {moved:.3e} J moved");
        // The step Jacobian of the nonlinear laws relative to the reference stays exact
        // (both new terms: the shifted strain w and the relative stretch rho).
        if law_is_nonlinear_with_stretch_bending(&name) {
            check_step_jacobian(&name, &sim);
        }
        assert!(moved > 1e-4, "{name}: the pressures do work");
        // The implicit midpoint rule conserves a quadratic energy exactly and a nonlinear
        // one to O(dt^2): 1 % of the energy moved, as tests/suite/dynamics_taper.rs.
        assert!(worst <= 1e-2 * moved, "{name}: balance {worst} of {moved}");
    }
}

/// The 'reference' start of the precurved, pre-strained arm: without gravity the unloaded
/// rod at rest in its reference shape is the 'static' start's state (the same rest problem,
/// every load off) to the Newton tolerance (1e-9 scaled: 1e-9 L), and stays there; the
/// 'straight' start is refused by name (held straight, the curved rod carries an internal
/// moment its free tip cannot).
#[test]
fn reference_start_is_the_unloaded_reference_shape() {
    let opts = DynOptions {
        dt: 5e-3,
        tol: 1e-12,
        ..Default::default()
    };
    let mut spec = precurved_arm();
    spec.mounting.gravity = [0.0; 3];
    let rod = Rod::new(spec).unwrap();
    let mut sim = Simulator::new(rod.clone(), &[0.0; 3], Initial::Reference, opts).unwrap();
    let stat = Simulator::new(rod.clone(), &[0.0; 3], Initial::Static, opts).unwrap();
    let d = dist(&sim.tip().r, &stat.tip().r);
    assert!(d < 1e-9 * 0.22, "{d:e}");
    assert!(sim.tip().r[0].abs() > 0.01, "curved: {:?}", sim.tip().r);
    let start = sim.tip().r;
    for _ in 0..20 {
        sim.step(&[0.0; 3]).unwrap();
    }
    assert!(dist(&sim.tip().r, &start) < 1e-12 * 0.22);
    let straight = Simulator::new(rod, &[0.0; 3], Initial::Straight, opts);
    assert!(matches!(straight, Err(e) if e.to_string().contains("'reference'")));
}
