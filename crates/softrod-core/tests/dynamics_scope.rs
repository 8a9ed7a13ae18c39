//! Issue 17 part A in dynamics: a constant reference shape (precurvature, pre-strain) with
//! the linear law enters the collocation dynamics through the law's shifts; what it does
//! not carry (a reference shape with a nonlinear axial law) is refused with the field named
//! (docs/scope.md). (Tendons and follower loads are carried: tests/dynamics_tendons.rs;
//! tapered sections and tabulated reference shapes: tests/dynamics_taper.rs.)

mod common;
use common::*;
use softrod_core::dynamics::{DynOptions, Initial, Simulator};
use softrod_core::spec::DesignSpec;
use softrod_core::statics::collocation::solve_static;
use softrod_core::statics::{solve, SolverOptions};
use softrod_core::Rod;

fn dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Paper 000's arm (as in tests/dynamics.rs), moulded curved and twisted.
fn precurved_arm() -> DesignSpec {
    let mut sec = direct_section("arm", 0.22, 262.8, 87.6, 0.04466, 0.02977, 0.165, 16);
    sec.chambers = [0.0, 120.0, 240.0]
        .iter()
        .enumerate()
        .map(|(k, a)| {
            let mut c = chamber(6.02e-3, 0.0175, *a, k);
            c.area = 113.88e-6;
            c
        })
        .collect();
    sec.reference.curvature = [0.0, 3.0, 0.5];
    sec.reference.strain = [0.0, 0.0, 1.02];
    let hanging = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];
    let mut spec = design(vec![sec], hanging, 9.81);
    spec.dynamics.damping_time = 0.19;
    spec
}

#[test]
fn precurved_arm_settles_on_the_statics() {
    let rod = Rod::new(precurved_arm()).unwrap();
    let p = [150e3, 0.0, 60e3];
    let opts = DynOptions {
        dt: 5e-3,
        tol: 1e-12,
        ..Default::default()
    };
    let mut sim = Simulator::new(rod.clone(), &[0.0; 3], Initial::Static, opts).unwrap();
    let start = sim.tip().r;
    for _ in 0..1000 {
        sim.step(&p).unwrap();
    }
    let coll = solve_static(&rod, &loads(&p), None, &SolverOptions::default()).unwrap();
    let tip = coll.evaluated.node_r.last().unwrap();
    let shooting = solve(&rod, &loads(&p), None, &SolverOptions::default()).unwrap();
    let d = dist(&sim.tip().r, tip);
    eprintln!(
        "tip after 5 s vs collocation statics {d:.3e} m, vs shooting {:.3e} m; moved {:.3e} m",
        dist(&sim.tip().r, &shooting.tip.r),
        dist(&start, tip)
    );
    // As tests/dynamics.rs: the slowest mode decays as exp(-5.8 t), so after 5 s the run
    // sits on the discretisation's own statics to the solvers' tolerance (1e-9 L), and on
    // the shooting statics to the two discretisations' O(h^4) difference (1e-6 L).
    assert!(d < 1e-9 * 0.22);
    assert!(dist(&sim.tip().r, &shooting.tip.r) < 1e-6 * 0.22);
    assert!(dist(&start, tip) > 0.05, "the pressure moves the arm");
}

#[test]
fn dynamics_refuses_what_it_does_not_carry() {
    type Change = fn(&mut DesignSpec);
    // A reference shape with a nonlinear axial law (Ogden): its pre-strain v* is not in
    // the dynamic Ogden law yet. (Tapered sections and tabulated reference shapes are
    // carried: tests/dynamics_taper.rs.)
    let cases: [(&str, Change); 1] = [("sections[0].reference", |s| {
        s.sections[0].law.axial = softrod_core::spec::AxialSpec::Ogden { alpha: 4.0 };
    })];
    for (field, change) in cases {
        let mut spec = precurved_arm();
        change(&mut spec);
        let rod = Rod::new(spec).unwrap();
        let Err(err) = Simulator::new(rod, &[0.0; 3], Initial::Static, DynOptions::default())
        else {
            panic!("{field}: refused");
        };
        let text = err.to_string();
        assert!(text.contains(field), "{text}");
        assert!(text.contains("not supported by the dynamics"), "{text}");
    }
}
